//! Registration of a generic face to synthetic scans with ground truth (and real GavabDB).

use crate::common;

use facesynth::feature_points::FeaturePoint;
use facesynth::generic_face::GenericFace;
use facesynth::registration::{self, DistanceStats, RegistrationParams, ScanEvaluation, WarpSpace};
use facesynth::{Mesh, io};
use glam::DVec3;
use std::path::Path;

/// A stand-in generic face until `generic_face::build()` lands: a 2.5 mm quad grid over an
/// analytic face-like height field (nose tip at the origin, looking towards +z), cut to a face
/// oval, with the 13 feature points at the generic branch's Table-2 placements.
fn standin_generic() -> GenericFace {
    let h = 2.5;
    let height = |x: f64, y: f64| -> f64 {
        let base = -25.0 - x * x / (2.0 * 75.0) - y * y / (2.0 * 220.0);
        let ridge = if y < 0.0 {
            (-(y * y) / (2.0 * 6.0 * 6.0)).exp()
        } else {
            (1.0 - y / 45.0).max(0.0).powi(2)
        };
        let nose = 25.0 * (-(x * x) / (2.0 * 7.0 * 7.0)).exp() * ridge;
        let chin =
            6.0 * (-(x * x) / (2.0 * 15.0 * 15.0) - (y + 70.0).powi(2) / (2.0 * 12.0 * 12.0)).exp();
        base + nose + chin
    };
    let (nx, ny) = (57usize, 73usize); // x in [-70, 70], y in [-95, 85]
    // A face outline: an oval above the mouth, a jaw line tapering to the chin below it.
    let inside = |x: f64, y: f64| {
        if y >= -30.0 {
            (x / 70.0).powi(2) + ((y + 30.0) / 112.0).powi(2) <= 1.0
        } else {
            y >= -88.0 && x.abs() <= 70.0 - (-30.0 - y) * (50.0 / 58.0)
        }
    };
    let mut positions = Vec::new();
    let mut id = vec![u32::MAX; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (-70.0 + h * i as f64, -95.0 + h * j as f64);
            if inside(x, y) {
                id[j * nx + i] = positions.len() as u32;
                positions.push(DVec3::new(x, y, height(x, y)));
            }
        }
    }
    let mut faces = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let q = [
                id[j * nx + i],
                id[j * nx + i + 1],
                id[(j + 1) * nx + i + 1],
                id[(j + 1) * nx + i],
            ];
            if q.iter().all(|&v| v != u32::MAX) {
                faces.push(q);
            }
        }
    }
    let mut mesh = Mesh::from_faces(positions, faces);
    mesh.remove_unreferenced_vertices();
    let targets = [
        (0.0, 0.0),
        (17.5, 32.2),
        (-17.5, 32.2),
        (48.1, 32.2),
        (-48.1, 32.2),
        (12.0, -6.0),
        (-12.0, -6.0),
        (25.0, -34.4),
        (-25.0, -34.4),
        (60.0, 0.0),
        (-60.0, 0.0),
        (0.0, 72.0),
        (0.0, -70.6),
    ];
    let feature_vertices = targets.map(|(x, y)| {
        (0..mesh.vertex_count())
            .min_by(|&a, &b| {
                let d = |v: usize| {
                    let p = mesh.positions_mm[v];
                    (p.x - x).powi(2) + (p.y - y).powi(2)
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap() as u32
    });
    GenericFace {
        mesh,
        feature_vertices,
    }
}

/// The generic face the evaluation uses: the real one once it exists, else the stand-in.
fn generic() -> GenericFace {
    std::panic::catch_unwind(facesynth::generic_face::build).unwrap_or_else(|_| standin_generic())
}

struct Case {
    name: String,
    all13: ScanEvaluation,
    gt9: ScanEvaluation,
}

fn evaluate_dir(
    noisy_dir: &Path,
    clean_dir: &Path,
    names: &[String],
    params: &RegistrationParams,
    use_noisy: bool,
) -> Vec<Case> {
    let generic = generic();
    let mut out = Vec::new();
    for name in names {
        let clean = io::read_mesh(&clean_dir.join(format!("{name}.wrl"))).unwrap();
        let scan = if use_noisy {
            io::read_mesh(&noisy_dir.join(format!("{name}.wrl"))).unwrap()
        } else {
            clean.clone()
        };
        let truth =
            registration::truth_points(&clean_dir.join(format!("{name}.json")), &clean).unwrap();
        let all: Vec<(FeaturePoint, DVec3)> = truth.landmarks.iter().collect();
        let gt9: Vec<(FeaturePoint, DVec3)> = truth
            .landmarks
            .iter()
            .filter(|(p, _)| !truth.derived[p.index()])
            .collect();
        let e13 = registration::evaluate(&generic, &scan, &clean, &all, &truth.landmarks, params)
            .unwrap();
        let e9 = registration::evaluate(&generic, &scan, &clean, &gt9, &truth.landmarks, params)
            .unwrap();
        out.push(Case {
            name: name.clone(),
            all13: e13,
            gt9: e9,
        });
    }
    out
}

fn summary(label: &str, evals: &[&ScanEvaluation]) -> String {
    let n = evals.len() as f64;
    let mean = |f: &dyn Fn(&ScanEvaluation) -> f64| evals.iter().map(|e| f(e)).sum::<f64>() / n;
    let worst = |f: &dyn Fn(&ScanEvaluation) -> f64| evals.iter().map(|e| f(e)).fold(0.0, f64::max);
    format!(
        "| {label} | {} | {:.3} | {:.3} / {:.3} | {:.3} / {:.3} | {:.2} / {:.2} | {:.3} | {:.1} | {:.1} | {:.2} |",
        evals.len(),
        mean(&|e| e.rigid_rms_mm),
        mean(&|e| e.surface_distance_mm.mean),
        worst(&|e| e.surface_distance_mm.mean),
        mean(&|e| e.surface_distance_mm.p95),
        worst(&|e| e.surface_distance_mm.p95),
        mean(&|e| e.surface_distance_mm.max),
        worst(&|e| e.surface_distance_mm.max),
        mean(&|e| e.landmark_residual_mean_mm),
        mean(&|e| e.unmatched_vertices as f64),
        mean(&|e| e.folded_warp_triangles as f64),
        mean(&|e| e.millis),
    )
}

const HEADER: &str = "| set | scans | rigid RMS | dist mean (avg / worst) | p95 (avg / worst) | max (avg / worst) | landmark resid | unmatched | folds | ms |\n|---|---|---|---|---|---|---|---|---|---|";

fn names(subjects: usize, scans: &[&str]) -> Vec<String> {
    (0..subjects)
        .flat_map(|s| scans.iter().map(move |k| format!("subj{s:03}_{k}")))
        .collect()
}

fn generic_vertex_count() -> usize {
    generic().mesh.vertex_count()
}

fn check(cases: &[Case], mean_max: f64, p95_max: f64) {
    for c in cases {
        for (label, e) in [("13", &c.all13), ("9", &c.gt9)] {
            // Projected vertices lie on the clean surface; filled ones (outside the scan's
            // coverage at the face border, holes) are bounded loosely (regression bound).
            let m: DistanceStats = e.matched_distance_mm;
            assert!(
                m.mean <= mean_max && m.p95 <= p95_max,
                "{} ({label} points): {m:?}",
                c.name
            );
            // All vertices, filled ones included: the goal on every scan of this set
            // (measured: worst scan mean 0.28 mm, p95 0.73 mm).
            let s = e.surface_distance_mm;
            assert!(
                s.mean <= 0.5 && s.p95 <= 1.5,
                "{} ({label} points): {s:?}",
                c.name
            );
            // At least 90 % of the generic vertices are projected, not filled.
            assert!(
                e.unmatched_vertices * 10 <= generic_vertex_count(),
                "{} ({label} points): {} unmatched",
                c.name,
                e.unmatched_vertices
            );
        }
        // With 13 points the feature vertices land on the ground truth.
        assert!(
            c.all13.landmark_residual_max_mm < 3.0,
            "{}: {:?}",
            c.name,
            c.all13
        );
    }
}

#[test]
fn cli_register_writes_mesh_and_report() {
    let clean = common::synth_dataset(5, 1, true);
    let scan_path = clean.join("subj002_frontal1.wrl");
    let scan = io::read_mesh(&scan_path).unwrap();
    let truth = registration::truth_points(&clean.join("subj002_frontal1.json"), &scan).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let lm = dir.path().join("lm.json");
    std::fs::write(&lm, serde_json::to_string(&truth.landmarks).unwrap()).unwrap();
    let out = dir.path().join("reg.obj");
    let report = dir.path().join("report.json");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args([
            "register",
            scan_path.to_str().unwrap(),
            "--landmarks",
            lm.to_str().unwrap(),
        ])
        .args([
            "--out",
            out.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    for key in [
        "rigid_rms_mm",
        "landmark_residual_mm",
        "surface_distance_mm",
        "unmatched_vertices",
        "millis",
    ] {
        assert!(!v[key].is_null(), "{key} missing: {v}");
    }
    assert_eq!(v["landmark_residual_mm"].as_object().unwrap().len(), 13);
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(written["unmatched_vertices"], v["unmatched_vertices"]);
    let mesh = io::read_mesh(&out).unwrap();
    assert_eq!(
        mesh.vertex_count(),
        facesynth::generic_face::build().mesh.vertex_count()
    );
    assert_eq!(v["landmarks_detected"], false);
    // Without --landmarks the points are detected (paper 2.1.2) and the report says so.
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args(["register", scan_path.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(v["landmarks_detected"], true);
    // Detected cheek and forehead borders do not drive the registration (pipeline docs).
    assert_eq!(
        v["landmark_residual_mm"].as_object().unwrap().len(),
        13 - facesynth::FeaturePoint::BORDER.len()
    );
}

#[test]
fn synthetic_regression_clean_and_noisy() {
    let noisy = common::synth_dataset(5, 1, false);
    let clean = common::synth_dataset(5, 1, true);
    let set = names(3, &["frontal1", "sonrisa"]);
    let params = RegistrationParams::default();
    let c = evaluate_dir(&noisy, &clean, &set, &params, false);
    let n = evaluate_dir(&noisy, &clean, &set, &params, true);
    for (kind, cases) in [("clean", &c), ("noisy", &n)] {
        println!("{HEADER}");
        let e13: Vec<_> = cases.iter().map(|c| &c.all13).collect();
        let e9: Vec<_> = cases.iter().map(|c| &c.gt9).collect();
        println!("{}", summary(&format!("{kind}, 13 pts"), &e13));
        println!("{}", summary(&format!("{kind}, 9 GT pts"), &e9));
    }
    check(&c, 0.5, 1.5);
    check(&n, 0.5, 1.5);
    // Averaged over the set, with all 13 points (measured 0.15 / 0.35 mm): the goal.
    for cases in [&c, &n] {
        let p95 = cases
            .iter()
            .map(|c| c.all13.surface_distance_mm.p95)
            .sum::<f64>()
            / 6.0;
        assert!(p95 <= 1.0, "mean p95 {p95}");
    }
}

#[test]
fn registration_with_a_subset_of_points_and_without_scale() {
    let clean = common::synth_dataset(5, 1, true);
    let scan = io::read_mesh(&clean.join("subj001_frontal2.wrl")).unwrap();
    let truth = registration::truth_points(&clean.join("subj001_frontal2.json"), &scan).unwrap();
    let generic = generic();
    use FeaturePoint::*;
    let four: Vec<_> = [NoseTip, InnerEyeLeft, InnerEyeRight, Chin]
        .into_iter()
        .map(|p| (p, truth.landmarks.get(p)))
        .collect();
    for with_scale in [true, false] {
        let params = RegistrationParams {
            with_scale,
            ..Default::default()
        };
        let r = registration::register_points(&generic, &scan, &four, &params).unwrap();
        assert_eq!(r.mesh.vertex_count(), generic.mesh.vertex_count());
        assert_eq!(r.mesh.faces, generic.mesh.faces);
        assert!(
            r.surface_distance_mm.mean < 4.0,
            "{:?}",
            r.surface_distance_mm
        );
        for (_, d) in &r.landmark_residual_mm {
            assert!(*d < 1.0, "{:?}", r.landmark_residual_mm);
        }
    }
    assert!(
        registration::register_points(&generic, &scan, &four[..3], &Default::default()).is_err()
    );
    let params = RegistrationParams {
        warp_space: WarpSpace::Xy,
        ..Default::default()
    };
    let r = registration::register(&generic, &scan, &truth.landmarks, &params).unwrap();
    assert!(r.surface_distance_mm.p95 < 25.0);
}

/// The full evaluation (≥ 20 subjects, all five scans, clean and noisy). Run with
/// `cargo test --release --no-default-features --test algorithms -- --ignored --nocapture`.
#[test]
#[ignore]
fn evaluation_table() {
    let subjects: usize = std::env::var("REG_SUBJECTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let seed: u64 = std::env::var("REG_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2024);
    let noisy = common::synth_dataset(subjects, seed, false);
    let clean = common::synth_dataset(subjects, seed, true);
    let mut params = RegistrationParams::default();
    if let Some(d) = std::env::var("REG_AXIS_DEPTH")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        params.axis_depth_mm = d;
    }
    if std::env::var("REG_NO_SCALE").is_ok() {
        params.with_scale = false;
    }
    if std::env::var("REG_XY").is_ok() {
        params.warp_space = WarpSpace::Xy;
    }
    println!("params: {params:?}");
    println!("{HEADER}");
    for (scans, label) in [
        (&["frontal1", "frontal2"][..], "neutral"),
        (&["sonrisa", "risa", "gesto"][..], "expressions"),
    ] {
        let set = names(subjects, scans);
        for (use_noisy, kind) in [(false, "clean"), (true, "noisy→clean")] {
            let cases = evaluate_dir(&noisy, &clean, &set, &params, use_noisy);
            let e13: Vec<_> = cases.iter().map(|c| &c.all13).collect();
            let e9: Vec<_> = cases.iter().map(|c| &c.gt9).collect();
            println!("{}", summary(&format!("{label}, {kind}, 13 pts"), &e13));
            println!("{}", summary(&format!("{label}, {kind}, 9 GT pts"), &e9));
            let mut worst: Vec<_> = cases
                .iter()
                .map(|c| {
                    (
                        c.all13.surface_distance_mm.p95,
                        &c.name,
                        c.all13.unmatched_vertices,
                    )
                })
                .collect();
            worst.sort_by(|a, b| b.0.total_cmp(&a.0));
            worst.truncate(3);
            println!("<!-- worst p95 (13 pts): {worst:?} -->");
        }
    }
}

#[test]
#[ignore]
fn debug_one() {
    let clean = common::synth_dataset(5, 1, true);
    let name = std::env::var("REG_CASE").unwrap_or("subj000_sonrisa".into());
    let scan = io::read_mesh(&clean.join(format!("{name}.wrl"))).unwrap();
    let truth = registration::truth_points(&clean.join(format!("{name}.json")), &scan).unwrap();
    let generic = generic();
    let r = registration::register(&generic, &scan, &truth.landmarks, &Default::default()).unwrap();
    println!("{}", r.report_json());
    let un: std::collections::HashSet<u32> = r.unmatched_vertices.iter().copied().collect();
    for (v, &d) in r.vertex_distance_mm.iter().enumerate() {
        if d > 2.0 {
            let g = generic.mesh.positions_mm[v];
            println!(
                "v{v} generic ({:.0},{:.0}) d={d:.2} unmatched={}",
                g.x,
                g.y,
                un.contains(&(v as u32))
            );
        }
    }
    for (p, x) in truth.landmarks.iter() {
        println!("{p} {x:.1}");
    }
}

/// The same table with the points the detector finds (the pipeline: denoise → detect →
/// register on the ten anatomical points), scored against the clean twins. On demand:
/// `cargo test --release --test algorithms -- --ignored --nocapture detected_landmarks`.
#[test]
#[ignore]
fn evaluation_table_with_detected_landmarks() {
    let subjects: usize = std::env::var("REG_SUBJECTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let noisy = common::synth_dataset(subjects, 2024, false);
    let clean = common::synth_dataset(subjects, 2024, true);
    let generic = generic();
    let params = RegistrationParams::default();
    println!("{HEADER}");
    for (scans, label) in [
        (&["frontal1", "frontal2"][..], "neutral"),
        (&["sonrisa", "risa", "gesto"][..], "expressions"),
    ] {
        let mut evals = Vec::new();
        let mut failed = 0;
        for name in names(subjects, scans) {
            let reference = io::read_mesh(&clean.join(format!("{name}.wrl"))).unwrap();
            let mut scan = io::read_mesh(&noisy.join(format!("{name}.wrl"))).unwrap();
            facesynth::denoise::denoise(&mut scan, &Default::default()).unwrap();
            let truth = registration::truth_points(&clean.join(format!("{name}.json")), &reference)
                .unwrap();
            let Ok(found) = facesynth::landmarks::detect(&scan, &Default::default()) else {
                failed += 1;
                continue;
            };
            let points: Vec<(FeaturePoint, DVec3)> = found
                .landmarks
                .iter()
                .filter(|(p, _)| !facesynth::FeaturePoint::BORDER.contains(p))
                .collect();
            match registration::evaluate(
                &generic,
                &scan,
                &reference,
                &points,
                &truth.landmarks,
                &params,
            ) {
                Ok(e) => evals.push(e),
                Err(_) => failed += 1,
            }
        }
        let refs: Vec<_> = evals.iter().collect();
        println!(
            "{}",
            summary(&format!("{label}, noisy→clean, detected (10 pts)"), &refs)
        );
        println!("<!-- {failed} scans without a registration -->");
    }
}

/// Regression (found by fuzzing the pipeline, `fuzz/` target `mesh_pipeline`): a scan with one
/// triangle far from the rest used to ask the closest-point grid for up to 1024³ cells, and a
/// query far off the scan widened its search over empty cells up to the limit. Both must
/// still give the right answers.
#[test]
fn closest_point_index_handles_a_far_away_triangle_and_far_queries() {
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    let n = 20u32;
    for j in 0..n {
        for i in 0..n {
            positions.push(DVec3::new(i as f64, j as f64, 0.0));
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i;
            faces.push(vec![v, v + 1, v + 1 + n]);
            faces.push(vec![v, v + 1 + n, v + n]);
        }
    }
    // One triangle 50 m away on every axis.
    let far = DVec3::splat(5.0e4);
    let k = positions.len() as u32;
    positions.extend([far, far + DVec3::X, far + DVec3::Y]);
    faces.push(vec![k, k + 1, k + 2]);
    let mesh = Mesh::from_faces(positions, faces);
    let index = facesynth::mesh::SurfaceIndex::new(&mesh, 4.0);
    // Above the grid patch: straight down onto it.
    let (d, q) = index.closest(DVec3::new(5.3, 7.6, 2.0), 10.0).unwrap();
    assert!((d - 2.0).abs() < 1e-9 && (q - DVec3::new(5.3, 7.6, 0.0)).length() < 1e-9);
    // Next to the far triangle: onto it.
    let (d, _) = index
        .closest(far + DVec3::new(0.2, 0.2, 3.0), 10.0)
        .unwrap();
    assert!((d - 3.0).abs() < 1e-9, "{d}");
    // Far from both, within and beyond the limit.
    let p = DVec3::new(-300.0, 0.0, 0.0);
    assert!(index.closest(p, 200.0).is_none());
    let (d, _) = index.closest(p, 400.0).unwrap();
    assert!((d - 300.0).abs() < 1e-9, "{d}");
}

/// Why vertices are unmatched: the generic face registered onto itself with a hole punched
/// around the left cheek point and the top cut off 10 mm below the forehead point. The hole's
/// vertices are `hole`, the ones above the cut `outside_scan`, and the rest are projected.
#[test]
fn unmatched_vertices_say_hole_or_outside_the_scan() {
    let generic = facesynth::generic_face::build();
    let lm = generic.landmarks();
    let cheek = lm.get(FeaturePoint::CheekLeft);
    let top = lm.get(FeaturePoint::Forehead).y - 10.0;
    let mut scan = generic.mesh.clone();
    let keep: Vec<bool> = scan
        .positions_mm
        .iter()
        .map(|p| p.distance(cheek) > 10.0 && p.y < top)
        .collect();
    scan.retain_vertices(&keep);
    let r = registration::register(&generic, &scan, &lm, &RegistrationParams::default()).unwrap();
    let reason_of = |v: usize| {
        r.unmatched_vertices
            .iter()
            .position(|&u| u as usize == v)
            .map(|k| r.unmatched_reasons[k])
    };
    let (mut in_hole, mut above) = (0, 0);
    for (v, p) in generic.mesh.positions_mm.iter().enumerate() {
        if p.distance(cheek) < 6.0 {
            assert_eq!(
                reason_of(v),
                Some(registration::Unmatched::Hole),
                "v{v} {p}"
            );
            in_hole += 1;
        } else if p.y > top + 3.0 {
            assert_eq!(
                reason_of(v),
                Some(registration::Unmatched::OutsideScan),
                "v{v} {p}"
            );
            above += 1;
        } else if p.distance(cheek) > 14.0 && p.y < top - 3.0 {
            assert_eq!(reason_of(v), None, "v{v} {p} unmatched inside the scan");
        }
    }
    assert!(in_hole > 3 && above > 20, "{in_hole} {above}");
    let counts = r.unmatched_by_reason(None);
    assert_eq!(counts.values().sum::<usize>(), r.unmatched_vertices.len());
}
