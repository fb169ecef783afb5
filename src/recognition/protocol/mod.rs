//! The GavabDB recognition protocol (paper section 4): gallery = one neutral scan per subject
//! (`frontal1`), optionally augmented with its synthetic expressions; probes = `frontal2`,
//! `sonrisa` (smile), `risa` (laugh), `gesto` (gesture). Fisherfaces on range images, nearest
//! gallery identity by cosine or Euclidean distance, CMC per probe kind. The dataset layout:
//! [`crate::recognition::dataset`].
//!
//! **Augmented gallery layout** (what `facesynth augment` must write): one folder per gallery
//! scan, `AUG/<subject>_<scan>/`, holding one mesh per synthetic expression (`*.obj` or
//! `*.ply`, any names, e.g. `happiness.obj`; a registered `neutral.obj` may be included and is
//! just one more gallery sample). The meshes must be in the **original scan's coordinate
//! frame** (mm): they are resampled with the gallery scan's nose tip and pose. Each becomes a
//! gallery sample of that subject, kind `synthetic`. A folder is used only once it holds
//! `done.json` (written last by `augment`); one without it is listed as a failure.
//!
//! **Nose tip and pose** come from [`scan_pose`] (then, for `auto` and `icp`, a surface
//! refinement against the mean gallery image). Default [`PoseSource::Auto`], what the
//! pipeline itself finds, so real scans work: the scan is denoised and its feature points
//! detected (as `pipeline::prepare_scan`), the nose tip is the detected one, the rotation is
//! the registration's rigid step (Horn's fit of the generic face's feature vertices onto the
//! detected nose tip, nose corners and eye corners, [`PosePoints::Rigid`]), and both are then
//! refined rigidly (6 DOF) against the mean gallery range image ([`refine_pose`]; measured
//! without it, `--pose landmarks`: frontal2 rank-1 85 % instead of 100 %, the detected points'
//! noise leaves a median 2.2° and 1.3 mm between a subject's two neutral scans). Gallery scans
//! reuse the feature points `augment` stored in `done.json` when it is given. Synthetic
//! expressions reuse their gallery scan's final pose. `--pose truth` reads the synthetic
//! ground truth beside the scan (`<subject>_<scan>.json`): a diagnostic upper bound. A scan
//! whose detected points are suspect is posed by face localisation's fit of the generic face
//! instead and listed in the report's `suspect` ([`scan_pose_checked`]).
//!
//! Measured rank-1 / rank-5 figures (seeds, pose sources, metrics, augmentation, learned
//! expressions, expression weights, speed, the real scans) and the commands behind them:
//! `docs/measurements.md`, section "Recognition protocol".

use super::cmc::{Rates, rank_of, rates_by_kind};
use super::expression_weights::{
    ExpressionWeightParams, apply as apply_weights, expression_weights, weighted,
};
use super::fisherfaces::{FisherModel, FisherParams, Method, Metric};
use super::pose::{
    PoseParams, PosePoints, ScanPose, align_to_reference, mean_image, pose_from_landmarks,
    refine_pose,
};
use super::range_image::{RangeImage, RangeImageParams, range_image};
use crate::generic_face::GenericFace;
use crate::{Error, Result, io};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use serde::Serialize;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod learned;
mod samples;
mod scoring;
mod start_pose;

use crate::recognition::dataset::is_mesh;
pub use crate::recognition::dataset::{ScanFile, list_scans};
pub use crate::recognition::sample::{Failure, Sample};
use learned::{learned_deviations, training_scans};
use samples::make_sample;
pub use samples::{Samples, ScanOrientation, collect_samples};
pub use scoring::{evaluate, score, score_variants};
use start_pose::*;
pub use start_pose::{
    nose_tip, scan_pose, scan_pose_checked, truth_face_from_scan, truth_nose_tip,
};

/// Where the nose tip and the rotation that makes a scan frontal come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum PoseSource {
    /// The pipeline's own (works on real scans): [`PoseSource::Landmarks`], then a rigid
    /// surface refinement of rotation and nose tip against the mean gallery range image
    /// ([`refine_pose`]; the mean is built in two rounds from the gallery scans only).
    #[default]
    Auto,
    /// The scan is denoised, its feature points detected; the nose tip is the detected one
    /// and the rotation is the registration's rigid fit of the generic face to the points
    /// ([`super::pose::pose_from_landmarks`]).
    Landmarks,
    /// Diagnostic: the ground-truth nose tip and pose in the JSON beside the scan
    /// (`synth_gavab.py`); a scan without one fails.
    Truth,
    /// No pose normalisation: the scan frame is taken as frontal (nose tip as for `icp`).
    Identity,
    /// Landmark-free: the rotation about the nose tip that aligns the upper face to the mean
    /// gallery range image ([`super::pose`]; the mean is built in two rounds, first from
    /// unaligned then from aligned gallery scans). Nose tip detected (the ground truth is read
    /// only by `truth`).
    Icp,
}

/// Parameters of [`evaluate`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProtocolParams {
    pub range: RangeImageParams,
    pub fisher: FisherParams,
    /// Default cosine.
    pub metric: Metric,
    /// Scan kinds in the gallery. Default `["frontal1"]`.
    pub gallery_scans: Vec<String>,
    /// Scan kinds used as probes. Default `["frontal2", "sonrisa", "risa", "gesto"]`.
    pub probe_scans: Vec<String>,
    /// Default [`PoseSource::Auto`].
    pub pose: PoseSource,
    /// The feature points the automatic pose is fitted to. Default [`PosePoints::Rigid`].
    pub pose_points: PosePoints,
    /// Used with [`PoseSource::Icp`].
    pub icp: PoseParams,
    /// A dataset of **other** people (same layout; no subject in common with the evaluated
    /// one): each of its probe-kind scans minus the same person's gallery scan, as range images
    /// in the evaluated dataset's frame, is a learned within-class deviation
    /// ([`FisherModel::train_with_deviations`]) of the augmented run. Default `None`.
    pub expression_training: Option<PathBuf>,
    /// Weights of the range-image samples from the synthetic expressions' spread
    /// ([`super::expression_weights`]), used whenever the gallery has synthetic samples;
    /// `None` scores every sample alike (the paper). Default on, scale 0.5 mm.
    pub expression_weights: Option<ExpressionWeightParams>,
    /// Where the correction files `<scan stem>.landmarks.json` are
    /// ([`crate::pipeline::correction_for`]); default `None`: beside each scan. A scan with one
    /// is posed by its points (every pose source but [`PoseSource::Truth`]).
    pub landmarks_dir: Option<PathBuf>,
}

impl Default for ProtocolParams {
    fn default() -> Self {
        ProtocolParams {
            range: RangeImageParams::default(),
            // A within-class floor of 3× the mean S_w eigenvalue: plain LDA overfits a handful
            // of samples per class (figures: docs/measurements.md, "Recognition protocol");
            // see `FisherParams::within_class_regularisation`.
            fisher: FisherParams {
                within_class_regularisation: 3.0,
                ..FisherParams::default()
            },
            metric: Metric::Cosine,
            gallery_scans: vec!["frontal1".into()],
            probe_scans: ["frontal2", "sonrisa", "risa", "gesto"]
                .map(String::from)
                .to_vec(),
            pose: PoseSource::Auto,
            pose_points: PosePoints::default(),
            icp: PoseParams::default(),
            expression_training: None,
            expression_weights: Some(ExpressionWeightParams::default()),
            landmarks_dir: None,
        }
    }
}

/// The scans of `dir` the protocol uses: those of a gallery or a probe kind.
fn protocol_scans(dir: &Path, params: &ProtocolParams) -> Result<Vec<ScanFile>> {
    Ok(list_scans(dir)?
        .into_iter()
        .filter(|s| params.gallery_scans.contains(&s.scan) || params.probe_scans.contains(&s.scan))
        .collect())
}

/// One probe's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProbeResult {
    pub file: PathBuf,
    pub subject: String,
    /// Scan kind (`frontal2`, `risa`, …).
    pub kind: String,
    /// 1-based rank of the probe's own identity (1 = recognised).
    pub rank: usize,
    /// The identity nearest to it.
    pub best_match: String,
}

/// The evaluation report (`facesynth evaluate --report`).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Gallery identities (N, the CMC's last rank).
    pub subjects: usize,
    /// Probes matched.
    pub probes: usize,
    pub method: Method,
    /// Why the method is what it is (one line).
    pub method_note: String,
    pub metric: Metric,
    pub pose: PoseSource,
    /// Feature points of the automatic pose ([`PoseSource::Auto`]).
    pub pose_points: PosePoints,
    /// Gallery scans whose detected feature points were read from augment's `done.json`.
    pub cached_landmarks: usize,
    /// Scans posed by a correction file's points (`<stem>.landmarks.json`).
    pub corrected_landmarks: Vec<PathBuf>,
    /// Gallery scans `augment` failed on (its `failures*.json`, shards merged).
    pub augment_failures: Vec<serde_json::Value>,
    /// Probes of people without a gallery scan: not ranked (an open-set probe), not a failure.
    pub probes_without_gallery: Vec<PathBuf>,
    pub rank1: f64,
    pub rank5: f64,
    pub cmc: Vec<f64>,
    pub by_probe_kind: BTreeMap<String, Rates>,
    pub failures: Vec<Failure>,
    /// Scans kept whose feature points were suspect, and why ([`Samples::suspect`]).
    pub suspect: Vec<Failure>,
    /// The rotation applied to each real scan, gallery, probes and expression-training scans
    /// ([`Samples::poses`]): the axes its face was found in and the head's turn.
    pub poses: Vec<ScanOrientation>,
    /// Every probe matched, in file order: which were missed and whom they were taken for.
    pub per_probe: Vec<ProbeResult>,
    /// Gallery samples M (neutral + synthetic).
    pub gallery_samples: usize,
    pub synthetic_gallery_samples: usize,
    /// Learned within-class deviations used ([`ProtocolParams::expression_training`]).
    pub learned_deviations: usize,
    /// The people they were learned from.
    pub expression_training_subjects: usize,
    /// The expression weights' scale `s` (mm) when the samples were weighted
    /// ([`super::expression_weights`]; only with synthetic expressions), else `None`.
    pub expression_weight_scale_mm: Option<f64>,
    /// Smallest and mean sample weight inside the elliptic mask (`None` unweighted).
    pub expression_weight_min: Option<f64>,
    pub expression_weight_mean: Option<f64>,
    pub gallery_scans: Vec<String>,
    pub pca_dims: usize,
    pub projected_dims: usize,
    pub feature_length: usize,
    pub range_image: RangeImageParams,
    pub seconds: BTreeMap<String, f64>,
}

/// Everything [`evaluate`] computed: the report plus the data behind it.
#[derive(Debug, Clone)]
pub struct Evaluation {
    pub report: Report,
    pub gallery: Vec<Sample>,
    pub probes: Vec<Sample>,
    /// Gallery identities in CMC order.
    pub identities: Vec<String>,
    /// Per probe: 1-based rank of its true identity.
    pub ranks: Vec<usize>,
    /// Per probe: the best-matching identity.
    pub best: Vec<String>,
}

impl Evaluation {
    /// The feature vectors (f32) with labels and our ranks, for cross-checks outside Rust
    /// (scripts/sklearn_crosscheck.py): `{"gallery": {"subject": [...], "kind": [...],
    /// "x": [[...]]}, "probes": {..., "rank": [...], "best": [...]}, "identities": [...],
    /// "report": {...}}`.
    pub fn features_json(&self) -> serde_json::Value {
        // The vectors are those the model saw: weighted when the report says so.
        let part = |samples: &[Sample]| {
            serde_json::json!({
                "subject": samples.iter().map(|s| s.subject.clone()).collect::<Vec<_>>(),
                "kind": samples.iter().map(|s| s.kind.clone()).collect::<Vec<_>>(),
                "path": samples.iter().map(|s| s.path.clone()).collect::<Vec<_>>(),
                "x": samples
                    .iter()
                    .map(|s| s.features.iter().map(|&v| v as f32).collect::<Vec<f32>>())
                    .collect::<Vec<_>>(),
            })
        };
        let mut probes = part(&self.probes);
        probes["rank"] = serde_json::json!(self.ranks);
        probes["best"] = serde_json::json!(self.best);
        serde_json::json!({
            "gallery": part(&self.gallery),
            "probes": probes,
            "identities": self.identities,
            "report": self.report,
        })
    }
}
