//! Surface descriptors of paper section 2.1.2 (Figure 7): principal curvatures, the shape
//! index, and the normal-derived "derivative maps" the feature-point steps threshold.
//!
//! # Principal curvatures
//!
//! At every vertex `v` a height function is fitted by least squares in the local frame of the
//! mesh normal `n₀` (tangent axes `t₁, t₂`): every vertex `p` of the `rings`-ring of `v` gives
//! local coordinates `(a, b, h) = ((p − v)·t₁, (p − v)·t₂, (p − v)·n₀)` and
//! `h ≈ A a² + B ab + C b² + D a + E b` (the surface passes through `v`). The fitted normal,
//! first and second fundamental forms at the origin give the shape operator, whose eigenvalues
//! are the principal curvatures `κ₁ ≥ κ₂` (1/mm).
//!
//! **Sign convention:** curvature is *positive where the surface bends away from its outward
//! normal* (convex, like the nose tip with normals towards the scanner, +z). A sphere of radius
//! R seen from outside has κ₁ = κ₂ = +1/R.
//!
//! # Shape index (Dorai & Jain 1997, as used by Colbry/Lu, the paper's ref. \[9\])
//!
//! `S = 1/2 + (1/π)·atan((κ₁ + κ₂)/(κ₁ − κ₂))`, in [0, 1]. With our sign convention this is
//! Dorai–Jain's `1/2 − (1/π)·atan(…)` (they take convex curvature as negative), and it gives
//! what the paper's thresholds need: **convex cap (nose tip, chin) → 1**, ridge (convex
//! cylinder) → 0.75, saddle → 0.5, rut (concave cylinder) → 0.25, **concave cup (inner eye
//! corner) → 0**. At umbilic points (κ₁ = κ₂) the fraction is ±∞ and `atan` gives ±π/2, so
//! caps and cups are exactly 1 and 0. **Planar points** (curvedness
//! `√((κ₁² + κ₂²)/2)` below [`CurvatureParams::flat_curvedness_per_mm`](CurvatureParams)) have no defined
//! shape index: we return **0.5** there (neither convex nor concave) and callers that care
//! check [`SurfaceDescriptors::curvedness_per_mm`](SurfaceDescriptors).
//!
//! # Derivative maps
//!
//! The paper thresholds `|∂/∂x|`, `|∂/∂z|` and `∇xy` without defining them; as in Colbry's
//! work they are read here as components of the **unit surface normal** `n = (n_x, n_y, n_z)`
//! in the scan frame (x to the subject's left, y up, z towards the scanner), taken from the
//! same quadric fit (smoother than the raw mesh normal):
//! - `|∂/∂x| = |n_x|`: 0 on surfaces facing the scanner, 1 on surfaces facing sideways
//!   (the sides of the nose);
//! - `|∂/∂z| = |n_z|`: 1 facing the scanner, 0 seen edge-on (face borders, nose sides);
//! - `∇xy = √(n_x² + n_y²)`: the sine of the angle between the normal and the viewing axis.
//!   For a depth map `z(x, y)` this is `|∇z| / √(1 + |∇z|²)`, so below ~0.35 it equals the
//!   depth gradient magnitude `|∇z|` within 7 % (the paper's thresholds are 0.25–0.35).
//!
//! Vertices whose ring gives no well-posed fit (fewer than 5 neighbours, or all of them on a
//! line — isolated or rim corner vertices) get κ₁ = κ₂ = 0, S = 0.5 and the mesh normal.

use crate::mesh::{Mesh, Topology};
use crate::{Error, Result};
use glam::DVec3;
use nalgebra::{SMatrix, SVector};

/// Parameters of [`compute`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvatureParams {
    /// Edge hops of the neighbourhood fitted at each vertex (≥ 1). Default 2 (the 2-ring:
    /// ~±3 mm on a 1.47 mm scan grid). Larger rings average out scanner noise at the cost of
    /// detail; the feature-point detector uses its own setting.
    pub rings: usize,
    /// Curvedness below which a point counts as planar and gets S = 0.5, 1/mm (≥ 0).
    /// Default 1e-6 /mm (a radius of curvature of 1 km).
    pub flat_curvedness_per_mm: f64,
}

impl Default for CurvatureParams {
    fn default() -> Self {
        CurvatureParams {
            rings: 2,
            flat_curvedness_per_mm: 1e-6,
        }
    }
}

/// Per-vertex descriptors (all vectors have one entry per mesh vertex).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceDescriptors {
    /// Larger principal curvature κ₁, 1/mm (positive = convex).
    pub k1_per_mm: Vec<f64>,
    /// Smaller principal curvature κ₂ ≤ κ₁, 1/mm.
    pub k2_per_mm: Vec<f64>,
    /// Shape index in [0, 1]: cap 1, ridge 0.75, saddle 0.5 (also: planar), rut 0.25, cup 0.
    pub shape_index: Vec<f64>,
    /// Curvedness √((κ₁² + κ₂²)/2), 1/mm.
    pub curvedness_per_mm: Vec<f64>,
    /// Fitted unit normal (outward).
    pub normal: Vec<DVec3>,
}

impl SurfaceDescriptors {
    pub fn len(&self) -> usize {
        self.shape_index.len()
    }

    pub fn is_empty(&self) -> bool {
        self.shape_index.is_empty()
    }

    /// `|∂/∂x| = |n_x|` at vertex `v`.
    pub fn dx(&self, v: usize) -> f64 {
        self.normal[v].x.abs()
    }

    /// `|∂/∂z| = |n_z|` at vertex `v`.
    pub fn dz(&self, v: usize) -> f64 {
        self.normal[v].z.abs()
    }

    /// `∇xy = √(n_x² + n_y²)` at vertex `v`.
    pub fn grad_xy(&self, v: usize) -> f64 {
        let n = self.normal[v];
        (n.x * n.x + n.y * n.y).sqrt()
    }

    /// The whole `|∂/∂x|` map.
    pub fn dx_map(&self) -> Vec<f64> {
        (0..self.len()).map(|v| self.dx(v)).collect()
    }

    /// The whole `|∂/∂z|` map.
    pub fn dz_map(&self) -> Vec<f64> {
        (0..self.len()).map(|v| self.dz(v)).collect()
    }

    /// The whole `∇xy` map.
    pub fn grad_xy_map(&self) -> Vec<f64> {
        (0..self.len()).map(|v| self.grad_xy(v)).collect()
    }
}

/// Shape index of principal curvatures `k1 ≥ k2` (any order accepted) in our sign convention
/// (convex positive); 0.5 when the curvedness is below `flat` (planar, undefined).
pub fn shape_index(k1: f64, k2: f64, flat: f64) -> f64 {
    let (k1, k2) = if k1 >= k2 { (k1, k2) } else { (k2, k1) };
    if ((k1 * k1 + k2 * k2) * 0.5).sqrt() <= flat {
        return 0.5;
    }
    let d = k1 - k2;
    let s = k1 + k2;
    // atan2 handles the umbilic case d = 0 (±π/2) without a division.
    0.5 + s.atan2(d) / std::f64::consts::PI
}

/// Computes the descriptors of every vertex of `mesh`.
pub fn compute(mesh: &Mesh, params: &CurvatureParams) -> Result<SurfaceDescriptors> {
    mesh.validate().map_err(Error::InvalidMesh)?;
    let topology = Topology::new(mesh);
    compute_with_topology(mesh, &topology, params)
}

/// [`compute`] for callers that already have the mesh's [`Topology`].
pub fn compute_with_topology(
    mesh: &Mesh,
    topology: &Topology,
    params: &CurvatureParams,
) -> Result<SurfaceDescriptors> {
    if params.rings == 0 {
        return Err(Error::algorithm("curvature", "rings must be ≥ 1, got 0"));
    }
    if !(params.flat_curvedness_per_mm >= 0.0 && params.flat_curvedness_per_mm.is_finite()) {
        return Err(Error::algorithm(
            "curvature",
            format!(
                "flat_curvedness_per_mm must be ≥ 0, got {}",
                params.flat_curvedness_per_mm
            ),
        ));
    }
    let n = mesh.vertex_count();
    if topology.vertex_count() != n || mesh.normals.len() != n {
        return Err(Error::InvalidMesh(format!(
            "topology/normals have {}/{} entries, mesh has {n} vertices",
            topology.vertex_count(),
            mesh.normals.len()
        )));
    }
    let mut out = SurfaceDescriptors {
        k1_per_mm: vec![0.0; n],
        k2_per_mm: vec![0.0; n],
        shape_index: vec![0.5; n],
        curvedness_per_mm: vec![0.0; n],
        normal: mesh.normals.clone(),
    };
    let mut scratch = vec![false; n];
    let mut ring = Vec::new();
    for v in 0..n {
        topology.k_ring(v, params.rings, &mut scratch, &mut ring);
        let n0 = mesh.normals[v];
        if n0 == DVec3::ZERO || ring.len() < 5 {
            continue;
        }
        if let Some(fit) = fit_vertex(mesh, v, n0, &ring) {
            out.k1_per_mm[v] = fit.k1;
            out.k2_per_mm[v] = fit.k2;
            out.shape_index[v] = shape_index(fit.k1, fit.k2, params.flat_curvedness_per_mm);
            out.curvedness_per_mm[v] = ((fit.k1 * fit.k1 + fit.k2 * fit.k2) * 0.5).sqrt();
            out.normal[v] = fit.normal;
        }
    }
    Ok(out)
}

struct Fit {
    k1: f64,
    k2: f64,
    normal: DVec3,
}

/// Least-squares height-function fit at `v` over `ring` in the frame of `n0`.
fn fit_vertex(mesh: &Mesh, v: usize, n0: DVec3, ring: &[u32]) -> Option<Fit> {
    let (t1, t2) = n0.any_orthonormal_pair();
    let p0 = mesh.positions_mm[v];
    // Scale local coordinates by the mean neighbour distance so the normal matrix is well
    // conditioned whatever the mesh resolution.
    let mut scale = 0.0;
    for &u in ring {
        scale += (mesh.positions_mm[u as usize] - p0).length();
    }
    scale /= ring.len() as f64;
    if !(scale > 0.0) {
        return None;
    }
    let inv = 1.0 / scale;
    let mut ata = SMatrix::<f64, 5, 5>::zeros();
    let mut atb = SVector::<f64, 5>::zeros();
    for &u in ring {
        let d = (mesh.positions_mm[u as usize] - p0) * inv;
        let (a, b, h) = (d.dot(t1), d.dot(t2), d.dot(n0));
        let row = SVector::<f64, 5>::new(a * a, a * b, b * b, a, b);
        ata += row * row.transpose();
        atb += row * h;
    }
    // Reject rank-deficient neighbourhoods (collinear rims) by the conditioning of AᵀA.
    let chol = ata.cholesky()?;
    if !well_conditioned(&ata, &chol) {
        return None;
    }
    let x = chol.solve(&atb);
    // Back to mm: h = A a² … with a, b, h in units of `scale`.
    let (fxx, fxy, fyy) = (2.0 * x[0] * inv, x[1] * inv, 2.0 * x[2] * inv);
    let (fx, fy) = (x[3], x[4]);
    let w = (1.0 + fx * fx + fy * fy).sqrt();
    // Fundamental forms of the graph (a, b, f(a, b)) at the origin.
    let (e, f, g) = (1.0 + fx * fx, fx * fy, 1.0 + fy * fy);
    let (l, m, nn) = (fxx / w, fxy / w, fyy / w);
    // Shape operator I⁻¹ II; its eigenvalues are the curvatures w.r.t. the upward (+n0)
    // normal, positive where the surface bends towards the normal (concave): negate.
    let det_i = e * g - f * f;
    let s11 = (g * l - f * m) / det_i;
    let s12 = (g * m - f * nn) / det_i;
    let s21 = (e * m - f * l) / det_i;
    let s22 = (e * nn - f * m) / det_i;
    let tr = s11 + s22;
    let det = s11 * s22 - s12 * s21;
    let disc = (tr * tr * 0.25 - det).max(0.0).sqrt();
    let (c1, c2) = (tr * 0.5 + disc, tr * 0.5 - disc);
    let normal = (n0 - t1 * fx - t2 * fy).normalize();
    Some(Fit {
        k1: -c2,
        k2: -c1,
        normal,
    })
}

/// Largest condition number λmax / λmin of a ring's normal matrix that is still fitted.
const MAX_CONDITION: f64 = 1e10;

/// Whether the positive definite `ata` has a condition number below [`MAX_CONDITION`].
/// [`condition_bound`] decides it without an eigensolver on all but nearly degenerate rings.
fn well_conditioned(
    ata: &SMatrix<f64, 5, 5>,
    chol: &nalgebra::Cholesky<f64, nalgebra::U5>,
) -> bool {
    if condition_bound(ata, chol) < MAX_CONDITION {
        return true;
    }
    let eig = ata.symmetric_eigenvalues();
    let (lo, hi) = eig
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), &e| (lo.min(e), hi.max(e)));
    lo > hi * MAX_CONDITION.recip()
}

/// tr(A)·tr(A⁻¹), an upper bound of A's condition number (λmax ≤ tr(A), 1 / λmin ≤ tr(A⁻¹);
/// at most 25× too large, the dimension squared). tr(A⁻¹) = ‖L⁻¹‖²_F from the Cholesky
/// factor, so only the triangular inverse is formed. Infinite if L is singular.
fn condition_bound(ata: &SMatrix<f64, 5, 5>, chol: &nalgebra::Cholesky<f64, nalgebra::U5>) -> f64 {
    chol.l_dirty()
        .solve_lower_triangular(&SMatrix::<f64, 5, 5>::identity())
        .map_or(f64::INFINITY, |l_inv| l_inv.norm_squared() * ata.trace())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The trace bounds give the eigenvalue test's answer, on matrices from well conditioned
    /// to singular (condition numbers 1 to 1e16, both sides of the 1e10 limit).
    #[test]
    fn conditioning_test_agrees_with_the_eigenvalues() {
        let mut rnd = crate::test_support::uniform(99);
        let (mut fast, mut slow) = (0, 0);
        for k in 0..=64 {
            let cond = 10f64.powf(k as f64 / 4.0);
            // A random rotation times a diagonal spread from 1 to 1 / cond.
            let q = SMatrix::<f64, 5, 5>::from_fn(|_, _| rnd()).qr().q();
            let d = SMatrix::<f64, 5, 5>::from_diagonal(&SVector::<f64, 5>::from_fn(|i, _| {
                cond.powf(-(i as f64) / 4.0)
            }));
            let a = q * d * q.transpose();
            let a = 0.5 * (a + a.transpose());
            let Some(chol) = a.cholesky() else {
                continue;
            };
            let eig = a.symmetric_eigenvalues();
            let (lo, hi) = eig
                .iter()
                .fold((f64::MAX, 0.0f64), |(lo, hi), &e| (lo.min(e), hi.max(e)));
            assert_eq!(
                well_conditioned(&a, &chol),
                lo > hi * 1e-10,
                "condition {cond:e}"
            );
            if condition_bound(&a, &chol) < MAX_CONDITION {
                fast += 1;
            } else {
                slow += 1;
            }
        }
        // Both paths were taken.
        assert!(fast > 10 && slow > 5, "fast {fast}, slow {slow}");
    }

    #[test]
    fn shape_index_of_textbook_curvature_pairs() {
        let flat = 1e-9;
        assert!((shape_index(0.1, 0.1, flat) - 1.0).abs() < 1e-12);
        assert!((shape_index(-0.1, -0.1, flat) - 0.0).abs() < 1e-12);
        assert!((shape_index(0.1, 0.0, flat) - 0.75).abs() < 1e-12);
        assert!((shape_index(0.0, -0.1, flat) - 0.25).abs() < 1e-12);
        assert!((shape_index(0.1, -0.1, flat) - 0.5).abs() < 1e-12);
        assert_eq!(shape_index(0.0, 0.0, flat), 0.5);
        // Order of the arguments does not matter.
        assert_eq!(shape_index(0.0, 0.1, flat), shape_index(0.1, 0.0, flat));
    }
}
