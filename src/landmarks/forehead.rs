//! Step 8: the forehead border.

use super::detector::Detector;
use super::frame::Frame;
use super::table2::TOP_OF_HEAD_TO_NOSE_TIP;
use crate::feature_points::FeaturePoint;
use glam::DVec2;

/// Paper step 8: the forehead's upper border is where `|∂/∂z| >` this ends.
pub const FOREHEAD_MIN_DZ: f64 = 0.6;
/// Our step 8: hair is rough; the forehead walk passes vertices with curvedness below
/// this, 1/mm (checked by eye on the real GavabDB scans: stops at the hairline on all).
pub const FOREHEAD_MAX_CURVEDNESS_PER_MM: f64 = 0.06;

impl Detector<'_> {
    /// Step 8: walk up a 16 mm midline strip, along mesh edges, through smooth front-facing
    /// skin (`|∂/∂z| > 0.6` as the paper, curvedness below
    /// [`FOREHEAD_MAX_CURVEDNESS_PER_MM`]); seeds are all strip vertices 20–35 mm above the
    /// eyes (mid-forehead, so brows and the nasion do not stop the walk). The highest vertex
    /// reached is the forehead border: the hairline (a data gap, or hair, which is rough).
    pub(super) fn forehead(
        &mut self,
        frame: &Frame,
        face: &[bool],
        mid_u: f64,
        eye_v: f64,
    ) -> usize {
        let top = TOP_OF_HEAD_TO_NOSE_TIP.max_mm;
        let key: Vec<f64> = (0..self.mesh.vertex_count())
            .map(|v| {
                let q = frame.uv(self.p(v));
                let inside = face[v]
                    && self.desc.dz(v) > FOREHEAD_MIN_DZ
                    && self.desc.curvedness_per_mm[v] < FOREHEAD_MAX_CURVEDNESS_PER_MM
                    && (q.x - mid_u).abs() <= 8.0
                    && q.y >= eye_v + 20.0
                    && q.y <= top;
                if inside { q.y } else { f64::NAN }
            })
            .collect();
        match self.strip_walk_by(&key, 15.0, |v| key[v]) {
            Some(v) => v,
            None => self.fallback(
                FeaturePoint::Forehead,
                0.0,
                frame,
                DVec2::new(mid_u, TOP_OF_HEAD_TO_NOSE_TIP.min_mm * 0.7),
            ),
        }
    }
}
