//! The GavabDB recognition protocol (paper section 4): gallery = one neutral scan per subject
//! (`frontal1`), optionally augmented with its synthetic expressions; probes = `frontal2`,
//! `sonrisa` (smile), `risa` (laugh), `gesto` (gesture). Fisherfaces on range images, nearest
//! gallery identity by cosine or Euclidean distance, CMC per probe kind.
//!
//! **Dataset layout** (GavabDB and `synth_gavab.py` alike): `DIR/<subject>_<scan>.<ext>` with
//! `<ext>` one of wrl, vrml, obj, ply, xyz, txt (point clouds, see `io::xyz`); the subject is everything before the last `_`
//! (`cara1_frontal1.wrl`, `subj007_risa.wrl`). Other files are ignored.
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
    PoseParams, PosePoints, ScanPose, align_to_reference, detect_landmarks, detect_report,
    mean_image, pose_from_landmarks, refine_pose,
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
mod scoring;
mod start_pose;

use learned::{learned_deviations, training_scans};
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

/// One scan file of a dataset.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct ScanFile {
    pub subject: String,
    /// `frontal1`, `risa`, …
    pub scan: String,
    pub path: PathBuf,
}

const MESH_EXTENSIONS: [&str; 6] = ["wrl", "vrml", "obj", "ply", "xyz", "txt"];

fn is_mesh(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| MESH_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

fn read_dir_sorted(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    out.sort();
    Ok(out)
}

/// The scans of `dir` the protocol uses: those of a gallery or a probe kind.
fn protocol_scans(dir: &Path, params: &ProtocolParams) -> Result<Vec<ScanFile>> {
    Ok(list_scans(dir)?
        .into_iter()
        .filter(|s| params.gallery_scans.contains(&s.scan) || params.probe_scans.contains(&s.scan))
        .collect())
}

/// The scans of a dataset folder, sorted by subject then scan.
pub fn list_scans(dir: &Path) -> Result<Vec<ScanFile>> {
    let mut out = Vec::new();
    for path in read_dir_sorted(dir)? {
        if !path.is_file() || !is_mesh(&path) {
            continue;
        }
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if let Some((subject, scan)) = stem.rsplit_once('_')
            && !subject.is_empty()
            && !scan.is_empty()
        {
            out.push(ScanFile {
                subject: subject.to_string(),
                scan: scan.to_string(),
                path: path.clone(),
            });
        }
    }
    out.sort();
    Ok(out)
}

/// A range image ready for recognition.
#[derive(Debug, Clone)]
pub struct Sample {
    pub subject: String,
    /// Scan kind (`frontal1`, `risa`, …) or `synthetic`.
    pub kind: String,
    pub path: PathBuf,
    /// Γ: the range image's depths (length `cols × rows`).
    pub features: Vec<f64>,
}

/// A file that could not be used, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Failure {
    pub file: PathBuf,
    pub reason: String,
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

/// Builds one sample (range image) from a mesh file in the pose `start` (the scan's own, or
/// its gallery scan's for a synthetic expression), first refined against `reference` when
/// given ([`PoseSource::Auto`]: rotation and nose tip, [`refine_pose`]; [`PoseSource::Icp`]:
/// rotation only). Returns the pose used.
fn make_sample(
    path: &Path,
    start: ScanPose,
    subject: &str,
    kind: &str,
    params: &ProtocolParams,
    reference: Option<&RangeImage>,
) -> std::result::Result<(Sample, ScanPose), Failure> {
    let fail = |e: Error| Failure {
        file: path.to_path_buf(),
        reason: e.to_string(),
    };
    let mesh = io::read_mesh(path).map_err(fail)?;
    let pose = match reference {
        Some(r) if params.pose == PoseSource::Icp => ScanPose {
            face_from_scan: align_to_reference(
                &mesh,
                start.nose_tip_in_scan,
                start.face_from_scan,
                r,
                &params.icp,
            ),
            ..start
        },
        Some(r) => refine_pose(&mesh, start, r, &params.icp),
        None => start,
    };
    let img = range_image(
        &mesh,
        pose.nose_tip_in_scan,
        pose.face_from_scan,
        &params.range,
    )
    .map_err(fail)?;
    let sample = Sample {
        subject: subject.to_string(),
        kind: kind.to_string(),
        path: path.to_path_buf(),
        features: img.depth_mm,
    };
    Ok((sample, pose))
}

/// The reference of the surface alignment ([`PoseSource::Auto`], [`PoseSource::Icp`]): the
/// mean range image of the gallery scans in their starting poses, then (second round) of the
/// same scans aligned to that first mean. Only gallery scans are used.
fn alignment_reference(
    gallery: &[(&ScanFile, ScanPose)],
    params: &ProtocolParams,
) -> Result<RangeImage> {
    let mut reference: Option<RangeImage> = None;
    for _round in 0..2 {
        let images: Vec<RangeImage> = gallery
            .par_iter()
            .filter_map(|(s, start)| {
                make_sample(
                    &s.path,
                    *start,
                    &s.subject,
                    &s.scan,
                    params,
                    reference.as_ref(),
                )
                .ok()
                .map(|(sample, _)| sample.features)
            })
            .map(|depth| RangeImage {
                depth_mm: depth,
                ..blank_image(&params.range)
            })
            .collect();
        let refs: Vec<&RangeImage> = images.iter().collect();
        reference = Some(mean_image(&refs).ok_or_else(|| {
            Error::algorithm(
                "pose",
                "no gallery scan gave a range image for the reference",
            )
        })?);
    }
    Ok(reference.unwrap())
}

/// A range image of the grid with the elliptic mask and zero depths.
fn blank_image(p: &RangeImageParams) -> RangeImage {
    let mask = p.mask();
    RangeImage {
        cols: p.cols,
        rows: p.rows,
        spacing_mm: p.spacing_mm,
        depth_mm: vec![0.0; p.len()],
        measured: mask.clone(),
        mask,
        coverage: 1.0,
        spikes_rejected: 0,
    }
}

/// The range images of a dataset (and of its synthetic gallery expressions), before any
/// training: [`score`] them with or without the synthetic ones.
#[derive(Debug, Clone)]
pub struct Samples {
    /// Real gallery scans.
    pub gallery: Vec<Sample>,
    /// Synthetic expressions of the gallery scans (empty without an augmented folder).
    pub synthetic: Vec<Sample>,
    /// Learned within-class deviations (expression − neutral range images of the people in
    /// [`ProtocolParams::expression_training`]; empty without it).
    pub deviations: Vec<Vec<f64>>,
    /// The people the deviations come from.
    pub training_subjects: Vec<String>,
    pub probes: Vec<Sample>,
    pub failures: Vec<Failure>,
    /// Scans whose detected feature points were suspect (low face-likeness, a profile, guessed
    /// points): kept, but posed by face localisation's fit instead of by the points.
    pub suspect: Vec<Failure>,
    /// Gallery scans whose feature points came from augment's `done.json` (not re-detected).
    pub cached_landmarks: usize,
    /// Scans posed by the points of a correction file (`<stem>.landmarks.json`), not detected.
    pub corrected_landmarks: Vec<PathBuf>,
    /// Augment's failures (`failures.json` and every shard's `failures.K-of-N.json`).
    pub augment_failures: Vec<serde_json::Value>,
    /// Wall time of building them, s.
    pub seconds: f64,
    /// Wall time per stage, s: `start_poses` (read + denoise + feature points of every scan),
    /// `reference` (the alignment reference), `scan_images` (refine + resample every scan),
    /// `synthetic_images` (read + resample the synthetic expressions), `learned_deviations`
    /// (pose + resample the expression training scans).
    pub stage_seconds: BTreeMap<String, f64>,
}

/// Augment's detected feature points of a gallery scan (`AUG/<stem>/done.json`, field
/// `landmarks`), when that file is for this very scan file.
fn cached_landmarks(augmented: &Path, scan: &ScanFile) -> Option<crate::Landmarks> {
    let stem = scan.path.file_stem()?.to_str()?;
    let done = augmented.join(stem).join(crate::pipeline::DONE_MARKER);
    let mut v = read_json(&done).ok()?;
    let same_file = v["scan"]
        .as_str()
        .and_then(|p| std::fs::canonicalize(p).ok())
        .zip(std::fs::canonicalize(&scan.path).ok())
        .is_some_and(|(a, b)| a == b);
    if !same_file {
        return None;
    }
    serde_json::from_value(v["landmarks"].take()).ok()
}

/// Builds the range images of `dataset` and, if given, of the synthetic expressions in
/// `augmented` (resampled with their gallery scan's nose tip and pose).
pub fn collect_samples(
    dataset: &Path,
    augmented: Option<&Path>,
    params: &ProtocolParams,
) -> Result<Samples> {
    let t0 = Instant::now();
    let scans = protocol_scans(dataset, params)?;
    if !scans.iter().any(|s| params.gallery_scans.contains(&s.scan)) {
        return Err(Error::invalid(
            dataset,
            format!(
                "no gallery scans (<subject>_{}.wrl …) in the dataset",
                params.gallery_scans.join("|")
            ),
        ));
    }
    let training = match &params.expression_training {
        Some(dir) => Some(training_scans(dir, &scans, params)?),
        None => None,
    };
    let generic = crate::generic_face::build();
    // A scan's correction file, where there is one (read errors fail that scan only).
    let corrections: Vec<Option<std::result::Result<crate::Landmarks, Failure>>> = scans
        .iter()
        .map(|s| {
            let path =
                crate::pipeline::correction_for(&s.path, None, params.landmarks_dir.as_deref())
                    .filter(|_| params.pose != PoseSource::Truth)?;
            Some(crate::pipeline::read_landmarks(&path).map_err(|e| Failure {
                file: s.path.clone(),
                reason: e.to_string(),
            }))
        })
        .collect();
    let corrected_landmarks: Vec<PathBuf> = scans
        .iter()
        .zip(&corrections)
        .filter(|(_, c)| matches!(c, Some(Ok(_))))
        .map(|(s, _)| s.path.clone())
        .collect();
    let cached: Vec<Option<crate::Landmarks>> = scans
        .iter()
        .zip(&corrections)
        .map(|(s, c)| {
            if let Some(Ok(points)) = c {
                return Some(*points);
            }
            augmented
                .filter(|_| {
                    matches!(params.pose, PoseSource::Auto | PoseSource::Landmarks)
                        && params.gallery_scans.contains(&s.scan)
                })
                .and_then(|aug| cached_landmarks(aug, s))
        })
        .collect();
    let augment_failures = match augmented {
        Some(aug) => crate::pipeline::read_augment_failures(aug)?,
        None => Vec::new(),
    };
    let mut stage_seconds = BTreeMap::new();
    let mut lap = Instant::now();
    let mut stage = |name: &str| {
        stage_seconds.insert(name.to_string(), lap.elapsed().as_secs_f64());
        lap = Instant::now();
    };
    // 1. Each scan's starting pose (feature points, ground truth, …).
    let checked: Vec<std::result::Result<(ScanPose, Vec<String>), Failure>> = scans
        .par_iter()
        .zip(&cached)
        .zip(&corrections)
        .map(|((s, lm), correction)| {
            if let Some(Err(f)) = correction {
                return Err(f.clone());
            }
            let fail = |e: Error| Failure {
                file: s.path.clone(),
                reason: e.to_string(),
            };
            scan_pose_checked(&s.path, params, &generic, lm.as_ref()).map_err(fail)
        })
        .collect();
    let mut suspect = Vec::new();
    let starts: Vec<std::result::Result<ScanPose, Failure>> = scans
        .iter()
        .zip(checked)
        .map(|(s, r)| {
            r.map(|(pose, reasons)| {
                if !reasons.is_empty() {
                    suspect.push(suspect_scan(&s.path, &reasons, ""));
                }
                pose
            })
        })
        .collect();
    stage("start_poses");
    // 2. The surface-alignment reference from the gallery scans.
    let reference = match params.pose {
        PoseSource::Auto | PoseSource::Icp => {
            let gallery: Vec<(&ScanFile, ScanPose)> = scans
                .iter()
                .zip(&starts)
                .filter(|(s, _)| params.gallery_scans.contains(&s.scan))
                .filter_map(|(s, p)| p.as_ref().ok().map(|p| (s, *p)))
                .collect();
            Some(alignment_reference(&gallery, params)?)
        }
        PoseSource::Landmarks | PoseSource::Truth | PoseSource::Identity => None,
    };
    stage("reference");
    // 3. Every scan aligned and resampled.
    let results: Vec<_> = scans
        .par_iter()
        .zip(starts)
        .map(|(s, start)| {
            make_sample(
                &s.path,
                start?,
                &s.subject,
                &s.scan,
                params,
                reference.as_ref(),
            )
        })
        .collect();
    let mut failures = Vec::new();
    let mut gallery = Vec::new();
    let mut probes = Vec::new();
    // Synthetic expressions of each gallery scan: (mesh, frame, subject).
    let mut synthetic_jobs: Vec<(PathBuf, ScanPose, String)> = Vec::new();
    for (s, r) in scans.iter().zip(results) {
        match r {
            Ok((sample, frame)) if params.gallery_scans.contains(&s.scan) => {
                gallery.push(sample);
                if let Some(aug) = augmented {
                    let dir = aug.join(format!("{}_{}", s.subject, s.scan));
                    // A folder without the done marker is from a killed or failed `augment`:
                    // its meshes may be a partial set, so none of them is used.
                    if dir.is_dir() && !dir.join(crate::pipeline::DONE_MARKER).is_file() {
                        failures.push(Failure {
                            file: dir.clone(),
                            reason: format!(
                                "augmentation unfinished (no {}); re-run `facesynth augment`",
                                crate::pipeline::DONE_MARKER
                            ),
                        });
                    } else if dir.is_dir() {
                        for p in read_dir_sorted(&dir)? {
                            if p.is_file() && is_mesh(&p) {
                                synthetic_jobs.push((p, frame, s.subject.clone()));
                            }
                        }
                    }
                }
            }
            Ok((sample, _)) => probes.push(sample),
            Err(f) => failures.push(f),
        }
    }
    stage("scan_images");
    let results: Vec<_> = synthetic_jobs
        .par_iter()
        .map(|(p, frame, subject)| make_sample(p, *frame, subject, "synthetic", params, None))
        .collect();
    let mut synthetic = Vec::new();
    for r in results {
        match r {
            Ok((sample, _)) => synthetic.push(sample),
            Err(f) => failures.push(f),
        }
    }
    stage("synthetic_images");
    let (deviations, training_subjects) = match (&params.expression_training, &training) {
        (Some(dir), Some(t)) => learned_deviations(
            dir,
            t,
            params,
            &generic,
            reference.as_ref(),
            (&mut failures, &mut suspect),
        )?,
        _ => (Vec::new(), Vec::new()),
    };
    stage("learned_deviations");
    Ok(Samples {
        gallery,
        synthetic,
        deviations,
        training_subjects,
        probes,
        failures,
        suspect,
        cached_landmarks: cached
            .iter()
            .zip(&corrections)
            .filter(|(c, k)| c.is_some() && k.is_none())
            .count(),
        corrected_landmarks,
        augment_failures,
        seconds: t0.elapsed().as_secs_f64(),
        stage_seconds,
    })
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
