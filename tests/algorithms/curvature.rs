//! Surface descriptors on analytic height fields: the textbook shape index values of caps,
//! cups, cylinders, saddles and planes, curvature magnitudes, and the normal maps.

use facesynth::Mesh;
use facesynth::curvature::{self, CurvatureParams};
use glam::DVec3;

/// A quad grid over [-half, half]² with spacing `h` (mm), z = f(x, y), CCW seen from +z.
fn height_field(half: f64, h: f64, f: impl Fn(f64, f64) -> f64) -> Mesh {
    let n = (2.0 * half / h).round() as usize + 1;
    let mut p = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (-half + i as f64 * h, -half + j as f64 * h);
            p.push(DVec3::new(x, y, f(x, y)));
        }
    }
    let id = |i: usize, j: usize| (j * n + i) as u32;
    let mut faces = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh::from_faces(p, faces)
}

/// Descriptors at the vertices within `r` mm of the origin in xy.
fn central(
    mesh: &Mesh,
    r: f64,
    params: &CurvatureParams,
) -> (curvature::SurfaceDescriptors, Vec<usize>) {
    let d = curvature::compute(mesh, params).unwrap();
    let idx = (0..mesh.vertex_count())
        .filter(|&v| mesh.positions_mm[v].truncate().length() <= r)
        .collect::<Vec<_>>();
    assert!(idx.len() > 10);
    (d, idx)
}

fn assert_all(values: &[f64], idx: &[usize], want: f64, tol: f64, what: &str) {
    for &v in idx {
        assert!(
            (values[v] - want).abs() <= tol,
            "{what}: vertex {v} has {} (want {want} ± {tol})",
            values[v]
        );
    }
}

const R: f64 = 40.0;

#[test]
fn sphere_cap_has_shape_index_one_and_curvature_one_over_r() {
    let m = height_field(15.0, 1.5, |x, y| (R * R - x * x - y * y).sqrt());
    let (d, idx) = central(&m, 10.0, &CurvatureParams::default());
    assert_all(&d.shape_index, &idx, 1.0, 0.02, "cap S");
    assert_all(&d.k1_per_mm, &idx, 1.0 / R, 0.02 / R, "cap k1");
    assert_all(&d.k2_per_mm, &idx, 1.0 / R, 0.02 / R, "cap k2");
}

#[test]
fn sphere_cup_has_shape_index_zero() {
    let m = height_field(15.0, 1.5, |x, y| -(R * R - x * x - y * y).sqrt());
    let (d, idx) = central(&m, 10.0, &CurvatureParams::default());
    assert_all(&d.shape_index, &idx, 0.0, 0.02, "cup S");
    assert_all(&d.k2_per_mm, &idx, -1.0 / R, 0.02 / R, "cup k2");
}

#[test]
fn convex_and_concave_cylinders_are_ridge_and_rut() {
    let ridge = height_field(15.0, 1.5, |x, _| (R * R - x * x).sqrt());
    let (d, idx) = central(&ridge, 10.0, &CurvatureParams::default());
    assert_all(&d.shape_index, &idx, 0.75, 0.01, "ridge S");
    assert_all(&d.k1_per_mm, &idx, 1.0 / R, 0.02 / R, "ridge k1");
    assert_all(&d.k2_per_mm, &idx, 0.0, 0.02 / R, "ridge k2");
    let rut = height_field(15.0, 1.5, |_, y| -(R * R - y * y).sqrt());
    let (d, idx) = central(&rut, 10.0, &CurvatureParams::default());
    assert_all(&d.shape_index, &idx, 0.25, 0.01, "rut S");
}

#[test]
fn symmetric_saddle_has_shape_index_one_half() {
    let m = height_field(15.0, 1.5, |x, y| (x * x - y * y) / (2.0 * R));
    let (d, idx) = central(&m, 3.0, &CurvatureParams::default());
    assert_all(&d.shape_index, &idx, 0.5, 0.01, "saddle S");
    assert_all(&d.k1_per_mm, &idx, 1.0 / R, 0.05 / R, "saddle k1");
    assert_all(&d.k2_per_mm, &idx, -1.0 / R, 0.05 / R, "saddle k2");
}

#[test]
fn plane_is_flat_with_the_documented_shape_index_and_exact_normal_maps() {
    // Tilted plane z = 0.3 x + 0.1 y: normal ∝ (-0.3, -0.1, 1).
    let m = height_field(15.0, 1.5, |x, y| 0.3 * x + 0.1 * y);
    let (d, idx) = central(&m, 14.0, &CurvatureParams::default());
    let n = DVec3::new(-0.3, -0.1, 1.0).normalize();
    assert_all(&d.curvedness_per_mm, &idx, 0.0, 1e-9, "plane curvedness");
    assert_all(&d.shape_index, &idx, 0.5, 0.0, "plane S (documented: 0.5)");
    assert_all(&d.dx_map(), &idx, n.x.abs(), 1e-9, "|n_x|");
    assert_all(&d.dz_map(), &idx, n.z.abs(), 1e-9, "|n_z|");
    let gxy = (n.x * n.x + n.y * n.y).sqrt();
    assert_all(&d.grad_xy_map(), &idx, gxy, 1e-9, "∇xy");
}

#[test]
fn cap_is_one_on_every_vertex_including_the_rim_and_values_stay_in_range() {
    // Shape index is scale free: a small, tight cap and a large one agree; all values in [0,1].
    for (radius, rings) in [(10.0, 2), (100.0, 3)] {
        let m = height_field(6.0, 1.0, |x, y| (radius * radius - x * x - y * y).sqrt());
        let d = curvature::compute(
            &m,
            &CurvatureParams {
                rings,
                ..Default::default()
            },
        )
        .unwrap();
        for (v, s) in d.shape_index.iter().enumerate() {
            assert!((0.0..=1.0).contains(s));
            assert!((s - 1.0).abs() < 0.05, "r {radius} vertex {v}: S {s}");
            assert!((d.normal[v].length() - 1.0).abs() < 1e-9);
        }
    }
}

#[test]
fn zero_rings_is_an_error_not_a_panic() {
    let m = height_field(3.0, 1.0, |_, _| 0.0);
    let err = curvature::compute(
        &m,
        &CurvatureParams {
            rings: 0,
            ..Default::default()
        },
    );
    assert!(err.unwrap_err().to_string().contains("rings"));
}
