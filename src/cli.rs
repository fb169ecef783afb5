//! Headless command implementations behind `facesynth <command>`; `main.rs` only parses.
//!
//! Every command prints one JSON object on stdout (machine-readable, pipe into `jq`) and
//! returns an error that `main` prints as one line before exiting with code 1.

mod args;
mod compare;
mod fem;
mod landmarks;
mod recognition;

pub use crate::view_options::{LayersShown, Overlay, ViewArgs};
pub use args::{
    BenchWhat, Cli, Command, EvaluateArgs, LimitArgs, LocaliseArgs, PairPoints, ScanPoints,
    UnitsArg,
};

use landmarks::landmark_params;
pub(crate) use landmarks::min_median;
pub use landmarks::{bench_landmarks, landmarks};
pub use recognition::{augment, evaluate};

use crate::{denoise, generic_face, io};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::Path;

/// The one line `main` prints for an error: the context chain joined by `: `, leaving out a
/// cause whose text the line already holds (the library's errors include their source's
/// message, so `{:#}` would print it twice), with line breaks flattened.
pub fn error_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line.replace(['\n', '\r'], " ")
}

/// What is left to do after [`run`]: nothing, or open the editor with these options. The
/// command line knows nothing of the GUI: `main` launches the editor.
#[derive(Debug)]
pub enum Next {
    Done,
    View(Box<ViewArgs>),
}

/// Runs a parsed command line (every headless command); `view` and `review` without `--list`
/// come back as [`Next::View`].
pub fn run(cli: Cli) -> Result<Next> {
    io::set_default_limits(cli.limits.read_limits());
    io::set_notice_hook(|note| eprintln!("facesynth: {note}"));
    let done: Result<()> = match cli.command {
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
            repair_max_mm,
        }) => {
            let mut mesh = io::read_mesh(&input)?;
            let params = denoise::DenoiseParams {
                method,
                iterations,
                w,
                repair_max_mm,
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
                "vertices_removed": report.vertices_removed,
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
            worst,
        }) => {
            let pairs = denoise::eval::load_pairs(&noisy_dir, &clean_dir, max_scans)?;
            anyhow::ensure!(!pairs.is_empty(), "{}: no scans", noisy_dir.display());
            if let Some(n) = worst {
                let over =
                    denoise::eval::vertices_over(&pairs, &denoise::DenoiseParams::default(), 2.0)?;
                let count = |f: &dyn Fn(&denoise::eval::VertexError) -> bool| {
                    over.iter().filter(|v| f(v)).count()
                };
                print_json(&json!({
                    "over_2mm": over.len(),
                    "spike": count(&|v| v.spike),
                    "spike_untouched": count(&|v| v.spike && !v.moved),
                    "boundary": count(&|v| v.boundary),
                    "damage": count(&|v| !v.spike && v.moved),
                    "worst": over.iter().take(n).collect::<Vec<_>>(),
                }))
            } else {
                let b = denoise::eval::benchmark(&pairs, k_max.max(1))?;
                let mut v = json!({ "scans": b.scans, "table": b.table });
                if sweeps {
                    v["laplacian_sweep"] = json!(b.laplacian_sweep);
                    v["taubin_sweep"] = json!(b.taubin_sweep);
                }
                print_json(&v)
            }
        }
        Some(Command::Register {
            scan,
            points,
            out,
            report,
        }) => print_json(&register(
            &scan,
            points.file(&scan).as_deref(),
            out.as_deref(),
            report.as_deref(),
        )?),
        Some(Command::Synthesize {
            scan,
            points,
            out,
            expressions,
            presets,
            muscles,
            png,
        }) => print_json(&fem::synthesize(
            scan.as_deref(),
            scan.as_deref().and_then(|s| points.file(s)).as_deref(),
            &out,
            &expressions,
            presets.as_deref(),
            muscles.as_deref(),
            png,
        )?),
        Some(Command::ExportFem {
            scan,
            points,
            expression,
            vtk,
            presets,
        }) => print_json(&fem::export_fem(
            scan.as_deref(),
            scan.as_deref().and_then(|s| points.file(s)).as_deref(),
            &expression,
            &vtk,
            presets.as_deref(),
        )?),
        Some(Command::FitExpression {
            neutral_scan,
            expression_scan,
            points,
            out,
            name,
            muscles,
            residual_ply,
            residual_png,
        }) => {
            let (landmarks, expression_landmarks) = points.files(&neutral_scan, &expression_scan);
            print_json(&fem::fit_expression(
                &neutral_scan,
                &expression_scan,
                landmarks.as_deref(),
                expression_landmarks.as_deref(),
                &fem::FitOutputs {
                    preset: &out,
                    residual_ply: residual_ply.as_deref(),
                    residual_png: residual_png.as_deref(),
                },
                name.as_deref(),
                muscles.as_deref(),
            )?)
        }
        Some(Command::CompareExpression {
            neutral_scan,
            real_expression_scan,
            preset,
            presets: _,
            preset_file,
            points,
            report,
        }) => {
            let (landmarks, expression_landmarks) =
                points.files(&neutral_scan, &real_expression_scan);
            let inputs = compare::CompareInputs {
                neutral: &neutral_scan,
                expression: &real_expression_scan,
                landmarks: landmarks.as_deref(),
                expression_landmarks: expression_landmarks.as_deref(),
                presets: &preset,
                preset_file: preset_file.as_deref(),
            };
            print_json(&compare::compare_expression(&inputs, report.as_deref())?)
        }
        Some(Command::Evaluate(args)) => print_json(&evaluate(&args)?),
        Some(Command::Augment {
            gallery,
            out,
            expressions,
            presets,
            suffix,
            intensities,
            jaw_open_deg,
            laugh_base,
            muscles,
            no_face_meshes,
            landmarks_dir,
            shard,
        }) => {
            let params = crate::augment::AugmentParams {
                landmarks_dir,
                shard,
                gallery_suffix: suffix,
                expressions,
                presets: fem::expression_set(presets.as_deref())?,
                intensities,
                jaw_open_deg,
                laugh_base,
                muscles: fem::muscle_set(muscles.as_deref())?,
                write_face_meshes: !no_face_meshes,
                ..Default::default()
            };
            print_json(&augment(&gallery, &out, &params)?)
        }
        Some(Command::Bench {
            what: BenchWhat::Fem,
        }) => print_json(&fem::bench_fem()?),
        Some(Command::Curvature {
            input,
            output,
            rings,
        }) => print_json(&curvature(&input, &output, rings)?),
        Some(Command::Landmarks {
            input,
            no_denoise,
            json,
            png,
            localise,
        }) => print_json(&landmarks(
            &input,
            !no_denoise,
            json.as_deref(),
            png.as_deref(),
            &landmark_params(&localise)?,
        )?),
        Some(Command::BenchLandmarks { input, repeat }) => {
            print_json(&bench_landmarks(&input, repeat)?)
        }
        Some(Command::EvalLandmarks {
            dir,
            no_denoise,
            json,
            localise,
        }) => {
            let params = landmark_params(&localise)?;
            let report = crate::landmarks::eval::evaluate_dir(&dir, !no_denoise, &params)?;
            if let Some(path) = &json {
                io::write_text_atomic(path, &(serde_json::to_string_pretty(&report)? + "\n"))?;
            }
            print_json(&serde_json::to_value(report.summary())?)
        }
        Some(Command::View(args)) => return Ok(Next::View(Box::new(args))),
        Some(Command::Review {
            dir,
            landmarks_dir,
            list: true,
            ..
        }) => {
            let queue =
                crate::pipeline::ReviewQueue::build(&dir, landmarks_dir.as_deref(), &|k, n| {
                    if k > 0 {
                        eprintln!("review [{k}/{n}]");
                    }
                })?;
            print_json(&json!({
                "dir": queue.dir,
                "scans": queue.entries.len(),
                "reviewed": queue.reviewed(),
                "cached": queue.cached,
                "entries": queue.entries.iter().map(|e| json!({
                    "scan": e.scan, "state": e.state, "reason": e.reason,
                    "problems": e.problems, "face_likeness": e.face_likeness,
                    "reviewed": e.reviewed,
                })).collect::<Vec<_>>(),
            }))
        }
        Some(Command::Review {
            dir,
            landmarks_dir,
            session,
            screenshot,
            ..
        }) => {
            return Ok(Next::View(Box::new(ViewArgs {
                review: Some(dir),
                landmarks_dir,
                session,
                screenshot,
                width: 1280,
                height: 800,
                ..ViewArgs::default()
            })));
        }
        None => return Ok(Next::View(Box::new(cli.view))),
    };
    done.map(|()| Next::Done)
}

/// `facesynth info FILE` as a JSON value.
pub fn info(file: &Path) -> Result<serde_json::Value> {
    let (mesh, units) = io::read_mesh_and_units(file)?;
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
        "units": units_json(units),
    }))
}

/// A report's record of the unit a scan file was read in (its coordinates are in millimetres
/// whatever the file's): `file` (`mm`, `cm`, `m`), `mm_per_file_unit`, `guessed` (from the
/// mesh's size, or given by `--units`).
pub(crate) fn units_json(units: io::UnitsRead) -> serde_json::Value {
    json!({
        "file": units.symbol(), "mm_per_file_unit": units.mm_per_unit(), "guessed": units.guessed,
    })
}

/// `facesynth curvature IN OUT.ply`: the shape index as the PLY's per-vertex `quality`.
pub fn curvature(input: &Path, output: &Path, rings: usize) -> Result<serde_json::Value> {
    if io::MeshFormat::from_path(output)? != io::MeshFormat::Ply {
        anyhow::bail!(
            "{}: the shape index is written as PLY only",
            output.display()
        );
    }
    let mesh = io::read_mesh(input)?;
    let params = crate::curvature::CurvatureParams {
        rings,
        ..Default::default()
    };
    let start = std::time::Instant::now();
    let d = crate::curvature::compute(&mesh, &params)?;
    let millis = start.elapsed().as_secs_f64() * 1e3;
    let s: Vec<f32> = d.shape_index.iter().map(|&v| v as f32).collect();
    io::write_atomic(output, |w| {
        io::ply::write_binary(w, &mesh, Some(("quality", &s)))
    })?;
    let mean = d.shape_index.iter().sum::<f64>() / d.len().max(1) as f64;
    Ok(json!({
        "input": input, "output": output, "vertices": mesh.vertex_count(),
        "rings": rings, "mean_shape_index": mean, "millis": millis,
    }))
}

/// `facesynth register`: registers the built-in generic face to `scan`.
pub fn register(
    scan: &Path,
    landmarks: Option<&Path>,
    out: Option<&Path>,
    report: Option<&Path>,
) -> Result<serde_json::Value> {
    let generic = generic_face::build();
    let prepared = crate::pipeline::prepare_scan(scan, landmarks, &generic)?;
    crate::pipeline::notify_suspect(scan, prepared.suspect_reasons());
    let result = &prepared.registration;
    if let Some(path) = out {
        io::write_mesh(path, &result.mesh)?;
    }
    let mut value = result.report_json();
    value["face_region_distance_mm"] = prepared.face_region_report(&generic.feature_vertices)?;
    value["landmarks_detected"] = json!(prepared.detection.is_some());
    value["landmarks_source"] = json!(prepared.landmark_source());
    value["landmarks_file"] = json!(prepared.given.as_ref().map(|(p, _)| p));
    // The scan's unit: the report's figures and `--out` are in millimetres whatever it was.
    value["units"] = json!(prepared.units.map(units_json));
    if let Some(d) = &prepared.detection {
        value["landmark_warnings"] = json!(d.warnings);
        // What `landmarks --json` says of the detection: how face-like, how the head is turned
        // (the rotation the steps worked in), and whether the points are suspect.
        value["landmarks_confidence"] = json!(d.confidence());
        value["landmarks_orientation"] = json!(d.orientation_json());
        value["landmarks_suspect"] = json!(!d.suspect.is_empty());
        value["landmarks_suspect_reasons"] = json!(d.suspect);
    }
    if let Some(path) = report {
        io::write_text_atomic(path, &(serde_json::to_string_pretty(&value)? + "\n"))?;
    }
    Ok(value)
}

fn print_json(value: &serde_json::Value) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}
