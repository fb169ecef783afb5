//! Headless command implementations behind `facesynth <command>`; `main.rs` only parses.
//!
//! Every command prints one JSON object on stdout (machine-readable, pipe into `jq`) and
//! returns an error that `main` prints as one line before exiting with code 1.

mod fem;

use crate::{denoise, generic_face, io};
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use serde_json::json;
use std::path::{Path, PathBuf};

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
    },
    /// Register the generic face to a scan (paper 2.1.3) and print the quality report as JSON.
    Register {
        /// Scan mesh (.wrl .vrml .obj .ply .xyz .txt).
        scan: PathBuf,
        /// The scan's 13 feature points as JSON (name → [x, y, z] mm). Required until automatic
        /// detection is available.
        #[arg(long)]
        landmarks: Option<PathBuf>,
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
        /// The scan's 13 feature points as JSON (name → [x, y, z] mm); required with SCAN.
        #[arg(long)]
        landmarks: Option<PathBuf>,
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
    },
    /// Export the FEM model with one expression's displacements as legacy VTK (ParaView).
    ExportFem {
        /// Neutral scan; without it the generic face is used.
        scan: Option<PathBuf>,
        /// The scan's 13 feature points as JSON; required with SCAN.
        #[arg(long)]
        landmarks: Option<PathBuf>,
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
    /// Face recognition on a GavabDB-style dataset (paper section 4): Fisherfaces on range
    /// images, gallery = frontal1 (+ synthetic expressions), probes = frontal2, sonrisa, risa,
    /// gesto; prints the report JSON (rank-1, rank-5, CMC, per probe kind, failures).
    Evaluate(EvaluateArgs),
    /// Print timings as JSON.
    Bench {
        #[command(subcommand)]
        what: BenchWhat,
    },
    /// Open the editor window on a scan (or the generic face).
    View(ViewArgs),
}

/// Options of `facesynth evaluate`.
#[derive(Debug, Clone, Args)]
pub struct EvaluateArgs {
    /// Folder of `<subject>_<scan>.wrl` scans (with `<subject>_<scan>.json` ground truth for
    /// the nose tip and pose).
    #[arg(long)]
    pub dataset: PathBuf,
    /// Synthetic gallery expressions: `DIR/<subject>_frontal1/*.obj`, in the scan's frame.
    #[arg(long)]
    pub augmented: Option<PathBuf>,
    /// Distance between projected faces.
    #[arg(long, value_enum, default_value_t = crate::recognition::Metric::Cosine)]
    pub metric: crate::recognition::Metric,
    /// Also write the report JSON to this file.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Pose normalisation before resampling.
    #[arg(long, value_enum, default_value_t = crate::recognition::PoseSource::Truth)]
    pub pose: crate::recognition::PoseSource,
    /// Comma-separated scan kinds forming the gallery.
    #[arg(long, default_value = "frontal1")]
    pub gallery_scans: String,
    /// Comma-separated scan kinds used as probes.
    #[arg(long, default_value = "frontal2,sonrisa,risa,gesto")]
    pub probe_scans: String,
    /// Write the feature vectors, labels and our ranks as JSON (for scripts/sklearn_crosscheck.py).
    #[arg(long)]
    pub features: Option<PathBuf>,
}

/// What `facesynth bench` measures.
#[derive(Debug, Clone, Copy, Subcommand)]
pub enum BenchWhat {
    /// FEM face: assembly, factorization, one solve, 18-muscle basis, slider update; also with
    /// 4× the elements and on the 53×53×3 test slab.
    Fem,
}

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
    /// The scan's feature points (JSON: name → [x, y, z] mm), loaded after the scan.
    #[arg(long, value_name = "JSON")]
    pub landmarks: Option<PathBuf>,
    /// Run the denoising filter (default parameters) after loading.
    #[arg(long)]
    pub denoise: bool,
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
}

/// FEM layers drawn in the viewport.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
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
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Info { file }) => print_json(&info(&file)?),
        Some(Command::Convert { input, output }) => {
            let mesh = io::read_mesh(&input)?;
            io::write_mesh(&output, &mesh)?;
            print_json(&json!({
                "input": input, "output": output,
                "vertices": mesh.vertex_count(), "faces": mesh.face_count(),
            }))
        }
        Some(Command::Generic { out, landmarks }) => {
            let face = generic_face::build();
            io::write_mesh(&out, &face.mesh)?;
            let points = face.landmarks();
            if let Some(path) = &landmarks {
                let text = serde_json::to_string_pretty(&points)?;
                io::write_text_atomic(path, &(text + "\n"))?;
            }
            let counts = face.mesh.face_counts();
            print_json(&json!({
                "out": out, "landmarks_file": landmarks,
                "vertices": face.mesh.vertex_count(), "faces": counts.faces,
                "quads": counts.quads, "triangles": counts.triangles,
                "landmarks": points,
            }))
        }
        Some(Command::Denoise {
            input,
            output,
            method,
            iterations,
            w,
            paper,
        }) => {
            let mut mesh = io::read_mesh(&input)?;
            let params = denoise::DenoiseParams {
                method,
                iterations,
                w,
                ..if paper {
                    denoise::DenoiseParams::paper()
                } else {
                    denoise::DenoiseParams::default()
                }
            };
            let start = std::time::Instant::now();
            let report = denoise::denoise(&mut mesh, &params)?;
            let millis = start.elapsed().as_secs_f64() * 1e3;
            io::write_mesh(&output, &mesh)?;
            print_json(&json!({
                "input": input, "output": output,
                "method": method.name(), "rule": params.rule,
                "iterations_run": report.iterations_run,
                "vertices_moved": report.vertices_moved,
                "max_displacement_mm": report.max_displacement_mm,
                "mean_displacement_mm": report.mean_displacement_mm,
                "millis": millis,
            }))
        }
        Some(Command::Register {
            scan,
            landmarks,
            out,
            report,
        }) => print_json(&register(
            &scan,
            landmarks.as_deref(),
            out.as_deref(),
            report.as_deref(),
        )?),
        Some(Command::Synthesize {
            scan,
            landmarks,
            out,
            expressions,
            presets,
            muscles,
        }) => print_json(&fem::synthesize(
            scan.as_deref(),
            landmarks.as_deref(),
            &out,
            &expressions,
            presets.as_deref(),
            muscles.as_deref(),
        )?),
        Some(Command::ExportFem {
            scan,
            landmarks,
            expression,
            vtk,
            presets,
        }) => print_json(&fem::export_fem(
            scan.as_deref(),
            landmarks.as_deref(),
            &expression,
            &vtk,
            presets.as_deref(),
        )?),
        Some(Command::Evaluate(args)) => print_json(&evaluate(&args)?),
        Some(Command::Bench {
            what: BenchWhat::Fem,
        }) => print_json(&fem::bench_fem()?),
        Some(Command::View(args)) => view(args),
        None => view(cli.view),
    }
}

/// `facesynth info FILE` as a JSON value.
pub fn info(file: &Path) -> Result<serde_json::Value> {
    let mesh = io::read_mesh(file)?;
    let counts = mesh.face_counts();
    let (lo, hi) = mesh.bbox_mm().context("mesh is empty")?;
    let round = |v: glam::DVec3| v.to_array().map(|c| (c * 1e4).round() / 1e4);
    Ok(json!({
        "file": file,
        "vertices": mesh.vertex_count(),
        "faces": counts.faces,
        "quads": counts.quads,
        "triangles": counts.triangles,
        "bbox_min_mm": round(lo),
        "bbox_max_mm": round(hi),
    }))
}

/// `facesynth register`: registers the built-in generic face to `scan`.
pub fn register(
    scan: &Path,
    landmarks: Option<&Path>,
    out: Option<&Path>,
    report: Option<&Path>,
) -> Result<serde_json::Value> {
    let landmarks = landmarks.context(
        "--landmarks FILE.json is required (automatic feature-point detection is not available yet)",
    )?;
    let text = std::fs::read_to_string(landmarks)
        .with_context(|| format!("{}: cannot read", landmarks.display()))?;
    let points: crate::Landmarks = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a landmark file", landmarks.display()))?;
    let mesh = io::read_mesh(scan)?;
    let generic = generic_face::build();
    let params = crate::registration::RegistrationParams::default();
    let result = crate::registration::register(&generic, &mesh, &points, &params)?;
    if let Some(path) = out {
        io::write_mesh(path, &result.mesh)?;
    }
    let value = result.report_json();
    if let Some(path) = report {
        io::write_text_atomic(path, &(serde_json::to_string_pretty(&value)? + "\n"))?;
    }
    Ok(value)
}

/// `facesynth evaluate`: the recognition report as JSON.
pub fn evaluate(args: &EvaluateArgs) -> Result<serde_json::Value> {
    use crate::recognition::ProtocolParams;
    let list = |s: &str| -> Vec<String> {
        s.split(',')
            .map(str::trim)
            .filter(|x| !x.is_empty())
            .map(String::from)
            .collect()
    };
    let params = ProtocolParams {
        metric: args.metric,
        pose: args.pose,
        gallery_scans: list(&args.gallery_scans),
        probe_scans: list(&args.probe_scans),
        ..ProtocolParams::default()
    };
    let eval = crate::recognition::evaluate(&args.dataset, args.augmented.as_deref(), &params)?;
    let value = serde_json::to_value(&eval.report)?;
    if let Some(path) = &args.report {
        io::write_text_atomic(path, &(serde_json::to_string_pretty(&value)? + "\n"))?;
    }
    if let Some(path) = &args.features {
        io::write_text_atomic(path, &serde_json::to_string(&eval.features_json())?)?;
    }
    Ok(value)
}

fn print_json(value: &serde_json::Value) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}

#[cfg(feature = "gui")]
fn view(args: ViewArgs) -> Result<()> {
    crate::app::run(args)
}

#[cfg(not(feature = "gui"))]
fn view(_args: ViewArgs) -> Result<()> {
    anyhow::bail!("this facesynth was built without the `gui` feature; the editor is unavailable")
}
