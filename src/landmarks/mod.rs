//! Automatic feature points (paper section 2.1.2): the paper's nine heuristic steps on the
//! surface descriptors of [`crate::curvature`], with the inter-anchor distance statistics of
//! the paper's Table 2 (from Colbry/Lu, ref. [9]) as named constants ([`TABLE_2`]).
//!
//! Input: a scan in millimetres, denoised first (the CLI and pipeline run
//! [`crate::denoise`]): without it, spikes and noise break up the concave regions the steps
//! look for. The paper's steps assume a frontal face in the scanner frame (face towards +z,
//! y up, the subject's left at +x) and take the biggest front-facing region as the face.
//! Before them, **face localisation** ([`localise`], our addition) finds the face among candidates
//! (protrusion peaks in the scanner frame, then tilted and axis-permuted frames) by the rigid fit
//! of the generic face and its **face-likeness** (the fraction of the generic face within 4 mm of
//! the scan after the fit). The steps then run on the scan turned so that z is the scanner's line
//! of sight (the mean vertex normal of the located face) and y the located face's up, with step 1
//! kept to an ellipse about the located nose and step 2 to 30 mm of it; the points are turned back,
//! so they are in the input's frame. Where localisation's finalists rank within
//! [`PLAUSIBILITY_TIE`] of each other, each gets the steps and the anatomically most plausible
//! result wins ([`implausibility`]); the lower-ranked ones too while that result is suspect.
//! The steps run in that view and in four views tilted by ±5° (`consensus.rs`): a point that
//! the untilted view puts more than [`CONSENSUS_KEEP_MM`] from the medoid of the five is
//! replaced by it, and the views' spread per point ([`LandmarkReport::spread_mm`]) names the
//! unstable ones.
//! [`LandmarkReport::localisation`] gives the orientation found; [`LandmarkReport::suspect`]
//! the reasons not to trust the points
//! ([`suspect_reasons`]: low face-likeness, a profile, a guessed anatomical point, three or
//! more failed Table 2 and level checks or unstable points, an eye, nose or mouth corner pair
//! more than [`SUSPECT_LEVEL_MM`] from level). Every command that detects says so: `augment`
//! refuses the scan, `evaluate` poses it without its points, the single-scan commands go on
//! and say it on stderr (`pipeline::notify_suspect`); all list it in their reports.
//!
//! Errors: [`detect`] fails only when there is no face to work on (a scan smaller than
//! [`MIN_FACE_EXTENT_MM`], no front-facing region, nothing that protrudes like a nose). A
//! feature that is not found (e.g. an eye lost to a hole) is placed at its Table 2 average
//! position and named in [`LandmarkReport::warnings`], so one bad region does not lose the
//! whole face.
//!
//! Output: the 13 [`FeaturePoint`]s, each snapped to a mesh vertex, plus the Table 2
//! plausibility check ([`LandmarkReport::distances`], [`LandmarkReport::warnings`]) and a
//! level check ([`LandmarkReport::level`]): the two eye, nose and mouth corners of a pair
//! should be about as high as each other across the face's symmetry line; where they
//! differ by more than [`LEVEL_MAX_MM`] both are flagged, since one is probably off. Table 2
//! cannot see that (its eye checks are horizontal distances and the bridge's mean height).
//!
//! # Parameters and units
//!
//! [`LandmarkParams`]: the descriptor neighbourhood (its reach, mm, turned into rings by the face's
//! sampling), the nose probe radius (mm) and the two fissure refinements (on / off). Every other
//! threshold is a named constant in the file of its step, re-exported here: lengths in mm, angles
//! in degrees, curvedness in 1/mm; `S` is the shape index (0 cup, 0.5 saddle or flat, 1 cap);
//! `|∂/∂x|`, `|∂/∂z|` are the components of the fitted unit normal and `∇xy` the in-plane slope,
//! all dimensionless.
//!
//! # The steps, and where they differ from the paper
//!
//! Boxes after step 3 are taken in the **face frame** (`frame.rs`): origin at the nose tip,
//! `u` along the line from the right to the left inner eye corner, `v` perpendicular to it in
//! the xy plane (up). This makes the boxes follow in-plane head roll (±10°); the paper uses
//! scan x/y. "Horizontal"/"vertical" distances of Table 2 are measured along `u`/`v`
//! (`table2.rs`). `detector.rs` runs the steps in order and holds the helpers they share.
//!
//! 1. **Facial segmentation** (`segmentation.rs`). Paper: drop `S < 0.375` and
//!    `|∂/∂z| < 0.5`, keep regions whose mean S exceeds 0.7. Here: vertices facing the
//!    scanner (`|∂/∂z| ≥ 0.5`), connected regions, the largest is the face. The mean shape
//!    index of a whole scan is 0.55–0.65 (most of a face is near-flat or saddle-like at the
//!    scale of a few mm), so the paper's `avg(S) > 0.7` rule discards the face itself; the
//!    largest front-facing region is what remains after dropping ears, neck and hair
//!    fragments (they are cut off by their steep borders). Front-facing islands the face
//!    surrounds are added back: a hole on the nose bridge and the steep sides of the nose
//!    can cut the whole nose off.
//! 2. **Nose tip** (`nose.rs`). Paper: bounding boxes from `∇xy` and `|∂/∂z|` regions, then
//!    the centroid of the highest flat (`∇xy < 0.25`) region. Here: every face vertex is
//!    scored by its **protrusion** — its z minus the mean height of the face on a circle of
//!    radius [`LandmarkParams::nose_probe_radius_mm`] around it (a coarse depth image) — and
//!    the most protruding one with at least 5/8 of its circle on the face wins (hair blobs,
//!    chin and forehead protrude far less than a nose at that radius). The tip is then, as in
//!    the paper, the centroid of the region around the highest point within 10 mm where
//!    `∇xy <` [`NOSE_TIP_MAX_SLOPE`] (0.25), kept within [`NOSE_TIP_REACH_MM`] of it: the
//!    lobule slopes gently up into the dorsum and steeply down into the columella, so it lies
//!    above the highest point (before: the vertices within 0.3 mm of the highest point's
//!    height, 0.3 mm lower on generated scans).
//!    This is robust to head pitch (the paper's "highest point" only after its boxes) and to
//!    holes.
//! 3. **Inner eye corners** (`eyes.rs`, `symmetry.rs`, `fissure.rs`). As the paper: in a box
//!    per side set by Table 2 (nose tip to nose bridge vertically, nose tip to inner eye
//!    horizontally, with margins), the biggest region of `S ≤ 0.25` — here also with
//!    curvedness ≥ [`FEATURE_MIN_CURVEDNESS_PER_MM`], so that shape-index noise on flat skin
//!    does not form regions — and the deepest region vertex within 3 mm of its centroid (the
//!    canthus pit; the centroid itself lies on the flank). In the paper the inner corners set
//!    the face frame's roll. Ours: the face's bilateral symmetry (the mirror line through the
//!    tip that best matches its depth) sets it, and the eye line only where no symmetry line
//!    is found; an inner-corner pair tilted more than [`INNER_EYE_ROLL_TOLERANCE_DEG`] from it
//!    is replaced by a pair of the next-biggest regions that agrees with it (a lid crease had
//!    outgrown the canthus on real scans). Then each corner moves to the medial end of its
//!    lid fissure, a narrow trench found in the depth relief (depth minus a 2 mm Gaussian
//!    mean of the surroundings), where that end is within 8 mm, at most 1 mm medial and 1 mm
//!    in front of the pit and keeps the pair symmetric: the biggest concave region is often
//!    the hollow between nose bridge and eye, whose pit lies ~4 mm medial and up of the
//!    canthus. An end found on one side only moves its corner whatever the symmetry if it
//!    lies at most [`FISSURE_LONE_MAX_UP_MM`] above the pit (both pits err alike, so their
//!    symmetry is no evidence against it; an end above the pit is an upper lid's crease).
//! 4. **Outer eye corners** (`outer_eyes.rs`). A box per side from the inner corner and
//!    Table 2's inner–outer distance; of the concave regions (`S < 0.3` plus the curvedness
//!    floor) of at least [`OUTER_EYE_MIN_REGION_VERTICES`], the vertices near the mean
//!    outer-corner offset [`OUTER_EYE_OFFSET_MM`] (and depth, [`OUTER_EYE_DEPTH_MM`]; none
//!    more than [`OUTER_EYE_MAX_BEHIND_MM`] behind the inner corner), chosen as a pair: the
//!    two sides' summed squared misses plus [`OUTER_EYE_SYMMETRY_WEIGHT`] times the squared
//!    difference of their offsets from their inner corners (a face is bilaterally
//!    symmetric; on real skin a crease below one canthus was often nearer the mean). The
//!    paper's `S < 0.5`, `|∂/∂x| ≤ 0.5`, `∇xy < 0.25` region is often empty (the lateral
//!    canthus faces sideways) and its centroid was 8–12 mm off on the benchmark. Then each
//!    corner moves to the lateral end of its lid fissure (the trench of step 3's refinement,
//!    at least [`OUTER_FISSURE_MIN_DEPTH_MM`] deep, in a box [`OUTER_FISSURE_BOX_MM`] around
//!    it; the end of its floor, half its deepest relief, so that a wrinkle running on from
//!    the canthus does not carry it away) unless that end is more than 8 mm away or
//!    [`OUTER_FISSURE_MAX_RISE_MM`] in front of it: the fixed offset from the inner corner
//!    scattered the point ±5–6 mm along the fissure, as the eyes' widths vary.
//! 5. **Nose corners** (`nose_corners.rs`). The paper's `|∂/∂z| ≤ 0.5`, `|∂/∂x| > 0.65`
//!    region (the side walls of the nose) gives the widest points of the alae; the ground
//!    truth we score against (iBUG 31/35) is the nostril base, lower and more medial, which
//!    is a concave crease: the biggest concave region 5–20 mm beside and 8–24 mm below the
//!    tip, its vertex nearest the midpoint of its centroid and the typical position
//!    [`NOSE_CORNER_OFFSET_MM`].
//! 6. **Mouth corners** (`mouth.rs`). As the paper's last stage: in a box per side from
//!    Table 2's nose-tip to mouth distance (starting 9 mm below the nose corners) and the
//!    outer eye corners, the biggest `S < 0.25` region; the corner (near the region's median
//!    height) is its most lateral vertex (the end of the lip line). Ours: a region that comes
//!    nowhere within [`MOUTH_CORNER_MAX_BEHIND_LIPS_MM`] of the lips' front is a cheek drawn
//!    in beside puckered lips, and does not compete.
//! 7. **Cheek borders** (`cheeks.rs`). Paper: `|∂/∂z| ≤ 0.4` in a box per side between mouth
//!    and eyes, outside the outer eye corners; centroid of the biggest region (snapped to the
//!    surface). Here: at the nose tip's height, walking out from the outer eye corner in
//!    1.5 mm steps, the first step where most of the cheek turns away from the scanner
//!    (`|∂/∂z| ≤ 0.7`), so the two cheeks are level and lie where the generic face has its
//!    cheek points.
//! 8. **Forehead border** (`forehead.rs`). Paper: regions above the eyes with
//!    `0.19 < |∂/∂x| < 0.25`, upper border where `|∂/∂z| > 0.6` ends. Here: walk up the
//!    midline strip of the face in 2 mm steps through smooth skin with `|∂/∂z| > 0.6` until
//!    more than 4 mm of it is not (hairline, the scan's edge; a wrinkle does not stop it).
//! 9. **Chin border** (`chin.rs`). The paper's biggest `S > 0.85`, `∇xy < 0.3` region is the
//!    front of the chin, ~10 mm above the jaw-contour chin point (iBUG 8). Here: walk down a
//!    midline strip from the mouth along mesh edges through vertices whose mesh normal faces
//!    the scanner; the chin is the vertex reached furthest down-and-forward, the tangent
//!    point of a 45° line (the chin–neck depth jump stops the walk), at least a lower lip's
//!    height below the mouth line ([`CHIN_MIN_BELOW_MOUTH_MM`]), or below the lower lip's top
//!    edge where the mouth is open (the lips' profile steps [`OPEN_MOUTH_STEP_MM`] forward
//!    from the mouth's cavity or a hole, [`LOWER_LIP_REACH_MM`]). Where that lies at the
//!    walk's lowest line ([`CHIN_AT_LIMIT_MM`]), the underside never turned back 45° (a chin
//!    running into the neck) and the tangent point of a steeper line
//!    ([`CHIN_SHALLOW_FORWARD_WEIGHT`]) is taken.
//!
//! # Accuracy and speed
//!
//! Measured on the synthetic benchmark with ground truth ([`eval`], `facesynth
//! eval-landmarks`), on the real scans in `../shared/data` against an independent detector
//! (`scripts/real_landmarks.sh`, with cluttered and resampled copies: `scripts/clutter_real.py`,
//! `scripts/resample_real.py`) and for speed with `facesynth bench-landmarks`. The figures, the
//! commands that reproduce them and what was tried: `docs/measurements.md` and README.

pub mod eval;
pub mod localise;
pub mod render;

mod cheeks;
mod chin;
mod consensus;
mod descriptors;
mod detector;
mod eyes;
mod fissure;
mod forehead;
mod frame;
mod mouth;
mod nose;
mod nose_corners;
mod outer_eyes;
mod segmentation;
mod suspect;
mod symmetry;
mod table2;

pub use cheeks::{CHEEK_MAX_DZ, CHEEK_STRIP_GAP_MM, CHEEK_STRIP_HALF_MM};
pub use chin::{
    CHIN_AT_LIMIT_MM, CHIN_FORWARD_WEIGHT, CHIN_MAX_GRAD_XY, CHIN_MIN_BELOW_MOUTH_MM, CHIN_MIN_S,
    CHIN_SHALLOW_FORWARD_WEIGHT, CHIN_WALK_MARGIN_MM, CHIN_WALK_MIN_NZ, CHIN_WALK_SEED_BAND_MM,
    CHIN_WALK_START_BELOW_MOUTH_MM, LIP_PROFILE_HALF_HEIGHT_MM, LIP_PROFILE_HALF_WIDTH_MM,
    LOWER_LIP_REACH_MM, OPEN_MOUTH_STEP_MM, UPPER_LIP_REACH_MM,
};
pub use consensus::{CONSENSUS_KEEP_MM, CONSENSUS_TILT_DEG, UNSTABLE_SPREAD_MM};
pub use descriptors::{
    DescriptorSampling, MAX_DESCRIPTOR_RINGS, MIN_DESCRIPTOR_RINGS, SPACING_RADIUS_MM,
    face_spacing_mm,
};
pub use detector::FEATURE_MIN_CURVEDNESS_PER_MM;
pub use eyes::{
    FISSURE_BOX_MM, FISSURE_DEPTH_BAND_MM, FISSURE_LONE_MAX_UP_MM, FISSURE_MAX_MEDIAL_MM,
    FISSURE_MAX_RISE_MM, FISSURE_MAX_SHIFT_MM, FISSURE_MIN_DEPTH_MM, FISSURE_SYMMETRY_SLACK_MM,
    INNER_EYE_CANDIDATE_REGIONS, INNER_EYE_MAX_S, INNER_EYE_ROLL_ACCEPT_DEG,
    INNER_EYE_ROLL_TOLERANCE_DEG,
};
pub use fissure::FISSURE_SMOOTHING_MM;
pub use forehead::{FOREHEAD_MAX_CURVEDNESS_PER_MM, FOREHEAD_MIN_DZ};
pub use mouth::{
    MOUTH_BELOW_NOSE_CORNERS_MM, MOUTH_CORNER_LINE_WEIGHT, MOUTH_CORNER_MAX_BEHIND_LIPS_MM,
    MOUTH_CORNER_MAX_S,
};
pub use nose::{NOSE_PRIOR_REACH_MM, NOSE_TIP_MAX_SLOPE, NOSE_TIP_REACH_MM};
pub use nose_corners::{
    NOSE_CORNER_CONCAVE_MAX_S, NOSE_CORNER_MAX_DZ, NOSE_CORNER_MIN_DX, NOSE_CORNER_OFFSET_MM,
};
pub use outer_eyes::{
    OUTER_EYE_CONCAVE_MAX_S, OUTER_EYE_DEPTH_MM, OUTER_EYE_DEPTH_WEIGHT, OUTER_EYE_MAX_BEHIND_MM,
    OUTER_EYE_MAX_DX, OUTER_EYE_MAX_GRAD_XY, OUTER_EYE_MAX_S, OUTER_EYE_MIN_REGION_VERTICES,
    OUTER_EYE_OFFSET_MM, OUTER_EYE_SYMMETRY_WEIGHT, OUTER_FISSURE_BOX_MM,
    OUTER_FISSURE_FLOOR_FRACTION, OUTER_FISSURE_MAX_RISE_MM, OUTER_FISSURE_MIN_DEPTH_MM,
};
pub use segmentation::{ENCLOSED_ISLAND_BAND_MM, ENCLOSED_ISLAND_MIN_VERTICES, FACE_MIN_DZ};
pub use suspect::{PROFILE_MIN_YAW_DEG, SUSPECT_FAILED_CHECKS, SUSPECT_LEVEL_MM, suspect_reasons};
pub use table2::{
    Direction, DistanceStat, INSIDE_EYE_TO_OUTSIDE_EYE, LEVEL_MAX_MM, NOSE_TIP_TO_CHIN,
    NOSE_TIP_TO_INSIDE_EYE, NOSE_TIP_TO_MOUTH, NOSE_TIP_TO_NOSE_BRIDGE, PairDistance, PairLevel,
    TABLE_2, TOP_OF_HEAD_TO_NOSE_TIP,
};

use crate::curvature::{self, CurvatureParams, SurfaceDescriptors};
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::mesh::{Mesh, Topology};
use crate::{Error, Result};
use detector::Detector;
use frame::Frame;
use serde_json::json;

/// Parameters of [`detect`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandmarkParams {
    /// Descriptor settings. Its `rings` are used as given only where
    /// [`Self::descriptor_reach_mm`] is `None`; default 5.
    pub curvature: CurvatureParams,
    /// How far the descriptors' quadric fit reaches, mm: the fit takes
    /// `round(reach / median edge length)` rings ([`Self::curvature_for`]), so that the shape
    /// index describes the same surface at any sampling density. Default `Some(10.0)`: 5
    /// rings at the middle of the whole scans' spacings the steps were measured on (1.5–2.4
    /// mm: GavabDB, POL-DB, the generated benchmark; their faces, 1.4–2.2 mm, get 5–7
    /// rings), wide enough to average out the 0.15 mm scanner noise the denoiser leaves (a
    /// 2-ring fit turns it into shape-index noise of ±0.2 on flat skin). `None`:
    /// `curvature.rings` whatever the spacing (the paper's fixed rings).
    pub descriptor_reach_mm: Option<f64>,
    /// Radius of the circle the nose tip's protrusion is measured against, mm (> 0).
    /// Default 25 mm: the nose's base half-width, so the circle lies on cheeks, lip and brow.
    pub nose_probe_radius_mm: f64,
    /// Move each inner eye corner to its lid fissure's medial end where that keeps the pair
    /// symmetric (`inner_eyes_at_fissures`). Default on (measured: docs/measurements.md).
    pub inner_eye_at_fissure: bool,
    /// Move each outer eye corner to its lid fissure's lateral end
    /// (`outer_eye_fissure_end`). Default on (measured: docs/measurements.md).
    pub outer_eye_at_fissure: bool,
    /// Move each mouth corner to its lip fissure's lateral end (`mouth_fissure_end`).
    /// Default on (measured: docs/measurements.md).
    pub mouth_corner_at_fissure: bool,
    /// Face localisation before the nine steps ([`localise`]): the face is found among
    /// candidates by its face-likeness, the scan is turned into its frame for the steps, and the
    /// points are turned back. Default on; `None` runs the paper's steps on the scan as it is
    /// (scanner frame assumed, the largest front-facing region taken as the face).
    pub localise: Option<localise::LocaliseParams>,
}

impl Default for LandmarkParams {
    fn default() -> Self {
        LandmarkParams {
            curvature: CurvatureParams {
                rings: 5,
                ..CurvatureParams::default()
            },
            descriptor_reach_mm: Some(10.0),
            nose_probe_radius_mm: 25.0,
            inner_eye_at_fissure: true,
            outer_eye_at_fissure: true,
            mouth_corner_at_fissure: true,
            localise: Some(localise::LocaliseParams::default()),
        }
    }
}

impl LandmarkParams {
    fn validate(&self) -> Result<()> {
        if let Some(reach_mm) = self.descriptor_reach_mm
            && !(reach_mm > 0.0 && reach_mm.is_finite())
        {
            return Err(Error::algorithm(
                "landmarks",
                format!("descriptor_reach_mm must be > 0, got {reach_mm}"),
            ));
        }
        if !(self.nose_probe_radius_mm > 0.0 && self.nose_probe_radius_mm.is_finite()) {
            return Err(Error::algorithm(
                "landmarks",
                format!(
                    "nose_probe_radius_mm must be > 0, got {}",
                    self.nose_probe_radius_mm
                ),
            ));
        }
        Ok(())
    }
}

/// What [`detect`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct LandmarkReport {
    /// The 13 points, mm, each on a mesh vertex (or an average of a few, for the nose tip).
    pub landmarks: Landmarks,
    /// The mesh vertex each point was snapped to.
    pub vertex: [usize; FeaturePoint::COUNT],
    /// Table 2 checks.
    pub distances: Vec<PairDistance>,
    /// Left/right pairs level across the symmetry line ([`LEVEL_MAX_MM`]); empty where no
    /// symmetry line was found (the frame's roll then comes from the inner corners).
    pub level: Vec<PairLevel>,
    /// One line per implausible point (out of its Table 2 range, or found by a fallback).
    pub warnings: Vec<String>,
    /// Roll of the face frame, degrees: [`Self::symmetry_roll_deg`] where found, else the
    /// angle of the inner-eye line from +x (clamped to ±20°).
    pub roll_deg: f64,
    /// Roll told by the face's bilateral symmetry alone (the mirror line through the nose
    /// tip that matches the face's depth best, as a roll of the eye line), degrees; `None`
    /// where too little of the face overlaps its mirror. Step 3 checks the inner corners
    /// against it.
    pub symmetry_roll_deg: Option<f64>,
    /// Vertices of the segmented face region (step 1).
    pub face_vertices: usize,
    /// Points placed at their Table 2 average position because their feature was not found.
    pub guessed: Vec<FeaturePoint>,
    /// Per point (indexed by [`FeaturePoint::index`]), how far apart the steps put it when the
    /// view is tilted by [`CONSENSUS_TILT_DEG`] (the largest distance from the chosen point to
    /// another view's, mm; `consensus.rs`). `None` without localisation (a single view).
    pub spread_mm: Option<[f64; FeaturePoint::COUNT]>,
    /// Where the face was found and how it is turned ([`localise`]); `None` when localisation
    /// was switched off ([`LandmarkParams::localise`]).
    pub localisation: Option<localise::Localisation>,
    /// The sampling the descriptors were fitted on ([`LandmarkParams::curvature_for`]).
    pub descriptors: Option<DescriptorSampling>,
    /// Why the points should not be trusted, one line each; empty when nothing speaks against
    /// them. See [`suspect_reasons`].
    pub suspect: Vec<String>,
}

impl LandmarkReport {
    /// The anatomical points (not the region borders) that had to be guessed at their Table 2
    /// average position.
    pub fn guessed_anatomical(&self) -> Vec<FeaturePoint> {
        (self.guessed.iter().copied())
            .filter(|p| !FeaturePoint::BORDER.contains(p))
            .collect()
    }

    /// The anatomical points (not the region borders) the tilted views put more than
    /// [`UNSTABLE_SPREAD_MM`] apart; none where the consensus did not run.
    pub fn unstable_points(&self) -> Vec<FeaturePoint> {
        self.spread_mm.map_or(Vec::new(), |s| {
            FeaturePoint::ALL
                .into_iter()
                .filter(|p| !FeaturePoint::BORDER.contains(p) && s[p.index()] > UNSTABLE_SPREAD_MM)
                .collect()
        })
    }

    /// The names of the Table 2 and level checks that fail (`nose_tip-chin`, `inner_eye`, …).
    pub fn failed_checks(&self) -> Vec<&str> {
        self.distances
            .iter()
            .filter(|d| !d.in_range)
            .map(|d| d.name.as_str())
            .chain(self.level.iter().filter(|l| !l.in_range).map(|l| l.name))
            .collect()
    }

    /// How far the detected nose tip lies from the nose tip of the [`Self::localisation`] fit
    /// of the generic face, across the fitted face (in its plane; along its direction the two
    /// differ by how far this nose protrudes beyond the generic one's), mm; `None` without
    /// localisation.
    pub fn fit_nose_tip_offset_mm(&self) -> Option<f64> {
        self.localisation.map(|l| {
            let d = self.landmarks.get(FeaturePoint::NoseTip) - l.nose_tip_in_scan;
            (l.face_from_scan * d).truncate().length()
        })
    }

    /// The CLI's JSON: `{"landmarks": {name: [x,y,z]}, "distances_mm": {...}, "warnings": [...]}`
    /// (the CLI adds `millis`).
    pub fn to_json(&self) -> serde_json::Value {
        let mut d = serde_json::Map::new();
        for p in &self.distances {
            d.insert(
                p.name.clone(),
                json!({
                    "direction": p.stat.direction, "measured": round3(p.measured_mm),
                    "min": p.stat.min_mm, "avg": p.stat.avg_mm, "max": p.stat.max_mm,
                    "in_range": p.in_range,
                }),
            );
        }
        let lm: serde_json::Map<String, serde_json::Value> = self
            .landmarks
            .iter()
            .map(|(p, x)| (p.name().to_string(), json!(x.to_array().map(round3))))
            .collect();
        let level: serde_json::Map<String, serde_json::Value> = self
            .level
            .iter()
            .map(|l| {
                (
                    l.name.to_string(),
                    json!({"difference": round3(l.difference_mm), "in_range": l.in_range}),
                )
            })
            .collect();
        json!({
            "landmarks": lm,
            "distances_mm": d,
            "level_mm": level,
            "warnings": self.warnings,
            "roll_deg": round3(self.roll_deg),
            "symmetry_roll_deg": self.symmetry_roll_deg.map(round3),
            "face_vertices": self.face_vertices,
            "guessed": self.guessed.iter().map(|p| p.name()).collect::<Vec<_>>(),
            "spread_mm": self.spread_mm.map(|s| {
                FeaturePoint::ALL
                    .iter()
                    .map(|p| (p.name().to_string(), json!(round3(s[p.index()]))))
                    .collect::<serde_json::Map<_, _>>()
            }),
            "descriptors": self.descriptors.map(|d| {
                json!({"spacing_mm": round3(d.spacing_mm), "rings": d.rings})
            }),
            "confidence": self.confidence(),
            "suspect": !self.suspect.is_empty(),
            "suspect_reasons": self.suspect,
            "orientation": self.orientation_json(),
        })
    }

    /// The JSON's `confidence`: the localisation's face-likeness to three decimals; `None`
    /// without localisation.
    pub fn confidence(&self) -> Option<f64> {
        self.localisation.map(|l| round3(l.face_likeness))
    }

    /// The JSON's `orientation`: the axes the face was found in and how the head is turned
    /// (`facing`, `up`, `yaw_deg`, `pitch_deg`, `roll_deg`, `face_from_scan`), and the generic
    /// face's fit that found it; `None` without localisation.
    pub fn orientation_json(&self) -> Option<serde_json::Value> {
        self.localisation.map(|l| {
            let (yaw, pitch, roll) = localise::yaw_pitch_roll_deg(l.face_from_scan);
            let (facing, up) = localise::facing_and_up(l.face_from_scan);
            let m = l.face_from_scan.transpose().to_cols_array_2d();
            json!({
                "facing": facing, "up": up,
                "yaw_deg": round3(yaw), "pitch_deg": round3(pitch), "roll_deg": round3(roll),
                "face_from_scan": m.map(|r| r.map(|x| (x * 1e6).round() / 1e6)),
                "nose_tip_fit_mm": l.nose_tip_in_scan.to_array().map(round3),
                "nose_tip_fit_offset_mm": self.fit_nose_tip_offset_mm().map(round3),
                "fit_rms_mm": round3(l.rms_mm),
                "size_vs_generic_face": round3(l.scale),
                "candidates_fitted": l.candidates_fitted,
            })
        })
    }
}

fn round3(x: f64) -> f64 {
    (x * 1e3).round() / 1e3
}

/// Detects the 13 feature points of a (denoised) frontal scan.
pub fn detect(mesh: &Mesh, params: &LandmarkParams) -> Result<LandmarkReport> {
    detect_with_descriptors(mesh, params).map(|(report, _)| report)
}

/// [`detect`], with the surface descriptors the steps read (the editor shows the same maps):
/// computed with [`LandmarkParams::curvature_for`] on the sampling about the located face
/// ([`LandmarkReport::descriptors`]).
pub fn detect_with_descriptors(
    mesh: &Mesh,
    params: &LandmarkParams,
) -> Result<(LandmarkReport, SurfaceDescriptors)> {
    mesh.validate().map_err(Error::InvalidMesh)?;
    params.validate()?;
    let extent_mm = mesh
        .bbox_mm()
        .map_or(0.0, |(lo, hi)| (hi - lo).max_element());
    if extent_mm < MIN_FACE_EXTENT_MM {
        return Err(Error::algorithm(
            "landmarks: facial segmentation",
            format!(
                "the scan is {extent_mm:.1} mm across at its widest, smaller than a face (both \
                 eyes alone span about 90 mm): if the file is in centimetres, give --units cm \
                 (--units m for metres)"
            ),
        ));
    }
    let topology = Topology::new(mesh);
    let n = mesh.vertex_count();
    // The finalists the face-likeness cannot tell apart (within `PLAUSIBILITY_TIE` of the
    // best) each get the steps; the one whose points pass the most anatomical checks wins.
    let located = match params.localise {
        None => None,
        Some(_) if n < MIN_FACE_VERTICES => {
            return Err(Error::algorithm(
                "landmarks: facial segmentation",
                format!(
                    "the scan has only {n} vertices; a face needs at least {MIN_FACE_VERTICES}"
                ),
            ));
        }
        Some(localise_params) => Some((
            localise_params,
            localise::localise_finalists(mesh, &localise_params)?,
        )),
    };
    // The descriptors' rings follow the sampling of the face (about the best-ranked fit's nose
    // tip), not of a torso or hair cap sampled otherwise.
    let around = (located.as_ref()).map(|(_, finalists)| finalists[0].0.nose_tip_in_scan);
    let sampling = params.descriptor_sampling(mesh, around);
    let desc = curvature::compute_with_topology(mesh, &topology, &params.curvature_with(sampling))?;
    let mut report = match located {
        None => {
            let mut report = Detector::new(mesh, &topology, &desc, params, None)
                .run()?
                .into_report();
            report.suspect = suspect_reasons(None, &report, &localise::LocaliseParams::default());
            report
        }
        Some((localise_params, finalists)) => {
            detect_located(mesh, &topology, &desc, params, &localise_params, finalists)?
        }
    };
    report.descriptors = Some(sampling);
    Ok((report, desc))
}

/// The nine steps on each finalist of face localisation within [`PLAUSIBILITY_TIE`] of the
/// best, and on the face-like finalists beyond it while the most plausible result so far is
/// suspect ([`SUSPECT_FAILED_CHECKS`] or more problems); the most plausible result
/// (beyond the tie, [`second_opinion_wins`]).
fn detect_located(
    mesh: &Mesh,
    topology: &Topology,
    desc: &SurfaceDescriptors,
    params: &LandmarkParams,
    localise_params: &localise::LocaliseParams,
    finalists: Vec<(localise::Localisation, f64)>,
) -> Result<LandmarkReport> {
    let best_rank = finalists[0].1;
    let scan = Scan {
        mesh,
        topology,
        desc,
        normal_sum: face_normal_sum(mesh, topology, &finalists[0].0),
    };
    let mut turned = consensus::Turned::new(mesh, desc);
    let mut best: Option<(usize, LandmarkReport)> = None;
    for (k, (found, rank)) in finalists.into_iter().enumerate() {
        let tied = rank >= best_rank - PLAUSIBILITY_TIE;
        // Beyond the tie, a finalist is a second opinion on a suspect result, if it is
        // face-like itself (never trade a suspect face for what localisation calls no face).
        let second_opinion = !tied
            && found.face_likeness >= localise_params.face_likeness_min
            && (best.as_ref()).is_some_and(|(b, _)| *b >= SUSPECT_FAILED_CHECKS);
        if !tied && !second_opinion {
            continue;
        }
        let mut report = match steps_for(&scan, &mut turned, params, localise_params, found) {
            Ok(r) => r,
            Err(e) if k == 0 => return Err(e),
            Err(_) => continue,
        };
        let problems = implausibility(&report);
        let wins = match &best {
            None => true,
            Some((b, _)) if tied => problems < *b,
            Some((b, first)) => {
                let kept = second_opinion_wins(first, &report);
                if kept {
                    let moved_mm = nose_tip_moved_mm(first, &report);
                    report.warnings.push(format!(
                        "face localisation: the best-ranked fit of the generic face gave a \
                         suspect face ({b} problems); a lower-ranked fit (face-likeness {:.2}) \
                         gave a plausible one with the nose tip {moved_mm:.0} mm away, which \
                         was kept: check the picture",
                        found.face_likeness
                    ));
                }
                kept
            }
        };
        if wins {
            best = Some((problems, report));
        }
    }
    best.map(|(_, r)| r)
        .ok_or_else(|| Error::algorithm("landmarks", "the steps failed on every located face"))
}

/// Finalists of face localisation whose rank is within this of the best get the steps, and
/// the one with the fewest anatomical problems ([`implausibility`]) wins (the best-ranked on a
/// tie): the generic face's fit can score as well slid onto the brow or the chin of a face far
/// from average as in the right place, while the steps' points then fail Table 2. The same
/// margin as the scanner-frame prior. A face-like finalist ranked lower still gets the steps
/// while the best result so far is suspect, and may replace it ([`second_opinion_wins`]): the
/// prior alone can lift a scanner-frame fit slid onto the chin above a tilted start's right
/// fit (a smile far from the average face). A plausible best result costs no extra run.
pub const PLAUSIBILITY_TIE: f64 = 0.1;

/// Whether `second`, the result of a finalist ranked beyond [`PLAUSIBILITY_TIE`], replaces
/// the suspect result `first` (with a warning that says so): it has fewer problems
/// ([`implausibility`]), is not suspect itself, and puts the nose tip more than
/// [`localise::DISTINCT_FIT_MM`] from `first`'s (the face found elsewhere). With the nose tip
/// where `first` has it, the problems are the face's own (far from Table 2's means), and
/// another frame whose checks happen to pass is no evidence against them.
pub fn second_opinion_wins(first: &LandmarkReport, second: &LandmarkReport) -> bool {
    implausibility(second) < implausibility(first)
        && second.suspect.is_empty()
        && nose_tip_moved_mm(first, second) > localise::DISTINCT_FIT_MM
}

/// How far apart two detections put the nose tip, mm.
fn nose_tip_moved_mm(a: &LandmarkReport, b: &LandmarkReport) -> f64 {
    let tip = |r: &LandmarkReport| r.landmarks.get(FeaturePoint::NoseTip);
    tip(a).distance(tip(b))
}

/// How many things speak against a detection's anatomy: failed Table 2 and level checks,
/// anatomical points guessed at their Table 2 position, and anatomical points the tilted views
/// put more than [`UNSTABLE_SPREAD_MM`] apart.
pub fn implausibility(report: &LandmarkReport) -> usize {
    report.failed_checks().len()
        + report.guessed_anatomical().len()
        + report.unstable_points().len()
}

/// The scan as the steps see it, with its line of sight's estimate, computed once for all
/// finalists.
struct Scan<'a> {
    mesh: &'a Mesh,
    topology: &'a Topology,
    desc: &'a SurfaceDescriptors,
    /// [`face_normal_sum`] about the best-ranked finalist ([`steps_frame`]).
    normal_sum: glam::DVec3,
}

/// The sum of the vertex normals of the surface about the face `found`, weighted by
/// [`localise::Localisation::coverage`], over the part of the mesh connected to the vertex nearest
/// the fit's nose tip: the line of sight's estimate ([`steps_frame`]). Only the face counts: a
/// torso, shoulders, a wall or anything else in the file would otherwise turn the view the steps
/// read depth along (measured: a flat patch 1 m beside cara1_abajo moved its inner eye corner 5.7
/// mm; turned 45°, 133 mm). The coverage sphere alone let a separate surface within the face's
/// radius count (a torso 40 mm below the chin moved cara1_abajo's mouth corner 2.7 mm and
/// cara5_gesto's nose tip 3.1 mm; docs/measurements.md, "the line of sight from the face's own
/// surface"). It is taken about the best-ranked finalist and serves every finalist: about each
/// finalist's own face, a face located on the chin and pitched 33° came with a view that agreed
/// with it and won (generated risa scans, 65 mm off); over all finalists together, the estimate
/// followed which finalists tied, and a rotated copy's forehead moved 6.6 mm.
fn face_normal_sum(
    mesh: &Mesh,
    topology: &Topology,
    found: &localise::Localisation,
) -> glam::DVec3 {
    let tip = frame::nearest(mesh, 0..mesh.vertex_count(), found.nose_tip_in_scan);
    let face = topology.within_rings(&[tip], usize::MAX);
    mesh.positions_mm
        .iter()
        .zip(&mesh.normals)
        .zip(face)
        .filter(|(_, on_face)| *on_face)
        .map(|((p, n), _)| *n * found.coverage(*p))
        .sum()
}

/// The nine steps (their consensus of views) on the face `found` by localisation, the points
/// in the scan's frame; `turned` is the working copy of the scan the views are turned into.
fn steps_for(
    scan: &Scan,
    turned: &mut consensus::Turned,
    params: &LandmarkParams,
    localise_params: &localise::LocaliseParams,
    found: localise::Localisation,
) -> Result<LandmarkReport> {
    // The steps run on the scan turned into a frame whose z is the scanner's line of sight and
    // whose y is the located face's up (any roll and any axis convention taken out). Yaw and
    // pitch of the head against the line of sight stay: the steps read depth, front-facing
    // normals and depth jumps, which mean what the scanner saw.
    let face_from_scan = steps_frame(scan.normal_sum, found.face_from_scan);
    let (points, spread) = consensus::consensus(
        turned,
        scan.mesh,
        scan.topology,
        scan.desc,
        params,
        face_from_scan,
        found.nose_tip_in_scan,
    )?;
    let mut report = points.into_report();
    report.spread_mm = Some(spread);
    let scan_from_face = face_from_scan.transpose();
    for p in FeaturePoint::ALL {
        report
            .landmarks
            .set(p, scan_from_face * report.landmarks.get(p));
    }
    report.localisation = Some(found);
    if let Some(off_mm) = (report.fit_nose_tip_offset_mm()).filter(|&d| d > FIT_NOSE_TIP_WARN_MM) {
        report.warnings.push(format!(
            "face localisation: the generic face's fit puts the nose tip {off_mm:.1} mm from the \
             detected one (more than {FIT_NOSE_TIP_WARN_MM} mm): it lies on another part of the \
             face, so the orientation figures (yaw, pitch, roll) are a misplaced fit's; check \
             the picture"
        ));
    }
    let yaw_deg = yaw_from_line_of_sight(scan.normal_sum, found.face_from_scan);
    report.suspect = suspect_reasons(Some((&found, yaw_deg)), &report, localise_params);
    Ok(report)
}

/// The frame the nine steps run in (rotation from the scan): z along the line of sight, estimated
/// as the mean vertex normal of the face (`normal_sum`, [`face_normal_sum`]: a single-view range
/// scan's surface faces its scanner, its normals spread about the line of sight), turned to the
/// side the located face looks to; y the located face's up, made perpendicular to it. Both
/// follow any rotation of the data, so the steps see the same thing however the file's axes lie.
fn steps_frame(normal_sum: glam::DVec3, located: glam::DMat3) -> glam::DMat3 {
    let face_z = located.transpose().z_axis;
    let face_y = located.transpose().y_axis;
    let mut z = normal_sum.normalize_or_zero();
    if z.dot(face_z) < 0.0 {
        z = -z;
    }
    // Not a single-view scan (a closed head), or the face looks across the view: the located
    // face's own direction.
    if z.dot(face_z) < 0.5 {
        z = face_z;
    }
    let y = (face_y - z * face_y.dot(z)).normalize_or(face_y);
    let x = y.cross(z);
    glam::DMat3::from_cols(x, y, z).transpose()
}

/// The head's turn (degrees) against the line of sight, whatever the file's axes: the angle,
/// about the located face's up axis, from the face's mean vertex normal (`normal_sum`; a
/// single-view scan faces its scanner) to the located face's direction. 0 for a closed mesh (no
/// line of sight).
fn yaw_from_line_of_sight(normal_sum: glam::DVec3, located: glam::DMat3) -> f64 {
    let face = located.transpose();
    let (up, facing) = (face.y_axis, face.z_axis);
    let mean = normal_sum;
    let mut sight = (mean - up * mean.dot(up)).normalize_or_zero();
    if sight == glam::DVec3::ZERO {
        return 0.0;
    }
    // Normals wound the other way round point into the head.
    if sight.dot(facing) < 0.0 {
        sight = -sight;
    }
    let across = up.cross(sight);
    facing.dot(across).atan2(facing.dot(sight)).to_degrees()
}

/// A detected nose tip further than this (mm, across the face) from the nose tip of the
/// generic face's fit that located the face gets a warning: the fit lies on another part of the
/// face (the steps may still find the right points), and the orientation figures are that
/// fit's (docs/measurements.md, "Where the generic face's fit and the detected points part").
/// The width of [`localise::Localisation::coverage`]'s fall from the whole face to nothing
/// ([`localise::COVER_TAPER_MM`]): a fit off by more no longer covers the same face.
pub const FIT_NOSE_TIP_WARN_MM: f64 = localise::COVER_TAPER_MM;

/// Fewer vertices than this cannot hold a face at scanner resolution (the paper's scans have
/// 10,000 or more; a face at 2 mm spacing ~3,000).
pub const MIN_FACE_VERTICES: usize = 200;

/// A scan whose bounding box is under this at its widest (mm) cannot hold the 13 points: both
/// eyes' outer corners alone lie about 85–100 mm apart in adults (biocular width; 82–96 mm on
/// the benchmark's faces), and forehead to chin spans more. A face that small is a file in
/// centimetres (a face 15–25 units wide) or inches, read as millimetres.
pub const MIN_FACE_EXTENT_MM: f64 = 80.0;
