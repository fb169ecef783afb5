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
//! ground truth beside the scan (`<subject>_<scan>.json`): a diagnostic upper bound.
//!
//! **Measured** (noisy synthetic sets, `synth_gavab.py --subjects 61 --seed 8` and `--seed 9`;
//! 244 probes each; gallery frontal1, so Eigenfaces without augmentation, Fisherfaces with the
//! 18 presets of `facesynth augment` (1,098 synthetic samples); `--sw-floor 3`; commit after
//! the jaw), rank-1 / rank-5 %:
//!
//! | seed | pose | metric | gallery | all | frontal2 | sonrisa | risa | gesto |
//! |---|---|---|---|---|---|---|---|---|
//! | 8 | auto | cosine | neutral | 61.5 / 75.4 | 100.0 / 100.0 | 77.0 / 98.4 | 4.9 / 23.0 | 63.9 / 80.3 |
//! | 8 | auto | cosine | augmented | 79.5 / 93.9 | 100.0 / 100.0 | 86.9 / 98.4 | 63.9 / 86.9 | 67.2 / 90.2 |
//! | 8 | auto | Euclidean | neutral | 60.2 / 75.4 | 100.0 / 100.0 | 78.7 / 95.1 | 3.3 / 23.0 | 59.0 / 83.6 |
//! | 8 | auto | Euclidean | augmented | 79.9 / 95.1 | 100.0 / 100.0 | 85.2 / 98.4 | 60.7 / 83.6 | 73.8 / 98.4 |
//! | 8 | truth | cosine | neutral | 63.9 / 83.6 | 100.0 / 100.0 | 80.3 / 98.4 | 8.2 / 47.5 | 67.2 / 88.5 |
//! | 8 | truth | cosine | augmented | 83.2 / 94.7 | 100.0 / 100.0 | 90.2 / 96.7 | 67.2 / 91.8 | 75.4 / 90.2 |
//! | 8 | truth | Euclidean | neutral | 65.6 / 81.6 | 100.0 / 100.0 | 88.5 / 100.0 | 9.8 / 45.9 | 63.9 / 80.3 |
//! | 8 | truth | Euclidean | augmented | 83.6 / 97.5 | 100.0 / 100.0 | 88.5 / 100.0 | 73.8 / 96.7 | 72.1 / 93.4 |
//! | 9 | auto | cosine | neutral | 61.9 / 75.0 | 98.4 / 100.0 | 83.6 / 93.4 | 6.6 / 32.8 | 59.0 / 73.8 |
//! | 9 | auto | cosine | augmented | 78.3 / 91.8 | 98.4 / 100.0 | 78.7 / 91.8 | 65.6 / 93.4 | 70.5 / 82.0 |
//! | 9 | auto | Euclidean | neutral | 59.4 / 73.0 | 98.4 / 100.0 | 75.4 / 93.4 | 9.8 / 24.6 | 54.1 / 73.8 |
//! | 9 | auto | Euclidean | augmented | 76.2 / 92.2 | 96.7 / 100.0 | 77.0 / 93.4 | 59.0 / 93.4 | 72.1 / 82.0 |
//! | 9 | truth | cosine | neutral | 65.2 / 79.1 | 100.0 / 100.0 | 86.9 / 95.1 | 11.5 / 44.3 | 62.3 / 77.0 |
//! | 9 | truth | cosine | augmented | 77.0 / 91.8 | 100.0 / 100.0 | 78.7 / 91.8 | 55.7 / 93.4 | 73.8 / 82.0 |
//! | 9 | truth | Euclidean | neutral | 67.2 / 79.1 | 100.0 / 100.0 | 96.7 / 100.0 | 13.1 / 41.0 | 59.0 / 75.4 |
//! | 9 | truth | Euclidean | augmented | 80.7 / 96.3 | 100.0 / 100.0 | 83.6 / 100.0 | 70.5 / 100.0 | 68.9 / 85.2 |
//!
//! Augmentation buys +16 … +20 points rank-1 with the automatic pose (seed 8 Euclidean: 60.2 →
//! 79.9, the paper's +20 nearly); the goal of ≥ 90 % was not reached then (it is with the
//! expression weights, below). Before the FEM jaw
//! ([`crate::fem::jaw`]) the same runs, re-measured with the binary of commit a82766d, gave
//! 75.8 / 61.5 (seed 8) and 68.4 / 61.9 (seed 9, auto, cosine, augmented / neutral): the laugh
//! rose from 42.6 / 27.9 % to 63.9 / 65.6 %, because `surprise` now drops the jaw 8° and the
//! scan inside the opened lips is pushed back into a mouth cavity (the probes' open mouth is a
//! 20–25 mm deep cavity between the lips). The smile pays for it (93.4 / 86.9 → 86.9 / 78.7 %).
//! Tried on both seeds (before the lip rim was split by topology, which moved the default by
//! −0.4 / −0.8 points), every other open-jaw preset choice cost the smile more than it gained:
//! the jaw also in fear and pain 78.7 / 78.3 %, surprise at 12° 79.1 / 77.0, at 5° 79.9 / 77.9
//! (default then 79.9 / 79.1). Gestures barely gain (pucker, cheek puff, sideways mouth:
//! motions no preset makes). Extra samples, same conditions: `--jaw-open-deg 4,8,12` (three
//! open-mouth laughs per scan) 81.1 / 78.3 %; 15 presets learned with `fit-expression` from the
//! smiles, laughs and gestures of 5 other people (`synth_gavab.py --seed 100`, `augment
//! --presets`) 84.4 / 77.9 %; nearest class centroid instead of nearest sample 80.7 / 76.6 %;
//! the presets also at 2× (`--intensities 1,2`, before the jaw) 77.0 % on seed 8. The defaults
//! stay the 18 presets and the nearest sample. `--pose identity`: 20.1 / 21.7 % rank-1 (seed 7,
//! no augmentation); `--pose icp`: 58.2 / 57.4 %. scikit-learn (PCA →
//! LinearDiscriminantAnalysis, scripts/sklearn_crosscheck.py) on the same feature vectors
//! ranks every probe identically.
//!
//! **What the FEM expressions miss**, measured on the seed 8 feature vectors (`--features`,
//! numpy): the real `expression − frontal1` range images of the other half of the subjects,
//! added to S_w, give 95.5 % rank-1 (a ceiling for perfect synthetic expressions); their top
//! 3 principal directions alone give 90.9 %, the laughs' top one alone 87.7 %. Those
//! directions are the laugh's open mouth (59 % of the laughs' variance), the smile's cheeks
//! widening at the face's sides with the lips pressed back (42 %), and the gesture's jaw
//! contour moving (71 %). The closest synthetic expressions point along them with cosines
//! of only 0.77 (surprise, laugh), 0.60 (grimace, smile) and 0.87 (surprise, gesture), and
//! no scaling of their intensity helps (×1.5 … ×3: 78.7–81.6 %): the LDA needs the direction.
//! Other measured non-gains: Gaussian blur of the images (σ = 1–3 samples: −0.4 … −12 points),
//! a pose-nuisance prior in S_w (±1 mm, ±1°, ±0.5 mm shifts: −1 … +3.7 points, seed 9 none).
//! **Learned expressions** ([`ProtocolParams::expression_training`]): the same deviations
//! from *other* people (`synth_gavab.py --subjects 20 --seed 100`, renamed) give 94.7 / 94.7 %
//! (seeds 8 / 9; 10 people: 92.2 / 91.4 %; 5 people: 92.6 / 90.6 %; Euclidean, 20 people:
//! 95.5 / 93.0 %) beside the 18 FEM expressions; the report's `synthetic_only` keeps the
//! FEM-only figure (79.5 / 78.3 %). Kinds the training people lack are not learned: without
//! their gestures `gesto` stays at 68.9 / 73.8 % (all probes 91.4 / 91.4 %).
//!
//! **The soft-tissue loads and the laughter preset** (`assets/muscles.ron` `bulges`: AU6
//! `cheek_raiser`, then `buccal_bulge`, `infraorbital_bulge`, `nasolabial_fold`, in the presets
//! with AU6 and AU12; `laughter`, AU6 + 10 + 12 + 25 + 26 with the jaw open 8°, replaces the
//! former `grimace`). Same protocol, auto pose, 244 probes per seed, rank-1 % (rank-5):
//!
//! | seed | metric | neutral gallery | 18 FEM, before | + cheek_raiser | + all 4 loads and laughter | learned + FEM, now |
//! |---|---|---|---|---|---|---|
//! | 8 | cosine | 61.5 | 79.5 | 81.1 | **85.2** (95.1) | 95.5 |
//! | 8 | Euclidean | 60.2 | 79.9 | – | **86.1** (97.5) | 95.1 |
//! | 9 | cosine | 61.9 | 78.3 | 83.6 | **85.7** (95.1) | 94.7 |
//! | 9 | Euclidean | 59.4 | 76.2 | – | **84.0** (94.3) | 94.3 |
//!
//! Augmentation now gains +23.7 / +25.9 (seed 8) and +23.8 / +24.6 points (seed 9); the goal
//! of ≥ 90 % rank-1 with the FEM expressions alone was still missed (until the expression
//! weights, below). Per probe kind, cosine,
//! seed 8 / 9: frontal2 100 / 96.7, sonrisa 100 / 96.7, risa 75.4 / 83.6 (was 63.9 / 65.6
//! before the loads), gesto 65.6 / 65.6 (67.2 / 70.5): the gestures are what is left. Steps,
//! cosine, seed 8 / 9: the three new loads in the AU12 presets alone 82.0 / 82.8; with
//! `laughter` instead of `grimace` 85.2 / 85.7. Tried and not kept: three gesture presets
//! added to the 18 (jaw 5 mm left, 5 mm right, a cheek puff of `buccal_bulge` 2.0) 86.9 /
//! 84.0, the gestures 73.8 / 65.6 and the laugh 73.8 / 77.0; also a jaw thrust and two
//! sideways mouths, 86.9 / 85.2. The seed 8 subjects 0–5 supplied the ratios of the new loads
//! to the zygomatic (see `assets/expressions.ron`); seed 9 was not used to choose anything.
//! The large table above is from before the loads.
//! **Re-measured after the denoising removal and the feature-point changes** (spikes the
//! filter cannot repair are removed, so the synthetic samples carry small holes; outer eye
//! corners from any concave region; enclosed islands in the face segmentation), cosine:
//! FEM only 82.8 % (seed 8; risa 70.5, gesto 60.7) and 85.7 % (seed 9, unchanged; gesto
//! 70.5, risa 80.3), learned + FEM 96.3 / 94.7 %, neutral 61.5 / 61.9 %. Swapping the two
//! builds' augment and evaluate on seed 8 puts most of the seed-8 loss in augment (old
//! evaluate on the new gallery 83.2 %, new evaluate on the old gallery 84.8 %); one probe is
//! 0.4 points, and seed 9 did not move, so this is within what these changes shake loose.
//! **Re-measured after the feature points' face frame took its roll from the symmetry line**
//! (no gallery scan's inner corners changed; the frame moves the later points by a few mm):
//! FEM only 84.0 % (seed 8; risa 72.1, gesto 63.9) and 86.1 % (seed 9; risa 80.3, gesto
//! 68.9), learned + FEM 96.3 / 95.1 %, neutral 61.5 / 62.3 %.
//!
//! **Expression weights** ([`super::expression_weights`], default on with synthetic
//! expressions): every range-image sample is weighted `1/√(1 + σ²/s²)`, σ the RMS by which
//! the synthetic expressions move it, s = 0.5 mm. The FEM expressions point the wrong way for
//! the LDA (cosines 0.60–0.87 with the real directions, above) but at the right places; the
//! weights make every change there count less, in whatever direction. Same gallery
//! augmentation (same `augment` output), rank-1 % (rank-5), auto pose unless noted:
//!
//! | seed | metric | neutral gallery | 18 FEM, unweighted | 18 FEM, weighted | learned + FEM, weighted |
//! |---|---|---|---|---|---|
//! | 8 | cosine | 61.5 (74.2) | 84.0 (93.0) | **91.8** (96.3) | 98.4 (98.8) |
//! | 9 | cosine | 62.3 (75.0) | 86.1 | **91.8** (95.9) | 95.5 (99.6) |
//! | 8 | Euclidean | 60.2 (75.4) | 84.8 | **92.2** (98.8) | – |
//! | 9 | Euclidean | 59.4 (74.2) | 82.8 | **89.8** (96.3) | – |
//! | 8 | cosine, `--pose truth` | 63.9 (83.6) | – | 93.4 (98.0) | – |
//! | 10 | cosine | 66.4 (75.0) | 87.7 (94.7) | **91.0** (97.1) | – |
//! | 10 | Euclidean | 63.1 (74.2) | 86.1 (95.5) | **91.8** (98.0) | – |
//!
//! Per probe kind, weighted, cosine, seed 8 / 9: frontal2 100 / 98.4, sonrisa 100 / 98.4,
//! risa 93.4 / 95.1 (unweighted 72.1 / 80.3), gesto 73.8 / 75.4 (63.9 / 68.9). Augmentation
//! now gains +30.3 / +29.5 points. The scale, seed 8 / 9: 0.25 mm 91.8 / 91.8, 0.5 mm 91.8 /
//! 91.8, 1 mm 90.2 / 89.3 (2 mm: 88.1, 4 mm: 85.7 on seed 8; a first version without the
//! 3 × 3 median, 0.1 mm: 92.2 on seed 8); 0.5 mm was chosen on seed 8, seed 9 checked after,
//! and seed 10 (`synth_gavab.py --subjects 61 --seed 10`) generated afterwards as a second
//! held-out set: risa 91.8, gesto 72.1 % (cosine). Of the six seed × metric runs, Euclidean
//! on seed 9 is the one under 90 % (89.8: 219 of 244). The neutral-only run is never weighted (there is nothing to weight by). Weights
//! inside the mask: mean 0.38, smallest 0.09 (seed 8); the nose and nose bridge keep 0.6–0.7,
//! the forehead ~0.5, the mouth, cheeks and jaw 0.1–0.3. A fixed prior instead (the lower face
//! from 15 mm below the nose tip weighted 0.5, measured first) gave 90.6 % but raised the
//! neutral gallery too (68.0 %). scikit-learn on the weighted vectors (`--sw-floor 0`, so
//! both are the paper's plain LDA; 53.7 % rank-1): the same best identity for all 244 probes,
//! the same rank for 243 (one differs by 1: the f32 export). Real scans (8 probes, below):
//! 8 / 8 weighted, 7 / 8 unweighted (cara1's laugh at rank 2), 7 / 8 neutral gallery.
//! The weights cost one pass over the synthetic images: training both models took 1.45 s with
//! them; the whole seed-8 experiment (`augment`, then `evaluate --augmented --plot`, 3 runs)
//! 51.9 s wall median (46.7–55.6 s, 94 s CPU, 453 MiB peak) on a day this machine was slower
//! than for the figure below.
//! **Speed** (seed 8, release build, this 2-core machine; `farm-bench -n 3` of `augment` then
//! `evaluate --augmented --plot`): **35.9 s** wall end to end (median; 63.8 s CPU, 597 MiB peak).
//! `augment` ~17 s (61 scans: denoise, feature points, registration, FEM factor and the
//! 22-actuator basis, 18 expressions carried onto the scan with weights computed once per
//! scan). `evaluate` 19.0 s: starting poses 9.1 s (denoise + feature points of the 244 probes;
//! the 61 gallery scans reuse augment's), reference 0.7 s, refining and resampling the 305 scans
//! 1.9 s, the 1,098 synthetic range images 3.8 s, training both models (with and without
//! augmentation) 3.4 s, matching 0.1 s.
//!
//! **Real scans** (`scripts/gavab_real_dataset.sh`: everything in ../shared/data/gavabdb, the
//! nine cara1 VRML scans and 20 point clouds): 8 gallery subjects (frontal1 of cara1, 6, 7, 32,
//! 46, 48, 50, 53), 8 probes (cara1 frontal2, sonrisa, risa, gesto; cara6 frontal2, risa; cara50
//! and cara53 frontal2); 4 more probes have no gallery scan and are listed as failures. Rank-1
//! 8 / 8 with augmentation, 7 / 8 without (cosine; Euclidean 6 / 8 → 8 / 8); before the jaw the
//! miss with augmentation was cara1's gesture. Too few to measure a gain. Re-measured with the
//! expression weights: 8 / 8 with augmentation (unweighted 7 / 8: cara1's laugh at rank 2 after
//! the feature-point changes), 7 / 8 without.

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
    /// unaligned then from aligned gallery scans). Nose tip from the ground truth when there is
    /// one, else detected.
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
}

impl Default for ProtocolParams {
    fn default() -> Self {
        ProtocolParams {
            range: RangeImageParams::default(),
            // A within-class floor of 3× the mean S_w eigenvalue: chosen on seed 7 (61
            // synthetic subjects), confirmed on seed 8 (augmented rank-1 78.7 % vs 43.9 % with
            // the paper's plain LDA); see `FisherParams::within_class_regularisation`.
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

fn truth_json(scan_path: &Path) -> Option<PathBuf> {
    let p = scan_path.with_extension("json");
    p.is_file().then_some(p)
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = io::read_text_file(path)?;
    serde_json::from_str(&text).map_err(|e| Error::invalid(path, e.to_string()))
}

/// The ground-truth nose tip of a scan (`landmarks.nose_tip.xyz_mm` in the JSON beside it),
/// mm, scan frame; an error when there is no ground truth.
pub fn truth_nose_tip(scan_path: &Path) -> Result<DVec3> {
    let json = truth_json(scan_path)
        .ok_or_else(|| Error::invalid(scan_path, "no ground-truth JSON beside the scan"))?;
    let v = read_json(&json)?;
    let xyz = v["landmarks"]["nose_tip"]["xyz_mm"]
        .as_array()
        .filter(|a| a.len() == 3)
        .and_then(|a| a.iter().map(|x| x.as_f64()).collect::<Option<Vec<f64>>>())
        .ok_or_else(|| Error::invalid(&json, "landmarks.nose_tip.xyz_mm is not [x, y, z]"))?;
    Ok(DVec3::new(xyz[0], xyz[1], xyz[2]))
}

/// The nose tip of a scan, mm, scan frame: the ground truth beside it when there is one,
/// else the automatic detection on the denoised mesh.
pub fn nose_tip(scan_path: &Path) -> Result<DVec3> {
    if truth_json(scan_path).is_some() {
        truth_nose_tip(scan_path)
    } else {
        // The mesh is read only when there is no ground truth to take the tip from.
        Ok(detect_landmarks(&io::read_mesh(scan_path)?)?.get(crate::FeaturePoint::NoseTip))
    }
}

/// The ground-truth frontalising rotation (`face_from_scan`): the transpose of `pose.rotation`
/// in the JSON beside the scan (which maps model to scan); an error without ground truth.
pub fn truth_face_from_scan(scan_path: &Path) -> Result<DMat3> {
    let json = truth_json(scan_path)
        .ok_or_else(|| Error::invalid(scan_path, "no ground-truth JSON beside the scan"))?;
    let v = read_json(&json)?;
    let rows: Option<Vec<[f64; 3]>> = v["pose"]["rotation"].as_array().and_then(|rows| {
        rows.iter()
            .map(|r| {
                let r = r.as_array()?;
                (r.len() == 3).then_some(())?;
                Some([r[0].as_f64()?, r[1].as_f64()?, r[2].as_f64()?])
            })
            .collect()
    });
    match rows {
        // Rows of R are the columns of Rᵀ.
        Some(rows) if rows.len() == 3 => {
            Ok(DMat3::from_cols_array_2d(&[rows[0], rows[1], rows[2]]))
        }
        _ => Err(Error::invalid(&json, "pose.rotation is not a 3×3 array")),
    }
}

/// The nose tip and frontalising rotation of a scan from `params.pose` (before the ICP
/// refinement of [`PoseSource::Icp`], which starts from identity). `landmarks`: the scan's
/// feature points if already detected (augment's cache), used by [`PoseSource::Auto`]. The
/// mesh is read only where the pose needs it (not for cached points or the ground truth).
pub fn scan_pose(
    scan_path: &Path,
    params: &ProtocolParams,
    generic: &GenericFace,
    landmarks: Option<&crate::Landmarks>,
) -> Result<ScanPose> {
    Ok(scan_pose_checked(scan_path, params, generic, landmarks)?.0)
}

/// [`scan_pose`], and why the detected feature points are suspect (empty: they are not, or
/// none were detected). A scan whose points are suspect is not posed by them: it gets the
/// pose of face localisation's fit of the generic face (rotation and nose tip), which needs no
/// feature point, and [`PoseSource::Auto`] refines it against the gallery's mean as any other.
pub fn scan_pose_checked(
    scan_path: &Path,
    params: &ProtocolParams,
    generic: &GenericFace,
    landmarks: Option<&crate::Landmarks>,
) -> Result<(ScanPose, Vec<String>)> {
    match params.pose {
        PoseSource::Auto | PoseSource::Landmarks => {
            if let Some(points) = landmarks {
                return Ok((
                    pose_from_landmarks(points, generic, params.pose_points)?,
                    Vec::new(),
                ));
            }
            let report = detect_report(&io::read_mesh(scan_path)?)?;
            match report.localisation {
                Some(l) if !report.suspect.is_empty() => Ok((
                    ScanPose {
                        nose_tip_in_scan: l.nose_tip_in_scan,
                        face_from_scan: l.face_from_scan,
                    },
                    report.suspect,
                )),
                _ => Ok((
                    pose_from_landmarks(&report.landmarks, generic, params.pose_points)?,
                    report.suspect,
                )),
            }
        }
        PoseSource::Truth => Ok((
            ScanPose {
                nose_tip_in_scan: truth_nose_tip(scan_path)?,
                face_from_scan: truth_face_from_scan(scan_path)?,
            },
            Vec::new(),
        )),
        PoseSource::Identity | PoseSource::Icp => Ok((
            ScanPose {
                nose_tip_in_scan: nose_tip(scan_path)?,
                face_from_scan: DMat3::IDENTITY,
            },
            Vec::new(),
        )),
    }
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
    let cached: Vec<Option<crate::Landmarks>> = scans
        .iter()
        .map(|s| {
            augmented
                .filter(|_| {
                    matches!(params.pose, PoseSource::Auto | PoseSource::Landmarks)
                        && params.gallery_scans.contains(&s.scan)
                })
                .and_then(|aug| cached_landmarks(aug, s))
        })
        .collect();
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
        .map(|(s, lm)| {
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
                    suspect.push(Failure {
                        file: s.path.clone(),
                        reason: format!(
                            "suspect feature points ({}); posed by the generic face's fit instead",
                            reasons.join("; ")
                        ),
                    });
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
        (Some(dir), Some(t)) => {
            learned_deviations(dir, t, params, &generic, reference.as_ref(), &mut failures)?
        }
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
        cached_landmarks: cached.iter().filter(|c| c.is_some()).count(),
        seconds: t0.elapsed().as_secs_f64(),
        stage_seconds,
    })
}

/// The scans of the expression training set `dir` that [`learned_deviations`] uses (gallery
/// and probe kinds); a set sharing a subject with `dataset_scans` is refused (a probe's own
/// expressions would be learned). Checked before any scan is read.
fn training_scans(
    dir: &Path,
    dataset_scans: &[ScanFile],
    params: &ProtocolParams,
) -> Result<Vec<ScanFile>> {
    let scans = protocol_scans(dir, params)?;
    let mut shared: Vec<&str> = scans
        .iter()
        .filter(|t| dataset_scans.iter().any(|s| s.subject == t.subject))
        .map(|t| t.subject.as_str())
        .collect();
    shared.dedup();
    if !shared.is_empty() {
        return Err(Error::invalid(
            dir,
            format!(
                "expression training set shares {} subject(s) with the dataset ({}…): their own \
                 expressions would be learned; train on other people",
                shared.len(),
                shared[..shared.len().min(3)].join(", ")
            ),
        ));
    }
    Ok(scans)
}

/// The within-class deviations learned from the expression training `scans` (from
/// [`training_scans`], folder `dir`): for each person there with a gallery-kind scan, every
/// probe-kind scan's range image minus that gallery scan's, both posed as the evaluated scans
/// are (`reference`: the evaluated gallery's alignment reference, so the deviations live in
/// the same frame). Scans that fail are added to `failures` and skipped.
fn learned_deviations(
    dir: &Path,
    scans: &[ScanFile],
    params: &ProtocolParams,
    generic: &GenericFace,
    reference: Option<&RangeImage>,
    failures: &mut Vec<Failure>,
) -> Result<(Vec<Vec<f64>>, Vec<String>)> {
    let images: Vec<Option<Sample>> = scans
        .par_iter()
        .map(|s| {
            let start = scan_pose(&s.path, params, generic, None).map_err(|e| Failure {
                file: s.path.clone(),
                reason: format!("expression training: {e}"),
            })?;
            make_sample(&s.path, start, &s.subject, &s.scan, params, reference)
                .map(|(sample, _)| sample)
                .map_err(|f| Failure {
                    reason: format!("expression training: {}", f.reason),
                    ..f
                })
        })
        .collect::<Vec<_>>()
        .into_iter()
        .map(|r| r.map_err(|f| failures.push(f)).ok())
        .collect();
    // Each person's first gallery-kind scan that gave an image.
    let mut neutral: BTreeMap<&str, &Sample> = BTreeMap::new();
    for (s, img) in scans.iter().zip(&images) {
        if let Some(img) = img
            .as_ref()
            .filter(|_| params.gallery_scans.contains(&s.scan))
        {
            neutral.entry(s.subject.as_str()).or_insert(img);
        }
    }
    let mut deviations = Vec::new();
    let mut subjects: Vec<String> = Vec::new();
    for (s, img) in scans.iter().zip(&images) {
        let (Some(expression), Some(neutral)) = (
            img.as_ref()
                .filter(|_| params.probe_scans.contains(&s.scan)),
            neutral.get(s.subject.as_str()),
        ) else {
            continue;
        };
        deviations.push(
            expression
                .features
                .iter()
                .zip(&neutral.features)
                .map(|(e, n)| e - n)
                .collect(),
        );
        if subjects.last() != Some(&s.subject) {
            subjects.push(s.subject.clone());
        }
    }
    if deviations.is_empty() {
        return Err(Error::invalid(
            dir,
            format!(
                "no person with a {} scan and a {} scan that both gave range images",
                params.gallery_scans.join("|"),
                params.probe_scans.join("|")
            ),
        ));
    }
    Ok((deviations, subjects))
}

/// Runs the protocol on `dataset`, with the synthetic gallery expressions of `augmented` if
/// given.
pub fn evaluate(
    dataset: &Path,
    augmented: Option<&Path>,
    params: &ProtocolParams,
) -> Result<Evaluation> {
    let samples = collect_samples(dataset, augmented, params)?;
    score(&samples, true, params).map_err(|e| e.in_file(dataset))
}

/// Trains on the gallery (with the synthetic expressions and the learned deviations when
/// `with_synthetic`) and matches the probes.
pub fn score(
    samples: &Samples,
    with_synthetic: bool,
    params: &ProtocolParams,
) -> Result<Evaluation> {
    let mut evals = score_variants(samples, with_synthetic, &[with_synthetic], params)?;
    Ok(evals.remove(0))
}

/// One [`score`] per entry of `with_learned` (the learned deviations on or off; `evaluate`'s
/// `synthetic_only` figure has them off), on the same gallery: the models share their PCA
/// ([`FisherModel::train_variants`]), which is most of the training time.
pub fn score_variants(
    samples: &Samples,
    with_synthetic: bool,
    with_learned: &[bool],
    params: &ProtocolParams,
) -> Result<Vec<Evaluation>> {
    let t0 = Instant::now();
    let failures = &samples.failures;
    let mut gallery = samples.gallery.clone();
    if with_synthetic {
        gallery.extend(samples.synthetic.iter().cloned());
    }
    let mut identities: Vec<String> = gallery.iter().map(|s| s.subject.clone()).collect();
    identities.sort();
    identities.dedup();
    if identities.len() < 2 {
        return Err(Error::algorithm(
            "evaluate",
            format!(
                "{} gallery identities; need at least 2 ({} scans failed{})",
                identities.len(),
                failures.len(),
                failures
                    .first()
                    .map(|f| format!(", first: {}", f.reason))
                    .unwrap_or_default()
            ),
        ));
    }
    let id_of = |s: &str| identities.binary_search_by(|x| x.as_str().cmp(s)).ok();
    let labels: Vec<usize> = gallery.iter().map(|s| id_of(&s.subject).unwrap()).collect();
    let t1 = Instant::now();
    // Expression weights: only a gallery with synthetic expressions has them.
    let weights = match (&params.expression_weights, with_synthetic) {
        (Some(w), true) => {
            expression_weights(&samples.gallery, &samples.synthetic, &params.range, w)?
        }
        _ => None,
    };
    if let Some(w) = &weights {
        for s in gallery.iter_mut() {
            apply_weights(w, &mut s.features);
        }
    }
    let deviations: Cow<[Vec<f64>]> = match &weights {
        Some(w) => Cow::Owned(samples.deviations.iter().map(|d| weighted(w, d)).collect()),
        None => Cow::Borrowed(&samples.deviations),
    };
    // The probes once for all variants, weighted like the gallery.
    let probes: Cow<[Sample]> = match &weights {
        Some(w) => Cow::Owned(
            samples
                .probes
                .iter()
                .map(|p| Sample {
                    features: weighted(w, &p.features),
                    ..p.clone()
                })
                .collect(),
        ),
        None => Cow::Borrowed(&samples.probes),
    };
    let weighting = weights
        .as_deref()
        .zip(params.expression_weights.as_ref())
        .map(|(w, p)| WeightSummary::new(w, p, &params.range));
    let xs: Vec<&[f64]> = gallery.iter().map(|s| s.features.as_slice()).collect();
    let sets: Vec<&[Vec<f64>]> = with_learned
        .iter()
        .map(|&learned| -> &[Vec<f64>] {
            if with_synthetic && learned {
                &deviations
            } else {
                &[]
            }
        })
        .collect();
    let models = FisherModel::train_variants(&xs, &labels, &sets, &params.fisher)?;
    let t_train = t1.elapsed().as_secs_f64();
    models
        .into_iter()
        .zip(sets)
        .map(|(model, deviations)| {
            let learned = if model.method == Method::Fisherfaces {
                deviations.len()
            } else {
                0
            };
            rank_probes(
                samples,
                &model,
                learned,
                Matching {
                    gallery: &gallery,
                    labels: &labels,
                    identities: &identities,
                    probes: &probes,
                    weighting,
                },
                failures.clone(),
                (t0, t_train),
                params,
            )
        })
        .collect()
}

/// The expression weights a run used, as the report gives them.
#[derive(Debug, Clone, Copy)]
struct WeightSummary {
    scale_mm: f64,
    /// Smallest and mean weight inside the elliptic mask.
    min: f64,
    mean: f64,
}

impl WeightSummary {
    fn new(w: &[f64], params: &ExpressionWeightParams, range: &RangeImageParams) -> Self {
        let (mut min, mut sum, mut n) = (1.0f64, 0.0, 0usize);
        for (x, _) in w.iter().zip(range.mask()).filter(|(_, m)| *m) {
            min = min.min(*x);
            sum += x;
            n += 1;
        }
        WeightSummary {
            scale_mm: params.scale_mm,
            min,
            mean: sum / n.max(1) as f64,
        }
    }
}

/// What one model is matched with: the gallery it was trained on and the probes, both weighted
/// when `weighting` is set.
struct Matching<'a> {
    gallery: &'a [Sample],
    /// Identity index of every gallery sample.
    labels: &'a [usize],
    identities: &'a [String],
    probes: &'a [Sample],
    weighting: Option<WeightSummary>,
}

/// Projects the gallery and the probes with `model` and ranks every probe (one variant of
/// [`score_variants`]).
fn rank_probes(
    samples: &Samples,
    model: &FisherModel,
    learned: usize,
    matching: Matching,
    mut failures: Vec<Failure>,
    (t0, t_train): (Instant, f64),
    params: &ProtocolParams,
) -> Result<Evaluation> {
    let Matching {
        gallery,
        labels,
        identities,
        probes,
        weighting,
    } = matching;
    let t_images = samples.seconds;
    let id_of = |s: &str| identities.binary_search_by(|x| x.as_str().cmp(s)).ok();
    let t2 = Instant::now();
    let gproj: Vec<Vec<f64>> = gallery
        .par_iter()
        .map(|s| model.project(&s.features))
        .collect();
    let n = identities.len();
    let mut ranks = Vec::new();
    let mut best = Vec::new();
    let mut kinds = Vec::new();
    let mut matched = Vec::new();
    for p in probes {
        let Some(truth) = id_of(&p.subject) else {
            failures.push(Failure {
                file: p.path.clone(),
                reason: format!("subject {} has no gallery scan", p.subject),
            });
            continue;
        };
        let proj = model.project(&p.features);
        let mut dist = vec![f64::INFINITY; n];
        for (g, &l) in gproj.iter().zip(labels) {
            dist[l] = dist[l].min(params.metric.distance(g, &proj));
        }
        ranks.push(rank_of(&dist, truth));
        let b = (0..n).min_by(|&i, &j| dist[i].total_cmp(&dist[j])).unwrap();
        best.push(identities[b].clone());
        kinds.push((p.kind.clone(), *ranks.last().unwrap()));
        matched.push(p);
    }
    let t_match = t2.elapsed().as_secs_f64();
    let (all, by_probe_kind) = rates_by_kind(&kinds, n);
    let method_note = match model.method {
        Method::Fisherfaces => format!(
            "Fisherfaces: PCA to M - c = {} dims, LDA to c - 1 = {}{}",
            model.pca_dims,
            model.dims(),
            weighting.map_or(String::new(), |w| format!(
                "; samples weighted by the synthetic expressions' spread (scale {} mm)",
                w.scale_mm
            ))
        ),
        Method::Eigenfaces => format!(
            "Eigenfaces (PCA to {} dims): one gallery sample per subject, so S_w = 0 and LDA is undefined",
            model.pca_dims
        ),
    };
    let synthetic = gallery.iter().filter(|s| s.kind == "synthetic").count();
    let mut seconds = BTreeMap::new();
    seconds.insert("range_images".to_string(), t_images);
    for (k, v) in &samples.stage_seconds {
        seconds.insert(format!("range_images.{k}"), *v);
    }
    seconds.insert("train".to_string(), t_train);
    seconds.insert("match".to_string(), t_match);
    seconds.insert("total".to_string(), t_images + t0.elapsed().as_secs_f64());
    let per_probe = matched
        .iter()
        .zip(&ranks)
        .zip(&best)
        .map(|((p, &rank), b)| ProbeResult {
            file: p.path.clone(),
            subject: p.subject.clone(),
            kind: p.kind.clone(),
            rank,
            best_match: b.clone(),
        })
        .collect();
    let report = Report {
        subjects: n,
        probes: matched.len(),
        method: model.method,
        method_note,
        metric: params.metric,
        pose: params.pose,
        pose_points: params.pose_points,
        cached_landmarks: samples.cached_landmarks,
        rank1: all.rank1,
        rank5: all.rank5,
        cmc: all.cmc,
        by_probe_kind,
        failures,
        suspect: samples.suspect.clone(),
        per_probe,
        gallery_samples: gallery.len(),
        synthetic_gallery_samples: synthetic,
        learned_deviations: learned,
        expression_training_subjects: if learned > 0 {
            samples.training_subjects.len()
        } else {
            0
        },
        expression_weight_scale_mm: weighting.map(|w| w.scale_mm),
        expression_weight_min: weighting.map(|w| w.min),
        expression_weight_mean: weighting.map(|w| w.mean),
        gallery_scans: params.gallery_scans.clone(),
        pca_dims: model.pca_dims,
        projected_dims: model.dims(),
        feature_length: params.range.len(),
        range_image: params.range,
        seconds,
    };
    Ok(Evaluation {
        report,
        gallery: gallery.to_vec(),
        probes: matched.into_iter().cloned().collect(),
        identities: identities.to_vec(),
        ranks,
        best,
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
