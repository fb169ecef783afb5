//! Valid elements always (issue 38, point 4): every FEM face built on a real gallery scan has
//! no hexahedron at or below the scaled-Jacobian floor, and the surface relaxation mends a
//! skewed vertex without leaving its plane.

use crate::common;

use facesynth::fem::layers::MIN_SCALED_JACOBIAN;
use facesynth::pipeline::{self, MIN_QUAD_SCALED_JACOBIAN, quad_corner_quality};

/// The gallery scans `augment` takes among the real GavabDB data (`*_frontal1*`).
fn real_gallery_scans() -> Vec<std::path::PathBuf> {
    let dir = common::shared_dir().join("data/gavabdb");
    let mut out = Vec::new();
    for d in [dir.clone(), dir.join("pointclouds")] {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if name.contains("_frontal1") && facesynth::io::MeshFormat::from_path(&p).is_ok() {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_real_gallery_scan_gets_elements_above_the_quality_floor() {
    let scans = real_gallery_scans();
    assert!(scans.len() >= 8, "{scans:?}");
    let generic = facesynth::generic_face::build();
    for scan in scans {
        let prepared = pipeline::prepare_scan(&scan, None, &generic).unwrap();
        let (model, repairs) = pipeline::repaired_fem_model(
            &prepared.registration.mesh,
            generic.feature_vertices,
            &Default::default(),
        )
        .unwrap();
        let q = model.quality;
        println!("{}: {q:?} {repairs:?}", scan.display());
        assert!(
            q.min_scaled_jacobian > MIN_SCALED_JACOBIAN,
            "{}: {q:?}",
            scan.display()
        );
        assert_eq!(q.inverted_elements, 0);
    }
}

#[test]
fn a_skewed_vertex_is_relaxed_within_its_plane() {
    // A 12 × 12 grid in z = 0 with one vertex pushed 0.8 mm towards a diagonal neighbour: the
    // quads around it get corners of about 10°.
    let mesh = common::grid(12, 12, |_, _| 0.0);
    let mut positions = mesh.positions_mm.clone();
    positions[5 * 12 + 5] += glam::DVec3::new(0.8, 0.8, 0.0);
    let mut skewed = facesynth::Mesh::new(positions, mesh.faces.clone());
    skewed.update_normals();
    let worst = |m: &facesynth::Mesh| {
        (0..m.faces.len())
            .map(|f| quad_corner_quality(m, f))
            .fold(f64::INFINITY, f64::min)
    };
    assert!(worst(&skewed) < 0.3, "{}", worst(&skewed));
    let (relaxed, moved) = pipeline::relax_skewed_quads(&skewed);
    assert!(moved > 0);
    assert!(
        worst(&relaxed) >= MIN_QUAD_SCALED_JACOBIAN,
        "{}",
        worst(&relaxed)
    );
    // Tangential moves only: the plane stays a plane.
    assert!(relaxed.positions_mm.iter().all(|p| p.z.abs() < 1e-9));
    // A grid without skew is left alone.
    assert_eq!(pipeline::relax_skewed_quads(&mesh).1, 0);
}
