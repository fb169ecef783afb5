//! Each scan's starting pose before resampling: from its feature points, its ground truth, or
//! the generic face's fit where the points are suspect.

use super::*;

pub(super) fn truth_json(scan_path: &Path) -> Option<PathBuf> {
    let p = scan_path.with_extension("json");
    p.is_file().then_some(p)
}

pub(super) fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = io::read_text_file(path)?;
    serde_json::from_str(&text).map_err(|e| Error::invalid(path, e.to_string()))
}

/// The ground-truth nose tip of a scan (`landmarks.nose_tip.xyz_mm` in the JSON beside it),
/// mm, scan frame; an error when there is no ground truth.
pub fn truth_nose_tip(scan_path: &Path) -> Result<DVec3> {
    let json = truth_json(scan_path)
        .ok_or_else(|| Error::invalid(scan_path, "no ground-truth JSON beside the scan"))?;
    let v = read_json(&json)?;
    let xyz = v["landmarks"]["nose_tip"]["xyz_mm"]
        .as_array()
        .filter(|a| a.len() == 3)
        .and_then(|a| a.iter().map(|x| x.as_f64()).collect::<Option<Vec<f64>>>())
        .ok_or_else(|| Error::invalid(&json, "landmarks.nose_tip.xyz_mm is not [x, y, z]"))?;
    Ok(DVec3::new(xyz[0], xyz[1], xyz[2]))
}

/// The nose tip of a scan, mm, scan frame: detected on the denoised mesh (the ground truth
/// beside a generated scan is read only by [`PoseSource::Truth`]).
pub fn nose_tip(scan_path: &Path) -> Result<DVec3> {
    let report = crate::pipeline::detect_scan(io::read_mesh(scan_path)?)?;
    Ok(report.landmarks.get(crate::FeaturePoint::NoseTip))
}

/// The ground-truth frontalising rotation (`face_from_scan`): the transpose of `pose.rotation`
/// in the JSON beside the scan (which maps model to scan); an error without ground truth.
pub fn truth_face_from_scan(scan_path: &Path) -> Result<DMat3> {
    let json = truth_json(scan_path)
        .ok_or_else(|| Error::invalid(scan_path, "no ground-truth JSON beside the scan"))?;
    let v = read_json(&json)?;
    let rows: Option<Vec<[f64; 3]>> = v["pose"]["rotation"].as_array().and_then(|rows| {
        rows.iter()
            .map(|r| {
                let r = r.as_array()?;
                (r.len() == 3).then_some(())?;
                Some([r[0].as_f64()?, r[1].as_f64()?, r[2].as_f64()?])
            })
            .collect()
    });
    match rows {
        // Rows of R are the columns of Rᵀ.
        Some(rows) if rows.len() == 3 => {
            Ok(DMat3::from_cols_array_2d(&[rows[0], rows[1], rows[2]]))
        }
        _ => Err(Error::invalid(&json, "pose.rotation is not a 3×3 array")),
    }
}

/// The nose tip and frontalising rotation of a scan from `params.pose` (before the ICP
/// refinement of [`PoseSource::Icp`], which starts from identity). `landmarks`: the scan's
/// feature points if already known (a correction file, augment's cache), used by every source
/// but [`PoseSource::Truth`] (the nose tip only, for identity and ICP). The
/// mesh is read only where the pose needs it (not for cached points or the ground truth).
pub fn scan_pose(
    scan_path: &Path,
    params: &ProtocolParams,
    generic: &GenericFace,
    landmarks: Option<&crate::Landmarks>,
) -> Result<ScanPose> {
    Ok(scan_pose_checked(scan_path, params, generic, landmarks)?.0)
}

/// [`scan_pose`], and why the detected feature points are suspect (empty: they are not, or
/// none were detected). A scan whose points are suspect is not posed by them: it gets the
/// pose of face localisation's fit of the generic face (rotation and nose tip), which needs no
/// feature point, and [`PoseSource::Auto`] refines it against the gallery's mean as any other.
pub fn scan_pose_checked(
    scan_path: &Path,
    params: &ProtocolParams,
    generic: &GenericFace,
    landmarks: Option<&crate::Landmarks>,
) -> Result<(ScanPose, Vec<String>)> {
    match params.pose {
        PoseSource::Auto | PoseSource::Landmarks => {
            if let Some(points) = landmarks {
                return Ok((
                    pose_from_landmarks(points, generic, params.pose_points)?,
                    Vec::new(),
                ));
            }
            let report = crate::pipeline::detect_scan(io::read_mesh(scan_path)?)?;
            match report.localisation {
                Some(l) if !report.suspect.is_empty() => Ok((
                    ScanPose {
                        nose_tip_in_scan: l.nose_tip_in_scan,
                        face_from_scan: l.face_from_scan,
                    },
                    report.suspect,
                )),
                _ => Ok((
                    pose_from_landmarks(&report.landmarks, generic, params.pose_points)?,
                    report.suspect,
                )),
            }
        }
        PoseSource::Truth => Ok((
            ScanPose {
                nose_tip_in_scan: truth_nose_tip(scan_path)?,
                face_from_scan: truth_face_from_scan(scan_path)?,
            },
            Vec::new(),
        )),
        PoseSource::Identity | PoseSource::Icp => Ok((
            ScanPose {
                nose_tip_in_scan: match landmarks {
                    Some(points) => points.get(crate::FeaturePoint::NoseTip),
                    None => nose_tip(scan_path)?,
                },
                face_from_scan: DMat3::IDENTITY,
            },
            Vec::new(),
        )),
    }
}

/// The report's line for a scan kept with suspect feature points (`reasons`), posed by face
/// localisation's fit instead; `context` prefixes the reason (e.g. `expression training: `).
pub(super) fn suspect_scan(path: &Path, reasons: &[String], context: &str) -> Failure {
    Failure {
        file: path.to_path_buf(),
        reason: format!(
            "{context}suspect feature points ({}); posed by the generic face's fit instead",
            reasons.join("; ")
        ),
    }
}
