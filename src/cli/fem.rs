//! `facesynth synthesize`, `export-fem` and `bench fem`: the FEM face on the command line.

use crate::fem::expressions::ExpressionSet;
use crate::fem::muscles::MuscleSet;
use crate::fem::{FaceModel, FemParams, HexMesh};
use crate::generic_face::{self, GenericFace};
use crate::io;
use anyhow::{Context, Result};
use glam::DVec3;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// The face to build the model on: the generic face, or the generic face registered to `scan`
/// (denoised, feature points detected or read from `landmarks`); with why the detected points
/// are suspect (also said on stderr; empty where they are not).
pub fn face_for(
    scan: Option<&Path>,
    landmarks: Option<&Path>,
) -> Result<(GenericFace, Vec<String>)> {
    let generic = generic_face::build();
    let Some(scan) = scan else {
        return Ok((generic, Vec::new()));
    };
    let prepared = crate::pipeline::prepare_scan(scan, landmarks, &generic)?;
    let suspect = crate::pipeline::notify_suspect(scan, prepared.suspect_reasons());
    let face = GenericFace {
        mesh: prepared.registration.mesh,
        feature_vertices: generic.feature_vertices,
    };
    Ok((face, suspect))
}

/// Presets: the built-ins plus an optional user file (same names replace built-ins).
pub fn expression_set(user: Option<&Path>) -> Result<ExpressionSet> {
    let mut set = ExpressionSet::builtin();
    if let Some(path) = user {
        set.merge(ExpressionSet::load(path)?);
    }
    Ok(set)
}

/// The muscles in `user` (RON), or the built-in ones.
pub fn muscle_set(user: Option<&Path>) -> Result<MuscleSet> {
    match user {
        Some(path) => Ok(MuscleSet::load(path)?),
        None => Ok(MuscleSet::builtin()),
    }
}

/// Builds, factors and solves the muscle basis, through the same repairs as `augment` and the
/// editor (folded quads unfolded, then thinner layers or local smoothing where the layers
/// would invert), so every command accepts the scans `augment` accepts.
pub fn solved_model(
    face: &GenericFace,
    muscles: Option<&Path>,
) -> Result<(FaceModel, crate::pipeline::FemRepairs)> {
    let (mut model, repairs) = crate::pipeline::repaired_fem_model(
        &face.mesh,
        face.feature_vertices,
        &FemParams::default(),
    )?;
    model.factor()?;
    model.set_muscles(&muscle_set(muscles)?)?;
    model.compute_basis()?;
    Ok((model, repairs))
}

pub(super) fn round(x: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (x * s).round() / s
}

/// `facesynth synthesize`.
pub fn synthesize(
    scan: Option<&Path>,
    landmarks: Option<&Path>,
    out: &Path,
    expressions: &str,
    presets: Option<&Path>,
    muscles: Option<&Path>,
    png: bool,
) -> Result<serde_json::Value> {
    let (face, suspect) = face_for(scan, landmarks)?;
    let set = expression_set(presets)?;
    let selected = set.select(expressions)?;
    let (model, repairs) = solved_model(&face, muscles)?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    io::write_mesh(&out.join("neutral.obj"), &model.surface)?;
    let names: Vec<String> = model.actuator_names();
    let mut report = serde_json::Map::new();
    let mut u = Vec::new();
    for e in selected {
        let a = e.activations_for(&names)?;
        model.combine_surface(&a, &mut u)?;
        let max = u.iter().map(|d| d.length()).fold(0.0, f64::max);
        let mean = u.iter().map(|d| d.length()).sum::<f64>() / u.len().max(1) as f64;
        let deformed = model.deformed_surface(&a)?;
        io::write_mesh(&out.join(format!("{}.obj", e.name)), &deformed)?;
        if png {
            let magnitude: Vec<f64> = u.iter().map(|d| d.length()).collect();
            let img = crate::fem::picture::render_front(&deformed, &magnitude, 10.0, 480);
            crate::io::write_png(&out.join(format!("{}.png", e.name)), &img)?;
        }
        report.insert(
            e.name.clone(),
            json!({"max_displacement_mm": round(max, 4), "mean_displacement_mm": round(mean, 4)}),
        );
    }
    let value = json!({
        "dofs": model.dofs(),
        "elements": model.elements(),
        "factor_millis": round(model.timings.factor_millis, 3),
        "basis_millis": round(model.timings.basis_millis, 3),
        "min_scaled_jacobian": round(model.quality.min_scaled_jacobian, 4),
        "thinned_vertices": model.extrusion.thinned_vertices,
        "min_thickness_factor": round(model.extrusion.min_thickness_factor, 4),
        "mean_scaled_jacobian": round(model.quality.mean_scaled_jacobian, 4),
        "repairs": repairs,
        "landmarks_suspect_reasons": suspect,
        "expressions": report,
    });
    io::write_text_atomic(
        &out.join("report.json"),
        &(serde_json::to_string_pretty(&value)? + "\n"),
    )?;
    Ok(value)
}

/// `facesynth export-fem`.
pub fn export_fem(
    scan: Option<&Path>,
    landmarks: Option<&Path>,
    expression: &str,
    vtk: &Path,
    presets: Option<&Path>,
) -> Result<serde_json::Value> {
    let (face, _) = face_for(scan, landmarks)?;
    let set = expression_set(presets)?;
    let e = set.get(expression).with_context(|| {
        format!(
            "unknown expression `{expression}` (known: {})",
            set.names().join(", ")
        )
    })?;
    let (model, _) = solved_model(&face, None)?;
    let names: Vec<String> = model.actuator_names();
    let a = e.activations_for(&names)?;
    let u = model.combine_volume(&a)?;
    let f = model.forces(&a);
    let eq = model.equilibrium(&u, &f)?;
    crate::fem::vtk::write(vtk, &model, &u, &f, &eq.reaction_n)?;
    let v = |x: DVec3| [x.x, x.y, x.z].map(|c| c as f32);
    Ok(json!({
        "vtk": vtk, "expression": expression, "points": model.volume.nodes_mm.len(),
        "cells": model.elements(), "dofs": model.dofs(),
        "max_displacement_mm": round(u.iter().map(|d| d.length()).fold(0.0, f64::max), 4),
        // The balance a cross-check starts from: Σ reactions = −Σ loads; free nodes balanced.
        "applied_force_sum_n": v(eq.applied_sum_n),
        "reaction_sum_n": v(eq.reaction_sum_n),
        "free_residual_n": eq.free_residual_n,
    }))
}

fn millis(start: Instant) -> f64 {
    round(start.elapsed().as_secs_f64() * 1e3, 3)
}

/// Times one model: build (assembly), factor, one solve, basis, slider update, modulus change.
fn bench_model(face: &GenericFace) -> Result<serde_json::Value> {
    let t = Instant::now();
    let mut model = FaceModel::from_generic(face, &FemParams::default())?;
    let build_millis = millis(t);
    let t = Instant::now();
    model.factor()?;
    let factor_millis = millis(t);
    model.set_muscles(&MuscleSet::builtin())?;
    let forces = model.muscles()[0].nodal_forces(model.volume.nodes_mm.len());
    // Median of repeated solves: the editor re-solves a muscle whenever its force changes.
    let mut solves: Vec<f64> = (0..11)
        .map(|_| {
            let t = Instant::now();
            model.solve(&forces).map(|_| millis(t))
        })
        .collect::<std::result::Result<_, _>>()?;
    let (solve_min_millis, solve_millis) = super::min_median(&mut solves);
    let t = Instant::now();
    model.compute_basis()?;
    let basis_millis = millis(t);
    let names: Vec<String> = model.actuator_names();
    let a = ExpressionSet::builtin().expressions[0].activations_for(&names)?;
    let mut u = Vec::new();
    let reps = 200;
    let t = Instant::now();
    for _ in 0..reps {
        model.combine_surface(&a, &mut u)?;
    }
    let slider_micros = round(t.elapsed().as_secs_f64() * 1e6 / reps as f64, 2);
    let p = model.params;
    let t = Instant::now();
    let mut skin = p.skin;
    skin.young_modulus_pa *= 1.1;
    model.set_materials(skin, p.fat)?;
    model.factor()?;
    let modulus_change_millis = millis(t);
    model.compute_basis()?;
    let mut m = model.muscles()[0].clone();
    m.forces_n.iter_mut().for_each(|f| *f *= 1.5);
    let t = Instant::now();
    model.set_muscle(0, m)?;
    let resolve_one_muscle_millis = millis(t);
    Ok(json!({
        "dofs": model.dofs(),
        "elements": model.elements(),
        "nonzeros_upper": model.system().nonzeros(),
        // One solve streams the factor twice; the split says how much of it two threads share.
        "factor_entries": model.solver().factor_entries(),
        // The factorization's probe solve (above 1e-12 single solves get refined).
        "probe_relative_residual": model.solver().probe_residual(),
        "one_solve_split_entries": model.solver().split_entries().map(|(serial, halves)| {
            json!({"serial": serial, "halves": halves})
        }),
        "extrusion_millis": round(model.timings.extrusion_millis, 3),
        "assembly_millis": round(model.timings.assembly_millis, 3),
        "build_millis": build_millis,
        "symbolic_analysis_millis": round(model.timings.analysis_millis, 3),
        "factorization_millis": factor_millis,
        "one_solve_millis": solve_millis,
        "one_solve_min_millis": solve_min_millis,
        // The whole basis: 18 muscles, 8 soft-tissue loads and the jaw's 4 prescribed motions.
        "actuators": model.actuator_count(),
        "basis_millis": basis_millis,
        "factor_plus_basis_millis": round(factor_millis + basis_millis, 3),
        "slider_update_micros": slider_micros,
        "modulus_change_refactor_millis": modulus_change_millis,
        "resolve_one_muscle_millis": round(resolve_one_muscle_millis, 3),
    }))
}

/// Each quad of `face` split into 4 (4× the elements), feature vertices kept.
fn refine_face(face: &GenericFace) -> GenericFace {
    let mesh = &face.mesh;
    let mut positions = mesh.positions_mm.clone();
    let mut edge_mid = std::collections::HashMap::new();
    let mut mid = |a: u32, b: u32, positions: &mut Vec<glam::DVec3>| -> u32 {
        *edge_mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            positions.push((positions[a as usize] + positions[b as usize]) * 0.5);
            (positions.len() - 1) as u32
        })
    };
    let mut faces = Vec::new();
    for poly in mesh.faces.iter() {
        if poly.len() != 4 {
            faces.push(poly.to_vec());
            continue;
        }
        let c: glam::DVec3 = poly
            .iter()
            .map(|&v| positions[v as usize])
            .sum::<glam::DVec3>()
            / 4.0;
        positions.push(c);
        let ci = (positions.len() - 1) as u32;
        let m: Vec<u32> = (0..4)
            .map(|k| mid(poly[k], poly[(k + 1) % 4], &mut positions))
            .collect();
        for k in 0..4 {
            faces.push(vec![poly[k], m[k], ci, m[(k + 3) % 4]]);
        }
    }
    GenericFace {
        mesh: crate::Mesh::from_faces(positions, faces),
        feature_vertices: face.feature_vertices,
    }
}

/// `facesynth bench fem`: JSON timings on the generic face and on 4× its elements.
pub fn bench_fem() -> Result<serde_json::Value> {
    let face = generic_face::build();
    let base = bench_model(&face)?;
    let fine = bench_model(&refine_face(&face))?;
    // The shared test slab of ../shared/STACK.md: 53×53×3 nodes.
    let slab = HexMesh::block(glam::DVec3::new(130.0, 130.0, 12.0), 52, 52, 2);
    let fixed: Vec<bool> = slab.nodes_mm.iter().map(|p| p.z == 0.0).collect();
    let t = Instant::now();
    let mut system = crate::fem::assembly::ReducedSystem::new(&slab, &fixed, &[0.45])?;
    let slab_assembly = millis(t);
    let t = Instant::now();
    system.combine(&[5600.0]);
    let combine = millis(t);
    let t = Instant::now();
    let mut solver = crate::fem::solver::CachedCholesky::analyze(
        system.dofs(),
        &system.col_ptr,
        &system.row_idx,
    )?;
    let analysis = millis(t);
    let t = Instant::now();
    solver.factor(&system.col_ptr, &system.row_idx, &system.values)?;
    let factor = millis(t);
    let mut rhs = vec![1e-3; system.dofs()];
    let t = Instant::now();
    solver.solve_in_place(&mut rhs)?;
    let solve = millis(t);
    Ok(json!({
        "note": "wall-clock on this machine; debug or release as built",
        "threads": rayon::current_num_threads(),
        "generic_face": base,
        "generic_face_4x_elements": fine,
        "slab_53x53x3": {
            "dofs": system.dofs(), "assembly_millis": slab_assembly,
            "combine_millis": combine, "symbolic_millis": analysis,
            "factor_millis": factor, "one_solve_millis": solve,
        },
    }))
}

/// A neutral scan's solved FEM face and an expression scan of the same person, ready to fit
/// or compare (`fit-expression`, `compare-expression`).
pub struct ScanPair {
    pub model: FaceModel,
    pub repairs: crate::pipeline::FemRepairs,
    /// The denoised neutral scan (where the registration reached it bounds the comparison).
    pub neutral_scan: crate::Mesh,
    /// The denoised expression scan.
    pub scan: crate::Mesh,
    /// Its feature points (they start the rigid alignment): read, or detected; `None` where
    /// detection failed (the alignment then uses the stable regions alone).
    pub scan_landmarks: Option<crate::Landmarks>,
    pub neutral_source: crate::pipeline::LandmarkSource,
    pub expression_source: Option<crate::pipeline::LandmarkSource>,
    /// Why each scan's detected points are suspect (said on stderr too; empty: they are not).
    pub neutral_suspect: Vec<String>,
    pub expression_suspect: Vec<String>,
}

impl ScanPair {
    pub fn prepare(
        neutral: &Path,
        expression: &Path,
        landmarks: Option<&Path>,
        expression_landmarks: Option<&Path>,
        muscles: Option<&Path>,
    ) -> Result<Self> {
        let generic = generic_face::build();
        let prepared = crate::pipeline::prepare_scan(neutral, landmarks, &generic)?;
        let neutral_suspect = crate::pipeline::notify_suspect(neutral, prepared.suspect_reasons());
        let neutral_source = prepared.landmark_source();
        let face = GenericFace {
            mesh: prepared.registration.mesh,
            feature_vertices: generic.feature_vertices,
        };
        let (model, repairs) = solved_model(&face, muscles)?;
        let (scan, found) =
            crate::pipeline::prepare_expression_scan(expression, expression_landmarks)?;
        let expression_source = found.as_ref().map(|f| f.source());
        let expression_suspect = found.as_ref().map_or(Vec::new(), |f| {
            crate::pipeline::notify_suspect(expression, f.suspect_reasons())
        });
        let scan_landmarks = found.map(|f| f.landmarks);
        Ok(ScanPair {
            model,
            repairs,
            neutral_scan: prepared.denoised,
            scan,
            scan_landmarks,
            neutral_source,
            expression_source,
            neutral_suspect,
            expression_suspect,
        })
    }
}

/// Where `fit-expression` writes: the preset, and optionally the residual map.
pub struct FitOutputs<'a> {
    pub preset: &'a Path,
    pub residual_ply: Option<&'a Path>,
    /// A front view of the fitted face coloured by the distance to the scan (0–5 mm).
    pub residual_png: Option<&'a Path>,
}

/// `facesynth fit-expression`.
pub fn fit_expression(
    neutral: &Path,
    expression: &Path,
    landmarks: Option<&Path>,
    expression_landmarks: Option<&Path>,
    outputs: &FitOutputs,
    name: Option<&str>,
    muscles: Option<&Path>,
) -> Result<serde_json::Value> {
    use crate::fem::expressions::Expression;
    use crate::fem::fit::{FitParams, fit_expression};
    let ScanPair {
        model,
        repairs,
        neutral_scan,
        scan,
        scan_landmarks,
        neutral_source,
        expression_source,
        neutral_suspect,
        expression_suspect,
    } = ScanPair::prepare(
        neutral,
        expression,
        landmarks,
        expression_landmarks,
        muscles,
    )?;
    let presets = ExpressionSet::builtin();
    let params = FitParams::default();
    let fit = fit_expression(
        &model,
        Some(&neutral_scan),
        &scan,
        scan_landmarks.as_ref(),
        &presets,
        &params,
    )?;
    let names: Vec<String> = model.actuator_names();
    let activations: std::collections::BTreeMap<String, f64> = names
        .iter()
        .zip(&fit.activations)
        .map(|(n, &a)| (n.clone(), round(a, 4)))
        .collect();
    let name = name.map(str::to_string).unwrap_or_else(|| {
        expression
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "fitted".into())
    });
    let preset = crate::fem::expressions::ExpressionSet {
        expressions: vec![Expression {
            name: name.clone(),
            description: format!("fitted to {}", expression.display()),
            action_units: Vec::new(),
            activations: activations.clone(),
        }],
    };
    let text = ron::ser::to_string_pretty(&preset, ron::ser::PrettyConfig::default())?;
    io::write_text_atomic(outputs.preset, &(text + "\n"))?;
    let residual = if outputs.residual_ply.is_some() || outputs.residual_png.is_some() {
        let (fitted, r) = fit.residual_map(&model, &params)?;
        if let Some(path) = outputs.residual_ply {
            let quality: Vec<f32> = r.iter().map(|d| d.unwrap_or(0.0) as f32).collect();
            io::write_atomic(path, |w| {
                io::ply::write_binary(w, &fitted, Some(("quality", &quality)))
            })?;
        }
        if let Some(path) = outputs.residual_png {
            let magnitude: Vec<f64> = r.iter().map(|d| d.map_or(0.0, f64::abs)).collect();
            let img = crate::fem::picture::render_front(
                &fitted,
                &magnitude,
                crate::fem::fit::RESIDUAL_MAX_MM,
                480,
            );
            crate::io::write_png(path, &img)?;
        }
        let inside: Vec<f64> = r.iter().flatten().copied().collect();
        let rms = (inside.iter().map(|d| d * d).sum::<f64>() / inside.len().max(1) as f64).sqrt();
        Some(json!({
            "path": outputs.residual_ply,
            "png": outputs.residual_png,
            "vertices_on_scan": inside.len(),
            "vertices_off_scan": r.len() - inside.len(),
            "rms_mm": round(rms, 4),
            "max_in_front_mm": round(inside.iter().copied().fold(0.0, f64::max), 4),
            "max_behind_mm": round(-inside.iter().copied().fold(0.0, f64::min), 4),
        }))
    } else {
        None
    };
    let contributions: Vec<serde_json::Value> = fit
        .ranked_contributions(&names)
        .iter()
        .map(|(n, c)| json!([n, round(*c, 3)]))
        .collect();
    let (closest, closest_rms) = fit
        .closest_preset
        .map(|(n, r)| (Some(n), Some(round(r, 4))))
        .unwrap_or((None, None));
    Ok(json!({
        "name": name,
        "out": outputs.preset,
        "activations": activations,
        "rms_before_mm": round(fit.rms_before_mm, 4),
        "rms_after_mm": round(fit.rms_after_mm, 4),
        // The same over the mouth, cheeks and chin (what an expression moves most).
        "moving_rms_before_mm": round(fit.moving_rms_before_mm, 4),
        "moving_rms_after_mm": round(fit.moving_rms_after_mm, 4),
        "moving_vertices": fit.moving_vertices,
        // What each actuator moves of the fitted face (RMS along the normals, mm), largest
        // first: comparable across muscles, soft-tissue loads and the jaw, unlike activations.
        "contributions_mm": contributions,
        // The same as shares per group of actuators (smile, lip_raise, lip_depress, brows,
        // jaw, other): which kind of motion explains the expression.
        "contribution_share": crate::fem::fit::contribution_shares(&names, &fit.contributions_mm)
            .into_iter()
            .map(|(g, s)| (g, round(s, 3)))
            .collect::<std::collections::BTreeMap<_, _>>(),
        "rms_model_to_neutral_scan_mm": fit.rms_neutral_scan_mm.map(|r| round(r, 4)),
        "repairs": repairs,
        "closest_preset": closest,
        "closest_preset_rms_mm": closest_rms,
        "vertices_used": fit.vertices_used,
        "residual_ply": residual,
        // The rigid motion of the expression scan onto the model and the stable parts'
        // agreement after it.
        "alignment": fit.alignment,
        // Where each scan's points came from (a correction file beside it, or detection;
        // `null`: the expression scan's detection failed, the alignment used no points).
        "landmarks_source": neutral_source,
        "expression_landmarks_source": expression_source,
        "landmarks_suspect_reasons": neutral_suspect,
        "expression_landmarks_suspect_reasons": expression_suspect,
        "landmarks_file": landmarks,
        "expression_landmarks_file": expression_landmarks,
    }))
}
