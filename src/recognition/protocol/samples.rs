//! Building the protocol's samples: every scan's start pose, the alignment reference, the
//! range images of the scans and of the synthetic expressions.

use super::*;

/// Builds one sample (range image) from a mesh file in the pose `start` (the scan's own, or
/// its gallery scan's for a synthetic expression), first refined against `reference` when
/// given ([`PoseSource::Auto`]: rotation and nose tip, [`refine_pose`]; [`PoseSource::Icp`]:
/// rotation only). Returns the pose used.
pub(super) fn make_sample(
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
    /// The rotation applied to each real scan that gave a sample (gallery and probes, file
    /// order; then the expression-training scans, [`ProtocolParams::expression_training`]).
    pub poses: Vec<ScanOrientation>,
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

/// The rotation the protocol applied to one scan: the pose its range image was taken in, as
/// the scan axes the face looks along and up and the head's turn (`landmarks --json`'s
/// `orientation` conventions, [`crate::landmarks::localise::yaw_pitch_roll_deg`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ScanOrientation {
    pub scan: PathBuf,
    pub facing: &'static str,
    pub up: &'static str,
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    pub roll_deg: f64,
}

impl ScanOrientation {
    pub(super) fn of(scan: &Path, pose: &ScanPose) -> Self {
        use crate::landmarks::localise::{facing_and_up, yaw_pitch_roll_deg};
        let (facing, up) = facing_and_up(pose.face_from_scan);
        let (yaw, pitch, roll) = yaw_pitch_roll_deg(pose.face_from_scan);
        let round = |x: f64| (x * 10.0).round() / 10.0;
        ScanOrientation {
            scan: scan.to_path_buf(),
            facing,
            up,
            yaw_deg: round(yaw),
            pitch_deg: round(pitch),
            roll_deg: round(roll),
        }
    }
}

/// Augment's detected feature points of a gallery scan (`AUG/<stem>/done.json`, field
/// `landmarks`), when that file is for this very scan file.
fn cached_landmarks(augmented: &Path, scan: &ScanFile) -> Option<crate::Landmarks> {
    let stem = scan.path.file_stem()?.to_str()?;
    let done = augmented.join(stem).join(crate::augment::DONE_MARKER);
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
        Some(aug) => crate::augment::read_augment_failures(aug)?,
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
    let mut poses = Vec::new();
    for (s, r) in scans.iter().zip(results) {
        if let Ok((_, frame)) = &r {
            poses.push(ScanOrientation::of(&s.path, frame));
        }
        match r {
            Ok((sample, frame)) if params.gallery_scans.contains(&s.scan) => {
                gallery.push(sample);
                if let Some(aug) = augmented {
                    let dir = aug.join(format!("{}_{}", s.subject, s.scan));
                    // A folder without the done marker is from a killed or failed `augment`:
                    // its meshes may be a partial set, so none of them is used.
                    if dir.is_dir() && !dir.join(crate::augment::DONE_MARKER).is_file() {
                        failures.push(Failure {
                            file: dir.clone(),
                            reason: format!(
                                "augmentation unfinished (no {}); re-run `facesynth augment`",
                                crate::augment::DONE_MARKER
                            ),
                        });
                    } else if dir.is_dir() {
                        for p in crate::io::read_dir_sorted(&dir)? {
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
            (&mut failures, &mut suspect, &mut poses),
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
        poses,
        augment_failures,
        seconds: t0.elapsed().as_secs_f64(),
        stage_seconds,
    })
}
