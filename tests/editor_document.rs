#![cfg(feature = "gui")]
//! The editor's edit logic without a window: commands applied to the document, worker jobs run
//! directly, results received — as the app does once per frame.

mod common;

use facesynth::app::document::{Command, Document};
use facesynth::app::worker::run_job;
use facesynth::feature_points::FeaturePoint;
use facesynth::generic_face;
use glam::DVec3;

/// Applies a command and runs the jobs it starts to completion.
fn apply(doc: &mut Document, command: Command) {
    for job in doc.apply(command) {
        doc.receive(run_job(job));
    }
    assert!(!doc.busy(), "every job answered");
}

#[test]
fn opening_a_real_scan_then_a_bad_file_keeps_the_scan_and_reports_the_file() {
    let mut doc = Document::new(generic_face::build());
    apply(
        &mut doc,
        Command::Open(Some(common::gavab("cara1_frontal1.wrl"))),
    );
    let scan = doc.scan.as_ref().expect("scan loaded");
    assert_eq!(scan.mesh.vertex_count(), 13_709);
    assert!(
        doc.edits.landmarks.is_none(),
        "a new scan has no landmarks yet"
    );
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("broken.wrl");
    std::fs::write(&bad, "#VRML V1.0 ascii\nCoordinate3 { point [ 1 2").unwrap();
    apply(&mut doc, Command::Open(Some(bad.clone())));
    let error = doc.error.clone().expect("an error is shown");
    assert!(error.contains("broken.wrl"), "{error}");
    assert_eq!(doc.scan.as_ref().unwrap().mesh.vertex_count(), 13_709);
}

#[test]
fn landmark_moves_undo_and_redo_one_step_each_and_survive_a_json_round_trip() {
    let mut doc = Document::new(generic_face::build());
    let original = doc.edits.landmarks.unwrap();
    let a = DVec3::new(1.0, 2.0, 3.0);
    let b = DVec3::new(4.0, 5.0, 6.0);
    apply(&mut doc, Command::MoveLandmark(FeaturePoint::Chin, a));
    apply(&mut doc, Command::MoveLandmark(FeaturePoint::NoseTip, b));
    let moved = doc.edits.landmarks.unwrap();
    assert_eq!(moved.get(FeaturePoint::Chin), a);
    assert_eq!(moved.get(FeaturePoint::NoseTip), b);

    apply(&mut doc, Command::Undo);
    let l = doc.edits.landmarks.unwrap();
    assert_eq!(
        l.get(FeaturePoint::NoseTip),
        original.get(FeaturePoint::NoseTip)
    );
    assert_eq!(l.get(FeaturePoint::Chin), a, "one undo reverts one move");
    apply(&mut doc, Command::Undo);
    assert_eq!(doc.edits.landmarks.as_ref(), Some(&original));
    assert!(!doc.history.can_undo());
    apply(&mut doc, Command::Redo);
    apply(&mut doc, Command::Redo);
    assert_eq!(doc.edits.landmarks.as_ref(), Some(&moved));

    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("points.json");
    apply(&mut doc, Command::SaveLandmarks(file.clone()));
    assert!(doc.error.is_none(), "{:?}", doc.error);
    apply(
        &mut doc,
        Command::MoveLandmark(FeaturePoint::Chin, DVec3::ZERO),
    );
    apply(&mut doc, Command::LoadLandmarks(file));
    assert_eq!(doc.edits.landmarks.as_ref(), Some(&moved));
    // Loading is one undoable step too.
    apply(&mut doc, Command::Undo);
    assert_eq!(
        doc.edits
            .landmarks
            .as_ref()
            .unwrap()
            .get(FeaturePoint::Chin),
        DVec3::ZERO
    );
}

#[test]
fn registering_the_generic_face_to_itself_lands_on_the_surface_and_goes_stale_on_edit() {
    let face = generic_face::build();
    let dir = tempfile::tempdir().unwrap();
    let scan_path = dir.path().join("generic.obj");
    facesynth::io::write_mesh(&scan_path, &face.mesh).unwrap();
    let mut doc = Document::new(generic_face::build());
    apply(&mut doc, Command::Open(Some(scan_path)));
    apply(&mut doc, Command::SetLandmarks(Box::new(face.landmarks())));
    apply(&mut doc, Command::Register);
    let reg = doc.registration.as_ref().expect("registered");
    assert!(doc.error.is_none());
    assert_eq!(reg.distance_mm.len(), face.mesh.vertex_count());
    let matched: Vec<f64> = reg
        .distance_mm
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    assert!(matched.len() * 10 > face.mesh.vertex_count() * 9);
    let mean = matched.iter().sum::<f64>() / matched.len() as f64;
    assert!(mean < 0.05, "mean distance {mean} mm");
    assert!(!doc.registration_stale());
    apply(
        &mut doc,
        Command::MoveLandmark(FeaturePoint::Chin, DVec3::new(0.0, -80.0, -20.0)),
    );
    assert!(doc.registration_stale());
}

#[test]
fn commands_that_need_a_scan_say_so_instead_of_failing_silently() {
    let mut doc = Document::new(generic_face::build());
    apply(&mut doc, Command::Denoise(Default::default()));
    assert!(doc.error.as_deref().unwrap().contains("scan"));
    apply(&mut doc, Command::Register);
    assert!(doc.error.is_some());
    apply(
        &mut doc,
        Command::ExportRegistered("/nonexistent/x.obj".into()),
    );
    assert!(doc.error.is_some());
}
