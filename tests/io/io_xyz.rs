//! xyz point clouds: every GavabDB cloud triangulates along its scanner grid.

use facesynth::io::{ReadLimits, read_file, read_mesh, xyz};
use std::path::{Path, PathBuf};
use std::time::Instant;

const CLOUDS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/data/gavabdb/pointclouds"
);
const GAVAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/gavabdb");

fn clouds() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(CLOUDS)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    v.sort();
    v
}

/// Triangulates every cloud, checks coverage and orientation, and prints the table quoted in
/// the module doc of `io::xyz` (run with `--nocapture`, in release for the timings).
#[test]
fn measure_all_point_clouds() {
    let files = clouds();
    assert_eq!(files.len(), 20);
    println!("| file | points | rows | triangles | used | ms |");
    for path in files {
        let bytes = read_file(&path, &ReadLimits::default()).unwrap();
        let t0 = Instant::now();
        let pts = xyz::parse_points(&bytes, &path, &ReadLimits::default()).unwrap();
        let (mesh, s) = xyz::triangulate(pts, &path).unwrap_or_else(|e| panic!("{e}"));
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        mesh.validate().unwrap();
        let name = path.file_name().unwrap().to_string_lossy();
        let used = s.used_points as f64 / s.points as f64;
        println!(
            "| {name} | {} | {} | {} | {:.1}% | {ms:.1} |",
            s.points,
            s.rows,
            s.triangles,
            100.0 * used
        );
        assert!(
            used > 0.95,
            "{name}: only {:.1}% of points used",
            100.0 * used
        );
        assert!(
            s.triangles as f64 > 1.8 * s.points as f64,
            "{name}: {} triangles for {} points",
            s.triangles,
            s.points
        );
        // Counter-clockwise seen from the scanner: the area-weighted mean normal points to +z.
        let mean: glam::DVec3 = mesh.normals.iter().copied().sum();
        assert!(mean.z > 0.5 * mean.length(), "{name}: mean normal {mean:?}");
    }
}

/// cara1_frontal1.txt is the same capture as cara1_frontal1.wrl: same first point, a similar
/// extent and about as many triangles as the .wrl has after splitting its quads.
#[test]
fn cloud_matches_the_vrml_scan_of_the_same_capture() {
    let cloud = read_mesh(&Path::new(CLOUDS).join("cara1_frontal1.txt")).unwrap();
    let scan = read_mesh(&Path::new(GAVAB).join("cara1_frontal1.wrl")).unwrap();
    let wrl_triangles = scan.triangles().len() as f64;
    let xyz_triangles = cloud.face_count() as f64;
    assert!(
        (xyz_triangles / wrl_triangles - 1.0).abs() < 0.05,
        "{xyz_triangles} vs {wrl_triangles}"
    );
    let (lo_c, hi_c) = cloud.bbox_mm().unwrap();
    let (lo_s, hi_s) = scan.bbox_mm().unwrap();
    // Same top (y) and depth range within a few mm; the cloud is the scan minus a few
    // points at the left and right edges.
    assert!((hi_c.y - hi_s.y).abs() < 1.0, "{hi_c:?} vs {hi_s:?}");
    assert!((lo_c.y - lo_s.y).abs() < 5.0, "{lo_c:?} vs {lo_s:?}");
    assert!(lo_c.x >= lo_s.x - 1e-9 && hi_c.x <= hi_s.x + 1e-9);
    assert_eq!(cloud.positions_mm[0], scan.positions_mm[0]);
}

#[test]
fn shuffled_cloud_is_refused_not_mangled() {
    let path = Path::new(CLOUDS).join("cara8_abajo.txt");
    let bytes = std::fs::read(&path).unwrap();
    let mut lines: Vec<&[u8]> = bytes.split(|&c| c == b'\n').collect();
    // A fixed pseudo-random permutation (no rand dependency).
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in (1..lines.len()).rev() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lines.swap(i, (state % (i as u64 + 1)) as usize);
    }
    let shuffled = lines.join(&b'\n');
    let e = match xyz::parse(&shuffled, Path::new("shuffled.xyz"), &ReadLimits::default()) {
        Ok(m) => panic!("a shuffled cloud gave a mesh of {} faces", m.face_count()),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("shuffled.xyz") && e.contains("row order"), "{e}");
}
