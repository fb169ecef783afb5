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
/// Our step 8: the steps of the walk up the midline strip, mm (about one scan sample).
pub const FOREHEAD_PROFILE_BIN_MM: f64 = 2.0;
/// Our step 8: a band of rough or missing steps at most this high, mm, does not end the
/// forehead (a deep forehead wrinkle is 2–4 mm; hair and the scan's edge go on).
pub const FOREHEAD_MAX_GAP_MM: f64 = 4.0;

impl Detector<'_> {
    /// Step 8: walk up a 16 mm midline strip of the face in [`FOREHEAD_PROFILE_BIN_MM`]
    /// steps from 20 mm above the eyes (mid-forehead, so brows and the nasion do not stop the
    /// walk), through steps where at least half the strip's vertices are smooth front-facing
    /// skin (`|∂/∂z| > 0.6` as the paper, curvedness below
    /// [`FOREHEAD_MAX_CURVEDNESS_PER_MM`]); the walk may start anywhere up to 35 mm above the
    /// eyes and ends where more than [`FOREHEAD_MAX_GAP_MM`] of steps are not (the hairline: a
    /// data gap, or hair, which is rough; not a wrinkle). The border is the last skin step's skin vertex nearest the midline. (A profile,
    /// not a walk along mesh edges: one vertex more or less joined the hair to the forehead
    /// under a half-degree change of the frame and moved the point 15 mm.)
    pub(super) fn forehead(
        &mut self,
        frame: &Frame,
        face: &[bool],
        mid_u: f64,
        eye_v: f64,
    ) -> usize {
        let top = TOP_OF_HEAD_TO_NOSE_TIP.max_mm;
        let bottom = eye_v + 20.0;
        let bins = ((top - bottom) / FOREHEAD_PROFILE_BIN_MM).ceil().max(0.0) as usize;
        // Per step: strip vertices, and the skin vertex nearest the midline.
        let mut count = vec![0usize; bins];
        let mut skin = vec![0usize; bins];
        let mut nearest: Vec<Option<(f64, usize)>> = vec![None; bins];
        for v in 0..self.mesh.vertex_count() {
            let q = frame.uv(self.p(v));
            if !face[v] || (q.x - mid_u).abs() > 8.0 || q.y < bottom || q.y >= top {
                continue;
            }
            let b = (((q.y - bottom) / FOREHEAD_PROFILE_BIN_MM) as usize).min(bins - 1);
            count[b] += 1;
            if self.desc.dz(v) > FOREHEAD_MIN_DZ
                && self.desc.curvedness_per_mm[v] < FOREHEAD_MAX_CURVEDNESS_PER_MM
            {
                skin[b] += 1;
                let off = (q.x - mid_u).abs();
                if nearest[b].is_none_or(|(o, _)| off < o) {
                    nearest[b] = Some((off, v));
                }
            }
        }
        let is_skin = |b: usize| count[b] > 0 && 2 * skin[b] >= count[b];
        let start_bins = (15.0 / FOREHEAD_PROFILE_BIN_MM).ceil() as usize;
        let border = (0..bins.min(start_bins))
            .find(|&b| is_skin(b))
            .map(|first| {
                // Up through skin steps; a run of non-skin steps no longer than
                // FOREHEAD_MAX_GAP_MM (a wrinkle) does not end the forehead.
                let max_gap = (FOREHEAD_MAX_GAP_MM / FOREHEAD_PROFILE_BIN_MM).round() as usize;
                let (mut last, mut gap) = (first, 0);
                for b in first + 1..bins {
                    if is_skin(b) {
                        (last, gap) = (b, 0);
                    } else {
                        gap += 1;
                        if gap > max_gap {
                            break;
                        }
                    }
                }
                nearest[last].map(|(_, v)| v)
            });
        match border.flatten() {
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
