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
/// Our step 9: a chin found within this of the walk's lowest line (mm) is at the search's
/// edge, not at a tangent point: the profile below the chin never turned more than 45° back
/// from vertical (a chin running smoothly into the neck), so down-and-forward grew all the
/// way to where the walk was cut off. About three rows of a GavabDB scan (1.5–2 mm): the
/// strip's centre-line penalty and the rows' spacing left such a winner up to 3.6 mm above
/// the line on the benchmark.
pub const CHIN_AT_LIMIT_MM: f64 = 5.0;
/// Our step 9: then the chin is the reached vertex furthest in `(0, −1, this)`: the tangent
/// point of a line atan(1/2) = 27° back from vertical, on the bend between the chin's front
/// (vertical) and an underside sloping back less than 45°.
pub const CHIN_SHALLOW_FORWARD_WEIGHT: f64 = 2.0;
/// Our step 9: the chin lies at least this far below the mouth line, mm: below the lower lip,
/// whose height (stomion to the labiomental fold, sto–sl) is 20.7 ± 1.1 mm in women and
/// 22.5 ± 1.9 mm in men (J Korean Assoc Maxillofac Plast Reconstr Surg 2019, 41:9, table 9;
/// the chin's lowest point, menton, 52–56 mm). A reached vertex higher up is the lower lip,
/// which a puckered or pushed-out mouth brings as far forward as the chin is low.
pub const CHIN_MIN_BELOW_MOUTH_MM: f64 = 20.0;
/// Our step 9: the chin walk passes vertices whose mesh normal has `n_z >` this.
pub const CHIN_WALK_MIN_NZ: f64 = 0.5;

impl Detector<'_> {
    /// Step 9: walk down a 16 mm wide strip from below the lower lip (centred between the
    /// mouth corners; seeds: every strip vertex 12–32 mm below the mouth line), along mesh
    /// edges, through vertices whose **mesh** normal faces the scanner
    /// (`n_z > 0.5`); the chin is the reached vertex furthest down-and-forward
    /// ([`CHIN_FORWARD_WEIGHT`]) of those at least [`CHIN_MIN_BELOW_MOUTH_MM`] below the mouth
    /// line (none: not found), less half its distance from the strip's centre line; where
    /// that is within [`CHIN_AT_LIMIT_MM`] of the walk's lowest line, the vertex furthest
    /// along [`CHIN_SHALLOW_FORWARD_WEIGHT`] instead. The scan's chin–neck depth jump, or the
    /// underside turning away, ends the walk. Changed from the paper (the lowest point of the
    /// biggest `S > 0.85`, `∇xy < 0.3` region): that region is the front of the chin, ~10 mm
    /// above the jaw-contour chin point (iBUG 8) of the benchmark. The mesh normal is used, not the
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
        let score = |v: usize, forward: f64| {
            key[v] - 0.5 * (frame.uv(self.p(v)).x - mid_u).abs()
                + forward * (self.p(v).z - frame.origin.z)
        };
        // The vertex of `reached` with the largest score; the earliest reached wins ties.
        let furthest = |reached: &[usize], forward: f64| {
            (reached.iter().copied()).fold(reached[0], |best, v| {
                if score(v, forward) > score(best, forward) {
                    v
                } else {
                    best
                }
            })
        };
        let at_limit = |v: usize| frame.uv(self.p(v)).y < lowest + CHIN_AT_LIMIT_MM;
        // The reached vertices below the lower lip ([`CHIN_MIN_BELOW_MOUTH_MM`]).
        let below_lip = |v: &usize| frame.uv(self.p(*v)).y <= mouth_v - CHIN_MIN_BELOW_MOUTH_MM;
        let reached = (self.strip_walk(&key, band))
            .map(|r| r.into_iter().filter(below_lip).collect::<Vec<_>>())
            .filter(|r| !r.is_empty());
        let chin = reached.map(|reached| match furthest(&reached, CHIN_FORWARD_WEIGHT) {
            v if at_limit(v) => furthest(&reached, CHIN_SHALLOW_FORWARD_WEIGHT),
            v => v,
        });
        match chin {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::detector::TestSurface;
    use crate::test_support::grid;
    use glam::DVec3;

    /// The chin of a profile surface (face frame: nose tip at the origin, y up, facing +z; the
    /// mouth line at y = −50 mm): the chin's front at z = −20 mm down to y = −80 mm, then a
    /// 3 mm-wide bend into an underside receding `degrees` from vertical, and a lower lip
    /// pushed `lip_mm` forward of the chin's front 12 mm below the mouth line (a Gaussian
    /// ridge, σ 4 mm); 60 mm wide, from y = −40 to −130 mm.
    fn chin_of_profile(degrees: f64, lip_mm: f64) -> f64 {
        let r = 3.0;
        let slope = degrees.to_radians().tan();
        let z = |y: f64| {
            -20.0 - slope * r * ((-80.0 - y) / r).exp().ln_1p()
                + lip_mm * (-(y + 62.0).powi(2) / 32.0).exp()
        };
        // The grid's corner (0, 0) lies 30 mm right of and 130 mm below the nose tip.
        let nose_tip = DVec3::new(30.0, 130.0, 0.0);
        let surface = TestSurface::new(grid(61, 91, |_, y| z(y - nose_tip.y)));
        let mut detector = surface.detector();
        let v = detector.chin(&Frame::new(nose_tip, 0.0), 0.0, -50.0);
        assert!(detector.guessed.is_empty());
        detector.p(v).y - nose_tip.y
    }

    /// The chin is at the bend under the chin's front, whether the underside turns back
    /// steeply (the 45° tangent point) or runs into the neck at less than 45° (without the
    /// second try the chin went to the walk's lowest line, 25 mm below).
    #[test]
    fn the_chin_is_the_bend_whether_or_not_the_underside_turns_back_more_than_45_degrees() {
        for degrees in [55.0, 35.0] {
            let y = chin_of_profile(degrees, 0.0);
            assert!(
                (y + 80.0).abs() <= 4.0,
                "underside at {degrees}°: chin at y = {y:.1} mm, the bend at −80"
            );
        }
    }

    /// A lower lip pushed 25 mm forward (a pucker) is further down-and-forward than the
    /// chin's bend (62 + 5 against 80 − 20 mm), but lies 12 mm below the mouth line, on the
    /// lip: the chin stays at the bend (without [`CHIN_MIN_BELOW_MOUTH_MM`] it went to the lip).
    #[test]
    fn a_lower_lip_pushed_forward_is_not_the_chin() {
        let y = chin_of_profile(55.0, 25.0);
        assert!(
            (y + 80.0).abs() <= 4.0,
            "chin at y = {y:.1} mm, the bend at −80"
        );
    }
}
