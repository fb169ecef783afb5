#![cfg(feature = "gui")]
//! The editor's landmark files (issue 37): Save JSON writes the one schema with its source and
//! the moved points, *Save as correction* writes `<stem>.landmarks.json` beside the scan, and
//! opening a scan with one loads its points.

use crate::common;

use facesynth::app::document::{Command, Document};
use facesynth::app::worker::WorkerState;
use facesynth::feature_points::FeaturePoint;
use facesynth::generic_face;
use facesynth::pipeline::{LandmarkFile, LandmarkSource};
use glam::DVec3;

fn apply(doc: &mut Document, command: Command) {
    let mut worker = WorkerState::default();
    let mut jobs: std::collections::VecDeque<_> = doc.apply(command).into();
    while let Some(job) = jobs.pop_front() {
        jobs.extend(doc.receive(worker.run(job)));
    }
    assert!(doc.error.is_none(), "{:?}", doc.error);
}

#[test]
fn saved_points_say_where_they_came_from_and_a_correction_reopens_with_its_scan() {
    let dir = tempfile::tempdir().unwrap();
    let data = common::synth_dataset(2, 11, false);
    let scan = dir.path().join("subj001_frontal1.wrl");
    std::fs::copy(data.join("subj001_frontal1.wrl"), &scan).unwrap();
    let mut doc = Document::new(generic_face::build());
    apply(&mut doc, Command::Open(Some(scan.clone())));
    assert!(
        doc.edits.landmarks.is_none(),
        "no correction yet: no points"
    );
    apply(&mut doc, Command::DetectLandmarks);
    let detected = doc.edits.landmarks.unwrap();

    // Unmoved: saved as detected, with the scan's name.
    let plain = dir.path().join("plain.json");
    apply(&mut doc, Command::SaveLandmarks(plain.clone()));
    let file = LandmarkFile::read(&plain).unwrap();
    assert_eq!(file.source, LandmarkSource::Detected);
    assert_eq!(file.scan.as_deref(), Some("subj001_frontal1.wrl"));
    assert!(file.corrected.is_empty());
    assert_eq!(file.landmarks, detected);

    // One point moved: corrected, that point listed; written beside the scan.
    let eye = detected.get(FeaturePoint::OuterEyeRight) + DVec3::new(-2.5, 0.5, 0.0);
    apply(
        &mut doc,
        Command::MoveLandmark(FeaturePoint::OuterEyeRight, eye),
    );
    apply(&mut doc, Command::SaveCorrection);
    let beside = dir.path().join("subj001_frontal1.landmarks.json");
    assert_eq!(doc.correction_path().as_deref(), Some(beside.as_path()));
    let file = LandmarkFile::read(&beside).unwrap();
    assert_eq!(file.source, LandmarkSource::Corrected);
    assert_eq!(file.corrected, [FeaturePoint::OuterEyeRight]);
    assert_eq!(file.landmarks.get(FeaturePoint::OuterEyeRight), eye);
    assert!(doc.unsaved().is_empty(), "{:?}", doc.unsaved());

    // Opened again: the correction gives the points, nothing to undo or save; a further move
    // keeps the earlier correction listed.
    let mut again = Document::new(generic_face::build());
    apply(&mut again, Command::Open(Some(scan.clone())));
    assert_eq!(again.edits.landmarks, Some(file.landmarks));
    assert!(!again.history.can_undo());
    assert!(again.unsaved().is_empty(), "{:?}", again.unsaved());
    let tip = detected.get(FeaturePoint::NoseTip) + DVec3::new(0.0, 1.0, 0.0);
    apply(
        &mut again,
        Command::MoveLandmark(FeaturePoint::NoseTip, tip),
    );
    let now = again.landmark_file().unwrap();
    assert_eq!(
        now.corrected,
        [FeaturePoint::NoseTip, FeaturePoint::OuterEyeRight]
    );
    // Undone: back to the file as saved.
    apply(&mut again, Command::Undo);
    assert_eq!(again.landmark_file().unwrap(), file);

    // A `landmarks --json` file loaded by hand is detected points.
    let json = dir.path().join("cli.json");
    common::json_of(&common::facesynth(&[
        "landmarks",
        scan.to_str().unwrap(),
        "--no-denoise",
        "--json",
        json.to_str().unwrap(),
    ]));
    apply(&mut again, Command::LoadLandmarks(json));
    let loaded = again.landmark_file().unwrap();
    assert_eq!(loaded.source, LandmarkSource::Detected);
    for p in FeaturePoint::ALL {
        // The command writes to 1 µm.
        assert!(
            (loaded.landmarks.get(p) - detected.get(p)).length() < 1e-3,
            "{p:?}"
        );
    }
}

/// The review queue without a window: it opens the worst scan with its detected points; a
/// moved point is written as that scan's correction when moving on; going back opens it with
/// the corrected points; the counter follows.
#[test]
fn the_review_queue_writes_a_correction_when_moving_on() {
    let dir = common::gallery_copy(3);
    let mut doc = Document::new(generic_face::build());
    apply(&mut doc, Command::Review(dir.path().to_path_buf()));
    let review = doc.review.clone().expect("queue built");
    assert_eq!(review.queue.entries.len(), 3);
    assert_eq!(review.current, Some(0));
    let first = review.queue.entries[0].scan.clone();
    assert_eq!(doc.scan.as_ref().unwrap().path, first);
    let detected = doc.edits.landmarks.expect("the queue's points");
    assert_eq!(
        doc.landmark_file().unwrap().source,
        LandmarkSource::Detected
    );
    assert_eq!(doc.review_counter().unwrap(), "0 of 3 reviewed");

    let tip = detected.get(FeaturePoint::NoseTip) + DVec3::new(0.0, -1.0, 0.5);
    apply(&mut doc, Command::MoveLandmark(FeaturePoint::NoseTip, tip));
    apply(&mut doc, Command::ReviewNext);
    let written = facesynth::pipeline::correction_path(&first, None);
    let file = LandmarkFile::read(&written).expect("correction written on moving on");
    assert_eq!(file.corrected, [FeaturePoint::NoseTip]);
    assert_eq!(file.landmarks.get(FeaturePoint::NoseTip), tip);
    assert_ne!(doc.scan.as_ref().unwrap().path, first);
    assert_eq!(doc.review_counter().unwrap(), "1 of 3 reviewed");
    // Moving on without a change writes nothing.
    apply(&mut doc, Command::ReviewNext);
    let corrections = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| facesynth::pipeline::is_correction_file(&e.as_ref().unwrap().path()))
        .count();
    assert_eq!(corrections, 1);
    assert_eq!(doc.review_counter().unwrap(), "2 of 3 reviewed");
    // Back to the first: its corrected points.
    apply(&mut doc, Command::ReviewGo(0));
    assert_eq!(doc.edits.landmarks, Some(file.landmarks));
    let entry = &doc.review.as_ref().unwrap().queue.entries[0];
    assert_eq!(entry.state, facesynth::pipeline::ReviewState::Corrected);
}
