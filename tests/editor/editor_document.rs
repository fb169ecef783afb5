#![cfg(feature = "gui")]
//! The editor's edit logic without a window: commands applied to the document, worker jobs run
//! directly, results received — as the app does once per frame.

use crate::common;

use facesynth::app::document::{Command, Document};
use facesynth::app::worker::WorkerState;
use facesynth::feature_points::FeaturePoint;
use facesynth::generic_face;
use glam::DVec3;

/// Applies a command and runs the jobs it starts to completion.
fn apply(doc: &mut Document, command: Command) {
    apply_with(&mut WorkerState::default(), doc, command);
}

/// The same with a worker state kept between commands (the FEM model lives there).
fn apply_with(worker: &mut WorkerState, doc: &mut Document, command: Command) {
    let mut jobs: std::collections::VecDeque<_> = doc.apply(command).into();
    while let Some(job) = jobs.pop_front() {
        jobs.extend(doc.receive(worker.run(job)));
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
    assert_eq!(scan.units.describe(), "mm (guessed from the size)");
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

/// A scan in metres opens scaled to millimetres, and the file panel says so (a desktop user
/// sees no stderr).
#[test]
fn a_scan_in_metres_opens_in_millimetres_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = facesynth::io::read_mesh(&common::gavab("cara1_frontal1.wrl")).unwrap();
    for p in &mut mesh.positions_mm {
        *p *= 0.001;
    }
    let metres = dir.path().join("head_in_metres.ply");
    facesynth::io::write_mesh(&metres, &mesh).unwrap();
    let mut doc = Document::new(generic_face::build());
    apply(&mut doc, Command::Open(Some(metres)));
    let scan = doc.scan.as_ref().expect("scan loaded");
    let (lo, hi) = scan.bbox_mm;
    assert!((100.0..300.0).contains(&(hi - lo).x), "{:?}", hi - lo);
    assert_eq!(
        scan.units.describe(),
        "m (guessed from the size; scaled ×1000 to mm)"
    );
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
    let loaded = doc.edits.landmarks.unwrap();
    for p in FeaturePoint::ALL {
        // JSON keeps the coordinates to well below a micrometre.
        assert!((loaded.get(p) - moved.get(p)).length() < 1e-9, "{p:?}");
    }
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
    apply(&mut doc, Command::Undo);
    assert!(!doc.registration_stale(), "the landmarks are as registered");
    // Erasing vertices changes the scan it was registered to.
    apply(&mut doc, Command::Checkpoint);
    apply(
        &mut doc,
        Command::Erase {
            centre_mm: face.mesh.positions_mm[0],
            radius_mm: 3.0,
        },
    );
    assert!(!doc.edits.erased.is_empty());
    assert!(doc.registration_stale());
}

/// A document with a flat `n × n`-quad grid of 1 mm spacing in z = 0 centred on the origin
/// open (written as OBJ into the returned folder), with one spike of `spike_mm` at (-10, -10).
fn open_grid(n: u32, spike_mm: f64) -> (tempfile::TempDir, Document) {
    let h = (n / 2) as f64;
    let mut grid = common::grid(n + 1, n + 1, |x, y| {
        if (x - h, y - h) == (-10.0, -10.0) {
            spike_mm
        } else {
            0.0
        }
    });
    for p in &mut grid.positions_mm {
        *p -= DVec3::new(h, h, 0.0);
    }
    let dir = tempfile::tempdir().unwrap();
    let scan_path = dir.path().join("grid.obj");
    facesynth::io::write_mesh(&scan_path, &grid).unwrap();
    let mut doc = Document::new(generic_face::build());
    apply(&mut doc, Command::Open(Some(scan_path)));
    (dir, doc)
}

/// The working scan's vertices are the scan's (or the denoised scan's) less the erased ones,
/// each at its source's position.
fn check_working(doc: &Document) {
    let w = doc.working.as_ref().expect("a working scan");
    let source = match &doc.denoised {
        Some(d) => (d.mesh.clone(), d.report.kept.clone()),
        None => {
            let m = doc.scan.as_ref().unwrap().mesh.clone();
            let ids = (0..m.vertex_count() as u32).collect();
            (m, ids)
        }
    };
    let position_of: std::collections::HashMap<u32, DVec3> = source
        .1
        .iter()
        .zip(&source.0.positions_mm)
        .map(|(&v, &x)| (v, x))
        .collect();
    assert_eq!(w.input_ids.len(), w.mesh.vertex_count());
    for (&v, x) in w.input_ids.iter().zip(&w.mesh.positions_mm) {
        assert!(
            !doc.edits.erased.contains(&v),
            "erased vertex {v} is still there"
        );
        assert_eq!(position_of[&v], *x, "vertex {v}");
    }
    let erased_present = source
        .1
        .iter()
        .filter(|v| doc.edits.erased.contains(v))
        .count();
    assert_eq!(w.mesh.vertex_count(), source.1.len() - erased_present);
    assert!(w.mesh.validate().is_ok());
}

#[test]
fn erasing_by_hand_removes_the_brushed_vertices_one_undo_step_per_stroke_and_saves_the_scan() {
    use facesynth::app::document::Part;
    let (dir, mut doc) = open_grid(40, 25.0);
    let n = doc.scan.as_ref().unwrap().mesh.vertex_count();
    assert_eq!(n, 41 * 41);
    assert!(!doc.is_dirty());

    // A click: the grid points within 2.5 mm of the origin (i² + j² ≤ 6.25: 21 of them).
    apply(&mut doc, Command::Checkpoint);
    apply(
        &mut doc,
        Command::Erase {
            centre_mm: DVec3::ZERO,
            radius_mm: 2.5,
        },
    );
    assert_eq!(doc.edits.erased.len(), 21);
    check_working(&doc);
    assert_eq!(doc.working_mesh().unwrap().vertex_count(), n - 21);
    assert_eq!(doc.unsaved(), vec![Part::Scan]);
    // A stroke over two frames: 5 + 5 points within 1 mm of (10, 0) and (11, 0), 2 shared.
    apply(&mut doc, Command::Checkpoint);
    for x in [10.0, 11.0] {
        apply(
            &mut doc,
            Command::Erase {
                centre_mm: DVec3::new(x, 0.0, 0.0),
                radius_mm: 1.0,
            },
        );
    }
    assert_eq!(doc.edits.erased.len(), 29);
    check_working(&doc);
    let stroked = doc.edits.erased.clone();
    apply(&mut doc, Command::Undo);
    assert_eq!(doc.edits.erased.len(), 21, "one undo per stroke");
    check_working(&doc);
    apply(&mut doc, Command::Undo);
    assert!(doc.edits.erased.is_empty());
    assert_eq!(doc.working_mesh().unwrap().vertex_count(), n);
    assert!(!doc.is_dirty(), "back to the scan as loaded");
    apply(&mut doc, Command::Redo);
    apply(&mut doc, Command::Redo);
    assert_eq!(doc.edits.erased, stroked);

    // Denoising keeps the erasures (they are scan ids): the spike goes, the brushed holes stay.
    apply(&mut doc, Command::Denoise(Default::default()));
    assert!(doc.error.is_none(), "{:?}", doc.error);
    check_working(&doc);
    let w = doc.working.as_ref().unwrap();
    let top = w.mesh.positions_mm.iter().map(|x| x.z).fold(0.0, f64::max);
    assert!(top < 2.0, "the 25 mm spike is gone: highest {top} mm");
    assert!(
        w.mesh
            .positions_mm
            .iter()
            .all(|x| x.length() > 2.5 - 1e-9 && x.distance(DVec3::new(10.5, 0.0, 0.0)) > 1.0),
        "no vertex inside the brushed spots"
    );

    // Saving writes the working scan and counts the erasures as saved; a failed save does not.
    apply(
        &mut doc,
        Command::SaveScan(dir.path().join("no/such/dir/grid_clean.ply")),
    );
    assert!(doc.error.as_deref().unwrap().contains("grid_clean.ply"));
    assert_eq!(doc.unsaved(), vec![Part::Scan]);
    let out = dir.path().join("grid_clean.ply");
    apply(&mut doc, Command::SaveScan(out.clone()));
    assert!(doc.error.is_none(), "{:?}", doc.error);
    assert!(!doc.is_dirty());
    let saved = facesynth::io::read_mesh(&out).unwrap();
    let w = doc.working_mesh().unwrap();
    assert_eq!(saved.vertex_count(), w.vertex_count());
    assert_eq!(saved.face_count(), w.face_count());
    for (a, b) in saved.positions_mm.iter().zip(&w.positions_mm) {
        assert!((*a - *b).length() < 1e-4, "{a} vs {b}");
    }

    // Restore all is one undoable step.
    apply(&mut doc, Command::RestoreErased);
    assert!(doc.edits.erased.is_empty());
    check_working(&doc);
    apply(&mut doc, Command::Undo);
    assert_eq!(doc.edits.erased, stroked);
    // A new scan starts with nothing erased.
    apply(&mut doc, Command::Open(None));
    assert!(doc.edits.erased.is_empty() && doc.working.is_none());
    apply(
        &mut doc,
        Command::Erase {
            centre_mm: DVec3::ZERO,
            radius_mm: 1.0,
        },
    );
    assert!(doc.error.as_deref().unwrap().contains("scan"));
}

#[test]
fn erasing_every_corner_but_one_of_a_face_takes_the_stranded_vertex_too() {
    let (_dir, mut doc) = open_grid(4, 0.0);
    // The corner (-2, -2) is in one quad only; erasing its three neighbours there strands it.
    apply(&mut doc, Command::Checkpoint);
    for centre in [(-1.0, -2.0), (-2.0, -1.0), (-1.0, -1.0)] {
        apply(
            &mut doc,
            Command::Erase {
                centre_mm: DVec3::new(centre.0, centre.1, 0.0),
                radius_mm: 0.1,
            },
        );
    }
    assert_eq!(doc.edits.erased.len(), 3);
    let w = doc.working.as_ref().unwrap();
    assert_eq!(w.mesh.vertex_count(), 25 - 4);
    assert!(
        !w.mesh.positions_mm.contains(&DVec3::new(-2.0, -2.0, 0.0)),
        "no stray point is left"
    );
    let mut used = vec![false; w.mesh.vertex_count()];
    for f in w.mesh.faces.iter() {
        f.iter().for_each(|&v| used[v as usize] = true);
    }
    assert!(used.iter().all(|&u| u));
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

/// Mean skin displacement (mm) of the document's current expression.
fn mean_displacement(doc: &Document) -> f64 {
    let fem = doc.fem.as_ref().expect("FEM built");
    let n = fem.surface.vertex_count();
    let u = fem.displacement(&doc.edits.activations);
    u[..n].iter().map(|d| d.length()).sum::<f64>() / n as f64
}

#[test]
fn fem_editing_softer_skin_moves_more_undo_restores_and_presets_round_trip() {
    let mut worker = WorkerState::default();
    let mut doc = Document::new(generic_face::build());
    apply_with(&mut worker, &mut doc, Command::BuildFem);
    assert!(doc.error.is_none(), "{:?}", doc.error);
    let fem = doc.fem.as_ref().expect("built");
    // Waters' 18 muscles and the 4 pairs of soft-tissue loads.
    assert_eq!(fem.muscles.len(), 26);
    apply_with(
        &mut worker,
        &mut doc,
        Command::ApplyPreset("happiness".into()),
    );
    let stiff = mean_displacement(&doc);
    assert!(stiff > 0.05, "a smile moves the face: {stiff} mm");

    // Softer skin: the worker refactors with the cached pattern and the face moves more.
    let mut soft = doc.edits.fem;
    soft.skin.young_modulus_pa /= 4.0;
    apply_with(&mut worker, &mut doc, Command::Checkpoint);
    apply_with(&mut worker, &mut doc, Command::SetFemParams(soft));
    let fem = doc.fem.as_ref().unwrap();
    assert!(
        fem.last_update.contains("refactored"),
        "{}",
        fem.last_update
    );
    let softer = mean_displacement(&doc);
    assert!(softer > stiff * 1.2, "E/4: {softer} vs {stiff} mm");

    // Undo brings the paper's modulus back and re-solves.
    apply_with(&mut worker, &mut doc, Command::Undo);
    assert_eq!(doc.edits.fem.skin.young_modulus_pa, 5600.0);
    let again = mean_displacement(&doc);
    assert!(
        (again - stiff).abs() < 1e-9 * stiff.max(1.0),
        "{again} vs {stiff}"
    );

    // Store the current activations as a preset, save all presets, load them into a fresh
    // document: the same expression comes back.
    apply_with(
        &mut worker,
        &mut doc,
        Command::StorePreset {
            name: "my_smile".into(),
            description: "test".into(),
        },
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("presets.ron");
    apply_with(&mut worker, &mut doc, Command::SavePresets(file.clone()));
    assert!(doc.error.is_none(), "{:?}", doc.error);
    let saved = doc.edits.activations.clone();

    let mut other = Document::new(generic_face::build());
    let mut w2 = WorkerState::default();
    apply_with(&mut w2, &mut other, Command::BuildFem);
    apply_with(&mut w2, &mut other, Command::LoadPresets(file));
    apply_with(&mut w2, &mut other, Command::ApplyPreset("my_smile".into()));
    assert_eq!(other.edits.activations, saved);
}

#[test]
fn mirrored_muscles_give_mirrored_skin_motion_on_the_symmetric_generic_face() {
    let mut worker = WorkerState::default();
    let mut doc = Document::new(generic_face::build());
    apply_with(&mut worker, &mut doc, Command::BuildFem);
    let pos = doc.fem.as_ref().unwrap().surface.positions_mm.clone();
    let disp = |doc: &Document, side: &str| {
        let mut a = std::collections::BTreeMap::new();
        a.insert(format!("zygomatic_major_{side}"), 1.0);
        doc.fem.as_ref().unwrap().displacement(&a)
    };
    let left = disp(&doc, "left");
    let right = disp(&doc, "right");
    // Vertex mirror map by position (x → −x).
    let mut worst: f64 = 0.0;
    let mut peak: f64 = 0.0;
    for (i, p) in pos.iter().enumerate() {
        let m = glam::DVec3::new(-p.x, p.y, p.z);
        let j = (0..pos.len())
            .min_by(|&a, &b| {
                pos[a]
                    .distance_squared(m)
                    .total_cmp(&pos[b].distance_squared(m))
            })
            .unwrap();
        if pos[j].distance(m) > 1e-6 {
            continue;
        }
        let mirrored = glam::DVec3::new(-right[j].x, right[j].y, right[j].z);
        worst = worst.max((left[i] - mirrored).length());
        peak = peak.max(left[i].length());
    }
    assert!(peak > 1.0, "the muscle moves the skin: {peak} mm");
    assert!(worst < 1e-6 * peak.max(1.0) + 1e-9, "asymmetry {worst} mm");
    // The left zygomatic moves the subject's left (+x) mouth corner, not the right.
    let mc_left = doc.generic.feature_vertex(FeaturePoint::MouthCornerLeft) as usize;
    let mc_right = doc.generic.feature_vertex(FeaturePoint::MouthCornerRight) as usize;
    assert!(left[mc_left].length() > 5.0 * left[mc_right].length());
}

#[test]
fn the_whole_pipeline_on_a_real_scan_denoise_detect_register_fem() {
    let mut worker = WorkerState::default();
    let mut doc = Document::new(generic_face::build());
    let scan = common::gavab("cara1_frontal1.wrl");
    apply_with(&mut worker, &mut doc, Command::Open(Some(scan)));
    apply_with(&mut worker, &mut doc, Command::Denoise(Default::default()));
    // The filter repairs or removes some of the scan's spikes (on cara1_frontal1 the few
    // repairs are in neighbourhoods that do not predict themselves, so they are removed).
    let report = &doc.denoised.as_ref().expect("denoised").report;
    assert!(report.vertices_moved + report.vertices_removed > 0);
    apply_with(&mut worker, &mut doc, Command::DetectLandmarks);
    assert!(doc.error.is_none(), "{:?}", doc.error);
    let l = doc.edits.landmarks.expect("detected");
    // Subject's left is +x; the nose tip is the most forward point among the 13.
    use FeaturePoint::*;
    assert!(l.get(InnerEyeLeft).x > l.get(InnerEyeRight).x);
    assert!(l.get(MouthCornerLeft).x > l.get(MouthCornerRight).x);
    assert!(l.get(Forehead).y > l.get(NoseTip).y && l.get(NoseTip).y > l.get(Chin).y);
    assert!(
        FeaturePoint::ALL
            .iter()
            .all(|&p| l.get(NoseTip).z >= l.get(p).z)
    );
    apply_with(&mut worker, &mut doc, Command::Register);
    let reg = doc.registration.as_ref().expect("registered");
    // Measured 6.7 mm (the 13 points after Horn's fit, before the warp makes them coincide).
    assert!(reg.result.rigid_rms_mm < 8.0, "{}", reg.result.rigid_rms_mm);
    apply_with(&mut worker, &mut doc, Command::BuildFem);
    let fem = doc.fem.as_ref().expect("FEM on the registered face");
    assert_ne!(
        fem.surface_id, 0,
        "built on the registration, not the generic face"
    );
    // Detection is one undo step: undo returns to "no points yet".
    apply_with(&mut worker, &mut doc, Command::Undo);
    assert!(doc.edits.landmarks.is_none());
}

#[test]
fn a_landmark_drag_over_many_frames_is_one_undo_step() {
    let mut doc = Document::new(generic_face::build());
    let original = doc.edits.landmarks.unwrap();
    // What the viewport sends: a checkpoint when the drag starts, a move every frame.
    apply(&mut doc, Command::Checkpoint);
    for k in 1..=10 {
        let p = DVec3::new(k as f64, 0.0, 0.0);
        apply(&mut doc, Command::DragLandmark(FeaturePoint::Chin, p));
    }
    let dragged = doc.edits.landmarks.unwrap();
    assert_eq!(dragged.get(FeaturePoint::Chin), DVec3::new(10.0, 0.0, 0.0));
    apply(&mut doc, Command::Undo);
    assert_eq!(doc.edits.landmarks.as_ref(), Some(&original), "one undo");
    assert!(!doc.history.can_undo(), "and only one step");
    apply(&mut doc, Command::Redo);
    assert_eq!(doc.edits.landmarks.as_ref(), Some(&dragged));
}

#[test]
fn session_steps_parse_and_become_the_commands_the_panels_send() {
    use facesynth::app::session::{Action, Step, parse};
    let steps = parse(
        r#"[
            BuildFem,
            Activation(muscle: "zygomatic_major_left", value: 1.25, mirror: true),
            Activation(muscle: "labii_nasi_right", value: 0.5, mirror: false),
            SkinModulus(2800.0),
            Panels(["muscles"]),
            Screenshot("x.png"),
        ]"#,
    )
    .unwrap();
    assert_eq!(steps.len(), 6);
    assert_eq!(steps[0], Step::BuildFem);
    let doc = Document::new(generic_face::build());
    let activations = |step: &Step| match step.action(&doc).unwrap() {
        Action::Commands(c) => match c.as_slice() {
            [Command::Checkpoint, Command::SetActivations(a)] => a.clone(),
            other => panic!("a slider is a checkpoint and new activations, got {other:?}"),
        },
        other => panic!("not commands: {other:?}"),
    };
    let a = activations(&steps[1]);
    assert_eq!(a.get("zygomatic_major_left"), Some(&1.25));
    assert_eq!(a.get("zygomatic_major_right"), Some(&1.25), "mirrored");
    let b = activations(&steps[2]);
    assert_eq!(b.get("labii_nasi_right"), Some(&0.5));
    assert_eq!(b.get("labii_nasi_left"), None, "not mirrored");
    match steps[3].action(&doc).unwrap() {
        Action::Commands(c) => match c.as_slice() {
            [Command::Checkpoint, Command::SetFemParams(p)] => {
                assert_eq!(p.skin.young_modulus_pa, 2800.0);
                assert_eq!(p.fat, doc.edits.fem.fat, "only the skin changes");
            }
            other => panic!("{other:?}"),
        },
        other => panic!("{other:?}"),
    }
    // Mistakes are named, not ignored.
    let bad = parse(r#"[Activation(muscle: "zygomatic", value: 1.0, mirror: true)]"#).unwrap();
    let e = bad[0].action(&doc).unwrap_err();
    assert!(e.contains("zygomatic"), "{e}");
    let bad = parse(r#"[Panels(["muscle"])]"#).unwrap();
    assert!(bad[0].action(&doc).unwrap_err().contains("muscle"));
    let e = parse("[Denoise, Frobnicate]").unwrap_err();
    assert!(e.contains("Frobnicate"), "{e}");
    // A nudge or an erase needs a scan to snap to.
    let nudge = parse(r#"[NudgeLandmark(point: "chin", offset_mm: (0.0, 1.0, 0.0))]"#).unwrap();
    assert!(nudge[0].action(&doc).unwrap_err().contains("scan"));
    let erase = parse(r#"[Erase(at_mm: (0.0, 1.0, 0.0), radius_mm: 4.0), RestoreErased]"#).unwrap();
    assert!(erase[0].action(&doc).unwrap_err().contains("scan"));
    assert_eq!(erase[1], Step::RestoreErased);
}

#[test]
fn a_session_nudge_snaps_the_point_to_the_scan_near_the_offset() {
    use facesynth::app::session::{Action, parse};
    let mut worker = WorkerState::default();
    let mut doc = Document::new(generic_face::build());
    apply_with(
        &mut worker,
        &mut doc,
        Command::Open(Some(common::gavab("cara1_frontal1.wrl"))),
    );
    apply_with(&mut worker, &mut doc, Command::DetectLandmarks);
    let before = doc
        .edits
        .landmarks
        .unwrap()
        .get(FeaturePoint::MouthCornerLeft);
    let step = parse(r#"[NudgeLandmark(point: "mouth_corner_left", offset_mm: (0.0, 4.0, 0.0))]"#)
        .unwrap()
        .remove(0);
    let Action::Commands(c) = step.action(&doc).unwrap() else {
        panic!("a nudge is a command");
    };
    let [Command::MoveLandmark(FeaturePoint::MouthCornerLeft, to)] = c.as_slice() else {
        panic!("a nudge is one landmark move, got {c:?}");
    };
    let scan = doc.working_mesh().unwrap();
    assert!(
        scan.positions_mm.contains(to),
        "the point is snapped onto a scan vertex"
    );
    // GavabDB's grid is ~1.5 mm: the snapped point is within a grid step or two of the target.
    let target = before + DVec3::new(0.0, 4.0, 0.0);
    assert!((*to - target).length() < 3.0, "{to} vs {target}");
}

#[test]
fn edits_make_the_document_dirty_and_saving_each_part_makes_it_clean() {
    use facesynth::app::document::Part;
    let mut doc = Document::new(generic_face::build());
    assert!(!doc.is_dirty(), "a new document has nothing to lose");
    apply(
        &mut doc,
        Command::MoveLandmark(FeaturePoint::Chin, DVec3::new(1.0, 2.0, 3.0)),
    );
    assert_eq!(doc.unsaved(), vec![Part::Landmarks]);
    // Undoing back to the saved state is clean again; redo is dirty again.
    apply(&mut doc, Command::Undo);
    assert!(!doc.is_dirty());
    apply(&mut doc, Command::Redo);
    assert!(doc.is_dirty());

    let dir = tempfile::tempdir().unwrap();
    apply(
        &mut doc,
        Command::SaveLandmarks(dir.path().join("points.json")),
    );
    assert!(doc.error.is_none(), "{:?}", doc.error);
    assert!(!doc.is_dirty(), "{:?}", doc.unsaved());

    // A failed save keeps the part unsaved.
    apply(
        &mut doc,
        Command::MoveLandmark(FeaturePoint::Chin, DVec3::ZERO),
    );
    apply(
        &mut doc,
        Command::SaveLandmarks(dir.path().join("no/such/dir/points.json")),
    );
    assert!(doc.error.is_some());
    assert_eq!(doc.unsaved(), vec![Part::Landmarks]);

    // Sliders and materials are unsaved work too; presets saved take the sliders with them.
    apply(&mut doc, Command::ApplyPreset("happiness".into()));
    let mut soft = doc.edits.fem;
    soft.skin.young_modulus_pa /= 2.0;
    apply(&mut doc, Command::SetFemParams(soft));
    assert_eq!(
        doc.unsaved(),
        vec![Part::Landmarks, Part::Activations, Part::Materials]
    );
    apply(
        &mut doc,
        Command::StorePreset {
            name: "mine".into(),
            description: String::new(),
        },
    );
    assert!(doc.unsaved().contains(&Part::Presets));
    apply(
        &mut doc,
        Command::SavePresets(dir.path().join("presets.ron")),
    );
    assert_eq!(doc.unsaved(), vec![Part::Landmarks, Part::Materials]);
    // Discarding counts everything as saved.
    doc.mark_all_saved();
    assert!(!doc.is_dirty());
    // Loading landmarks from a file is not unsaved work.
    apply(
        &mut doc,
        Command::LoadLandmarks(dir.path().join("points.json")),
    );
    assert!(doc.error.is_none(), "{:?}", doc.error);
    assert!(!doc.unsaved().contains(&Part::Landmarks));
}

#[test]
fn autosave_round_trips_and_restores_the_edits_onto_the_reloaded_scan() {
    use facesynth::app::autosave::{self, AutosaveState};
    let mut doc = Document::new(generic_face::build());
    apply(
        &mut doc,
        Command::Open(Some(common::gavab("cara1_frontal1.wrl"))),
    );
    let params = facesynth::denoise::DenoiseParams {
        iterations: 9,
        ..Default::default()
    };
    apply(&mut doc, Command::Denoise(params));
    let start = doc.generic.landmarks();
    apply(&mut doc, Command::SetLandmarks(Box::new(start)));
    apply(
        &mut doc,
        Command::MoveLandmark(FeaturePoint::NoseTip, DVec3::new(1.5, -2.0, 80.0)),
    );
    apply(&mut doc, Command::ApplyPreset("sadness".into()));
    // Some hair erased by hand (cara1_frontal1's forehead top).
    let hair = doc.working_mesh().unwrap().positions_mm[doc
        .working_mesh()
        .unwrap()
        .positions_mm
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.y.total_cmp(&b.1.y))
        .unwrap()
        .0];
    apply(&mut doc, Command::Checkpoint);
    apply(
        &mut doc,
        Command::Erase {
            centre_mm: hair,
            radius_mm: 6.0,
        },
    );
    let erased = doc.edits.erased.len();
    assert!(erased > 5, "{erased}");
    let mut fem = doc.edits.fem;
    fem.fat.young_modulus_pa = 240.0;
    apply(&mut doc, Command::SetFemParams(fem));
    apply(
        &mut doc,
        Command::StorePreset {
            name: "sad2".into(),
            description: "d".into(),
        },
    );
    assert!(doc.is_dirty());

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state/facesynth/autosave.ron");
    let state = AutosaveState::of(&doc);
    state.write(&path).unwrap();
    // Written atomically: no temporary file is left beside it.
    let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("autosave.ron")]);
    let back = autosave::find(&path).expect("found").unwrap();
    assert_eq!(back, state);
    assert_eq!(
        back.scan.as_deref(),
        Some(&*common::gavab("cara1_frontal1.wrl"))
    );

    // A fresh editor restores it: the scan is read again and the edits come back on it.
    let mut fresh = Document::new(generic_face::build());
    let mut worker = WorkerState::default();
    let mut jobs: std::collections::VecDeque<_> = back.restore(&mut fresh).into();
    while let Some(job) = jobs.pop_front() {
        jobs.extend(fresh.receive(worker.run(job)));
    }
    assert!(fresh.error.is_none(), "{:?}", fresh.error);
    assert_eq!(fresh.scan.as_ref().unwrap().mesh.vertex_count(), 13_709);
    assert_eq!(fresh.edits, doc.edits);
    assert_eq!(
        fresh.denoised.as_ref().map(|d| d.params),
        Some(params),
        "the scan is denoised again as it was"
    );
    assert_eq!(
        fresh.working_mesh().unwrap().positions_mm,
        doc.working_mesh().unwrap().positions_mm,
        "the erasures are applied to the same denoised scan"
    );
    check_working(&fresh);
    assert!(fresh.is_dirty(), "restored work is still unsaved");
    assert!(fresh.edits.presets.get("sad2").is_some());

    // An autosave written before erasing and denoising were kept still reads.
    let older = AutosaveState {
        scan: None,
        denoise: None,
        edits: facesynth::app::document::Edits::default(),
        ..back.clone()
    };
    let text: String = older
        .to_ron()
        .lines()
        .filter(|l| !l.contains("erased:") && !l.contains("denoise:"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(
        !text.contains("erased") && !text.contains("denoise"),
        "{text}"
    );
    assert_eq!(AutosaveState::from_ron(&text, &path).unwrap(), older);

    // A damaged autosave is reported with its name, not restored.
    std::fs::write(&path, "(format: 1, saved_unix_s: ").unwrap();
    let e = autosave::find(&path).unwrap().unwrap_err().to_string();
    assert!(e.contains("autosave.ron"), "{e}");
    autosave::remove(&path);
    assert!(autosave::find(&path).is_none());
}

/// Learning an expression in the editor: the fit comes back with the fitted face's residual per
/// skin vertex (what the "fit residual" overlay colours) and the actuators that explain it.
#[test]
fn a_fit_in_the_editor_carries_its_residual_map() {
    let mut worker = WorkerState::default();
    let mut doc = Document::new(generic_face::build());
    apply_with(&mut worker, &mut doc, Command::BuildFem);
    apply_with(
        &mut worker,
        &mut doc,
        Command::ApplyPreset("happiness".into()),
    );
    let fem = doc.fem.as_ref().expect("built");
    let n = fem.surface.vertex_count();
    let smile = fem.deformed_surface(&doc.edits.activations);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("smile.obj");
    facesynth::io::write_mesh(&path, &smile).unwrap();
    apply_with(&mut worker, &mut doc, Command::FitExpression(path));
    assert!(doc.error.is_none(), "{:?}", doc.error);
    let fit = doc.fit.as_ref().expect("fitted");
    assert!(fit.rms_after_mm < 0.3 * fit.rms_before_mm, "{fit:?}");
    assert_eq!(fit.residual_mm.len(), n);
    let on: Vec<f64> = fit.residual_mm.iter().flatten().map(|r| r.abs()).collect();
    assert!(on.len() > n / 2, "{} of {n} on the scan", on.len());
    let close = on.iter().filter(|&&r| r < 0.5).count();
    assert!(close > on.len() * 9 / 10, "{close} of {}", on.len());
    let (leader, _) = &fit.contributions_mm[0];
    assert!(
        leader.starts_with("zygomatic_major") || leader.starts_with("cheek_raiser"),
        "{:?}",
        fit.contributions_mm
    );
}
