//! Parse-time measurements quoted in the module docs of `io::vrml` and `io::xyz`.
//! Run: `cargo test --release --no-default-features --test io -- --ignored --nocapture`.

use facesynth::io::{ReadLimits, vrml, xyz};
use std::path::Path;
use std::time::Instant;

const GAVAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/gavabdb");

/// CPU time this thread has run, ns (Linux `/proc/thread-self/schedstat`); the machine is
/// shared by several builds, so wall-clock time says little.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Mean CPU time of `runs` calls, ms (best wall-clock time where schedstat is missing).
fn cpu_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    if let Some(t0) = thread_cpu_ns() {
        for _ in 0..runs {
            f();
        }
        let t1 = thread_cpu_ns().unwrap_or(t0);
        return (t1 - t0) as f64 / runs as f64 / 1e6;
    }
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn files(dir: &Path, ext: &str) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    v.sort();
    v
}

#[test]
#[ignore = "timing; run in release with --ignored --nocapture"]
fn parse_times() {
    let limits = ReadLimits::default();
    println!("| file | bytes | vertices | faces | CPU ms |");
    for path in files(Path::new(GAVAB), "wrl") {
        let bytes = std::fs::read(&path).unwrap();
        let m = vrml::parse(&bytes, &path, &limits).unwrap();
        let ms = cpu_ms(20, || {
            vrml::parse(&bytes, &path, &limits).unwrap();
        });
        println!(
            "| {} | {} | {} | {} | {ms:.1} |",
            path.file_name().unwrap().to_string_lossy(),
            bytes.len(),
            m.vertex_count(),
            m.face_count()
        );
    }
    // Baseline for this machine: splitting cara1_frontal1.wrl into words and parsing every
    // numeric one, the least any text reader must do.
    let bytes = std::fs::read(Path::new(GAVAB).join("cara1_frontal1.wrl")).unwrap();
    let mut sum = 0.0;
    let base = cpu_ms(20, || {
        for w in bytes.split(|c| matches!(c, b' ' | b'\t' | b'\r' | b'\n' | b',')) {
            if let Some(v) = std::str::from_utf8(w)
                .ok()
                .and_then(|t| t.parse::<f64>().ok())
            {
                sum += v;
            }
        }
    });
    println!("baseline (split + parse every number of cara1_frontal1.wrl): {base:.2} ms ({sum})");
    println!("| file | points | rows | triangles | used | median spacing mm | CPU ms |");
    for path in files(&Path::new(GAVAB).join("pointclouds"), "txt") {
        let bytes = std::fs::read(&path).unwrap();
        let pts = xyz::parse_points(&bytes, &path, &limits).unwrap();
        let (_, s) = xyz::triangulate(pts, &path).unwrap();
        let ms = cpu_ms(10, || {
            xyz::parse(&bytes, &path, &limits).unwrap();
        });
        println!(
            "| {} | {} | {} | {} | {} ({:.1}%) | {:.2} | {ms:.1} |",
            path.file_name().unwrap().to_string_lossy(),
            s.points,
            s.rows,
            s.triangles,
            s.used_points,
            100.0 * s.used_points as f64 / s.points as f64,
            s.median_spacing_mm
        );
    }
}
