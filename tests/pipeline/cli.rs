//! The command line end to end: JSON on stdout, one-line errors and exit code 1 on bad input.

use crate::common::{self, facesynth, json_of};

#[test]
fn info_reports_gavabdb_counts_in_millimetres() {
    let path = common::gavab("cara1_frontal1.wrl");
    let v = json_of(&facesynth(&["info", path.to_str().unwrap()]));
    assert_eq!(v["vertices"], 13709);
    assert_eq!(v["faces"], 13395);
    assert_eq!(v["quads"], 13215);
    assert_eq!(v["triangles"], 180);
    let width = v["bbox_max_mm"][0].as_f64().unwrap() - v["bbox_min_mm"][0].as_f64().unwrap();
    assert!((100.0..250.0).contains(&width), "face width {width} mm");
}

#[test]
fn convert_round_trips_through_obj_and_ply() {
    let dir = tempfile::tempdir().unwrap();
    let src = common::gavab("cara1_sonrisa.wrl");
    for ext in ["obj", "ply"] {
        let out = dir.path().join(format!("sonrisa.{ext}"));
        json_of(&facesynth(&[
            "convert",
            src.to_str().unwrap(),
            out.to_str().unwrap(),
        ]));
        let v = json_of(&facesynth(&["info", out.to_str().unwrap()]));
        assert_eq!(v["vertices"], 13296, "{ext}");
        assert_eq!(v["faces"], 12920, "{ext}");
        assert_eq!(v["quads"], 12687, "{ext}");
        assert_eq!(v["triangles"], 233, "{ext}");
    }
}

#[test]
fn generic_writes_mesh_and_thirteen_feature_points() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("generic.obj");
    let json = dir.path().join("generic.json");
    json_of(&facesynth(&[
        "generic",
        "--out",
        obj.to_str().unwrap(),
        "--landmarks",
        json.to_str().unwrap(),
    ]));
    let points: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(points.len(), 13);
    let v = json_of(&facesynth(&["info", obj.to_str().unwrap()]));
    let n = v["vertices"].as_u64().unwrap();
    assert!((2500..=4000).contains(&n), "{n} vertices");
}

#[test]
fn bad_input_gives_one_line_error_naming_the_file_and_exit_code_1() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(std::path::PathBuf, &[u8])> = vec![
        (
            dir.path().join("garbage.wrl"),
            &[0xff, 0x00, 0x13, 0x37, 0x80],
        ),
        (dir.path().join("empty.obj"), b""),
        (dir.path().join("scan.unknown"), b"1 2 3\n"),
        (
            dir.path().join("bad_index.obj"),
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        ),
    ];
    for (path, bytes) in &cases {
        std::fs::write(path, bytes).unwrap();
    }
    let missing = dir.path().join("missing.wrl");
    let paths: Vec<&std::path::Path> = cases
        .iter()
        .map(|(p, _)| p.as_path())
        .chain([missing.as_path(), dir.path()])
        .collect();
    for path in paths {
        let out = facesynth(&["info", path.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(1), "{}", path.display());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        let name = path.file_name().unwrap().to_str().unwrap();
        assert!(stderr.contains(name), "{stderr} should name {name}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[test]
fn curvature_writes_shape_index_as_ply_quality() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.ply");
    let src = common::gavab("cara1_frontal1.wrl");
    let v = json_of(&facesynth(&[
        "curvature",
        src.to_str().unwrap(),
        out.to_str().unwrap(),
    ]));
    assert_eq!(v["vertices"], 13709);
    let bytes = std::fs::read(&out).unwrap();
    let (mesh, s) = facesynth::io::ply::parse_with_scalar(
        &bytes,
        &out,
        &facesynth::io::ReadLimits::default(),
        Some("quality"),
    )
    .unwrap();
    let s = s.expect("quality property");
    assert_eq!(s.len(), mesh.vertex_count());
    assert!(s.iter().all(|x| (0.0..=1.0).contains(x)));
    // Writing anything but PLY is refused with one line.
    let bad = facesynth(&["curvature", src.to_str().unwrap(), "x.obj"]);
    assert!(!bad.status.success());
}

#[test]
fn landmarks_prints_points_distances_warnings_and_time() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("lm.json");
    let src = common::gavab("cara1_frontal1.wrl");
    let v = json_of(&facesynth(&[
        "landmarks",
        src.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]));
    let lm = v["landmarks"].as_object().unwrap();
    assert_eq!(lm.len(), 13);
    let points: facesynth::Landmarks = serde_json::from_value(v["landmarks"].clone()).unwrap();
    assert!(points.get(facesynth::FeaturePoint::NoseTip).z > -1250.0);
    assert_eq!(v["distances_mm"].as_object().unwrap().len(), 9);
    assert!(v["warnings"].is_array());
    assert!(v["millis"].as_f64().unwrap() > 0.0);
    // The sampling the descriptors were fitted on: GavabDB's face is sampled every 1.4–1.8 mm,
    // and the fit reaches `descriptor_reach_mm` (10 mm) in whole rings.
    let spacing_mm = v["descriptors"]["spacing_mm"].as_f64().unwrap();
    let rings = v["descriptors"]["rings"].as_u64().unwrap() as f64;
    assert!((1.4..1.8).contains(&spacing_mm), "{}", v["descriptors"]);
    assert_eq!(rings, (10.0 / spacing_mm).round(), "{}", v["descriptors"]);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(saved["landmarks"], v["landmarks"]);
}

#[test]
fn bench_landmarks_reports_stage_times() {
    let src = common::gavab("cara1_frontal1.wrl");
    let v = json_of(&facesynth(&[
        "bench-landmarks",
        src.to_str().unwrap(),
        "--repeat",
        "1",
    ]));
    assert_eq!(v["vertices"], 13709);
    for k in ["denoise_ms", "landmarks_ms", "total_ms"] {
        assert!(v[k]["min"].as_f64().unwrap() > 0.0, "{k}");
    }
}

/// Every point of two `landmarks --json` outputs within `tol_mm`.
fn assert_same_points(a: &serde_json::Value, b: &serde_json::Value, tol_mm: f64) {
    for (name, p) in a["landmarks"].as_object().unwrap() {
        let q = &b["landmarks"][name];
        let d: f64 = (0..3)
            .map(|k| (p[k].as_f64().unwrap() - q[k].as_f64().unwrap()).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(d < tol_mm, "{name}: {d} mm apart");
    }
}

/// cara1_frontal1 and a copy of it scaled by `factor` (file units per millimetre), written as
/// `dir/name`.
fn cara1_scaled(
    dir: &std::path::Path,
    factor: f64,
    name: &str,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let src = common::gavab("cara1_frontal1.wrl");
    let mut mesh = facesynth::io::read_mesh(&src).unwrap();
    for p in &mut mesh.positions_mm {
        *p *= factor;
    }
    let scaled = dir.join(name);
    facesynth::io::write_mesh(&scaled, &mesh).unwrap();
    (src, scaled)
}

/// A real scan exported in metres (a face 0.2 units wide, as a real head scan came) is scaled
/// to millimetres, said on stderr with the file's name and in `landmarks`', `info`'s and
/// `register`'s `units`, and gives the points of the millimetre scan; `--units mm` reads it as
/// it is and then finds no face, and says which flag reads it.
#[test]
fn a_scan_in_metres_is_scaled_to_millimetres_and_said() {
    let dir = tempfile::tempdir().unwrap();
    let (src, metres) = cara1_scaled(dir.path(), 0.001, "head_in_metres.ply");
    let mm = json_of(&facesynth(&["landmarks", src.to_str().unwrap()]));
    let out = facesynth(&["landmarks", metres.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("head_in_metres.ply") && stderr.contains("metres"),
        "{stderr}"
    );
    let scaled = json_of(&out);
    // PLY stores single precision: 1e-3 m ~ 1e-4 mm relative; the points agree to 0.1 mm.
    assert_same_points(&mm, &scaled, 0.1);
    assert_eq!(
        scaled["units"],
        serde_json::json!({"file": "m", "mm_per_file_unit": 1000.0, "guessed": true})
    );
    assert_eq!(
        mm["units"],
        serde_json::json!({"file": "mm", "mm_per_file_unit": 1.0, "guessed": true})
    );
    let info = json_of(&facesynth(&["info", metres.to_str().unwrap()]));
    assert_eq!(info["units"], scaled["units"]);
    let registered = json_of(&facesynth(&["register", metres.to_str().unwrap()]));
    assert_eq!(registered["units"], scaled["units"]);
    let out = facesynth(&["landmarks", metres.to_str().unwrap(), "--units", "mm"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--units m"));
}

/// A scan in centimetres (a face 26 units wide) is not guessed (a millimetre crop can be that
/// size), but the feature points refuse it with a one-line error naming the file and the flag;
/// with `--units cm` it gives the millimetre scan's points, and the JSON says so.
#[test]
fn a_scan_in_centimetres_is_refused_with_the_flag_that_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let (src, cm) = cara1_scaled(dir.path(), 0.1, "head_in_cm.ply");
    let out = facesynth(&["landmarks", cm.to_str().unwrap()]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.lines().count() == 1
            && stderr.contains("head_in_cm.ply")
            && stderr.contains("--units cm"),
        "{stderr}"
    );
    let mm = json_of(&facesynth(&["landmarks", src.to_str().unwrap()]));
    let read = json_of(&facesynth(&[
        "landmarks",
        cm.to_str().unwrap(),
        "--units",
        "cm",
    ]));
    assert_same_points(&mm, &read, 0.1);
    assert_eq!(
        read["units"],
        serde_json::json!({"file": "cm", "mm_per_file_unit": 10.0, "guessed": false})
    );
}

/// A scan in other axes (facing −x, forehead +z): the search finds its face, `--facing/--up`
/// give the same points, `register` the same fit as in the scanner frame, and a pair that is
/// not a frame is a one-line error naming the flags.
#[test]
fn facing_and_up_give_the_scan_axes() {
    let dir = tempfile::tempdir().unwrap();
    let src = common::gavab("cara1_frontal1.wrl");
    let mut mesh = facesynth::io::read_mesh(&src).unwrap();
    // Face towards −x, forehead towards +z: (x, y, z) ↦ (−z, −x, y) maps +z to −x and +y to +z.
    for p in &mut mesh.positions_mm {
        *p = glam::DVec3::new(-p.z, -p.x, p.y);
    }
    mesh.update_normals();
    let turned = dir.path().join("turned.ply");
    facesynth::io::write_mesh(&turned, &mesh).unwrap();
    let t = turned.to_str().unwrap();
    let searched = json_of(&facesynth(&["landmarks", t]));
    let given = json_of(&facesynth(&[
        "landmarks",
        t,
        "--facing",
        "-x",
        "--up",
        "+z",
    ]));
    assert_eq!(given["orientation"]["facing"], "-x");
    assert_eq!(given["orientation"]["up"], "+z");
    assert_eq!(given["suspect"], false, "{}", given["suspect_reasons"]);
    assert_same_points(&searched, &given, 2.0);
    // Registration on the file in other axes: the same fit as on the scan in its own frame,
    // and its report says in which axes it found the face.
    let reg = |path: &str| json_of(&facesynth(&["register", path]));
    let (a, b) = (reg(src.to_str().unwrap()), reg(t));
    assert_eq!(a["landmarks_orientation"]["facing"], "+z");
    assert_eq!(b["landmarks_orientation"]["facing"], "-x");
    assert_eq!(b["landmarks_orientation"]["up"], "+z");
    for key in ["rigid_rms_mm", "unmatched_vertices"] {
        let (x, y) = (a[key].as_f64().unwrap(), b[key].as_f64().unwrap());
        assert!(
            (x - y).abs() <= 1e-3 * x.abs().max(1.0),
            "{key}: {x} vs {y}"
        );
    }
    // Inside the face (below the detected hairline, between the temples) the registered face
    // lies on the real scan: measured mean 0.07 mm, p95 0.0 mm over 1,603 vertices, 19 of
    // them beyond the scan's edge; above the hairline or beyond the temples mean 6.9 mm.
    let face = &a["face_region_distance_mm"];
    let (mean, p95) = (
        face["mean"].as_f64().unwrap(),
        face["p95"].as_f64().unwrap(),
    );
    assert!(mean <= 1.0 && p95 <= 3.0, "{face}");
    assert_eq!(face["by_region"].as_object().unwrap().len(), 6, "{face}");
    assert!(
        face["above_hairline_or_temples"]["mean"].as_f64().unwrap() > mean,
        "{face}"
    );
    let out = facesynth(&["landmarks", t, "--facing", "+z", "--up", "-z"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--facing") && err.contains("perpendicular"),
        "{err}"
    );
}

/// One landmark file format: what `landmarks --json` writes is read back by `--landmarks`
/// (the points under `"landmarks"`, source `detected`: registered as detection registers,
/// cheek and forehead borders left out), as is a flat name → [x, y, z] map (source `given`:
/// all 13 points matched). A file without all 13 points is a one-line error naming it.
#[test]
fn landmarks_json_feeds_register_in_either_shape() {
    let dir = tempfile::tempdir().unwrap();
    let scan = common::gavab("cara1_frontal1.wrl");
    let scan = scan.to_str().unwrap();
    let report = dir.path().join("report.json");
    json_of(&facesynth(&[
        "landmarks",
        scan,
        "--json",
        report.to_str().unwrap(),
    ]));
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let flat = dir.path().join("flat.json");
    std::fs::write(&flat, written["landmarks"].to_string()).unwrap();
    let register = |file: Option<&std::path::Path>| {
        let mut args = vec!["register", scan];
        if let Some(f) = file {
            args.extend(["--landmarks", f.to_str().unwrap()]);
        }
        let mut v = json_of(&facesynth(&args));
        assert_eq!(v["landmarks_detected"], file.is_none());
        for k in [
            "millis",
            "landmarks_file",
            "landmarks_source",
            "landmarks_detected",
        ] {
            v.as_object_mut().unwrap().remove(k);
        }
        v.as_object_mut().unwrap().remove("landmark_warnings");
        v
    };
    let (detected, a, b) = (
        register(None),
        register(Some(&report)),
        register(Some(&flat)),
    );
    // The file holds the points to 1 µm: the same fit as detection, to the 4 decimals printed
    // (measured: 6.68 mm over the 10 anatomical points).
    assert_eq!(a["rigid_rms_mm"], detected["rigid_rms_mm"]);
    assert_eq!(
        a["landmark_residual_mm"].as_object().unwrap().len(),
        10,
        "{a}"
    );
    // The flat map matches the borders too (measured 12.6 mm over 13 points).
    assert_eq!(
        b["landmark_residual_mm"].as_object().unwrap().len(),
        13,
        "{b}"
    );
    assert!(b["rigid_rms_mm"].as_f64().unwrap() < 15.0, "{b}");
    let partial = dir.path().join("partial.json");
    std::fs::write(&partial, r#"{"landmarks": {"nose_tip": [0, 0, 0]}}"#).unwrap();
    let out = facesynth(&["register", scan, "--landmarks", partial.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("partial.json") && err.contains("inner_eye_left"),
        "{err}"
    );
}

/// `register` goes on with suspect feature points (a false alarm must not block the work) but
/// says so: one line on stderr naming the file and the reasons, and the report's
/// `landmarks_suspect` and `landmarks_suspect_reasons`. A profile is suspect by design; a
/// frontal scan says nothing.
#[test]
fn register_says_when_its_feature_points_are_suspect() {
    let profile = common::gavab("cara1_derecha.wrl");
    let out = facesynth(&["register", profile.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.lines().count() == 1
            && stderr.contains("cara1_derecha.wrl")
            && stderr.contains("suspect feature points")
            && stderr.contains("profile"),
        "{stderr}"
    );
    let v = json_of(&out);
    assert_eq!(v["landmarks_suspect"], true);
    let reasons = v["landmarks_suspect_reasons"].as_array().unwrap();
    assert!(
        reasons
            .iter()
            .any(|r| r.as_str().unwrap().contains("profile")),
        "{reasons:?}"
    );
    let frontal = common::gavab("cara1_frontal1.wrl");
    let out = facesynth(&["register", frontal.to_str().unwrap()]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("suspect"));
    let v = json_of(&out);
    assert_eq!(v["landmarks_suspect"], false);
    assert_eq!(v["landmarks_suspect_reasons"], serde_json::json!([]));
}
