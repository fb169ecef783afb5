//! Registration of the generic face to a scan (paper section 2.1.3, Figure 13).
//!
//! Three steps, as in the paper:
//!
//! 1. **Global alignment** — Horn's closed-form unit-quaternion absolute orientation on the
//!    corresponding feature points (generic ↔ scan), with an optional uniform scale
//!    ([`horn_absolute_orientation`]). The result is [`RegistrationResult::scan_from_generic`].
//!    Scale is **on** by default: the generic face has average proportions and a fixed size,
//!    while subjects differ by ±10 % in face size; with scale the rigid residual and the warp
//!    that must absorb it are smaller (see the crate's registration evaluation).
//! 2. **Planar deformation** — a piecewise-linear map ([`PlanarWarp`]) over a Delaunay
//!    triangulation of the feature points plus a ring of *anchors* placed around them (an
//!    ellipse 1.6× the feature points' extent). Inside a triangle a vertex keeps its
//!    barycentric coordinates. The anchors, and everything outside their ring, follow a blend
//!    of the identity and the feature points' least-squares affine map
//!    ([`RegistrationParams::affine_outside`]: fixed anchors when both cheek points are given,
//!    which bound the face laterally; the full affine map when they are not, so the face
//!    beyond the inner points is stretched like the face between them). The map is
//!    continuous and puts every feature point exactly on its scan counterpart. The plane is
//!    the unrolled projection cylinder (u = R₀·θ, v = height; [`WarpSpace::Cylindrical`], the
//!    default), which equals the paper's XY plane near the midline and makes the feature points
//!    land *exactly* on the scan landmarks after step 3; [`WarpSpace::Xy`] warps the plain
//!    frontal XY plane instead.
//! 3. **Z by cylindrical projection** — a vertical cylinder axis (the aligned generic's up
//!    direction) runs [`RegistrationParams::axis_depth_mm`] behind the nose tip, roughly
//!    through the head centre. Every generic vertex is moved along the ray from the axis
//!    through it, onto the outermost scan triangle the ray hits ([`CylinderProjector`], a
//!    uniform grid over the scan triangles in (u, v)); the position is the barycentric point
//!    of that triangle. A vertex is *unmatched* when its ray hits nothing, hits a triangle
//!    next to a spike, hits more than `max_offset_mm` from where it was, or moves far more
//!    than its neighbours (`outlier_mm`). Unmatched vertices get a harmonic (Laplacian) fill
//!    of the radial offset from the matched vertices around them on the generic mesh, so a
//!    hole takes the generic face's shape, lifted smoothly onto the surrounding scan.
//!
//! Quality figures come with every result: rigid RMS, per-landmark residuals, the distance of
//! each registered vertex to the scan surface ([`SurfaceIndex`]) and the fraction of vertices
//! that were projected rather than filled ([`RegistrationResult::matched_fraction`]). A
//! projected vertex lies on the scan by construction, so its distance to the scan it was
//! projected on is ~0; the evaluation ([`evaluate`]) therefore measures against the *clean
//! twin* of a noisy scan, over all vertices, filled ones included.
//!
//! # Measured (issue #4)
//!
//! 20 synthetic subjects (`synth_gavab.py --seed 2024`), 40 neutral and 60 expression scans,
//! ground-truth landmarks; distances to the clean twin, per-scan mean and p95 averaged over
//! the scans (worst scan in brackets); `cargo test --release --no-default-features --test
//! registration -- --ignored --nocapture evaluation_table`:
//!
//! | set | points | mean mm | p95 mm | unmatched (of 3,577) |
//! |---|---|---|---|---|
//! | neutral, clean | 13 | 0.050 (0.35) | 0.13 (2.30) | 76 |
//! | neutral, clean | 9 GT | 0.134 (0.46) | 0.35 (2.64) | 138 |
//! | neutral, noisy | 13 | 0.114 (0.41) | 0.31 (2.34) | 140 |
//! | neutral, noisy | 9 GT | 0.195 (0.52) | 0.56 (2.49) | 207 |
//! | expressions, clean | 13 | 0.039 (0.40) | 0.06 (2.94) | 59 |
//! | expressions, clean | 9 GT | 0.126 (0.52) | 0.47 (4.37) | 156 |
//! | expressions, noisy | 13 | 0.104 (0.45) | 0.26 (2.90) | 128 |
//! | expressions, noisy | 9 GT | 0.187 (0.57) | 0.66 (4.38) | 233 |
//!
//! "13" = the 9 generator landmarks plus cheeks and forehead derived from its iBUG-68 points
//! ([`truth_points`]). Before (generic face to the front of the ears, cheeks derived at the
//! jaw contour, fixed anchors): mean 1.59 / 0.76 mm, p95 11.5 / 5.8 mm (13 / 9 points, neutral
//! clean) with 758 / 486 of 3,760 vertices unmatched. The worst scans now (subject 16, p95
//! 2.3–4.4 mm) still lose the chin's lower rows and one side of the jaw off the scan.

use crate::feature_points::{FeaturePoint, Landmarks};
use crate::generic_face::GenericFace;
use crate::mesh::{Mesh, Topology};
use crate::{Error, Result};
use glam::{DMat3, DQuat, DVec2, DVec3};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

// ---------------------------------------------------------------------------------------------
// Parameters and results
// ---------------------------------------------------------------------------------------------

/// The plane in which the piecewise-linear feature-point warp is done.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum WarpSpace {
    /// The unrolled projection cylinder: u = R₀·θ (arc length at the nose tip's radius),
    /// v = height along the axis. Feature points then land exactly on the scan landmarks.
    Cylindrical,
    /// The frontal XY plane of the aligned generic face (the paper's wording).
    Xy,
}

/// Settings of [`register`]. `Default` gives the documented defaults.
#[derive(Debug, Clone, Serialize)]
pub struct RegistrationParams {
    /// Fit a uniform scale in the global alignment (default `true`).
    pub with_scale: bool,
    /// Distance of the cylinder axis behind the nose tip, mm (default 90: roughly the head
    /// centre; the synthetic heads' centre is ~130 mm behind the tip, but a shorter radius
    /// makes the rays meet the sides of the face less obliquely).
    pub axis_depth_mm: f64,
    /// Where the planar warp is done (default [`WarpSpace::Cylindrical`]).
    pub warp_space: WarpSpace,
    /// Size of the anchor ellipse relative to the feature points' extent about their centroid
    /// (default 1.6; must be > √2 so the ring encloses every feature point).
    pub anchor_scale: f64,
    /// Number of anchors on the ring (default 16).
    pub anchor_count: usize,
    /// How far the anchors follow the feature points' least-squares affine map, 0–1
    /// ([`PlanarWarp::with_affine_anchor_ring`]): 0 keeps them fixed (beyond the features the
    /// generic face is pulled back towards its unwarped self), 1 extrapolates the features'
    /// affine stretch. `None` (default): 0 when both cheek points are given (they bound the
    /// face laterally), else 1. Measured on 20 synthetic subjects (issue #4): with 13 points
    /// fixed anchors give the lower p95 (0.45 vs 1.32 mm), with the 9 inner points the affine
    /// extrapolation does (1.52 vs 1.88 mm).
    pub affine_outside: Option<f64>,
    /// A scan vertex whose radial distance from the axis differs from the median of its
    /// neighbours' by more than this is a spike; triangles touching it are ignored (default
    /// 3 mm; the scanner noise is ~0.15 mm).
    pub spike_threshold_mm: f64,
    /// A hit more than this far (radially) from the warped generic vertex is rejected, mm
    /// (default 40).
    pub max_offset_mm: f64,
    /// A matched vertex whose radial offset differs from the median offset of its matched
    /// neighbours by more than this is treated as unmatched, mm (default 4).
    pub outlier_mm: f64,
    /// Cell size of the (u, v) grid over the scan triangles, mm (default 2).
    pub grid_cell_mm: f64,
}

impl Default for RegistrationParams {
    fn default() -> Self {
        RegistrationParams {
            with_scale: true,
            axis_depth_mm: 90.0,
            warp_space: WarpSpace::Cylindrical,
            anchor_scale: 1.6,
            anchor_count: 16,
            affine_outside: None,
            spike_threshold_mm: 3.0,
            max_offset_mm: 40.0,
            outlier_mm: 4.0,
            grid_cell_mm: 2.0,
        }
    }
}

/// A similarity transform `p ↦ scale · rotation · p + translation`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Similarity {
    pub rotation: DQuat,
    pub scale: f64,
    pub translation_mm: DVec3,
}

impl Similarity {
    pub const IDENTITY: Similarity = Similarity {
        rotation: DQuat::IDENTITY,
        scale: 1.0,
        translation_mm: DVec3::ZERO,
    };

    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.scale * (self.rotation * p) + self.translation_mm
    }

    pub fn inverse(&self) -> Similarity {
        let rotation = self.rotation.inverse();
        let scale = 1.0 / self.scale;
        Similarity {
            rotation,
            scale,
            translation_mm: -(scale * (rotation * self.translation_mm)),
        }
    }

    /// The rotation as a matrix.
    pub fn rotation_matrix(&self) -> DMat3 {
        DMat3::from_quat(self.rotation)
    }
}

/// Mean, 95th percentile and maximum of a set of distances, mm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct DistanceStats {
    pub mean: f64,
    pub p95: f64,
    pub max: f64,
}

impl DistanceStats {
    pub fn of(values: &[f64]) -> DistanceStats {
        if values.is_empty() {
            return DistanceStats::default();
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let rank = ((0.95 * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
        DistanceStats {
            mean: v.iter().sum::<f64>() / v.len() as f64,
            p95: v[rank],
            max: v[v.len() - 1],
        }
    }
}

/// What [`register`] returns.
#[derive(Debug, Clone)]
pub struct RegistrationResult {
    /// The generic face's topology with the registered positions (scan frame, mm).
    pub mesh: Mesh,
    /// Global alignment, generic frame → scan frame.
    pub scan_from_generic: Similarity,
    /// RMS distance between the aligned generic feature points and the scan's, mm.
    pub rigid_rms_mm: f64,
    /// Distance from each registered feature vertex to the scan landmark it was given, mm.
    pub landmark_residual_mm: Vec<(FeaturePoint, f64)>,
    /// Generic vertices whose position is filled in, not projected (scan holes, spikes, …).
    pub unmatched_vertices: Vec<u32>,
    /// Triangles of the planar warp that the targets turned over (0 for sane landmarks).
    pub folded_warp_triangles: usize,
    /// Distance of each registered vertex to the scan surface.
    pub surface_distance_mm: DistanceStats,
    /// Wall time of the registration (surface-distance figures included), ms.
    pub millis: f64,
}

impl RegistrationResult {
    /// Fraction of the generic vertices that were projected onto the scan (the rest are
    /// filled in: scan holes, beyond the scan's border, spikes).
    pub fn matched_fraction(&self) -> f64 {
        let n = self.mesh.vertex_count();
        if n == 0 {
            return 0.0;
        }
        1.0 - self.unmatched_vertices.len() as f64 / n as f64
    }

    /// The JSON report of `facesynth register`.
    pub fn report_json(&self) -> serde_json::Value {
        let residuals: BTreeMap<&str, f64> = self
            .landmark_residual_mm
            .iter()
            .map(|(p, d)| (p.name(), round4(*d)))
            .collect();
        serde_json::json!({
            "rigid_rms_mm": round4(self.rigid_rms_mm),
            "landmark_residual_mm": residuals,
            "surface_distance_mm": {
                "mean": round4(self.surface_distance_mm.mean),
                "p95": round4(self.surface_distance_mm.p95),
                "max": round4(self.surface_distance_mm.max),
            },
            "unmatched_vertices": self.unmatched_vertices.len(),
            "vertices": self.mesh.vertex_count(),
            "matched_fraction": round4(self.matched_fraction()),
            "folded_warp_triangles": self.folded_warp_triangles,
            "scale": round4(self.scan_from_generic.scale),
            "millis": (self.millis * 100.0).round() / 100.0,
        })
    }
}

fn round4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

// ---------------------------------------------------------------------------------------------
// The pipeline
// ---------------------------------------------------------------------------------------------

/// Registers the generic face to a scan given all 13 scan landmarks.
pub fn register(
    generic: &GenericFace,
    scan: &Mesh,
    scan_landmarks: &Landmarks,
    params: &RegistrationParams,
) -> Result<RegistrationResult> {
    let pairs: Vec<(FeaturePoint, DVec3)> = scan_landmarks.iter().collect();
    register_points(generic, scan, &pairs, params)
}

/// Registers the generic face to a scan given any ≥ 4 of the feature points (the nose tip
/// must be one of them: it places the cylinder axis). Points not given simply move with the
/// warp.
pub fn register_points(
    generic: &GenericFace,
    scan: &Mesh,
    scan_points: &[(FeaturePoint, DVec3)],
    params: &RegistrationParams,
) -> Result<RegistrationResult> {
    let start = Instant::now();
    generic.mesh.validate().map_err(Error::InvalidMesh)?;
    scan.validate().map_err(Error::InvalidMesh)?;
    if scan_points.len() < 4 {
        return Err(Error::algorithm(
            "registration",
            format!("need at least 4 feature points, got {}", scan_points.len()),
        ));
    }
    if !scan_points.iter().all(|(_, p)| p.is_finite()) {
        return Err(Error::algorithm(
            "registration",
            "a feature point is not finite",
        ));
    }
    let nose = scan_points
        .iter()
        .find(|(p, _)| *p == FeaturePoint::NoseTip)
        .map(|(_, x)| *x)
        .ok_or_else(|| Error::algorithm("registration", "the nose tip is required"))?;
    for (i, (p, _)) in scan_points.iter().enumerate() {
        if scan_points[..i].iter().any(|(q, _)| q == p) {
            return Err(Error::algorithm(
                "registration",
                format!("feature point {p} given twice"),
            ));
        }
    }

    // 1. Global alignment.
    let generic_pts: Vec<DVec3> = scan_points
        .iter()
        .map(|(p, _)| generic.mesh.positions_mm[generic.feature_vertex(*p) as usize])
        .collect();
    let target_pts: Vec<DVec3> = scan_points.iter().map(|(_, x)| *x).collect();
    let scan_from_generic =
        horn_absolute_orientation(&generic_pts, &target_pts, params.with_scale)?;
    let rigid_rms_mm = (generic_pts
        .iter()
        .zip(&target_pts)
        .map(|(g, s)| scan_from_generic.apply(*g).distance_squared(*s))
        .sum::<f64>()
        / generic_pts.len() as f64)
        .sqrt();

    // The cylinder: vertical along the aligned generic's up, through a point behind the nose.
    let frame = CylinderFrame {
        origin_mm: nose - scan_from_generic.rotation * DVec3::Z * params.axis_depth_mm,
        rotation: scan_from_generic.rotation,
    };
    let r0 = params.axis_depth_mm;
    let aligned: Vec<DVec3> = generic
        .mesh
        .positions_mm
        .iter()
        .map(|p| frame.to_local(scan_from_generic.apply(*p)))
        .collect();

    // 2. Planar warp.
    let to_plane = |q: DVec3| -> DVec2 {
        match params.warp_space {
            WarpSpace::Cylindrical => DVec2::new(r0 * q.x.atan2(q.z), q.y),
            WarpSpace::Xy => DVec2::new(q.x, q.y),
        }
    };
    let src: Vec<DVec2> = scan_points
        .iter()
        .map(|(p, _)| to_plane(aligned[generic.feature_vertex(*p) as usize]))
        .collect();
    let dst: Vec<DVec2> = target_pts
        .iter()
        .map(|x| to_plane(frame.to_local(*x)))
        .collect();
    let has = |f: FeaturePoint| scan_points.iter().any(|(p, _)| *p == f);
    let follow = params.affine_outside.unwrap_or(
        if has(FeaturePoint::CheekLeft) && has(FeaturePoint::CheekRight) {
            0.0
        } else {
            1.0
        },
    );
    let warp = PlanarWarp::with_affine_anchor_ring(
        &src,
        &dst,
        params.anchor_scale,
        params.anchor_count,
        follow,
    )?;
    let warped: Vec<DVec3> = aligned
        .iter()
        .map(|&q| {
            let w = warp.apply(to_plane(q));
            match params.warp_space {
                WarpSpace::Cylindrical => {
                    let r = q.x.hypot(q.z);
                    let theta = w.x / r0;
                    DVec3::new(r * theta.sin(), w.y, r * theta.cos())
                }
                WarpSpace::Xy => DVec3::new(w.x, w.y, q.z),
            }
        })
        .collect();

    // 3. Cylindrical projection.
    let projector = CylinderProjector::new(scan, frame, r0, params)?;
    let topo = Topology::new(&generic.mesh);
    let n = warped.len();
    let mut offset = vec![0.0f64; n];
    let mut matched = vec![false; n];
    let mut hit_local = vec![DVec3::ZERO; n];
    for (v, q) in warped.iter().enumerate() {
        let theta = q.x.atan2(q.z);
        let r = q.x.hypot(q.z);
        if let Some(hit) = projector.cast(theta, q.y)
            && (hit.radius - r).abs() <= params.max_offset_mm
        {
            offset[v] = hit.radius - r;
            matched[v] = true;
            hit_local[v] = hit.local;
        }
    }
    // Offsets far from their neighbours' median are spikes, hair or wrong layers.
    let mut outliers = Vec::new();
    let mut scratch = Vec::new();
    for v in 0..n {
        if !matched[v] {
            continue;
        }
        scratch.clear();
        scratch.extend(
            topo.neighbours(v)
                .iter()
                .filter(|&&u| matched[u as usize])
                .map(|&u| offset[u as usize]),
        );
        if scratch.len() >= 2 && (offset[v] - median(&mut scratch)).abs() > params.outlier_mm {
            outliers.push(v);
        }
    }
    for &v in &outliers {
        matched[v] = false;
    }
    harmonic_fill(&topo, &matched, &mut offset);
    let mut positions = Vec::with_capacity(n);
    let mut unmatched_vertices = Vec::new();
    for v in 0..n {
        let local = if matched[v] {
            hit_local[v]
        } else {
            unmatched_vertices.push(v as u32);
            let q = warped[v];
            let r = q.x.hypot(q.z);
            let s = (r + offset[v]).max(0.0) / r.max(1e-12);
            DVec3::new(q.x * s, q.y, q.z * s)
        };
        positions.push(frame.to_world(local));
    }
    let mesh = Mesh::new(positions, generic.mesh.faces.clone());

    let landmark_residual_mm = scan_points
        .iter()
        .map(|(p, x)| {
            (
                *p,
                mesh.positions_mm[generic.feature_vertex(*p) as usize].distance(*x),
            )
        })
        .collect();
    let index = SurfaceIndex::new(scan, 4.0);
    let distances: Vec<f64> = mesh
        .positions_mm
        .iter()
        .map(|p| index.distance(*p, 200.0))
        .collect();
    Ok(RegistrationResult {
        mesh,
        scan_from_generic,
        rigid_rms_mm,
        landmark_residual_mm,
        unmatched_vertices,
        folded_warp_triangles: warp.folded_triangles(),
        surface_distance_mm: DistanceStats::of(&distances),
        millis: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// Harmonic fill: unknown values (`known[v] == false`) become the average of their neighbours
/// (Gauss–Seidel to convergence), known values stay. Unknown vertices with no known vertex in
/// their connected component get 0.
fn harmonic_fill(topo: &Topology, known: &[bool], values: &mut [f64]) {
    let n = values.len();
    let unknown: Vec<usize> = (0..n).filter(|&v| !known[v]).collect();
    if unknown.is_empty() {
        return;
    }
    // Initial guess by breadth-first layers from the known rim (also finds orphans).
    let mut set = known.to_vec();
    let mut frontier: Vec<usize> = unknown.clone();
    loop {
        let mut next = Vec::new();
        let mut newly = Vec::new();
        for &v in &frontier {
            let (mut sum, mut cnt) = (0.0, 0usize);
            for &u in topo.neighbours(v) {
                if set[u as usize] {
                    sum += values[u as usize];
                    cnt += 1;
                }
            }
            if cnt > 0 {
                newly.push((v, sum / cnt as f64));
            } else {
                next.push(v);
            }
        }
        if newly.is_empty() {
            for v in next {
                values[v] = 0.0;
            }
            break;
        }
        for (v, x) in newly {
            values[v] = x;
            set[v] = true;
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    for _ in 0..5000 {
        let mut change: f64 = 0.0;
        for &v in &unknown {
            let nb = topo.neighbours(v);
            if nb.is_empty() {
                continue;
            }
            let avg = nb.iter().map(|&u| values[u as usize]).sum::<f64>() / nb.len() as f64;
            change = change.max((avg - values[v]).abs());
            values[v] = avg;
        }
        if change < 1e-6 {
            break;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Step 1: Horn's absolute orientation
// ---------------------------------------------------------------------------------------------

/// Horn (1987) closed-form absolute orientation with unit quaternions: the similarity `T`
/// minimising Σ |to_i − T(from_i)|². The rotation is the eigenvector of the largest
/// eigenvalue of Horn's symmetric 4×4 matrix N. With `with_scale` the scale is the
/// least-squares one, s = Σ to'_i · R from'_i / Σ |from'_i|² (primes: centred), which makes
/// the result the same as Umeyama's SVD solution; without it s = 1 (rigid).
///
/// Needs ≥ 3 points that are not collinear.
pub fn horn_absolute_orientation(
    from: &[DVec3],
    to: &[DVec3],
    with_scale: bool,
) -> Result<Similarity> {
    if from.len() != to.len() || from.len() < 3 {
        return Err(Error::algorithm(
            "horn",
            format!("need ≥ 3 point pairs, got {} and {}", from.len(), to.len()),
        ));
    }
    let n = from.len() as f64;
    let ca = from.iter().copied().sum::<DVec3>() / n;
    let cb = to.iter().copied().sum::<DVec3>() / n;
    let mut s = [[0.0f64; 3]; 3]; // s[i][j] = Σ a'_i b'_j
    let mut aa = 0.0;
    for (a, b) in from.iter().zip(to) {
        let a = (*a - ca).to_array();
        let b = (*b - cb).to_array();
        for i in 0..3 {
            aa += a[i] * a[i];
            for j in 0..3 {
                s[i][j] += a[i] * b[j];
            }
        }
    }
    // Collinearity check: the spread of `from` must have rank ≥ 2.
    let cov = {
        let mut m = nalgebra::Matrix3::<f64>::zeros();
        for a in from {
            let d = *a - ca;
            let v = nalgebra::Vector3::new(d.x, d.y, d.z);
            m += v * v.transpose();
        }
        m
    };
    let ev = nalgebra::SymmetricEigen::new(cov).eigenvalues;
    let mut ev: Vec<f64> = ev.iter().copied().collect();
    ev.sort_by(f64::total_cmp);
    if !(ev[1] > 1e-12 * ev[2].max(1e-300)) || aa <= 0.0 {
        return Err(Error::algorithm(
            "horn",
            "the feature points are collinear or coincide",
        ));
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    #[rustfmt::skip]
    let nm = nalgebra::Matrix4::new(
        sxx + syy + szz, syz - szy,       szx - sxz,        sxy - syx,
        syz - szy,       sxx - syy - szz, sxy + syx,        szx + sxz,
        szx - sxz,       sxy + syx,       -sxx + syy - szz, syz + szy,
        sxy - syx,       szx + sxz,       syz + szy,        -sxx - syy + szz,
    );
    let eig = nalgebra::SymmetricEigen::new(nm);
    let k = eig.eigenvalues.imax();
    let q = eig.eigenvectors.column(k);
    let rotation = DQuat::from_xyzw(q[1], q[2], q[3], q[0]).normalize();
    let scale = if with_scale {
        let mut num = 0.0;
        for (a, b) in from.iter().zip(to) {
            num += (*b - cb).dot(rotation * (*a - ca));
        }
        num / aa
    } else {
        1.0
    };
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(Error::algorithm(
            "horn",
            format!("degenerate scale {scale}"),
        ));
    }
    Ok(Similarity {
        rotation,
        scale,
        translation_mm: cb - scale * (rotation * ca),
    })
}

// ---------------------------------------------------------------------------------------------
// Step 2: piecewise-linear planar warp
// ---------------------------------------------------------------------------------------------

/// A continuous piecewise-linear map of the plane: a triangulation of control points, each
/// with a source and a target position; a point inside a source triangle goes to the same
/// barycentric point of the target triangle, and a point outside the triangulation is not
/// moved (the outer control points are fixed anchors, so the map stays continuous there).
#[derive(Debug, Clone)]
pub struct PlanarWarp {
    src: Vec<DVec2>,
    dst: Vec<DVec2>,
    triangles: Vec<[usize; 3]>,
    /// The map outside the triangulation, `p ↦ m p + t` (identity unless anchors follow an
    /// affine map, see [`PlanarWarp::with_affine_anchor_ring`]).
    outside: (glam::DMat2, DVec2),
}

impl PlanarWarp {
    /// Feature points `src[i] → dst[i]` plus `anchor_count` fixed anchors on an ellipse with
    /// semi-axes `anchor_scale` × the features' largest offset from their centroid along each
    /// axis (`anchor_scale` > √2 puts every source feature inside the ring).
    pub fn with_anchor_ring(
        src: &[DVec2],
        dst: &[DVec2],
        anchor_scale: f64,
        anchor_count: usize,
    ) -> Result<Self> {
        if src.len() != dst.len() || src.len() < 3 {
            return Err(Error::algorithm("warp", "need ≥ 3 feature points"));
        }
        if anchor_scale <= std::f64::consts::SQRT_2 || anchor_count < 3 {
            return Err(Error::algorithm(
                "warp",
                "anchor_scale must exceed √2 and anchor_count ≥ 3",
            ));
        }
        let c = src.iter().copied().sum::<DVec2>() / src.len() as f64;
        let ext = src
            .iter()
            .fold(DVec2::ZERO, |m, p| m.max((*p - c).abs()))
            .max(DVec2::splat(1.0));
        let mut s = src.to_vec();
        let mut d = dst.to_vec();
        for k in 0..anchor_count {
            // The phase breaks the ring's mirror symmetry (no four cocircular anchors).
            let a = 0.1 + std::f64::consts::TAU * k as f64 / anchor_count as f64;
            let p = c + DVec2::new(a.cos(), a.sin()) * ext * anchor_scale;
            s.push(p);
            d.push(p);
        }
        Self::new(s, d)
    }

    /// As [`PlanarWarp::with_anchor_ring`], but the anchors (and everything outside the
    /// ring) follow the least-squares affine map of the feature points instead of staying
    /// put: beyond the feature points the generic face is stretched or narrowed like the
    /// face between them, instead of being pulled back towards its unwarped shape. Continuous
    /// (the piecewise-linear map equals the affine map along the ring's edges).
    /// `follow` ∈ [0, 1] blends the affine map with the identity (0: fixed anchors, the same
    /// map as [`PlanarWarp::with_anchor_ring`]).
    pub fn with_affine_anchor_ring(
        src: &[DVec2],
        dst: &[DVec2],
        anchor_scale: f64,
        anchor_count: usize,
        follow: f64,
    ) -> Result<Self> {
        if !(0.0..=1.0).contains(&follow) {
            return Err(Error::algorithm("warp", "affine follow must be in [0, 1]"));
        }
        let fixed = Self::with_anchor_ring(src, dst, anchor_scale, anchor_count)?;
        let (m, t) = affine_fit(src, dst)
            .ok_or_else(|| Error::algorithm("warp", "feature points are collinear"))?;
        let m = glam::DMat2::IDENTITY * (1.0 - follow) + m * follow;
        let t = t * follow;
        let mut d = fixed.dst;
        for (dp, sp) in d.iter_mut().zip(&fixed.src).skip(src.len()) {
            *dp = m * *sp + t;
        }
        Ok(PlanarWarp {
            src: fixed.src,
            dst: d,
            triangles: fixed.triangles,
            outside: (m, t),
        })
    }

    /// A warp over the Delaunay triangulation of `src` (control points `src[i] → dst[i]`).
    pub fn new(src: Vec<DVec2>, dst: Vec<DVec2>) -> Result<Self> {
        if src.len() != dst.len() {
            return Err(Error::algorithm("warp", "source and target counts differ"));
        }
        let triangles = delaunay(&src);
        if triangles.is_empty() {
            return Err(Error::algorithm("warp", "control points are collinear"));
        }
        Ok(PlanarWarp {
            src,
            dst,
            triangles,
            outside: (glam::DMat2::IDENTITY, DVec2::ZERO),
        })
    }

    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    pub fn sources(&self) -> &[DVec2] {
        &self.src
    }

    /// Number of triangles whose target orientation is opposite to (or degenerate compared
    /// with) their source orientation: the map folds over there.
    pub fn folded_triangles(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| {
                let a = cross2(
                    self.src[t[1]] - self.src[t[0]],
                    self.src[t[2]] - self.src[t[0]],
                );
                let b = cross2(
                    self.dst[t[1]] - self.dst[t[0]],
                    self.dst[t[2]] - self.dst[t[0]],
                );
                a * b <= 0.0
            })
            .count()
    }

    /// Maps a point.
    pub fn apply(&self, p: DVec2) -> DVec2 {
        let mut best: Option<(f64, usize, [f64; 3])> = None;
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(b) = barycentric2(p, self.src[t[0]], self.src[t[1]], self.src[t[2]]) {
                let m = b[0].min(b[1]).min(b[2]);
                if m >= -1e-9 {
                    if m >= 0.0 {
                        best = Some((m, i, b));
                        break;
                    }
                    if best.is_none_or(|(bm, _, _)| m > bm) {
                        best = Some((m, i, b));
                    }
                }
            }
        }
        match best {
            Some((_, i, b)) => {
                let t = self.triangles[i];
                self.dst[t[0]] * b[0] + self.dst[t[1]] * b[1] + self.dst[t[2]] * b[2]
            }
            None => self.outside.0 * p + self.outside.1,
        }
    }
}

/// Least-squares affine map `dst ≈ m src + t`; `None` if the sources are collinear.
fn affine_fit(src: &[DVec2], dst: &[DVec2]) -> Option<(glam::DMat2, DVec2)> {
    let n = src.len() as f64;
    let cs = src.iter().copied().sum::<DVec2>() / n;
    let cd = dst.iter().copied().sum::<DVec2>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    let (mut bx, mut by) = (DVec2::ZERO, DVec2::ZERO);
    for (s, d) in src.iter().zip(dst) {
        let (a, b) = (*s - cs, *d - cd);
        sxx += a.x * a.x;
        sxy += a.x * a.y;
        syy += a.y * a.y;
        bx += a.x * b;
        by += a.y * b;
    }
    let det = sxx * syy - sxy * sxy;
    if !(det.abs() > 1e-12 * (sxx * syy).max(1e-300)) {
        return None;
    }
    // Rows of m solve [sxx sxy; sxy syy] [m_r0 m_r1]ᵀ = [bx_r by_r]ᵀ.
    let col0 = (bx * syy - by * sxy) / det;
    let col1 = (by * sxx - bx * sxy) / det;
    let m = glam::DMat2::from_cols(col0, col1);
    Some((m, cd - m * cs))
}

fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

fn barycentric2(p: DVec2, a: DVec2, b: DVec2, c: DVec2) -> Option<[f64; 3]> {
    let d = cross2(b - a, c - a);
    if d.abs() < 1e-300 {
        return None;
    }
    let l1 = cross2(p - a, c - a) / d;
    let l2 = cross2(b - a, p - a) / d;
    Some([1.0 - l1 - l2, l1, l2])
}

/// Delaunay triangulation (Bowyer–Watson), counter-clockwise triangles over input indices.
/// Near-cocircular points are resolved consistently (a relative tolerance on the in-circle
/// test), so symmetric configurations triangulate without overlaps.
pub fn delaunay(points: &[DVec2]) -> Vec<[usize; 3]> {
    let n = points.len();
    if n < 3 {
        return Vec::new();
    }
    let (lo, hi) = points
        .iter()
        .fold((points[0], points[0]), |(l, h), p| (l.min(*p), h.max(*p)));
    let span = (hi - lo).max_element().max(1e-9);
    let mid = (lo + hi) * 0.5;
    let mut pts = points.to_vec();
    pts.push(mid + DVec2::new(-40.0 * span, -30.0 * span));
    pts.push(mid + DVec2::new(40.0 * span, -30.0 * span));
    pts.push(mid + DVec2::new(0.0, 50.0 * span));
    let mut tris: Vec<[usize; 3]> = vec![[n, n + 1, n + 2]];
    let scale2 = span * span;
    for i in 0..n {
        let p = pts[i];
        let mut bad = Vec::new();
        for (k, t) in tris.iter().enumerate() {
            if in_circumcircle(pts[t[0]], pts[t[1]], pts[t[2]], p, scale2) {
                bad.push(k);
            }
        }
        let mut edges: Vec<(usize, usize)> = Vec::new();
        for &k in &bad {
            let t = tris[k];
            for e in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                if let Some(j) = edges.iter().position(|&(a, b)| a == e.1 && b == e.0) {
                    edges.swap_remove(j);
                } else {
                    edges.push(e);
                }
            }
        }
        for &k in bad.iter().rev() {
            tris.swap_remove(k);
        }
        for (a, b) in edges {
            if cross2(pts[b] - pts[a], p - pts[a]) > 0.0 {
                tris.push([a, b, i]);
            }
        }
    }
    tris.retain(|t| t.iter().all(|&v| v < n));
    tris
}

fn in_circumcircle(a: DVec2, b: DVec2, c: DVec2, p: DVec2, scale2: f64) -> bool {
    let (ax, ay) = (a.x - p.x, a.y - p.y);
    let (bx, by) = (b.x - p.x, b.y - p.y);
    let (cx, cy) = (c.x - p.x, c.y - p.y);
    let det = (ax * ax + ay * ay) * (bx * cy - cx * by) - (bx * bx + by * by) * (ax * cy - cx * ay)
        + (cx * cx + cy * cy) * (ax * by - bx * ay);
    let orient = cross2(b - a, c - a);
    // Triangles are kept counter-clockwise, so det > 0 means inside; the tolerance is relative
    // to the size of the configuration (det scales with length⁴).
    det * orient.signum() > 1e-10 * scale2 * scale2
}

// ---------------------------------------------------------------------------------------------
// Step 3: cylindrical projection
// ---------------------------------------------------------------------------------------------

/// The projection cylinder's frame: `origin_mm` is on the axis, the axis is `rotation · Y`
/// and θ = 0 points along `rotation · Z` (towards the face). Local coordinates are mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CylinderFrame {
    pub origin_mm: DVec3,
    pub rotation: DQuat,
}

impl CylinderFrame {
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.rotation.inverse() * (p - self.origin_mm)
    }

    pub fn to_world(&self, q: DVec3) -> DVec3 {
        self.rotation * q + self.origin_mm
    }
}

/// A ray hit of [`CylinderProjector::cast`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CylinderHit {
    /// Hit point in the cylinder frame.
    pub local: DVec3,
    /// Its distance from the axis, mm.
    pub radius: f64,
    /// Index into `scan.triangles()`.
    pub triangle: usize,
    /// Barycentric coordinates in that triangle.
    pub barycentric: [f64; 3],
}

/// Casts horizontal rays from the cylinder axis onto a scan, through a uniform grid over the
/// scan triangles in the unrolled (u = r₀·θ, height) plane.
#[derive(Debug, Clone)]
pub struct CylinderProjector {
    frame: CylinderFrame,
    r0: f64,
    local: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    grid: Grid2,
}

impl CylinderProjector {
    /// `r0` scales θ into mm for the grid (use the nose tip's distance from the axis).
    pub fn new(
        scan: &Mesh,
        frame: CylinderFrame,
        r0: f64,
        params: &RegistrationParams,
    ) -> Result<Self> {
        let local: Vec<DVec3> = scan
            .positions_mm
            .iter()
            .map(|p| frame.to_local(*p))
            .collect();
        let radius: Vec<f64> = local.iter().map(|q| q.x.hypot(q.z)).collect();
        // Spikes: radial distance far from the median of the 1-ring.
        let mut spike = vec![false; local.len()];
        if params.spike_threshold_mm.is_finite() {
            let topo = Topology::new(scan);
            let mut nb = Vec::new();
            for (v, s) in spike.iter_mut().enumerate() {
                nb.clear();
                nb.extend(topo.neighbours(v).iter().map(|&u| radius[u as usize]));
                if nb.len() >= 2 {
                    *s = (radius[v] - median(&mut nb)).abs() > params.spike_threshold_mm;
                }
            }
        }
        let triangles: Vec<[u32; 3]> = scan
            .triangles()
            .into_iter()
            .filter(|t| t.iter().all(|&v| !spike[v as usize]))
            .collect();
        let uv = |q: DVec3| DVec2::new(r0 * q.x.atan2(q.z), q.y);
        let mut boxes = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let p = t.map(|v| local[v as usize]);
            let a = p.map(uv);
            // Skip triangles across θ = ±π (behind the head) or touching the axis.
            let wrap = (a[0].x - a[1].x).abs().max((a[1].x - a[2].x).abs()) > r0 * 1.5;
            let near_axis = t.iter().any(|&v| radius[v as usize] < 1e-6);
            if wrap || near_axis {
                boxes.push(None);
                continue;
            }
            let lo = a[0].min(a[1]).min(a[2]);
            let hi = a[0].max(a[1]).max(a[2]);
            // Edges bulge in (θ, h): pad by a small fraction of the extent.
            let pad = (hi - lo).max_element() * 0.05 + 1e-6;
            boxes.push(Some((lo - pad, hi + pad)));
        }
        let grid = Grid2::build(&boxes, params.grid_cell_mm.max(0.1));
        Ok(CylinderProjector {
            frame,
            r0,
            local,
            triangles,
            grid,
        })
    }

    pub fn frame(&self) -> CylinderFrame {
        self.frame
    }

    /// The outermost scan point on the horizontal ray from the axis at height `h` towards
    /// angle `theta` (radians, 0 = towards the face, positive towards local +x).
    pub fn cast(&self, theta: f64, h: f64) -> Option<CylinderHit> {
        let dir = DVec3::new(theta.sin(), 0.0, theta.cos());
        let origin = DVec3::new(0.0, h, 0.0);
        let mut best: Option<CylinderHit> = None;
        for &ti in self.grid.query(DVec2::new(self.r0 * theta, h)) {
            let t = self.triangles[ti as usize];
            let [a, b, c] = t.map(|v| self.local[v as usize]);
            if let Some((dist, bary)) = ray_triangle(origin, dir, a, b, c)
                && dist > 0.0
                && best.is_none_or(|h| dist > h.radius)
            {
                best = Some(CylinderHit {
                    local: a * bary[0] + b * bary[1] + c * bary[2],
                    radius: dist,
                    triangle: ti as usize,
                    barycentric: bary,
                });
            }
        }
        best
    }
}

/// Möller–Trumbore, both sides: (distance along `dir`, barycentric) or `None`.
fn ray_triangle(o: DVec3, dir: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<(f64, [f64; 3])> {
    let e1 = b - a;
    let e2 = c - a;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 * e1.length_squared().max(e2.length_squared()) {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    const EPS: f64 = 1e-9;
    if !(-EPS..=1.0 + EPS).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < -EPS || u + v > 1.0 + EPS {
        return None;
    }
    let t = e2.dot(q) * inv;
    let (u, v) = (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0));
    let w = (1.0 - u - v).max(0.0);
    let sum = u + v + w;
    Some((t, [w / sum, u / sum, v / sum]))
}

/// A uniform 2D grid of item ids by bounding box (CSR storage).
#[derive(Debug, Clone)]
struct Grid2 {
    min: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl Grid2 {
    fn build(boxes: &[Option<(DVec2, DVec2)>], cell: f64) -> Self {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for (l, h) in boxes.iter().flatten() {
            lo = lo.min(*l);
            hi = hi.max(*h);
        }
        if !lo.is_finite() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        let nx = (((hi.x - lo.x) / cell).floor() as usize + 1).min(1 << 14);
        let ny = (((hi.y - lo.y) / cell).floor() as usize + 1).min(1 << 14);
        let cell_of = |p: DVec2| -> (usize, usize) {
            let i = (((p.x - lo.x) / cell).floor().max(0.0) as usize).min(nx - 1);
            let j = (((p.y - lo.y) / cell).floor().max(0.0) as usize).min(ny - 1);
            (i, j)
        };
        let mut counts = vec![0u32; nx * ny + 1];
        for (l, h) in boxes.iter().flatten() {
            let (i0, j0) = cell_of(*l);
            let (i1, j1) = cell_of(*h);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    counts[j * nx + i + 1] += 1;
                }
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[nx * ny] as usize];
        for (id, b) in boxes.iter().enumerate() {
            if let Some((l, h)) = b {
                let (i0, j0) = cell_of(*l);
                let (i1, j1) = cell_of(*h);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let c = j * nx + i;
                        items[fill[c] as usize] = id as u32;
                        fill[c] += 1;
                    }
                }
            }
        }
        Grid2 {
            min: lo,
            cell,
            nx,
            ny,
            offsets: counts,
            items,
        }
    }

    fn query(&self, p: DVec2) -> &[u32] {
        let fx = (p.x - self.min.x) / self.cell;
        let fy = (p.y - self.min.y) / self.cell;
        if !(fx >= 0.0 && fy >= 0.0) || fx >= self.nx as f64 || fy >= self.ny as f64 {
            return &[];
        }
        let c = fy as usize * self.nx + fx as usize;
        &self.items[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }
}

// ---------------------------------------------------------------------------------------------
// Point-to-surface distance
// ---------------------------------------------------------------------------------------------

/// Distances from points to a mesh surface (exact point-to-triangle), through a uniform 3D
/// grid of triangles by bounding box.
#[derive(Debug, Clone)]
pub struct SurfaceIndex {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    min: DVec3,
    /// The grid's far corner (`min + dims · cell`): it covers every triangle.
    max: DVec3,
    cell: f64,
    dims: [usize; 3],
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl SurfaceIndex {
    pub fn new(mesh: &Mesh, cell_mm: f64) -> Self {
        let triangles = mesh.triangles();
        let positions = mesh.positions_mm.clone();
        let (lo, hi) = mesh.bbox_mm().unwrap_or((DVec3::ZERO, DVec3::ZERO));
        // Cells grow until the grid holds at most a few per triangle, and at most 1024 along
        // any axis: a scan with one vertex far away would otherwise ask for a billion cells.
        // (Growing the cell, not clamping the count, keeps the whole bounding box covered.)
        let budget = (4 * triangles.len()).max(1 << 12) as f64;
        let mut cell = cell_mm.max(1e-3);
        let extent = hi - lo;
        let counts = |cell: f64| [0, 1, 2].map(|k| (extent[k] / cell).floor() + 1.0);
        while counts(cell).iter().product::<f64>() > budget
            || counts(cell).iter().any(|&n| n > 1024.0)
        {
            cell *= 2.0;
        }
        let dims = counts(cell).map(|n| n as usize);
        let cell_of = |p: DVec3| -> [usize; 3] {
            [0, 1, 2].map(|k| (((p[k] - lo[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1))
        };
        let ncell = dims[0] * dims[1] * dims[2];
        let bounds: Vec<([usize; 3], [usize; 3])> = triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| positions[v as usize]);
                (
                    cell_of(p[0].min(p[1]).min(p[2])),
                    cell_of(p[0].max(p[1]).max(p[2])),
                )
            })
            .collect();
        let idx = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
        let mut counts = vec![0u32; ncell + 1];
        for (a, b) in &bounds {
            for k in a[2]..=b[2] {
                for j in a[1]..=b[1] {
                    for i in a[0]..=b[0] {
                        counts[idx(i, j, k) + 1] += 1;
                    }
                }
            }
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[ncell] as usize];
        for (t, (a, b)) in bounds.iter().enumerate() {
            for k in a[2]..=b[2] {
                for j in a[1]..=b[1] {
                    for i in a[0]..=b[0] {
                        let c = idx(i, j, k);
                        items[fill[c] as usize] = t as u32;
                        fill[c] += 1;
                    }
                }
            }
        }
        SurfaceIndex {
            positions,
            triangles,
            min: lo,
            max: lo + DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * cell,
            cell,
            dims,
            offsets: counts,
            items,
        }
    }

    /// Distance from `p` to the surface, mm; `max_mm` if nothing is closer.
    pub fn distance(&self, p: DVec3, max_mm: f64) -> f64 {
        self.closest(p, max_mm).map_or(max_mm, |(d, _)| d)
    }

    /// The closest surface point within `max_mm`: (distance, point).
    pub fn closest(&self, p: DVec3, max_mm: f64) -> Option<(f64, DVec3)> {
        if self.triangles.is_empty() {
            return None;
        }
        // Nothing within reach of the grid: answer at once instead of widening the search to
        // `max_mm` over empty cells (a registration far off the scan made this slow; found by
        // fuzzing the pipeline).
        let outside = (self.min - p).max(p - self.max).max(DVec3::ZERO);
        if !(outside.length() <= max_mm) {
            return None;
        }
        let mut r = self.cell;
        loop {
            let r_eff = r.min(max_mm);
            let lo = [0, 1, 2].map(|k| ((p[k] - r_eff - self.min[k]) / self.cell).floor());
            let hi = [0, 1, 2].map(|k| ((p[k] + r_eff - self.min[k]) / self.cell).floor());
            let mut best: Option<(f64, DVec3)> = None;
            if (0..3).all(|k| hi[k] >= 0.0 && lo[k] < self.dims[k] as f64) {
                let lo = [0, 1, 2].map(|k| lo[k].max(0.0) as usize);
                let hi = [0, 1, 2].map(|k| (hi[k] as usize).min(self.dims[k] - 1));
                for kz in lo[2]..=hi[2] {
                    for jy in lo[1]..=hi[1] {
                        for ix in lo[0]..=hi[0] {
                            let c = (kz * self.dims[1] + jy) * self.dims[0] + ix;
                            for &t in
                                &self.items[self.offsets[c] as usize..self.offsets[c + 1] as usize]
                            {
                                let [a, b, cc] =
                                    self.triangles[t as usize].map(|v| self.positions[v as usize]);
                                // A triangle whose bounding box is no nearer than the best
                                // so far cannot beat it (and a triangle spanning several
                                // cells comes up once per cell).
                                if let Some((bd, _)) = best {
                                    let gap = (a.min(b).min(cc) - p)
                                        .max(p - a.max(b).max(cc))
                                        .max(DVec3::ZERO);
                                    if gap.length_squared() >= bd {
                                        continue;
                                    }
                                }
                                let q = closest_point_on_triangle(p, a, b, cc);
                                let d2 = q.distance_squared(p);
                                if best.is_none_or(|(bd, _)| d2 < bd) {
                                    best = Some((d2, q));
                                }
                            }
                        }
                    }
                }
            }
            // Once the box holds the whole grid, a wider one finds nothing more.
            let whole = (0..3).all(|k| lo[k] <= 0.0 && hi[k] >= self.dims[k] as f64 - 1.0);
            if let Some((d2, q)) = best
                && (d2.sqrt() <= r_eff || whole)
            {
                return (d2.sqrt() <= max_mm).then_some((d2.sqrt(), q));
            }
            if r_eff >= max_mm || whole {
                return None;
            }
            r *= 2.0;
        }
    }
}

/// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5).
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

// ---------------------------------------------------------------------------------------------
// Evaluation on the synthetic benchmark
// ---------------------------------------------------------------------------------------------

/// Ground-truth feature points of a synthetic scan: the 9 named generator landmarks plus the
/// 4 the generator lacks, derived from its iBUG-68 points (`derived[i]` marks them) the way the
/// generic face places its own:
///
/// * **cheeks** — on the generic face the cheek point is the cheek at the nose tip's height,
///   [`GENERIC_CHEEK_X_MM`] − 48.1 = 11.9 mm lateral of the outer eye corner (12.4 % of the
///   outer-eye distance; the paper's step 7 looks for it in a box beside the outer eye
///   corners). The derived point is the same: from each outer eye corner (iBUG 36 / 45),
///   [`CHEEK_BEYOND_OUTER_EYE`] × the scan's outer-eye distance further out along the
///   eye line, moved along the face's up direction (chin iBUG 8 → nasion iBUG 27) to the nose
///   tip's height, then onto the front-most scan surface along z. (Earlier versions took the
///   jaw contour iBUG 0–16 at that height, i.e. the face's silhouette, which is ~10 mm further
///   out than the generic face's cheek point and dragged its side off the scan.)
/// * **forehead** — the midpoint of the inner brow ends (iBUG 21, 22) moved 25 mm up along the
///   same direction, snapped to the closest point of `surface` (the clean scan).
#[derive(Debug, Clone, Copy)]
pub struct TruthPoints {
    pub landmarks: Landmarks,
    pub derived: [bool; FeaturePoint::COUNT],
}

/// Frontal x of the built-in generic face's cheek points, mm (`generic_face` grid).
pub const GENERIC_CHEEK_X_MM: f64 = 60.0;
/// How far the derived cheek points lie beyond the outer eye corners, as a fraction of the
/// outer-eye distance: (60 − 48.1) / 96.2 on the generic face.
pub const CHEEK_BEYOND_OUTER_EYE: f64 = (GENERIC_CHEEK_X_MM
    - (crate::generic_face::targets::NOSE_TO_INNER_EYE_X
        + crate::generic_face::targets::INNER_TO_OUTER_EYE_X))
    / (2.0
        * (crate::generic_face::targets::NOSE_TO_INNER_EYE_X
            + crate::generic_face::targets::INNER_TO_OUTER_EYE_X));

/// Height of the derived forehead point above the inner brow ends, mm.
pub const FOREHEAD_ABOVE_BROWS_MM: f64 = 25.0;

/// Reads a synth_gavab JSON and builds [`TruthPoints`].
pub fn truth_points(json_path: &Path, surface: &Mesh) -> Result<TruthPoints> {
    let truth = crate::ground_truth::ScanTruth::load(json_path)?;
    let text = std::fs::read_to_string(json_path).map_err(|e| Error::io(json_path, e))?;
    #[derive(serde::Deserialize)]
    struct Ibug {
        ibug68_xyz_mm: Vec<[f64; 3]>,
    }
    let ibug: Ibug =
        serde_json::from_str(&text).map_err(|e| Error::invalid(json_path, e.to_string()))?;
    if ibug.ibug68_xyz_mm.len() != 68 {
        return Err(Error::invalid(
            json_path,
            "ibug68_xyz_mm must have 68 points",
        ));
    }
    let pts: Vec<DVec3> = ibug
        .ibug68_xyz_mm
        .iter()
        .map(|p| DVec3::from_array(*p))
        .collect();
    let mut out = [DVec3::NAN; FeaturePoint::COUNT];
    let mut derived = [false; FeaturePoint::COUNT];
    for (p, x, _) in truth.feature_points() {
        out[p.index()] = x;
    }
    let nose = out[FeaturePoint::NoseTip.index()];
    if !nose.is_finite() {
        return Err(Error::invalid(json_path, "no nose_tip landmark"));
    }
    let up = (pts[27] - pts[8]).normalize();
    let index = SurfaceIndex::new(surface, 4.0);
    let snap = |x: DVec3| index.closest(x, 50.0).map_or(x, |(_, q)| q);
    // Front-most scan surface at (x, y) of `x`: the highest z of the scan triangles over it.
    let front_at = |x: DVec3| -> DVec3 {
        let mut best: Option<f64> = None;
        for f in 0..surface.face_count() {
            let poly = surface.faces.get(f);
            for k in 1..poly.len().saturating_sub(1) {
                let [a, b, c] =
                    [poly[0], poly[k], poly[k + 1]].map(|i| surface.positions_mm[i as usize]);
                let q = DVec2::new(x.x, x.y);
                if let Some(w) = barycentric2(q, a.truncate(), b.truncate(), c.truncate())
                    && w.iter().all(|&t| t >= -1e-9)
                {
                    let z = a.z * w[0] + b.z * w[1] + c.z * w[2];
                    best = Some(best.map_or(z, |z0: f64| z0.max(z)));
                }
            }
        }
        best.map_or_else(|| snap(x), |z| DVec3::new(x.x, x.y, z))
    };
    let (eye_r, eye_l) = (pts[36], pts[45]);
    let across = eye_l - eye_r;
    let cheek = |eye: DVec3, outward: DVec3| -> DVec3 {
        let mut c = eye + outward * CHEEK_BEYOND_OUTER_EYE;
        c += up * (nose - c).dot(up);
        front_at(c)
    };
    out[FeaturePoint::CheekRight.index()] = cheek(eye_r, -across);
    out[FeaturePoint::CheekLeft.index()] = cheek(eye_l, across);
    out[FeaturePoint::Forehead.index()] =
        snap((pts[21] + pts[22]) * 0.5 + up * FOREHEAD_ABOVE_BROWS_MM);
    for p in [
        FeaturePoint::CheekLeft,
        FeaturePoint::CheekRight,
        FeaturePoint::Forehead,
    ] {
        derived[p.index()] = true;
    }
    if let Some(p) = FeaturePoint::ALL
        .iter()
        .find(|p| !out[p.index()].is_finite())
    {
        return Err(Error::invalid(
            json_path,
            format!("no ground truth for {p}"),
        ));
    }
    Ok(TruthPoints {
        landmarks: Landmarks(out),
        derived,
    })
}

/// One scan's registration figures against ground truth.
#[derive(Debug, Clone, Serialize)]
pub struct ScanEvaluation {
    pub rigid_rms_mm: f64,
    /// Registered feature vertex ↔ ground-truth landmark, over the landmarks given.
    pub landmark_residual_mean_mm: f64,
    pub landmark_residual_max_mm: f64,
    /// Registered vertices → the *reference* surface (the clean twin).
    pub surface_distance_mm: DistanceStats,
    /// Registered vertices → the scan registered to (as in [`RegistrationResult`]).
    pub scan_distance_mm: DistanceStats,
    /// As `surface_distance_mm`, over the matched (projected, not filled) vertices only.
    pub matched_distance_mm: DistanceStats,
    pub unmatched_vertices: usize,
    pub folded_warp_triangles: usize,
    pub scale: f64,
    pub millis: f64,
}

/// Registers `generic` to `scan` with the given points and scores the result against
/// `reference` (the clean twin of the scan; pass the scan itself for clean data) and the
/// ground-truth landmarks `truth`.
pub fn evaluate(
    generic: &GenericFace,
    scan: &Mesh,
    reference: &Mesh,
    points: &[(FeaturePoint, DVec3)],
    truth: &Landmarks,
    params: &RegistrationParams,
) -> Result<ScanEvaluation> {
    let res = register_points(generic, scan, points, params)?;
    let index = SurfaceIndex::new(reference, 4.0);
    let d: Vec<f64> = res
        .mesh
        .positions_mm
        .iter()
        .map(|p| index.distance(*p, 200.0))
        .collect();
    let resid: Vec<f64> = points
        .iter()
        .map(|(p, _)| {
            res.mesh.positions_mm[generic.feature_vertex(*p) as usize].distance(truth.get(*p))
        })
        .collect();
    let mut is_unmatched = vec![false; d.len()];
    for &v in &res.unmatched_vertices {
        is_unmatched[v as usize] = true;
    }
    let matched: Vec<f64> = d
        .iter()
        .zip(&is_unmatched)
        .filter(|(_, u)| !**u)
        .map(|(x, _)| *x)
        .collect();
    Ok(ScanEvaluation {
        matched_distance_mm: DistanceStats::of(&matched),
        rigid_rms_mm: res.rigid_rms_mm,
        landmark_residual_mean_mm: resid.iter().sum::<f64>() / resid.len() as f64,
        landmark_residual_max_mm: resid.iter().copied().fold(0.0, f64::max),
        surface_distance_mm: DistanceStats::of(&d),
        scan_distance_mm: res.surface_distance_mm,
        unmatched_vertices: res.unmatched_vertices.len(),
        folded_warp_triangles: res.folded_warp_triangles,
        scale: res.scan_from_generic.scale,
        millis: res.millis,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
            (svd.singular_values[0] + svd.singular_values[1] + d[(2, 2)] * svd.singular_values[2])
                / aa
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
        let warp = PlanarWarp::with_anchor_ring(&src, &src, 1.6, 16)
            .expect("warp over a symmetric layout");
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
}
