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
/// Our step 7: the steps of the walk out along the strip, mm (about one scan sample).
pub const CHEEK_PROFILE_BIN_MM: f64 = 1.5;

impl Detector<'_> {
    /// Step 7: in a strip [`CHEEK_STRIP_HALF_MM`] high at the nose tip's height, from 5 mm
    /// inside the outer eye corner outwards to the first gap ([`CHEEK_STRIP_GAP_MM`]), the
    /// first place where the cheek turns away from the scanner: walking out in
    /// [`CHEEK_PROFILE_BIN_MM`] steps, the first step where at least half the strip's vertices
    /// have `|∂/∂z| ≤` [`CHEEK_MAX_DZ`]; the border is that step's turned vertex nearest the
    /// nose tip's height. (A profile, not the biggest connected region: in a strip two or three
    /// vertices high, connectivity flips with a tenth of a degree of head roll and moved the
    /// point 5–60 mm.) Where the scan ends before the cheek turns, the strip's most lateral
    /// vertex (the data's border). Changed from the paper, whose centroid of the
    /// `|∂/∂z| ≤ 0.4` region anywhere between the eyes' and mouth's heights landed at eye
    /// height on one side and mouth height on the other on half the real scans, and further
    /// out than the generic face's cheek point (the cheek at the nose tip's height, 12 % of
    /// the outer-eye distance beyond the outer eye corner:
    /// [`crate::registration::truth_points`]). (The pipeline still registers without
    /// detected cheeks, [`FeaturePoint::BORDER`].)
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
            across.truncate(k + 1);
        }
        // Steps of the walk: fixed bins from the strip's start (5 mm inside the outer corner).
        let turned = |v: usize| self.desc.dz(v) <= CHEEK_MAX_DZ;
        let bin_of = |u: f64| ((u - (au - 5.0)) / CHEEK_PROFILE_BIN_MM).floor() as i64;
        let mut start = 0;
        while start < across.len() {
            let bin = bin_of(across[start].0);
            let end = start + across[start..].partition_point(|&(u, _)| bin_of(u) == bin);
            let in_bin = &across[start..end];
            let (n_turned, best) = in_bin.iter().filter(|&&(_, v)| turned(v)).fold(
                (0, None::<(f64, usize)>),
                |(n, best), &(_, v)| {
                    let height = frame.uv(self.p(v)).y.abs();
                    let nearer = best.is_none_or(|(h, _)| height < h);
                    (n + 1, if nearer { Some((height, v)) } else { best })
                },
            );
            if let Some((_, v)) = best.filter(|_| 2 * n_turned >= in_bin.len()) {
                return v;
            }
            start = end;
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
