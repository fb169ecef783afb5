//! The per-scan pipeline every command shares (paper section 2.1): denoise → feature points
//! (detected, or given) → registration of the generic face. `register`, `synthesize`,
//! `export-fem`, `fit-expression` and the editor all go through here, so they agree.

use crate::denoise::{self, DenoiseParams};
use crate::generic_face::GenericFace;
use crate::landmarks::{self, LandmarkParams, LandmarkReport};
use crate::registration::{self, RegistrationParams, RegistrationResult};
use crate::{Error, Landmarks, Mesh, Result, io};
use std::path::Path;

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
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::Syntax {
        path: path.to_path_buf(),
        line: e.line(),
        message: format!("not a landmark file: {e}"),
    })
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
    let registration =
        registration::register(generic, &scan, &points, &RegistrationParams::default())?;
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
