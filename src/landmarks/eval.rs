//! Scoring [`super::detect`] against the ground truth of `../shared/bench/synth_gavab.py`
//! (`facesynth eval-landmarks DIR`).
//!
//! Error = 3D distance, mm, between a detected point and its ground truth, for the 9 points
//! the generator provides (nose tip, eye corners, nose corners = iBUG 31/35, mouth corners,
//! chin = iBUG 8). Points the generator marks as not visible (closed lids, out of view) are
//! left out of the statistics and of the success test. A scan is a **success** when every
//! scored point is within [`SUCCESS_RADIUS_MM`]; a scan where detection fails counts as a
//! failure. Neutral scans (`frontal1`, `frontal2`) and expression scans (`sonrisa`, `risa`,
//! `gesto`) are reported separately.
//!
//! Measured accuracy on the benchmark (per point, with the mean offsets) and the command:
//! `docs/measurements.md`, "Feature points: benchmark accuracy".

use super::{Frame, LandmarkParams, detect};
use crate::denoise;
use crate::feature_points::FeaturePoint;
use crate::ground_truth::ScanTruth;
use crate::{Error, Result, io};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// A scan succeeds when all its scored points are within this distance, mm.
pub const SUCCESS_RADIUS_MM: f64 = 10.0;

/// One scan's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct ScanResult {
    /// File stem, e.g. `subj003_risa`.
    pub stem: String,
    /// `frontal1`, `frontal2`, `sonrisa`, `risa` or `gesto`.
    pub scan: String,
    /// Point name → error in mm (visible ground-truth points only).
    pub errors_mm: BTreeMap<String, f64>,
    /// Point name → the error as a vector in the detection's face frame, mm: (lateral, up,
    /// towards the scanner), lateral counted away from the midline (towards the subject's
    /// left for midline points). Its length is the point's `errors_mm`.
    pub offsets_mm: BTreeMap<String, [f64; 3]>,
    /// The detected points (all 13), mm.
    pub detected: BTreeMap<String, [f64; 3]>,
    /// Every scored point within [`SUCCESS_RADIUS_MM`].
    pub success: bool,
    /// Detection error message, if detection failed.
    pub failure: Option<String>,
    /// Why the detection flagged itself as suspect (`LandmarkReport::suspect`); empty if not.
    pub suspect: Vec<String>,
    /// Plausibility warnings of the detection.
    pub warnings: Vec<String>,
    /// Point name → the spread of the consensus views, mm (`LandmarkReport::spread_mm`; empty
    /// without localisation).
    pub spread_mm: BTreeMap<String, f64>,
    /// Roll of the detection's face frame, degrees (0 where detection failed); with the
    /// detected nose tip it gives the frame in which errors split into lateral and vertical.
    pub roll_deg: f64,
    /// Denoise + detection time, ms.
    pub millis: f64,
}

impl ScanResult {
    pub fn is_neutral(&self) -> bool {
        self.scan.starts_with("frontal")
    }
}

/// Error statistics of one point over a group of scans, mm.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PointStats {
    /// Scans in which the point was scored.
    pub n: usize,
    pub mean_mm: f64,
    pub p95_mm: f64,
    pub max_mm: f64,
    /// Fraction within [`SUCCESS_RADIUS_MM`].
    pub within_10mm: f64,
    /// Mean of [`ScanResult::offsets_mm`]: the systematic part of the error (lateral away
    /// from the midline, up, towards the scanner), mm. Where it is large the detector finds a
    /// different point than the ground truth names, consistently.
    pub mean_offset_mm: [f64; 3],
}

/// Statistics of a group of scans (neutral or expression).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GroupSummary {
    pub scans: usize,
    /// Scans where detection returned points.
    pub detected: usize,
    /// Fraction of scans with every scored point within 10 mm.
    pub success_rate: f64,
    /// Scans that failed (not detected, or a point over 10 mm) ...
    pub failed: usize,
    /// ... and of those, the ones the detector flagged (an error or suspect): failures a user
    /// is told about.
    pub failed_flagged: usize,
    /// Successful scans flagged suspect anyway (false alarms).
    pub succeeded_flagged: usize,
    pub points: BTreeMap<String, PointStats>,
    pub mean_millis: f64,
}

/// The whole evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    pub dir: String,
    pub denoised: bool,
    pub scans: Vec<ScanResult>,
}

/// Both groups.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Summary {
    pub neutral: GroupSummary,
    pub expression: GroupSummary,
}

impl EvalReport {
    pub fn summary(&self) -> Summary {
        let group =
            |neutral: bool| summarize(self.scans.iter().filter(|s| s.is_neutral() == neutral));
        Summary {
            neutral: group(true),
            expression: group(false),
        }
    }
}

fn summarize<'a>(scans: impl Iterator<Item = &'a ScanResult>) -> GroupSummary {
    let scans: Vec<&ScanResult> = scans.collect();
    let mut per: BTreeMap<String, (Vec<f64>, [f64; 3])> = BTreeMap::new();
    for s in &scans {
        if s.failure.is_some() {
            continue;
        }
        for (k, e) in &s.errors_mm {
            let (errors, offset_sum) = per.entry(k.clone()).or_default();
            errors.push(*e);
            for (sum, o) in offset_sum.iter_mut().zip(s.offsets_mm[k]) {
                *sum += o;
            }
        }
    }
    let points = per
        .into_iter()
        .map(|(k, (mut e, offset_sum))| {
            e.sort_by(f64::total_cmp);
            let n = e.len();
            let p95 = e[((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1];
            let stats = PointStats {
                n,
                mean_mm: e.iter().sum::<f64>() / n as f64,
                p95_mm: p95,
                max_mm: e[n - 1],
                within_10mm: e.iter().filter(|&&x| x <= SUCCESS_RADIUS_MM).count() as f64
                    / n as f64,
                mean_offset_mm: offset_sum.map(|o| o / n as f64),
            };
            (k, stats)
        })
        .collect();
    let total = scans.len().max(1) as f64;
    GroupSummary {
        scans: scans.len(),
        detected: scans.iter().filter(|s| s.failure.is_none()).count(),
        success_rate: scans.iter().filter(|s| s.success).count() as f64 / total,
        failed: scans.iter().filter(|s| !s.success).count(),
        failed_flagged: scans
            .iter()
            .filter(|s| !s.success && (s.failure.is_some() || !s.suspect.is_empty()))
            .count(),
        succeeded_flagged: scans
            .iter()
            .filter(|s| s.success && !s.suspect.is_empty())
            .count(),
        points,
        mean_millis: scans.iter().map(|s| s.millis).sum::<f64>() / total,
    }
}

/// Scores one scan file (`stem.wrl`) against its ground truth (`stem.json`).
pub fn evaluate_scan(
    mesh_path: &Path,
    truth: &ScanTruth,
    denoise_first: bool,
    params: &LandmarkParams,
) -> Result<ScanResult> {
    let mut mesh = io::read_mesh(mesh_path)?;
    let start = std::time::Instant::now();
    let found = (|| {
        if denoise_first {
            denoise::denoise(&mut mesh, &denoise::DenoiseParams::default())?;
        }
        detect(&mesh, params)
    })();
    let millis = start.elapsed().as_secs_f64() * 1e3;
    let stem = mesh_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut out = ScanResult {
        stem,
        scan: truth.scan.clone(),
        errors_mm: BTreeMap::new(),
        offsets_mm: BTreeMap::new(),
        detected: BTreeMap::new(),
        success: false,
        failure: None,
        suspect: Vec::new(),
        warnings: Vec::new(),
        spread_mm: BTreeMap::new(),
        roll_deg: 0.0,
        millis,
    };
    match found {
        Err(e) => out.failure = Some(e.to_string()),
        Ok(report) => {
            // The detection's face frame, only its rotation: errors are differences.
            let frame = Frame::new(DVec3::ZERO, report.roll_deg.to_radians());
            for (p, xyz, t) in truth.feature_points() {
                if t.visible {
                    let d = report.landmarks.get(p) - xyz;
                    // Away from the midline; midline points towards the subject's left.
                    let lateral = if p.side() < 0.0 { -1.0 } else { 1.0 };
                    let uv = frame.uv(d);
                    let offset = [lateral * uv.x, uv.y, d.z];
                    out.errors_mm.insert(p.name().to_string(), d.length());
                    out.offsets_mm.insert(p.name().to_string(), offset);
                }
            }
            out.success = out.errors_mm.values().all(|&e| e <= SUCCESS_RADIUS_MM);
            out.warnings = report.warnings;
            out.suspect = report.suspect;
            if let Some(spread) = report.spread_mm {
                out.spread_mm = FeaturePoint::ALL
                    .iter()
                    .map(|p| (p.name().to_string(), spread[p.index()]))
                    .collect();
            }
            out.roll_deg = report.roll_deg;
            out.detected = report.landmarks.to_map();
        }
    }
    Ok(out)
}

/// Scores every scan of a synth_gavab.py folder (in parallel over scans).
pub fn evaluate_dir(
    dir: &Path,
    denoise_first: bool,
    params: &LandmarkParams,
) -> Result<EvalReport> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut stems: Vec<String> = rd
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "wrl"))
        .filter(|p| p.with_extension("json").exists())
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    stems.sort();
    if stems.is_empty() {
        return Err(Error::invalid(
            dir,
            "no scan with ground truth (NAME.wrl + NAME.json) in this folder",
        ));
    }
    let scans = stems
        .par_iter()
        .map(|stem| {
            let truth = ScanTruth::load(&dir.join(format!("{stem}.json")))?;
            evaluate_scan(
                &dir.join(format!("{stem}.wrl")),
                &truth,
                denoise_first,
                params,
            )
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(EvalReport {
        dir: dir.display().to_string(),
        denoised: denoise_first,
        scans,
    })
}

/// The 9 points with ground truth, in [`FeaturePoint::ALL`] order.
pub fn scored_points() -> Vec<FeaturePoint> {
    FeaturePoint::ALL
        .into_iter()
        .filter(|&p| crate::ground_truth::truth_name(p).is_some())
        .collect()
}
