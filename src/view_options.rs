//! The editor window's options (`facesynth view`): parsed by the command line, read by the
//! editor. Apart from both so that neither depends on the other.

use clap::Args;
use std::path::PathBuf;

/// Options of the editor window.
#[derive(Debug, Clone, Default, Args)]
pub struct ViewArgs {
    /// Mesh to open; without it the generic face is shown.
    pub file: Option<PathBuf>,
    /// Render one frame after loading, save it as PNG and exit (for CI and reviews).
    #[arg(long, value_name = "PNG")]
    pub screenshot: Option<PathBuf>,
    /// Window width in logical pixels.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Window height in logical pixels.
    #[arg(long, default_value_t = 800)]
    pub height: u32,
    /// The scan's feature points (a landmark file), loaded after the scan. Without it, the
    /// scan's correction file `<stem>.landmarks.json` (beside it, or in --landmarks-dir) is
    /// loaded if there is one, and replaces --detect.
    #[arg(long, value_name = "JSON")]
    pub landmarks: Option<PathBuf>,
    /// Review the scans of this folder, worst feature points first (`facesynth review DIR`).
    #[arg(long, value_name = "DIR")]
    pub review: Option<PathBuf>,
    /// Folder of correction files `<scan stem>.landmarks.json` (default: beside the scan);
    /// *Save as correction* writes there too.
    #[arg(long, value_name = "DIR")]
    pub landmarks_dir: Option<PathBuf>,
    /// Run the denoising filter (default parameters) after loading.
    #[arg(long)]
    pub denoise: bool,
    /// Detect the 13 feature points (after --denoise, if given).
    #[arg(long)]
    pub detect: bool,
    /// Register the generic face to the scan (needs the scan's landmarks).
    #[arg(long)]
    pub register: bool,
    /// What the viewport colours by (default: chosen from what was computed).
    #[arg(long, value_enum)]
    pub show: Option<Overlay>,
    /// Build the layered FEM face (on the registered face if --register, else the generic).
    #[arg(long)]
    pub fem: bool,
    /// Apply an expression preset (implies --fem), e.g. `happiness`.
    #[arg(long, value_name = "NAME")]
    pub expression: Option<String>,
    /// Learn an expression from this scan of the same person (implies --fem).
    #[arg(long, value_name = "SCAN")]
    pub fit: Option<PathBuf>,
    /// Which FEM layers to draw.
    #[arg(long, value_enum)]
    pub layers: Option<LayersShown>,
    /// Draw the 18 muscles as arrows (insertion towards origin, length ∝ force).
    #[arg(long)]
    pub muscles: bool,
    /// Camera turn about the vertical axis, degrees (positive: towards the subject's left).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub yaw: f64,
    /// Camera elevation, degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub pitch: f64,
    /// Responsiveness check: after the scripted steps, drive the zygomatic sliders for this
    /// many frames, then halve the skin modulus; print frame times and the worker's re-solve
    /// time as JSON and exit (builds the FEM model if the script did not).
    #[arg(long, value_name = "FRAMES")]
    pub measure_slider: Option<u32>,
    /// Run a scripted editor session (a RON list of steps: open, denoise, move a landmark,
    /// set a slider, store a preset, undo, screenshot, …; see `src/app/session.rs`) in this
    /// window after the other options' steps, then close it.
    #[arg(long, value_name = "RON")]
    pub session: Option<PathBuf>,
}

impl ViewArgs {
    /// A scripted run (`--screenshot`, `--session`, `--measure-slider`): it keeps no settings,
    /// neither prompts nor autosaves, and closes itself when done.
    pub fn scripted(&self) -> bool {
        self.screenshot.is_some() || self.session.is_some() || self.measure_slider.is_some()
    }
}

/// FEM layers drawn in the viewport.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
pub enum LayersShown {
    /// The skin surface only.
    Skin,
    /// Skin, fat/skin interface and cranium surfaces with the hexahedra's edges.
    All,
    /// All layers cut by a sagittal plane left of the midline, so the hexahedra show through
    /// the thickness.
    Cutaway,
}

/// Per-vertex colouring of the viewport.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Deserialize)]
pub enum Overlay {
    /// Plain shading.
    #[default]
    Plain,
    /// How far the denoising filter moved each scan vertex (mm), removed spikes marked.
    Denoise,
    /// Registered generic face over the scan, coloured by its distance to the scan (mm).
    Registration,
    /// The FEM face coloured by the expression's displacement magnitude (mm).
    Displacement,
    /// The scan's shape index (cap 1, saddle 0.5, cup 0) from the feature-point detection.
    ShapeIndex,
    /// The face fitted to an expression scan (`--fit`), coloured by its distance to that scan
    /// (0–5 mm, as `fit-expression --residual-png`; grey: no scan point within reach).
    FitResidual,
}
