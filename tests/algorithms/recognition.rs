//! Recognition on a small generated synthetic GavabDB-like set (paper section 4 protocol).

use crate::common;

use facesynth::io;
use facesynth::recognition::{Method, Metric, PoseSource, ProtocolParams, evaluate, protocol};
use std::path::Path;

const SUBJECTS: usize = 6;
const SEED: u64 = 31;

fn check_cmc(cmc: &[f64], n: usize) {
    assert_eq!(cmc.len(), n);
    assert!(cmc.windows(2).all(|w| w[0] <= w[1]), "{cmc:?}");
    assert_eq!(*cmc.last().unwrap(), 1.0);
}

/// The scans without their ground-truth JSON, as real scans come.
fn without_ground_truth(dir: &Path) -> tempfile::TempDir {
    let copy = tempfile::tempdir().unwrap();
    for s in protocol::list_scans(dir).unwrap() {
        std::fs::copy(&s.path, copy.path().join(s.path.file_name().unwrap())).unwrap();
    }
    copy
}

#[test]
fn neutral_gallery_recognises_neutral_probes_with_eigenfaces_and_automatic_pose() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    // No ground truth: nose tip and pose come from the pipeline (PoseSource::Auto).
    let copy = without_ground_truth(&dir);
    let params = ProtocolParams::default();
    assert_eq!(params.pose, PoseSource::Auto);
    let samples = protocol::collect_samples(copy.path(), None, &params).unwrap();
    for metric in [Metric::Cosine, Metric::Euclidean] {
        let params = ProtocolParams {
            metric,
            ..ProtocolParams::default()
        };
        let eval = protocol::score(&samples, true, &params).unwrap();
        let r = &eval.report;
        assert!(r.failures.is_empty(), "{:?}", r.failures);
        assert_eq!(r.subjects, SUBJECTS);
        assert_eq!(r.probes, 4 * SUBJECTS);
        assert_eq!(r.method, Method::Eigenfaces, "one sample per class: no LDA");
        assert!(r.method_note.contains("S_w = 0"));
        assert_eq!(r.feature_length, 9879);
        check_cmc(&r.cmc, SUBJECTS);
        for rates in r.by_probe_kind.values() {
            check_cmc(&rates.cmc, SUBJECTS);
            assert_eq!(rates.probes, SUBJECTS);
        }
        // Chance is 1/6; the second neutral scan differs only in pose, grid phase and noise.
        let frontal2 = r.by_probe_kind["frontal2"].rank1;
        assert!(
            frontal2 >= 5.0 / 6.0,
            "{metric:?}: frontal2 rank-1 {frontal2}"
        );
    }
}

/// An "augmented" folder with one pseudo-expression per subject: the frontal1 scan with a
/// smooth 3 mm bulge below the nose, written as OBJ in the scan's frame.
fn bulge_augmented(dir: &Path) -> tempfile::TempDir {
    let aug = tempfile::tempdir().unwrap();
    for s in protocol::list_scans(dir).unwrap() {
        if s.scan != "frontal1" {
            continue;
        }
        let mut mesh = io::read_mesh(&s.path).unwrap();
        let nose = protocol::nose_tip(&s.path).unwrap();
        for p in &mut mesh.positions_mm {
            let dy = p.y - (nose.y - 40.0);
            p.z += 3.0 * (-(dy * dy + (p.x - nose.x).powi(2)) / 400.0).exp();
        }
        let out = aug.path().join(format!("{}_frontal1", s.subject));
        std::fs::create_dir_all(&out).unwrap();
        io::write_mesh(&out.join("bulge.obj"), &mesh).unwrap();
        // `augment` marks a finished folder; evaluate uses only marked ones.
        std::fs::write(out.join(facesynth::augment::DONE_MARKER), "{}\n").unwrap();
    }
    aug
}

#[test]
fn two_neutral_gallery_uses_lda_and_augmented_folder_is_read() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let aug = bulge_augmented(&dir);
    let eval = evaluate(&dir, Some(aug.path()), &ProtocolParams::default()).unwrap();
    let r = &eval.report;
    assert!(r.failures.is_empty(), "{:?}", r.failures);
    assert_eq!(r.gallery_samples, 2 * SUBJECTS);
    assert_eq!(r.synthetic_gallery_samples, SUBJECTS);
    assert_eq!(r.method, Method::Fisherfaces);
    assert_eq!(r.pca_dims, 2 * SUBJECTS - SUBJECTS);
    assert_eq!(r.projected_dims, SUBJECTS - 1);
    check_cmc(&r.cmc, SUBJECTS);

    // Gallery of both neutral scans, expressions as probes: LDA with real within-class data.
    let params = ProtocolParams {
        gallery_scans: vec!["frontal1".into(), "frontal2".into()],
        probe_scans: vec!["sonrisa".into(), "risa".into(), "gesto".into()],
        ..ProtocolParams::default()
    };
    let eval = evaluate(&dir, None, &params).unwrap();
    let r = &eval.report;
    assert_eq!(r.method, Method::Fisherfaces);
    assert_eq!(r.probes, 3 * SUBJECTS);
    // Measured 0.67 (12 of 18 probes); chance is 1/6.
    assert!(r.rank1 >= 0.55, "rank-1 {}", r.rank1);
    check_cmc(&r.cmc, SUBJECTS);
}

#[test]
fn expression_weights_damp_where_the_synthetic_expressions_move_the_face() {
    use facesynth::recognition::expression_weights::expression_weights;
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let aug = bulge_augmented(&dir);
    let params = ProtocolParams::default();
    let samples = protocol::collect_samples(&dir, Some(aug.path()), &params).unwrap();
    let weights = params.expression_weights.unwrap();
    let w = expression_weights(
        &samples.gallery,
        &samples.synthetic,
        &params.range,
        &weights,
    )
    .unwrap()
    .expect("every synthetic sample has its gallery scan");
    let at = |x: f64, y: f64| {
        let r = &params.range;
        let (i, j) = (0..r.cols)
            .flat_map(|i| (0..r.rows).map(move |j| (i, j)))
            .min_by(|&(a, b), &(c, d)| {
                let e = |i, j| {
                    let (sx, sy) = r.sample_xy_mm(i, j);
                    (sx - x).powi(2) + (sy - y).powi(2)
                };
                e(a, b).total_cmp(&e(c, d))
            })
            .unwrap();
        w[j * r.cols + i]
    };
    // The bulge: 3 mm at 40 mm below the nose tip, σ² ≈ 9 mm², so w ≈ 1/√(1 + 36) ≈ 0.16
    // (the pose refinement moves the images by a little; hence the margins).
    assert!(at(0.0, -40.0) < 0.3, "bulge centre {}", at(0.0, -40.0));
    // Nothing moved on the forehead or at the sides of the nose bridge.
    for (x, y) in [(0.0, 45.0), (-20.0, 30.0), (20.0, 30.0)] {
        assert!(at(x, y) > 0.9, "({x}, {y}): {}", at(x, y));
    }
    // The augmented run is weighted and says so; the run without synthetic samples is not.
    let with = protocol::score(&samples, true, &params).unwrap().report;
    assert_eq!(with.expression_weight_scale_mm, Some(0.5));
    assert!(
        with.method_note.contains("weighted"),
        "{}",
        with.method_note
    );
    assert!(with.expression_weight_min.unwrap() < 0.3);
    let without = protocol::score(&samples, false, &params).unwrap().report;
    assert_eq!(without.expression_weight_scale_mm, None);
    assert!(!without.method_note.contains("weighted"));
    // Off: the model sees the range images as they are.
    let off = ProtocolParams {
        expression_weights: None,
        ..ProtocolParams::default()
    };
    let eval = protocol::score(&samples, true, &off).unwrap();
    assert_eq!(eval.report.expression_weight_scale_mm, None);
    assert_eq!(eval.gallery[0].features, samples.gallery[0].features);
}

#[test]
fn missing_ground_truth_is_a_failure_not_a_crash() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let copy = tempfile::tempdir().unwrap();
    for s in protocol::list_scans(&dir).unwrap() {
        let name = s.path.file_name().unwrap();
        std::fs::copy(&s.path, copy.path().join(name)).unwrap();
        // Ground truth for every scan but subject 0's frontal2.
        if !(s.subject == "subj000" && s.scan == "frontal2") {
            let json = s.path.with_extension("json");
            std::fs::copy(&json, copy.path().join(json.file_name().unwrap())).unwrap();
        }
    }
    let params = ProtocolParams {
        pose: PoseSource::Truth,
        probe_scans: vec!["frontal2".into()],
        ..ProtocolParams::default()
    };
    let eval = evaluate(copy.path(), None, &params).unwrap();
    assert_eq!(eval.report.failures.len(), 1);
    let f = &eval.report.failures[0];
    assert!(f.file.ends_with(Path::new("subj000_frontal2.wrl")));
    assert!(f.reason.contains("ground-truth"), "{}", f.reason);
    assert_eq!(eval.report.probes, SUBJECTS - 1);
}

#[test]
fn evaluate_command_writes_the_report() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let out = tempfile::tempdir().unwrap();
    let report = out.path().join("report.json");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args(["evaluate", "--metric", "euclidean", "--dataset"])
        .arg(&dir)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in [
        "subjects",
        "probes",
        "method",
        "metric",
        "rank1",
        "rank5",
        "cmc",
        "by_probe_kind",
        "failures",
    ] {
        assert!(v.get(key).is_some(), "report lacks {key}");
    }
    assert_eq!(v["metric"], "euclidean");
    assert_eq!(v["method"], "eigenfaces");
    assert_eq!(v["cmc"].as_array().unwrap().len(), SUBJECTS);
    // Per probe: as many as matched, and their ranks give the CMC's rank-1.
    let per = v["per_probe"].as_array().unwrap();
    assert_eq!(per.len() as u64, v["probes"].as_u64().unwrap());
    let first = per.iter().filter(|p| p["rank"] == 1).count() as f64 / per.len() as f64;
    assert!((first - v["rank1"].as_f64().unwrap()).abs() < 1e-12);
    for p in per {
        let recognised = p["best_match"] == p["subject"];
        assert_eq!(recognised, p["rank"] == 1, "{p}");
        assert!(
            p["file"]
                .as_str()
                .unwrap()
                .contains(p["subject"].as_str().unwrap())
        );
    }
    // The rotation applied to every scan that gave a sample: each probe is there, facing the
    // scanner (+z, up +y), with the head's yaw and roll within 4° of the generator's (measured
    // at most 2.8° over 130 scans; the pitch is the face frame's, which differs from the
    // model's by each face's own slope, so it is not compared).
    let poses = v["poses"].as_array().unwrap();
    for p in per {
        assert!(poses.iter().any(|q| q["scan"] == p["file"]), "{p}");
    }
    for q in poses {
        assert!(q["facing"] == "+z" && q["up"] == "+y", "{q}");
        let truth = std::path::Path::new(q["scan"].as_str().unwrap()).with_extension("json");
        let truth: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(truth).unwrap()).unwrap();
        let t = &truth["pose"]["yaw_pitch_roll_deg"];
        for (k, i) in [("yaw_deg", 0), ("roll_deg", 2)] {
            let d = q[k].as_f64().unwrap() - t[i].as_f64().unwrap();
            assert!(d.abs() < 4.0, "{k} off by {d:.1}°: {q}");
        }
    }
    let stdout: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(stdout, v);
}

#[test]
fn expressions_learned_from_other_people_join_the_within_class_scatter() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let aug = bulge_augmented(&dir);
    // Four other people (another seed), renamed so no subject name is shared.
    let others = common::synth_dataset(4, SEED + 1, false);
    let training = tempfile::tempdir().unwrap();
    for s in protocol::list_scans(&others).unwrap() {
        let name = format!("other{}_{}.wrl", s.subject, s.scan);
        std::fs::copy(&s.path, training.path().join(name)).unwrap();
    }
    // A profile (a real scan turned 44°) among them is posed by the generic face's fit and
    // listed as suspect; its person has no gallery-kind scan, so it adds no deviation.
    std::fs::copy(
        common::gavab("cara1_derecha.wrl"),
        training.path().join("profile_risa.wrl"),
    )
    .unwrap();
    // A broken training scan is listed, not fatal.
    std::fs::write(
        training.path().join("broken_risa.wrl"),
        "#VRML V2.0 utf8\nShape {",
    )
    .unwrap();
    let params = ProtocolParams {
        expression_training: Some(training.path().to_path_buf()),
        ..ProtocolParams::default()
    };
    let samples = protocol::collect_samples(&dir, Some(aug.path()), &params).unwrap();
    // Each person: frontal2, sonrisa, risa and gesto minus frontal1.
    assert_eq!(samples.deviations.len(), 4 * 4);
    assert_eq!(samples.training_subjects.len(), 4);
    assert_eq!(samples.failures.len(), 1, "{:?}", samples.failures);
    assert!(samples.failures[0].file.ends_with("broken_risa.wrl"));
    assert!(
        samples
            .suspect
            .iter()
            .any(|f| f.file.ends_with("profile_risa.wrl")
                && f.reason
                    .starts_with("expression training: suspect feature points")),
        "{:?}",
        samples.suspect
    );
    assert!(
        samples.failures[0]
            .reason
            .starts_with("expression training: ")
    );
    // Every training scan that gave an image reports its pose: the 20 generated ones facing the
    // scanner, the profile turned well away from it.
    let training_poses: Vec<_> = (samples.poses.iter())
        .filter(|p| p.scan.starts_with(training.path()))
        .collect();
    assert_eq!(training_poses.len(), 4 * 5 + 1, "{training_poses:?}");
    for p in &training_poses {
        let profile = p.scan.ends_with("profile_risa.wrl");
        assert_eq!(profile, p.yaw_deg.abs() > 30.0, "{p:?}");
    }
    let learned = protocol::score(&samples, true, &params).unwrap().report;
    assert_eq!(learned.learned_deviations, 16);
    assert_eq!(learned.expression_training_subjects, 4);
    assert_eq!(learned.method, Method::Fisherfaces);
    // The deviations change the LDA, not the gallery or the PCA.
    let synthetic_only = protocol::Samples {
        deviations: Vec::new(),
        ..samples.clone()
    };
    let plain = protocol::score(&synthetic_only, true, &params)
        .unwrap()
        .report;
    assert_eq!(plain.learned_deviations, 0);
    assert_eq!(plain.gallery_samples, learned.gallery_samples);
    assert_eq!(plain.pca_dims, learned.pca_dims);
    assert_ne!(
        plain.cmc, learned.cmc,
        "the learned scatter must change the matching"
    );
    // Without augmentation there is no within-class scatter to add them to.
    let neutral = protocol::score(&samples, false, &params).unwrap().report;
    assert_eq!(neutral.method, Method::Eigenfaces);
    assert_eq!(neutral.learned_deviations, 0);

    // A training set with the dataset's own people is refused before any scan is read.
    let leak = ProtocolParams {
        expression_training: Some(dir.clone()),
        ..ProtocolParams::default()
    };
    let err = protocol::collect_samples(&dir, Some(aug.path()), &leak)
        .unwrap_err()
        .to_string();
    assert!(err.contains("shares 6 subject(s)"), "{err}");
}

#[test]
fn expression_training_without_augmentation_is_refused() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let err = common::cli_error(&[
        "evaluate".as_ref(),
        "--dataset".as_ref(),
        dir.as_os_str(),
        "--expression-training".as_ref(),
        dir.as_os_str(),
    ]);
    assert!(
        err.contains("--expression-training needs --augmented"),
        "{err}"
    );
}

/// A scan whose detected points are suspect (a real profile, cara1_derecha, turned 44°) is not
/// posed by them: it gets face localisation's pose, which sees the head turned, and the
/// reasons; a frontal scan is posed by its points and has none.
#[test]
fn a_suspect_scan_is_posed_by_the_generic_face_fit() {
    let generic = facesynth::generic_face::build();
    let params = ProtocolParams::default();
    let (pose, reasons) =
        protocol::scan_pose_checked(&common::gavab("cara1_derecha.wrl"), &params, &generic, None)
            .unwrap();
    assert!(reasons.iter().any(|r| r.contains("turned")), "{reasons:?}");
    let (yaw, _, _) = facesynth::landmarks::localise::yaw_pitch_roll_deg(pose.face_from_scan);
    assert!(yaw.abs() > 30.0, "yaw {yaw}");
    let (_, reasons) = protocol::scan_pose_checked(
        &common::gavab("cara1_frontal1.wrl"),
        &params,
        &generic,
        None,
    )
    .unwrap();
    assert!(reasons.is_empty(), "{reasons:?}");
}

/// The ground truth beside a generated scan is read only by `--pose truth`: the nose tip of the
/// other pose sources is detected, whatever the JSON says (here a tip moved 50 mm).
#[test]
fn ground_truth_is_read_only_by_the_truth_pose() {
    let dir = common::synth_dataset(SUBJECTS, SEED, false);
    let tmp = tempfile::tempdir().unwrap();
    let scan = tmp.path().join("subj000_frontal1.wrl");
    std::fs::copy(dir.join("subj000_frontal1.wrl"), &scan).unwrap();
    let json_path = dir.join("subj000_frontal1.json");
    let mut truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    let real = truth["landmarks"]["nose_tip"]["xyz_mm"].clone();
    truth["landmarks"]["nose_tip"]["xyz_mm"][0] = (real[0].as_f64().unwrap() + 50.0).into();
    std::fs::write(
        tmp.path().join("subj000_frontal1.json"),
        serde_json::to_string(&truth).unwrap(),
    )
    .unwrap();
    let tip = protocol::nose_tip(&scan).unwrap();
    let off = (tip.x - real[0].as_f64().unwrap()).abs();
    assert!(
        off < 5.0,
        "nose tip {tip} is {off} mm from the scan's real tip"
    );
    let moved = protocol::truth_nose_tip(&scan).unwrap();
    assert!(
        (moved.x - tip.x).abs() > 40.0,
        "--pose truth reads the JSON"
    );
}
