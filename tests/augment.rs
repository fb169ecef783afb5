//! Gallery augmentation (paper section 3) on generated scans: outputs, resume after a killed
//! run, failure list; and the expression transfer onto the scan on an analytic case.

mod common;

use facesynth::Mesh;
use facesynth::pipeline::{self, AugmentParams, DONE_MARKER};
use glam::DVec3;

/// A regular grid of quads in the plane z = 0, `n × n` vertices, `step` mm apart.
fn plane(n: usize, step: f64) -> Mesh {
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            positions.push(DVec3::new(i as f64 * step, j as f64 * step, 0.0));
        }
    }
    for j in 0..n as u32 - 1 {
        for i in 0..n as u32 - 1 {
            let v = j * n as u32 + i;
            faces.push([v, v + 1, v + 1 + n as u32, v + n as u32]);
        }
    }
    Mesh::from_faces(positions, faces)
}

#[test]
fn transfer_moves_the_scan_with_the_face_and_leaves_the_far_part_alone() {
    let scan = plane(41, 1.0); // 40 × 40 mm
    // The "face" covers the left half of the scan and moves 2 mm up everywhere.
    let face = Mesh::from_faces(
        plane(11, 2.0)
            .positions_mm
            .iter()
            .map(|p| *p + DVec3::new(0.0, 10.0, 0.0))
            .collect(),
        plane(11, 2.0)
            .faces
            .iter()
            .map(|f| f.to_vec())
            .collect::<Vec<_>>(),
    );
    let u = vec![DVec3::new(0.0, 2.0, 0.0); face.vertex_count()];
    let out = pipeline::transfer_expression(&scan, &face, &u, 8.0);
    for (p, q) in scan.positions_mm.iter().zip(&out.positions_mm) {
        let d = *q - *p;
        let inside = p.x <= 20.0 && (10.0..=30.0).contains(&p.y);
        if inside {
            assert!((d - DVec3::new(0.0, 2.0, 0.0)).length() < 1e-9, "{p}: {d}");
        }
        let far = p.x > 28.0 || p.y < 2.0 || p.y > 38.0;
        if far {
            assert!(d.length() < 1e-12, "{p} moved {d}");
        }
        assert!(d.x.abs() < 1e-12 && d.z.abs() < 1e-12 && d.y <= 2.0 + 1e-12);
    }
}

#[test]
fn augment_writes_18_expressions_per_scan_and_resumes_after_a_killed_run() {
    let data = common::synth_dataset(2, 11, false);
    let out = tempfile::tempdir().unwrap();
    let params = AugmentParams::default();
    let quiet = |_: usize, _: usize, _: &str| {};
    // The progress callback (the CLI's bar): once with 0 before any work, then each count once.
    let calls = std::sync::Mutex::new(Vec::new());
    let record = |k: usize, n: usize, _: &str| calls.lock().unwrap().push((k, n));
    let (done, failed) = pipeline::augment(&data, out.path(), &params, &record).unwrap();
    let mut calls = calls.into_inner().unwrap();
    assert_eq!(calls[0], (0, 2));
    calls.sort();
    assert_eq!(calls, [(0, 2), (1, 2), (2, 2)]);
    assert_eq!(done.len() + failed.len(), 2);
    assert!(failed.is_empty(), "{failed:?}");
    let dir = out.path().join("subj000_frontal1");
    let plys = std::fs::read_dir(&dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "ply")
        })
        .count();
    assert_eq!(plys, 18);
    assert!(dir.join("face/neutral.obj").is_file());
    assert!(dir.join(DONE_MARKER).is_file());
    // The synthetic smile is the scan itself (same vertex count), moved near the mouth only.
    let scan = facesynth::io::read_mesh(&data.join("subj000_frontal1.wrl")).unwrap();
    let smile = facesynth::io::read_mesh(&dir.join("happiness.ply")).unwrap();
    assert_eq!(smile.vertex_count(), scan.vertex_count());
    assert!(
        std::fs::read_to_string(out.path().join("failures.json"))
            .unwrap()
            .contains("[]")
    );

    // A killed run: one subject lost its marker and has a truncated file. Re-running redoes
    // exactly that subject; the finished one is skipped.
    std::fs::remove_file(dir.join(DONE_MARKER)).unwrap();
    std::fs::write(dir.join("happiness.ply"), b"ply\nformat binary_little").unwrap();
    let (again, failed) = pipeline::augment(&data, out.path(), &params, &quiet).unwrap();
    assert!(failed.is_empty());
    let redone: Vec<_> = again.iter().filter(|a| !a.resumed).collect();
    assert_eq!(redone.len(), 1);
    assert!(redone[0].scan.ends_with("subj000_frontal1.wrl"));
    let smile = facesynth::io::read_mesh(&dir.join("happiness.ply")).unwrap();
    assert_eq!(smile.vertex_count(), scan.vertex_count());
}

#[test]
fn augment_lists_a_broken_scan_and_goes_on() {
    let data = common::synth_dataset(2, 11, false);
    let gallery = tempfile::tempdir().unwrap();
    std::fs::copy(
        data.join("subj000_frontal1.wrl"),
        gallery.path().join("subj000_frontal1.wrl"),
    )
    .unwrap();
    std::fs::write(
        gallery.path().join("broken_frontal1.wrl"),
        "#VRML V1.0 ascii\n[",
    )
    .unwrap();
    let out = tempfile::tempdir().unwrap();
    let (done, failed) = pipeline::augment(
        gallery.path(),
        out.path(),
        &AugmentParams::default(),
        &|_, _, _| {},
    )
    .unwrap();
    assert_eq!(done.len(), 1);
    assert_eq!(failed.len(), 1);
    assert!(
        failed[0].reason.contains("broken_frontal1.wrl"),
        "{}",
        failed[0].reason
    );
}

#[test]
fn augmented_gallery_feeds_the_recognition_protocol() {
    let data = common::synth_dataset(2, 11, false);
    let out = tempfile::tempdir().unwrap();
    let (done, _) =
        pipeline::augment(&data, out.path(), &AugmentParams::default(), &|_, _, _| {}).unwrap();
    let params = facesynth::recognition::ProtocolParams::default();
    let eval = facesynth::recognition::evaluate(&data, Some(out.path()), &params).unwrap();
    let r = &eval.report;
    assert_eq!(r.synthetic_gallery_samples, 18 * done.len());
    assert_eq!(r.method, facesynth::recognition::Method::Fisherfaces);
    assert!(r.failures.is_empty(), "{:?}", r.failures);
    // The gallery scans' feature points come from augment's done.json, not a new detection.
    assert_eq!(r.cached_landmarks, done.len());

    // The command: report with and without the synthetic gallery, and the CMC plot.
    let report = out.path().join("report.json");
    let plot = out.path().join("cmc.png");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .arg("evaluate")
        .arg("--dataset")
        .arg(&data)
        .arg("--augmented")
        .arg(out.path())
        .arg("--report")
        .arg(&report)
        .arg("--plot")
        .arg(&plot)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(v["synthetic_gallery_samples"], 18 * done.len());
    let without = &v["without_augmentation"];
    assert_eq!(without["method"], "eigenfaces");
    assert_eq!(without["gallery_samples"], done.len());
    assert_eq!(without["cmc"].as_array().unwrap().len(), done.len());
    // A PNG of the documented size, mostly white, with curves and text drawn on it.
    let img = image::open(&plot).unwrap().to_rgb8();
    let (w, h) = facesynth::recognition::plot::DEFAULT_SIZE;
    assert_eq!(img.dimensions(), (w, h));
    let inked = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
    let total = (w * h) as usize;
    assert!(
        inked > total / 200 && inked < total / 2,
        "{inked} of {total} pixels drawn"
    );
    // Colour curves (not only black axes and text).
    assert!(img.pixels().any(|p| p.0[0].abs_diff(p.0[2]) > 100));
}

#[test]
fn unfold_repairs_a_turned_over_quad_and_leaves_a_clean_surface_alone() {
    let clean = plane(9, 2.0);
    let (same, moved) = pipeline::unfold_surface(&clean);
    assert_eq!(moved, 0);
    assert_eq!(same.positions_mm, clean.positions_mm);
    // Push one interior vertex across its neighbours: its quads turn over.
    let mut folded = clean.clone();
    let v = 4 * 9 + 4;
    folded.positions_mm[v] += DVec3::new(5.0, 5.0, 0.0);
    let (fixed, moved) = pipeline::unfold_surface(&folded);
    assert!(moved >= 1);
    // Every quad turns the same way again (corner normals along +z).
    for f in fixed.faces.iter() {
        for k in 0..4 {
            let p = |i: usize| fixed.positions_mm[f[(k + i) % 4] as usize];
            assert!(
                (p(1) - p(0)).cross(p(3) - p(0)).z > 0.0,
                "face {f:?} still folded"
            );
        }
    }
    // Far from the fold nothing moved.
    assert_eq!(fixed.positions_mm[0], clean.positions_mm[0]);
}

#[test]
fn open_jaw_turns_only_the_lower_face_down_and_back() {
    // A vertical plane facing +z through the nose tip, in a scan frame turned by 90° about y
    // (the face frame is recovered through the pose).
    let mut face = plane(41, 3.0);
    for p in &mut face.positions_mm {
        *p = DVec3::new(p.x - 60.0, p.y - 90.0, 0.0);
    }
    let scan_from_face = glam::DMat3::from_rotation_y(std::f64::consts::FRAC_PI_2);
    let nose = DVec3::new(5.0, 2.0, -1200.0);
    let scan = Mesh::from_faces(
        face.positions_mm
            .iter()
            .map(|&p| nose + scan_from_face * p)
            .collect(),
        face.faces.iter().map(|f| f.to_vec()).collect::<Vec<_>>(),
    );
    let pose = facesynth::recognition::pose::ScanPose {
        nose_tip_in_scan: nose,
        face_from_scan: scan_from_face.transpose(),
    };
    let jaw = pipeline::JawParams::default();
    let mouth = (0.0, -35.0, 25.0);
    let out = pipeline::open_jaw(&scan, &pose, mouth, 8.0, &jaw);
    for (f, q) in face.positions_mm.iter().zip(&out.positions_mm) {
        let moved = pose.face_from_scan * (*q - nose) - *f;
        if f.y >= mouth.1 + jaw.blend_above_mm {
            assert!(moved.length() < 1e-9, "{f} moved {moved}");
        }
        if f.y <= -70.0 {
            // The chin turns about the hinge: down and back, by about angle × radius.
            assert!(moved.y < -1.0 && moved.z < -1.0, "{f}: {moved}");
            let radius = (*f - DVec3::new(f.x, jaw.hinge_y_mm, jaw.hinge_z_mm)).length();
            assert!((moved.length() - 8f64.to_radians() * radius).abs() < 0.05 * radius);
        }
    }
    // The cavity: the middle of the lip band, between the corners, is pushed back.
    let mid = face
        .positions_mm
        .iter()
        .position(|p| p.x.abs() < 1.6 && (p.y - (mouth.1 - 4.0)).abs() < 1.6)
        .unwrap();
    let moved = pose.face_from_scan * (out.positions_mm[mid] - nose) - face.positions_mm[mid];
    assert!(moved.z < -10.0, "{moved}");
}
