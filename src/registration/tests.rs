//! Tests of the registration steps: Horn's fit, the Delaunay warp, the cylindrical projection
//! and the closest-point index.

use super::delaunay::cross2;
use super::*;
use crate::mesh::closest_point_on_triangle;

/// Deterministic pseudo-random numbers in [-1, 1) (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    fn vec3(&mut self) -> DVec3 {
        DVec3::new(self.next(), self.next(), self.next())
    }
}

fn cloud(rng: &mut Rng, n: usize) -> Vec<DVec3> {
    (0..n).map(|_| rng.vec3() * 60.0).collect()
}

/// Umeyama / Kabsch by SVD: the least-squares similarity (or rigid) transform.
fn kabsch(from: &[DVec3], to: &[DVec3], with_scale: bool) -> (DMat3, f64, DVec3) {
    use nalgebra::{Matrix3, Vector3};
    let n = from.len() as f64;
    let ca = from.iter().copied().sum::<DVec3>() / n;
    let cb = to.iter().copied().sum::<DVec3>() / n;
    let v = |p: DVec3| Vector3::new(p.x, p.y, p.z);
    let mut cov = Matrix3::zeros();
    let mut aa = 0.0;
    for (a, b) in from.iter().zip(to) {
        cov += v(*b - cb) * v(*a - ca).transpose();
        aa += (*a - ca).length_squared();
    }
    let svd = cov.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let s = if with_scale {
        (svd.singular_values[0] + svd.singular_values[1] + d[(2, 2)] * svd.singular_values[2]) / aa
    } else {
        1.0
    };
    let rm = DMat3::from_cols_array(&[
        r[(0, 0)],
        r[(1, 0)],
        r[(2, 0)],
        r[(0, 1)],
        r[(1, 1)],
        r[(2, 1)],
        r[(0, 2)],
        r[(1, 2)],
        r[(2, 2)],
    ]);
    (rm, s, cb - s * (rm * ca))
}

#[test]
fn horn_recovers_a_known_similarity_exactly() {
    let mut rng = Rng(0x9e3779b97f4a7c15);
    for with_scale in [false, true] {
        for trial in 0..20 {
            let axis = rng.vec3().normalize();
            let truth = Similarity {
                rotation: DQuat::from_axis_angle(axis, 3.0 * rng.next()),
                scale: if with_scale {
                    1.0 + 0.3 * rng.next()
                } else {
                    1.0
                },
                translation_mm: rng.vec3() * 500.0,
            };
            let from = cloud(&mut rng, 4 + trial % 10);
            let to: Vec<DVec3> = from.iter().map(|p| truth.apply(*p)).collect();
            let t = horn_absolute_orientation(&from, &to, with_scale).unwrap();
            let dq = t.rotation.dot(truth.rotation).abs();
            assert!((1.0 - dq).abs() < 1e-12, "rotation off: {dq}");
            assert!((t.scale - truth.scale).abs() < 1e-12);
            assert!(t.translation_mm.distance(truth.translation_mm) < 1e-9);
            for (a, b) in from.iter().zip(&to) {
                assert!(t.apply(*a).distance(*b) < 1e-9);
            }
            let back = t.inverse();
            assert!(back.apply(to[0]).distance(from[0]) < 1e-9);
        }
    }
}

#[test]
fn horn_is_the_least_squares_optimum_under_noise() {
    let mut rng = Rng(12345);
    for with_scale in [false, true] {
        for _ in 0..20 {
            let truth = Similarity {
                rotation: DQuat::from_axis_angle(rng.vec3().normalize(), 2.0 * rng.next()),
                scale: if with_scale { 1.1 } else { 1.0 },
                translation_mm: rng.vec3() * 100.0,
            };
            let from = cloud(&mut rng, 13);
            let to: Vec<DVec3> = from
                .iter()
                .map(|p| truth.apply(*p) + rng.vec3() * 3.0)
                .collect();
            let h = horn_absolute_orientation(&from, &to, with_scale).unwrap();
            let (r, s, t) = kabsch(&from, &to, with_scale);
            let hr = h.rotation_matrix();
            assert!(
                (hr - r).abs_diff_eq(DMat3::ZERO, 1e-9)
                    || (hr - r).to_cols_array().iter().all(|x| x.abs() < 1e-9)
            );
            assert!((h.scale - s).abs() < 1e-9, "{} vs {s}", h.scale);
            assert!(h.translation_mm.distance(t) < 1e-9);
            // And no small perturbation does better.
            let cost = |x: &Similarity| -> f64 {
                from.iter()
                    .zip(&to)
                    .map(|(a, b)| x.apply(*a).distance_squared(*b))
                    .sum()
            };
            let c0 = cost(&h);
            for k in 0..3 {
                let mut axis = DVec3::ZERO;
                axis[k] = 1.0;
                for sign in [-1.0, 1.0] {
                    let mut p = h;
                    p.rotation = DQuat::from_axis_angle(axis, sign * 1e-4) * h.rotation;
                    // keep the centroid map optimal: recompute translation
                    let ca = from.iter().copied().sum::<DVec3>() / 13.0;
                    let cb = to.iter().copied().sum::<DVec3>() / 13.0;
                    p.translation_mm = cb - p.scale * (p.rotation * ca);
                    assert!(cost(&p) >= c0);
                }
            }
        }
    }
}

#[test]
fn horn_rejects_collinear_points() {
    let from = vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0];
    assert!(horn_absolute_orientation(&from, &from, true).is_err());
    assert!(horn_absolute_orientation(&from[..2], &from[..2], true).is_err());
}

/// A symmetric 13-point face layout (generic-face-like, mm).
fn face_layout() -> Vec<DVec2> {
    [
        (0.0, 0.0),
        (17.5, 32.2),
        (-17.5, 32.2),
        (48.1, 32.2),
        (-48.1, 32.2),
        (12.0, -6.0),
        (-12.0, -6.0),
        (25.0, -34.4),
        (-25.0, -34.4),
        (60.0, 0.0),
        (-60.0, 0.0),
        (0.0, 72.0),
        (0.0, -70.6),
    ]
    .map(|(x, y)| DVec2::new(x, y))
    .to_vec()
}

#[test]
fn delaunay_covers_the_hull_without_overlap_even_when_cocircular() {
    let mut rng = Rng(7);
    let mut src = face_layout();
    let n0 = src.len();
    let warp =
        PlanarWarp::with_anchor_ring(&src, &src, 1.6, 16).expect("warp over a symmetric layout");
    src = warp.sources().to_vec();
    let area: f64 = warp
        .triangles()
        .iter()
        .map(|t| cross2(src[t[1]] - src[t[0]], src[t[2]] - src[t[0]]) * 0.5)
        .sum();
    assert!(
        warp.triangles()
            .iter()
            .all(|t| cross2(src[t[1]] - src[t[0]], src[t[2]] - src[t[0]]) > 0.0)
    );
    // The hull is the anchor polygon (all features are inside it).
    let ring = &src[n0..];
    let hull: f64 = (0..ring.len())
        .map(|k| cross2(ring[k], ring[(k + 1) % ring.len()]) * 0.5)
        .sum();
    assert!(
        (area - hull).abs() < 1e-6 * hull,
        "area {area} vs hull {hull}"
    );
    // Random points: exactly one triangle contains each (interior points).
    for _ in 0..2000 {
        let p = DVec2::new(rng.next() * 80.0, rng.next() * 100.0);
        let inside = warp
            .triangles()
            .iter()
            .filter(|t| {
                barycentric2(p, src[t[0]], src[t[1]], src[t[2]])
                    .is_some_and(|b| b.iter().all(|&x| x > 1e-9))
            })
            .count();
        assert!(inside <= 1);
    }
    // A perfect grid (maximally cocircular) triangulates too.
    let grid: Vec<DVec2> = (0..25)
        .map(|k| DVec2::new((k % 5) as f64, (k / 5) as f64))
        .collect();
    let tris = delaunay(&grid);
    assert_eq!(tris.len(), 32);
    let a: f64 = tris
        .iter()
        .map(|t| cross2(grid[t[1]] - grid[t[0]], grid[t[2]] - grid[t[0]]) * 0.5)
        .sum();
    assert!((a - 16.0).abs() < 1e-9);
}

#[test]
fn warp_is_exact_at_features_identity_far_away_and_continuous() {
    let mut rng = Rng(99);
    let src = face_layout();
    let dst: Vec<DVec2> = src
        .iter()
        .map(|p| *p * 1.05 + DVec2::new(rng.next(), rng.next()) * 4.0)
        .collect();
    let warp = PlanarWarp::with_anchor_ring(&src, &dst, 1.6, 16).unwrap();
    assert_eq!(warp.folded_triangles(), 0);
    for (s, d) in src.iter().zip(&dst) {
        assert!(warp.apply(*s).distance(*d) < 1e-9);
    }
    // Far away: identity.
    for p in [DVec2::new(500.0, 0.0), DVec2::new(-200.0, 300.0)] {
        assert_eq!(warp.apply(p), p);
    }
    // Continuity: across every edge (and the outer ring), both sides agree at the edge.
    let s = warp.sources();
    for t in warp.triangles() {
        for k in 0..3 {
            let (a, b) = (s[t[k]], s[t[(k + 1) % 3]]);
            for i in 1..10 {
                let m = a.lerp(b, i as f64 / 10.0);
                let normal = (b - a).perp().normalize() * 1e-7;
                let l = warp.apply(m + normal);
                let r = warp.apply(m - normal);
                assert!(l.distance(r) < 1e-5, "jump {} at {m}", l.distance(r));
            }
        }
    }
    // Random segments: no jumps larger than the Lipschitz bound allows.
    for _ in 0..200 {
        let p = DVec2::new(rng.next() * 120.0, rng.next() * 150.0);
        let q = p + DVec2::new(rng.next(), rng.next()) * 1e-6;
        assert!(warp.apply(p).distance(warp.apply(q)) < 1e-4);
    }
}

/// A sphere cap (radius 100 mm, centre at the origin), facing +z, as a quad grid.
fn sphere_cap(n: usize, radius: f64) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let lon = -1.0 + 2.0 * i as f64 / n as f64;
            let lat = -0.9 + 1.8 * j as f64 / n as f64;
            positions.push(DVec3::new(
                radius * lat.cos() * lon.sin(),
                radius * lat.sin(),
                radius * lat.cos() * lon.cos(),
            ));
        }
    }
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let v = (j * (n + 1) + i) as u32;
            let w = v + (n + 1) as u32;
            faces.push([v, v + 1, w + 1, w]);
        }
    }
    Mesh::from_faces(positions, faces)
}

#[test]
fn cylindrical_projection_lands_on_a_sphere_and_a_cylinder() {
    let radius = 100.0;
    let sphere = sphere_cap(120, radius);
    let params = RegistrationParams::default();
    // Axis 30 mm behind the sphere centre (not through it): rays are not radial.
    let frame = CylinderFrame {
        origin_mm: DVec3::new(3.0, 0.0, -30.0),
        rotation: DQuat::IDENTITY,
    };
    let proj = CylinderProjector::new(&sphere, frame, 130.0, &params).unwrap();
    let mut rng = Rng(5);
    // Facet error of a 1.7° grid on a 100 mm sphere is < 100·(1 − cos(0.85°)) ≈ 0.02 mm
    // for the quads' diagonals; allow 0.05.
    for _ in 0..500 {
        let theta = rng.next() * 0.6;
        let h = rng.next() * 60.0;
        let hit = proj.cast(theta, h).expect("ray hits the cap");
        let world = frame.to_world(hit.local);
        assert!(
            (world.length() - radius).abs() < 0.05,
            "off the sphere: {}",
            world.length()
        );
        // On the ray: same height and direction.
        assert!((hit.local.y - h).abs() < 1e-9);
        assert!((hit.local.x.atan2(hit.local.z) - theta).abs() < 1e-9);
    }
    // Beyond the cap: no hit.
    assert!(proj.cast(0.0, 200.0).is_none());

    // A vertical cylinder of radius 80 around the axis: every hit has radius 80.
    let mut positions = Vec::new();
    let (nu, nv) = (90usize, 40usize);
    for j in 0..=nv {
        for i in 0..=nu {
            let a = -1.2 + 2.4 * i as f64 / nu as f64;
            positions.push(DVec3::new(
                80.0 * a.sin(),
                -50.0 + 100.0 * j as f64 / nv as f64,
                80.0 * a.cos(),
            ));
        }
    }
    let mut faces = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let v = (j * (nu + 1) + i) as u32;
            let w = v + (nu + 1) as u32;
            faces.push([v, v + 1, w + 1, w]);
        }
    }
    let cyl = Mesh::from_faces(positions, faces);
    let frame = CylinderFrame {
        origin_mm: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
    };
    let proj = CylinderProjector::new(&cyl, frame, 80.0, &params).unwrap();
    for _ in 0..300 {
        let theta = rng.next();
        let hit = proj.cast(theta, rng.next() * 45.0).unwrap();
        // chord sag of a 1.53° facet on r = 80 is ≤ 0.0072 mm
        assert!((hit.radius - 80.0).abs() < 0.008, "{}", hit.radius);
    }
}

#[test]
fn closest_point_queries_match_brute_force() {
    let sphere = sphere_cap(30, 50.0);
    let index = SurfaceIndex::new(&sphere, 4.0);
    let tris = sphere.triangles();
    let mut rng = Rng(77);
    for _ in 0..300 {
        let p = rng.vec3() * 80.0;
        let brute = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| sphere.positions_mm[v as usize]);
                closest_point_on_triangle(p, a, b, c).distance(p)
            })
            .fold(f64::INFINITY, f64::min);
        let d = index.distance(p, 1000.0);
        assert!((d - brute).abs() < 1e-9, "{d} vs {brute}");
    }
}

#[test]
fn distance_stats_are_mean_p95_max() {
    let v: Vec<f64> = (1..=100).map(f64::from).collect();
    let s = DistanceStats::of(&v);
    assert_eq!(s.mean, 50.5);
    assert_eq!(s.p95, 95.0);
    assert_eq!(s.max, 100.0);
}
