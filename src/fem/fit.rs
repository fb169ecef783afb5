//! Learning an expression from a scan (paper: "additional expressions can be learned from
//! input faces"): given the FEM face of a person's neutral scan and a scan of the same person
//! with an expression, align the expression scan rigidly on stable regions (upper forehead and
//! nose), then fit the 18 muscle activations and the jaw by non-negative least squares so that the
//! synthesized surface meets the scan, re-taking closest points a few times. The fit is
//! point-to-plane (along the model's vertex normals): a surface scan shows where the skin is,
//! not how far it slid along itself. [`signed_residuals`] (`fit-expression --residual-ply`)
//! maps what is left, per vertex and with its sign.
//!
//! Why the soft-tissue loads exist: on the cara1 smile the residual map without them showed
//! the lateral cheeks 3–7 mm in front of the fitted model, since a contracting linear muscle
//! slides skin along itself and cannot thicken the cheek (`assets/muscles.ron`). Per actuator,
//! [`FitResult::contributions_mm`] says what explained the expression. Measured fits, on cara1
//! and cara6 and on generated smiles: `docs/measurements.md`, "Expressions on real pairs" and
//! "Expression fit: the soft-tissue loads".

use super::FaceModel;
use super::anchor::FaceFrame;
use super::expressions::ExpressionSet;
use super::regions::Regions;
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::mesh::SurfaceIndex;
use crate::registration::{Similarity, horn_absolute_orientation};
use crate::{FemError, Mesh, Result};
use glam::DVec3;

/// Parameters of [`fit_expression`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitParams {
    /// Rigid ICP rounds on the stable region (default 30).
    pub icp_rounds: usize,
    /// Closest-point / NNLS rounds of the activation fit (default 5).
    pub fit_rounds: usize,
    /// Model vertices farther than this from the scan are left out (holes, hair), mm
    /// (default 8).
    pub max_distance_mm: f64,
    /// With the neutral scan given, model vertices farther than this from it (where the
    /// registration did not reach the scan) are left out, mm (default 1.5).
    pub max_neutral_error_mm: f64,
    /// Ridge weight on the activations, relative to each activation's own diagonal entry of
    /// the normal matrix (default 1e-4), so it does not depend on the activations' units
    /// (force multiples, degrees, mm).
    pub ridge: f64,
}

impl Default for FitParams {
    fn default() -> Self {
        FitParams {
            icp_rounds: 30,
            fit_rounds: 5,
            max_distance_mm: 8.0,
            max_neutral_error_mm: 1.5,
            ridge: 1e-4,
        }
    }
}

/// What [`fit_expression`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct FitResult {
    /// One non-negative activation per actuator (model order: the muscles, then the jaw).
    pub activations: Vec<f64>,
    /// RMS distance of the neutral model surface to the aligned expression scan, mm.
    pub rms_before_mm: f64,
    /// RMS distance of the fitted expression to the scan, mm (the best fit round; never above
    /// `rms_before_mm`).
    pub rms_after_mm: f64,
    /// With the neutral scan given: RMS distance of the model to its own neutral scan over the
    /// same vertices — the registration's floor under any fit, mm.
    pub rms_neutral_scan_mm: Option<f64>,
    /// The preset whose synthesized surface is closest to the scan, and its RMS distance.
    pub closest_preset: Option<(String, f64)>,
    /// Model vertices used in the fit.
    pub vertices_used: usize,
    /// The expression scan moved into the model's frame.
    pub aligned_scan: Mesh,
    /// The rigid motion that moved it, and how well the stable parts agree after it.
    pub alignment: Alignment,
    /// RMS before and after over the part an expression moves most: the fitted vertices below
    /// the eyes outside the nose (mouth, cheeks, chin), against the finally aligned scan, mm.
    pub moving_rms_before_mm: f64,
    pub moving_rms_after_mm: f64,
    /// Vertices in that part.
    pub moving_vertices: usize,
    /// Per actuator (model order): how much of the fitted surface motion it makes, as the RMS
    /// over the fitted vertices of its activation times its displacement along the vertex
    /// normal (what the fit sees), mm. Unlike the activations (forces, degrees, mm), these
    /// compare across actuators: the largest ones are what the expression was explained by.
    pub contributions_mm: Vec<f64>,
}

impl FitResult {
    /// The actuators that moved the face (`names` in model order), largest contribution first:
    /// (name, [`FitResult::contributions_mm`]).
    pub fn ranked_contributions(&self, names: &[String]) -> Vec<(String, f64)> {
        let mut out: Vec<(String, f64)> = names
            .iter()
            .cloned()
            .zip(self.contributions_mm.iter().copied())
            .filter(|(_, c)| *c > 0.0)
            .collect();
        out.sort_by(|a, b| b.1.total_cmp(&a.1));
        out
    }

    /// The fitted face of `model` and its signed distance to the aligned scan per vertex
    /// ([`signed_residuals`] within [`FitParams::max_distance_mm`]): the residual map.
    pub fn residual_map(
        &self,
        model: &FaceModel,
        params: &FitParams,
    ) -> Result<(Mesh, Vec<Option<f64>>)> {
        let fitted = model.deformed_surface(&self.activations)?;
        let residual = signed_residuals(&fitted, &self.aligned_scan, params.max_distance_mm);
        Ok((fitted, residual))
    }
}

/// The rigid alignment of the expression scan onto the model ([`align_scan`]), as reported.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Alignment {
    /// Angle of the rotation, degrees.
    pub rotation_deg: f64,
    /// Translation, mm (model frame).
    pub translation_mm: [f64; 3],
    /// RMS distance of the model's stable vertices to the aligned scan, mm, per stable part
    /// (vertices within [`FitParams::max_distance_mm`] of the scan).
    pub forehead_rms_mm: f64,
    pub nose_rms_mm: f64,
    /// Stable vertices that found the scan within reach.
    pub stable_vertices_on_scan: usize,
}

/// After the rigid fit, a stable part (forehead, nose) farther than this from the expression
/// scan (RMS) means the two scans do not show the same rigid face: another person, a hat or
/// hair over the forehead, or a failed detection that started the fit elsewhere. Scanner noise
/// and what expressions do to the forehead and nose stay well below it (brow raisers move the
/// lower forehead, which the forehead part excludes; cara1: 0.3–0.6 mm).
pub const STABLE_PART_MAX_RMS_MM: f64 = 2.5;

/// The built-in actuators grouped by what they do (FACS action units), for
/// [`contribution_shares`]: `smile` zygomatic major (AU12) and the soft-tissue loads that come
/// with it (cheek raiser and lower-lid bulge AU6, buccal bulge, nasolabial fold); `lip_raise`
/// the levators (AU9/10); `lip_depress` the angular depressor (AU15); `brows` frontalis and
/// corrugator (AU1/2/4); `jaw` (AU26/27/29/30). Other names (user-defined muscles): `other`.
pub fn actuator_group(name: &str) -> &'static str {
    let groups: [(&str, &[&str]); 5] = [
        (
            "smile",
            &[
                "zygomatic_major",
                "cheek_raiser",
                "buccal_bulge",
                "infraorbital_bulge",
                "nasolabial_fold",
            ],
        ),
        ("lip_raise", &["labii_nasi", "inner_labii_nasi"]),
        ("lip_depress", &["angular_depressor"]),
        (
            "brows",
            &["frontalis", "secondary_frontalis", "lateral_corrugator"],
        ),
        ("jaw", &["jaw_"]),
    ];
    groups
        .iter()
        .find(|(_, prefixes)| prefixes.iter().any(|p| name.starts_with(p)))
        .map_or("other", |(g, _)| g)
}

/// Each group's share of a fit's motion ([`FitResult::contributions_mm`] squared and summed
/// per [`actuator_group`], normalised to 1); empty when nothing moved.
pub fn contribution_shares(
    names: &[String],
    contributions_mm: &[f64],
) -> std::collections::BTreeMap<&'static str, f64> {
    let total: f64 = contributions_mm.iter().map(|c| c * c).sum();
    let mut out = std::collections::BTreeMap::new();
    if total > 0.0 {
        for (name, c) in names.iter().zip(contributions_mm) {
            *out.entry(actuator_group(name)).or_insert(0.0) += c * c / total;
        }
    }
    out
}

/// Top of the residual maps' colour range (`fit-expression --residual-png`, the editor's fit
/// residual overlay), mm: a fit is good where it stays well below, scanner noise and
/// registration error are ~0.5–1.5 mm.
pub const RESIDUAL_MAX_MM: f64 = 5.0;

/// ICP pairs farther apart than this many times the median pair distance (but at least
/// [`ICP_TRIM_MIN_MM`]) are left out of a round.
const ICP_TRIM_FACTOR: f64 = 2.5;
const ICP_TRIM_MIN_MM: f64 = 1.0;

/// The RMS distance of `points` to the scan (`index`), over those within `max_mm` of it, and
/// how many those are.
fn part_rms(points: &[DVec3], index: &SurfaceIndex, max_mm: f64) -> (f64, usize) {
    let d: Vec<f64> = points
        .iter()
        .filter_map(|&p| index.closest(p, max_mm).map(|(d, _)| d))
        .collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len().max(1) as f64).sqrt();
    (rms, d.len())
}

pub(super) fn transform(mesh: &Mesh, t: &Similarity) -> Mesh {
    Mesh::new(
        mesh.positions_mm.iter().map(|&p| t.apply(p)).collect(),
        mesh.faces.clone(),
    )
}

/// Where the stable `vertices` should meet the expression scan: their `reference_mm`
/// positions, or with the neutral scan's index the neutral scan's points under them
/// (closest within [`FitParams::max_distance_mm`]; vertices off the scan are left out) moved
/// by the displacement `reference_mm` gives them (see [`align_scan`]).
fn stable_targets(
    model: &FaceModel,
    reference_mm: &[DVec3],
    neutral: Option<&SurfaceIndex>,
    vertices: &[usize],
    params: &FitParams,
) -> Vec<DVec3> {
    vertices
        .iter()
        .filter_map(|&v| {
            let rest = model.surface.positions_mm[v];
            match neutral {
                None => Some(reference_mm[v]),
                Some(index) => index
                    .closest(rest, params.max_distance_mm)
                    .map(|(_, c)| c + (reference_mm[v] - rest)),
            }
        })
        .collect()
}

/// The rigid transform that moves a scan (`scan_index`, its index) into the frame of `model`:
/// Horn on the stable landmarks if given, then ICP of the `stable` vertices
/// ([`Regions::stable`]) of `reference_mm` (the model surface, possibly already deformed by
/// the current expression estimate: one position per surface vertex).
///
/// With the neutral scan (`neutral`, its index) the ICP targets are the neutral scan's points
/// under the model's stable vertices (closest points, within [`FitParams::max_distance_mm`]),
/// moved by the same displacement `reference_mm` gives them: the expression scan is aligned
/// onto the neutral scan, two measurements of the same forehead and nose, and the
/// registration's own error there (1–2 mm on real scans) does not tilt it.
pub fn align_scan(
    model: &FaceModel,
    stable: &[usize],
    reference_mm: &[DVec3],
    neutral: Option<&SurfaceIndex>,
    scan_index: &SurfaceIndex,
    scan_landmarks: Option<&Landmarks>,
    params: &FitParams,
) -> Result<Similarity> {
    let targets = stable_targets(model, reference_mm, neutral, stable, params);
    // The scan stays where it is and the targets are taken into its frame: one index for all
    // rounds and both starts.
    let index = scan_index;
    let plain = icp(index, Similarity::IDENTITY, &targets, params);
    let best = match scan_landmarks {
        None => plain?.0,
        Some(lm) => {
            // Points that expressions barely move: the outer eye corners ride up with the
            // cheeks in a smile, and the forehead point is a border (hair line) estimate.
            let stable_points = [
                FeaturePoint::NoseTip,
                FeaturePoint::InnerEyeLeft,
                FeaturePoint::InnerEyeRight,
                FeaturePoint::NoseCornerLeft,
                FeaturePoint::NoseCornerRight,
            ];
            let from: Vec<DVec3> = stable_points.iter().map(|&p| lm.get(p)).collect();
            let to: Vec<DVec3> = stable_points
                .iter()
                .map(|&p| reference_mm[model.feature_vertices[p.index()] as usize])
                .collect();
            let t = horn_absolute_orientation(&from, &to, false)?;
            let started = icp(index, t, &targets, params);
            // Detected points can be wrong (a smile moves the nose corners, a failed detection
            // puts them anywhere): the start whose ICP ends nearer the stable parts wins.
            match (started, plain) {
                (Ok(a), Ok(b)) => {
                    if a.1 <= b.1 {
                        a.0
                    } else {
                        b.0
                    }
                }
                (Ok(a), Err(_)) => a.0,
                (Err(e), _) => return Err(e),
            }
        }
    };
    Ok(best)
}

/// Trimmed ICP of the scan (`index`, in its own frame) onto the stable `targets` (model
/// frame), from the scan-to-model transform `start`, [`FitParams::icp_rounds`] rounds: the
/// final transform and the RMS distance of all targets to the moved scan (a target with no
/// scan point within [`FitParams::max_distance_mm`] counts as that far), mm.
fn icp(
    index: &SurfaceIndex,
    start: Similarity,
    targets: &[DVec3],
    params: &FitParams,
) -> Result<(Similarity, f64)> {
    let mut to_model = start;
    for _ in 0..params.icp_rounds {
        let to_scan = to_model.inverse();
        let mut pairs = Vec::new();
        for &p in targets {
            if let Some((d, c)) = index.closest(to_scan.apply(p), params.max_distance_mm) {
                pairs.push((d, to_model.apply(c), p));
            }
        }
        // Trimmed ICP: pairs much farther apart than the typical one are hair, holes or
        // skin that the expression moved, and would drag the rigid fit.
        let mut ds: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let limit = if ds.is_empty() {
            0.0
        } else {
            let mid = ds.len() / 2;
            let median = *ds.select_nth_unstable_by(mid, f64::total_cmp).1;
            (ICP_TRIM_FACTOR * median).max(ICP_TRIM_MIN_MM)
        };
        let (from, to): (Vec<DVec3>, Vec<DVec3>) = pairs
            .iter()
            .filter(|p| p.0 <= limit)
            .map(|p| (p.1, p.2))
            .unzip();
        if from.len() < 10 {
            return Err(FemError::Definition(format!(
                "expression scan does not overlap the model's forehead and nose ({} points within {} mm); give --expression-landmarks",
                from.len(),
                params.max_distance_mm
            ))
            .into());
        }
        let t = horn_absolute_orientation(&from, &to, false)?;
        to_model = to_model.then(&t);
    }
    let to_scan = to_model.inverse();
    let max = params.max_distance_mm;
    let sum: f64 = targets
        .iter()
        .map(|&p| {
            let d = index.closest(to_scan.apply(p), max).map_or(max, |(d, _)| d);
            d * d
        })
        .sum();
    Ok((to_model, (sum / targets.len().max(1) as f64).sqrt()))
}

/// Per-activation ridge weights: `ridge` × each activation's diagonal entry of `G` (see
/// [`FitParams::ridge`]). Rescaling an activation's unit rescales its answer and nothing else.
/// A column the data cannot see has a zero diagonal, a zero row and `h = 0`: its activation
/// stays 0 without any ridge.
pub fn column_ridge(g: &[Vec<f64>], ridge: f64) -> Vec<f64> {
    (0..g.len()).map(|i| ridge * g[i][i]).collect()
}

/// Non-negative least squares `min ‖A a − b‖² + Σ ridgeᵢ aᵢ², a ≥ 0` from the normal
/// equations `G = AᵀA`, `h = Aᵀb` (projected Gauss–Seidel; converges for positive definite
/// `G + diag(ridge)`).
pub fn nnls(g: &[Vec<f64>], h: &[f64], ridge: &[f64]) -> Vec<f64> {
    let n = h.len();
    let mut a = vec![0.0; n];
    for _ in 0..5000 {
        let mut change: f64 = 0.0;
        for i in 0..n {
            let gii = g[i][i] + ridge[i];
            if !(gii > 0.0) {
                continue;
            }
            let r: f64 = h[i] - (0..n).map(|j| g[i][j] * a[j]).sum::<f64>() - ridge[i] * a[i];
            let new = (a[i] + r / gii).max(0.0);
            change = change.max((new - a[i]).abs());
            a[i] = new;
        }
        if change < 1e-12 {
            break;
        }
    }
    a
}

/// The model vertices a fit or a comparison uses: free (not fixed), within
/// [`FitParams::max_distance_mm`] of the aligned expression scan (`index`: holes and hair stay
/// out) and, with the neutral scan's index, within [`FitParams::max_neutral_error_mm`] of it
/// (where the registration reached the scan). Errors when fewer than 50 are left.
pub(super) fn vertices_on_scans(
    model: &FaceModel,
    index: &SurfaceIndex,
    neutral_index: Option<&SurfaceIndex>,
    params: &FitParams,
) -> Result<Vec<usize>> {
    let fixed = model.fixed_nodes();
    let vertices: Vec<usize> = (0..model.surface.vertex_count())
        .filter(|&v| {
            let p = model.surface.positions_mm[v];
            !fixed[v]
                && index.closest(p, params.max_distance_mm).is_some()
                && neutral_index
                    .is_none_or(|ni| ni.closest(p, params.max_neutral_error_mm).is_some())
        })
        .collect();
    if vertices.len() < 50 {
        return Err(FemError::Definition(format!(
            "only {} model vertices lie within {} mm of the expression scan",
            vertices.len(),
            params.max_distance_mm
        ))
        .into());
    }
    Ok(vertices)
}

/// The rigid motion `to_model` that aligned the scan, and how well the stable parts agree with
/// the aligned scan (`index`): the model's surface `surface_mm` (deformed by the expression
/// estimate) there, or with the neutral scan's index the neutral scan under it, as in
/// [`align_scan`]. Errors naming the parts farther than [`STABLE_PART_MAX_RMS_MM`].
pub(super) fn check_alignment(
    model: &FaceModel,
    regions: &Regions,
    surface_mm: &[DVec3],
    neutral: Option<&SurfaceIndex>,
    to_model: &Similarity,
    index: &SurfaceIndex,
    params: &FitParams,
) -> Result<Alignment> {
    let part = |vs: &[usize]| {
        let targets = stable_targets(model, surface_mm, neutral, vs, params);
        part_rms(&targets, index, params.max_distance_mm)
    };
    let (forehead_rms_mm, on_forehead) = part(&regions.forehead);
    let (nose_rms_mm, on_nose) = part(&regions.nose);
    let bad: Vec<String> = [
        ("forehead", forehead_rms_mm, on_forehead),
        ("nose", nose_rms_mm, on_nose),
    ]
    .iter()
    .filter(|(_, rms, on)| *rms > STABLE_PART_MAX_RMS_MM || *on == 0)
    .map(|(name, rms, on)| format!("{name} {rms:.1} mm RMS over {on} vertices"))
    .collect();
    if !bad.is_empty() {
        return Err(FemError::Definition(format!(
            "the expression scan's stable parts do not agree with the neutral face after the rigid fit ({}; at most {STABLE_PART_MAX_RMS_MM} mm): another person, hair or a hat over the forehead, or feature points detected in the wrong place",
            bad.join(", ")
        ))
        .into());
    }
    Ok(Alignment {
        rotation_deg: to_model.rotation.to_axis_angle().1.to_degrees(),
        translation_mm: to_model.translation_mm.to_array(),
        forehead_rms_mm,
        nose_rms_mm,
        stable_vertices_on_scan: on_forehead + on_nose,
    })
}

/// RMS distance (mm) of `vertices`, displaced by `displacement`, to the scan (`index`); a
/// vertex with no scan point within `max_mm` counts as `max_mm` away.
pub(super) fn rms_to_scan(
    model: &FaceModel,
    index: &SurfaceIndex,
    vertices: &[usize],
    displacement: &[DVec3],
    max_mm: f64,
) -> f64 {
    let mut sum = 0.0;
    let mut count = 0usize;
    for &v in vertices {
        let p = model.surface.positions_mm[v] + displacement[v];
        let d = index.closest(p, max_mm).map(|(d, _)| d).unwrap_or(max_mm);
        sum += d * d;
        count += 1;
    }
    (sum / count.max(1) as f64).sqrt()
}

/// Signed distance (mm) from each vertex of `surface` to `scan`: the closest-point distance,
/// positive where the scan lies in front of the surface (along the vertex normal), negative
/// behind it; `None` where no scan point lies within `max_mm` (holes, hair, outside the scan).
/// This is what the fit minimises, per vertex, so a map of it shows where a fit fails.
pub fn signed_residuals(surface: &Mesh, scan: &Mesh, max_mm: f64) -> Vec<Option<f64>> {
    let index = SurfaceIndex::new(scan, 4.0);
    surface
        .positions_mm
        .iter()
        .zip(&surface.normals)
        .map(|(&p, &n)| {
            index
                .closest(p, max_mm)
                .map(|(d, c)| if n.dot(c - p) < 0.0 { -d } else { d })
        })
        .collect()
}

/// Fits the muscle activations of `model` (basis computed) to an expression scan of the same
/// person (see the module docs). With `neutral_scan`, vertices the registration left off that
/// scan are not used. `presets` are compared to find the closest one.
pub fn fit_expression(
    model: &FaceModel,
    neutral_scan: Option<&Mesh>,
    expression_scan: &Mesh,
    scan_landmarks: Option<&Landmarks>,
    presets: &ExpressionSet,
    params: &FitParams,
) -> Result<FitResult> {
    if !model.has_basis() {
        return Err(FemError::Definition("fit needs the muscle basis".into()).into());
    }
    let n = model.surface.vertex_count();
    let neutral_index = neutral_scan.map(|m| SurfaceIndex::new(m, 4.0));
    let regions = Regions::of(&model.surface, &model.feature_vertices)?;
    let stable = regions.stable();
    let mut to_model = align_scan(
        model,
        &stable,
        &model.surface.positions_mm,
        neutral_index.as_ref(),
        &SurfaceIndex::new(expression_scan, 4.0),
        scan_landmarks,
        params,
    )?;
    let mut aligned = transform(expression_scan, &to_model);
    let mut index = SurfaceIndex::new(&aligned, 4.0);
    // Vertices the scan covers (checked on the neutral face; holes and hair stay out), and
    // that the registration put on the neutral scan.
    let vertices = vertices_on_scans(model, &index, neutral_index.as_ref(), params)?;
    let m = model.actuator_count();
    let basis: Vec<Vec<DVec3>> = (0..m)
        .map(|i| model.basis_displacement(i).expect("basis"))
        .collect();
    let zero = vec![DVec3::ZERO; n];
    let rms_before_mm = rms_to_scan(model, &index, &vertices, &zero, params.max_distance_mm);
    let rms_neutral_scan_mm = neutral_index
        .as_ref()
        .map(|ni| rms_to_scan(model, ni, &vertices, &zero, params.max_distance_mm));
    let mut best = (
        rms_before_mm,
        vec![0.0; model.actuator_count()],
        aligned.clone(),
        to_model,
    );
    let mut activations = vec![0.0; m];
    let mut u = vec![DVec3::ZERO; n];
    for round in 0..params.fit_rounds {
        if round > 0 {
            // Re-align on the stable region of the current estimate: expressions move the
            // forehead a little too, and aligning to the neutral face would bias the fit.
            let reference: Vec<DVec3> = (0..n)
                .map(|v| model.surface.positions_mm[v] + u[v])
                .collect();
            let t = align_scan(
                model,
                &stable,
                &reference,
                neutral_index.as_ref(),
                &index,
                None,
                params,
            )?;
            aligned = transform(&aligned, &t);
            to_model = to_model.then(&t);
            index = SurfaceIndex::new(&aligned, 4.0);
        }
        // Target displacement of each vertex: to its closest scan point from where it is now.
        let mut g = vec![vec![0.0; m]; m];
        let mut h = vec![0.0; m];
        for &v in &vertices {
            let p = model.surface.positions_mm[v] + u[v];
            let Some((_, c)) = index.closest(p, params.max_distance_mm) else {
                continue;
            };
            // Point-to-plane: only the offset along the surface normal is observable (a scan
            // cannot see skin sliding along itself), so tangential motion is left free.
            let normal = model.surface.normals[v];
            let target = normal.dot(c - model.surface.positions_mm[v]);
            let rows: Vec<f64> = (0..m).map(|i| normal.dot(basis[i][v])).collect();
            for i in 0..m {
                h[i] += rows[i] * target;
                for j in i..m {
                    let gij = rows[i] * rows[j];
                    g[i][j] += gij;
                    if i != j {
                        g[j][i] += gij;
                    }
                }
            }
        }
        activations = nnls(&g, &h, &column_ridge(&g, params.ridge));
        u = vec![DVec3::ZERO; n];
        for i in 0..m {
            for v in 0..n {
                u[v] += basis[i][v] * activations[i];
            }
        }
        let rms = rms_to_scan(model, &index, &vertices, &u, params.max_distance_mm);
        if rms < best.0 {
            best = (rms, activations.clone(), aligned.clone(), to_model);
        }
    }
    let (rms_after_mm, activations, aligned, to_model) = best;
    let index = SurfaceIndex::new(&aligned, 4.0);
    // How well the stable parts agree, on the fitted surface (the expression moves them a
    // little too).
    let fitted: Vec<DVec3> = {
        let mut w = Vec::new();
        model.combine_surface(&activations, &mut w)?;
        (0..n)
            .map(|v| model.surface.positions_mm[v] + w[v])
            .collect()
    };
    let alignment = check_alignment(
        model,
        &regions,
        &fitted,
        neutral_index.as_ref(),
        &to_model,
        &index,
        params,
    )?;
    // The moving part: below the eyes (a quarter of the face height above the nose tip) and
    // outside the nose part.
    let moving: Vec<usize> = {
        let s = &model.surface;
        let pos = |p: FeaturePoint| s.positions_mm[model.feature_vertices[p.index()] as usize];
        let frame = FaceFrame::new(pos)?;
        let tip = pos(FeaturePoint::NoseTip);
        let nose_set: std::collections::HashSet<usize> = regions.nose.iter().copied().collect();
        vertices
            .iter()
            .copied()
            .filter(|&v| {
                (s.positions_mm[v] - tip).dot(frame.y) < 0.25 * frame.scale_y_mm
                    && !nose_set.contains(&v)
            })
            .collect()
    };
    let fitted_u: Vec<DVec3> = (0..n)
        .map(|v| fitted[v] - model.surface.positions_mm[v])
        .collect();
    let moving_rms_before_mm = rms_to_scan(model, &index, &moving, &zero, params.max_distance_mm);
    let moving_rms_after_mm =
        rms_to_scan(model, &index, &moving, &fitted_u, params.max_distance_mm);
    let contributions_mm: Vec<f64> = basis
        .iter()
        .zip(&activations)
        .map(|(b, &a)| {
            let sum: f64 = vertices
                .iter()
                .map(|&v| (a * model.surface.normals[v].dot(b[v])).powi(2))
                .sum();
            (sum / vertices.len() as f64).sqrt()
        })
        .collect();
    let names: Vec<String> = model.actuator_names();
    let mut closest_preset: Option<(String, f64)> = None;
    let mut w = Vec::new();
    for e in &presets.expressions {
        let a = e.activations_for(&names)?;
        model.combine_surface(&a, &mut w)?;
        let rms = rms_to_scan(model, &index, &vertices, &w, params.max_distance_mm);
        if closest_preset.as_ref().is_none_or(|(_, best)| rms < *best) {
            closest_preset = Some((e.name.clone(), rms));
        }
    }
    Ok(FitResult {
        activations,
        rms_before_mm,
        rms_after_mm,
        rms_neutral_scan_mm,
        closest_preset,
        vertices_used: vertices.len(),
        aligned_scan: aligned,
        alignment,
        moving_rms_before_mm,
        moving_rms_after_mm,
        moving_vertices: moving.len(),
        contributions_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_residuals_see_a_scan_in_front_behind_and_missing() {
        let face = crate::generic_face::build().mesh;
        let along = |mm: f64| -> Mesh {
            let u: Vec<DVec3> = face.normals.iter().map(|&n| n * mm).collect();
            face.displaced(&u)
        };
        for offset in [1.5, -1.5] {
            let r = signed_residuals(&face, &along(offset), 8.0);
            let mut d: Vec<f64> = r.iter().map(|x| x.expect("within 8 mm")).collect();
            let right_side = d.iter().filter(|x| x.signum() == offset.signum()).count();
            assert!(
                right_side as f64 > 0.98 * d.len() as f64,
                "{offset}: {right_side}"
            );
            let mid = d.len() / 2;
            let median = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
            // A closest point on a curved offset surface is at most the offset away.
            assert!((median - offset).abs() < 0.05, "{offset}: median {median}");
        }
        let far = signed_residuals(&face, &along(20.0), 8.0);
        assert!(far.iter().filter(|x| x.is_some()).count() < face.vertex_count() / 20);
    }

    /// Every built-in actuator belongs to a named group (none falls to `other`), the smile
    /// group holds zygomatic major and the cheek loads, and the shares sum to 1.
    #[test]
    fn built_in_actuators_are_grouped_and_shares_sum_to_one() {
        let set = crate::fem::muscles::MuscleSet::builtin();
        let names = set.actuator_names();
        assert_eq!(names.len(), 30);
        for n in &names {
            assert_ne!(actuator_group(n), "other", "{n}");
        }
        assert_eq!(actuator_group("zygomatic_major_left"), "smile");
        assert_eq!(actuator_group("cheek_raiser_right"), "smile");
        assert_eq!(actuator_group("jaw_forward"), "jaw");
        assert_eq!(actuator_group("my_own_muscle"), "other");
        let c: Vec<f64> = (0..names.len()).map(|i| (i % 4) as f64 * 0.3).collect();
        let shares = contribution_shares(&names, &c);
        assert!(
            (shares.values().sum::<f64>() - 1.0).abs() < 1e-12,
            "{shares:?}"
        );
        assert!(contribution_shares(&names, &vec![0.0; names.len()]).is_empty());
    }

    #[test]
    fn nnls_recovers_a_non_negative_solution_and_clamps_negative_ones() {
        // G = I-ish, h chosen so the unconstrained optimum is (2, -1, 0.5).
        let g = vec![
            vec![2.0, 0.5, 0.0],
            vec![0.5, 1.0, 0.2],
            vec![0.0, 0.2, 1.5],
        ];
        let x = [2.0, -1.0, 0.5];
        let h: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| g[i][j] * x[j]).sum())
            .collect();
        let a = nnls(&g, &h, &vec![0.0; h.len()]);
        assert!(a.iter().all(|&v| v >= 0.0));
        assert_eq!(a[1], 0.0);
        // KKT: gradient zero on the free set, non-negative on the clamped one.
        let grad: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| g[i][j] * a[j]).sum::<f64>() - h[i])
            .collect();
        assert!(grad[0].abs() < 1e-9 && grad[2].abs() < 1e-9);
        assert!(grad[1] >= -1e-9);
    }

    #[test]
    fn the_ridge_does_not_depend_on_the_activations_units() {
        // Three columns; then the second measured in units 1000× smaller (degrees vs a force
        // multiple, say): G' = S G S, h' = S h. The answer must be S⁻¹ a, ridge included.
        let g = vec![
            vec![3.0, 1.0, 0.4],
            vec![1.0, 2.0, 0.3],
            vec![0.4, 0.3, 1.0],
        ];
        let h = vec![2.0, 1.5, 0.7];
        let scale = [1.0, 1e-3, 1.0];
        let gs: Vec<Vec<f64>> = (0..3)
            .map(|i| (0..3).map(|j| scale[i] * g[i][j] * scale[j]).collect())
            .collect();
        let hs: Vec<f64> = (0..3).map(|i| scale[i] * h[i]).collect();
        let ridge = 0.05;
        let a = nnls(&g, &h, &column_ridge(&g, ridge));
        let b = nnls(&gs, &hs, &column_ridge(&gs, ridge));
        for i in 0..3 {
            assert!((b[i] * scale[i] - a[i]).abs() < 1e-8, "{i}: {a:?} {b:?}");
        }
        // The ridge acts: the answer differs from the plain least-squares one.
        let plain = nnls(&g, &h, &[0.0; 3]);
        assert!((0..3).any(|i| (plain[i] - a[i]).abs() > 1e-3));
    }
}
