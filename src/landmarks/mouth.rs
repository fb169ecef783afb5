//! Step 6: the mouth corners.

use super::detector::Detector;
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
        (out[0], out[1])
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
}
