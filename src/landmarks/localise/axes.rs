//! Axis-aligned frames (the face's direction and up along the scan's axes) and the yaw,
//! pitch and roll reported for a located face.

use glam::{DMat3, DVec3};

/// An axis-aligned frame: the scan axis the face looks along and the one its forehead points to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisFrame {
    /// Index 0–5 of +x, −x, +y, −y, +z, −z.
    pub facing: usize,
    pub up: usize,
}

pub(super) const AXIS_NAMES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];

pub(super) fn axis(k: usize) -> DVec3 {
    let mut v = DVec3::ZERO;
    v[k / 2] = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
    v
}

impl AxisFrame {
    /// The scanner frame: facing +z, y up.
    pub const SCANNER: AxisFrame = AxisFrame { facing: 4, up: 2 };

    /// All 24 axis-aligned frames, the scanner frame first.
    pub fn all() -> Vec<AxisFrame> {
        let mut out = vec![Self::SCANNER];
        for facing in 0..6 {
            for up in 0..6 {
                let f = AxisFrame { facing, up };
                if up / 2 != facing / 2 && f != Self::SCANNER {
                    out.push(f);
                }
            }
        }
        out
    }

    /// The frame whose face looks along the axis named `facing` and whose forehead points
    /// along `up` (`+x`, `-x`, `+y`, `-y`, `+z`, `-z`); an error naming the problem otherwise.
    pub fn from_names(facing: &str, up: &str) -> std::result::Result<AxisFrame, String> {
        let index = |name: &str| {
            AXIS_NAMES.iter().position(|&a| a == name).ok_or_else(|| {
                format!("`{name}` is not an axis (one of {})", AXIS_NAMES.join(", "))
            })
        };
        let frame = AxisFrame {
            facing: index(facing)?,
            up: index(up)?,
        };
        if frame.facing / 2 == frame.up / 2 {
            return Err(format!(
                "the face cannot look along {facing} with its forehead along {up}: they must \
                 be perpendicular axes"
            ));
        }
        Ok(frame)
    }

    /// Name of the axis the face looks along, e.g. `+z`.
    pub fn facing_name(&self) -> &'static str {
        AXIS_NAMES[self.facing]
    }

    /// Name of the axis the forehead points to, e.g. `+y`.
    pub fn up_name(&self) -> &'static str {
        AXIS_NAMES[self.up]
    }

    /// The rotation from the scan frame into this frame's face frame (rows: x, y, z of the face).
    pub fn face_from_scan(&self) -> DMat3 {
        let z = axis(self.facing);
        let y = axis(self.up);
        let x = y.cross(z);
        DMat3::from_cols(x, y, z).transpose()
    }
}

/// The nearest axis-aligned frame to a rotation (what the JSON reports as `facing` / `up`).
pub fn nearest_axis_frame(face_from_scan: DMat3) -> AxisFrame {
    let pick = |v: DVec3| {
        (0..6)
            .max_by(|&a, &b| axis(a).dot(v).total_cmp(&axis(b).dot(v)))
            .unwrap_or(4)
    };
    let scan_from_face = face_from_scan.transpose();
    AxisFrame {
        facing: pick(scan_from_face.z_axis),
        up: pick(scan_from_face.y_axis),
    }
}

/// The rotation's yaw, pitch and roll of the head against the scanner frame, degrees (face
/// frame = roll · pitch · yaw applied to the scan), for reports.
pub fn yaw_pitch_roll_deg(face_from_scan: DMat3) -> (f64, f64, f64) {
    let scan_from_face = face_from_scan.transpose();
    let z = scan_from_face.z_axis; // the face's viewing direction in the scan
    let y = scan_from_face.y_axis;
    let yaw = z.x.atan2(z.z).to_degrees();
    let pitch = (-z.y).atan2((z.x * z.x + z.z * z.z).sqrt()).to_degrees();
    let roll = (-y.x).atan2(y.y).to_degrees();
    (yaw, pitch, roll)
}

/// Names of the frame's axes for reports: the scan axis the face looks along and the one its
/// forehead points to.
pub fn facing_and_up(face_from_scan: DMat3) -> (&'static str, &'static str) {
    let f = nearest_axis_frame(face_from_scan);
    (f.facing_name(), f.up_name())
}
