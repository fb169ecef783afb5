//! What the editor holds per pipeline step: the scan, its denoising, feature points,
//! registration and FEM face, and the user's edits.

use super::*;

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
