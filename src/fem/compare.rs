//! Synthetic against real, side by side (`facesynth compare-expression`): each expression
//! preset carried onto a person's neutral FEM face, against a real scan of that person with an
//! expression, as RMS distance per face region ([`Regions`]: mouth, cheeks, brows, eyes) and
//! over the whole face. The paper shows synthetic expressions but never measures how close
//! they come to real ones; this does, on any real pair.
//!
//! The expression scan is aligned as [`super::fit`] aligns it: Horn on its stable feature
//! points, then trimmed ICP on the model's upper forehead and nose, refused when those stable
//! parts do not agree. Each preset is then compared after re-aligning the scan on that
//! preset's own surface (an expression moves the forehead a little), and the row "none" (the
//! neutral face) is the baseline a preset has to beat. Vertices and misses are counted as in
//! the fit ([`super::fit::vertices_on_scans`], a vertex with no scan point within reach counts
//! as that far away).

use super::FaceModel;
use super::expressions::ExpressionSet;
use super::fit::Alignment;
use super::fit::{FitParams, align_scan, check_alignment, transform, vertices_on_scans};
use super::regions::{EXPRESSION_REGIONS, Regions};
use crate::feature_points::Landmarks;
use crate::mesh::SurfaceIndex;
use crate::{Mesh, Result};
use glam::DVec3;
use serde::Serialize;
use std::collections::BTreeMap;

/// The name of the baseline row: the neutral face, no expression.
pub const NO_EXPRESSION: &str = "none";

/// One preset's distances to the real expression, mm.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PresetDistance {
    pub preset: String,
    /// RMS over every compared vertex.
    pub whole_face_rms_mm: f64,
    /// RMS per expression region (`mouth`, `cheeks`, `brows`, `eyes`).
    pub region_rms_mm: BTreeMap<String, f64>,
}

/// What [`compare_presets`] measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// The rigid alignment on the neutral face and its residual on the stable parts.
    pub alignment: Alignment,
    /// Compared vertices, in all and per region.
    pub vertices: usize,
    pub region_vertices: BTreeMap<String, usize>,
    /// The baseline ([`NO_EXPRESSION`]) first, then the presets in the order given.
    pub rows: Vec<PresetDistance>,
}

impl Comparison {
    /// Per region (and `whole_face`): the preset nearest the real expression, its RMS, and the
    /// baseline's.
    pub fn best(&self) -> BTreeMap<String, (String, f64, f64)> {
        let base = &self.rows[0];
        let mut out = BTreeMap::new();
        let pick = |value: &dyn Fn(&PresetDistance) -> f64| {
            let best = self.rows[1..]
                .iter()
                .min_by(|a, b| value(a).total_cmp(&value(b)))
                .unwrap_or(base);
            (best.preset.clone(), value(best), value(base))
        };
        out.insert("whole_face".into(), pick(&|r| r.whole_face_rms_mm));
        for name in EXPRESSION_REGIONS {
            out.insert(name.into(), pick(&|r| r.region_rms_mm[name]));
        }
        out
    }
}

/// Compares `presets` (all of `set` when `None`) carried onto `model` (basis computed) with
/// the real `expression_scan` of the same person; `neutral_scan` limits the comparison to where
/// the registration reached the scan, `scan_landmarks` start the alignment.
pub fn compare_presets(
    model: &FaceModel,
    neutral_scan: Option<&Mesh>,
    expression_scan: &Mesh,
    scan_landmarks: Option<&Landmarks>,
    set: &ExpressionSet,
    presets: Option<&[String]>,
    params: &FitParams,
) -> Result<Comparison> {
    let rest = &model.surface.positions_mm;
    let neutral_index = neutral_scan.map(|m| SurfaceIndex::new(m, 4.0));
    let neutral = neutral_index.as_ref();
    let regions = Regions::of(&model.surface, &model.feature_vertices)?;
    let stable = regions.stable();
    let to_model = align_scan(
        model,
        &stable,
        rest,
        neutral,
        &SurfaceIndex::new(expression_scan, 4.0),
        scan_landmarks,
        params,
    )?;
    let aligned = transform(expression_scan, &to_model);
    let index = SurfaceIndex::new(&aligned, 4.0);
    let alignment = check_alignment(model, &regions, rest, neutral, &to_model, &index, params)?;
    let vertices = vertices_on_scans(model, &index, neutral, params)?;
    let used: Vec<bool> = {
        let mut u = vec![false; rest.len()];
        vertices.iter().for_each(|&v| u[v] = true);
        u
    };
    let region_vertices: BTreeMap<String, Vec<usize>> = EXPRESSION_REGIONS
        .iter()
        .map(|&name| {
            let vs = regions.expression_region(name).expect("known region");
            (
                name.to_string(),
                vs.iter().copied().filter(|&v| used[v]).collect(),
            )
        })
        .collect();
    let names = model.actuator_names();
    let chosen: Vec<&super::expressions::Expression> = match presets {
        None => set.expressions.iter().collect(),
        Some(wanted) => wanted
            .iter()
            .map(|w| set.lookup(w, "preset"))
            .collect::<Result<_>>()?,
    };
    let distance = |name: &str, u: &[DVec3]| -> Result<PresetDistance> {
        // Re-align on this preset's surface: its forehead and nose moved a little too.
        let surface: Vec<DVec3> = rest.iter().zip(u).map(|(p, d)| *p + *d).collect();
        let t = align_scan(model, &stable, &surface, neutral, &index, None, params)?;
        let again = SurfaceIndex::new(&transform(&aligned, &t), 4.0);
        // Each compared vertex's squared distance once; the regions are subsets.
        let max = params.max_distance_mm;
        let mut d2 = vec![0.0; rest.len()];
        for &v in &vertices {
            let d = again.closest(rest[v] + u[v], max).map_or(max, |(d, _)| d);
            d2[v] = d * d;
        }
        let rms =
            |vs: &[usize]| (vs.iter().fold(0.0, |s, &v| s + d2[v]) / vs.len().max(1) as f64).sqrt();
        Ok(PresetDistance {
            preset: name.to_string(),
            whole_face_rms_mm: rms(&vertices),
            region_rms_mm: region_vertices
                .iter()
                .map(|(n, vs)| (n.clone(), rms(vs)))
                .collect(),
        })
    };
    let mut rows = vec![distance(NO_EXPRESSION, &vec![DVec3::ZERO; rest.len()])?];
    let mut u = Vec::new();
    for e in chosen {
        model.combine_surface(&e.activations_for(&names)?, &mut u)?;
        rows.push(distance(&e.name, &u)?);
    }
    Ok(Comparison {
        alignment,
        vertices: vertices.len(),
        region_vertices: region_vertices
            .iter()
            .map(|(n, vs)| (n.clone(), vs.len()))
            .collect(),
        rows,
    })
}
