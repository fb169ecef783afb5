//! Step 3: the inner eye corners, checked against the symmetry line, then moved to the
//! medial end of their lid fissures.

use super::detector::{Detector, FEATURE_MIN_CURVEDNESS_PER_MM};
use super::frame::{Frame, side_box, side_name};
use super::table2::{NOSE_TIP_TO_INSIDE_EYE, NOSE_TIP_TO_NOSE_BRIDGE};
use crate::feature_points::FeaturePoint;
use crate::{Error, Result};
use glam::DVec2;

/// Paper step 3: inner eye corners are regions with `S ≤` this.
pub const INNER_EYE_MAX_S: f64 = 0.25;
/// Our step 3: an inner-corner pair whose roll differs from the face's symmetry roll by more
/// than this, degrees, is checked against the other concave regions of the boxes (on the
/// benchmark the detected pair differs from the symmetry roll by up to 9°) ...
pub const INNER_EYE_ROLL_TOLERANCE_DEG: f64 = 10.0;
/// ... and replaced only by a pair within this of the symmetry roll, degrees.
pub const INNER_EYE_ROLL_ACCEPT_DEG: f64 = 5.0;
/// Our step 3: how many of the biggest concave regions per side may be the inner corner.
pub const INNER_EYE_CANDIDATE_REGIONS: usize = 4;
/// How far below its surroundings' mean depth a vertex of the fissure lies, at least (mm).
pub const FISSURE_MIN_DEPTH_MM: f64 = 0.5;
/// Where the fissure is searched around the concave region's point (mm, face frame):
/// from 6 medial to 16 lateral, 9 down to 6 up.
pub const FISSURE_BOX_MM: (f64, f64, f64, f64) = (-6.0, 16.0, 9.0, 6.0);
/// The fissure's vertices within this of its deepest z (mm) are its floor.
pub const FISSURE_DEPTH_BAND_MM: f64 = 3.0;
/// A fissure end further than this from the concave region's point (mm) is not taken.
pub const FISSURE_MAX_SHIFT_MM: f64 = 8.0;
/// … nor one more than this in front of it (mm along z): the canthus is the deepest part
/// of the corner, and the trenches that are not the fissure (the lid crease above it, the
/// fold beside the nose bridge) lie higher.
pub const FISSURE_MAX_RISE_MM: f64 = 1.0;
/// … nor one more than this medial of it (mm): the concave region's point errs medially
/// (towards the nose bridge), and on real scans the trenches medial of it were the hollow
/// beside the nose.
pub const FISSURE_MAX_MEDIAL_MM: f64 = 1.0;
/// How much less symmetric than the most symmetric choice a pair of refined inner corners
/// may be (mm; see `inner_eyes_at_fissures`).
pub const FISSURE_SYMMETRY_SLACK_MM: f64 = 1.5;
/// A corner whose side alone found its fissure end moves there, whatever the symmetry, if
/// that end lies no more than this above its pit (mm, face frame): the pit errs into the
/// hollow between nose bridge and eye, which lies medial of and above the canthus (on both
/// sides alike, so a pair of such pits looks symmetric), and the correction runs laterally
/// and down; a lone end above the pit is the upper lid's margin or crease.
pub const FISSURE_LONE_MAX_UP_MM: f64 = 1.0;

impl Detector<'_> {
    /// Step 3 for both sides: [`Self::inner_eye_candidates`] per side, the biggest region's
    /// point each. Where the face's symmetry roll is known ([`Self::symmetry_roll`]) and that
    /// pair's roll differs from it by more than [`INNER_EYE_ROLL_TOLERANCE_DEG`], the pair of
    /// candidates whose roll is nearest it is taken instead if it is within
    /// [`INNER_EYE_ROLL_ACCEPT_DEG`], with a warning: on real scans a lid crease or a hole's
    /// rim was the bigger region on one side and tilted the whole face frame by 20°, which
    /// then lost the mouth and nose corners too. A side without candidates falls back (with a
    /// warning) to Table 2's average inner-corner position, so one missing eye does not lose
    /// the whole face.
    pub(super) fn inner_eyes(
        &mut self,
        frame: &Frame,
        symmetry_roll: Option<f64>,
    ) -> (usize, usize) {
        let mut side_candidates = |side: f64| match self.inner_eye_candidates(frame, side) {
            Ok(c) => c,
            Err(e) => {
                self.warnings.push(e.to_string());
                let at = DVec2::new(
                    side * NOSE_TIP_TO_INSIDE_EYE.avg_mm,
                    NOSE_TIP_TO_NOSE_BRIDGE.avg_mm,
                );
                vec![self.fallback(FeaturePoint::InnerEyeLeft, side, frame, at)]
            }
        };
        let right = side_candidates(-1.0);
        let left = side_candidates(1.0);
        let Some(symmetry) = symmetry_roll else {
            return (right[0], left[0]);
        };
        let off = |r: usize, l: usize| (self.eye_line_roll(r, l) - symmetry).abs();
        let tolerance = INNER_EYE_ROLL_TOLERANCE_DEG.to_radians();
        if off(right[0], left[0]) <= tolerance {
            return (right[0], left[0]);
        }
        let (r, l) = right
            .iter()
            .flat_map(|&r| left.iter().map(move |&l| (r, l)))
            .min_by(|a, b| off(a.0, a.1).total_cmp(&off(b.0, b.1)))
            .filter(|&(r, l)| off(r, l) <= INNER_EYE_ROLL_ACCEPT_DEG.to_radians())
            .unwrap_or((right[0], left[0]));
        if (r, l) != (right[0], left[0]) {
            self.warnings.push(format!(
                "inner eye corners: the biggest concave regions tilt the eye line {:.1}° against \
                 the face's symmetry line ({:.1}°); took the regions that tilt it {:.1}°",
                self.eye_line_roll(right[0], left[0]).to_degrees(),
                symmetry.to_degrees(),
                self.eye_line_roll(r, l).to_degrees()
            ));
        }
        (r, l)
    }

    /// Step 3, one side: the concave regions (`S ≤ 0.25`, curvedness ≥
    /// [`FEATURE_MIN_CURVEDNESS_PER_MM`], which drops shape-index noise on flat skin) in a box
    /// set by Table 2, biggest first (at most [`INNER_EYE_CANDIDATE_REGIONS`], none under a
    /// quarter of the biggest's size); each region's point is its deepest vertex within 3 mm
    /// (xy) of its centroid (closer on the benchmark than the region's deepest or most
    /// cup-like vertex, or the vertex nearest the centroid: docs/measurements.md).
    fn inner_eye_candidates(&self, frame: &Frame, side: f64) -> Result<Vec<usize>> {
        let t = NOSE_TIP_TO_INSIDE_EYE;
        let b = NOSE_TIP_TO_NOSE_BRIDGE;
        let bx = side_box(
            side,
            (t.min_mm - 7.0, t.max_mm + 7.0),
            (b.min_mm - 8.0, b.max_mm + 4.0),
        );
        let mask = self.box_mask(frame, bx, |v| {
            self.desc.shape_index[v] <= INNER_EYE_MAX_S
                && self.desc.curvedness_per_mm[v] >= FEATURE_MIN_CURVEDNESS_PER_MM
        });
        let mut regions = self.regions(&mask);
        regions.sort_by_key(|r| std::cmp::Reverse(r.len()));
        let Some(biggest) = regions.first().map(Vec::len) else {
            return Err(Error::algorithm(
                "landmarks: inner eye corners",
                format!(
                    "no concave region (S ≤ {INNER_EYE_MAX_S}) beside the nose bridge on the subject's {}",
                    side_name(side)
                ),
            ));
        };
        // The centroid lies on the region's flank; the canthus is the pit: the deepest
        // vertex within 3 mm (xy) of the centroid. Where the biggest region is the hollow
        // between nose bridge and eye, `inner_eye_fissure_end` moves the point to the lid
        // fissure. (Other searches tried: docs/measurements.md.)
        Ok(regions
            .iter()
            .take(INNER_EYE_CANDIDATE_REGIONS)
            .filter(|r| r.len() * 4 >= biggest)
            .map(|region| {
                let c = self.p(self.centroid_vertex(region));
                self.most(region, |p| {
                    if (p - c).truncate().length() < 3.0 {
                        -p.z
                    } else {
                        f64::MIN
                    }
                })
            })
            .collect())
    }

    /// Step 3's refinement, both sides: each inner corner moves to its lid fissure's medial
    /// end ([`Self::inner_eye_fissure_end`]) where that keeps the pair symmetric: of the
    /// pairs with both, one or neither side moved, the first (in that order) whose mirror
    /// asymmetry (|u_left + u_right| + |v_left − v_right| in the face frame, mm) is within
    /// [`FISSURE_SYMMETRY_SLACK_MM`] of the least. On real scans with open eyes a trench
    /// beside the eyeball on one side only moved that corner 5–7 mm off its mirror image.
    /// The exception: where only one side found an end and it lies at most
    /// [`FISSURE_LONE_MAX_UP_MM`] above its pit, that side moves (the other pit is no
    /// evidence against it: both pits err alike, into the hollows beside the nose bridge).
    pub(super) fn inner_eyes_at_fissures(
        &self,
        frame: &Frame,
        right: usize,
        left: usize,
    ) -> (usize, usize) {
        let fr = self.inner_eye_fissure_end(frame, right, -1.0);
        let fl = self.inner_eye_fissure_end(frame, left, 1.0);
        let up = |pit: usize, end: usize| self.lateral_from(frame, pit, 1.0)(end).y;
        match (fr != right, fl != left) {
            (true, false) if up(right, fr) <= FISSURE_LONE_MAX_UP_MM => return (fr, left),
            (false, true) if up(left, fl) <= FISSURE_LONE_MAX_UP_MM => return (right, fl),
            _ => {}
        }
        let asymmetry = |(r, l): (usize, usize)| {
            let (qr, ql) = (frame.uv(self.p(r)), frame.uv(self.p(l)));
            (qr.x + ql.x).abs() + (qr.y - ql.y).abs()
        };
        let pairs = [(fr, fl), (fr, left), (right, fl), (right, left)].map(|p| (p, asymmetry(p)));
        let least = pairs.iter().map(|&(_, a)| a).fold(f64::MAX, f64::min);
        pairs
            .into_iter()
            .find(|&(_, a)| a <= least + FISSURE_SYMMETRY_SLACK_MM)
            .map_or((right, left), |(p, _)| p)
    }

    /// Step 3's refinement: the medial end of the lid fissure near the concave region's
    /// point `near` ([`Self::fissure_trench`] in a box [`FISSURE_BOX_MM`] around it: lateral
    /// from, lateral to, down, up; face frame). Of the trench's vertices within
    /// [`FISSURE_DEPTH_BAND_MM`] of its deepest z (its medial end otherwise climbs the nose's
    /// side wall) the most medial is the corner. No trench, or a corner more than
    /// [`FISSURE_MAX_SHIFT_MM`] from `near`, more than [`FISSURE_MAX_MEDIAL_MM`] medial of it
    /// or more than [`FISSURE_MAX_RISE_MM`] in front of it: `near` stays.
    fn inner_eye_fissure_end(&self, frame: &Frame, near: usize, side: f64) -> usize {
        let rel = self.lateral_from(frame, near, side);
        let Some(trench) =
            self.fissure_trench(frame, near, side, FISSURE_BOX_MM, FISSURE_MIN_DEPTH_MM)
        else {
            return near;
        };
        let trench = trench.vertices;
        let z_min = trench
            .iter()
            .map(|&v| self.p(v as usize).z)
            .fold(f64::MAX, f64::min);
        let corner = trench
            .iter()
            .map(|&v| v as usize)
            .filter(|&v| self.p(v).z <= z_min + FISSURE_DEPTH_BAND_MM)
            .min_by(|&a, &b| rel(a).x.total_cmp(&rel(b).x))
            .unwrap_or(near);
        if rel(corner).length() <= FISSURE_MAX_SHIFT_MM
            && rel(corner).x >= -FISSURE_MAX_MEDIAL_MM
            && self.p(corner).z <= self.p(near).z + FISSURE_MAX_RISE_MM
        {
            corner
        } else {
            near
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::detector::TestSurface;
    use crate::test_support::grid;
    use glam::DVec3;

    /// The nose tip of the test surface (grid coordinates, mm).
    const TIP: DVec3 = DVec3::new(50.0, 20.0, 0.0);

    /// Step 3's refinement on a flat face (face frame: nose tip at [`TIP`], no roll) with
    /// one lid fissure, a groove 2 mm deep running from 20 to 32 mm right of the midline at
    /// height `fissure_v` (mm above the tip), and no fissure on the left. Both pits lie
    /// 16 mm beside the midline, 33 mm up (the hollows beside the nose bridge). Returns the
    /// refined right and left corners, face frame.
    fn refined(fissure_v: f64) -> (DVec2, DVec2) {
        let groove = |u: f64, v: f64| {
            // How far beyond the groove's ends, mm.
            let beyond = (u + 20.0).max(0.0) + (-32.0 - u).max(0.0);
            -2.0 * (-(v - fissure_v).powi(2) / 1.28).exp() * (-beyond.powi(2)).exp()
        };
        let surface = TestSurface::new(grid(101, 61, |x, y| groove(x - TIP.x, y - TIP.y)));
        let detector = surface.detector();
        let frame = Frame::new(TIP, 0.0);
        let at = |u: f64, v: f64| ((TIP.y + v) as usize) * 101 + (TIP.x + u) as usize;
        let (r, l) = detector.inner_eyes_at_fissures(&frame, at(-16.0, 33.0), at(16.0, 33.0));
        (frame.uv(detector.p(r)), frame.uv(detector.p(l)))
    }

    /// A fissure end found on one side only moves that corner when it lies below its pit
    /// (lateral and down of the hollow, where the canthus is), although the pair becomes
    /// less symmetric; one above the pit (an upper lid's crease) does not move it.
    #[test]
    fn a_lone_fissure_end_below_the_pit_moves_the_corner_and_one_above_does_not() {
        let (r, l) = refined(30.0);
        assert!(
            (r - DVec2::new(-20.0, 30.0)).length() <= 1.5,
            "right corner at {r}, the fissure's medial end at (-20, 30)"
        );
        assert_eq!(l, DVec2::new(16.0, 33.0), "the left pit has no fissure");
        let (r, l) = refined(36.0);
        assert_eq!(
            r,
            DVec2::new(-16.0, 33.0),
            "an end above the pit: the pit stays"
        );
        assert_eq!(l, DVec2::new(16.0, 33.0));
    }
}
