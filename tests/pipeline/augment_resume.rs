//! `facesynth augment` survives SIGKILL: the killed run's unfinished subject has no done
//! marker and is neither counted as finished nor read by `evaluate`; re-running resumes (the
//! finished subjects are skipped) and completes every subject, with no temporary file left or
//! taken for a mesh.

use crate::common;

use facesynth::augment::DONE_MARKER;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const SUBJECTS: usize = 5;
const EXPRESSIONS: &str = "happiness,sadness";

fn subject_dirs(out: &Path) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(out)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_dir())
                .collect()
        })
        .unwrap_or_default();
    dirs.sort();
    dirs
}

fn finished(out: &Path) -> usize {
    subject_dirs(out)
        .iter()
        .filter(|d| d.join(DONE_MARKER).is_file())
        .count()
}

/// Every file under `dir`, recursively.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out
}

fn augment_cmd(gallery: &Path, out: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_facesynth"));
    cmd.args(["augment", "--expressions", EXPRESSIONS, "--gallery"])
        .arg(gallery)
        .arg("--out")
        .arg(out)
        // One subject at a time, so the kill lands between finished and unfinished subjects.
        .env("RAYON_NUM_THREADS", "1");
    cmd
}

#[test]
fn augment_killed_mid_run_resumes_and_finishes_every_subject() {
    let data = common::synth_dataset(SUBJECTS, 1, false);
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("aug");

    // Run 1: SIGKILL as soon as the first subject is finished.
    let mut child = augment_cmd(&data, &out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while finished(&out) == 0 {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("augment exited ({status}) before finishing a subject");
        }
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no subject finished"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    let done_after_kill = finished(&out);
    assert!(
        (1..SUBJECTS).contains(&done_after_kill),
        "{done_after_kill} of {SUBJECTS} finished at the kill"
    );
    // No failure list: the killed process never got to write it.
    assert!(!out.join("failures.json").exists());
    // A subject with a done marker has all its meshes, and each one reads.
    for d in subject_dirs(&out) {
        if d.join(DONE_MARKER).is_file() {
            for name in EXPRESSIONS.split(',') {
                facesynth::io::read_mesh(&d.join(format!("{name}.ply"))).unwrap();
            }
        }
    }

    // The recognition protocol does not take the unfinished folder's meshes for gallery samples.
    let unfinished: Vec<PathBuf> = subject_dirs(&out)
        .into_iter()
        .filter(|d| !d.join(DONE_MARKER).is_file())
        .collect();
    if !unfinished.is_empty() {
        let eval = facesynth::recognition::evaluate(
            &data,
            Some(&out),
            &facesynth::recognition::ProtocolParams::default(),
        )
        .unwrap();
        let r = &eval.report;
        assert_eq!(
            r.synthetic_gallery_samples,
            done_after_kill * EXPRESSIONS.split(',').count(),
            "{:?}",
            r.failures
        );
        for d in &unfinished {
            assert!(
                r.failures
                    .iter()
                    .any(|f| f.file == *d && f.reason.contains("unfinished")),
                "{} not listed as unfinished: {:?}",
                d.display(),
                r.failures
            );
        }
    }

    // Run 2: resumes.
    let run = augment_cmd(&data, &out).output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["scans"], SUBJECTS);
    assert_eq!(report["resumed"], done_after_kill);
    assert_eq!(report["augmented"], SUBJECTS - done_after_kill);
    assert_eq!(report["failures"].as_array().map(Vec::len), Some(0));
    assert_eq!(finished(&out), SUBJECTS);
    for f in files_under(&out) {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            !name.contains(".tmp-"),
            "temporary file left: {}",
            f.display()
        );
    }
    for d in subject_dirs(&out) {
        for name in EXPRESSIONS.split(',') {
            let m = facesynth::io::read_mesh(&d.join(format!("{name}.ply"))).unwrap();
            assert!(m.vertex_count() > 1000);
        }
    }
}
