//! The per-scan pipeline every command shares (paper section 2.1): denoise → feature points
//! (detected, or given) → registration of the generic face. `register`, `synthesize`,
//! `export-fem`, `fit-expression` and the editor all go through here, so they agree.

use crate::denoise::{self, DenoiseParams};
use crate::generic_face::GenericFace;
use crate::landmarks::{self, LandmarkParams, LandmarkReport};
use crate::registration::{self, RegistrationParams, RegistrationResult};
use crate::{Landmarks, Mesh, Result, io};
use std::path::Path;

mod face_region;
mod landmark_file;
mod review;
mod transfer;

pub use crate::fem::repair::{
    FemRepairs, MIN_QUAD_SCALED_JACOBIAN, SURFACE_REPAIRS, fem_model, quad_corner_quality,
    quad_scaled_jacobian, relax_skewed_quads, repaired_fem_model, smooth_patch, unfold_surface,
};
pub use landmark_file::{
    CORRECTION_SUFFIX, LandmarkFile, LandmarkSource, correction_for, correction_path,
    is_correction_file,
};
pub use review::{REVIEW_CACHE, ReviewEntry, ReviewQueue, ReviewState};
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
    /// The detector's report (Table 2 checks, warnings); `None` when the points were read.
    pub detection: Option<LandmarkReport>,
    /// The file the points were read from, and what it said; `None` when detected.
    pub given: Option<(std::path::PathBuf, LandmarkFile)>,
    pub registration: RegistrationResult,
    /// The unit the scan file was read in ([`prepare_scan`]); `None` when prepared from a mesh.
    pub units: Option<io::UnitsRead>,
}

impl PreparedScan {
    /// `detected`, `corrected` or `given`.
    pub fn landmark_source(&self) -> LandmarkSource {
        source_of(&self.given)
    }

    /// Why the detected points are suspect ([`LandmarkReport::suspect`]); empty where they
    /// are not, or were read from a file.
    pub fn suspect_reasons(&self) -> &[String] {
        suspect_of(&self.detection)
    }
}

fn suspect_of(detection: &Option<LandmarkReport>) -> &[String] {
    detection.as_ref().map_or(&[], |d| &d.suspect)
}

/// Says through [`io::notify`] (stderr in the CLI) that the points detected on `path` are
/// suspect, and why; nothing where `reasons` is empty. Returns the reasons, for the report. For the single-scan commands that go on
/// with them (`register`, `synthesize`, `export-fem`, `fit-expression`, `compare-expression`):
/// the user asked for that scan, and a false alarm must not block the work, but what is built
/// on wrong points is wrong. (`augment` refuses such a scan and `evaluate` poses it without
/// them; both list it.)
pub fn notify_suspect(path: &Path, reasons: &[String]) -> Vec<String> {
    if !reasons.is_empty() {
        io::notify(&format!(
            "{}: suspect feature points, so what is built on them may be wrong (move them in \
             `facesynth view`, which saves <scan>.landmarks.json beside the scan for every \
             command to use): {}",
            path.display(),
            reasons.join("; ")
        ));
    }
    reasons.to_vec()
}

/// Reads a landmark file ([`LandmarkFile`]: what `facesynth landmarks --json` and the
/// editor write, or a flat map name → [x, y, z] mm); all 13 names.
pub fn read_landmarks(path: &Path) -> Result<Landmarks> {
    Ok(LandmarkFile::read(path)?.landmarks)
}

/// Parses a landmark file's text, either shape of [`read_landmarks`] (`path` only names it in
/// errors).
pub fn parse_landmarks(text: &str, path: &Path) -> Result<Landmarks> {
    Ok(LandmarkFile::parse(text, path)?.landmarks)
}

/// A scan's feature points and where they came from.
pub struct ScanLandmarks {
    pub landmarks: Landmarks,
    pub detection: Option<LandmarkReport>,
    pub given: Option<(std::path::PathBuf, LandmarkFile)>,
}

/// Where points came from: the file's own source, or detection when no file was read.
fn source_of(given: &Option<(std::path::PathBuf, LandmarkFile)>) -> LandmarkSource {
    given
        .as_ref()
        .map_or(LandmarkSource::Detected, |(_, f)| f.source)
}

impl ScanLandmarks {
    /// `detected`, `corrected` or `given`.
    pub fn source(&self) -> LandmarkSource {
        source_of(&self.given)
    }

    /// [`PreparedScan::suspect_reasons`].
    pub fn suspect_reasons(&self) -> &[String] {
        suspect_of(&self.detection)
    }

    /// The points the registration matches ([`registration_points`]).
    pub fn registration_points(&self) -> Vec<(crate::FeaturePoint, glam::DVec3)> {
        let borders_detected = self
            .given
            .as_ref()
            .is_none_or(|(_, f)| f.borders_detected());
        registration_points(&self.landmarks, borders_detected)
    }
}

/// Denoises `mesh` and detects its feature points with the default settings, as the batch
/// commands do before registering (`evaluate`'s pose, the review queue).
pub fn detect_scan(mut mesh: Mesh) -> Result<LandmarkReport> {
    denoise::denoise(&mut mesh, &DenoiseParams::default())?;
    landmarks::detect(&mesh, &LandmarkParams::default())
}

/// An expression scan for fitting or comparing with a neutral one: read, denoised, and its
/// points read from `landmarks` (a bad file is an error) or detected (`None` when detection
/// fails: the rigid alignment then starts from the stable parts alone).
pub fn prepare_expression_scan(
    path: &Path,
    landmarks: Option<&Path>,
) -> Result<(Mesh, Option<ScanLandmarks>)> {
    let mut scan = crate::io::read_mesh(path)?;
    denoise::denoise(&mut scan, &DenoiseParams::default())?;
    let found = match scan_landmarks(&scan, landmarks) {
        Ok(found) => Some(found),
        Err(e) if landmarks.is_some() => return Err(e),
        Err(_) => None,
    };
    Ok((scan, found))
}

/// The scan's feature points: read from `given`, else detected on the (denoised) mesh.
pub fn scan_landmarks(denoised: &Mesh, given: Option<&Path>) -> Result<ScanLandmarks> {
    match given {
        Some(path) => {
            let file = LandmarkFile::read(path)?;
            Ok(ScanLandmarks {
                landmarks: file.landmarks,
                detection: None,
                given: Some((path.to_path_buf(), file)),
            })
        }
        None => {
            let report = landmarks::detect(denoised, &LandmarkParams::default())?;
            Ok(ScanLandmarks {
                landmarks: report.landmarks,
                detection: Some(report),
                given: None,
            })
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
    let points = scan_landmarks(&scan, landmarks_file)?;
    let registration = registration::register_points(
        generic,
        &scan,
        &points.registration_points(),
        &RegistrationParams::default(),
    )?;
    Ok(PreparedScan {
        denoised: scan,
        landmarks: points.landmarks,
        detection: points.detection,
        given: points.given,
        registration,
        units: None,
    })
}

/// [`prepare_mesh`] on a file; errors name the file. `landmarks_file`: the points to use
/// (see [`correction_for`]); `None` detects them.
pub fn prepare_scan(
    path: &Path,
    landmarks_file: Option<&Path>,
    generic: &GenericFace,
) -> Result<PreparedScan> {
    let (mesh, units) = io::read_mesh_and_units(path)?;
    let prepared = prepare_mesh(mesh, landmarks_file, generic).map_err(|e| e.in_file(path))?;
    Ok(PreparedScan {
        units: Some(units),
        ..prepared
    })
}

/// The gallery scans of `dir` (sorted).
pub fn gallery_scans(dir: &Path, suffix: &str) -> Result<Vec<std::path::PathBuf>> {
    let mut out = io::read_dir_sorted(dir)?;
    out.retain(|p| {
        p.is_file()
            && p.file_stem()
                .is_some_and(|s| s.to_string_lossy().ends_with(suffix))
            && io::MeshFormat::from_path(p).is_ok()
    });
    Ok(out)
}
