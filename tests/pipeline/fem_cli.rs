//! `facesynth synthesize` and `export-fem` end to end.

use crate::common;

fn run(args: &[&str]) -> serde_json::Value {
    common::json_of(&common::facesynth(args))
}

#[test]
fn synthesize_generic_writes_meshes_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let v = run(&[
        "synthesize",
        "--out",
        out.to_str().unwrap(),
        "--expressions",
        "happiness,frown",
        "--png",
    ]);
    for name in [
        "neutral.obj",
        "happiness.obj",
        "frown.obj",
        "report.json",
        "happiness.png",
    ] {
        assert!(out.join(name).is_file(), "{name} missing");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report, v);
    // Two element layers under every quad of the generic face.
    let quads = facesynth::generic_face::build().mesh.face_counts().quads;
    assert_eq!(v["elements"], 2 * quads as u64);
    assert!(v["dofs"].as_u64().unwrap() > 20_000);
    assert!(v["factor_millis"].as_f64().unwrap() > 0.0);
    assert!(v["basis_millis"].as_f64().unwrap() > 0.0);
    let smile = &v["expressions"]["happiness"];
    let max = smile["max_displacement_mm"].as_f64().unwrap();
    assert!((3.0..15.0).contains(&max), "{max}");
    assert!(smile["mean_displacement_mm"].as_f64().unwrap() < max);
    // Same topology, moved vertices.
    let neutral = facesynth::io::read_mesh(&out.join("neutral.obj")).unwrap();
    let happy = facesynth::io::read_mesh(&out.join("happiness.obj")).unwrap();
    assert_eq!(neutral.faces, happy.faces);
    assert_ne!(neutral.positions_mm, happy.positions_mm);
    // Unknown names are one-line errors.
    let bad = common::facesynth(&[
        "synthesize",
        "--out",
        out.to_str().unwrap(),
        "--expressions",
        "nope",
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown expression"));
}

#[test]
fn export_fem_writes_a_legacy_vtk_hex_grid() {
    let dir = tempfile::tempdir().unwrap();
    let vtk = dir.path().join("happy.vtk");
    let v = run(&[
        "export-fem",
        "--expression",
        "happiness",
        "--vtk",
        vtk.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&vtk).unwrap();
    let points = v["points"].as_u64().unwrap() as usize;
    let cells = v["cells"].as_u64().unwrap() as usize;
    assert!(text.starts_with("# vtk DataFile Version 3.0\n"));
    assert!(text.contains(&format!("POINTS {points} double")));
    assert!(text.contains(&format!("CELLS {cells} {}", 9 * cells)));
    assert!(text.contains(&format!("POINT_DATA {points}")));
    assert!(text.contains(&format!("CELL_DATA {cells}")));
    for key in [
        "VECTORS displacement double",
        "VECTORS force double",
        "VECTORS reaction double",
        "SCALARS fixed int 1",
        "SCALARS young_modulus_pa double 1",
        "SCALARS poisson_ratio double 1",
    ] {
        assert!(text.contains(key), "{key}");
    }
    let types: Vec<&str> = text
        .split("CELL_TYPES")
        .nth(1)
        .unwrap()
        .lines()
        .skip(1)
        .take(cells)
        .collect();
    assert!(types.iter().all(|t| *t == "12"));
    assert!(!text.contains("NaN") && !text.contains("inf"));
    // The reactions balance the muscle loads.
    let sum = |key: &str| -> Vec<f64> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (applied, reaction) = (sum("applied_force_sum_n"), sum("reaction_sum_n"));
    let size = applied.iter().map(|a| a.abs()).fold(0.0, f64::max);
    assert!(size > 0.0);
    for (a, r) in applied.iter().zip(&reaction) {
        assert!((a + r).abs() <= 1e-5 * size, "{applied:?} {reaction:?}");
    }
}

#[test]
fn synthesize_on_a_registered_scan() {
    let clean = common::synth_dataset(5, 1, true);
    let scan_path = clean.join("subj002_frontal1.wrl");
    let scan = facesynth::io::read_mesh(&scan_path).unwrap();
    let truth =
        facesynth::registration::truth_points(&clean.join("subj002_frontal1.json"), &scan).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let lm = dir.path().join("lm.json");
    std::fs::write(&lm, serde_json::to_string(&truth.landmarks).unwrap()).unwrap();
    let out = dir.path().join("out");
    let v = run(&[
        "synthesize",
        scan_path.to_str().unwrap(),
        "--landmarks",
        lm.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--expressions",
        "happiness,surprise",
    ]);
    println!("{v}");
    for e in ["happiness", "surprise"] {
        let max = v["expressions"][e]["max_displacement_mm"].as_f64().unwrap();
        // Surprise drops the jaw 8 degrees: the chin moves 10-20 mm on a real face.
        assert!((1.0..25.0).contains(&max), "{e}: {max}");
    }
}

#[test]
fn fit_expression_writes_a_loadable_preset() {
    let clean = common::synth_dataset(5, 1, true);
    let neutral = clean.join("subj002_frontal1.wrl");
    let smile = clean.join("subj002_sonrisa.wrl");
    let dir = tempfile::tempdir().unwrap();
    let mut lm_paths = Vec::new();
    for (scan, name) in [(&neutral, "frontal1"), (&smile, "sonrisa")] {
        let mesh = facesynth::io::read_mesh(scan).unwrap();
        let truth = facesynth::registration::truth_points(
            &clean.join(format!("subj002_{name}.json")),
            &mesh,
        )
        .unwrap();
        let path = dir.path().join(format!("{name}.json"));
        std::fs::write(&path, serde_json::to_string(&truth.landmarks).unwrap()).unwrap();
        lm_paths.push(path);
    }
    let preset = dir.path().join("smile.ron");
    let residual = dir.path().join("residual.ply");
    let picture = dir.path().join("residual.png");
    // The two scans and their points, as fit-expression and compare-expression take them.
    let pair = [
        neutral.to_str().unwrap(),
        smile.to_str().unwrap(),
        "--landmarks",
        lm_paths[0].to_str().unwrap(),
        "--expression-landmarks",
        lm_paths[1].to_str().unwrap(),
    ];
    let v = run(&[
        &[
            "fit-expression",
            "--residual-ply",
            residual.to_str().unwrap(),
            "--residual-png",
            picture.to_str().unwrap(),
        ][..],
        &pair,
        &["--out", preset.to_str().unwrap(), "--name", "learned_smile"],
    ]
    .concat());
    println!("{v}");
    // Measured 1.42 -> 0.66 mm: the fit explains over half the expression's displacement.
    let (before, after) = (
        v["rms_before_mm"].as_f64().unwrap(),
        v["rms_after_mm"].as_f64().unwrap(),
    );
    assert!(after < 0.6 * before, "{before} -> {after}");
    assert!(v["closest_preset"].is_string());
    // The residual picture: the fitted face from the front, 480 px wide, coloured (not grey).
    let img = image::open(&picture).unwrap().to_rgb8();
    assert_eq!(img.width(), 480);
    assert!(img.pixels().any(|p| p.0[0].abs_diff(p.0[2]) > 100));
    // Both scans' points came from the (flat, ground-truth) files, so nothing is suspect.
    assert_eq!(v["landmarks_source"], "given");
    assert_eq!(v["landmarks_suspect_reasons"], serde_json::json!([]));
    assert_eq!(
        v["expression_landmarks_suspect_reasons"],
        serde_json::json!([])
    );
    assert_eq!(v["expression_landmarks_source"], "given");
    // 18 muscles, the 8 soft-tissue loads (4 pairs) and the jaw's four actuators.
    let fitted = v["activations"].as_object().unwrap();
    assert_eq!(fitted.len(), 30);
    assert!(fitted.contains_key("jaw_open"));
    // The residual map: the fitted face with its signed distance to the scan per vertex.
    let bytes = std::fs::read(&residual).unwrap();
    let (mesh, quality) = facesynth::io::ply::parse_with_scalar(
        &bytes,
        &residual,
        &facesynth::io::default_limits(),
        Some("quality"),
    )
    .unwrap();
    let quality = quality.expect("quality property");
    let r = &v["residual_ply"];
    let on = r["vertices_on_scan"].as_u64().unwrap() as usize;
    assert_eq!(
        on + r["vertices_off_scan"].as_u64().unwrap() as usize,
        mesh.vertex_count()
    );
    assert_eq!(quality.len(), mesh.vertex_count());
    let on_scan: Vec<f64> = quality
        .iter()
        .filter(|&&q| q != 0.0)
        .map(|&q| q as f64)
        .collect();
    assert!(on_scan.len() <= on && on_scan.len() > on * 9 / 10);
    let rms = (on_scan.iter().map(|q| q * q).sum::<f64>() / on as f64).sqrt();
    assert!(
        (rms - r["rms_mm"].as_f64().unwrap()).abs() < 1e-3,
        "{rms} vs {r}"
    );
    // Both signs occur, and no residual exceeds the 8 mm search radius.
    assert!(on_scan.iter().any(|&q| q > 0.0) && on_scan.iter().any(|&q| q < 0.0));
    assert!(on_scan.iter().all(|q| q.abs() <= 8.0));
    let set = facesynth::fem::expressions::ExpressionSet::load(&preset).unwrap();
    assert_eq!(set.expressions[0].name, "learned_smile");
    // The learned preset synthesizes like a built-in one.
    let out = dir.path().join("out");
    let s = run(&[
        "synthesize",
        "--out",
        out.to_str().unwrap(),
        "--presets",
        preset.to_str().unwrap(),
        "--expressions",
        "learned_smile",
    ]);
    assert!(
        s["expressions"]["learned_smile"]["max_displacement_mm"]
            .as_f64()
            .unwrap()
            > 0.5
    );
    // Side by side with the scan it was learned from, the learned preset beats a built-in
    // smile and the neutral face over the whole face and on the mouth.
    let compare = |extra: &[&'static str]| -> Vec<&str> {
        [
            &["compare-expression"][..],
            &pair,
            &["--preset-file", preset.to_str().unwrap()],
            extra,
        ]
        .concat()
    };
    let c = run(&compare(&[
        "--preset",
        "learned_smile",
        "--preset",
        "happiness",
    ]));
    println!("{c}");
    let rows = c["rows"].as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["preset"].as_str().unwrap()).collect();
    assert_eq!(names, ["none", "learned_smile", "happiness"]);
    for key in ["whole_face_rms_mm", "mouth_rms_mm"] {
        let rms = |k: usize| rows[k][key].as_f64().unwrap();
        assert!(rms(1) < rms(2) && rms(1) < rms(0), "{key}: {rows:?}");
    }
    assert_eq!(c["best"]["whole_face"]["preset"], "learned_smile");
    let bad = compare(&["--preset", "smirk"]);
    let err = common::cli_error(&bad.iter().map(std::ffi::OsStr::new).collect::<Vec<_>>());
    assert!(err.contains("unknown preset `smirk`"), "{err}");
}

#[test]
fn fit_expression_learns_an_open_jaw_and_repairs_folds_like_augment() {
    // Seed 100's subject 4: its registered face has folded quads (a projection across a hole's
    // rim), which inverted the layers in fit-expression while augment repaired them.
    let data = common::synth_dataset(6, 100, false);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("laugh.ron");
    let v = run(&[
        "fit-expression",
        data.join("subj004_frontal1.wrl").to_str().unwrap(),
        data.join("subj004_risa.wrl").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    println!("{v}");
    let repairs = &v["repairs"];
    assert!(repairs["unfolded_vertices"].is_u64() && repairs["layer_thickness_factor"].is_f64());
    let (before, after) = (
        v["rms_before_mm"].as_f64().unwrap(),
        v["rms_after_mm"].as_f64().unwrap(),
    );
    // Measured 2.90 -> 1.07 mm.
    assert!(after < 0.5 * before, "{before} -> {after}");
    // The laugh opens the mouth (ground truth: jawOpen 0.25-0.55 of the ICT model's range).
    let jaw = v["activations"]["jaw_open"].as_f64().unwrap();
    assert!(jaw > 2.0, "jaw_open {jaw} degrees");
}

/// `synthesize` on a scan whose detected points are suspect (a profile) builds the face but
/// says so on stderr and lists the reasons in its report.
#[test]
fn synthesize_on_suspect_points_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let profile = common::gavab("cara1_derecha.wrl");
    let done = common::facesynth(&[
        "synthesize",
        profile.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--expressions",
        "happiness",
    ]);
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(
        stderr.contains("cara1_derecha.wrl") && stderr.contains("suspect feature points"),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert!(
        !report["landmarks_suspect_reasons"]
            .as_array()
            .unwrap()
            .is_empty()
    );
}
