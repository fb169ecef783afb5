//! Landmark-free pose normalisation for recognition: a rotation about the nose tip that
//! aligns a scan's rigid upper face (forehead, eyes, nose) to a reference range image, by
//! iterated closest points along z.
//!
//! Each iteration takes the scan's vertices (every `subsample`-th) in the current face frame
//! `f = R (p − nose tip)`, keeps those inside the reference's mask, above
//! [`PoseParams::exclude_below_nose_mm`] (mouth and jaw move with the expression) and within
//! [`PoseParams::max_residual_mm`] of the reference surface, pairs each with the reference point
//! straight behind or in front of it (`(f.x, f.y, ref(f.x, f.y))`, bilinear), and takes a
//! Gauss–Newton step for the small rotation ω about the origin that minimises the
//! point-to-plane distances (the plane from the reference's depth gradient).
//! The reference is typically the mean gallery range image ([`mean_image`]).
//!
//! **Status: experimental.** It recovers an analytic test surface's pose to < 0.5°, but on a
//! noisy 61-subject synthetic set the converged pose of one subject's scans is not
//! consistent (before the pairing region was restricted to 35 × 55 mm: mean 2.8° between
//! frontal1 and frontal2, outliers > 20°; a subject's face is not the mean face, and holes,
//! hair and expressions change which points pair up), so rank-1 with it is 58 % against 70 %
//! with the ground-truth pose and 20 % without any
//! normalisation. The default pose source is now [`pose_from_landmarks`] (the registration's
//! rigid fit to the generic face) on the points [`crate::pipeline::detect_scan`] finds; this
//! ICP is kept as a diagnostic (`--pose icp`).
//!
//! **Landmark pose** ([`crate::pipeline::detect_scan`] then [`pose_from_landmarks`], `--pose auto`, the default): the scan is denoised
//! (as `pipeline::prepare_scan` does), its feature points are detected, and the rotation is
//! that of the registration's first step — Horn's absolute orientation of the generic face's
//! feature vertices onto the detected points ([`crate::registration::horn_absolute_orientation`]);
//! `face_from_scan` is its inverse, so every scan is turned into the generic face's frame.
//! The nose tip is the detected one.

use super::range_image::RangeImage;
use crate::generic_face::GenericFace;
use crate::{FeaturePoint, Landmarks, Mesh, Result};
use glam::{DMat3, DVec3};
use nalgebra::Matrix3;
use serde::Serialize;

/// Parameters of [`align_to_reference`]. Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PoseParams {
    /// Iterations. Default 40.
    pub iterations: usize,
    /// Use every n-th vertex (≥ 1). Default 3.
    pub subsample: usize,
    /// Ignore points more than this below the nose tip, mm (mouth, jaw). Default 15.
    pub exclude_below_nose_mm: f64,
    /// Ignore pairs further apart along z than this, mm. Default 8.
    pub max_residual_mm: f64,
    /// Only points inside this ellipse about the nose tip pair up, mm. Defaults 35 × 55 (the
    /// rim of the range-image mask is mostly hole-filled cheek and hairline).
    pub region_semi_x_mm: f64,
    pub region_semi_y_mm: f64,
    /// Levenberg–Marquardt damping, as a fraction of the mean diagonal. Default 0.01.
    pub damping: f64,
    /// Largest rotation per iteration, degrees. Default 1.
    pub max_step_deg: f64,
    /// Largest nose-tip shift per iteration of [`refine_pose`], mm. Default 1.
    pub max_shift_step_mm: f64,
}

impl Default for PoseParams {
    fn default() -> Self {
        PoseParams {
            iterations: 40,
            subsample: 3,
            exclude_below_nose_mm: 15.0,
            max_residual_mm: 8.0,
            region_semi_x_mm: 35.0,
            region_semi_y_mm: 55.0,
            damping: 0.01,
            max_step_deg: 1.0,
            max_shift_step_mm: 1.0,
        }
    }
}

/// The mean of range images on the same grid (mask and measured flags of the first, measured
/// marked everywhere inside the mask). `None` for an empty list.
pub fn mean_image(images: &[&RangeImage]) -> Option<RangeImage> {
    let first = *images.first()?;
    let mut mean = first.clone();
    for (k, v) in mean.depth_mm.iter_mut().enumerate() {
        *v = images.iter().map(|i| i.depth_mm[k]).sum::<f64>() / images.len() as f64;
    }
    mean.measured = mean.mask.clone();
    mean.coverage = 1.0;
    Some(mean)
}

/// Bilinear depth of `image` at face-frame (x, y) mm; `None` outside the mask.
fn depth_at(image: &RangeImage, x: f64, y: f64) -> Option<f64> {
    let cx = (image.cols as f64 - 1.0) / 2.0;
    let cy = (image.rows as f64 - 1.0) / 2.0;
    let u = x / image.spacing_mm + cx;
    let v = cy - y / image.spacing_mm;
    if !(u >= 0.0 && v >= 0.0) || u >= (image.cols - 1) as f64 || v >= (image.rows - 1) as f64 {
        return None;
    }
    let (i, j) = (u as usize, v as usize);
    let (fu, fv) = (u - i as f64, v - j as f64);
    let k = j * image.cols + i;
    let ks = [k, k + 1, k + image.cols, k + image.cols + 1];
    if ks.iter().any(|&k| !image.mask[k]) {
        return None;
    }
    let d = ks.map(|k| image.depth_mm[k]);
    Some((1.0 - fv) * ((1.0 - fu) * d[0] + fu * d[1]) + fv * ((1.0 - fu) * d[2] + fu * d[3]))
}

/// The rotation `face_from_scan` (about the nose tip) that best aligns `mesh` to `reference`,
/// starting from `initial` (rotation only; [`refine_pose`] also moves the nose tip).
pub fn align_to_reference(
    mesh: &Mesh,
    nose_tip_in_scan: DVec3,
    initial: DMat3,
    reference: &RangeImage,
    params: &PoseParams,
) -> DMat3 {
    let start = ScanPose {
        nose_tip_in_scan,
        face_from_scan: initial,
    };
    align(mesh, start, reference, params, false).face_from_scan
}

/// Rigid (6 degrees of freedom) refinement of a pose: the rotation and the nose-tip position
/// that best align the upper face of `mesh` to `reference` (same pairing and
/// Levenberg–Marquardt steps as [`align_to_reference`], with a translation `t` of the face
/// frame added to the unknowns; the nose tip becomes `n − Rᵀ t`). Used after the landmark
/// pose ([`PoseSource`](super::PoseSource)`::Auto`) to take out the few degrees and
/// millimetres that feature-point noise leaves (a few degrees and about a millimetre between a
/// subject's two neutral scans: docs/measurements.md, "Figures moved from the code's
/// comments").
pub fn refine_pose(
    mesh: &Mesh,
    start: ScanPose,
    reference: &RangeImage,
    params: &PoseParams,
) -> ScanPose {
    align(mesh, start, reference, params, true)
}

fn align(
    mesh: &Mesh,
    start: ScanPose,
    reference: &RangeImage,
    params: &PoseParams,
    translate: bool,
) -> ScanPose {
    use nalgebra::{SMatrix, SVector};
    let step = params.subsample.max(1);
    let scan_points: Vec<DVec3> = mesh.positions_mm.iter().step_by(step).copied().collect();
    let mut r = start.face_from_scan;
    let mut nose = start.nose_tip_in_scan;
    let h = reference.spacing_mm;
    for _ in 0..params.iterations {
        // Gauss–Newton on point-to-plane distances, small motion: f' = f + ω × f + t.
        let mut ata = SMatrix::<f64, 6, 6>::zeros();
        let mut atb = SVector::<f64, 6>::zeros();
        let mut pairs = 0usize;
        for &p in &scan_points {
            let f = r * (p - nose);
            if f.y < -params.exclude_below_nose_mm
                || (f.x / params.region_semi_x_mm).powi(2) + (f.y / params.region_semi_y_mm).powi(2)
                    > 1.0
            {
                continue;
            }
            let (Some(z), Some(zx0), Some(zx1), Some(zy0), Some(zy1)) = (
                depth_at(reference, f.x, f.y),
                depth_at(reference, f.x - h, f.y),
                depth_at(reference, f.x + h, f.y),
                depth_at(reference, f.x, f.y - h),
                depth_at(reference, f.x, f.y + h),
            ) else {
                continue;
            };
            if (z - f.z).abs() > params.max_residual_mm {
                continue;
            }
            let n = DVec3::new(-(zx1 - zx0) / (2.0 * h), -(zy1 - zy0) / (2.0 * h), 1.0).normalize();
            let dist = n.dot(f - DVec3::new(f.x, f.y, z));
            let c = f.cross(n);
            let row = SVector::<f64, 6>::from([c.x, c.y, c.z, n.x, n.y, n.z]);
            ata += row * row.transpose();
            atb -= row * dist;
            pairs += 1;
        }
        if pairs < 10 {
            break;
        }
        // Levenberg–Marquardt damping: roll about the view axis is weakly constrained.
        let mut damped = ata;
        let rot_damping = params.damping * (ata[(0, 0)] + ata[(1, 1)] + ata[(2, 2)]) / 3.0;
        let tr_damping = params.damping * (ata[(3, 3)] + ata[(4, 4)] + ata[(5, 5)]) / 3.0;
        for k in 0..3 {
            damped[(k, k)] += rot_damping;
            damped[(k + 3, k + 3)] += tr_damping;
        }
        let (omega, t) = if translate {
            let Some(x) = damped.lu().solve(&atb) else {
                break;
            };
            (DVec3::new(x[0], x[1], x[2]), DVec3::new(x[3], x[4], x[5]))
        } else {
            let m3: Matrix3<f64> = damped.fixed_view::<3, 3>(0, 0).into();
            let Some(x) = m3.lu().solve(&atb.fixed_rows::<3>(0).into_owned()) else {
                break;
            };
            (DVec3::new(x[0], x[1], x[2]), DVec3::ZERO)
        };
        let mut omega = omega;
        let max_step = params.max_step_deg.to_radians();
        if omega.length() > max_step {
            omega *= max_step / omega.length();
        }
        let mut t = t;
        if t.length() > params.max_shift_step_mm {
            t *= params.max_shift_step_mm / t.length();
        }
        let angle = omega.length();
        if !(angle.is_finite() && t.is_finite()) {
            break;
        }
        if angle > 0.0 {
            r = DMat3::from_axis_angle(omega / angle, angle) * r;
        }
        // f' = R'(p − n') = R'(p − n) + t  ⇒  n' = n − R'ᵀ t.
        nose -= r.transpose() * t;
        if angle < 1e-7 && t.length() < 1e-5 {
            break;
        }
    }
    ScanPose {
        nose_tip_in_scan: nose,
        face_from_scan: r,
    }
}

/// Angle of the rotation `a · bᵀ`, degrees (how far apart two rotations are).
pub fn angle_between_deg(a: DMat3, b: DMat3) -> f64 {
    let m = a * b.transpose();
    let c = ((m.x_axis.x + m.y_axis.y + m.z_axis.z - 1.0) / 2.0).clamp(-1.0, 1.0);
    c.acos().to_degrees()
}

/// Which detected feature points the landmark pose ([`pose_from_landmarks`]) is fitted to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum PosePoints {
    /// The points the registration uses (the ten anatomical ones:
    /// [`crate::pipeline::registration_points`] with detected points), so the pose is exactly
    /// the registration's rigid step.
    Registration,
    /// Only the points an expression hardly moves: nose tip, nose corners, inner and outer eye
    /// corners (seven). Mouth corners and chin move with a smile or an open mouth and tilt the
    /// fit.
    #[default]
    Rigid,
}

impl PosePoints {
    fn uses(self, p: FeaturePoint) -> bool {
        match self {
            PosePoints::Registration => true,
            PosePoints::Rigid => !matches!(
                p,
                FeaturePoint::MouthCornerLeft | FeaturePoint::MouthCornerRight | FeaturePoint::Chin
            ),
        }
    }
}

/// A scan's nose tip (scan frame, mm) and the rotation that turns it frontal
/// (`face_from_scan`, applied to `p − nose tip`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanPose {
    pub nose_tip_in_scan: DVec3,
    pub face_from_scan: DMat3,
}

/// The pose from feature points already found on the scan: nose tip = the detected one,
/// `face_from_scan` = the inverse rotation of Horn's fit of the generic face's feature vertices
/// onto the scan's points (the registration's global alignment, scale included as there).
pub fn pose_from_landmarks(
    landmarks: &Landmarks,
    generic: &GenericFace,
    points: PosePoints,
) -> Result<ScanPose> {
    let pairs: Vec<(FeaturePoint, DVec3)> = crate::pipeline::registration_points(landmarks, true)
        .into_iter()
        .filter(|(p, _)| points.uses(*p))
        .collect();
    let from: Vec<DVec3> = pairs
        .iter()
        .map(|(p, _)| generic.mesh.positions_mm[generic.feature_vertex(*p) as usize])
        .collect();
    let to: Vec<DVec3> = pairs.iter().map(|(_, x)| *x).collect();
    let with_scale = crate::registration::RegistrationParams::default().with_scale;
    let scan_from_generic = crate::registration::horn_absolute_orientation(&from, &to, with_scale)?;
    let nose = landmarks.get(FeaturePoint::NoseTip);
    if !nose.is_finite() {
        return Err(crate::Error::algorithm(
            "pose",
            "the nose tip is not finite",
        ));
    }
    Ok(ScanPose {
        nose_tip_in_scan: nose,
        face_from_scan: scan_from_generic.rotation_matrix().transpose(),
    })
}

#[cfg(test)]
mod tests {
    use super::super::range_image::{RangeImageParams, range_image};
    use super::*;

    /// A smooth face-like bump field: a nose (Gaussian) on an ellipsoidal dome.
    fn face(n: usize) -> Mesh {
        let mut pos = Vec::new();
        let h = 180.0 / (n - 1) as f64;
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (i as f64 * h - 90.0, j as f64 * h - 90.0);
                let dome = -(x * x / 150.0 + y * y / 250.0);
                let nose = 20.0 * (-(x * x + y * y) / 200.0).exp() - 20.0;
                let brow = 6.0 * (-((y - 35.0).powi(2)) / 60.0).exp();
                pos.push(DVec3::new(x, y, dome + nose + brow));
            }
        }
        let mut faces = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let k = (j * n + i) as u32;
                faces.push([k, k + 1, k + 1 + n as u32, k + n as u32]);
            }
        }
        Mesh::from_faces(pos, faces)
    }

    #[test]
    fn recovers_a_small_rotation() {
        let params = RangeImageParams::default();
        let mesh = face(181);
        let reference = range_image(&mesh, DVec3::ZERO, DMat3::IDENTITY, &params).unwrap();
        let scan_from_face = DMat3::from_euler(glam::EulerRot::ZXY, 0.06, -0.08, 0.09);
        let mut posed = mesh.clone();
        for p in &mut posed.positions_mm {
            *p = scan_from_face * *p;
        }
        let start = angle_between_deg(DMat3::IDENTITY, scan_from_face.transpose());
        let r = align_to_reference(
            &posed,
            DVec3::ZERO,
            DMat3::IDENTITY,
            &reference,
            &PoseParams::default(),
        );
        let err = angle_between_deg(r, scan_from_face.transpose());
        assert!(start > 6.0, "{start}");
        assert!(err < 0.5, "residual {err} degrees (start {start})");
    }

    #[test]
    fn refinement_recovers_a_small_rotation_and_nose_shift() {
        let params = RangeImageParams::default();
        let mesh = face(181);
        let reference = range_image(&mesh, DVec3::ZERO, DMat3::IDENTITY, &params).unwrap();
        // The scan: the face turned by ~5° and moved; the start pose is off by the motion.
        let scan_from_face = DMat3::from_euler(glam::EulerRot::ZXY, 0.03, -0.05, 0.06);
        let shift = DVec3::new(1.5, -2.0, 0.8);
        let mut posed = mesh.clone();
        for p in &mut posed.positions_mm {
            *p = scan_from_face * *p + shift;
        }
        let start = ScanPose {
            nose_tip_in_scan: DVec3::ZERO,
            face_from_scan: DMat3::IDENTITY,
        };
        let got = refine_pose(&posed, start, &reference, &PoseParams::default());
        let err = angle_between_deg(got.face_from_scan, scan_from_face.transpose());
        assert!(err < 0.5, "rotation residual {err} degrees");
        let nose_err = got.nose_tip_in_scan.distance(shift);
        assert!(
            nose_err < 0.3,
            "nose tip {} vs {shift}",
            got.nose_tip_in_scan
        );
    }
}
