//! The per-scan pipeline every command shares (paper section 2.1): denoise → feature points
//! (detected, or given) → registration of the generic face. `register`, `synthesize`,
//! `export-fem`, `fit-expression` and the editor all go through here, so they agree.

use crate::denoise::{self, DenoiseParams};
use crate::generic_face::GenericFace;
use crate::landmarks::{self, LandmarkParams, LandmarkReport};
use crate::registration::{self, RegistrationParams, RegistrationResult};
use crate::{Error, Landmarks, Mesh, Result, io};
use std::path::Path;

mod augment;
mod fem_model;
mod transfer;

pub use augment::{
    AugmentFailure, AugmentParams, AugmentedScan, DONE_MARKER, augment, augment_recipe,
    augment_scan, gallery_scans,
};
pub use fem_model::{
    FemRepairs, SURFACE_REPAIRS, fem_model, repaired_fem_model, smooth_patch, unfold_surface,
};
pub use transfer::{CavityParams, TransferWeights, mouth_cavity, transfer_expression};

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
        .filter(|(p, _)| !detected || !crate::FeaturePoint::BORDER.contains(p))
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

/// Reads a landmark file: what `facesynth landmarks --json` writes (the points under
/// `"landmarks"`, beside its checks) or a flat map, name → [x, y, z] mm; all 13 names.
pub fn read_landmarks(path: &Path) -> Result<Landmarks> {
    parse_landmarks(&io::read_text_file(path)?, path)
}

/// Parses a landmark file's text, either shape of [`read_landmarks`] (`path` only names it in
/// errors).
pub fn parse_landmarks(text: &str, path: &Path) -> Result<Landmarks> {
    let value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| Error::syntax(path, e.line(), format!("not a landmark file: {e}")))?;
    let points = match value.get("landmarks") {
        Some(inner) if inner.is_object() => inner.clone(),
        _ => value,
    };
    serde_json::from_value(points)
        .map_err(|e| Error::invalid(path, format!("not a landmark file: {e}")))
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
