//! What the editor holds per pipeline step: the scan, its denoising, feature points,
//! registration and FEM face, and the user's edits.

use super::*;

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
    /// Input ids of the vertices the filter moved by more than [`SPIKE_MM`] or removed: the
    /// long peaks it took away.
    pub spikes: Vec<u32>,
    pub millis: f64,
}

/// The mesh the pipeline steps work on: the denoised scan (or the scan) without the vertices
/// erased by hand.
#[derive(Debug, Clone)]
pub struct WorkingScan {
    pub mesh: Arc<Mesh>,
    /// Per working vertex: its id in the scan as loaded (what [`Edits::erased`] and the
    /// denoising report's per-input-vertex figures are indexed by).
    pub input_ids: Vec<u32>,
    /// Distinct for every rebuild, so results computed on an earlier working scan (feature
    /// point detection, registration) can tell they are out of date.
    pub id: u64,
}

/// Default radius of the erase brush, mm (a spike cluster is 1–3 scan samples across, ~1.5 mm
/// apart on GavabDB scans).
pub const ERASE_RADIUS_MM: f64 = 3.0;

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
    pub millis: f64,
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
    /// Which surface it was built on (see [`Document::fem_surface_id`]).
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

/// The part of the document that undo/redo restores (and the autosave keeps).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Edits {
    /// The scan's 13 feature points (or the generic face's when no scan is loaded).
    pub landmarks: Option<Landmarks>,
    /// Layer thicknesses and materials of the FEM model.
    pub fem: FemParams,
    /// Muscle definitions (force magnitudes, insertion/origin anchors).
    pub muscles: MuscleSet,
    /// Muscle activations by muscle name (`zygomatic_major_left`, …); missing = 0.
    pub activations: BTreeMap<String, f64>,
    /// Expression presets (built-in + loaded + saved from the editor).
    pub presets: ExpressionSet,
    /// The preset last applied (for "revert").
    pub applied_preset: Option<String>,
    /// Scan vertices erased by hand (ids in the scan as loaded): spikes, hair or clothing the
    /// filter left. They stay erased through a new denoising run; the working scan is the
    /// (denoised) scan without them.
    #[serde(default)]
    pub erased: BTreeSet<u32>,
}

impl Default for Edits {
    fn default() -> Self {
        Edits {
            landmarks: None,
            fem: FemParams::default(),
            muscles: MuscleSet::builtin(),
            activations: BTreeMap::new(),
            presets: ExpressionSet::builtin(),
            applied_preset: None,
            erased: BTreeSet::new(),
        }
    }
}
