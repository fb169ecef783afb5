//! `facesynth compare-expression`: the presets on a person's neutral face against a real
//! expression scan of that person, per region ([`crate::fem::compare`]).

use super::fem::{ScanPair, expression_set, round};
use crate::fem::compare::compare_presets;
use crate::fem::fit::FitParams;
use crate::io;
use anyhow::Result;
use serde_json::json;
use std::path::Path;

/// What to compare and where the points come from.
pub struct CompareInputs<'a> {
    pub neutral: &'a Path,
    pub expression: &'a Path,
    pub landmarks: Option<&'a Path>,
    pub expression_landmarks: Option<&'a Path>,
    /// Presets by name; empty: all.
    pub presets: &'a [String],
    pub preset_file: Option<&'a Path>,
}

/// `facesynth compare-expression`.
pub fn compare_expression(
    inputs: &CompareInputs,
    report: Option<&Path>,
) -> Result<serde_json::Value> {
    let set = expression_set(inputs.preset_file)?;
    let pair = ScanPair::prepare(
        inputs.neutral,
        inputs.expression,
        inputs.landmarks,
        inputs.expression_landmarks,
        None,
    )?;
    let wanted = (!inputs.presets.is_empty()).then_some(inputs.presets);
    let c = compare_presets(
        &pair.model,
        Some(&pair.neutral_scan),
        &pair.scan,
        pair.scan_landmarks.as_ref(),
        &set,
        wanted,
        &FitParams::default(),
    )?;
    let rows: Vec<serde_json::Value> = c
        .rows
        .iter()
        .map(|r| {
            let mut row = json!({
                "preset": r.preset,
                "whole_face_rms_mm": round(r.whole_face_rms_mm, 3),
            });
            for (name, v) in &r.region_rms_mm {
                row[format!("{name}_rms_mm")] = json!(round(*v, 3));
            }
            row
        })
        .collect();
    let best: serde_json::Map<String, serde_json::Value> = c
        .best()
        .into_iter()
        .map(|(region, (preset, rms, none))| {
            (
                region,
                json!({"preset": preset, "rms_mm": round(rms, 3), "none_rms_mm": round(none, 3)}),
            )
        })
        .collect();
    let value = json!({
        "neutral_scan": inputs.neutral,
        "expression_scan": inputs.expression,
        "alignment": c.alignment,
        "vertices": c.vertices,
        "region_vertices": c.region_vertices,
        // Per region: the preset nearest the real expression, and the neutral face's distance.
        "best": best,
        "rows": rows,
        "repairs": pair.repairs,
        "landmarks_source": pair.neutral_source,
        "expression_landmarks_source": pair.expression_source,
        "landmarks_suspect_reasons": pair.neutral_suspect,
        "expression_landmarks_suspect_reasons": pair.expression_suspect,
    });
    if let Some(path) = report {
        io::write_text_atomic(path, &(serde_json::to_string_pretty(&value)? + "\n"))?;
    }
    Ok(value)
}
