//! Step 4: the outer eye corners, then moved to the lateral end of their lid fissures.

use super::detector::{Detector, FEATURE_MIN_CURVEDNESS_PER_MM};
use super::eyes::FISSURE_MAX_SHIFT_MM;
use super::frame::{Frame, side_box};
use super::table2::INSIDE_EYE_TO_OUTSIDE_EYE;
use crate::feature_points::FeaturePoint;
use glam::DVec2;

/// Paper step 4: outer eye corners: `S <` this, with `|∂/∂x| ≤ 0.5` and `∇xy < 0.25`.
pub const OUTER_EYE_MAX_S: f64 = 0.5;
/// Paper step 4: `|∂/∂x| ≤` this at outer eye corners.
pub const OUTER_EYE_MAX_DX: f64 = 0.5;
/// Paper step 4: `∇xy <` this at outer eye corners.
pub const OUTER_EYE_MAX_GRAD_XY: f64 = 0.25;
/// Our step 4: outer eye corners lie in concave regions with `S <` this.
pub const OUTER_EYE_CONCAVE_MAX_S: f64 = 0.3;
/// Our step 4: concave regions of fewer vertices than this are noise. Every vertex of any
/// larger region is a candidate (not only of the biggest region), which cut the mean error by
/// 0.7–1.1 mm on the benchmark (docs/measurements.md).
pub const OUTER_EYE_MIN_REGION_VERTICES: usize = 5;
/// Our step 4: average outer eye corner relative to the inner one (outwards, up), mm
/// (Table 2's inner–outer horizontal range 15.9–39.7 mm; 26 mm measured on the benchmark).
pub const OUTER_EYE_OFFSET_MM: (f64, f64) = (26.0, 1.5);
/// Our step 4: the outer eye corner lies this far behind the inner one (scanner depth), mm:
/// the lateral canthus sits back on the side of the face (−6.1 ± 2.5 mm measured on the
/// benchmark). Without it the nearest concave vertex was as often on the upper lid in front
/// of the corner, or round on the temple behind it.
pub const OUTER_EYE_DEPTH_MM: f64 = -6.0;
/// Our step 4: concave vertices further than this behind the inner corner (mm, scanner depth)
/// are not the lateral canthus but the side of the head, the ear or a spike the denoiser
/// left. The canthus lies about 6 mm behind (the depth prior above), so this is a gate, not a
/// preference: the depth term alone let a 90 mm deep region win where it was the only
/// candidate in the box.
pub const OUTER_EYE_MAX_BEHIND_MM: f64 = 20.0;
/// Our step 4: weight of the squared left–right difference of the two outer corners' in-plane
/// offsets from their inner corners, against the squared misses of the average position. 1:
/// natural asymmetry of the canthi (1–2 mm) is of the order of the average position's own
/// spread (lateral 1.5–2.4 mm, up 0.9–1.3 mm on the benchmark's ground truth).
pub const OUTER_EYE_SYMMETRY_WEIGHT: f64 = 1.0;
/// Our step 4: a millimetre of depth off [`OUTER_EYE_DEPTH_MM`] counts this many millimetres
/// of in-plane distance to the prior.
pub const OUTER_EYE_DEPTH_WEIGHT: f64 = 1.5;
/// Where the outer eye corner's fissure is searched around the concave region's point (mm,
/// face frame): from 10 medial to 4 lateral, 2 down to 3 up. Further out laterally or down,
/// the lateral end on real scans ran on along a crease below the canthus.
pub const OUTER_FISSURE_BOX_MM: (f64, f64, f64, f64) = (-10.0, 4.0, 2.0, 3.0);
/// How far below its surroundings' mean depth a vertex of the fissure at the outer corner
/// lies, at least (mm).
pub const OUTER_FISSURE_MIN_DEPTH_MM: f64 = 0.8;
/// The outer fissure's end is the most lateral vertex of its floor: the trench's vertices at
/// least this fraction as deep as its deepest (half depth, as a peak's half-maximum width).
/// Real skin has wrinkles running on laterally from the canthus (crow's feet) that reach
/// the trench's absolute depth threshold but not half the fissure's depth; the generated
/// benchmark's skin has none (measured: docs/measurements.md).
pub const OUTER_FISSURE_FLOOR_FRACTION: f64 = 0.5;
/// An outer fissure end more than this in front of the concave region's point (mm along z)
/// is not taken: it is on the upper lid.
pub const OUTER_FISSURE_MAX_RISE_MM: f64 = 4.0;

impl Detector<'_> {
    /// Step 4, both sides together: per side, the concave vertices of
    /// [`Self::outer_eye_candidates`] score their squared miss of the average outer corner
    /// position; the pair chosen minimises both misses plus [`OUTER_EYE_SYMMETRY_WEIGHT`]
    /// times the squared difference of their in-plane offsets from their own inner corners
    /// (lateral, up): a face is bilaterally symmetric, so the two canthi lie alike beside
    /// their medial ones. A side without candidates is placed at its average position (a
    /// guessed point) and the other side chooses alone. Returns (right, left).
    pub(super) fn outer_eyes(
        &mut self,
        frame: &Frame,
        inner_r: usize,
        inner_l: usize,
    ) -> (usize, usize) {
        let right = self.outer_eye_candidates(frame, inner_r, -1.0);
        let left = self.outer_eye_candidates(frame, inner_l, 1.0);
        let (r, l) = match symmetric_pair(&right, &left) {
            Some((i, j)) => (Some(right.vertices[i]), Some(left.vertices[j])),
            None => (right.nearest(), left.nearest()),
        };
        let mut place = |v: Option<u32>, side: f64, prior: DVec2| match v {
            Some(v) => v as usize,
            None => self.fallback(FeaturePoint::OuterEyeLeft, side, frame, prior),
        };
        (place(r, -1.0, right.prior), place(l, 1.0, left.prior))
    }

    /// Step 4, one side: in a box from the inner corner (Table 2's inner–outer distance), the
    /// vertices of every concave region (`S < 0.3`, curvedness ≥
    /// [`FEATURE_MIN_CURVEDNESS_PER_MM`]) of at least [`OUTER_EYE_MIN_REGION_VERTICES`], each
    /// with its squared miss of the average outer corner position (26 mm out, 1.5 mm up and
    /// [`OUTER_EYE_DEPTH_MM`] behind the inner corner, face frame; depth weighted by
    /// [`OUTER_EYE_DEPTH_WEIGHT`]) and its offset from the inner corner. Changed from the
    /// paper: its `S < 0.5`, `|∂/∂x| ≤ 0.5`, `∇xy < 0.25` region was empty on 1 neutral scan
    /// in 3 (the lateral canthus faces sideways by more than 14°) and its centroid was 8–12 mm
    /// off.
    fn outer_eye_candidates(&self, frame: &Frame, inner: usize, side: f64) -> SideCandidates {
        let q = frame.uv(self.p(inner));
        let s = INSIDE_EYE_TO_OUTSIDE_EYE;
        let au = q.x.abs();
        let bx = side_box(
            side,
            (au + s.min_mm, au + s.max_mm + 6.0),
            (q.y - 12.0, q.y + 10.0),
        );
        let behind_limit_mm = self.p(inner).z - OUTER_EYE_MAX_BEHIND_MM;
        let mask = self.box_mask(frame, bx, |v| {
            self.p(v).z >= behind_limit_mm
                && self.desc.shape_index[v] < OUTER_EYE_CONCAVE_MAX_S
                && self.desc.curvedness_per_mm[v] >= FEATURE_MIN_CURVEDNESS_PER_MM
        });
        let prior = DVec2::new(
            q.x + side * OUTER_EYE_OFFSET_MM.0,
            q.y + OUTER_EYE_OFFSET_MM.1,
        );
        let depth_mm = self.p(inner).z + OUTER_EYE_DEPTH_MM;
        // Every concave region big enough not to be noise competes, not only the biggest:
        // the biggest was as often the temple's hollow or a lid crease cut off from the
        // canthus by a hole (measured below).
        let vertices: Vec<u32> = self
            .regions(&mask)
            .into_iter()
            .filter(|r| r.len() >= OUTER_EYE_MIN_REGION_VERTICES)
            .flatten()
            .collect();
        let (miss_mm2, offset) = vertices
            .iter()
            .map(|&v| {
                let p = self.p(v as usize);
                let uv = frame.uv(p);
                let miss = (uv - prior).length_squared()
                    + (OUTER_EYE_DEPTH_WEIGHT * (p.z - depth_mm)).powi(2);
                (miss, DVec2::new(side * (uv.x - q.x), uv.y - q.y))
            })
            .unzip();
        SideCandidates {
            vertices,
            miss_mm2,
            offset,
            prior,
        }
    }

    /// Step 4's refinement: the lateral end of the lid fissure near the concave region's
    /// point `near` (the lateral canthus is where the trench between the lids ends). The
    /// trench is [`Self::fissure_trench`] in a box [`OUTER_FISSURE_BOX_MM`] around `near`,
    /// with vertices at least [`OUTER_FISSURE_MIN_DEPTH_MM`] deep (shallower creases run on
    /// from the canthus towards the temple); the most lateral vertex of its floor
    /// ([`OUTER_FISSURE_FLOOR_FRACTION`] of its deepest relief) is the corner. No
    /// trench, or a corner more than [`FISSURE_MAX_SHIFT_MM`] from `near` or more than
    /// [`OUTER_FISSURE_MAX_RISE_MM`] in front of it (the upper lid): `near` stays.
    pub(super) fn outer_eye_fissure_end(&self, frame: &Frame, near: usize, side: f64) -> usize {
        let rel = self.lateral_from(frame, near, side);
        let Some(trench) = self.fissure_trench(
            frame,
            near,
            side,
            OUTER_FISSURE_BOX_MM,
            OUTER_FISSURE_MIN_DEPTH_MM,
        ) else {
            return near;
        };
        let floor_mm = OUTER_FISSURE_FLOOR_FRACTION * trench.deepest_mm();
        let corner = trench
            .vertices
            .iter()
            .zip(&trench.relief_mm)
            .filter(|&(_, &r)| r <= floor_mm)
            .map(|(&v, _)| v as usize)
            .max_by(|&a, &b| rel(a).x.total_cmp(&rel(b).x))
            .unwrap_or(near);
        if rel(corner).length() <= FISSURE_MAX_SHIFT_MM
            && self.p(corner).z <= self.p(near).z + OUTER_FISSURE_MAX_RISE_MM
        {
            corner
        } else {
            near
        }
    }
}

/// The pair (right index, left index) of candidates of least summed squared misses plus
/// [`OUTER_EYE_SYMMETRY_WEIGHT`] times the squared difference of their offsets; `None`
/// where a side has none.
fn symmetric_pair(right: &SideCandidates, left: &SideCandidates) -> Option<(usize, usize)> {
    let mut best: Option<(usize, usize, f64)> = None;
    for (i, (qr, mr)) in right.offset.iter().zip(&right.miss_mm2).enumerate() {
        for (j, (ql, ml)) in left.offset.iter().zip(&left.miss_mm2).enumerate() {
            let cost = mr + ml + OUTER_EYE_SYMMETRY_WEIGHT * (*qr - *ql).length_squared();
            if best.is_none_or(|b| cost < b.2) {
                best = Some((i, j, cost));
            }
        }
    }
    best.map(|(i, j, _)| (i, j))
}

/// One side's outer-corner candidates ([`Detector::outer_eye_candidates`]).
struct SideCandidates {
    vertices: Vec<u32>,
    /// Per candidate, its squared miss of the average position, mm².
    miss_mm2: Vec<f64>,
    /// Per candidate, its offset from the inner corner (lateral, up), mm.
    offset: Vec<DVec2>,
    /// The average position in the face frame, mm.
    prior: DVec2,
}

impl SideCandidates {
    /// The candidate nearest the average position, where there is one.
    fn nearest(&self) -> Option<u32> {
        self.vertices
            .iter()
            .zip(&self.miss_mm2)
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map(|(&v, _)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn side(cands: &[(f64, f64)]) -> SideCandidates {
        let prior = DVec2::new(OUTER_EYE_OFFSET_MM.0, OUTER_EYE_OFFSET_MM.1);
        let offset: Vec<DVec2> = cands.iter().map(|&(x, y)| DVec2::new(x, y)).collect();
        SideCandidates {
            vertices: (0..cands.len() as u32).collect(),
            miss_mm2: offset
                .iter()
                .map(|q| (*q - prior).length_squared())
                .collect(),
            offset,
            prior,
        }
    }

    /// A crease below one canthus that lies nearer the average position than that side's
    /// true corner loses to the corner mirroring the other side's; a lone crease is still
    /// taken (symmetry chooses, it does not reject); a side without candidates gives no pair.
    #[test]
    fn the_outer_corners_are_chosen_as_a_mirror_symmetric_pair() {
        // Average position (26, 1.5). Right: the true corner (30, 3.5), miss 4.5 mm, and a
        // crease (29.5, -0.5), miss 4.0 mm. Left: its corner alone, mirroring the right
        // one's offset within 0.5 mm.
        let right = side(&[(30.0, 3.5), (29.5, -0.5)]);
        let left = side(&[(29.6, 3.2)]);
        assert_eq!(right.nearest(), Some(1), "alone, the crease is nearer");
        assert_eq!(symmetric_pair(&right, &left), Some((0, 0)));
        assert_eq!(symmetric_pair(&left, &right), Some((0, 0)));
        let crease = side(&[(29.5, -0.5)]);
        assert_eq!(symmetric_pair(&crease, &left), Some((0, 0)));
        assert_eq!(symmetric_pair(&side(&[]), &left), None);
        assert_eq!(side(&[]).nearest(), None);
    }
}
