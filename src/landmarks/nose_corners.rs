//! Step 5: the nose corners (nostril bases).

use super::detector::{Detector, FEATURE_MIN_CURVEDNESS_PER_MM};
use super::frame::{Frame, side_box};
use crate::feature_points::FeaturePoint;
use glam::DVec2;

/// Paper step 5: nose corners: `|∂/∂z| ≤` this …
pub const NOSE_CORNER_MAX_DZ: f64 = 0.5;
/// … and `|∂/∂x| >` this.
pub const NOSE_CORNER_MIN_DX: f64 = 0.65;
/// Our step 5: nose corners (nostril bases) lie in concave regions with `S <` this.
pub const NOSE_CORNER_CONCAVE_MAX_S: f64 = 0.3;
/// Our step 5: typical nostril-base position relative to the nose tip (out, up), mm: half
/// an alar base width of ~25 mm, 15 mm below the tip (also the benchmark's mean). The nose
/// corner is the region vertex nearest the midpoint of the region's centroid and this
/// (closer to the benchmark's corners than the centroid alone: docs/measurements.md).
pub const NOSE_CORNER_OFFSET_MM: (f64, f64) = (12.0, -15.0);

impl Detector<'_> {
    /// Step 5: the benchmark's nose corners (iBUG 31/35) are the nostril bases, where the
    /// ala meets the upper lip — a concave crease — not the widest points of the alae that
    /// the paper's `|∂/∂z| ≤ 0.5`, `|∂/∂x| > 0.65` region gives (measured 9.5 mm off, 6.7 mm
    /// too high). Here: the biggest concave region (`S < 0.3`, curvedness ≥
    /// [`FEATURE_MIN_CURVEDNESS_PER_MM`]) in a box 5–20 mm beside and 8–24 mm below the nose
    /// tip, its vertex nearest the midpoint of its centroid and [`NOSE_CORNER_OFFSET_MM`].
    pub(super) fn nose_corner(&mut self, frame: &Frame, side: f64) -> usize {
        let bx = side_box(side, (5.0, 20.0), (-24.0, -8.0));
        let mask = self.box_mask(frame, bx, |v| {
            self.desc.shape_index[v] < NOSE_CORNER_CONCAVE_MAX_S
                && self.desc.curvedness_per_mm[v] >= FEATURE_MIN_CURVEDNESS_PER_MM
        });
        match self.biggest(&mask) {
            Some(r) => {
                let c = frame.uv(self.p(self.centroid_vertex(&r)));
                let prior = DVec2::new(side * NOSE_CORNER_OFFSET_MM.0, NOSE_CORNER_OFFSET_MM.1);
                let t = (c + prior) * 0.5;
                self.most(&r, |p| -(frame.uv(p) - t).length())
            }
            None => self.fallback(
                FeaturePoint::NoseCornerLeft,
                side,
                frame,
                DVec2::new(side * NOSE_CORNER_OFFSET_MM.0, NOSE_CORNER_OFFSET_MM.1),
            ),
        }
    }
}
