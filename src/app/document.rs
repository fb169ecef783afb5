//! The editor's document: what the user loaded, computed and edited, and the commands that
//! change it. No egui here: panels emit [`Command`]s, [`Document::apply`] turns them into state
//! changes and worker [`Job`]s, [`Document::receive`] takes the worker's results. So the whole
//! edit logic (loading, landmark moves, undo, registration) is testable without a window.

use super::jobs::{
    DenoiseState, DetectionState, FemState, FitState, Job, JobResult, RegistrationState,
    ReviewProgress, ScanState,
};
use super::undo::History;
use crate::denoise::DenoiseParams;
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::fem::FemParams;
use crate::fem::expressions::{Expression, ExpressionSet};
use crate::fem::muscles::MuscleSet;
use crate::generic_face::GenericFace;
use crate::{Mesh, io};
use glam::DVec3;
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Arc;

mod corrections;
mod receive;
mod review;
mod state;

pub use review::Review;
pub use state::*;

/// What a panel or the command line asks the document to do.
#[derive(Debug, Clone)]
pub enum Command {
    /// Open a scan; `None` shows the generic face alone.
    Open(Option<PathBuf>),
    Denoise(DenoiseParams),
    /// Drop the denoised scan and work on the original again.
    ClearDenoise,
    /// Erase the working scan's vertices within `radius_mm` of a point (mm). No undo step of
    /// its own: a click or a brush stroke sends [`Command::Checkpoint`] first, so a stroke over
    /// many frames is one step.
    Erase {
        centre_mm: DVec3,
        radius_mm: f64,
    },
    /// Bring every erased vertex back (one undo step).
    RestoreErased,
    /// Write the working scan (denoised, erased vertices gone) as .obj/.ply (atomic), to feed
    /// the corrected scan to the batch commands.
    SaveScan(PathBuf),
    /// Detect the 13 feature points on the working scan (denoise first for real scans).
    DetectLandmarks,
    /// Place one feature point (snapped to the surface by the caller).
    MoveLandmark(FeaturePoint, DVec3),
    /// Move a feature point during a drag: no undo step of its own (the drag's start sends
    /// [`Command::Checkpoint`], so the whole drag is one step).
    DragLandmark(FeaturePoint, DVec3),
    SetLandmarks(Box<Landmarks>),
    LoadLandmarks(PathBuf),
    /// Write the points as a landmark file (`source`, `scan`, `corrected`, `landmarks`).
    SaveLandmarks(PathBuf),
    /// Write them as the scan's correction file (`<stem>.landmarks.json` beside it, or in the
    /// `--landmarks-dir`), which every batch command then uses.
    SaveCorrection,
    /// Build the review queue of a folder (detection on the worker, cached) and open its worst
    /// scan.
    Review(PathBuf),
    /// Open the review queue's next / previous / n-th scan (writing the open one's correction
    /// if its points were moved).
    ReviewNext,
    ReviewPrevious,
    ReviewGo(usize),
    /// Register the generic face to the working scan with the current landmarks.
    Register,
    /// Write the registered generic face (.obj/.ply).
    ExportRegistered(PathBuf),
    /// Build (or rebuild) the layered FEM model on the registered face, or the generic face.
    BuildFem,
    /// Store the current edits as one undo step (sent when a slider drag starts).
    Checkpoint,
    /// New materials / layer thicknesses: the worker refactors (or re-extrudes).
    SetFemParams(FemParams),
    /// New muscle definitions: the worker re-solves the basis with the cached factor.
    SetMuscles(MuscleSet),
    /// New activations: a 30-term sum (muscles, soft-tissue loads, jaw) on the UI thread, no solve.
    SetActivations(BTreeMap<String, f64>),
    /// Set the activations to a preset's.
    ApplyPreset(String),
    /// Activations = Σ weight × preset activations.
    BlendPresets(Vec<(String, f64)>),
    /// Back to the preset last applied (or neutral).
    RevertActivations,
    /// Store the current activations as a new (or replaced) preset.
    StorePreset {
        name: String,
        description: String,
    },
    /// Write the presets to a RON file (atomic).
    SavePresets(PathBuf),
    /// Add the presets of a RON file.
    LoadPresets(PathBuf),
    /// Learn an expression from a scan of the same person: fit the activations, apply them.
    FitExpression(PathBuf),
    /// Write the current expression's skin surface (.obj/.ply).
    ExportExpression(PathBuf),
    /// Write every preset's surface into a folder (`<name>.obj`, plus `neutral.obj`).
    ExportAllExpressions(PathBuf),
    Undo,
    Redo,
}

/// Everything the editor holds besides view options.
pub struct Document {
    pub generic: Arc<GenericFace>,
    pub scan: Option<ScanState>,
    pub denoised: Option<DenoiseState>,
    /// The (denoised) scan without the erased vertices; `None` without a scan.
    pub working: Option<WorkingScan>,
    /// Rebuilds of the working scan so far (the next [`WorkingScan::id`]).
    working_count: u64,
    /// The working scan each running detection / registration job was sent with, and the one
    /// the current result was computed on.
    detect_sent_on: u64,
    register_sent_on: u64,
    detected_on: u64,
    registered_on: u64,
    pub detection: Option<DetectionState>,
    pub registration: Option<RegistrationState>,
    pub fem: Option<FemState>,
    /// The last expression learned from a scan.
    pub fit: Option<FitState>,
    /// The FEM inputs changed while a solve was running: send again when it returns.
    fem_dirty: bool,
    /// The user asked for the FEM model (it then follows every edit).
    fem_enabled: bool,
    /// Bumped on every registration, so the FEM model knows its surface changed.
    registration_count: u64,
    pub edits: Edits,
    pub history: History<Edits>,
    /// Bumped whenever a mesh or overlay changes, so the viewport re-uploads.
    pub version: u64,
    /// Jobs sent to the worker and not yet answered.
    pub pending: Vec<&'static str>,
    /// The last error (worker or command), shown in the side panel.
    pub error: Option<String>,
    /// A short note of the last thing done ("saved …").
    pub status: Option<String>,
    /// A name the expressions panel offers for "store as preset" (e.g. the fitted scan's).
    pub preset_name_hint: Option<String>,
    /// The edits as last loaded or saved, part by part: what [`Document::unsaved`] compares
    /// against (so undoing back to the saved state counts as saved again).
    saved: Edits,
    /// Where the feature points started (the detection as a `detected` file, or the file
    /// loaded); the points moved since are the corrections ([`Document::landmark_file`]).
    pub landmark_origin: Option<crate::pipeline::LandmarkFile>,
    /// Folder of correction files (`view --landmarks-dir`); `None`: beside the scan.
    pub landmarks_dir: Option<PathBuf>,
    /// The review queue, once built.
    pub review: Option<Review>,
    /// The queue's detection while it runs.
    pub review_progress: Option<Arc<ReviewProgress>>,
    /// Points for the scan being opened (the review queue's detection), used when it has no
    /// correction file.
    pending_points: Option<crate::pipeline::LandmarkFile>,
    /// Edits from an autosave, put back once the scan it was made on has loaded.
    pending_restore: Option<Edits>,
    /// The autosave's denoising, run again once its scan has loaded.
    pending_denoise: Option<DenoiseParams>,
}

/// A part of the edits that can be unsaved (see [`Document::unsaved`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Saved by `SaveLandmarks` (JSON).
    Landmarks,
    /// Saved by `SavePresets` (RON).
    Presets,
    /// The activation sliders: saved with the presets (store them as a preset first).
    Activations,
    /// Materials and layer thicknesses: no file of their own; kept by the autosave.
    Materials,
    /// Muscle definitions: no file of their own in the editor; kept by the autosave.
    Muscles,
    /// Vertices erased by hand: saved by `SaveScan` (the corrected scan).
    Scan,
}

impl Part {
    pub fn name(self) -> &'static str {
        match self {
            Part::Landmarks => "landmarks",
            Part::Presets => "presets",
            Part::Activations => "activations",
            Part::Materials => "materials",
            Part::Muscles => "muscles",
            Part::Scan => "erased vertices (the scan)",
        }
    }
}

impl Document {
    pub fn new(generic: GenericFace) -> Self {
        let landmarks = Some(generic.landmarks());
        Document {
            generic: Arc::new(generic),
            scan: None,
            denoised: None,
            working: None,
            working_count: 0,
            detect_sent_on: 0,
            register_sent_on: 0,
            detected_on: 0,
            registered_on: 0,
            detection: None,
            registration: None,
            fem: None,
            fit: None,
            fem_dirty: false,
            fem_enabled: false,
            registration_count: 0,
            edits: Edits {
                landmarks,
                ..Edits::default()
            },
            saved: Edits {
                landmarks,
                ..Edits::default()
            },
            landmark_origin: None,
            landmarks_dir: None,
            review: None,
            review_progress: None,
            pending_points: None,
            pending_restore: None,
            pending_denoise: None,
            history: History::new(200),
            version: 0,
            pending: Vec::new(),
            error: None,
            status: None,
            preset_name_hint: None,
        }
    }

    /// The parts edited since they were last loaded or saved (empty: nothing to lose).
    pub fn unsaved(&self) -> Vec<Part> {
        let (e, s) = (&self.edits, &self.saved);
        let mut out = Vec::new();
        if e.landmarks != s.landmarks {
            out.push(Part::Landmarks);
        }
        if e.presets != s.presets {
            out.push(Part::Presets);
        }
        if e.activations != s.activations || e.applied_preset != s.applied_preset {
            out.push(Part::Activations);
        }
        if e.fem != s.fem {
            out.push(Part::Materials);
        }
        if e.muscles != s.muscles {
            out.push(Part::Muscles);
        }
        if e.erased != s.erased {
            out.push(Part::Scan);
        }
        out
    }

    /// Any edit since the last load or save.
    pub fn is_dirty(&self) -> bool {
        self.edits != self.saved
    }

    /// Counts everything as saved (the user chose to discard the changes).
    pub fn mark_all_saved(&mut self) {
        self.saved = self.edits.clone();
    }

    /// Puts a saved state (an autosave) back: re-opens `scan` (the edits follow once it has
    /// loaded, denoised with `denoise` if given) or, with no scan, restores the edits at once.
    /// The restored edits count as unsaved.
    pub fn restore_saved(
        &mut self,
        scan: Option<&std::path::Path>,
        edits: Edits,
        denoise: Option<DenoiseParams>,
    ) -> Vec<Job> {
        match scan {
            Some(path) => {
                self.pending_restore = Some(edits);
                self.pending_denoise = denoise;
                self.apply(Command::Open(Some(path.to_path_buf())))
            }
            None => {
                let mut jobs = self.apply(Command::Open(None));
                self.history.checkpoint(&self.edits);
                jobs.extend(self.restore(edits));
                jobs
            }
        }
    }

    /// The mesh the pipeline works on: the denoised scan if there is one, else the scan, less
    /// the vertices erased by hand.
    pub fn working_mesh(&self) -> Option<&Arc<Mesh>> {
        self.working.as_ref().map(|w| &w.mesh)
    }

    /// Builds the working scan again after the scan, the denoising or the erased set changed.
    fn rebuild_working(&mut self) {
        self.version += 1;
        self.working_count += 1;
        let Some(scan) = &self.scan else {
            self.working = None;
            return;
        };
        let (base, ids) = match &self.denoised {
            Some(d) => (&d.mesh, d.report.kept.clone()),
            None => (&scan.mesh, (0..scan.mesh.vertex_count() as u32).collect()),
        };
        let erased = &self.edits.erased;
        let mut removed: Vec<bool> = ids.iter().map(|v| erased.contains(v)).collect();
        let (mesh, input_ids) = if !removed.contains(&true) {
            (base.clone(), ids)
        } else {
            // A vertex whose faces were all erased goes too (a stray point would otherwise
            // stay behind in the saved scan); points the scan had without faces stay.
            crate::denoise::removal::add_orphans(&base.faces, &mut removed);
            let keep: Vec<bool> = removed.iter().map(|r| !r).collect();
            let mut mesh = (**base).clone();
            let kept = mesh.retain_vertices(&keep);
            let input_ids = kept.iter().map(|&v| ids[v as usize]).collect();
            (Arc::new(mesh), input_ids)
        };
        self.working = Some(WorkingScan {
            mesh,
            input_ids,
            id: self.working_count,
        });
    }

    fn working_id(&self) -> u64 {
        self.working.as_ref().map_or(0, |w| w.id)
    }

    /// The detection was run on the working scan as it is now (its shape index fits it).
    pub fn detection_current(&self) -> bool {
        self.detection.is_some() && self.detected_on == self.working_id()
    }

    /// True while the worker has something to do.
    pub fn busy(&self) -> bool {
        !self.pending.is_empty()
    }

    /// The registration was computed from other landmarks (or another working scan) than the
    /// current.
    pub fn registration_stale(&self) -> bool {
        let scan_changed = self.registered_on != self.working_id();
        match (&self.registration, &self.edits.landmarks) {
            (Some(r), Some(l)) => r.landmarks != *l || scan_changed,
            (Some(_), None) => true,
            _ => false,
        }
    }

    /// Applies a command; returns the jobs to run on the worker.
    fn place_landmark(&mut self, point: FeaturePoint, to_mm: DVec3) -> Vec<Job> {
        let mut landmarks = self.edits.landmarks.unwrap_or_else(|| {
            // No landmarks yet: start from the generic face's, moved onto the scan later one
            // by one.
            self.generic.landmarks()
        });
        landmarks.set(point, to_mm);
        self.edits.landmarks = Some(landmarks);
        self.version += 1;
        Vec::new()
    }

    pub fn apply(&mut self, command: Command) -> Vec<Job> {
        self.error = None;
        match command {
            Command::Open(path) => match path {
                Some(p) => {
                    self.pending.push("loading");
                    vec![Job::Load(p)]
                }
                None => {
                    self.scan = None;
                    self.denoised = None;
                    self.detection = None;
                    self.registration = None;
                    self.edits.landmarks = Some(self.generic.landmarks());
                    self.saved.landmarks = self.edits.landmarks;
                    self.landmark_origin = None;
                    self.edits.erased.clear();
                    self.saved.erased.clear();
                    self.rebuild_working();
                    self.history.clear();
                    if self.fem.as_ref().is_some_and(|f| f.surface_id != 0) {
                        self.fem_job()
                    } else {
                        Vec::new()
                    }
                }
            },
            Command::Denoise(params) => match &self.scan {
                Some(scan) => {
                    self.pending.push("denoising");
                    vec![Job::Denoise {
                        mesh: scan.mesh.clone(),
                        params,
                    }]
                }
                None => self.fail("open a scan first"),
            },
            Command::ClearDenoise => {
                self.denoised = None;
                self.rebuild_working();
                Vec::new()
            }
            Command::Erase {
                centre_mm,
                radius_mm,
            } => {
                let Some(w) = &self.working else {
                    return self.fail("open a scan first");
                };
                let r2 = radius_mm * radius_mm;
                let before = self.edits.erased.len();
                self.edits.erased.extend(
                    w.mesh
                        .positions_mm
                        .iter()
                        .zip(&w.input_ids)
                        .filter(|(x, _)| x.distance_squared(centre_mm) <= r2)
                        .map(|(_, &v)| v),
                );
                if self.edits.erased.len() != before {
                    self.rebuild_working();
                }
                Vec::new()
            }
            Command::RestoreErased => {
                if !self.edits.erased.is_empty() {
                    self.history.checkpoint(&self.edits);
                    self.edits.erased.clear();
                    self.rebuild_working();
                }
                Vec::new()
            }
            Command::SaveScan(path) => {
                let Some(mesh) = self.working_mesh() else {
                    return self.fail("open a scan first");
                };
                match io::write_mesh(&path, mesh) {
                    Ok(()) => {
                        self.saved.erased = self.edits.erased.clone();
                        self.status = Some(format!("wrote {}", path.display()));
                    }
                    Err(e) => self.error = Some(e.to_string()),
                }
                Vec::new()
            }
            Command::DetectLandmarks => match self.working_mesh() {
                Some(mesh) => {
                    let job = Job::DetectLandmarks { mesh: mesh.clone() };
                    self.detect_sent_on = self.working_id();
                    self.pending.push("detecting");
                    vec![job]
                }
                None => self.fail("open a scan first"),
            },
            Command::MoveLandmark(point, to_mm) => {
                self.history.checkpoint(&self.edits);
                self.place_landmark(point, to_mm)
            }
            Command::DragLandmark(point, to_mm) => self.place_landmark(point, to_mm),
            Command::SetLandmarks(landmarks) => {
                self.history.checkpoint(&self.edits);
                self.edits.landmarks = Some(*landmarks);
                self.version += 1;
                Vec::new()
            }
            Command::LoadLandmarks(path) => self.load_landmark_file(&path),
            Command::SaveLandmarks(path) => {
                self.save_landmark_file(&path);
                Vec::new()
            }
            Command::Review(dir) => self.start_review(dir),
            Command::ReviewNext | Command::ReviewPrevious => {
                let current = self.review.as_ref().and_then(|r| r.current);
                match (command, current) {
                    (Command::ReviewNext, Some(i)) => self.review_go(i + 1),
                    (Command::ReviewPrevious, Some(0)) => {
                        self.status = Some("start of the review queue".into());
                        Vec::new()
                    }
                    (Command::ReviewPrevious, Some(i)) => self.review_go(i - 1),
                    _ => self.review_go(0),
                }
            }
            Command::ReviewGo(i) => self.review_go(i),
            Command::SaveCorrection => {
                match self.correction_path() {
                    Some(path) => self.save_landmark_file(&path),
                    None => self.error = Some("no scan: nothing to correct".into()),
                }
                Vec::new()
            }
            Command::Register => {
                let (Some(mesh), Some(landmarks)) = (self.working_mesh(), &self.edits.landmarks)
                else {
                    return self.fail("registration needs a scan and its 13 feature points");
                };
                // Detected cheek/forehead borders are left out, as in the pipeline, unless the
                // user has placed them (then they are meant as the generic face's points).
                let border_detected = self.borders_detected();
                let job = Job::Register {
                    generic: self.generic.clone(),
                    scan: mesh.clone(),
                    landmarks: Box::new(*landmarks),
                    borders_detected: border_detected,
                };
                self.register_sent_on = self.working_id();
                self.pending.push("registering");
                vec![job]
            }
            Command::ExportRegistered(path) => {
                let Some(r) = &self.registration else {
                    return self.fail("nothing registered yet");
                };
                match io::write_mesh(&path, &r.result.mesh) {
                    Ok(()) => self.status = Some(format!("wrote {}", path.display())),
                    Err(e) => self.error = Some(e.to_string()),
                }
                Vec::new()
            }
            Command::BuildFem => {
                self.fem_enabled = true;
                self.fem_job()
            }
            Command::Checkpoint => {
                self.history.checkpoint(&self.edits);
                Vec::new()
            }
            Command::SetFemParams(params) => {
                self.edits.fem = params;
                self.fem_job()
            }
            Command::SetMuscles(muscles) => {
                self.edits.muscles = muscles;
                self.fem_job()
            }
            Command::SetActivations(a) => {
                self.edits.activations = a;
                self.version += 1;
                Vec::new()
            }
            Command::ApplyPreset(name) => match self.preset_activations(&name) {
                Ok(a) => {
                    self.history.checkpoint(&self.edits);
                    self.edits.activations = a;
                    self.edits.applied_preset = Some(name);
                    self.version += 1;
                    Vec::new()
                }
                Err(e) => self.fail(e),
            },
            Command::BlendPresets(weights) => {
                let mut out: BTreeMap<String, f64> = BTreeMap::new();
                for (name, w) in &weights {
                    match self.preset_activations(name) {
                        Ok(a) => {
                            for (k, v) in a {
                                *out.entry(k).or_default() += w * v;
                            }
                        }
                        Err(e) => return self.fail(e),
                    }
                }
                self.edits.activations = out;
                self.version += 1;
                Vec::new()
            }
            Command::RevertActivations => {
                self.history.checkpoint(&self.edits);
                self.edits.activations = match self.edits.applied_preset.clone() {
                    Some(name) => self.preset_activations(&name).unwrap_or_default(),
                    None => BTreeMap::new(),
                };
                self.version += 1;
                Vec::new()
            }
            Command::StorePreset { name, description } => {
                let name = name.trim().to_string();
                if name.is_empty() {
                    return self.fail("a preset needs a name");
                }
                self.history.checkpoint(&self.edits);
                let activations = self
                    .edits
                    .activations
                    .iter()
                    .filter(|(_, a)| **a != 0.0)
                    .map(|(k, a)| (k.clone(), *a))
                    .collect();
                self.edits.presets.merge(ExpressionSet {
                    expressions: vec![Expression {
                        name: name.clone(),
                        description,
                        action_units: Vec::new(),
                        activations,
                    }],
                });
                self.edits.applied_preset = Some(name.clone());
                self.status = Some(format!("stored preset {name}"));
                Vec::new()
            }
            Command::SavePresets(path) => {
                let pretty = ron::ser::PrettyConfig::new();
                match ron::ser::to_string_pretty(&self.edits.presets, pretty) {
                    Ok(text) => match io::write_text_atomic(&path, &(text + "\n")) {
                        Ok(()) => {
                            // The sliders count as saved with the presets they were stored in.
                            self.saved.presets = self.edits.presets.clone();
                            self.saved.activations = self.edits.activations.clone();
                            self.saved.applied_preset = self.edits.applied_preset.clone();
                            self.status = Some(format!("saved {}", path.display()));
                        }
                        Err(e) => self.error = Some(e.to_string()),
                    },
                    Err(e) => self.error = Some(format!("{}: {e}", path.display())),
                }
                Vec::new()
            }
            Command::LoadPresets(path) => match ExpressionSet::load(&path) {
                Ok(set) => {
                    self.history.checkpoint(&self.edits);
                    // Loaded presets are not unsaved work, but earlier unsaved ones still are.
                    let clean = self.edits.presets == self.saved.presets;
                    self.edits.presets.merge(set);
                    if clean {
                        self.saved.presets = self.edits.presets.clone();
                    }
                    self.status = Some(format!("loaded {}", path.display()));
                    Vec::new()
                }
                Err(e) => self.fail(e.to_string()),
            },
            Command::FitExpression(path) => {
                if self.fem.is_none() {
                    return self.fail("build the FEM model first");
                }
                self.pending.push("fitting");
                vec![Job::FitExpression {
                    scan: path,
                    neutral: self.working_mesh().cloned(),
                    presets: self.edits.presets.clone(),
                }]
            }
            Command::ExportExpression(path) => {
                let Some(fem) = &self.fem else {
                    return self.fail("build the FEM model first");
                };
                let mesh = fem.deformed_surface(&self.edits.activations);
                match io::write_mesh(&path, &mesh) {
                    Ok(()) => self.status = Some(format!("wrote {}", path.display())),
                    Err(e) => self.error = Some(e.to_string()),
                }
                Vec::new()
            }
            Command::ExportAllExpressions(dir) => {
                let Some(fem) = &self.fem else {
                    return self.fail("build the FEM model first");
                };
                if let Err(e) = std::fs::create_dir_all(&dir) {
                    return self.fail(format!("{}: cannot create: {e}", dir.display()));
                }
                let mut written = 0;
                let neutral = (*fem.surface).clone();
                if let Err(e) = io::write_mesh(&dir.join("neutral.obj"), &neutral) {
                    return self.fail(e.to_string());
                }
                for name in self.edits.presets.names() {
                    let a = match self.preset_activations(name) {
                        Ok(a) => a,
                        Err(e) => return self.fail(e),
                    };
                    let mesh = fem.deformed_surface(&a);
                    if let Err(e) = io::write_mesh(&dir.join(format!("{name}.obj")), &mesh) {
                        return self.fail(e.to_string());
                    }
                    written += 1;
                }
                self.status = Some(format!("wrote {written} expressions to {}", dir.display()));
                Vec::new()
            }
            Command::Undo => {
                if let Some(previous) = self.history.undo(&self.edits) {
                    self.restore(previous)
                } else {
                    Vec::new()
                }
            }
            Command::Redo => {
                if let Some(next) = self.history.redo(&self.edits) {
                    self.restore(next)
                } else {
                    Vec::new()
                }
            }
        }
    }

    /// Restores an undo/redo snapshot; the FEM model follows changed materials or muscles, the
    /// working scan the erased vertices.
    fn restore(&mut self, edits: Edits) -> Vec<Job> {
        let fem_changed = edits.fem != self.edits.fem || edits.muscles != self.edits.muscles;
        let erased_changed = edits.erased != self.edits.erased;
        self.edits = edits;
        self.version += 1;
        if erased_changed {
            self.rebuild_working();
        }
        if fem_changed {
            self.fem_job()
        } else {
            Vec::new()
        }
    }

    /// Which surface the FEM model is built on: 0 = the generic face, else the registration.
    pub fn fem_surface_id(&self) -> u64 {
        if self.registration.is_some() {
            self.registration_count
        } else {
            0
        }
    }

    /// The FEM job for the current inputs, or none while one is running (it is sent again
    /// when that one returns: slider drags do not queue up stale solves).
    fn fem_job(&mut self) -> Vec<Job> {
        if !self.fem_enabled {
            return Vec::new();
        }
        if self.pending.contains(&"solving") {
            self.fem_dirty = true;
            return Vec::new();
        }
        self.fem_dirty = false;
        let (surface, feature_vertices) = match &self.registration {
            Some(r) => (
                Arc::new(r.result.mesh.clone()),
                self.generic.feature_vertices,
            ),
            None => (
                Arc::new(self.generic.mesh.clone()),
                self.generic.feature_vertices,
            ),
        };
        self.pending.push("solving");
        vec![Job::Fem {
            surface,
            surface_id: self.fem_surface_id(),
            feature_vertices,
            params: self.edits.fem,
            muscles: Box::new(self.edits.muscles.clone()),
        }]
    }

    /// A preset's activations by muscle name (pair names expanded to both sides).
    fn preset_activations(&self, name: &str) -> Result<BTreeMap<String, f64>, String> {
        let preset = self
            .edits
            .presets
            .get(name)
            .ok_or_else(|| format!("no preset named `{name}`"))?;
        let names = self.edits.muscles.actuator_names();
        let a = preset.activations_for(&names).map_err(|e| e.to_string())?;
        Ok(names
            .into_iter()
            .zip(a)
            .filter(|(_, a)| *a != 0.0)
            .collect())
    }

    fn fail(&mut self, message: impl Into<String>) -> Vec<Job> {
        self.error = Some(message.into());
        Vec::new()
    }
}
