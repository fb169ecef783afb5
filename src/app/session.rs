//! Scripted editor sessions: `facesynth view --session FILE.ron` runs a list of [`Step`]s in one
//! window, one after the other, each when the previous one (and the worker) has finished, and
//! takes screenshots between them. The steps are what a person does in the panels and they go
//! through the same [`Command`]s the panels emit (a slider step is a checkpoint plus the new
//! activations, exactly as a slider drag), so a session shows the real editor in one sitting.
//!
//! The file is a RON list, e.g.
//! ```ron
//! [
//!     Open("../shared/data/gavabdb/cara1_frontal1.wrl"),
//!     Denoise,
//!     Show(Denoise),
//!     Screenshot("shots/01_denoise.png"),
//!     Erase(at_mm: (60.0, 10.0, -40.0), radius_mm: 8.0),
//!     SaveScan("shots/cara1_frontal1_clean.ply"),
//!     NudgeLandmark(point: "mouth_corner_left", offset_mm: (0.0, 3.0, 0.0)),
//!     Activation(muscle: "zygomatic_major_left", value: 1.5, mirror: true),
//!     Undo,
//! ]
//! ```
//! Relative paths are taken from the current directory.

use super::document::{Command, Document};
use crate::feature_points::FeaturePoint;
use crate::view_options::{LayersShown, Overlay};
use glam::DVec3;
use std::path::{Path, PathBuf};

/// One step of a session.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
pub enum Step {
    /// Open a scan.
    Open(PathBuf),
    /// Run the denoising filter with its default parameters.
    Denoise,
    /// Show the original scan instead of the denoised one (the before/after toggle).
    ShowOriginal(bool),
    /// One click of the erase brush at the working scan's vertex nearest a point (mm, scan
    /// frame): an undo step erasing the vertices within `radius_mm` of it.
    Erase {
        at_mm: (f64, f64, f64),
        radius_mm: f64,
    },
    /// Bring every erased vertex back.
    RestoreErased,
    /// Write the working scan (denoised, erased vertices gone).
    SaveScan(PathBuf),
    DetectLandmarks,
    /// Move a feature point by an offset (mm, scan frame), snapped to the nearest vertex of the
    /// working scan: what a click on the surface does.
    NudgeLandmark {
        point: String,
        offset_mm: (f64, f64, f64),
    },
    LoadLandmarks(PathBuf),
    SaveLandmarks(PathBuf),
    Register,
    BuildFem,
    /// Young's modulus of the skin layer, Pa (the Materials panel).
    SkinModulus(f64),
    /// One activation slider; with `mirror`, the other side's too (the panel's mirror link).
    Activation {
        muscle: String,
        value: f64,
        mirror: bool,
    },
    ApplyPreset(String),
    /// Store the current activations as a preset of this name.
    StorePreset(String),
    SavePresets(PathBuf),
    LoadPresets(PathBuf),
    FitExpression(PathBuf),
    ExportExpression(PathBuf),
    Undo,
    Redo,
    /// What the viewport colours by.
    Show(Overlay),
    /// Which FEM layers are drawn.
    Layers(LayersShown),
    /// Muscle arrows on or off.
    Muscles(bool),
    /// The scan under the registered face on or off.
    ShowScan(bool),
    /// Camera angles, degrees.
    Camera {
        yaw_deg: f64,
        pitch_deg: f64,
    },
    /// Build the review queue of a folder and open its worst scan.
    Review(PathBuf),
    /// The review queue's next / previous scan (moved points are saved as the correction).
    ReviewNext,
    ReviewPrevious,
    /// Open exactly these side-panel sections (`denoise`, `landmarks`, `registration`,
    /// `materials`, `muscles`, `expressions`, `view`), so a screenshot shows that panel.
    Panels(Vec<String>),
    /// Save the window as a PNG once everything before has finished.
    Screenshot(PathBuf),
}

/// Reads a session file.
pub fn load(path: &Path) -> crate::Result<Vec<Step>> {
    let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io(path, e))?;
    parse(&text).map_err(|e| crate::Error::invalid(path, e))
}

/// Parses the text of a session file.
pub fn parse(text: &str) -> Result<Vec<Step>, String> {
    ron::from_str(text).map_err(|e| format!("not a session (a RON list of steps): {e}"))
}

/// What the app does with a step.
#[derive(Debug, Clone)]
pub enum Action {
    /// Document commands, applied in order.
    Commands(Vec<Command>),
    /// A change of the view options or camera.
    View(ViewChange),
    Screenshot(PathBuf),
}

/// View changes a session can make.
#[derive(Debug, Clone, PartialEq)]
pub enum ViewChange {
    Show(Overlay),
    Layers(LayersShown),
    Muscles(bool),
    ShowScan(bool),
    ShowOriginal(bool),
    Camera { yaw_deg: f64, pitch_deg: f64 },
    Panels(Vec<String>),
}

impl Step {
    /// Turns the step into what the app does, given the document as it is when the step runs
    /// (a nudge starts from the current point, a slider from the current activations).
    pub fn action(&self, doc: &Document) -> Result<Action, String> {
        use Command as C;
        let commands = |c: Vec<Command>| Ok(Action::Commands(c));
        match self {
            Step::Open(p) => commands(vec![C::Open(Some(p.clone()))]),
            Step::Denoise => commands(vec![C::Denoise(Default::default())]),
            Step::ShowOriginal(b) => Ok(Action::View(ViewChange::ShowOriginal(*b))),
            Step::Erase { at_mm, radius_mm } => {
                let mesh = doc.working_mesh().ok_or("no scan is open")?;
                let centre_mm = nearest_vertex(mesh, DVec3::from(*at_mm))?;
                commands(vec![
                    C::Checkpoint,
                    C::Erase {
                        centre_mm,
                        radius_mm: *radius_mm,
                    },
                ])
            }
            Step::RestoreErased => commands(vec![C::RestoreErased]),
            Step::SaveScan(p) => commands(vec![C::SaveScan(p.clone())]),
            Step::DetectLandmarks => commands(vec![C::DetectLandmarks]),
            Step::NudgeLandmark { point, offset_mm } => {
                let p = FeaturePoint::from_name(point)
                    .ok_or_else(|| format!("no feature point named {point:?}"))?;
                let landmarks = doc
                    .edits
                    .landmarks
                    .as_ref()
                    .ok_or("no landmarks to move yet (detect or load them first)")?;
                let mesh = doc.working_mesh().ok_or("no scan is open")?;
                let target = landmarks.get(p) + DVec3::from(*offset_mm);
                commands(vec![C::MoveLandmark(p, nearest_vertex(mesh, target)?)])
            }
            Step::LoadLandmarks(p) => commands(vec![C::LoadLandmarks(p.clone())]),
            Step::SaveLandmarks(p) => commands(vec![C::SaveLandmarks(p.clone())]),
            Step::Register => commands(vec![C::Register]),
            Step::BuildFem => commands(vec![C::BuildFem]),
            Step::SkinModulus(pa) => {
                let mut fem = doc.edits.fem;
                fem.skin.young_modulus_pa = *pa;
                commands(vec![C::Checkpoint, C::SetFemParams(fem)])
            }
            Step::Activation {
                muscle,
                value,
                mirror,
            } => {
                // Muscles and the jaw's actuators alike.
                if !doc.edits.muscles.actuator_names().contains(muscle) {
                    return Err(format!("no muscle or jaw actuator named {muscle:?}"));
                }
                let mut a = doc.edits.activations.clone();
                a.insert(muscle.clone(), *value);
                if *mirror && let Some(other) = mirrored(muscle) {
                    a.insert(other, *value);
                }
                a.retain(|_, v| *v != 0.0);
                commands(vec![C::Checkpoint, C::SetActivations(a)])
            }
            Step::ApplyPreset(n) => commands(vec![C::ApplyPreset(n.clone())]),
            Step::StorePreset(n) => commands(vec![C::StorePreset {
                name: n.clone(),
                description: "stored in a scripted editor session".into(),
            }]),
            Step::SavePresets(p) => commands(vec![C::SavePresets(p.clone())]),
            Step::LoadPresets(p) => commands(vec![C::LoadPresets(p.clone())]),
            Step::FitExpression(p) => commands(vec![C::FitExpression(p.clone())]),
            Step::ExportExpression(p) => commands(vec![C::ExportExpression(p.clone())]),
            Step::Review(dir) => commands(vec![C::Review(dir.clone())]),
            Step::ReviewNext => commands(vec![C::ReviewNext]),
            Step::ReviewPrevious => commands(vec![C::ReviewPrevious]),
            Step::Undo => commands(vec![C::Undo]),
            Step::Redo => commands(vec![C::Redo]),
            Step::Show(o) => Ok(Action::View(ViewChange::Show(*o))),
            Step::Layers(l) => Ok(Action::View(ViewChange::Layers(*l))),
            Step::Muscles(b) => Ok(Action::View(ViewChange::Muscles(*b))),
            Step::ShowScan(b) => Ok(Action::View(ViewChange::ShowScan(*b))),
            Step::Camera { yaw_deg, pitch_deg } => Ok(Action::View(ViewChange::Camera {
                yaw_deg: *yaw_deg,
                pitch_deg: *pitch_deg,
            })),
            Step::Panels(names) => {
                if let Some(bad) = names
                    .iter()
                    .find(|n| !super::panels::SECTIONS.contains(&n.as_str()))
                {
                    return Err(format!(
                        "no side-panel section {bad:?} (one of {})",
                        super::panels::SECTIONS.join(", ")
                    ));
                }
                Ok(Action::View(ViewChange::Panels(names.clone())))
            }
            Step::Screenshot(p) => Ok(Action::Screenshot(p.clone())),
        }
    }
}

/// The mesh's vertex nearest `target`, mm (what a click on the surface there picks).
fn nearest_vertex(mesh: &crate::Mesh, target: DVec3) -> Result<DVec3, String> {
    mesh.positions_mm
        .iter()
        .copied()
        .min_by(|a, b| {
            a.distance_squared(target)
                .total_cmp(&b.distance_squared(target))
        })
        .ok_or_else(|| "the scan has no vertices".to_string())
}

/// `x_left` ↔ `x_right`; none for the jaw's actuators (`jaw_left` and `jaw_right` are
/// opposite shifts, so mirroring one onto the other would cancel it).
pub fn mirrored(muscle: &str) -> Option<String> {
    if crate::fem::jaw::ACTUATORS.contains(&muscle) {
        return None;
    }
    if let Some(base) = muscle.strip_suffix("_left") {
        Some(format!("{base}_right"))
    } else {
        muscle
            .strip_suffix("_right")
            .map(|base| format!("{base}_left"))
    }
}
