//! The command line's arguments (clap): the commands, their options and defaults, with units.

use crate::view_options::ViewArgs;
use crate::{denoise, io};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// facesynth — 3D facial expression synthesis with a layered FEM face, and 3D face recognition.
///
/// With no command (or just a FILE) the editor window opens.
#[derive(Debug, Parser)]
#[command(name = "facesynth", version, args_conflicts_with_subcommands = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub limits: LimitArgs,
}

/// What the mesh readers accept, for every command (see `io::ReadLimits`).
#[derive(Debug, Clone, Default, Args)]
pub struct LimitArgs {
    /// Largest mesh file read, MiB [default: 1024]. Larger files are refused before reading.
    #[arg(long, global = true, value_name = "MB")]
    pub max_file_mb: Option<u64>,
    /// Largest vertex (point) count read [default: 20000000]. Peak memory through the landmark
    /// pipeline is about 400 bytes per vertex (measured on 1M-vertex meshes).
    #[arg(long, global = true, value_name = "N")]
    pub max_vertices: Option<usize>,
    /// Units of the scan files' coordinates [default: auto: metres where a mesh is 0.03–3 units
    /// across (a head in metres), millimetres otherwise; a scaled file is named on stderr].
    #[arg(long, global = true, value_enum)]
    pub units: Option<UnitsArg>,
}

/// How feature-point detection finds the face (`landmarks`, `eval-landmarks`).
#[derive(Debug, Clone, Default, Args)]
pub struct LocaliseArgs {
    /// Skip face localisation: run the paper's steps on the scan as it is (scanner frame,
    /// face towards +z and y up; the largest front-facing region taken as the face).
    #[arg(long, conflicts_with_all = ["facing", "up"])]
    pub no_localise: bool,
    /// The scan axis the face looks along (+x, -x, +y, -y, +z, -z), where known; with --up.
    /// Default: found by face localisation (the scanner frame first, then every axis frame).
    #[arg(long, value_name = "AXIS", requires = "up", allow_hyphen_values = true)]
    pub facing: Option<String>,
    /// The scan axis the forehead points to, where known; with --facing.
    #[arg(
        long,
        value_name = "AXIS",
        requires = "facing",
        allow_hyphen_values = true
    )]
    pub up: Option<String>,
}

/// `--units` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum UnitsArg {
    Auto,
    Mm,
    Cm,
    M,
}

impl From<UnitsArg> for io::Units {
    fn from(u: UnitsArg) -> Self {
        match u {
            UnitsArg::Auto => io::Units::Auto,
            UnitsArg::Mm => io::Units::Millimetres,
            UnitsArg::Cm => io::Units::Centimetres,
            UnitsArg::M => io::Units::Metres,
        }
    }
}

impl LimitArgs {
    /// The reader limits these flags give (defaults where not given).
    pub fn read_limits(&self) -> io::ReadLimits {
        let d = io::ReadLimits::DEFAULT;
        io::ReadLimits {
            max_file_bytes: self
                .max_file_mb
                .map_or(d.max_file_bytes, |mb| mb.saturating_mul(1 << 20)),
            max_vertices: self.max_vertices.unwrap_or(d.max_vertices),
            units: self.units.map_or(d.units, io::Units::from),
            ..d
        }
    }
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print a mesh file's figures as JSON (vertices, faces, quads, triangles, bounding box).
    Info {
        /// Mesh file (.wrl .vrml .obj .ply .xyz .txt).
        file: PathBuf,
    },
    /// Convert a mesh between formats (by extension; writes .obj or .ply).
    Convert { input: PathBuf, output: PathBuf },
    /// Write the built-in generic face and its 13 feature points.
    Generic {
        /// Output mesh (.obj or .ply).
        #[arg(long)]
        out: PathBuf,
        /// Also write the feature points as JSON: name → [x, y, z] mm.
        #[arg(long)]
        landmarks: Option<PathBuf>,
    },
    /// Remove spikes and noise from a scan (paper 2.1.1) and write the result (.obj or .ply).
    Denoise {
        input: PathBuf,
        output: PathBuf,
        /// Filter: the paper's median + Laplacian, or a baseline.
        #[arg(long, value_enum, default_value_t = denoise::DenoiseMethod::MedianLaplacian)]
        method: denoise::DenoiseMethod,
        /// Maximum iterations k.
        #[arg(long, default_value_t = 15)]
        iterations: usize,
        /// Change fraction w (0 < w ≤ 1) of the median-Laplacian filter.
        #[arg(long, default_value_t = 0.8)]
        w: f64,
        /// The literal paper rule: one global threshold w·max, no 1 mm floor (default: a
        /// threshold per connected region, see `denoise::MoveRule`).
        #[arg(long)]
        paper: bool,
        /// A vertex the filter moved further than this (mm) is removed instead of kept where
        /// it was put (`inf` keeps every repair). Default filter only.
        #[arg(long, default_value_t = 3.0)]
        repair_max_mm: f64,
    },
    /// Score the denoisers against ground truth: noisy synth_gavab scans and their `--clean`
    /// twins (same seed). Prints the benchmark table (input, paper, default, baselines at
    /// their best k) as JSON.
    EvalDenoise {
        noisy_dir: PathBuf,
        clean_dir: PathBuf,
        /// Use at most this many scans (sorted by name).
        #[arg(long, default_value_t = usize::MAX)]
        max_scans: usize,
        /// Largest k tried for the Laplacian and Taubin baselines.
        #[arg(long, default_value_t = 60)]
        k_max: usize,
        /// Also print the baselines' scores for every k.
        #[arg(long)]
        sweeps: bool,
        /// Only list the vertices the default filter leaves more than 2 mm off (worst
        /// first, at most this many), with where they are and whether they moved.
        #[arg(long, value_name = "N")]
        worst: Option<usize>,
    },
    /// Register the generic face to a scan (paper 2.1.3) and print the quality report as JSON.
    Register {
        /// Scan mesh (.wrl .vrml .obj .ply .xyz .txt).
        scan: PathBuf,
        #[command(flatten)]
        points: ScanPoints,
        /// Write the registered generic face (.obj or .ply).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also write the report JSON to this file.
        #[arg(long)]
        report: Option<PathBuf>,
    },
    /// Synthesize expressions with the layered FEM face (paper section 2): writes neutral.obj,
    /// one OBJ per expression and report.json into DIR.
    Synthesize {
        /// Neutral scan; without it the generic face is used.
        scan: Option<PathBuf>,
        #[command(flatten)]
        points: ScanPoints,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// `all` or a comma-separated list of preset names.
        #[arg(long, default_value = "all")]
        expressions: String,
        /// Extra presets (RON, like assets/expressions.ron); same names replace built-ins.
        #[arg(long)]
        presets: Option<PathBuf>,
        /// Muscle definitions (RON, like assets/muscles.ron) instead of the built-in ones.
        #[arg(long)]
        muscles: Option<PathBuf>,
        /// Also write a front-view PNG per expression, coloured by displacement (0–10 mm).
        #[arg(long)]
        png: bool,
    },
    /// Export the FEM model with one expression's displacements as legacy VTK (ParaView).
    ExportFem {
        /// Neutral scan; without it the generic face is used.
        scan: Option<PathBuf>,
        #[command(flatten)]
        points: ScanPoints,
        /// Preset name (e.g. happiness).
        #[arg(long)]
        expression: String,
        /// Output .vtk file.
        #[arg(long)]
        vtk: PathBuf,
        /// Extra presets (RON).
        #[arg(long)]
        presets: Option<PathBuf>,
    },
    /// Learn an expression from a scan: fit the 18 muscle, 8 soft-tissue and 4 jaw activations (non-negative
    /// least squares) so the FEM face of NEUTRAL_SCAN meets EXPRESSION_SCAN; writes a preset (RON).
    FitExpression {
        neutral_scan: PathBuf,
        expression_scan: PathBuf,
        #[command(flatten)]
        points: PairPoints,
        /// Output preset file (.ron), loadable with `synthesize --presets`.
        #[arg(long)]
        out: PathBuf,
        /// Preset name (default: the expression scan's file stem).
        #[arg(long)]
        name: Option<String>,
        /// Muscle definitions (RON, like assets/muscles.ron) instead of the built-in ones.
        #[arg(long)]
        muscles: Option<PathBuf>,
        /// Also write the fitted face as binary PLY with the signed distance to the scan
        /// (mm, + = scan in front) as vertex quality; 0 where no scan point is within 8 mm.
        /// MeshLab colours it by quality: where the fit misses, and in which direction.
        #[arg(long)]
        residual_ply: Option<PathBuf>,
        /// Also write a front view of the fitted face coloured by its distance to the scan
        /// (blue 0 → red 5 mm; blue also where no scan point is within 8 mm).
        #[arg(long, value_name = "PNG")]
        residual_png: Option<PathBuf>,
    },
    /// Synthetic against real: carry each expression preset onto the FEM face of NEUTRAL_SCAN,
    /// align REAL_EXPRESSION_SCAN on the stable parts (as fit-expression does) and print the RMS
    /// distance per region (mouth, cheeks, brows, eyes) and over the whole face, mm, next to the
    /// neutral face's ("none").
    CompareExpression {
        neutral_scan: PathBuf,
        real_expression_scan: PathBuf,
        /// Compare this preset only (repeatable).
        #[arg(long, conflicts_with = "presets")]
        preset: Vec<String>,
        /// `all`: every preset (the default).
        #[arg(long, value_parser = ["all"])]
        presets: Option<String>,
        /// Extra presets (RON, like `synthesize --presets`) added to the built-in ones.
        #[arg(long)]
        preset_file: Option<PathBuf>,
        #[command(flatten)]
        points: PairPoints,
        /// Also write the JSON here.
        #[arg(long)]
        report: Option<PathBuf>,
    },
    /// Face recognition on a GavabDB-style dataset (paper section 4): Fisherfaces on range
    /// images, gallery = frontal1 (+ synthetic expressions), probes = frontal2, sonrisa, risa,
    /// gesto; prints the report JSON (rank-1, rank-5, CMC, per probe kind, failures).
    Evaluate(EvaluateArgs),
    /// Gallery augmentation (paper section 3): for every neutral gallery scan, denoise →
    /// landmarks → register → FEM → 18 synthetic expressions carried onto the scan, written as
    /// OUT/<scan>/<name>.ply (scan frame, mm; the FEM face's own surfaces in OUT/<scan>/face/);
    /// resumable, failures listed, not fatal.
    Augment {
        /// Folder of scans; the gallery scans are those whose name ends with --suffix.
        #[arg(long)]
        gallery: PathBuf,
        /// Output folder (one sub-folder per gallery scan; `failures.json`).
        #[arg(long)]
        out: PathBuf,
        /// `all` or a comma-separated list of preset names.
        #[arg(long, default_value = "all")]
        expressions: String,
        /// Extra presets (RON, like assets/expressions.ron, e.g. from `fit-expression`); same
        /// names replace built-ins, new names are added to `all`.
        #[arg(long)]
        presets: Option<PathBuf>,
        /// File-name stem suffix of the neutral gallery scans.
        #[arg(long, default_value = "_frontal1")]
        suffix: String,
        /// Comma-separated multiples of each preset's activations to write (1 = as defined).
        #[arg(long, value_delimiter = ',', default_value = "1")]
        intensities: Vec<f64>,
        /// Comma-separated jaw-opening angles (degrees) of extra open-mouth laughs: the laugh
        /// base preset with the FEM jaw opened that much more, the mouth's inside pushed back;
        /// empty for none.
        #[arg(long, value_delimiter = ',', num_args = 0..)]
        jaw_open_deg: Vec<f64>,
        /// The preset the open-mouth laughs start from.
        #[arg(long, default_value = "broad_smile")]
        laugh_base: String,
        /// Muscle definitions (RON, like assets/muscles.ron) instead of the built-in ones.
        #[arg(long)]
        muscles: Option<PathBuf>,
        /// Skip writing the FEM face's own surfaces (`face/*.obj`); recognition does not read them.
        #[arg(long)]
        no_face_meshes: bool,
        /// Folder of correction files `<scan stem>.landmarks.json` (default: beside each
        /// gallery scan); a scan with one is augmented from its points, not detected ones.
        #[arg(long, value_name = "DIR")]
        landmarks_dir: Option<PathBuf>,
        /// Only the gallery scans whose index in the sorted gallery is ≡ K (mod N), e.g. one
        /// task of a cluster job array; the shards together write what one run writes
        /// (failures in `failures.K-of-N.json`).
        #[arg(long, value_name = "K/N")]
        shard: Option<crate::augment::Shard>,
    },
    /// Print timings as JSON.
    Bench {
        #[command(subcommand)]
        what: BenchWhat,
    },
    /// Write a scan with its shape index (paper 2.1.2) as the per-vertex `quality` of a PLY.
    Curvature {
        input: PathBuf,
        /// Output .ply (binary; MeshLab shows the scalar as vertex quality).
        output: PathBuf,
        /// Edge hops of the neighbourhood fitted at each vertex.
        #[arg(long, default_value_t = 2)]
        rings: usize,
    },
    /// Detect the 13 feature points of a scan (paper 2.1.2) and print them as JSON.
    Landmarks {
        input: PathBuf,
        /// Skip the median-Laplacian denoising that runs first by default.
        #[arg(long)]
        no_denoise: bool,
        /// Also write the JSON report to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Also write a picture: shape index seen from the scanner, with the points.
        #[arg(long, value_name = "PNG")]
        png: Option<PathBuf>,
        #[command(flatten)]
        localise: LocaliseArgs,
    },
    /// Benchmark: denoise + feature points on one scan, repeated; prints min/median ms per stage.
    BenchLandmarks {
        input: PathBuf,
        /// Repetitions (the minimum is the least disturbed on a shared machine).
        #[arg(long, default_value_t = 20)]
        repeat: usize,
    },
    /// Score feature-point detection on a synth_gavab.py folder against its ground truth.
    EvalLandmarks {
        /// Folder written by ../shared/bench/synth_gavab.py (scans + JSON ground truth).
        dir: PathBuf,
        /// Skip denoising before detection.
        #[arg(long)]
        no_denoise: bool,
        /// Also write the JSON report (with per-scan errors) to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        #[command(flatten)]
        localise: LocaliseArgs,
    },
    /// Open the editor window on a scan (or the generic face).
    View(ViewArgs),
    /// Review the feature points of every scan in a folder, worst first, in the editor: each
    /// row says detected / corrected / suspect and why; Next / Previous (N / P) open the next
    /// scan with its points, and moved points are written as `<stem>.landmarks.json`, which
    /// every batch command then uses. Detection is cached (`.facesynth-review.json`).
    Review {
        dir: PathBuf,
        /// Folder of the correction files (default: beside the scans).
        #[arg(long, value_name = "DIR")]
        landmarks_dir: Option<PathBuf>,
        /// Print the queue as JSON instead of opening the editor (no window).
        #[arg(long)]
        list: bool,
        /// A scripted session in the review window (see `view --session`).
        #[arg(long, value_name = "RON")]
        session: Option<PathBuf>,
        /// Save the window as a PNG once the queue has opened, and exit.
        #[arg(long, value_name = "PNG")]
        screenshot: Option<PathBuf>,
    },
}

/// Options of `facesynth evaluate`.
#[derive(Debug, Clone, Args)]
pub struct EvaluateArgs {
    /// Folder of `<subject>_<scan>.<ext>` scans (wrl, vrml, obj, ply, xyz, txt).
    #[arg(long)]
    pub dataset: PathBuf,
    /// Synthetic gallery expressions (`facesynth augment`'s output): `DIR/<subject>_frontal1/*.ply`
    /// (or .obj), in the scan's frame. The report then also gives the figures without them.
    #[arg(long)]
    pub augmented: Option<PathBuf>,
    /// A dataset of other people (same layout, no subject in common): their expression −
    /// neutral range images join the augmented run's within-class scatter (learned
    /// expressions, beside the synthetic ones). Needs --augmented. The report then also gives
    /// the figures with the synthetic expressions only (`synthetic_only`).
    #[arg(long, value_name = "DIR")]
    pub expression_training: Option<PathBuf>,
    /// Distance between projected faces.
    #[arg(long, value_enum, default_value_t = crate::recognition::Metric::Cosine)]
    pub metric: crate::recognition::Metric,
    /// Also write the report JSON to this file.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Nose tip and pose normalisation before resampling: `auto` = detected feature points
    /// and the registration's rigid fit to the generic face; `truth` = the synthetic ground
    /// truth beside each scan (diagnostic).
    #[arg(long, value_enum, default_value_t = crate::recognition::PoseSource::Auto)]
    pub pose: crate::recognition::PoseSource,
    /// Feature points the automatic pose is fitted to.
    #[arg(long, value_enum, default_value_t = crate::recognition::pose::PosePoints::Rigid)]
    pub pose_points: crate::recognition::pose::PosePoints,
    /// Write a PNG of the CMC curves; with --augmented the run is scored both without and
    /// with the synthetic gallery expressions, and both curves are drawn.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Comma-separated scan kinds forming the gallery.
    #[arg(long, default_value = "frontal1")]
    pub gallery_scans: String,
    /// Comma-separated scan kinds used as probes.
    #[arg(long, default_value = "frontal2,sonrisa,risa,gesto")]
    pub probe_scans: String,
    /// Write the feature vectors, labels and our ranks as JSON (for scripts/sklearn_crosscheck.py).
    #[arg(long)]
    pub features: Option<PathBuf>,
    /// At most this many PCA dimensions before the LDA (default: the paper's M − c).
    #[arg(long)]
    pub pca_dims: Option<usize>,
    /// Within-class scatter floor λ (× its mean eigenvalue); 0 = the paper's plain LDA.
    #[arg(long, default_value_t = 3.0)]
    pub sw_floor: f64,
    /// Expression weights' scale, mm: with synthetic expressions, every range-image sample is
    /// weighted 1/√(1 + σ²/s²), σ = how much the synthetic expressions move it (RMS), so the
    /// regions expressions move count less (see `recognition::expression_weights`).
    #[arg(long, value_name = "MM", default_value_t = 0.5)]
    pub expression_weight_mm: f64,
    /// Score every range-image sample alike, as the paper does (no expression weights).
    #[arg(long)]
    pub no_expression_weights: bool,
    /// Folder of correction files `<scan stem>.landmarks.json` (default: beside each scan);
    /// a gallery or probe scan with one is posed by its points, not detected ones.
    #[arg(long, value_name = "DIR")]
    pub landmarks_dir: Option<PathBuf>,
}

/// Where a scan's feature points come from (`register`, `synthesize`, `export-fem`).
#[derive(Debug, Clone, Default, Args)]
pub struct ScanPoints {
    /// The scan's 13 feature points (a landmark file); when omitted, the correction file
    /// beside the scan, else detected.
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Folder of correction files `<scan stem>.landmarks.json` (default: beside the scan); one
    /// there replaces detection unless --landmarks is given.
    #[arg(long, value_name = "DIR")]
    pub landmarks_dir: Option<PathBuf>,
}

impl ScanPoints {
    /// The landmark file of `scan`: given, else the correction beside it (or in the folder).
    pub fn file(&self, scan: &std::path::Path) -> Option<PathBuf> {
        crate::pipeline::correction_for(
            scan,
            self.landmarks.as_deref(),
            self.landmarks_dir.as_deref(),
        )
    }
}

/// Where the feature points of a neutral scan and an expression scan of the same person come
/// from (`fit-expression`, `compare-expression`).
#[derive(Debug, Clone, Default, Args)]
pub struct PairPoints {
    /// The neutral scan's 13 feature points (a landmark file); when omitted, the correction
    /// file beside the scan, else detected.
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// The expression scan's feature points (start of the rigid alignment); when omitted, the
    /// correction file beside it, else detected.
    #[arg(long)]
    pub expression_landmarks: Option<PathBuf>,
    /// Folder of correction files `<scan stem>.landmarks.json` for both scans (default: beside
    /// each scan).
    #[arg(long, value_name = "DIR")]
    pub landmarks_dir: Option<PathBuf>,
}

impl PairPoints {
    /// The landmark files of (neutral, expression): given, else the correction beside each.
    pub fn files(
        &self,
        neutral: &std::path::Path,
        expression: &std::path::Path,
    ) -> (Option<PathBuf>, Option<PathBuf>) {
        let dir = self.landmarks_dir.as_deref();
        (
            crate::pipeline::correction_for(neutral, self.landmarks.as_deref(), dir),
            crate::pipeline::correction_for(expression, self.expression_landmarks.as_deref(), dir),
        )
    }
}

/// What `facesynth bench` measures.
#[derive(Debug, Clone, Copy, Subcommand)]
pub enum BenchWhat {
    /// FEM face: assembly, factorization, one solve, basis (18 muscles + jaw), slider update; also with
    /// 4× the elements and on the 53×53×3 test slab.
    Fem,
}
