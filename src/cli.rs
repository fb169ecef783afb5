//! Headless command implementations behind `facesynth <command>`; `main.rs` only parses.
//!
//! Every command prints one JSON object on stdout (machine-readable, pipe into `jq`) and
//! returns an error that `main` prints as one line before exiting with code 1.

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
    /// Open the editor window on a scan (or the generic face).
    View(ViewArgs),
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
                "method": method.name(), "rule": params.rule, "estimator": params.estimator,
                "iterations_run": report.iterations_run,
                "vertices_moved": report.vertices_moved,
                "max_displacement_mm": report.max_displacement_mm,
                "mean_displacement_mm": report.mean_displacement_mm,
                "millis": millis,
            }))
        }
        Some(Command::EvalDenoise {
            noisy_dir,
            clean_dir,
            max_scans,
            k_max,
            sweeps,
        }) => {
            let pairs = denoise::eval::load_pairs(&noisy_dir, &clean_dir, max_scans)?;
            anyhow::ensure!(!pairs.is_empty(), "{}: no scans", noisy_dir.display());
            let b = denoise::eval::benchmark(&pairs, k_max.max(1))?;
            let mut v = json!({ "scans": b.scans, "table": b.table });
            if sweeps {
                v["laplacian_sweep"] = json!(b.laplacian_sweep);
                v["taubin_sweep"] = json!(b.taubin_sweep);
            }
            print_json(&v)
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
