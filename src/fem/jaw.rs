//! The jaw: the mandible as a prescribed rigid motion of the bone under the lower face.
//!
//! Waters' 18 linear muscles cannot open the mouth: in a laugh, a yawn or surprise the chin drops
//! because the mandible rotates, and the soft tissue follows the bone. The model therefore gets
//! four jaw actuators besides the muscles, each a **prescribed displacement** of the fixed
//! nodes over the mandible (the cranium layer under the lower face, and the border nodes there),
//! solved like a muscle into a basis vector (`K_ff u_f = −K_fp u_p`), so a jaw slider is still an
//! 18 + 4-term sum:
//!
//! * `jaw_open` — rotation about the opening axis, **degrees** per unit. The axis is parallel to
//!   the face's x̂ (ear to ear) through the [`JawDef::hinge`] anchor, placed about where the
//!   condyle sits: the first ~20 mm of opening between the teeth are a pure rotation there (the
//!   condyle's forward glide comes later, in wide yawns). The motion is the linearised rotation
//!   `θ x̂ × (p − hinge)` (linear elasticity). Its error against the true rotation is
//!   `r √((1 − cos θ)² + (θ − sin θ)²)` for a point `r` from the hinge: 1.5 % of `r` at 10°,
//!   3.4 % at 15°, 6 % at 20° (the editor slider's end), and it lengthens the jaw rather than
//!   turning it.
//! * `jaw_left` / `jaw_right` — sideways shift towards the subject's left / right, **mm** per unit
//!   (FACS AU30), two non-negative actuators so fits stay non-negative and the pair mirrors.
//! * `jaw_forward` — thrust along the face's forward axis ẑ, **mm** per unit (FACS AU29). Fitting
//!   cara1's smile chose 4.4 mm of it (RMS 2.31 → 2.11 mm): that scan's lower face stands 2–6 mm
//!   in front of its neutral scan, which no muscle pull along the skin produces.
//!
//! **Which bone moves.** A surface vertex lies over the mandible when it is below the mouth-corner
//! line (by [`JawDef::below_mouth`] face units of y). The mouth is a slit whose two lips are
//! separate vertices, so the lower lip is over the mandible and the upper lip is not; the slit's
//! own rim is classified by topology, not height (its loop split at the two corner vertices: the
//! lower arc 1, the upper arc 0, the corners ½), so a registered lip line that sags below the
//! corners does not put the upper lip on the jaw. The 0/1
//! indicator is then averaged over the 1-ring [`JawDef::blend_rounds`] times. Across the slit
//! nothing mixes, but beside the mouth corners the edge between the cheek (fixed maxilla) and
//! the jaw becomes a ramp a few rings wide instead of a shear within one element. A fixed node
//! follows the mandible with the weight of its surface vertex; free nodes are solved.

use super::anchor::{Anchor, FaceFrame};
use super::{FaceModel, HexMesh};
use crate::feature_points::FeaturePoint;
use crate::mesh::Topology;
use crate::{FemError, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Actuator names, in basis order after the muscles.
pub const ACTUATORS: [&str; 4] = ["jaw_open", "jaw_left", "jaw_right", "jaw_forward"];

/// The jaw's definition (in `assets/muscles.ron`, relative to the feature points).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JawDef {
    /// What it does (for tooltips).
    #[serde(default)]
    pub description: String,
    /// A point on the effective opening axis: a feature point plus an offset in face units,
    /// placed like a muscle anchor (snapped to the skin, then `z` face units along ẑ).
    pub hinge: Anchor,
    /// The mandible starts this far below the mouth-corner line, face units of y (≥ 0; 0: at the
    /// line, so the lower lip moves with the jaw).
    #[serde(default)]
    pub below_mouth: f64,
    /// 1-ring averaging rounds that soften the mandible's edge beside the mouth (count).
    pub blend_rounds: usize,
}

/// The jaw resolved on one face.
#[derive(Debug, Clone, PartialEq)]
pub struct Jaw {
    /// A point on the opening axis, mm.
    pub hinge_mm: DVec3,
    /// The opening axis and the sideways direction: the face's x̂ (towards the subject's left).
    pub axis: DVec3,
    /// The face's forward axis ẑ (jaw thrust).
    pub forward: DVec3,
    /// The face's up axis ŷ.
    pub up: DVec3,
    /// The mouth slit's boundary loop on the surface (empty if the face has none): the lips'
    /// rim, which the jaw opens.
    pub mouth_rim: Vec<u32>,
    /// Per surface vertex: the share of the mandible's motion the bone under it follows, 0–1.
    pub weights: Vec<f64>,
}

impl JawDef {
    /// Checks the definition; the message names what is wrong.
    pub fn check(&self) -> std::result::Result<(), String> {
        if FeaturePoint::from_name(&self.hinge.point).is_none() {
            return Err(format!("jaw: unknown feature point `{}`", self.hinge.point));
        }
        if !(self.below_mouth >= 0.0 && self.below_mouth.is_finite())
            || self.hinge.offset.iter().any(|v| !v.is_finite())
        {
            return Err("jaw: below_mouth must be ≥ 0 and the hinge offset finite".into());
        }
        Ok(())
    }

    /// Places the hinge and the mandible weights on `model`'s surface.
    pub fn resolve(&self, model: &FaceModel) -> Result<Jaw> {
        let surface = &model.surface;
        let position =
            |p: FeaturePoint| surface.positions_mm[model.feature_vertices[p.index()] as usize];
        let frame = FaceFrame::new(position)?;
        self.check().map_err(FemError::Definition)?;
        let hinge_mm = self.hinge.place(surface, &frame, position, false);
        let mouth = (position(FeaturePoint::MouthCornerLeft)
            + position(FeaturePoint::MouthCornerRight))
            * 0.5;
        let limit_mm = self.below_mouth * frame.scale_y_mm;
        let mut weights: Vec<f64> = surface
            .positions_mm
            .iter()
            .map(|p| f64::from(u8::from((*p - mouth).dot(frame.y) < -limit_mm)))
            .collect();
        let corners = [
            FeaturePoint::MouthCornerLeft,
            FeaturePoint::MouthCornerRight,
        ]
        .map(|p| model.feature_vertices[p.index()]);
        let mouth_rim = crate::generic_face::boundary_loops(surface)
            .into_iter()
            .find(|l| corners.iter().all(|c| l.contains(c)))
            .unwrap_or_default();
        if !mouth_rim.is_empty() {
            let rim = &mouth_rim;
            // The two arcs between the corners; the one lower on average is the lower lip.
            let start = rim.iter().position(|&v| v == corners[0]).expect("contains");
            let turned: Vec<u32> = rim[start..].iter().chain(&rim[..start]).copied().collect();
            let split = turned
                .iter()
                .position(|&v| v == corners[1])
                .expect("contains");
            let (a, b) = (&turned[1..split], &turned[split + 1..]);
            let height = |arc: &[u32]| {
                arc.iter()
                    .map(|&v| surface.positions_mm[v as usize].dot(frame.y))
                    .sum::<f64>()
                    / arc.len().max(1) as f64
            };
            let (lower, upper) = if height(a) < height(b) {
                (a, b)
            } else {
                (b, a)
            };
            lower.iter().for_each(|&v| weights[v as usize] = 1.0);
            upper.iter().for_each(|&v| weights[v as usize] = 0.0);
            corners.iter().for_each(|&v| weights[v as usize] = 0.5);
        }
        let topology = Topology::new(surface);
        let mut next = weights.clone();
        for _ in 0..self.blend_rounds {
            for (v, w) in next.iter_mut().enumerate() {
                let ring = topology.neighbours(v);
                let sum: f64 = ring.iter().map(|&u| weights[u as usize]).sum();
                *w = (weights[v] + sum) / (1 + ring.len()) as f64;
            }
            std::mem::swap(&mut weights, &mut next);
        }
        let jaw = Jaw {
            hinge_mm,
            axis: frame.x,
            forward: frame.z,
            up: frame.y,
            mouth_rim,
            weights,
        };
        if !jaw.moves_some(model.fixed_nodes()) {
            return Err(FemError::Definition(
                "jaw: no fixed node lies under the face below the mouth".into(),
            )
            .into());
        }
        Ok(jaw)
    }
}

impl Jaw {
    /// Whether some node of `fixed` lies under the jaw (a weight above 0), i.e. the jaw has
    /// bone to move.
    pub fn moves_some(&self, fixed: &[bool]) -> bool {
        let n = self.weights.len();
        (0..fixed.len()).any(|node| fixed[node] && self.weights[node % n] > 0.0)
    }

    /// Displacement (mm) of every volume node at unit activation of actuator `k` (index into
    /// [`ACTUATORS`]): the mandible's motion on the fixed nodes, zero on the free ones.
    pub fn prescribed(&self, k: usize, volume: &HexMesh, fixed: &[bool]) -> Vec<DVec3> {
        let n = self.weights.len();
        volume
            .nodes_mm
            .iter()
            .enumerate()
            .map(|(node, &p)| {
                let w = self.weights[node % n];
                if !fixed[node] || w == 0.0 {
                    return DVec3::ZERO;
                }
                let unit = match k {
                    0 => self.axis.cross(p - self.hinge_mm) * 1f64.to_radians(),
                    1 => self.axis,
                    2 => -self.axis,
                    _ => self.forward,
                };
                unit * w
            })
            .collect()
    }
}
