//! Shared test helpers: paths into ../shared and generated synthetic scans.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

/// `../shared` beside the crate root (the layout of every checkout and of CI).
pub fn shared_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")
}

/// A real GavabDB file, e.g. `gavab("cara1_frontal1.wrl")`.
pub fn gavab(name: &str) -> PathBuf {
    shared_dir().join("data/gavabdb").join(name)
}

static GENERATE: Mutex<()> = Mutex::new(());

/// A synthetic GavabDB-like dataset made by `../shared/bench/synth_gavab.py` (needs python3
/// with numpy), generated once into `target/synth/` and reused by later test runs.
/// Same seed → same subjects; `clean` gives the noise-free twin.
pub fn synth_dataset(subjects: usize, seed: u64, clean: bool) -> PathBuf {
    let _guard = GENERATE.lock().unwrap_or_else(|e| e.into_inner());
    let name = format!(
        "s{subjects}-seed{seed}{}",
        if clean { "-clean" } else { "" }
    );
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    let dir = target.join("synth").join(name);
    if dir.join("manifest.json").exists() {
        return dir;
    }
    let tmp = dir.with_extension(format!("tmp{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let mut cmd = Command::new("python3");
    cmd.arg(shared_dir().join("bench/synth_gavab.py"))
        .arg("--out")
        .arg(&tmp)
        .args([
            "--subjects",
            &subjects.to_string(),
            "--seed",
            &seed.to_string(),
        ]);
    if clean {
        cmd.arg("--clean");
    }
    let out = cmd
        .output()
        .expect("python3 must be installed to generate test data");
    assert!(
        out.status.success(),
        "synth_gavab.py failed (is numpy installed?): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::rename(&tmp, &dir).expect("move generated dataset into place");
    dir
}

/// A folder of its own holding copies of the first `n` gallery scans (`subjNNN_frontal1.wrl`)
/// of a generated dataset (3 subjects, seed 11): for tests that write beside the scans
/// (corrections, the review cache) or add files to a gallery.
pub fn gallery_copy(n: usize) -> tempfile::TempDir {
    let data = synth_dataset(3, 11, false);
    let dir = tempfile::tempdir().unwrap();
    for i in 0..n {
        let name = format!("subj{i:03}_frontal1.wrl");
        std::fs::copy(data.join(&name), dir.path().join(&name)).unwrap();
    }
    dir
}

/// Runs the `facesynth` binary with `args`.
pub fn facesynth(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args(args)
        .output()
        .expect("run facesynth")
}

/// The JSON object a successful run printed on stdout.
pub fn json_of(out: &std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "facesynth failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

/// Runs the `facesynth` binary with `args`, which must fail with one line on stderr; returns
/// that line.
pub fn cli_error(args: &[&std::ffi::OsStr]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "accepted: {args:?}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    err
}

/// `nx × ny` vertex grid of quads, spacing 1 mm, z = f(x, y).
pub fn grid(nx: u32, ny: u32, f: impl Fn(f64, f64) -> f64) -> facesynth::Mesh {
    let mut p = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (i as f64, j as f64);
            p.push(glam::DVec3::new(x, y, f(x, y)));
        }
    }
    let mut faces = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let v = j * nx + i;
            faces.push([v, v + 1, v + 1 + nx, v + nx]);
        }
    }
    facesynth::Mesh::from_faces(p, faces)
}
