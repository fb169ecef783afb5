//! Anchors: points given by a feature point and an offset in the **face frame** of that face's
//! own landmarks, so muscle ends and the jaw hinge follow any registered face.
//!
//! * `x̂` from the right to the left outer eye corner (the subject's left is +x),
//! * `ŷ` from the chin towards the forehead, made orthogonal to `x̂`,
//! * `ẑ = x̂ × ŷ`, out of the face;
//! * offsets are in face units: x and z multiplied by half the outer-eye-corner distance
//!   (≈ 48 mm on the generic face), y by the vertical distance from the mouth-corner line to
//!   the inner-eye-corner line (≈ 67 mm).
//!
//! An anchor is first placed in the face plane (x, y), then snapped to the skin along `ẑ` (the
//! forward-facing surface vertex nearest in the plane) and moved `z` face units along `ẑ`
//! (negative: under the skin, as bone origins are).

use crate::feature_points::FeaturePoint;
use crate::{FemError, Mesh, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A point given by a feature point and an offset in face units (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Anchor {
    /// Feature-point name (`FeaturePoint::name`, e.g. `mouth_corner_left`).
    pub point: String,
    /// Offset `(x, y, z)` in face units.
    #[serde(default)]
    pub offset: [f64; 3],
}

impl Anchor {
    /// The anchor's position (mm) on `surface`, whose feature points are `position(p)`;
    /// `mirrored` places the right-side twin (point mirrored, x offset negated). The point name
    /// must have been validated (`FeaturePoint::from_name`).
    pub fn place(
        &self,
        surface: &Mesh,
        frame: &FaceFrame,
        position: impl Fn(FeaturePoint) -> DVec3,
        mirrored: bool,
    ) -> DVec3 {
        let mut p = FeaturePoint::from_name(&self.point).expect("validated anchor point");
        let mut offset = self.offset;
        if mirrored {
            p = p.mirror();
            offset[0] = -offset[0];
        }
        let target = position(p) + frame.offset_mm([offset[0], offset[1], 0.0]);
        snap_to_skin(surface, frame, target) + frame.offset_mm([0.0, 0.0, offset[2]])
    }
}

/// The face frame of a set of landmark positions (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceFrame {
    pub x: DVec3,
    pub y: DVec3,
    pub z: DVec3,
    /// mm per face unit along x and z.
    pub scale_xz_mm: f64,
    /// mm per face unit along y.
    pub scale_y_mm: f64,
}

impl FaceFrame {
    /// The frame of landmarks given as `position(FeaturePoint)`.
    pub fn new(position: impl Fn(FeaturePoint) -> DVec3) -> Result<Self> {
        let eyes = position(FeaturePoint::OuterEyeLeft) - position(FeaturePoint::OuterEyeRight);
        let up = position(FeaturePoint::Forehead) - position(FeaturePoint::Chin);
        let x = eyes.normalize_or_zero();
        let y = (up - x * up.dot(x)).normalize_or_zero();
        let inner =
            (position(FeaturePoint::InnerEyeLeft) + position(FeaturePoint::InnerEyeRight)) * 0.5;
        let mouth = (position(FeaturePoint::MouthCornerLeft)
            + position(FeaturePoint::MouthCornerRight))
            * 0.5;
        let scale_y_mm = (inner - mouth).dot(y);
        let scale_xz_mm = eyes.length() * 0.5;
        if x == DVec3::ZERO || y == DVec3::ZERO || !(scale_y_mm > 1.0) || !(scale_xz_mm > 1.0) {
            return Err(FemError::Definition(
                "feature points do not span a face frame (eyes, chin/forehead, mouth coincide or are upside down)".into(),
            )
            .into());
        }
        Ok(FaceFrame {
            x,
            y,
            z: x.cross(y),
            scale_xz_mm,
            scale_y_mm,
        })
    }

    /// The offset vector (mm) of face-unit offsets.
    pub fn offset_mm(&self, offset: [f64; 3]) -> DVec3 {
        self.x * offset[0] * self.scale_xz_mm
            + self.y * offset[1] * self.scale_y_mm
            + self.z * offset[2] * self.scale_xz_mm
    }
}

/// The skin point "under" `target` seen along the face's forward axis: the forward-facing
/// surface vertex closest to `target` in the face plane.
fn snap_to_skin(surface: &Mesh, frame: &FaceFrame, target: DVec3) -> DVec3 {
    let mut best = (f64::INFINITY, target);
    for (p, n) in surface.positions_mm.iter().zip(&surface.normals) {
        if n.dot(frame.z) < 0.2 {
            continue;
        }
        let d = *p - target;
        let in_plane = d - frame.z * d.dot(frame.z);
        let dist = in_plane.length_squared();
        if dist < best.0 {
            best = (dist, *p);
        }
    }
    best.1
}
