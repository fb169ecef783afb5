//! Every input the fuzzers (`fuzz/`) found a crash, hang or runaway allocation with, minimised,
//! under `tests/fuzz_regressions/<target>/`: each is fed to the same entry point as its fuzz
//! target and must give Ok or a one-line error naming the file, never a panic.

use facesynth::io::{MeshFormat, ReadLimits, parse_mesh};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fuzz_regressions");

/// Runs one input through target `target`; returns the error message, if any.
fn run(target: &str, data: &[u8]) -> Option<String> {
    let text = || std::str::from_utf8(data).ok();
    let (name, result): (&str, facesynth::Result<()>) = match target {
        "vrml" | "obj" | "ply" | "xyz" => {
            let (format, name) = match target {
                "vrml" => (MeshFormat::Vrml, "scan.wrl"),
                "obj" => (MeshFormat::Obj, "scan.obj"),
                "ply" => (MeshFormat::Ply, "scan.ply"),
                _ => (MeshFormat::Xyz, "scan.xyz"),
            };
            let r = parse_mesh(data, format, Path::new(name), &ReadLimits::default());
            (name, r.map(|_| ()))
        }
        "presets_ron" => {
            let (&which, rest) = data.split_first()?;
            let text = std::str::from_utf8(rest).ok()?;
            let path = Path::new("user.ron");
            let r = if which & 1 == 0 {
                facesynth::fem::expressions::ExpressionSet::parse(text, path).map(|_| ())
            } else {
                facesynth::fem::muscles::MuscleSet::parse(text, path).map(|_| ())
            };
            ("user.ron", r)
        }
        "landmarks_json" => {
            let r = facesynth::pipeline::parse_landmarks(text()?, Path::new("points.json"));
            ("points.json", r.map(|_| ()))
        }
        "sidecar_json" => {
            let r = facesynth::ground_truth::ScanTruth::parse(text()?, Path::new("scan.json"));
            ("scan.json", r.map(|_| ()))
        }
        "mesh_pipeline" => {
            // The fuzz target's steps: whatever parses goes on through the pipeline.
            let limits = ReadLimits {
                max_vertices: 4000,
                ..ReadLimits::default()
            };
            let path = Path::new("scan.obj");
            let Ok(mut mesh) = parse_mesh(data, MeshFormat::Obj, path, &limits) else {
                return None;
            };
            let _ = facesynth::denoise::denoise(&mut mesh, &Default::default());
            let _ = facesynth::curvature::compute(&mesh, &Default::default());
            let r = facesynth::landmarks::detect(&mesh, &Default::default()).and_then(|report| {
                let generic = facesynth::generic_face::build();
                let points = facesynth::pipeline::registration_points(&report.landmarks, true);
                facesynth::registration::register_points(
                    &generic,
                    &mesh,
                    &points,
                    &Default::default(),
                )
                .map(|_| ())
            });
            ("scan.obj", r.map_err(|e| e.in_file(path)))
        }
        other => panic!("unknown fuzz target folder {other}"),
    };
    let msg = result.err()?.to_string();
    assert!(msg.contains(name) && !msg.contains('\n'), "{target}: {msg}");
    Some(msg)
}

fn inputs() -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    for target in std::fs::read_dir(DIR).unwrap().flatten() {
        if !target.path().is_dir() {
            continue;
        }
        let name = target.file_name().to_string_lossy().into_owned();
        for f in std::fs::read_dir(target.path()).unwrap().flatten() {
            out.push((name.clone(), f.path()));
        }
    }
    out.sort();
    out
}

#[test]
fn fuzz_regressions_neither_panic_nor_run_away() {
    for (target, path) in inputs() {
        let data = std::fs::read(&path).unwrap();
        let r = catch_unwind(AssertUnwindSafe(|| run(&target, &data)));
        assert!(r.is_ok(), "{} panics", path.display());
    }
}
