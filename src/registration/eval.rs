//! Evaluation of a registration against ground truth: the generic face's feature points on a
//! generated scan and the distance to the clean twin.

use super::*;

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
