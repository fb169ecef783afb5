//! Unit tests of the generic face's parts: the analytic surface, quad quality, boundary loops.

use super::shape::{Section, relief, surface};
use super::*;
use glam::DVec3;

#[test]
fn surface_is_mirror_symmetric_and_keeps_height() {
    for &t in &[-78.0, -34.4, -5.0, 0.0, 17.0, 32.2, 60.0, 84.0] {
        for &s in &[0.0, 3.0, 17.5, 40.0, 90.0] {
            let a = surface(s, t);
            let b = surface(-s, t);
            assert_eq!(a, DVec3::new(-b.x, b.y, b.z));
            assert_eq!(a.y, t);
        }
        assert_eq!(surface(0.0, t).x, 0.0);
    }
    assert_eq!(relief(12.0, 3.0), relief(-12.0, 3.0));
}

#[test]
fn arc_length_inverts() {
    let sec = Section::at(20.0);
    for &theta in &[0.0, 0.3, 1.0, 1.4] {
        let s = sec.arc(theta);
        assert!((sec.theta_at(s) - theta).abs() < 1e-9);
    }
    // A circle's quarter arc is πr/2.
    let circle = Section {
        a: 70.0,
        b: 70.0,
        front_z: 0.0,
    };
    let quarter = circle.arc(std::f64::consts::FRAC_PI_2);
    assert!((quarter - 35.0 * std::f64::consts::PI).abs() < 1e-9);
}

#[test]
fn quad_quality_of_square_and_rhombus() {
    let square = Mesh::from_faces(
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ],
        [[0u32, 1, 2, 3]],
    );
    let q = quad_quality(&square);
    assert!((q.min_scaled_jacobian - 1.0).abs() < 1e-12);
    assert!((q.max_edge_ratio - 1.0).abs() < 1e-12);
    assert!(q.max_warp_deg.abs() < 1e-6);
    let angle = 50f64.to_radians();
    let e = DVec3::new(angle.cos(), angle.sin(), 0.0);
    let rhombus = Mesh::from_faces(
        vec![DVec3::ZERO, DVec3::X, DVec3::X + e, e],
        [[0u32, 1, 2, 3]],
    );
    let q = quad_quality(&rhombus);
    assert!((q.min_scaled_jacobian - angle.sin()).abs() < 1e-12);
    // Clockwise (folded) quads score negative against their own normal only if reflex; a
    // non-convex "dart" has a negative corner.
    let dart = Mesh::from_faces(
        vec![
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.5, 0.5, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ],
        [[0u32, 1, 2, 3]],
    );
    assert!(quad_quality(&dart).min_scaled_jacobian < 0.0);
}

#[test]
fn boundary_loops_of_a_grid_with_a_hole() {
    // 4×4 vertices, 3×3 quads, the middle quad removed: outer loop of 12, hole loop of 4.
    let mut p = Vec::new();
    for j in 0..4 {
        for i in 0..4 {
            p.push(DVec3::new(i as f64, j as f64, 0.0));
        }
    }
    let mut faces = Vec::new();
    for j in 0..3u32 {
        for i in 0..3u32 {
            if (i, j) != (1, 1) {
                faces.push([
                    j * 4 + i,
                    j * 4 + i + 1,
                    (j + 1) * 4 + i + 1,
                    (j + 1) * 4 + i,
                ]);
            }
        }
    }
    let mesh = Mesh::from_faces(p, faces);
    let mut sizes: Vec<usize> = boundary_loops(&mesh).iter().map(Vec::len).collect();
    sizes.sort();
    assert_eq!(sizes, vec![4, 12]);
}

#[test]
fn sidecar_map_checks() {
    let mut map: BTreeMap<String, i64> = FeaturePoint::ALL
        .iter()
        .enumerate()
        .map(|(k, p)| (p.name().to_string(), k as i64))
        .collect();
    assert_eq!(feature_ids_from_map(&map, 13).unwrap()[12], 12);
    assert!(feature_ids_from_map(&map, 12).unwrap_err().contains("chin"));
    map.insert("chin".into(), 0);
    assert!(
        feature_ids_from_map(&map, 13)
            .unwrap_err()
            .contains("both use vertex 0")
    );
}
