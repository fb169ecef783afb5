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
//! Measured accuracy against the clean twins (and the command): `docs/measurements.md`,
//! section "Registration".

use crate::feature_points::{FeaturePoint, Landmarks};
use crate::generic_face::GenericFace;
use crate::mesh::{Mesh, SurfaceIndex, Topology, ray_triangle};
use crate::{Error, Result};
use glam::{DMat3, DQuat, DVec2, DVec3};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

mod cylinder;
mod delaunay;
mod eval;
mod fill;
mod horn;
#[cfg(test)]
mod tests;
mod warp;

pub use cylinder::{CylinderFrame, CylinderHit, CylinderProjector};
pub use delaunay::delaunay;
pub use eval::{
    CHEEK_BEYOND_OUTER_EYE, FOREHEAD_ABOVE_BROWS_MM, GENERIC_CHEEK_X_MM, ScanEvaluation,
    TruthPoints, evaluate, truth_points,
};
pub use fill::Unmatched;
use fill::{harmonic_fill, mark_outside_scan};
pub use horn::horn_absolute_orientation;
pub use warp::PlanarWarp;
use warp::barycentric2;

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

    /// `next` after `self`: `p ↦ next.apply(self.apply(p))`.
    pub fn then(&self, next: &Similarity) -> Similarity {
        Similarity {
            rotation: next.rotation * self.rotation,
            scale: next.scale * self.scale,
            translation_mm: next.apply(self.translation_mm),
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

    /// Rounded to 0.1 µm, as the reports print them.
    pub fn rounded(self) -> DistanceStats {
        DistanceStats {
            mean: round4(self.mean),
            p95: round4(self.p95),
            max: round4(self.max),
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
    /// Why, per vertex of `unmatched_vertices`.
    pub unmatched_reasons: Vec<Unmatched>,
    /// Triangles of the planar warp that the targets turned over (0 for sane landmarks).
    pub folded_warp_triangles: usize,
    /// Mean, p95 and max of `vertex_distance_mm`.
    pub surface_distance_mm: DistanceStats,
    /// Distance of each registered vertex to the scan surface (mm; at most 200).
    pub vertex_distance_mm: Vec<f64>,
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

    /// How many vertices were left unmatched for each reason (of `among`, a sorted vertex
    /// list, when given).
    pub fn unmatched_by_reason(&self, among: Option<&[usize]>) -> BTreeMap<&'static str, usize> {
        let mut out: BTreeMap<&'static str, usize> =
            Unmatched::ALL.iter().map(|r| (r.name(), 0)).collect();
        for (&v, r) in self.unmatched_vertices.iter().zip(&self.unmatched_reasons) {
            if among.is_none_or(|a| a.binary_search(&(v as usize)).is_ok()) {
                *out.entry(r.name()).or_default() += 1;
            }
        }
        out
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
            "surface_distance_mm": self.surface_distance_mm.rounded(),
            "unmatched_vertices": self.unmatched_vertices.len(),
            "unmatched_by_reason": self.unmatched_by_reason(None),
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
    // `None`: projected onto the scan.
    let mut reason: Vec<Option<Unmatched>> = vec![None; n];
    let mut hit_local = vec![DVec3::ZERO; n];
    for (v, q) in warped.iter().enumerate() {
        let theta = q.x.atan2(q.z);
        let r = q.x.hypot(q.z);
        match projector.cast(theta, q.y) {
            Some(hit) if (hit.radius - r).abs() <= params.max_offset_mm => {
                offset[v] = hit.radius - r;
                hit_local[v] = hit.local;
            }
            Some(_) => reason[v] = Some(Unmatched::FarSurface),
            None => reason[v] = Some(Unmatched::Hole),
        }
    }
    mark_outside_scan(&generic.mesh, &topo, &mut reason);
    // Offsets far from their neighbours' median are spikes, hair or wrong layers.
    let mut outliers = Vec::new();
    let mut scratch = Vec::new();
    for v in 0..n {
        if reason[v].is_some() {
            continue;
        }
        scratch.clear();
        scratch.extend(
            topo.neighbours(v)
                .iter()
                .filter(|&&u| reason[u as usize].is_none())
                .map(|&u| offset[u as usize]),
        );
        if scratch.len() >= 2 && (offset[v] - median(&mut scratch)).abs() > params.outlier_mm {
            outliers.push(v);
        }
    }
    for &v in &outliers {
        reason[v] = Some(Unmatched::Outlier);
    }
    let matched: Vec<bool> = reason.iter().map(Option::is_none).collect();
    harmonic_fill(&topo, &matched, &mut offset);
    let mut positions = Vec::with_capacity(n);
    let mut unmatched_vertices = Vec::new();
    let mut unmatched_reasons = Vec::new();
    for v in 0..n {
        let local = if let Some(why) = reason[v] {
            unmatched_vertices.push(v as u32);
            unmatched_reasons.push(why);
            let q = warped[v];
            let r = q.x.hypot(q.z);
            let s = (r + offset[v]).max(0.0) / r.max(1e-12);
            DVec3::new(q.x * s, q.y, q.z * s)
        } else {
            hit_local[v]
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
        unmatched_reasons,
        folded_warp_triangles: warp.folded_triangles(),
        surface_distance_mm: DistanceStats::of(&distances),
        vertex_distance_mm: distances,
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
