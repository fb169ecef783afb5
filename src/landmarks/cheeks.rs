//! Step 7: the cheek borders.

use super::detector::Detector;
use super::frame::{Frame, side_box};
use crate::feature_points::FeaturePoint;
use glam::DVec2;

/// Paper step 7: cheek borders are regions with `|∂/∂z| ≤` this.
pub const CHEEK_MAX_DZ: f64 = 0.7;
/// Our step 7: half the height of the strip at the nose tip's height the cheek border is
/// sought in, mm (the scan grid is ~1.5 mm).
pub const CHEEK_STRIP_HALF_MM: f64 = 1.5;
/// Our step 7: walking out along the strip, a gap wider than this (mm, across) ends the face:
/// beyond it lie an ear, hair or a shoulder, not the cheek (scan spacing is 1–3 mm).
pub const CHEEK_STRIP_GAP_MM: f64 = 6.0;

impl Detector<'_> {
    /// Step 7: in a strip [`CHEEK_STRIP_HALF_MM`] high at the nose tip's height, from 5 mm
    /// inside the outer eye corner outwards to the first gap ([`CHEEK_STRIP_GAP_MM`]), the
    /// biggest region of vertices turned away from the scanner (`|∂/∂z| ≤`
    /// [`CHEEK_MAX_DZ`]); the border is its most medial vertex, where
    /// the cheek turns. Where the scan ends before the cheek turns, the strip's most lateral
    /// vertex (the data's border). Changed from the paper, whose centroid of the `|∂/∂z| ≤ 0.4`
    /// region anywhere between the eyes' and mouth's heights landed at eye height on one side
    /// and mouth height on the other on half the real scans, and further out than the generic
    /// face's cheek point (the cheek at the nose tip's height, 12 % of the outer-eye distance
    /// beyond the outer eye corner: [`crate::registration::truth_points`]). (The pipeline
    /// still registers without detected cheeks, [`FeaturePoint::BORDER`].)
    pub(super) fn cheek(&mut self, frame: &Frame, outer: usize, side: f64) -> usize {
        let au = frame.uv(self.p(outer)).x.abs();
        let h = CHEEK_STRIP_HALF_MM;
        let mut strip = self.box_mask(
            frame,
            side_box(side, (au - 5.0, au + 60.0), (-h, h)),
            |_| true,
        );
        // Only the part of the strip continuous with the face, out to its first gap.
        let mut across: Vec<(f64, usize)> = (0..strip.len())
            .filter(|&v| strip[v])
            .map(|v| (frame.uv(self.p(v)).x.abs(), v))
            .collect();
        across.sort_by(|a, b| a.0.total_cmp(&b.0));
        if let Some(k) = across
            .windows(2)
            .position(|w| w[1].0 - w[0].0 > CHEEK_STRIP_GAP_MM)
        {
            for &(_, v) in &across[k + 1..] {
                strip[v] = false;
            }
        }
        let turned: Vec<bool> = (0..strip.len())
            .map(|v| strip[v] && self.desc.dz(v) <= CHEEK_MAX_DZ)
            .collect();
        if let Some(r) = self.biggest(&turned) {
            return self.most(&r, |p| -frame.uv(p).x.abs());
        }
        let strip: Vec<u32> = (0..strip.len() as u32)
            .filter(|&v| strip[v as usize])
            .collect();
        if strip.is_empty() {
            return self.fallback(
                FeaturePoint::CheekLeft,
                side,
                frame,
                DVec2::new(side * (au + 12.0), 0.0),
            );
        }
        self.most(&strip, |p| frame.uv(p).x.abs())
    }
}
