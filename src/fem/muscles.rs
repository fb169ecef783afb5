//! The 18 linear muscles (9 left/right pairs after Waters' classic set), defined **relative to
//! the 13 feature points** so they follow any registered face.
//!
//! A muscle's insertion (skin end) and origin (bone end) are each an [`Anchor`]: a feature
//! point plus an offset in the face frame of that face's own landmarks (`super::anchor`).
//! The asset stores one definition per pair for the subject's **left** side; the right muscle is
//! its mirror image (feature point mirrored, x offset negated), so left/right stay symmetric on
//! any face. A muscle acts on the skin-surface nodes within `radius` of its insertion with the
//! smooth fall-off weight `w = (1 − (d/r)²)²`; each node is pulled towards the origin with
//! force `force_n · w / Σw`, so the muscle's total force at activation 1 is `force_n` newtons.
//!
//! The same file defines `bulges`: pairs resolved exactly like muscles (and actuated after
//! them) whose "origin" lies in front of the skin, so they push outwards (or behind it, so
//! they pull the skin in). The 4 built-in pairs stand in for what the smile does to soft
//! tissue that a linear muscle cannot: `cheek_raiser` (AU6, the malar cheek), `buccal_bulge`
//! (the cheek beside the pulled lip corner), `infraorbital_bulge` (the lower lid) and
//! `nasolabial_fold` (inwards). See `assets/muscles.ron` for what they were measured to explain.

use super::FaceModel;
use super::anchor::{Anchor, FaceFrame};
use crate::feature_points::FeaturePoint;
use crate::{Error, FemError, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The built-in muscle definitions (`assets/muscles.ron`).
pub const BUILTIN_RON: &str = include_str!("../../assets/muscles.ron");

/// One muscle pair's definition (left side; the right side is mirrored).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MuscleDef {
    /// Pair name, snake_case; the muscles are `<name>_left` and `<name>_right`.
    pub name: String,
    /// What it does (for the editor's tooltips).
    #[serde(default)]
    pub description: String,
    /// Skin end: the nodes around it are pulled.
    pub insertion: Anchor,
    /// Bone end: the pull points towards it.
    pub origin: Anchor,
    /// Fall-off radius around the insertion, in face units (× half the outer-eye distance).
    pub radius: f64,
    /// Total force at activation 1, N.
    pub force_n: f64,
}

/// A set of muscle definitions as stored in RON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MuscleSet {
    pub muscles: Vec<MuscleDef>,
    /// The jaw's actuators (`jaw_open`, `jaw_left`, `jaw_right`, `jaw_forward`). A file without
    /// the field (older muscle files and autosaves) gets the built-in jaw; `jaw: None` turns it
    /// off (then the presets' jaw keys are ignored).
    #[serde(default = "builtin_jaw")]
    pub jaw: Option<super::jaw::JawDef>,
    /// Soft-tissue loads that are not among Waters' 18 muscles: pairs defined like a muscle
    /// whose "origin" lies in front of the skin (push out) or behind it (pull in). They stand
    /// in for the bunching of the cheeks and lids and the deepening fold that contracting
    /// muscles cause in a real face and that a linear small-strain model cannot produce (it
    /// does not thicken under shortening). Files without the field get the built-in ones;
    /// `bulges: []` turns them off.
    #[serde(default = "builtin_bulges")]
    pub bulges: Vec<MuscleDef>,
}

/// A muscle resolved on one face: its skin nodes and their forces at unit activation.
#[derive(Debug, Clone, PartialEq)]
pub struct Muscle {
    /// `<pair>_left` or `<pair>_right`.
    pub name: String,
    pub insertion_mm: DVec3,
    pub origin_mm: DVec3,
    pub radius_mm: f64,
    pub force_n: f64,
    /// Volume node ids (skin surface layer) the muscle pulls.
    pub nodes: Vec<u32>,
    /// Fall-off weights of `nodes` (sum 1).
    pub weights: Vec<f64>,
    /// Force on each of `nodes` at activation 1, N.
    pub forces_n: Vec<DVec3>,
}

impl Muscle {
    /// The full nodal force field (one per volume node, N) at activation 1.
    pub fn nodal_forces(&self, node_count: usize) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; node_count];
        for (&n, &f) in self.nodes.iter().zip(&self.forces_n) {
            out[n as usize] += f;
        }
        out
    }
}

/// The built-in jaw (`assets/muscles.ron`), for files written before the jaw.
fn builtin_jaw() -> Option<super::jaw::JawDef> {
    MuscleSet::builtin().jaw
}

/// The built-in soft-tissue loads, for files written before them.
fn builtin_bulges() -> Vec<MuscleDef> {
    MuscleSet::builtin().bulges
}

impl MuscleSet {
    /// The built-in 9 pairs = 18 muscles, the cheek loads and the jaw.
    pub fn builtin() -> Self {
        Self::parse(BUILTIN_RON, Path::new("assets/muscles.ron"))
            .expect("built-in muscles.ron parses")
    }

    /// Parses RON text (`path` only names it in errors) and validates it.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let set: MuscleSet = ron::from_str(text)
            .map_err(|e| Error::syntax(path, e.span.start.line, e.code.to_string()))?;
        let mut seen = std::collections::HashSet::new();
        for def in set.pairs() {
            if !seen.insert(def.name.as_str()) {
                return Err(Error::invalid(
                    path,
                    format!("two muscle or bulge pairs are named `{}`", def.name),
                ));
            }
            for anchor in [&def.insertion, &def.origin] {
                if FeaturePoint::from_name(&anchor.point).is_none() {
                    return Err(Error::invalid(
                        path,
                        format!(
                            "muscle `{}`: unknown feature point `{}`",
                            def.name, anchor.point
                        ),
                    ));
                }
            }
            if !(def.radius > 0.0 && def.radius.is_finite() && def.force_n.is_finite()) {
                return Err(Error::invalid(
                    path,
                    format!(
                        "muscle `{}`: radius must be > 0 and force_n finite",
                        def.name
                    ),
                ));
            }
        }
        if let Some(jaw) = &set.jaw {
            jaw.check().map_err(|why| Error::invalid(path, why))?;
            if set.pairs().any(|d| d.name == "jaw") {
                return Err(Error::invalid(
                    path,
                    "a muscle pair named `jaw` would clash with the jaw's actuators",
                ));
            }
        }
        Ok(set)
    }

    /// Reads a user muscle file (RON).
    pub fn load(path: &Path) -> Result<Self> {
        Self::parse(&crate::io::read_text_file(path)?, path)
    }

    /// Every left/right pair in model order: the muscles, then the bulges.
    pub fn pairs(&self) -> impl Iterator<Item = &MuscleDef> {
        self.muscles.iter().chain(&self.bulges)
    }

    /// [`pairs`](Self::pairs), mutable (the editor's definition sliders).
    pub fn pairs_mut(&mut self) -> impl Iterator<Item = &mut MuscleDef> {
        self.muscles.iter_mut().chain(&mut self.bulges)
    }

    /// Muscle and bulge names in model order: per pair, left then right.
    pub fn names(&self) -> Vec<String> {
        self.pairs()
            .flat_map(|d| [format!("{}_left", d.name), format!("{}_right", d.name)])
            .collect()
    }

    /// Actuator names in basis order: the muscles, the bulges, then the jaw's (if defined).
    pub fn actuator_names(&self) -> Vec<String> {
        let mut names = self.names();
        if self.jaw.is_some() {
            names.extend(super::jaw::ACTUATORS.iter().map(|s| s.to_string()));
        }
        names
    }

    /// Resolves every muscle and bulge on `model`'s surface (left then right per pair).
    pub fn resolve(&self, model: &FaceModel) -> Result<Vec<Muscle>> {
        let surface = &model.surface;
        let position =
            |p: FeaturePoint| surface.positions_mm[model.feature_vertices[p.index()] as usize];
        let frame = FaceFrame::new(position)?;
        let fixed = model.fixed_nodes();
        let mut out = Vec::with_capacity(2 * (self.muscles.len() + self.bulges.len()));
        for def in self.pairs() {
            for mirrored in [false, true] {
                let place = |a: &Anchor| a.place(surface, &frame, position, mirrored);
                let insertion_mm = place(&def.insertion);
                let origin_mm = place(&def.origin);
                let radius_mm = def.radius * frame.scale_xz_mm;
                let mut nodes = Vec::new();
                let mut weights = Vec::new();
                for (v, p) in surface.positions_mm.iter().enumerate() {
                    let d = (*p - insertion_mm).length();
                    if d < radius_mm && !fixed[v] {
                        let t = d / radius_mm;
                        nodes.push(v as u32);
                        weights.push((1.0 - t * t).powi(2));
                    }
                }
                let total: f64 = weights.iter().sum();
                let side = if mirrored { "right" } else { "left" };
                let name = format!("{}_{side}", def.name);
                if !(total > 0.0) {
                    return Err(FemError::Definition(format!(
                        "muscle `{name}`: no free skin node within {radius_mm:.1} mm of its insertion"
                    ))
                    .into());
                }
                weights.iter_mut().for_each(|w| *w /= total);
                let forces_n = nodes
                    .iter()
                    .zip(&weights)
                    .map(|(&v, &w)| {
                        (origin_mm - surface.positions_mm[v as usize]).normalize_or_zero()
                            * (def.force_n * w)
                    })
                    .collect();
                out.push(Muscle {
                    name,
                    insertion_mm,
                    origin_mm,
                    radius_mm,
                    force_n: def.force_n,
                    nodes,
                    weights,
                    forces_n,
                });
            }
        }
        Ok(out)
    }
}

/// The built-in set as RON cut before `field` (and the fields after it): a file written
/// before that field existed.
#[cfg(test)]
pub(crate) fn builtin_ron_before(field: &str) -> String {
    let mut text = ron::to_string(&MuscleSet::builtin()).unwrap();
    let at = text
        .find(&format!(",{field}:"))
        .unwrap_or_else(|| panic!("serialised {field} field"));
    text.truncate(at);
    text.push(')');
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_without_bulges_get_the_builtin_ones_and_names_must_not_repeat() {
        let builtin = MuscleSet::builtin();
        assert_eq!(builtin.bulges.len(), 4);
        let old = builtin_ron_before("bulges");
        let parsed = MuscleSet::parse(&old, Path::new("old.ron")).unwrap();
        assert_eq!(parsed.bulges, builtin.bulges);
        assert_eq!(parsed.jaw, builtin.jaw);
        // A bulge named like a muscle would give two actuators one name.
        let mut clash = builtin.clone();
        clash.bulges[0].name = clash.muscles[0].name.clone();
        let text = ron::to_string(&clash).unwrap();
        let err = MuscleSet::parse(&text, Path::new("clash.ron")).unwrap_err();
        assert!(err.to_string().contains("clash.ron"), "{err}");
        assert!(err.to_string().contains("named"), "{err}");
    }

    #[test]
    fn the_cheek_bulge_pushes_the_skin_outwards_and_the_muscles_do_not() {
        let face = crate::generic_face::build();
        let mut model = FaceModel::from_generic(&face, &super::super::FemParams::default())
            .expect("generic face model");
        let set = MuscleSet::builtin();
        model.set_muscles(&set).unwrap();
        let s = &model.surface;
        let outward = |m: &Muscle| -> f64 {
            let along: f64 = m
                .nodes
                .iter()
                .zip(&m.forces_n)
                .map(|(&v, f)| f.dot(s.normals[v as usize]))
                .sum();
            along / m.force_n
        };
        let all: Vec<(String, f64)> = model
            .muscles()
            .iter()
            .map(|m| (m.name.clone(), outward(m)))
            .collect();
        for (name, o) in &all {
            if name.starts_with("nasolabial_fold") {
                // The fold load pulls the skin in.
                assert!(*o < -0.3, "{name}: {o} ({all:?})");
            } else if name.contains("bulge") || name.starts_with("cheek_raiser") {
                // The push is forwards (the face's axis) and the lateral cheek faces sideways
                // too, so only part of it is along the normal.
                assert!(*o > 0.3, "{name}: {o} ({all:?})");
            } else {
                // A muscle pulls along the skin or into it, never much out of it.
                assert!(*o < 0.15, "{name}: {o} ({all:?})");
            }
        }
    }
}
