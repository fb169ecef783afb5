//! `facesynth landmarks`, `eval-landmarks`'s settings and `bench-landmarks`: feature points
//! (paper step 2) on the command line.

use crate::{denoise, io};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::Path;

/// `facesynth landmarks IN`: denoise (unless told not to), detect, report.
pub fn landmarks(
    input: &Path,
    denoise_first: bool,
    out: Option<&Path>,
    png: Option<&Path>,
    params: &crate::landmarks::LandmarkParams,
) -> Result<serde_json::Value> {
    let (mut mesh, units) = io::read_mesh_and_units(input)?;
    let start = std::time::Instant::now();
    if denoise_first {
        denoise::denoise(&mut mesh, &denoise::DenoiseParams::default())?;
    }
    let found = crate::landmarks::detect_with_descriptors(&mesh, params);
    let millis = start.elapsed().as_secs_f64() * 1e3;
    let (found, shape_index) = match found {
        Ok((report, d)) => (Ok(report), Some(d.shape_index)),
        Err(e) => (Err(e), None),
    };
    if let Some(path) = png {
        // The shape index the steps read; where detection failed, on the whole scan's sampling.
        let shape_index = match shape_index {
            Some(s) => s,
            None => {
                crate::curvature::compute(&mesh, &params.curvature_for(&mesh, None))?.shape_index
            }
        };
        let points = found.as_ref().ok().map(|r| &r.landmarks);
        crate::landmarks::render::write_png(path, &mesh, &shape_index, points)?;
    }
    let report = found.with_context(|| format!("{}: feature points not found", input.display()))?;
    if !report.suspect.is_empty() {
        eprintln!(
            "facesynth: {}: suspect feature points: {}",
            input.display(),
            report.suspect.join("; ")
        );
    }
    let mut value = report.to_json();
    value["millis"] = json!(millis);
    value["input"] = json!(input);
    value["denoised"] = json!(denoise_first);
    // The points are in millimetres whatever the file's unit: the unit says how to go back.
    value["units"] = super::units_json(units);
    // The landmark file schema (`pipeline::LandmarkFile`): what it is and whose points.
    value["source"] = json!(crate::pipeline::LandmarkSource::Detected);
    value["scan"] = json!(input.file_name().map(|n| n.to_string_lossy()));
    value["corrected"] = json!([]);
    if let Some(path) = out {
        io::write_text_atomic(path, &(serde_json::to_string_pretty(&value)? + "\n"))?;
    }
    Ok(value)
}

/// The feature-point settings of `landmarks` and `eval-landmarks`: the defaults, without face
/// localisation with `--no-localise`, with the file's axes given by `--facing` and `--up`.
pub(super) fn landmark_params(
    args: &super::LocaliseArgs,
) -> Result<crate::landmarks::LandmarkParams> {
    let mut params = crate::landmarks::LandmarkParams::default();
    if args.no_localise {
        params.localise = None;
    }
    if let (Some(facing), Some(up), Some(localise)) = (&args.facing, &args.up, &mut params.localise)
    {
        let axes = crate::landmarks::localise::AxisFrame::from_names(facing, up)
            .map_err(|e| anyhow::anyhow!("--facing {facing} --up {up}: {e}"))?;
        localise.axes = Some(axes);
    }
    Ok(params)
}

/// The smallest and the median (upper median for an even count) of repeated timings; `(NaN,
/// NaN)` for none.
pub(crate) fn min_median(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    match v.first() {
        Some(&min) => (min, v[v.len() / 2]),
        None => (f64::NAN, f64::NAN),
    }
}

/// `facesynth bench-landmarks IN`: wall time of denoise and of detection, `repeat` times
/// (single-threaded code; run it pinned to one core, e.g. `taskset -c 0`).
pub fn bench_landmarks(input: &Path, repeat: usize) -> Result<serde_json::Value> {
    let mesh = io::read_mesh(input)?;
    let params = crate::landmarks::LandmarkParams::default();
    let (mut den, mut det, mut total) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeat.max(1) {
        let mut m = mesh.clone();
        let t0 = std::time::Instant::now();
        denoise::denoise(&mut m, &denoise::DenoiseParams::default())?;
        let t1 = std::time::Instant::now();
        crate::landmarks::detect(&m, &params)?;
        let t2 = std::time::Instant::now();
        den.push((t1 - t0).as_secs_f64() * 1e3);
        det.push((t2 - t1).as_secs_f64() * 1e3);
        total.push((t2 - t0).as_secs_f64() * 1e3);
    }
    let stats = |v: &mut Vec<f64>| {
        let (min, median) = min_median(v);
        json!({"min": min, "median": median})
    };
    Ok(json!({
        "input": input, "vertices": mesh.vertex_count(), "repeat": repeat.max(1),
        "denoise_ms": stats(&mut den), "landmarks_ms": stats(&mut det),
        "total_ms": stats(&mut total),
    }))
}
