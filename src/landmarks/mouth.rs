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

impl Detector<'_> {
    /// Step 6: in a box per side from Table 2's nose-tip-to-mouth range (but at least
    /// [`MOUTH_BELOW_NOSE_CORNERS_MM`] below the nose corners) out to the outer eye corners,
    /// the biggest `S < 0.25` region; the corner is the most lateral of its vertices curved at
    /// least as much as the region's median (the fissure, not a crease running on from it),
    /// near the region's median height ([`MOUTH_CORNER_LINE_WEIGHT`]).
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
        let mut out = [0usize; 2];
        for (k, side) in [-1.0, 1.0].into_iter().enumerate() {
            let lim = if side < 0.0 { -ur } else { ul };
            let bx = side_box(side, (6.0, lim.clamp(20.0, 45.0)), (-t.max_mm - 6.0, top));
            let mask = self.box_mask(frame, bx, |v| self.desc.shape_index[v] < MOUTH_CORNER_MAX_S);
            out[k] = match self.biggest(&mask) {
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
