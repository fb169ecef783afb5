//! The editor's document: what the user loaded, computed and edited, and the commands that
//! change it. No egui here: panels emit [`Command`]s, [`Document::apply`] turns them into state
//! changes and worker [`Job`]s, [`Document::receive`] takes the worker's results. So the whole
//! edit logic (loading, landmark moves, undo, registration) is testable without a window.

use super::undo::History;
use super::worker::{Job, JobResult};
use crate::denoise::{DenoiseParams, DenoiseReport};
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::generic_face::GenericFace;
use crate::mesh::FaceCounts;
use crate::registration::RegistrationResult;
use crate::{Mesh, io};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A loaded input scan.
#[derive(Debug, Clone)]
pub struct ScanState {
    pub name: String,
    pub path: PathBuf,
    pub mesh: Arc<Mesh>,
    pub counts: FaceCounts,
    pub bbox_mm: (DVec3, DVec3),
    pub load_millis: f64,
}

/// The scan after the denoising filter.
#[derive(Debug, Clone)]
pub struct DenoiseState {
    pub params: DenoiseParams,
    pub mesh: Arc<Mesh>,
    pub report: DenoiseReport,
    /// Vertices the filter moved by more than [`SPIKE_MM`]: the long peaks it removed.
    pub spikes: Vec<u32>,
    pub millis: f64,
}

/// A move larger than this counts as a removed spike (scanner noise is ~0.15 mm).
pub const SPIKE_MM: f64 = 2.0;

/// The generic face registered to the scan.
#[derive(Debug, Clone)]
pub struct RegistrationState {
    pub result: Arc<RegistrationResult>,
    /// Per registered vertex: distance to the scan surface, mm (NaN: unmatched, filled).
    pub distance_mm: Vec<f64>,
    /// The landmarks it was computed from (to tell when it is out of date).
    pub landmarks: Landmarks,
}

/// The part of the document that undo/redo restores.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Edits {
    /// The scan's 13 feature points (or the generic face's when no scan is loaded).
    pub landmarks: Option<Landmarks>,
}

/// What a panel or the command line asks the document to do.
#[derive(Debug, Clone)]
pub enum Command {
    /// Open a scan; `None` shows the generic face alone.
    Open(Option<PathBuf>),
    Denoise(DenoiseParams),
    /// Drop the denoised scan and work on the original again.
    ClearDenoise,
    /// Place one feature point (snapped to the surface by the caller).
    MoveLandmark(FeaturePoint, DVec3),
    SetLandmarks(Box<Landmarks>),
    LoadLandmarks(PathBuf),
    SaveLandmarks(PathBuf),
    /// Register the generic face to the working scan with the current landmarks.
    Register,
    /// Write the registered generic face (.obj/.ply).
    ExportRegistered(PathBuf),
    Undo,
    Redo,
}

/// Everything the editor holds besides view options.
pub struct Document {
    pub generic: Arc<GenericFace>,
    pub scan: Option<ScanState>,
    pub denoised: Option<DenoiseState>,
    pub registration: Option<RegistrationState>,
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
}

impl Document {
    pub fn new(generic: GenericFace) -> Self {
        let landmarks = Some(generic.landmarks());
        Document {
            generic: Arc::new(generic),
            scan: None,
            denoised: None,
            registration: None,
            edits: Edits { landmarks },
            history: History::new(200),
            version: 0,
            pending: Vec::new(),
            error: None,
            status: None,
        }
    }

    /// The mesh the pipeline works on: the denoised scan if there is one, else the scan.
    pub fn working_mesh(&self) -> Option<&Arc<Mesh>> {
        self.denoised
            .as_ref()
            .map(|d| &d.mesh)
            .or(self.scan.as_ref().map(|s| &s.mesh))
    }

    /// True while the worker has something to do.
    pub fn busy(&self) -> bool {
        !self.pending.is_empty()
    }

    /// The registration was computed from other landmarks (or another scan) than the current.
    pub fn registration_stale(&self) -> bool {
        match (&self.registration, &self.edits.landmarks) {
            (Some(r), Some(l)) => r.landmarks != *l,
            (Some(_), None) => true,
            _ => false,
        }
    }

    /// Applies a command; returns the jobs to run on the worker.
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
                    self.registration = None;
                    self.edits.landmarks = Some(self.generic.landmarks());
                    self.history.clear();
                    self.version += 1;
                    Vec::new()
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
                self.version += 1;
                Vec::new()
            }
            Command::MoveLandmark(point, to_mm) => {
                let mut landmarks = self.edits.landmarks.unwrap_or_else(|| {
                    // No landmarks yet: start from the generic face's, moved onto the scan
                    // later one by one.
                    self.generic.landmarks()
                });
                self.history.checkpoint(&self.edits);
                landmarks.set(point, to_mm);
                self.edits.landmarks = Some(landmarks);
                self.version += 1;
                Vec::new()
            }
            Command::SetLandmarks(landmarks) => {
                self.history.checkpoint(&self.edits);
                self.edits.landmarks = Some(*landmarks);
                self.version += 1;
                Vec::new()
            }
            Command::LoadLandmarks(path) => match read_landmarks(&path) {
                Ok(l) => {
                    self.status = Some(format!("loaded {}", path.display()));
                    self.apply(Command::SetLandmarks(Box::new(l)))
                }
                Err(e) => self.fail(e),
            },
            Command::SaveLandmarks(path) => {
                let Some(l) = &self.edits.landmarks else {
                    return self.fail("no landmarks to save");
                };
                let text = serde_json::to_string_pretty(l).unwrap_or_default() + "\n";
                match io::write_text_atomic(&path, &text) {
                    Ok(()) => self.status = Some(format!("saved {}", path.display())),
                    Err(e) => self.error = Some(e.to_string()),
                }
                Vec::new()
            }
            Command::Register => {
                let (Some(mesh), Some(landmarks)) = (self.working_mesh(), &self.edits.landmarks)
                else {
                    return self.fail("registration needs a scan and its 13 feature points");
                };
                let job = Job::Register {
                    generic: self.generic.clone(),
                    scan: mesh.clone(),
                    landmarks: Box::new(*landmarks),
                };
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
            Command::Undo => {
                if let Some(previous) = self.history.undo(&self.edits) {
                    self.edits = previous;
                    self.version += 1;
                }
                Vec::new()
            }
            Command::Redo => {
                if let Some(next) = self.history.redo(&self.edits) {
                    self.edits = next;
                    self.version += 1;
                }
                Vec::new()
            }
        }
    }

    fn fail(&mut self, message: impl Into<String>) -> Vec<Job> {
        self.error = Some(message.into());
        Vec::new()
    }

    /// Takes one worker result. A failure keeps the previous state and shows the error.
    pub fn receive(&mut self, result: JobResult) {
        let what = match &result {
            JobResult::Loaded(_) => "loading",
            JobResult::Denoised(_) => "denoising",
            JobResult::Registered(_) => "registering",
        };
        if let Some(i) = self.pending.iter().position(|p| *p == what) {
            self.pending.remove(i);
        }
        match result {
            JobResult::Loaded(Ok(scan)) => {
                self.scan = Some(*scan);
                self.denoised = None;
                self.registration = None;
                // A new scan's feature points are unknown until detected, loaded or placed.
                self.edits.landmarks = None;
                self.history.clear();
                self.version += 1;
            }
            JobResult::Denoised(Ok(d)) => {
                self.denoised = Some(*d);
                self.version += 1;
            }
            JobResult::Registered(Ok(r)) => {
                self.registration = Some(*r);
                self.version += 1;
            }
            JobResult::Loaded(Err(e))
            | JobResult::Denoised(Err(e))
            | JobResult::Registered(Err(e)) => {
                self.error = Some(e);
            }
        }
    }
}

/// Reads a landmark file (JSON: name → [x, y, z] mm, all 13 names).
pub fn read_landmarks(path: &Path) -> Result<Landmarks, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: not a landmark file: {e}", path.display()))
}
