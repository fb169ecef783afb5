//! Step 9: the chin border.

use super::detector::Detector;
use super::frame::Frame;
use super::table2::NOSE_TIP_TO_CHIN;
use crate::feature_points::FeaturePoint;
use glam::DVec2;

/// Paper step 9: the chin is a region with `S >` this …
pub const CHIN_MIN_S: f64 = 0.85;
/// … and `∇xy <` this.
pub const CHIN_MAX_GRAD_XY: f64 = 0.3;
/// Our step 9: the chin walk starts this far below the mouth line, mm (below the lower lip),
/// from every strip vertex in the [`CHIN_WALK_SEED_BAND_MM`] below that.
pub const CHIN_WALK_START_BELOW_MOUTH_MM: f64 = 12.0;
/// Our step 9: the walk goes no lower than Table 2's largest nose-tip-to-chin distance plus
/// this, mm: enough for an open-mouthed laugh's chin, too little for a walk round a hole
/// under the chin to reach the neck (docs/measurements.md).
pub const CHIN_WALK_MARGIN_MM: f64 = 10.0;
/// Our step 9: height of the band of walk seeds, mm. 20 mm reaches the lower lip of an open
/// mouth (laugh), whose cavity would otherwise trap the walk.
pub const CHIN_WALK_SEED_BAND_MM: f64 = 20.0;
/// Our step 9: the chin is the reached vertex furthest in the direction `(0, −1, this)`
/// (face frame `v`, scan `z`): down *and forward*, so a neck joined to the chin (no depth
/// jump) does not win by being lower. 1.0 rather than the slightly more accurate 0.8, with
/// which more walks ran on under the jaw (docs/measurements.md).
pub const CHIN_FORWARD_WEIGHT: f64 = 1.0;
/// Our step 9: the chin walk passes vertices whose mesh normal has `n_z >` this.
pub const CHIN_WALK_MIN_NZ: f64 = 0.5;

impl Detector<'_> {
    /// Step 9: walk down a 16 mm wide strip from below the lower lip (centred between the
    /// mouth corners; seeds: every strip vertex 12–32 mm below the mouth line), along mesh
    /// edges, through vertices whose **mesh** normal faces the scanner
    /// (`n_z > 0.5`); the chin is the reached vertex furthest down-and-forward
    /// ([`CHIN_FORWARD_WEIGHT`]), less half its distance from the strip's centre line. The scan's chin–neck depth jump, or the underside turning
    /// away, ends the walk. Changed from the paper (the lowest point of the biggest
    /// `S > 0.85`, `∇xy < 0.3` region): that region is the front of the chin, ~10 mm above
    /// the jaw-contour chin point (iBUG 8) of the benchmark. The mesh normal is used, not the
    /// fitted one: the 5-ring fit smooths normals across the chin's rim and lets the walk
    /// run on down the neck.
    pub(super) fn chin(&mut self, frame: &Frame, mid_u: f64, mouth_v: f64) -> usize {
        let lowest = -NOSE_TIP_TO_CHIN.max_mm - CHIN_WALK_MARGIN_MM;
        // Start below the lower lip (whose underside faces down and would end the walk).
        let (top, band) = (
            mouth_v - CHIN_WALK_START_BELOW_MOUTH_MM,
            CHIN_WALK_SEED_BAND_MM,
        );
        let in_strip = |v: usize| {
            let q = frame.uv(self.p(v));
            (q.x - mid_u).abs() <= 8.0 && q.y <= top && q.y >= lowest
        };
        let key: Vec<f64> = (0..self.mesh.vertex_count())
            .map(|v| {
                let inside = in_strip(v) && self.mesh.normals[v].z > CHIN_WALK_MIN_NZ;
                if inside {
                    -frame.uv(self.p(v)).y
                } else {
                    f64::NAN
                }
            })
            .collect();
        let score = |v: usize| {
            key[v] - 0.5 * (frame.uv(self.p(v)).x - mid_u).abs()
                + CHIN_FORWARD_WEIGHT * (self.p(v).z - frame.origin.z)
        };
        match self.strip_walk_by(&key, band, score) {
            Some(v) => v,
            None => self.fallback(
                FeaturePoint::Chin,
                0.0,
                frame,
                DVec2::new(mid_u, -NOSE_TIP_TO_CHIN.avg_mm),
            ),
        }
    }
}
