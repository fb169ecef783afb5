//! Parse-time measurements quoted in the module docs of `io::vrml` and `io::xyz`.
//! Run: `cargo test --release --no-default-features --test io_timing -- --ignored --nocapture`.

use facesynth::io::{ReadLimits, vrml, xyz};
use std::path::Path;
use std::time::Instant;

const GAVAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/gavabdb");

/// Best of `runs` wall-clock times, ms (the machine is shared; the minimum is the cost).
fn best_ms(runs: usize, mut f: impl FnMut()) -> f64 {
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
    println!("| file | bytes | vertices | faces | ms |");
    for path in files(Path::new(GAVAB), "wrl") {
        let bytes = std::fs::read(&path).unwrap();
        let m = vrml::parse(&bytes, &path, &limits).unwrap();
        let ms = best_ms(20, || {
            vrml::parse(&bytes, &path, &limits).unwrap();
        });
        println!(
            "| {} | {} | {} | {} | {ms:.2} |",
            path.file_name().unwrap().to_string_lossy(),
            bytes.len(),
            m.vertex_count(),
            m.face_count()
        );
    }
    println!("| file | points | rows | triangles | used | median spacing mm | ms |");
    for path in files(&Path::new(GAVAB).join("pointclouds"), "txt") {
        let bytes = std::fs::read(&path).unwrap();
        let pts = xyz::parse_points(&bytes, &path, &limits).unwrap();
        let (_, s) = xyz::triangulate(pts, &path).unwrap();
        let ms = best_ms(10, || {
            xyz::parse(&bytes, &path, &limits).unwrap();
        });
        println!(
            "| {} | {} | {} | {} | {:.1}% | {:.2} | {ms:.2} |",
            path.file_name().unwrap().to_string_lossy(),
            s.points,
            s.rows,
            s.triangles,
            100.0 * s.used_points as f64 / s.points as f64,
            s.median_spacing_mm
        );
    }
}
