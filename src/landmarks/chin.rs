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
/// Our step 9: the chin walk starts this far below the mouth line, or below an open mouth's
/// lower-lip top edge, mm (below the lower lip), from every strip vertex in the
/// [`CHIN_WALK_SEED_BAND_MM`] below that.
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
/// Our step 9, open mouths: the lips' profile at the corner line lying at least this far
/// (mm, scanner depth) behind the upper lip's front is the mouth's cavity (or a hole), and the
/// lower lip's top edge is where the profile below steps this far forward of the cavity.
/// Closed lips meet in a crease: on the 34 real scans, a median 4.3 mm behind the upper lip,
/// but up to 10.6 mm where the upper lip juts out; the step onto the lower lip is what
/// separates an open mouth (it fires on none of them).
pub const OPEN_MOUTH_STEP_MM: f64 = 8.0;
/// Our step 9, open mouths: the lips' profile is the median depth of the vertices within this
/// half-width (mm) of the mouth's centre line, in rows of half-height
/// [`LIP_PROFILE_HALF_HEIGHT_MM`] 1 mm apart: two rows of a 2.4 mm scan at least.
pub const LIP_PROFILE_HALF_WIDTH_MM: f64 = 6.0;
/// See [`LIP_PROFILE_HALF_WIDTH_MM`].
pub const LIP_PROFILE_HALF_HEIGHT_MM: f64 = 2.0;
/// Our step 9, open mouths: the upper lip's front is the profile's most forward row up to this
/// far above the corner line, mm (the upper vermilion is ~8–10 mm tall).
pub const UPPER_LIP_REACH_MM: f64 = 12.0;
/// Our step 9, open mouths: the lower lip's top edge is searched down to this far below the
/// corner line, mm: a mouth opened 50 mm (about the widest) with the corners half-way.
pub const LOWER_LIP_REACH_MM: f64 = 25.0;
/// Our step 9, open mouths: the opening at the mouth's centre line is looked for from 2 mm
/// above the corner line down to this far below it, mm: the lip line curves, and in a smile or
/// a laugh the corners rise above the middle of the lips' meeting line.
pub const OPENING_BELOW_CORNERS_MM: f64 = 6.0;

impl Detector<'_> {
    /// Step 9: walk down a 16 mm wide strip from below the lower lip (centred between the
    /// mouth corners; seeds: every strip vertex 12–32 mm below the mouth line, or below an
    /// open mouth's lower-lip top edge), along mesh edges, through vertices whose **mesh**
    /// normal faces the scanner (`n_z > 0.5`); the chin is the reached vertex furthest
    /// down-and-forward ([`CHIN_FORWARD_WEIGHT`]) of those at least
    /// [`CHIN_MIN_BELOW_MOUTH_MM`] below the mouth line (none: not found), less half its
    /// distance from the strip's centre line; where that is within [`CHIN_AT_LIMIT_MM`] of the
    /// walk's lowest line, the vertex furthest along [`CHIN_SHALLOW_FORWARD_WEIGHT`] instead.
    /// The scan's chin–neck depth jump, or the underside turning away, ends the walk. Changed
    /// from the paper (the lowest point of the biggest `S > 0.85`, `∇xy < 0.3` region): that
    /// region is the front of the chin, ~10 mm above the jaw-contour chin point (iBUG 8) of the
    /// benchmark. The mesh normal is used, not the fitted one: the 5-ring fit smooths normals
    /// across the chin's rim and lets the walk run on down the neck. Where the mouth is open
    /// ([`Self::open_mouth_lower_lip`]), the lower lip's height is counted from its top edge,
    /// not from the corner line.
    pub(super) fn chin(&mut self, frame: &Frame, mid_u: f64, mouth_v: f64) -> usize {
        let lowest = -NOSE_TIP_TO_CHIN.max_mm - CHIN_WALK_MARGIN_MM;
        // Where the lips meet, or the lower lip's top edge where the mouth is open.
        let lip_top_v =
            (self.open_mouth_lower_lip(frame, mid_u, mouth_v)).map_or(mouth_v, |v| v.min(mouth_v));
        // Start below the lower lip (whose underside faces down and would end the walk).
        let (top, band) = (
            lip_top_v - CHIN_WALK_START_BELOW_MOUTH_MM,
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
        let below_lip = |v: &usize| frame.uv(self.p(*v)).y <= lip_top_v - CHIN_MIN_BELOW_MOUTH_MM;
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

    /// Our step 9, open mouths: the height (face frame `v`, mm) of the lower lip's top edge,
    /// or `None` where the mouth is closed. The lips' profile (median depth per row, see
    /// [`LIP_PROFILE_HALF_WIDTH_MM`]) is open where, from 2 mm above the corner line to
    /// [`OPENING_BELOW_CORNERS_MM`] below it, a row is
    /// empty (a hole) or lies [`OPEN_MOUTH_STEP_MM`] behind the upper lip's front; going down
    /// through such rows, the first row [`OPEN_MOUTH_STEP_MM`] in front of the deepest one
    /// passed is the lower lip's top. A row that is neither ends the search (closed).
    /// Our addition: the lower lip's height ([`CHIN_MIN_BELOW_MOUTH_MM`]) is measured from
    /// where the lips meet, and an open-mouthed laugh's lower lip lies 6–15 mm below the
    /// corner line on the benchmark.
    fn open_mouth_lower_lip(&self, frame: &Frame, mid_u: f64, mouth_v: f64) -> Option<f64> {
        let (top, bottom) = (mouth_v + UPPER_LIP_REACH_MM, mouth_v - LOWER_LIP_REACH_MM);
        let (rows, profile): (Vec<f64>, Vec<Option<f64>>) = self
            .lips_profile(frame, mid_u, top, bottom)
            .into_iter()
            .unzip();
        let upper_lip_z = (rows.iter().zip(&profile))
            .filter(|&(&v, _)| v >= mouth_v)
            .filter_map(|(_, &z)| z)
            .max_by(f64::total_cmp)?;
        let cavity = |z: Option<f64>| z.is_none_or(|z| z <= upper_lip_z - OPEN_MOUTH_STEP_MM);
        let start = (rows.iter().zip(&profile)).position(|(&v, &z)| {
            (-OPENING_BELOW_CORNERS_MM..=2.0).contains(&(v - mouth_v)) && cavity(z)
        })?;
        let mut deepest = f64::INFINITY;
        for (&v, &z) in rows.iter().zip(&profile).skip(start) {
            if z.is_some_and(|z| z >= deepest + OPEN_MOUTH_STEP_MM) {
                return Some(v);
            }
            if !cavity(z) {
                return None;
            }
            deepest = deepest.min(z.unwrap_or(f64::NEG_INFINITY));
        }
        None
    }

    /// The lips' profile along the mouth's centre line `mid_u` (face frame, mm): per row from
    /// `top` down to `bottom`, 1 mm apart, the row's height and the median depth (scan `z`) of
    /// the vertices within [`LIP_PROFILE_HALF_WIDTH_MM`] of the line and
    /// [`LIP_PROFILE_HALF_HEIGHT_MM`] of the row, `None` for an empty row (a hole).
    pub(super) fn lips_profile(
        &self,
        frame: &Frame,
        mid_u: f64,
        top: f64,
        bottom: f64,
    ) -> Vec<(f64, Option<f64>)> {
        let h = LIP_PROFILE_HALF_HEIGHT_MM;
        let strip: Vec<(f64, f64)> = (0..self.mesh.vertex_count())
            .filter_map(|v| {
                let (p, q) = (self.p(v), frame.uv(self.p(v)));
                let inside = (q.x - mid_u).abs() <= LIP_PROFILE_HALF_WIDTH_MM
                    && q.y <= top + h
                    && q.y >= bottom - h;
                inside.then_some((q.y, p.z))
            })
            .collect();
        (0..)
            .map(|i| top - i as f64)
            .take_while(|&v| v >= bottom)
            .map(|v| {
                let mut z: Vec<f64> = (strip.iter())
                    .filter(|(y, _)| (y - v).abs() <= h)
                    .map(|&(_, z)| z)
                    .collect();
                z.sort_by(f64::total_cmp);
                (v, (!z.is_empty()).then(|| z[z.len() / 2]))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::detector::TestSurface;
    use crate::test_support::grid;
    use glam::DVec3;

    /// The chin and the open mouth's lower-lip edge of a profile surface `z(y)` (face frame:
    /// nose tip at the origin, y up, facing +z; the mouth line at y = −50 mm), 60 mm wide, from
    /// y = −30 to −130 mm, without the rows where `hole(y)`.
    fn chin_of(z: impl Fn(f64) -> f64, hole: impl Fn(f64) -> bool) -> (f64, Option<f64>) {
        // The grid's corner (0, 0) lies 30 mm right of and 130 mm below the nose tip.
        let nose_tip = DVec3::new(30.0, 130.0, 0.0);
        let mut mesh = grid(61, 101, |_, y| z(y - nose_tip.y));
        let keep: Vec<bool> = (mesh.positions_mm.iter())
            .map(|p| !hole(p.y - nose_tip.y))
            .collect();
        mesh.retain_vertices(&keep);
        let surface = TestSurface::new(mesh);
        let mut detector = surface.detector();
        let frame = Frame::new(nose_tip, 0.0);
        let lip = detector.open_mouth_lower_lip(&frame, 0.0, -50.0);
        let v = detector.chin(&frame, 0.0, -50.0);
        assert!(detector.guessed.is_empty());
        (detector.p(v).y - nose_tip.y, lip)
    }

    /// The chin of a profile surface: the chin's front at z = −20 mm down to y = −80 mm, then a
    /// 3 mm-wide bend into an underside receding `degrees` from vertical, and a lower lip
    /// pushed `lip_mm` forward of the chin's front 12 mm below the mouth line (a Gaussian
    /// ridge, σ 4 mm).
    fn chin_of_profile(degrees: f64, lip_mm: f64) -> f64 {
        let z =
            |y: f64| bend(y, -80.0, degrees) - 20.0 + lip_mm * (-(y + 62.0).powi(2) / 32.0).exp();
        let (chin, lip) = chin_of(z, |_| false);
        assert_eq!(lip, None, "closed lips are not an open mouth");
        chin
    }

    /// Depth (mm) of a 3 mm-wide bend at height `at` from a vertical front into an underside
    /// receding `degrees` from vertical: 0 above the bend.
    fn bend(y: f64, at: f64, degrees: f64) -> f64 {
        let r = 3.0;
        -degrees.to_radians().tan() * r * ((at - y) / r).exp().ln_1p()
    }

    /// Closed lips with a hole where they meet (a dark lip line the scanner missed): a hole
    /// up to 4 mm tall leaves no profile row empty, so the mouth is closed; a 6 mm hole reads
    /// as open, with the lower lip's edge within 2 mm of the hole's lower end (y = −53 mm, the
    /// rows being 4 mm tall). Either way the chin stays at the bend.
    #[test]
    fn a_hole_where_closed_lips_meet_leaves_the_chin() {
        let closed = |y: f64| bend(y, -80.0, 55.0) - 20.0;
        for (half_mm, edge) in [(1.5, None), (3.0, Some(-53.0))] {
            let (chin, lip) = chin_of(closed, |y| (y + 50.0).abs() < half_mm);
            match (lip, edge) {
                (None, None) => {}
                (Some(lip), Some(edge)) => {
                    assert!(
                        (lip - edge).abs() <= 2.0,
                        "hole ±{half_mm}: edge at {lip:.1}"
                    )
                }
                _ => panic!("hole ±{half_mm} mm: lip edge {lip:?}, expected {edge:?}"),
            }
            assert!(
                (chin + 80.0).abs() <= 4.0,
                "hole ±{half_mm}: chin at {chin:.1}"
            );
        }
    }

    /// An open-mouthed laugh's profile: the upper lip (z = −15 mm) above the mouth line, the
    /// mouth's cavity 25 mm behind it from 5 above to 8 below the line, and below the cavity,
    /// from y = −58 mm, a lower lip 20 mm in front of the chin, whose front recedes 1 mm in 2
    /// down to its bend at y = −100 mm.
    fn open_mouth(y: f64) -> f64 {
        let lower_lip = 20.0 / (1.0 + (-(y + 75.0)).exp());
        if y > -45.0 {
            -15.0
        } else if y > -58.0 {
            -40.0
        } else {
            -20.0 + lower_lip - 0.5 * (-78.0 - y).max(0.0) + bend(y, -100.0, 55.0)
        }
    }

    /// The lower lip of an open mouth, cavity scanned or a hole, is found at its top edge
    /// (y = −58 mm), and the chin stays at the bend under the receding front even though the
    /// lip, 25 mm below the mouth line, lies further down-and-forward (75 − 0 against
    /// 100 − 31 mm). Counting the lower lip's height from the corner line put the chin on
    /// the lip, at y = −72 mm, in both.
    #[test]
    fn an_open_mouths_lower_lip_is_not_the_chin() {
        for hole in [false, true] {
            let (chin, lip) = chin_of(open_mouth, |y| hole && (-57.0..-45.0).contains(&y));
            let lip = lip.expect("open mouth");
            assert!(
                (lip + 58.0).abs() <= 2.0,
                "hole {hole}: lip edge at {lip:.1}"
            );
            assert!(
                (chin + 100.0).abs() <= 4.0,
                "hole {hole}: chin at y = {chin:.1} mm, the bend at −100"
            );
        }
    }

    /// A laugh whose corners rise above the middle of the lips' meeting line: the upper lip
    /// hangs 4 mm below the corner line (y = −50 mm) at the centre, the cavity lies between
    /// it and [`open_mouth`]'s lower lip (top edge y = −58 mm). The opening is found there,
    /// and the chin stays at the bend; looking for the cavity within 2 mm of the corner line
    /// only, the mouth read as closed and the chin went to the lower lip.
    #[test]
    fn an_opening_below_the_corner_line_is_an_open_mouth() {
        let laugh = |y: f64| match y {
            y if y > -54.0 => -15.0,
            y if y > -58.0 => -40.0,
            y => open_mouth(y),
        };
        let (chin, lip) = chin_of(laugh, |_| false);
        let lip = lip.expect("open mouth");
        assert!((lip + 58.0).abs() <= 2.0, "lip edge at {lip:.1}");
        assert!(
            (chin + 100.0).abs() <= 4.0,
            "chin at y = {chin:.1} mm, the bend at −100"
        );
    }

    /// A wide-open laugh's lower lip, 18 mm tall below its top edge (y = −62 mm) and 20 mm in
    /// front of the chin, ends in an underside facing down (y = −80 to −84 mm) that no walk
    /// passes. The walk starts below the lower lip's top edge, so it reaches the chin's bend
    /// (y = −100 mm); started below the corner line (y = −50 mm), every seed lay on the lip
    /// and the chin was not found.
    #[test]
    fn the_chin_walk_starts_below_an_open_mouths_lower_lip() {
        let laugh = |y: f64| match y {
            y if y > -45.0 => -15.0,
            y if y > -62.0 => -40.0,
            y if y > -80.0 => 0.0,
            y if y > -84.0 => 5.0 * (y + 80.0),
            y => -20.0 + bend(y, -100.0, 55.0),
        };
        let (chin, lip) = chin_of(laugh, |_| false);
        assert!(
            lip.is_some_and(|lip| (lip + 62.0).abs() <= 2.0),
            "lip edge {lip:?}"
        );
        assert!(
            (chin + 100.0).abs() <= 4.0,
            "chin at y = {chin:.1} mm, the bend at −100"
        );
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
