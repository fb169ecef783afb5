//! PLY writer/reader round trips, and a real scan written and read back as PLY and OBJ.

use facesynth::Mesh;
use facesynth::io::{ReadLimits, ply, read_mesh, write_mesh};
use glam::DVec3;
use std::path::Path;

fn quad_and_triangle() -> Mesh {
    Mesh::from_faces(
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.5, 0.0, 0.0),
            DVec3::new(1.5, 2.0, 0.25),
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(3.0, 1.0, -1258.123456789),
        ],
        [vec![0u32, 1, 2, 3], vec![1, 4, 2]],
    )
}

#[test]
fn binary_round_trip_keeps_quads_positions_and_scalar() {
    let mesh = quad_and_triangle();
    let quality = [0.0f32, -1.0, 0.5, 1.0, 3.25];
    let mut bytes = Vec::new();
    ply::write_binary(&mut bytes, &mesh, Some(("quality", &quality))).unwrap();
    let header = String::from_utf8_lossy(&bytes[..200]);
    assert!(header.contains("property float quality\n"), "{header}");
    let (back, values) = ply::parse_with_scalar(
        &bytes,
        Path::new("rt.ply"),
        &ReadLimits::default(),
        Some("quality"),
    )
    .unwrap();
    assert_eq!(back.faces, mesh.faces);
    assert_eq!(back.positions_mm, mesh.positions_mm);
    assert_eq!(values.as_deref(), Some(&quality[..]));
    assert_eq!(back.face_counts().quads, 1);
}

#[test]
fn write_mesh_and_read_mesh_round_trip_a_real_scan() {
    let src = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/gavabdb/cara1_frontal1.wrl"
    );
    let mesh = read_mesh(Path::new(src)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cara1.ply");
    write_mesh(&out, &mesh).unwrap();
    let back = read_mesh(&out).unwrap();
    assert_eq!(back.positions_mm, mesh.positions_mm);
    assert_eq!(back.faces, mesh.faces);
    assert_eq!(back.face_counts().quads, 13_215);
    // OBJ keeps vertex ids too (6 decimals: positions within 1e-6 mm).
    let out = dir.path().join("cara1.obj");
    write_mesh(&out, &mesh).unwrap();
    let back = read_mesh(&out).unwrap();
    assert_eq!(back.faces, mesh.faces);
    for (a, b) in back.positions_mm.iter().zip(&mesh.positions_mm) {
        assert!((*a - *b).length() < 1e-5);
    }
}

#[test]
fn scalar_of_wrong_length_or_bad_name_is_refused() {
    let mesh = quad_and_triangle();
    let mut out = Vec::new();
    assert!(ply::write_binary(&mut out, &mesh, Some(("quality", &[1.0]))).is_err());
    let five = [0.0f32; 5];
    assert!(ply::write_binary(&mut out, &mesh, Some(("two words", &five))).is_err());
    assert!(ply::write_binary(&mut out, &mesh, Some(("", &five))).is_err());
}

#[test]
fn ascii_float_and_double_with_uint_indices() {
    let text = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n\
        property double z\nproperty float nx\nproperty float ny\nproperty float nz\n\
        element face 1\nproperty list int uint vertex_indices\nend_header\n\
        0 0 0 0 0 1\n1.0e1 0 0 0 0 1\n10 10 0 0 0 1\n0 10 0 0 0 1\n4 0 1 2 3\n";
    let m = ply::parse(text, Path::new("a.ply"), &ReadLimits::default()).unwrap();
    assert_eq!(m.positions_mm[1], DVec3::new(10.0, 0.0, 0.0));
    assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
    assert!((m.normals[0] - DVec3::Z).length() < 1e-12);
}
