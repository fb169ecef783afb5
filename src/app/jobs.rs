//! What the editor's UI thread and its worker exchange: the jobs, their results, and the
//! per-step states a result carries (the scan, its denoising, feature points, registration,
//! FEM face and fitted expression). Plain data, shared by `document` (which sends jobs and keeps
//! the states) and `worker` (which computes them); neither imports the other.

use crate::Mesh;
use crate::denoise::{DenoiseParams, DenoiseReport};
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::fem::expressions::ExpressionSet;
use crate::fem::layers::ElementQuality;
use crate::fem::muscles::{Muscle, MuscleSet};
use crate::fem::{FemParams, HexMesh, Timings};
use crate::generic_face::GenericFace;
use crate::mesh::FaceCounts;
use crate::registration::RegistrationResult;
use glam::DVec3;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A slow step the worker runs.
pub enum Job {
    Load(PathBuf),
    Denoise {
        mesh: Arc<Mesh>,
        params: DenoiseParams,
    },
    DetectLandmarks {
        mesh: Arc<Mesh>,
    },
    Register {
        generic: Arc<GenericFace>,
        scan: Arc<Mesh>,
        landmarks: Box<Landmarks>,
        /// The cheek and forehead points are the detector's (see
        /// `pipeline::registration_points`).
        borders_detected: bool,
    },
    /// Fit the muscle and jaw activations to an expression scan with the current FEM model.
    FitExpression {
        scan: PathBuf,
        /// The (denoised) neutral scan the model was registered to, if any.
        neutral: Option<Arc<Mesh>>,
        presets: ExpressionSet,
    },
    /// Build the review queue of a folder (detection where the cache has none).
    Review {
        dir: PathBuf,
        landmarks_dir: Option<PathBuf>,
        progress: Arc<ReviewProgress>,
    },
    /// Bring the FEM model up to date with these inputs (build, refactor or re-solve, as
    /// little as the change needs) and return its basis.
    Fem {
        surface: Arc<Mesh>,
        surface_id: u64,
        feature_vertices: [u32; FeaturePoint::COUNT],
        params: FemParams,
        muscles: Box<MuscleSet>,
    },
}

/// What a [`Job`] gave back (errors as the one-line message the status bar shows).
pub enum JobResult {
    Loaded(Result<Box<ScanState>, String>),
    Denoised(Result<Box<DenoiseState>, String>),
    Registered(Result<Box<RegistrationState>, String>),
    Fem(Result<Box<FemState>, String>),
    Detected(Result<Box<DetectionState>, String>),
    Fitted(Result<Box<FitState>, String>),
    Reviewed(Result<Box<crate::pipeline::ReviewQueue>, String>),
}

/// A loaded input scan.
#[derive(Debug, Clone)]
pub struct ScanState {
    pub name: String,
    pub path: PathBuf,
    pub mesh: Arc<Mesh>,
    pub counts: FaceCounts,
    pub bbox_mm: (DVec3, DVec3),
    /// The unit the file was read in (the mesh is in mm whatever it was): shown in the file
    /// panel, since a scan scaled from metres by a guess must be seen to be.
    pub units: crate::io::UnitsRead,
    pub load_millis: f64,
}

/// The scan after the denoising filter.
#[derive(Debug, Clone)]
pub struct DenoiseState {
    pub params: DenoiseParams,
    pub mesh: Arc<Mesh>,
    pub report: DenoiseReport,
    /// Input ids of the vertices the filter moved by more than [`SPIKE_MM`] or removed: the
    /// long peaks it took away.
    pub spikes: Vec<u32>,
    pub millis: f64,
}

/// A move larger than this counts as a removed spike (scanner noise is ~0.15 mm).
pub const SPIKE_MM: f64 = 2.0;

/// An expression learned from a scan (fit of the 18 muscle, 8 soft-tissue and 4 jaw activations, paper: "additional
/// expressions can be learned from input faces").
#[derive(Debug, Clone)]
pub struct FitState {
    pub name: String,
    pub activations: BTreeMap<String, f64>,
    pub rms_before_mm: f64,
    pub rms_after_mm: f64,
    pub closest_preset: Option<(String, f64)>,
    pub vertices_used: usize,
    /// The same over the part an expression moves most (mouth, cheeks, chin), mm.
    pub moving_rms_before_mm: f64,
    pub moving_rms_after_mm: f64,
    /// Per skin vertex of the fitted face: its signed distance to the aligned expression scan,
    /// mm (+: the scan in front; `None`: no scan point within reach), as
    /// [`crate::fem::fit::signed_residuals`].
    pub residual_mm: Vec<Option<f64>>,
    /// The actuators that explain the fit, largest first: (name, contribution in mm).
    pub contributions_mm: Vec<(String, f64)>,
    pub millis: f64,
}

impl FitState {
    /// |residual| per skin vertex of the fitted face (NaN: no scan point within reach), when
    /// the fit was made on this face (`n` skin vertices).
    pub fn residual_magnitude(&self, n: usize) -> Option<Vec<f64>> {
        (self.residual_mm.len() == n).then(|| {
            self.residual_mm
                .iter()
                .map(|r| r.map_or(f64::NAN, f64::abs))
                .collect()
        })
    }
}

/// The automatic feature-point detection on the working scan (paper 2.1.2).
#[derive(Debug, Clone)]
pub struct DetectionState {
    pub report: crate::landmarks::LandmarkReport,
    /// Shape index per scan vertex (cap 1, saddle 0.5, cup 0), as the detector saw it.
    pub shape_index: Vec<f64>,
    pub millis: f64,
}

impl DetectionState {
    /// The Table 2 and level checks that failed for a point (empty: plausible).
    pub fn implausible(&self, p: FeaturePoint) -> Vec<String> {
        let table2 = self
            .report
            .distances
            .iter()
            .filter(|d| d.point == p && !d.in_range)
            .map(|d| {
                format!(
                    "{}: {:.1} mm outside [{:.1}, {:.1}]",
                    d.name, d.measured_mm, d.stat.min_mm, d.stat.max_mm
                )
            });
        let level = self
            .report
            .level
            .iter()
            .filter(|l| (l.left == p || l.right == p) && !l.in_range)
            .map(|l| {
                format!(
                    "{} {:.1} mm higher than {} across the symmetry line (limit {})",
                    l.left,
                    l.difference_mm,
                    l.right,
                    crate::landmarks::LEVEL_MAX_MM
                )
            });
        table2.chain(level).collect()
    }
}

/// The generic face registered to the scan.
#[derive(Debug, Clone)]
pub struct RegistrationState {
    pub result: Arc<RegistrationResult>,
    /// Per registered vertex: distance to the scan surface, mm (NaN: unmatched, filled).
    pub distance_mm: Vec<f64>,
    /// The landmarks it was computed from (to tell when it is out of date).
    pub landmarks: Landmarks,
}

/// The solved layered face model as the UI needs it: rest geometry, the muscle basis, and the
/// figures. The factorization itself stays with the worker.
#[derive(Debug, Clone)]
pub struct FemState {
    /// Rest geometry of the volume (node layer k of surface vertex v is node k·n + v).
    pub volume: Arc<HexMesh>,
    /// The skin surface at rest (generic or registered face).
    pub surface: Arc<Mesh>,
    pub muscles: Vec<Muscle>,
    /// Per actuator (`muscle_set.actuator_names()` order): displacement of every volume node at activation 1, mm.
    pub basis: Arc<Vec<Vec<DVec3>>>,
    pub fixed: Vec<bool>,
    pub params: FemParams,
    pub muscle_set: MuscleSet,
    pub dofs: usize,
    pub quality: ElementQuality,
    pub timings: Timings,
    /// What the last worker update did ("built", "refactored", "muscles re-solved").
    pub last_update: String,
    /// Wall time of the last worker update, ms.
    pub millis: f64,
    /// Which surface it was built on (see the document's `fem_surface_id`).
    pub surface_id: u64,
}

impl FemState {
    /// The activation vector in model order for a name → activation map (missing: 0).
    /// `muscle_set` is the set the model was built from, so its actuator names are the basis's.
    pub fn activation_vector(&self, activations: &BTreeMap<String, f64>) -> Vec<f64> {
        self.muscle_set
            .actuator_names()
            .iter()
            .map(|name| activations.get(name).copied().unwrap_or(0.0))
            .collect()
    }

    /// `u = Σ a_i u_i` at every volume node (the slider update: no solve), mm.
    pub fn displacement(&self, activations: &BTreeMap<String, f64>) -> Vec<DVec3> {
        let a = self.activation_vector(activations);
        let mut out = vec![DVec3::ZERO; self.volume.nodes_mm.len()];
        for (ai, basis) in a.iter().zip(self.basis.iter()) {
            if *ai == 0.0 {
                continue;
            }
            for (o, b) in out.iter_mut().zip(basis) {
                *o += *b * *ai;
            }
        }
        out
    }

    /// The skin surface deformed by `activations` (normals recomputed).
    pub fn deformed_surface(&self, activations: &BTreeMap<String, f64>) -> Mesh {
        // The skin is the first layer of volume nodes, so the surface takes their displacement.
        self.surface.displaced(&self.displacement(activations))
    }
}

/// How far the folder's detection has got (shared with the worker).
#[derive(Debug, Default)]
pub struct ReviewProgress {
    pub done: AtomicUsize,
    pub total: AtomicUsize,
}

impl ReviewProgress {
    /// (done, total).
    pub fn get(&self) -> (usize, usize) {
        (
            self.done.load(Ordering::Relaxed),
            self.total.load(Ordering::Relaxed),
        )
    }
}
