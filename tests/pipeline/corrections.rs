//! Landmark files and corrections (issue 37): one schema read by every command, correction
//! files beside a scan (or in `--landmarks-dir`) used by the batch, and `augment --shard`.

use crate::common;

use facesynth::augment::{AugmentParams, DONE_MARKER, Shard};
use facesynth::pipeline::{self, LandmarkFile, LandmarkSource};
use facesynth::{FeaturePoint, Landmarks};
use std::path::{Path, PathBuf};

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A copy of one generated gallery scan in a folder of its own (corrections go beside it).
fn scan_copy(dir: &Path) -> PathBuf {
    let data = common::synth_dataset(2, 11, false);
    let scan = dir.join("subj000_frontal1.wrl");
    std::fs::copy(data.join("subj000_frontal1.wrl"), &scan).unwrap();
    scan
}

/// Every writer (`landmarks --json`, a corrected [`LandmarkFile`], the flat map of `generic
/// --landmarks`) is read back by the library reader and by `register --landmarks` with the
/// same points, and with the source each writer means.
#[test]
fn every_landmark_file_writer_is_read_by_every_reader() {
    let dir = tempfile::tempdir().unwrap();
    let scan = scan_copy(dir.path());
    let detected = dir.path().join("detected.json");
    let out = common::facesynth(&[
        "landmarks",
        scan.to_str().unwrap(),
        "--json",
        detected.to_str().unwrap(),
    ]);
    let printed = common::json_of(&out);
    assert_eq!(printed["source"], "detected");
    assert_eq!(printed["scan"], "subj000_frontal1.wrl");
    let file = LandmarkFile::read(&detected).unwrap();
    assert_eq!(file.source, LandmarkSource::Detected);
    assert_eq!(file.scan.as_deref(), Some("subj000_frontal1.wrl"));
    assert!(file.borders_detected());

    // A correction: the nose tip moved 2 mm; written, read back identically.
    let mut moved = file.clone();
    let tip = moved.landmarks.get(FeaturePoint::NoseTip);
    moved
        .landmarks
        .set(FeaturePoint::NoseTip, tip + glam::DVec3::new(0.0, 2.0, 0.0));
    moved.source = LandmarkSource::Corrected;
    moved.corrected = vec![FeaturePoint::NoseTip];
    let corrected = dir.path().join("corrected.json");
    moved.write(&corrected).unwrap();
    assert_eq!(LandmarkFile::read(&corrected).unwrap(), moved);
    // Borders still the detector's: the registration leaves them out as for detected points.
    assert!(moved.borders_detected());

    // The flat map of `generic --landmarks`: read as given (every point meant).
    let flat = dir.path().join("flat.json");
    let generic = dir.path().join("generic.obj");
    common::json_of(&common::facesynth(&[
        "generic",
        "--out",
        generic.to_str().unwrap(),
        "--landmarks",
        flat.to_str().unwrap(),
    ]));
    let given = LandmarkFile::read(&flat).unwrap();
    assert_eq!(given.source, LandmarkSource::Given);
    assert!(!given.borders_detected());
    let flat_map: std::collections::BTreeMap<String, [f64; 3]> =
        serde_json::from_value(read_json(&flat)).unwrap();
    assert_eq!(given.landmarks, Landmarks::from_map(&flat_map).unwrap());

    // `register --landmarks` with each: the source is reported; the detected file registers
    // exactly as detection does (its borders are left out, as detected ones are).
    let register = |extra: &[&str]| {
        let mut args = vec!["register", scan.to_str().unwrap()];
        args.extend_from_slice(extra);
        common::json_of(&common::facesynth(&args))
    };
    let by_detection = register(&[]);
    let by_file = register(&["--landmarks", detected.to_str().unwrap()]);
    assert_eq!(by_file["landmarks_source"], "detected");
    assert!(difference_mm(&by_file, &by_detection) < SAME_MM);
    let by_correction = register(&["--landmarks", corrected.to_str().unwrap()]);
    assert_eq!(by_correction["landmarks_source"], "corrected");
    assert!(difference_mm(&by_correction, &by_detection) > 10.0 * SAME_MM);
}

/// A registration report's figures in mm (landmark residuals, surface distances, the rigid
/// fit's RMS), flattened: what the points change.
fn geometry(report: &serde_json::Value) -> Vec<f64> {
    let mut out = vec![report["rigid_rms_mm"].as_f64().unwrap()];
    for k in ["landmark_residual_mm", "surface_distance_mm"] {
        out.extend(
            report[k]
                .as_object()
                .unwrap()
                .values()
                .map(|x| x.as_f64().unwrap()),
        );
    }
    out
}

/// The largest difference between two reports' figures, mm.
fn difference_mm(a: &serde_json::Value, b: &serde_json::Value) -> f64 {
    let (a, b) = (geometry(a), geometry(b));
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Landmark files hold points to 1 µm: a registration from a file matches one from the same
/// points in memory to within rounding.
const SAME_MM: f64 = 0.005;

/// A correction file beside the scan replaces detection; `--landmarks-dir` points elsewhere;
/// `--landmarks` beats both; a broken correction file is a one-line error naming it.
#[test]
fn a_correction_beside_the_scan_replaces_detection() {
    let dir = tempfile::tempdir().unwrap();
    let scan = scan_copy(dir.path());
    let s = scan.to_str().unwrap();
    let detected = common::json_of(&common::facesynth(&["register", s]));
    assert_eq!(detected["landmarks_source"], "detected");

    let lm = dir.path().join("lm.json");
    common::json_of(&common::facesynth(&[
        "landmarks",
        s,
        "--json",
        lm.to_str().unwrap(),
    ]));
    let mut file = LandmarkFile::read(&lm).unwrap();
    let p = file.landmarks.get(FeaturePoint::OuterEyeLeft);
    file.landmarks.set(
        FeaturePoint::OuterEyeLeft,
        p + glam::DVec3::new(3.0, 0.0, 0.0),
    );
    file.source = LandmarkSource::Corrected;
    file.corrected = vec![FeaturePoint::OuterEyeLeft];
    let beside = pipeline::correction_path(&scan, None);
    assert_eq!(beside, dir.path().join("subj000_frontal1.landmarks.json"));
    file.write(&beside).unwrap();
    let corrected = common::json_of(&common::facesynth(&["register", s]));
    assert_eq!(corrected["landmarks_source"], "corrected");
    assert_eq!(corrected["landmarks_file"], beside.to_str().unwrap());
    assert!(difference_mm(&corrected, &detected) > 10.0 * SAME_MM);
    // --landmarks wins over the file beside the scan.
    let explicit = common::json_of(&common::facesynth(&[
        "register",
        s,
        "--landmarks",
        lm.to_str().unwrap(),
    ]));
    assert_eq!(explicit["landmarks_source"], "detected");
    assert!(difference_mm(&explicit, &detected) < SAME_MM);

    // Moved into another folder: found there with --landmarks-dir only.
    let other = tempfile::tempdir().unwrap();
    let moved = other.path().join("subj000_frontal1.landmarks.json");
    std::fs::rename(&beside, &moved).unwrap();
    let without = common::json_of(&common::facesynth(&["register", s]));
    assert_eq!(without["landmarks_source"], "detected");
    let with = common::json_of(&common::facesynth(&[
        "register",
        s,
        "--landmarks-dir",
        other.path().to_str().unwrap(),
    ]));
    assert_eq!(with["landmarks_source"], "corrected");
    assert!(difference_mm(&with, &corrected) < SAME_MM);

    // A broken correction file: one line naming it.
    std::fs::write(&moved, "{\"landmarks\": {\"nose_tip\": [1, 2]}}").unwrap();
    let err = common::cli_error(&[
        "register".as_ref(),
        scan.as_os_str(),
        "--landmarks-dir".as_ref(),
        other.path().as_os_str(),
    ]);
    assert!(err.contains("subj000_frontal1.landmarks.json"), "{err}");
}

/// The points `augment` used for a subject (its `done.json`).
fn done_of(out: &Path, stem: &str) -> serde_json::Value {
    read_json(&out.join(stem).join(DONE_MARKER))
}

/// `augment` uses a correction file, records it, redoes a subject whose correction changed and
/// only that one; `evaluate` poses the scan by it and says so.
#[test]
fn augment_and_evaluate_use_corrections_and_redo_a_changed_one() {
    let data = common::synth_dataset(2, 11, false);
    let corrections = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let params = AugmentParams {
        expressions: "happiness".into(),
        write_face_meshes: false,
        landmarks_dir: Some(corrections.path().to_path_buf()),
        ..AugmentParams::default()
    };
    let quiet = |_: usize, _: usize, _: &str| {};
    let (first, failed) = facesynth::augment::augment(&data, out.path(), &params, &quiet).unwrap();
    assert!(failed.is_empty(), "{failed:?}");
    assert!(
        first
            .iter()
            .all(|a| a.landmarks_source == LandmarkSource::Detected)
    );
    // Each detection reports the axes it found the face in (the generated scans face +z).
    assert!(
        first
            .iter()
            .all(|a| a.orientation.as_ref().is_some_and(|o| o["facing"] == "+z")),
        "{first:?}"
    );
    let detected: Landmarks =
        serde_json::from_value(done_of(out.path(), "subj000_frontal1")["landmarks"].clone())
            .unwrap();

    // The user corrects subj000's nose tip: that subject is redone from the corrected points,
    // the other is resumed.
    let mut points = detected;
    let tip = points.get(FeaturePoint::NoseTip);
    points.set(
        FeaturePoint::NoseTip,
        tip + glam::DVec3::new(0.0, -1.5, 0.0),
    );
    let mut file = LandmarkFile {
        landmarks: points,
        source: LandmarkSource::Corrected,
        scan: Some("subj000_frontal1.wrl".into()),
        corrected: vec![FeaturePoint::NoseTip],
    };
    let path = corrections.path().join("subj000_frontal1.landmarks.json");
    file.write(&path).unwrap();
    let (second, failed) = facesynth::augment::augment(&data, out.path(), &params, &quiet).unwrap();
    assert!(failed.is_empty(), "{failed:?}");
    let by_stem = |list: &[facesynth::augment::AugmentedScan], stem: &str| {
        list.iter()
            .find(|a| a.scan.file_stem().unwrap() == stem)
            .unwrap()
            .clone()
    };
    let a0 = by_stem(&second, "subj000_frontal1");
    assert!(a0.redone && !a0.resumed);
    assert_eq!(a0.landmarks_source, LandmarkSource::Corrected);
    assert_eq!(a0.corrected_points, ["nose_tip"]);
    let resumed = by_stem(&second, "subj001_frontal1");
    assert!(resumed.resumed);
    // A resumed scan keeps the orientation its finished run recorded; corrected points came
    // from a file, not a detection.
    assert_eq!(
        resumed.orientation,
        by_stem(&first, "subj001_frontal1").orientation
    );
    assert_eq!(a0.orientation, None);
    let done = done_of(out.path(), "subj000_frontal1");
    let used: Landmarks = serde_json::from_value(done["landmarks"].clone()).unwrap();
    assert_eq!(used, points);
    assert_eq!(done["landmarks_source"], "corrected");
    assert_eq!(done["corrected_points"], serde_json::json!(["nose_tip"]));

    // Unchanged: resumed. Changed again: redone.
    let (third, _) = facesynth::augment::augment(&data, out.path(), &params, &quiet).unwrap();
    assert!(third.iter().all(|a| a.resumed));
    assert_eq!(
        by_stem(&third, "subj000_frontal1").landmarks_source,
        LandmarkSource::Corrected
    );
    file.landmarks.set(FeaturePoint::NoseTip, tip);
    file.write(&path).unwrap();
    let (fourth, _) = facesynth::augment::augment(&data, out.path(), &params, &quiet).unwrap();
    assert!(by_stem(&fourth, "subj000_frontal1").redone);
    assert!(by_stem(&fourth, "subj001_frontal1").resumed);

    // evaluate: the corrected gallery scan is posed by its file, and reported.
    let protocol = facesynth::recognition::ProtocolParams {
        landmarks_dir: Some(corrections.path().to_path_buf()),
        ..Default::default()
    };
    let eval = facesynth::recognition::evaluate(&data, Some(out.path()), &protocol).unwrap();
    assert_eq!(
        eval.report.corrected_landmarks,
        [data.join("subj000_frontal1.wrl")]
    );
    assert_eq!(eval.report.cached_landmarks, 1);
    assert!(eval.report.augment_failures.is_empty());
}

/// `--shard K/N`: three shards write byte-identical samples to one run; each shard's failures
/// go to `failures.K-of-N.json` and are merged on read.
#[test]
fn three_shards_write_what_one_run_writes() {
    let gallery = common::gallery_copy(3);
    // Sorted first, so shard 0 of 3 gets it together with subj002.
    std::fs::write(
        gallery.path().join("broken_frontal1.wrl"),
        "#VRML V1.0 ascii\n[",
    )
    .unwrap();
    let params = AugmentParams {
        expressions: "happiness,frown".into(),
        write_face_meshes: false,
        ..AugmentParams::default()
    };
    let quiet = |_: usize, _: usize, _: &str| {};
    let single = tempfile::tempdir().unwrap();
    let (done, failed) =
        facesynth::augment::augment(gallery.path(), single.path(), &params, &quiet).unwrap();
    assert_eq!((done.len(), failed.len()), (3, 1));
    let sharded = tempfile::tempdir().unwrap();
    let mut handled = Vec::new();
    for k in 0..3 {
        let shard = Some(Shard { index: k, count: 3 });
        let p = AugmentParams {
            shard,
            ..params.clone()
        };
        let (done, failed) =
            facesynth::augment::augment(gallery.path(), sharded.path(), &p, &quiet).unwrap();
        handled.extend(done.iter().map(|a| a.scan.clone()));
        handled.extend(failed.iter().map(|f| f.scan.clone()));
        let list = read_json(&sharded.path().join(format!("failures.{k}-of-3.json")));
        assert_eq!(list.as_array().unwrap().len(), usize::from(k == 0));
    }
    handled.sort();
    assert_eq!(
        handled,
        pipeline::gallery_scans(gallery.path(), "_frontal1").unwrap()
    );
    for s in ["subj000", "subj001", "subj002"] {
        for name in ["happiness.ply", "frown.ply"] {
            let a = std::fs::read(single.path().join(format!("{s}_frontal1")).join(name)).unwrap();
            let b = std::fs::read(sharded.path().join(format!("{s}_frontal1")).join(name)).unwrap();
            assert!(
                a == b,
                "{s}/{name} differs between the single run and the shards"
            );
        }
    }
    let merged = facesynth::augment::read_augment_failures(sharded.path()).unwrap();
    assert_eq!(merged.len(), 1);
    assert!(
        merged[0]["scan"]
            .as_str()
            .unwrap()
            .ends_with("broken_frontal1.wrl")
    );
    assert_eq!(
        facesynth::augment::read_augment_failures(single.path()).unwrap(),
        merged
    );

    // The option: K/N with K < N, or a one-line error.
    assert_eq!(
        "2/16".parse::<Shard>(),
        Ok(Shard {
            index: 2,
            count: 16
        })
    );
    for bad in ["3/3", "1", "a/2", "0/0"] {
        assert!(bad.parse::<Shard>().is_err(), "{bad}");
    }
    let run = common::facesynth(&[
        "augment",
        "--gallery",
        gallery.path().to_str().unwrap(),
        "--out",
        sharded.path().to_str().unwrap(),
        "--shard",
        "3/3",
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(err.contains("shard `3/3`: need 0 ≤ K < N"), "{err}");
}

/// The review queue: a broken file first, then a suspect scan (a real profile), then the
/// detected ones, the corrected one last; the second build reads every detection from the
/// cache, a changed scan is detected again, and the reviewed marks persist.
#[test]
fn the_review_queue_puts_the_worst_first_and_caches_its_detection() {
    use facesynth::pipeline::{ReviewQueue, ReviewState};
    let data = common::synth_dataset(2, 11, false);
    let dir = tempfile::tempdir().unwrap();
    for name in ["subj000_frontal1.wrl", "subj001_frontal1.wrl"] {
        std::fs::copy(data.join(name), dir.path().join(name)).unwrap();
    }
    std::fs::copy(
        common::gavab("cara1_derecha.wrl"),
        dir.path().join("cara1_derecha.wrl"),
    )
    .unwrap();
    std::fs::write(dir.path().join("broken.wrl"), "#VRML V1.0 ascii\n[").unwrap();
    // subj001 was corrected already: last.
    let scan1 = dir.path().join("subj001_frontal1.wrl");
    let lm = dir.path().join("lm.json");
    common::json_of(&common::facesynth(&[
        "landmarks",
        scan1.to_str().unwrap(),
        "--json",
        lm.to_str().unwrap(),
    ]));
    let mut file = LandmarkFile::read(&lm).unwrap();
    std::fs::remove_file(&lm).unwrap();
    file.source = LandmarkSource::Corrected;
    file.corrected = vec![FeaturePoint::Chin];
    file.write(&pipeline::correction_path(&scan1, None))
        .unwrap();

    let calls = std::sync::Mutex::new(0);
    let count = |_: usize, _: usize| *calls.lock().unwrap() += 1;
    let mut queue = ReviewQueue::build(dir.path(), None, &count).unwrap();
    let order: Vec<(String, ReviewState)> = queue
        .entries
        .iter()
        .map(|e| {
            (
                e.scan.file_name().unwrap().to_string_lossy().into_owned(),
                e.state,
            )
        })
        .collect();
    assert_eq!(
        order,
        [
            ("broken.wrl".to_string(), ReviewState::Failed),
            ("cara1_derecha.wrl".to_string(), ReviewState::Suspect),
            ("subj000_frontal1.wrl".to_string(), ReviewState::Detected),
            ("subj001_frontal1.wrl".to_string(), ReviewState::Corrected),
        ]
    );
    assert!(queue.entries[0].reason.contains("broken.wrl"));
    assert!(
        queue.entries[1].reason.contains("profile"),
        "{}",
        queue.entries[1].reason
    );
    assert!(queue.entries[3].reason.contains("chin"));
    assert_eq!(queue.cached, 0);
    assert_eq!(*calls.lock().unwrap(), 5, "once before, once per scan");
    assert_eq!(queue.reviewed(), 1, "a corrected scan is reviewed");
    // The detected points of a scan are what `landmarks` finds.
    let detected = queue.entries[2].detected_file().unwrap();
    let cli = common::json_of(&common::facesynth(&[
        "landmarks",
        dir.path().join("subj000_frontal1.wrl").to_str().unwrap(),
    ]));
    let cli: Landmarks = serde_json::from_value(cli["landmarks"].clone()).unwrap();
    for p in FeaturePoint::ALL {
        assert!(
            (detected.landmarks.get(p) - cli.get(p)).length() < 1e-3,
            "{p:?}"
        );
    }
    queue.mark_reviewed(2).unwrap();

    // Again: all from the cache, the same queue, the mark kept.
    let again = ReviewQueue::build(dir.path(), None, &|_, _| {}).unwrap();
    assert_eq!(again.cached, 4);
    assert_eq!(again.entries, queue.entries);
    assert_eq!(again.reviewed(), 2);
    // A scan rewritten since (another size): detected again.
    let text = std::fs::read_to_string(dir.path().join("broken.wrl")).unwrap();
    std::fs::write(dir.path().join("broken.wrl"), text + "\n").unwrap();
    let third = ReviewQueue::build(dir.path(), None, &|_, _| {}).unwrap();
    assert_eq!(third.cached, 3);
}

/// `fit-expression` takes each scan's correction file (neutral and expression) and says so.
#[test]
fn fit_expression_uses_the_corrections_beside_both_scans() {
    let data = common::synth_dataset(2, 11, false);
    let dir = tempfile::tempdir().unwrap();
    let mut scans = Vec::new();
    for name in ["subj000_frontal1.wrl", "subj000_sonrisa.wrl"] {
        let scan = dir.path().join(name);
        std::fs::copy(data.join(name), &scan).unwrap();
        let lm = dir.path().join("lm.json");
        common::json_of(&common::facesynth(&[
            "landmarks",
            scan.to_str().unwrap(),
            "--json",
            lm.to_str().unwrap(),
        ]));
        let mut file = LandmarkFile::read(&lm).unwrap();
        std::fs::remove_file(&lm).unwrap();
        file.source = LandmarkSource::Corrected;
        file.write(&pipeline::correction_path(&scan, None)).unwrap();
        scans.push(scan);
    }
    let preset = dir.path().join("fit.ron");
    let v = common::json_of(&common::facesynth(&[
        "fit-expression",
        scans[0].to_str().unwrap(),
        scans[1].to_str().unwrap(),
        "--out",
        preset.to_str().unwrap(),
    ]));
    assert_eq!(v["landmarks_source"], "corrected");
    assert_eq!(v["expression_landmarks_source"], "corrected");
    assert!(
        v["expression_landmarks_file"]
            .as_str()
            .unwrap()
            .ends_with("subj000_sonrisa.landmarks.json")
    );
}
