//! Step 6: the mouth corners.

use super::detector::Detector;
use super::fissure::Relief;
use super::frame::{Frame, side_box};
use super::table2::NOSE_TIP_TO_MOUTH;
use crate::feature_points::FeaturePoint;
use glam::DVec2;

/// Paper step 6: mouth corners are regions with `S <` this.
pub const MOUTH_CORNER_MAX_S: f64 = 0.25;
/// Our step 6: the mouth-corner box starts this far below the nose corners, mm (Table 2's
/// 16.9 mm minimum below the nose tip reaches the alar creases, concave too, on some real
/// scans; the benchmark's mouth corners are 23 ± 4 mm below its nose corners).
pub const MOUTH_BELOW_NOSE_CORNERS_MM: f64 = 9.0;
/// Our step 6: the corner is the region vertex maximising `lateral − this · |v − median v|`:
/// the lateral end of the lip line, not of a fold running down from it (0, the most lateral
/// vertex, was ~1 mm worse on the benchmark: docs/measurements.md).
pub const MOUTH_CORNER_LINE_WEIGHT: f64 = 1.5;
/// Our step 6: a concave region none of whose vertices comes within this of the lips' front
/// (mm, scanner depth; the most forward row of the lips' profile below the nose tip, see
/// [`super::LIP_PROFILE_HALF_WIDTH_MM`]) is the cheek beside the mouth, not its corner: a
/// puckered or funnelled mouth pushes the lips forward and draws the cheeks in, and the
/// hollow outgrew the small corner regions. The corner lies on the lips' arch, at most 33 mm
/// behind their front on the benchmark's truth (laughs draw it back), and its region reaches
/// further forward than the corner itself (docs/measurements.md).
pub const MOUTH_CORNER_MAX_BEHIND_LIPS_MM: f64 = 35.0;
/// Our step 6: the lip fissure is followed at most this far lateral of the concave region's
/// corner, mm.
pub const MOUTH_FISSURE_MAX_SHIFT_MM: f64 = 15.0;
/// Our step 6: the lip fissure is followed within this height above and below the concave
/// region's corner, mm.
pub const MOUTH_FISSURE_HALF_HEIGHT_MM: f64 = 3.0;
/// Our step 6: a vertex at least this far below its surroundings (mm,
/// [`Detector::relief_around`]) is in the lip fissure's groove.
pub const MOUTH_FISSURE_MIN_DEPTH_MM: f64 = 0.8;
/// Our step 6: the lip fissure ends where neither its groove nor the mouth's opening goes on
/// within this lateral gap, mm (two sample spacings of a VIVID scan).
pub const MOUTH_FISSURE_MAX_GAP_MM: f64 = 3.0;
/// Our step 6: the mouth's opening is searched within this height above and below the
/// corner, mm (parted lips: the opening's half-height, at most about the lips' own height).
pub const MOUTH_OPENING_HALF_HEIGHT_MM: f64 = 15.0;

impl Detector<'_> {
    /// Step 6: in a box per side from Table 2's nose-tip-to-mouth range (but at least
    /// [`MOUTH_BELOW_NOSE_CORNERS_MM`] below the nose corners) out to the outer eye corners,
    /// the biggest `S < 0.25` region that comes within [`MOUTH_CORNER_MAX_BEHIND_LIPS_MM`] of
    /// the lips' front (ours: the paper takes the biggest); the corner is the most lateral of
    /// its vertices curved at least as much as the region's median (the fissure, not a crease
    /// running on from it), near the region's median height ([`MOUTH_CORNER_LINE_WEIGHT`]).
    pub(super) fn mouth_corners(
        &mut self,
        frame: &Frame,
        outer_r: usize,
        outer_l: usize,
        nose_v: f64,
    ) -> (usize, usize) {
        let top = (-NOSE_TIP_TO_MOUTH.min_mm).min(nose_v - MOUTH_BELOW_NOSE_CORNERS_MM);
        let t = NOSE_TIP_TO_MOUTH;
        let ur = frame.uv(self.p(outer_r)).x;
        let ul = frame.uv(self.p(outer_l)).x;
        let bottom = -t.max_mm - 6.0;
        // The lips' front: the most forward row of the lips' profile below the nose.
        let behind_limit_mm = (self.lips_profile(frame, 0.0, top, bottom).into_iter())
            .filter_map(|(_, z)| z)
            .max_by(f64::total_cmp)
            .map_or(f64::NEG_INFINITY, |z| z - MOUTH_CORNER_MAX_BEHIND_LIPS_MM);
        let mut out = [0usize; 2];
        for (k, side) in [-1.0, 1.0].into_iter().enumerate() {
            let lim = if side < 0.0 { -ur } else { ul };
            let bx = side_box(side, (6.0, lim.clamp(20.0, 45.0)), (bottom, top));
            let mask = self.box_mask(frame, bx, |v| self.desc.shape_index[v] < MOUTH_CORNER_MAX_S);
            // A region that nowhere comes within the limit of the lips' front is the cheek.
            let reaches_lips =
                |r: &[u32]| r.iter().any(|&v| self.p(v as usize).z >= behind_limit_mm);
            out[k] = match self.biggest_where(&mask, reaches_lips) {
                Some(r) => {
                    let mut vs: Vec<f64> =
                        r.iter().map(|&v| frame.uv(self.p(v as usize)).y).collect();
                    vs.sort_by(f64::total_cmp);
                    let med = vs[vs.len() / 2];
                    // The corner ends the lip fissure, the region's sharply curved part; a
                    // shallow crease running on from it (down the cheek) must not carry the
                    // most lateral vertex out with it.
                    let curvedness = |v: u32| self.desc.curvedness_per_mm[v as usize];
                    let mut cs: Vec<f64> = r.iter().map(|&v| curvedness(v)).collect();
                    cs.sort_by(f64::total_cmp);
                    let median_curvedness = cs[cs.len() / 2];
                    let fissure: Vec<u32> = r
                        .iter()
                        .copied()
                        .filter(|&v| curvedness(v) >= median_curvedness)
                        .collect();
                    self.most(&fissure, |p| {
                        let q = frame.uv(p);
                        side * q.x - MOUTH_CORNER_LINE_WEIGHT * (q.y - med).abs()
                    })
                }
                None => self.fallback(
                    FeaturePoint::MouthCornerLeft,
                    side,
                    frame,
                    DVec2::new(side * 25.0, -t.avg_mm),
                ),
            };
        }
        if self.params.mouth_corner_at_fissure {
            out[0] = self.mouth_fissure_end(frame, out[0], -1.0);
            out[1] = self.mouth_fissure_end(frame, out[1], 1.0);
        }
        (out[0], out[1])
    }

    /// Step 6's refinement: the lateral end of the lip fissure from `near` (the mouth corner
    /// is where the lips meet). Parted lips leave an opening, a hole in the scan, whose
    /// concave rim ends short of the corner; the lips then meet along a groove out to the
    /// corner. From `near`, the fissure is followed laterally within
    /// [`MOUTH_FISSURE_HALF_HEIGHT_MM`] of its height over groove vertices
    /// ([`MOUTH_FISSURE_MIN_DEPTH_MM`] deep) and the opening's rim
    /// ([`Self::mouth_opening_rim`]), as long as no lateral gap exceeds
    /// [`MOUTH_FISSURE_MAX_GAP_MM`], at most [`MOUTH_FISSURE_MAX_SHIFT_MM`]; its most lateral
    /// vertex is the corner. Any other hole (a scanner's dropout beside a closed mouth) ends
    /// the fissure.
    fn mouth_fissure_end(&self, frame: &Frame, near: usize, side: f64) -> usize {
        let h = MOUTH_FISSURE_HALF_HEIGHT_MM;
        let rim = self.mouth_opening_rim(frame, near);
        let mut fissure: Vec<Relief> = self
            .relief_around(frame, near, side, (0.0, MOUTH_FISSURE_MAX_SHIFT_MM, h, h))
            .into_iter()
            .filter(|r| match r.relief_mm {
                Some(d) => d < -MOUTH_FISSURE_MIN_DEPTH_MM,
                None => rim.as_ref().is_some_and(|rim| rim[r.vertex]),
            })
            .collect();
        fissure.sort_by(|a, b| a.at.x.total_cmp(&b.at.x));
        let (mut corner, mut reach_mm) = (near, 0.0);
        for r in fissure {
            if r.at.x > reach_mm + MOUTH_FISSURE_MAX_GAP_MM {
                break;
            }
            (corner, reach_mm) = (r.vertex, r.at.x);
        }
        corner
    }

    /// The rim of the mouth's opening beside `near`, where the lips are parted: the vertices
    /// beside a hole ([`crate::mesh::Topology::touches_boundary`]) connected to one within two
    /// rings of `near`, within [`MOUTH_OPENING_HALF_HEIGHT_MM`] of its height, when they reach
    /// across the face's midline (an opening between the lips straddles it; a dropout beside
    /// a corner does not). `None` otherwise. Flags per vertex.
    fn mouth_opening_rim(&self, frame: &Frame, near: usize) -> Option<Vec<bool>> {
        let topo = self.topology;
        let v0 = frame.uv(self.p(near)).y;
        let inside = |v: usize| {
            topo.touches_boundary(v)
                && (frame.uv(self.p(v)).y - v0).abs() <= MOUTH_OPENING_HALF_HEIGHT_MM
        };
        let seeds = topo.within_rings(&[near], 2);
        let mut rim = vec![false; self.mesh.vertex_count()];
        let mut front: Vec<usize> = (0..rim.len()).filter(|&v| seeds[v] && inside(v)).collect();
        for &v in &front {
            rim[v] = true;
        }
        while let Some(v) = front.pop() {
            for &u in topo.neighbours(v) {
                let u = u as usize;
                if !rim[u] && inside(u) {
                    rim[u] = true;
                    front.push(u);
                }
            }
        }
        let (mut left, mut right) = (false, false);
        for v in (0..rim.len()).filter(|&v| rim[v]) {
            let u = frame.uv(self.p(v)).x;
            left |= u > 0.0;
            right |= u < 0.0;
        }
        (left && right).then_some(rim)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::detector::TestSurface;
    use crate::test_support::grid;
    use glam::DVec3;

    /// The mouth corners of a puckered mouth (face frame: nose tip at the origin, y up,
    /// facing +z): lips pushed 18 mm forward of a face whose cheeks recede 0.012 mm/mm², a
    /// 3 mm-deep pit at each corner (u = ±13 mm, 38 mm below the tip) and, beside each, the
    /// cheek drawn in by a 12 mm-deep hollow (u = ±38 mm), the bigger concave region. The
    /// hollow lies about 47 mm behind the lips' front: the corners must be the pits.
    #[test]
    fn a_drawn_in_cheek_behind_puckered_lips_is_not_a_mouth_corner() {
        let nose_tip = DVec3::new(60.0, 80.0, 0.0);
        let gauss = |u: f64, v: f64, su: f64, sv: f64| {
            (-(u * u) / (2.0 * su * su) - (v * v) / (2.0 * sv * sv)).exp()
        };
        let z = |x: f64, y: f64| {
            let (u, v) = (x - nose_tip.x, y - nose_tip.y);
            let lips = 18.0 * gauss(u, v + 38.0, 9.0, 6.0);
            let pits = gauss(u - 13.0, v + 38.0, 3.0, 3.0) + gauss(u + 13.0, v + 38.0, 3.0, 3.0);
            let hollows = gauss(u - 38.0, v + 38.0, 6.0, 6.0) + gauss(u + 38.0, v + 38.0, 6.0, 6.0);
            -20.0 - 0.012 * u * u + lips - 3.0 * pits - 12.0 * hollows
        };
        let surface = TestSurface::new(grid(121, 81, z));
        let mut detector = surface.detector();
        let frame = Frame::new(nose_tip, 0.0);
        let vertex = |x: f64, y: f64| (y as usize) * 121 + x as usize;
        let (outer_r, outer_l) = (vertex(15.0, 75.0), vertex(105.0, 75.0));
        let (r, l) = detector.mouth_corners(&frame, outer_r, outer_l, -12.0);
        assert!(detector.guessed.is_empty());
        for (v, side) in [(r, -1.0), (l, 1.0)] {
            let q = frame.uv(detector.p(v));
            assert!(
                (side * q.x - 13.0).abs() <= 5.0 && (q.y + 38.0).abs() <= 5.0,
                "side {side}: corner at ({:.1}, {:.1}), not at the pit (±13, −38)",
                q.x,
                q.y
            );
        }
    }

    /// Lips meeting along a groove (2 mm deep, σ 1 mm) at v = −40 mm that ends at the corners
    /// u = ±20 mm (face frame, 1 mm grid), on a face receding 0.01 mm/mm², without the
    /// vertices where `hole(u, v)`; the corner each side reaches from `near_u`.
    fn fissure_ends(near_u: f64, hole: impl Fn(f64, f64) -> bool) -> [f64; 2] {
        let nose_tip = DVec3::new(50.0, 80.0, 0.0);
        let z = |x: f64, y: f64| {
            let (u, v) = (x - nose_tip.x, y - nose_tip.y);
            let along = 1.0 / (1.0 + ((u.abs() - 20.0) / 0.7).exp());
            -20.0 - 0.01 * u * u - 2.0 * along * (-(v + 40.0).powi(2) / 2.0).exp()
        };
        let mut mesh = grid(101, 81, z);
        let keep: Vec<bool> = (mesh.positions_mm.iter())
            .map(|p| !hole(p.x - nose_tip.x, p.y - nose_tip.y))
            .collect();
        mesh.retain_vertices(&keep);
        let surface = TestSurface::new(mesh);
        let detector = surface.detector();
        let frame = Frame::new(nose_tip, 0.0);
        [-1.0, 1.0].map(|side: f64| {
            let (x, y) = (nose_tip.x + side * near_u, nose_tip.y - 40.0);
            let at = DVec3::new(x, y, z(x, y));
            let near = (0..surface.mesh.vertex_count())
                .min_by(|&a, &b| {
                    let d = |v: usize| detector.p(v).distance_squared(at);
                    d(a).total_cmp(&d(b))
                })
                .unwrap();
            frame
                .uv(detector.p(detector.mouth_fissure_end(&frame, near, side)))
                .x
        })
    }

    /// Parted lips: an opening (a hole 16 mm wide and 6 mm tall, across the midline) whose
    /// end (u = ±9 mm) is where the concave rim stops; the lips meet along the groove out to
    /// u = ±20 mm, and the corner goes there. Closed lips with a scanner's dropout beside the
    /// right corner (u −30 to −22 mm, not reaching the midline): the corner stays at the
    /// groove's end, and on the groove's end it stays put.
    #[test]
    fn the_mouth_corner_is_the_lateral_end_of_the_lips_fissure() {
        let lips_height = |v: f64| (-42.0..=-37.0).contains(&v);
        let [r, l] = fissure_ends(9.0, |u, v| u.abs() <= 8.0 && lips_height(v));
        assert!(
            (r + 20.0).abs() <= 1.5,
            "right corner at u = {r:.1}, not −20"
        );
        assert!((l - 20.0).abs() <= 1.5, "left corner at u = {l:.1}, not 20");
        let dropout = |u: f64, v: f64| (-30.0..=-22.0).contains(&u) && lips_height(v);
        let [r, l] = fissure_ends(19.0, dropout);
        assert!(
            (r + 20.0).abs() <= 1.5,
            "right corner at u = {r:.1}: across the dropout"
        );
        assert!((l - 20.0).abs() <= 1.5, "left corner at u = {l:.1}, not 20");
    }
}
