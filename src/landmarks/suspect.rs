//! Why a detection should not be trusted: the reasons [`LandmarkReport::suspect`] lists.

use super::{LandmarkReport, localise};
use crate::feature_points::FeaturePoint;

/// A head turned further than this from frontal (yaw, degrees) is a profile: half the face is
/// hidden and the nine steps, built for frontal faces, place points on what is left.
pub const PROFILE_MIN_YAW_DEG: f64 = 35.0;

/// This many failed Table 2 and level checks make a detection suspect. Table 2's ranges span
/// a population (min to max), so a right detection on an unusual face fails one or two; three
/// or more mean the face frame itself is probably wrong (on two generated seeds: 3 of 4 such
/// scans had points more than 10 mm off; of the real scans in `../shared/data`, only the two
/// profiles fail three).
pub const SUSPECT_FAILED_CHECKS: usize = 3;

/// Why a detection is suspect (empty: it is not), from the localisation and the head's yaw
/// against the line of sight, degrees: its face-likeness is below
/// [`localise::LocaliseParams::face_likeness_min`] (not a face, or most of it missing), the
/// head is turned into a profile ([`PROFILE_MIN_YAW_DEG`]), one of the nine anatomical points
/// (all but cheeks and forehead, which are region borders) had to be guessed at its Table 2
/// average position, or [`SUSPECT_FAILED_CHECKS`] or more of `report`'s Table 2 and level
/// checks fail.
pub fn suspect_reasons(
    localisation: Option<(&localise::Localisation, f64)>,
    report: &LandmarkReport,
    params: &localise::LocaliseParams,
) -> Vec<String> {
    let guessed = &report.guessed;
    let mut out = Vec::new();
    if let Some((l, yaw)) = localisation {
        if l.face_likeness < params.face_likeness_min {
            out.push(format!(
                "face-likeness {:.2} is below {}: only {:.0} % of the generic face lies within \
                 {} mm of the scan (not a face, most of it missing, or the face's direction not \
                 found: give it with --facing and --up)",
                l.face_likeness,
                params.face_likeness_min,
                100.0 * l.face_likeness,
                params.inlier_mm
            ));
        }
        if yaw.abs() > PROFILE_MIN_YAW_DEG {
            out.push(format!(
                "the head is turned {yaw:.0}° (a profile; the feature steps need a face within \
                 ±{PROFILE_MIN_YAW_DEG}° of frontal)"
            ));
        }
    }
    let anatomical: Vec<&str> = guessed
        .iter()
        .filter(|p| !FeaturePoint::BORDER.contains(p))
        .map(|p| p.name())
        .collect();
    if !anatomical.is_empty() {
        out.push(format!(
            "not found, placed at the Table 2 average position: {}",
            anatomical.join(", ")
        ));
    }
    let failed = report.failed_checks();
    if failed.len() >= SUSPECT_FAILED_CHECKS {
        out.push(format!(
            "{} Table 2 and level checks fail ({}): the face frame is probably wrong",
            failed.len(),
            failed.join(", ")
        ));
    }
    out
}
