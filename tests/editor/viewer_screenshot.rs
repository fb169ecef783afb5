#![cfg(feature = "gui")]
//! The editor in a real window: Xvfb + Mesa's software Vulkan (lavapipe), one frame rendered
//! after loading a real GavabDB scan, saved as PNG and checked for a drawn face.

use crate::common;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Xvfb(Child);

impl Drop for Xvfb {
    fn drop(&mut self) {
        // SIGTERM, so the server removes its lock and socket (a killed one leaves both behind,
        // and left-overs used to exhaust the display numbers across runs).
        let _ = Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(3) {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts Xvfb on a display number it picks itself (`-displayfd`: the server takes the first
/// free one, clearing stale locks, and prints it once it accepts connections).
fn start_xvfb() -> (Xvfb, String) {
    use std::io::BufRead;
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1280x800x24",
            "-nolisten",
            "tcp",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("Xvfb is needed for the window test: run scripts/setup.sh");
    let stdout = child.stdout.take().expect("piped stdout");
    let xvfb = Xvfb(child);
    let mut line = String::new();
    std::io::BufReader::new(stdout)
        .read_line(&mut line)
        .expect("read Xvfb's display number");
    let display = line.trim();
    assert!(
        !display.is_empty() && display.chars().all(|c| c.is_ascii_digit()),
        "Xvfb did not start (printed {line:?})"
    );
    (xvfb, format!(":{display}"))
}

/// One window at a time: the tests of this file share the display search.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs `facesynth ARGS…` in a window on a fresh Xvfb display; panics with its stderr if it fails.
fn run_in_window(args: &[&std::ffi::OsStr]) {
    let _guard = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let (_xvfb, display) = start_xvfb();
    let runtime = std::env::temp_dir().join("facesynth-xdg");
    std::fs::create_dir_all(&runtime).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args(args)
        .env("DISPLAY", &display)
        .env_remove("WAYLAND_DISPLAY")
        .env("XDG_RUNTIME_DIR", &runtime)
        .output()
        .expect("run facesynth");
    assert!(
        out.status.success(),
        "facesynth {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn screenshot(args: &[&str], png: &Path) {
    let mut all: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
    all.extend(["--screenshot".as_ref(), png.as_os_str()]);
    run_in_window(&all);
}

/// Fraction of viewport pixels that differ clearly from the background, and how many distinct
/// colours the viewport holds (shading gives hundreds; a blank or flat fill gives a few).
fn viewport_stats(png: &Path) -> (f64, usize) {
    let img = image::open(png).expect("a PNG").to_rgb8();
    let (w, h) = img.dimensions();
    assert!(w >= 640 && h >= 400, "screenshot is {w}×{h}");
    // The side panel is on the left; sample the right two thirds.
    let x0 = w / 3;
    let bg = *img.get_pixel(w - 3, 3);
    let mut differing = 0usize;
    let mut total = 0usize;
    let mut colours = std::collections::HashSet::new();
    for y in (0..h).step_by(2) {
        for x in (x0..w).step_by(2) {
            let p = img.get_pixel(x, y);
            total += 1;
            let d: i32 = (0..3).map(|c| (p[c] as i32 - bg[c] as i32).abs()).sum();
            if d > 40 {
                differing += 1;
            }
            colours.insert(p.0);
        }
    }
    (differing as f64 / total as f64, colours.len())
}

#[test]
fn viewer_renders_a_real_scan_under_xvfb() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("cara1.png");
    let scan = common::gavab("cara1_frontal1.wrl");
    screenshot(&["view", scan.to_str().unwrap()], &png);
    let (covered, colours) = viewport_stats(&png);
    assert!(
        covered > 0.10,
        "only {:.1}% of the viewport is drawn",
        covered * 100.0
    );
    assert!(
        colours > 100,
        "only {colours} colours: not a shaded surface"
    );
    // Keep a copy for people to look at (ignored by git).
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/screenshots");
    let _ = std::fs::create_dir_all(&keep);
    let _ = std::fs::copy(&png, keep.join("cara1_frontal1.png"));
}

#[test]
fn viewer_shows_the_generic_face_without_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("generic.png");
    screenshot(&[], &png);
    let (covered, colours) = viewport_stats(&png);
    assert!(
        covered > 0.10,
        "only {:.1}% of the viewport is drawn",
        covered * 100.0
    );
    assert!(colours > 100, "only {colours} colours");
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/screenshots");
    let _ = std::fs::create_dir_all(&keep);
    let _ = std::fs::copy(&png, keep.join("generic.png"));
}

#[test]
fn viewer_shows_the_denoise_heat_map_with_spike_markers() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("denoise.png");
    let scan = common::gavab("cara1_frontal1.wrl");
    screenshot(
        &[
            "view",
            scan.to_str().unwrap(),
            "--denoise",
            "--show",
            "denoise",
        ],
        &png,
    );
    let img = image::open(&png).unwrap().to_rgb8();
    // Spike markers are magenta (the real scan has long peaks at the eyebrows and ears).
    let magenta = img
        .pixels()
        .filter(|p| p[0] > 180 && p[1] < 110 && p[2] > 180)
        .count();
    assert!(magenta > 50, "{magenta} spike-marker pixels");
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/screenshots");
    let _ = std::fs::create_dir_all(&keep);
    let _ = std::fs::copy(&png, keep.join("cara1_denoise.png"));
}

/// `view --fit`: the smile learned from cara1_sonrisa, coloured by its distance to that scan.
/// Plain shading is grey and the markers are red, green and yellow; the residual ramp runs
/// from dark blue (0 mm) through green to yellow (5 mm), so the face shows saturated blue
/// where the fit lies on the scan.
#[test]
fn viewer_shows_the_fit_residual_of_a_real_smile() {
    let dir = tempfile::tempdir().unwrap();
    let scan = common::gavab("cara1_frontal1.wrl");
    let smile = common::gavab("cara1_sonrisa.wrl");
    let (scan, smile) = (scan.to_str().unwrap(), smile.to_str().unwrap());
    let blue = |png: &Path| {
        let img = image::open(png).unwrap().to_rgb8();
        let (w, h) = img.dimensions();
        let mut count = 0usize;
        // The viewport right of the side panel, left of the legend.
        for y in (0..h).step_by(2) {
            for x in (w / 2..w * 9 / 10).step_by(2) {
                let [r, _, b] = img.get_pixel(x, y).0.map(i32::from);
                count += usize::from(b > r + 30 && b > 80);
            }
        }
        count
    };
    let png = dir.path().join("fit.png");
    let base = ["view", scan, "--denoise", "--register", "--fit", smile];
    screenshot(&base, &png);
    let plain = dir.path().join("plain.png");
    screenshot(&[&base[..], &["--show", "plain"]].concat(), &plain);
    // Measured: 10,282 blue pixels with the residual, 525 in plain shading (the scan behind).
    let (fit, shaded) = (blue(&png), blue(&plain));
    assert!(
        fit > 2000 && fit > 10 * shaded,
        "{fit} vs {shaded} residual-blue pixels"
    );
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/screenshots");
    let _ = std::fs::create_dir_all(&keep);
    let _ = std::fs::copy(&png, keep.join("cara1_fit_sonrisa.png"));
}

/// Runs `facesynth view --session FILE` (the session's own screenshots, no `--screenshot`).
fn run_session(session: &Path) {
    run_in_window(&["view".as_ref(), "--session".as_ref(), session.as_os_str()]);
}

/// Share of viewport pixels (right two thirds, where the side panel is not) that differ
/// between two screenshots.
fn viewport_difference(a: &Path, b: &Path) -> f64 {
    let a = image::open(a).expect("a PNG").to_rgb8();
    let b = image::open(b).expect("a PNG").to_rgb8();
    assert_eq!(a.dimensions(), b.dimensions());
    let (w, h) = a.dimensions();
    let (mut differ, mut total) = (0usize, 0usize);
    for y in 0..h {
        for x in w / 3..w {
            let (p, q) = (a.get_pixel(x, y), b.get_pixel(x, y));
            let d: i32 = (0..3).map(|c| (p[c] as i32 - q[c] as i32).abs()).sum();
            differ += usize::from(d > 30);
            total += 1;
        }
    }
    differ as f64 / total as f64
}

#[test]
fn one_session_shapes_a_mirrored_smile_softens_the_skin_stores_a_preset_and_undoes_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display();
    let session = dir.path().join("session.ron");
    std::fs::write(
        &session,
        format!(
            r#"[
                BuildFem,
                Show(Displacement),
                Activation(muscle: "zygomatic_major_left", value: 1.5, mirror: true),
                Screenshot("{d}/a_smile.png"),
                SkinModulus(2800.0),
                Screenshot("{d}/b_soft.png"),
                StorePreset("session_smile"),
                SavePresets("{d}/presets.ron"),
                Undo,
                Undo,
                Screenshot("{d}/c_undo.png"),
                Redo,
                Redo,
                Screenshot("{d}/d_redo.png"),
            ]"#
        ),
    )
    .unwrap();
    run_session(&session);
    let shot = |n: &str| dir.path().join(n);
    let (covered, _) = viewport_stats(&shot("a_smile.png"));
    assert!(covered > 0.10, "the face is not drawn");
    // Softer skin, same forces: the face moves further (colours and legend change).
    let soft = viewport_difference(&shot("a_smile.png"), &shot("b_soft.png"));
    assert!(
        soft > 0.01,
        "softening the skin changed only {:.2}%",
        soft * 100.0
    );
    // Undo twice (the preset, then the modulus) gives back the first picture; redo the second.
    let undo = viewport_difference(&shot("a_smile.png"), &shot("c_undo.png"));
    assert!(
        undo < 0.002,
        "undo left {:.2}% of the viewport different",
        undo * 100.0
    );
    let redo = viewport_difference(&shot("b_soft.png"), &shot("d_redo.png"));
    assert!(
        redo < 0.002,
        "redo left {:.2}% of the viewport different",
        redo * 100.0
    );
    let presets = std::fs::read_to_string(shot("presets.ron")).unwrap();
    assert!(
        presets.contains("session_smile"),
        "the stored preset was saved"
    );
    let set: facesynth::fem::expressions::ExpressionSet = ron::from_str(&presets).unwrap();
    let smile = set
        .expressions
        .iter()
        .find(|e| e.name == "session_smile")
        .expect("preset in the file");
    assert_eq!(
        smile.activations.get("zygomatic_major_right"),
        Some(&1.5),
        "mirrored"
    );
}

/// `facesynth review DIR --session`: the queue opens in a window, three scans are reviewed,
/// one point is corrected; the correction is on disk, the cache counts the reviewed scans, and
/// `augment` then builds that subject from the corrected points.
#[test]
fn a_review_session_corrects_one_point_and_augment_uses_it() {
    let gallery = common::gallery_copy(3);
    let shots = tempfile::tempdir().unwrap();
    let d = shots.path().display();
    let session = shots.path().join("review.ron");
    std::fs::write(
        &session,
        format!(
            r#"[
                Screenshot("{d}/queue.png"),
                NudgeLandmark(point: "mouth_corner_left", offset_mm: (0.0, 4.0, 0.0)),
                ReviewNext,
                ReviewNext,
                ReviewNext,
            ]"#
        ),
    )
    .unwrap();
    run_in_window(&[
        "review".as_ref(),
        gallery.path().as_os_str(),
        "--session".as_ref(),
        session.as_os_str(),
    ]);
    let (covered, _) = viewport_stats(&shots.path().join("queue.png"));
    assert!(covered > 0.05, "the first scan of the queue is not drawn");
    let corrections: Vec<_> = std::fs::read_dir(gallery.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| facesynth::pipeline::is_correction_file(p))
        .collect();
    assert_eq!(corrections.len(), 1, "{corrections:?}");
    let file = facesynth::pipeline::LandmarkFile::read(&corrections[0]).unwrap();
    assert_eq!(file.corrected, [facesynth::FeaturePoint::MouthCornerLeft]);
    let listed = common::json_of(&common::facesynth(&[
        "review",
        gallery.path().to_str().unwrap(),
        "--list",
    ]));
    assert_eq!(listed["reviewed"], 3);
    assert_eq!(listed["cached"], 3);
    assert_eq!(listed["entries"][2]["state"], "corrected");

    let out = tempfile::tempdir().unwrap();
    let report = common::json_of(&common::facesynth(&[
        "augment",
        "--gallery",
        gallery.path().to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
        "--expressions",
        "happiness",
        "--no-face-meshes",
    ]));
    let corrected = report["corrected_landmarks"].as_array().unwrap();
    assert_eq!(corrected.len(), 1);
    assert_eq!(
        corrected[0]["corrected"],
        serde_json::json!(["mouth_corner_left"])
    );
    let stem = file.scan.as_deref().unwrap().trim_end_matches(".wrl");
    let done: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.path().join(stem).join("done.json")).unwrap(),
    )
    .unwrap();
    let used: facesynth::Landmarks = serde_json::from_value(done["landmarks"].clone()).unwrap();
    assert_eq!(used, file.landmarks);
}
