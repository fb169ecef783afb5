//! The per-scan pipeline every command shares (paper section 2.1): denoise → feature points
//! (detected, or given) → registration of the generic face. `register`, `synthesize`,
//! `export-fem`, `fit-expression` and the editor all go through here, so they agree.

use crate::denoise::{self, DenoiseParams};
use crate::generic_face::GenericFace;
use crate::landmarks::{self, LandmarkParams, LandmarkReport};
use crate::registration::{self, RegistrationParams, RegistrationResult};
use crate::{Error, Landmarks, Mesh, Result, io};
use std::path::Path;

/// Feature points the detector finds as borders of the face region rather than as anatomical
/// points (see [`prepare_mesh`]).
pub const BORDER_POINTS: [crate::FeaturePoint; 3] = crate::FeaturePoint::BORDER;

/// The points the registration is driven by. Detected cheek and forehead points are the face
/// region's borders (paper steps 7–8: where the cheek turns away, the hairline), not the
/// generic face's fixed cheek and forehead vertices; matching them stretches the generic face
/// past the scan, so with `detected` only the ten anatomical points are used. Points given by
/// the user (a file, or placed in the editor) are all used.
pub fn registration_points(
    landmarks: &Landmarks,
    detected: bool,
) -> Vec<(crate::FeaturePoint, glam::DVec3)> {
    landmarks
        .iter()
        .filter(|(p, _)| !detected || !BORDER_POINTS.contains(p))
        .collect()
}

/// A scan taken through the pre-processing steps.
#[derive(Debug, Clone)]
pub struct PreparedScan {
    /// The scan after denoising (what the landmarks and the registration used).
    pub denoised: Mesh,
    pub landmarks: Landmarks,
    /// The detector's report (Table 2 checks, warnings); `None` when the points were given.
    pub detection: Option<LandmarkReport>,
    pub registration: RegistrationResult,
}

/// Reads a landmark file (JSON: name → [x, y, z] mm, all 13 names).
pub fn read_landmarks(path: &Path) -> Result<Landmarks> {
    parse_landmarks(&io::read_text_file(path)?, path)
}

/// Parses a landmark file's text (`path` only names it in errors).
pub fn parse_landmarks(text: &str, path: &Path) -> Result<Landmarks> {
    serde_json::from_str(text)
        .map_err(|e| Error::syntax(path, e.line(), format!("not a landmark file: {e}")))
}

/// The scan's feature points: read from `given`, else detected on the (denoised) mesh.
pub fn scan_landmarks(
    denoised: &Mesh,
    given: Option<&Path>,
) -> Result<(Landmarks, Option<LandmarkReport>)> {
    match given {
        Some(path) => Ok((read_landmarks(path)?, None)),
        None => {
            let report = landmarks::detect(denoised, &LandmarkParams::default())?;
            Ok((report.landmarks, Some(report)))
        }
    }
}

/// Denoises `scan`, finds (or reads) its feature points and registers `generic` to it.
pub fn prepare_mesh(
    mut scan: Mesh,
    landmarks_file: Option<&Path>,
    generic: &GenericFace,
) -> Result<PreparedScan> {
    denoise::denoise(&mut scan, &DenoiseParams::default())?;
    let (points, detection) = scan_landmarks(&scan, landmarks_file)?;
    let registration = registration::register_points(
        generic,
        &scan,
        &registration_points(&points, detection.is_some()),
        &RegistrationParams::default(),
    )?;
    Ok(PreparedScan {
        denoised: scan,
        landmarks: points,
        detection,
        registration,
    })
}

/// [`prepare_mesh`] on a file; errors name the file.
pub fn prepare_scan(
    path: &Path,
    landmarks_file: Option<&Path>,
    generic: &GenericFace,
) -> Result<PreparedScan> {
    let mesh = io::read_mesh(path)?;
    prepare_mesh(mesh, landmarks_file, generic).map_err(|e| e.in_file(path))
}

// ---------------------------------------------------------------------------------------------
// Gallery augmentation (paper section 3: 18 synthetic expressions per neutral gallery scan)
// ---------------------------------------------------------------------------------------------

/// Settings of [`augment`].
#[derive(Debug, Clone)]
pub struct AugmentParams {
    /// A gallery scan is a mesh file whose stem ends with this (default `_frontal1`, the
    /// GavabDB neutral scan).
    pub gallery_suffix: String,
    /// `all` or a comma-separated list of preset names (default `all`: the 18 presets).
    pub expressions: String,
    /// The presets to choose from (default: the 18 built-ins; `augment --presets FILE` adds or
    /// replaces some, e.g. expressions learned with `fit-expression`).
    pub presets: crate::fem::expressions::ExpressionSet,
    /// Materials and layers of the FEM face (default: the paper's).
    pub fem: crate::fem::FemParams,
    /// The muscles (default: the built-in `assets/muscles.ron`; `augment --muscles FILE`).
    pub muscles: crate::fem::muscles::MuscleSet,
    /// Reach of the expression transfer onto the scan, mm (default 8: about three of the
    /// generic face's quads; see [`transfer_expression`]).
    pub transfer_radius_mm: f64,
    /// Each preset is also written at these multiples of its activations (default `[1]`:
    /// the presets as they are). A multiple other than 1 is written as `<name>_x<m>.ply`.
    pub intensities: Vec<f64>,
    /// Open-mouth laughs: for each angle (degrees), [`Self::laugh_base`] with the FEM jaw
    /// opened by that angle (`jaw_open`, on top of the preset's own), carried onto the scan,
    /// with the mouth's inside pushed back ([`mouth_cavity`]); written as `laugh_jaw<deg>.ply`.
    /// Default empty (the 18 presets only).
    pub jaw_open_deg: Vec<f64>,
    /// The FEM preset the laughs start from (default `broad_smile`).
    pub laugh_base: String,
    /// The open mouth's inside as the scanner sees it ([`mouth_cavity`]).
    pub cavity: CavityParams,
    /// Also write the FEM face's own surfaces (`face/*.obj`, for looking at). Default true.
    pub write_face_meshes: bool,
}

/// How deep the open mouth looks to the scanner ([`mouth_cavity`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CavityParams {
    /// Deepest point of the cavity, mm per degree of jaw opening (default 2.5: synth_gavab's
    /// laughs show a ~20–25 mm deep opening between the lips for ~5–9°). 0: none.
    pub depth_mm_per_deg: f64,
    /// How fast the cavity deepens inwards from the lips, mm of depth per mm of distance from
    /// the nearest lip (default 1.5: the inner lip and the teeth behind it).
    pub wall_slope: f64,
}

impl Default for CavityParams {
    fn default() -> Self {
        CavityParams {
            depth_mm_per_deg: 2.5,
            wall_slope: 1.5,
        }
    }
}

/// Pushes back the part of an expression-carrying scan that lies inside the FEM face's open
/// mouth. The neutral scan's lips are closed, so carrying an open jaw onto it stretches its
/// skin across the opening, where a real scan of an open mouth sees the inside of the mouth
/// (teeth, tongue, shadow) far behind the lips. Every scan vertex that falls, in the face plane,
/// inside the deformed mouth rim of `model` (the slit's boundary loop displaced by `u_mm`)
/// moves back along the face's forward axis by `min(depth, wall_slope × distance to the rim)`,
/// `depth = depth_mm_per_deg × jaw_deg`.
pub fn mouth_cavity(
    scan: &mut Mesh,
    model: &crate::fem::FaceModel,
    u_mm: &[glam::DVec3],
    jaw_deg: f64,
    params: &CavityParams,
) -> Result<()> {
    use glam::{DVec2, DVec3};
    let depth = params.depth_mm_per_deg * jaw_deg;
    if !(depth > 0.0) {
        return Ok(());
    }
    // The jaw resolved the lips' rim and the face's axes once for all expressions.
    let Some(jaw) = model.jaw().filter(|j| !j.mouth_rim.is_empty()) else {
        return Err(Error::algorithm(
            "augment",
            "the FEM face has no jaw or no mouth opening",
        ));
    };
    let surface = &model.surface;
    let rim = &jaw.mouth_rim;
    let plane = |p: DVec3| DVec2::new(p.dot(jaw.axis), p.dot(jaw.up));
    let polygon: Vec<DVec2> = rim
        .iter()
        .map(|&v| plane(surface.positions_mm[v as usize] + u_mm[v as usize]))
        .collect();
    let (lo, hi) = polygon.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    for q in &mut scan.positions_mm {
        let p = plane(*q);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            continue;
        }
        // Even-odd rule, and the distance to the nearest rim edge.
        let mut inside = false;
        let mut nearest = f64::INFINITY;
        for k in 0..polygon.len() {
            let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
            if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x) {
                inside = !inside;
            }
            let ab = b - a;
            let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
            nearest = nearest.min((a + ab * t).distance(p));
        }
        if inside {
            *q -= jaw.forward * depth.min(params.wall_slope * nearest);
        }
    }
    scan.update_normals();
    Ok(())
}

impl Default for AugmentParams {
    fn default() -> Self {
        AugmentParams {
            gallery_suffix: "_frontal1".into(),
            expressions: "all".into(),
            presets: crate::fem::expressions::ExpressionSet::builtin(),
            fem: crate::fem::FemParams::default(),
            muscles: crate::fem::muscles::MuscleSet::builtin(),
            transfer_radius_mm: 8.0,
            intensities: vec![1.0],
            jaw_open_deg: Vec::new(),
            laugh_base: "broad_smile".into(),
            cavity: CavityParams::default(),
            write_face_meshes: true,
        }
    }
}

/// What [`augment`] did with one gallery scan.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AugmentedScan {
    pub scan: std::path::PathBuf,
    /// `OUT/<stem>/`: one PLY per expression (the scan carrying it, scan frame, mm) and
    /// `face/` with the FEM face's own surfaces (`neutral.obj` + one OBJ per expression).
    pub dir: std::path::PathBuf,
    /// Finished by an earlier run with the same settings (its `done.json` records the same
    /// [`augment_recipe`]): skipped.
    pub resumed: bool,
    /// Finished by an earlier run with other settings: its samples were removed and made again.
    pub redone: bool,
    pub expressions: usize,
    pub landmark_warnings: usize,
    pub matched_fraction: f64,
    pub millis: f64,
}

/// A gallery scan that a step failed on, and why (the batch goes on).
#[derive(Debug, Clone, serde::Serialize)]
pub struct AugmentFailure {
    pub scan: std::path::PathBuf,
    /// The step that failed (`landmarks` for "no nose tip found", `fem` for a singular
    /// system, `input` for a bad file …).
    pub stage: crate::error::Stage,
    pub reason: String,
    /// The detected feature points were suspect ([`crate::landmarks::LandmarkReport::suspect`]):
    /// the scan was not augmented from them.
    pub suspect: bool,
}

/// Carries the FEM face's expression onto the scan itself: every scan vertex moves by the
/// displacement of the registered face near it (inverse-square-distance weights over the face
/// vertices within `radius_mm`), faded out linearly between `radius_mm / 2` and `radius_mm`
/// from the face (hair, ears and neck stay put).
///
/// Why: recognition trains on range images, and a synthetic sample made from the generic
/// face differs from the person's real scans in everything the generic face lacks (eyeballs,
/// skin detail, the hairline, scan holes) — LDA then learns "generic vs scan" instead of
/// "expression". Moving the scan itself keeps all of that and changes only the expression.
pub fn transfer_expression(
    scan: &Mesh,
    face_rest: &Mesh,
    displacement_mm: &[glam::DVec3],
    radius_mm: f64,
) -> Mesh {
    TransferWeights::new(scan, face_rest, radius_mm).apply(scan, displacement_mm)
}

/// The weights of [`transfer_expression`] for one scan and rest face, computed once and
/// applied to any number of displacement fields (augment carries 18+ expressions onto the same
/// scan; the neighbour search is the costly part).
#[derive(Debug, Clone)]
pub struct TransferWeights {
    /// Per scan vertex: start of its entries in `face_vertex` / `weight`.
    offsets: Vec<usize>,
    face_vertex: Vec<u32>,
    /// Normalised weight × fade.
    weight: Vec<f64>,
}

impl TransferWeights {
    pub fn new(scan: &Mesh, face_rest: &Mesh, radius_mm: f64) -> TransferWeights {
        use glam::DVec3;
        let cell = radius_mm.max(0.5);
        let key = |p: DVec3| {
            (
                (p.x / cell).floor() as i64,
                (p.y / cell).floor() as i64,
                (p.z / cell).floor() as i64,
            )
        };
        let mut grid: std::collections::HashMap<(i64, i64, i64), Vec<u32>> = Default::default();
        for (i, &p) in face_rest.positions_mm.iter().enumerate() {
            grid.entry(key(p)).or_default().push(i as u32);
        }
        let mut offsets = Vec::with_capacity(scan.vertex_count() + 1);
        let mut face_vertex = Vec::new();
        let mut weight = Vec::new();
        offsets.push(0);
        for &p in &scan.positions_mm {
            let (cx, cy, cz) = key(p);
            let start = face_vertex.len();
            let (mut total, mut nearest) = (0.0, f64::INFINITY);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(ids) = grid.get(&(cx + dx, cy + dy, cz + dz)) else {
                            continue;
                        };
                        for &i in ids {
                            let d = face_rest.positions_mm[i as usize].distance(p);
                            if d < radius_mm {
                                let w = 1.0 / (d * d + 0.25);
                                face_vertex.push(i);
                                weight.push(w);
                                total += w;
                                nearest = nearest.min(d);
                            }
                        }
                    }
                }
            }
            if total > 0.0 {
                let fade = ((radius_mm - nearest) / (radius_mm * 0.5)).clamp(0.0, 1.0);
                for w in &mut weight[start..] {
                    *w *= fade / total;
                }
            }
            offsets.push(face_vertex.len());
        }
        TransferWeights {
            offsets,
            face_vertex,
            weight,
        }
    }

    /// The scan moved by `displacement_mm` (one per rest-face vertex); normals recomputed.
    /// `scan` must be the mesh the weights were made for.
    pub fn apply(&self, scan: &Mesh, displacement_mm: &[glam::DVec3]) -> Mesh {
        let positions = scan
            .positions_mm
            .iter()
            .enumerate()
            .map(|(v, &p)| {
                let range = self.offsets[v]..self.offsets[v + 1];
                p + self.face_vertex[range.clone()]
                    .iter()
                    .zip(&self.weight[range])
                    .map(|(&i, &w)| {
                        displacement_mm.get(i as usize).copied().unwrap_or_default() * w
                    })
                    .sum::<glam::DVec3>()
            })
            .collect();
        let mut out = Mesh::new(positions, scan.faces.clone());
        out.update_normals();
        out
    }
}

/// Smooths away the folds a registration can leave in the surface (a quad turned over where
/// the projection jumps across a crease or a hole's rim): the vertices of every quad whose
/// corner normals disagree with the quad's smoothed normal by more than 90° (or whose corner
/// turns the wrong way) move to the mean of their neighbours, a few rounds, until none is
/// left. Returns the surface and how many vertices moved. Folded quads extrude into inverted
/// hexahedra, so the FEM needs this; elsewhere the surface is untouched.
pub fn unfold_surface(surface: &Mesh) -> (Mesh, usize) {
    const ROUNDS: usize = 30;
    let mut mesh = surface.clone();
    let topology = crate::mesh::Topology::new(&mesh);
    let mut moved = vec![false; mesh.vertex_count()];
    for _ in 0..ROUNDS {
        mesh.update_normals();
        let mut bad = Vec::new();
        for poly in mesh.faces.iter() {
            let n = poly.len();
            let avg: glam::DVec3 = poly.iter().map(|&v| mesh.normals[v as usize]).sum();
            let folded = (0..n).any(|k| {
                let p = |i: usize| mesh.positions_mm[poly[(k + i) % n] as usize];
                let corner = (p(1) - p(0)).cross(p(n - 1) - p(0));
                corner.dot(avg) <= 0.0
            });
            if folded {
                bad.extend(poly.iter().map(|&v| v as usize));
            }
        }
        if bad.is_empty() {
            break;
        }
        bad.sort_unstable();
        bad.dedup();
        let old = mesh.positions_mm.clone();
        for &v in &bad {
            let ring = topology.neighbours(v);
            if !ring.is_empty() {
                let sum: glam::DVec3 = ring.iter().map(|&u| old[u as usize]).sum();
                mesh.positions_mm[v] = sum / ring.len() as f64;
                moved[v] = true;
            }
        }
    }
    mesh.update_normals();
    (mesh, moved.iter().filter(|&&m| m).count())
}

/// What [`repaired_fem_model`] changed to get valid layers under a registered face (nothing on
/// the generic face: 0, 1, 0).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FemRepairs {
    /// Vertices [`unfold_surface`] moved.
    pub unfolded_vertices: usize,
    /// Layer thickness factor [`fem_model`] used (1 = as asked).
    pub layer_thickness_factor: f64,
    /// Local surface repairs [`fem_model`] made.
    pub local_surface_repairs: usize,
}

/// The FEM model of a registered face the way every command builds it: folds unfolded
/// ([`unfold_surface`]), then [`fem_model`]'s thinner layers or local repairs. The model's
/// `surface` is the repaired one.
pub fn repaired_fem_model(
    surface: &Mesh,
    feature_vertices: [u32; crate::FeaturePoint::COUNT],
    params: &crate::fem::FemParams,
) -> Result<(crate::fem::FaceModel, FemRepairs)> {
    let (mesh, unfolded_vertices) = unfold_surface(surface);
    let face = GenericFace {
        mesh,
        feature_vertices,
    };
    let (model, layer_thickness_factor, local_surface_repairs) = fem_model(&face, params)?;
    Ok((
        model,
        FemRepairs {
            unfolded_vertices,
            layer_thickness_factor,
            local_surface_repairs,
        },
    ))
}

/// Thickness factors tried, in order, when the layers invert under a registered face (a crease
/// or fold of the scan that even local thinning cannot follow).
const THICKNESS_FALLBACK: [f64; 3] = [1.0, 0.6, 0.35];

/// Local surface repairs [`fem_model`] tries when every thickness still inverts an element.
pub const SURFACE_REPAIRS: usize = 16;

/// The FEM model of a registered face. When the layers invert, they are made thinner (the
/// factors of `THICKNESS_FALLBACK`); when even the thinnest layers invert, the registered surface is
/// smoothed locally around the offending element (its corners' 2-ring, [`smooth_patch`]) and
/// everything is tried again, up to [`SURFACE_REPAIRS`] times. Why: the elements that still
/// invert sit on a surface quad that the registration has all but collapsed (a projection
/// across a hole's rim or a scan border; measured on seed 8: 8 of 61 gallery scans, minimum
/// Jacobians of −1e−2 … −1e−4 mm³ even at 0.35 of the thickness), which no thickness fixes.
/// Returns the model (its `surface` is the repaired one), the factor used (1 = the requested
/// thicknesses) and the number of surface repairs.
pub fn fem_model(
    face: &GenericFace,
    params: &crate::fem::FemParams,
) -> Result<(crate::fem::FaceModel, f64, usize)> {
    let mut surface = face.mesh.clone();
    let mut repairs = 0;
    loop {
        let face = GenericFace {
            mesh: surface.clone(),
            feature_vertices: face.feature_vertices,
        };
        let mut inverted = None;
        for factor in THICKNESS_FALLBACK {
            let mut p = *params;
            p.layers.skin_thickness_mm *= factor;
            p.layers.fat_thickness_mm *= factor;
            match crate::fem::FaceModel::from_generic(&face, &p) {
                Ok(model) => return Ok((model, factor, repairs)),
                Err(e @ Error::Fem(crate::FemError::InvertedElement { .. })) => inverted = Some(e),
                Err(e) => return Err(e),
            }
        }
        let Some(Error::Fem(crate::FemError::InvertedElement { element, .. })) = inverted else {
            unreachable!("at least one thickness was tried");
        };
        if repairs == SURFACE_REPAIRS {
            return Err(inverted.unwrap());
        }
        // The element's surface corners: its nodes modulo the surface vertex count (the
        // extrusion numbers nodes layer by layer, the element order does not depend on the
        // smoothing or thickness).
        let hex = crate::fem::layers::extrude(&surface, &params.layers)?;
        let n = surface.vertex_count();
        let Some(nodes) = hex.elements.get(element) else {
            return Err(inverted.unwrap());
        };
        let corners: Vec<usize> = nodes.iter().map(|&v| v as usize % n).collect();
        surface = smooth_patch(&surface, &corners, 2, 5);
        repairs += 1;
    }
}

/// Umbrella (Laplacian, λ = ½) smoothing of the vertices within `rings` edge hops of `seeds`,
/// `iterations` times; all other vertices stay put. Normals are recomputed.
pub fn smooth_patch(surface: &Mesh, seeds: &[usize], rings: usize, iterations: usize) -> Mesh {
    let topology = crate::mesh::Topology::new(surface);
    let n = surface.vertex_count();
    let inside = topology.within_rings(seeds, rings);
    let patch: Vec<usize> = (0..n).filter(|&v| inside[v]).collect();
    let mut mesh = surface.clone();
    for _ in 0..iterations {
        let old = mesh.positions_mm.clone();
        for &v in &patch {
            let ring = topology.neighbours(v);
            if !ring.is_empty() {
                let mean: glam::DVec3 =
                    ring.iter().map(|&u| old[u as usize]).sum::<glam::DVec3>() / ring.len() as f64;
                mesh.positions_mm[v] = 0.5 * (old[v] + mean);
            }
        }
    }
    mesh.update_normals();
    mesh
}

/// The marker a finished subject's folder gets last: a folder without it is unfinished and is
/// redone (its files may be from a killed run).
pub const DONE_MARKER: &str = "done.json";

/// Everything that decides what a subject's samples look like: the chosen presets (names
/// *and* activations: a `--presets` file may change a preset under the same name), their
/// intensities, the open-mouth laughs, the cavity, the FEM and the transfer settings. It is
/// recorded in [`DONE_MARKER`]; a resumed [`augment`] skips a subject only if its recorded
/// recipe is this one, and otherwise redoes it (samples made with other settings would be
/// mixed into one gallery without anyone noticing).
///
/// Errors (the settings' only check, so [`augment`] refuses them before any scan): an unknown
/// preset name, a negative or non-finite laugh angle.
pub fn augment_recipe(params: &AugmentParams) -> Result<serde_json::Value> {
    if let Some(bad) = params
        .jaw_open_deg
        .iter()
        .find(|d| !(d.is_finite() && **d >= 0.0))
    {
        return Err(Error::algorithm(
            "augment",
            format!(
                "jaw opening {bad}° (must be ≥ 0: a negative angle closes the jaw into the face)"
            ),
        ));
    }
    let chosen = params.presets.select(&params.expressions)?;
    let laugh = if params.jaw_open_deg.is_empty() {
        serde_json::Value::Null
    } else {
        let base = params.presets.select(&params.laugh_base)?;
        serde_json::json!({
            "base": base.first().map(|e| (&e.name, &e.activations)),
            "jaw_open_deg": params.jaw_open_deg,
        })
    };
    Ok(serde_json::json!({
        "presets": chosen.iter().map(|e| (&e.name, &e.activations)).collect::<Vec<_>>(),
        "intensities": params.intensities,
        "laughs": laugh,
        "cavity": params.cavity,
        "fem": params.fem,
        "muscles": params.muscles,
        "transfer_radius_mm": params.transfer_radius_mm,
    }))
}

/// Whether `dir` holds a finished augmentation made with `recipe` (its [`DONE_MARKER`] records
/// the same recipe).
fn finished_with(dir: &Path, recipe: &serde_json::Value) -> Finished {
    let Ok(text) = std::fs::read_to_string(dir.join(DONE_MARKER)) else {
        return Finished::No;
    };
    match serde_json::from_str::<serde_json::Value>(&text) {
        Ok(done) if done.get("recipe") == Some(recipe) => Finished::Same,
        _ => Finished::OtherSettings,
    }
}

enum Finished {
    No,
    Same,
    /// Finished with other settings (or by a version that did not record them).
    OtherSettings,
}

/// Empties a subject folder before it is (re)done: the marker first, so a run killed while
/// clearing leaves an unfinished folder, then the sample meshes directly in it (the folder is
/// `augment`'s own output; `face/` is overwritten as it is written). Without this, the samples
/// of presets the new run does not make would stay and be read as gallery samples.
fn clear_samples(dir: &Path) -> Result<()> {
    let marker = dir.join(DONE_MARKER);
    if marker.is_file() {
        std::fs::remove_file(&marker).map_err(|e| Error::io(&marker, e))?;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for p in entries.flatten().map(|e| e.path()) {
        if p.is_file() && io::MeshFormat::from_path(&p).is_ok() {
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
    }
    Ok(())
}

/// Removes the temporary files [`io::write_atomic`] leaves when a process is killed mid-write
/// (`.<name>.tmp-<pid>`). Best effort: a file that cannot be removed is left.
fn remove_stale_temp_files(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if name.starts_with('.') && name.contains(".tmp-") {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// The gallery scans of `dir` (sorted).
pub fn gallery_scans(dir: &Path, suffix: &str) -> Result<Vec<std::path::PathBuf>> {
    let mut out: Vec<_> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.file_stem()
                    .is_some_and(|s| s.to_string_lossy().ends_with(suffix))
                && io::MeshFormat::from_path(p).is_ok()
        })
        .collect();
    out.sort();
    Ok(out)
}

/// One gallery scan: denoise → landmarks → register → FEM → expressions, written into
/// `out_dir` atomically, `done.json` last.
pub fn augment_scan(
    scan: &Path,
    out_dir: &Path,
    generic: &GenericFace,
    params: &AugmentParams,
) -> Result<AugmentedScan> {
    let start = std::time::Instant::now();
    let presets = &params.presets;
    // Checked before the FEM work, so a bad name or angle fails at once, not after every
    // expression.
    let recipe = augment_recipe(params)?;
    let chosen = presets.select(&params.expressions)?;
    let laugh = if params.jaw_open_deg.is_empty() {
        None
    } else {
        Some(presets.select(&params.laugh_base)?)
    };
    let prepared = prepare_scan(scan, None, generic)?;
    let in_file = |e: Error| e.in_file(scan);
    // Suspect points would carry a wrong registration into 18 wrong expressions.
    if let Some(report) = prepared
        .detection
        .as_ref()
        .filter(|r| !r.suspect.is_empty())
    {
        return Err(in_file(Error::SuspectLandmarks {
            reasons: report.suspect.clone(),
        }));
    }
    let (mut model, repairs) = repaired_fem_model(
        &prepared.registration.mesh,
        generic.feature_vertices,
        &params.fem,
    )
    .map_err(in_file)?;
    model.factor().map_err(in_file)?;
    model.set_muscles(&params.muscles).map_err(in_file)?;
    model.compute_basis().map_err(in_file)?;
    // The gallery samples (the scan with each expression) go in `out_dir`, the FEM face's own
    // surfaces in `out_dir/face/` (for looking at; recognition reads only the top folder).
    let face_dir = out_dir.join("face");
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    // A killed run may have left temporary files; nothing reads them, but they would pile up.
    remove_stale_temp_files(out_dir);
    if params.write_face_meshes {
        std::fs::create_dir_all(&face_dir).map_err(|e| Error::io(&face_dir, e))?;
        remove_stale_temp_files(&face_dir);
        // The surface the FEM was built on (locally repaired where the layers inverted).
        io::write_mesh(&face_dir.join("neutral.obj"), &model.surface)?;
    }
    let names: Vec<String> = model.actuator_names();
    let open = names.iter().position(|n| n == "jaw_open");
    let mut figures = serde_json::Map::new();
    let mut u = Vec::new();
    let mut written = 0;
    let transfer = TransferWeights::new(
        &prepared.denoised,
        &model.surface,
        params.transfer_radius_mm,
    );
    let intensity_tag = |m: f64| {
        if m == 1.0 {
            String::new()
        } else {
            format!("_x{m}")
        }
    };
    for e in &chosen {
        let base = e.activations_for(&names)?;
        for &m in &params.intensities {
            let a: Vec<f64> = base.iter().map(|x| x * m).collect();
            model.combine_surface(&a, &mut u)?;
            let name = format!("{}{}", e.name, intensity_tag(m));
            if params.write_face_meshes {
                let mesh = model.surface.displaced(&u);
                io::write_mesh(&face_dir.join(format!("{name}.obj")), &mesh)?;
            }
            let mut on_scan = transfer.apply(&prepared.denoised, &u);
            if let Some(deg) = open.map(|k| a[k]).filter(|&d| d > 0.0) {
                mouth_cavity(&mut on_scan, &model, &u, deg, &params.cavity).map_err(in_file)?;
            }
            io::write_mesh(&out_dir.join(format!("{name}.ply")), &on_scan)?;
            written += 1;
            let max = u.iter().map(|d| d.length()).fold(0.0, f64::max);
            figures.insert(name, serde_json::json!({ "max_displacement_mm": max }));
        }
    }
    if let Some(laugh) = laugh {
        let mut a = laugh
            .first()
            .ok_or_else(|| Error::algorithm("augment", "no laugh base preset"))?
            .activations_for(&names)?;
        let open = open.ok_or_else(|| Error::algorithm("augment", "the muscle set has no jaw"))?;
        let base_deg = a[open];
        for &deg in &params.jaw_open_deg {
            a[open] = base_deg + deg;
            model.combine_surface(&a, &mut u)?;
            let mut on_scan = transfer.apply(&prepared.denoised, &u);
            mouth_cavity(&mut on_scan, &model, &u, a[open], &params.cavity).map_err(in_file)?;
            io::write_mesh(&out_dir.join(format!("laugh_jaw{deg}.ply")), &on_scan)?;
            written += 1;
        }
    }
    let result = AugmentedScan {
        scan: scan.to_path_buf(),
        dir: out_dir.to_path_buf(),
        resumed: false,
        redone: false,
        expressions: written,
        landmark_warnings: prepared.detection.as_ref().map_or(0, |d| d.warnings.len()),
        matched_fraction: prepared.registration.matched_fraction(),
        millis: start.elapsed().as_secs_f64() * 1e3,
    };
    let mut done = serde_json::to_value(&result).unwrap_or_default();
    done["layer_thickness_factor"] = serde_json::json!(repairs.layer_thickness_factor);
    done["unfolded_vertices"] = serde_json::json!(repairs.unfolded_vertices);
    done["surface_repairs"] = serde_json::json!(repairs.local_surface_repairs);
    done["expressions_mm"] = serde_json::Value::Object(figures);
    // What made the samples (presets, laughs' angles …), so a resumed run with other settings
    // can be told apart.
    done["recipe"] = recipe;
    done["landmarks"] = serde_json::to_value(prepared.landmarks).unwrap_or_default();
    io::write_text_atomic(
        &out_dir.join(DONE_MARKER),
        &(serde_json::to_string_pretty(&done).unwrap_or_default() + "\n"),
    )?;
    Ok(result)
}

/// Augments every gallery scan of `gallery` into `out/<stem>/`, in parallel. Resumable: a
/// subject whose folder has [`DONE_MARKER`] is skipped. A failed scan goes to the failure
/// list; the batch goes on. `progress` is called once before the first scan (0, total, line)
/// and after each scan (done count, total, line).
pub fn augment(
    gallery: &Path,
    out: &Path,
    params: &AugmentParams,
    progress: &(dyn Fn(usize, usize, &str) + Sync),
) -> Result<(Vec<AugmentedScan>, Vec<AugmentFailure>)> {
    use rayon::prelude::*;
    let scans = gallery_scans(gallery, &params.gallery_suffix)?;
    if scans.is_empty() {
        return Err(Error::InvalidData {
            path: gallery.to_path_buf(),
            message: format!(
                "no gallery scans (mesh files whose name ends with `{}`)",
                params.gallery_suffix
            ),
        });
    }
    // Checked once up front: a bad preset name or angle fails the batch, not every scan.
    let recipe = augment_recipe(params)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let generic = crate::generic_face::build();
    let total = scans.len();
    progress(0, total, &format!("{total} gallery scans"));
    let counter = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<std::result::Result<AugmentedScan, AugmentFailure>> = scans
        .par_iter()
        .map(|scan| {
            let stem = scan
                .file_stem()
                .map_or_else(|| "scan".into(), |s| s.to_string_lossy().into_owned());
            let dir = out.join(&stem);
            let finished = finished_with(&dir, &recipe);
            let redone = matches!(finished, Finished::OtherSettings);
            let r = if matches!(finished, Finished::Same) {
                Ok(AugmentedScan {
                    scan: scan.clone(),
                    dir,
                    resumed: true,
                    redone: false,
                    expressions: 0,
                    landmark_warnings: 0,
                    matched_fraction: f64::NAN,
                    millis: 0.0,
                })
            } else {
                clear_samples(&dir)
                    .and_then(|()| augment_scan(scan, &dir, &generic, params))
                    .map(|a| AugmentedScan { redone, ..a })
                    .map_err(|e| AugmentFailure {
                        scan: scan.clone(),
                        stage: e.stage(),
                        reason: e.to_string(),
                        suspect: e.is_suspect(),
                    })
            };
            let k = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            let line = match &r {
                Ok(a) if a.resumed => format!("{stem}: already done"),
                Ok(a) if a.redone => format!(
                    "{stem}: redone (the earlier run used other settings): {} expressions in {:.0} ms",
                    a.expressions, a.millis
                ),
                Ok(a) => format!(
                    "{stem}: {} expressions in {:.0} ms",
                    a.expressions, a.millis
                ),
                Err(f) => format!("{stem}: FAILED: {}", f.reason),
            };
            progress(k, total, &line);
            r
        })
        .collect();
    let mut done = Vec::new();
    let mut failed = Vec::new();
    for r in results {
        match r {
            Ok(a) => done.push(a),
            Err(f) => failed.push(f),
        }
    }
    let failures = serde_json::to_string_pretty(&failed).unwrap_or_default() + "\n";
    io::write_text_atomic(&out.join("failures.json"), &failures)?;
    Ok((done, failed))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A recorded recipe is read back as the same recipe, also for activations whose shortest
    /// decimal form a best-effort float parser reads one ulp off (fitted presets have such
    /// values; without exact parsing every resume would redo every subject).
    #[test]
    fn a_recorded_recipe_reads_back_as_the_same_recipe() {
        let mut params = AugmentParams::default();
        for (i, e) in params.presets.expressions.iter_mut().enumerate() {
            e.activations.insert(
                "zygomatic_major".into(),
                2.6739865357037638 + i as f64 * 0.1,
            );
        }
        let recipe = augment_recipe(&params).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let done = serde_json::json!({ "recipe": recipe });
        std::fs::write(
            dir.path().join(DONE_MARKER),
            serde_json::to_string_pretty(&done).unwrap(),
        )
        .unwrap();
        assert!(matches!(finished_with(dir.path(), &recipe), Finished::Same));
        // Another activation, or no recipe at all: other settings.
        params.presets.expressions[0]
            .activations
            .insert("zygomatic_major".into(), 2.673986535703764);
        let other = augment_recipe(&params).unwrap();
        assert!(matches!(
            finished_with(dir.path(), &other),
            Finished::OtherSettings
        ));
        std::fs::write(dir.path().join(DONE_MARKER), "{}").unwrap();
        assert!(matches!(
            finished_with(dir.path(), &recipe),
            Finished::OtherSettings
        ));
        std::fs::remove_file(dir.path().join(DONE_MARKER)).unwrap();
        assert!(matches!(finished_with(dir.path(), &recipe), Finished::No));
    }
}
