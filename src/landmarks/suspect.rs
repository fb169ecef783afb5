//! Why a detection should not be trusted: the reasons [`LandmarkReport::suspect`] lists.

use super::{CONSENSUS_TILT_DEG, LEVEL_MAX_MM, LandmarkReport, UNSTABLE_SPREAD_MM, localise};

/// A head turned further than this from frontal (yaw, degrees) is a profile: half the face is
/// hidden and the nine steps, built for frontal faces, place points on what is left.
pub const PROFILE_MIN_YAW_DEG: f64 = 35.0;

/// This many problems make a detection suspect: failed Table 2 and level checks, and
/// anatomical points the tilted views put more than [`UNSTABLE_SPREAD_MM`] apart (the same
/// evidence [`super::implausibility`] weighs between localisation finalists). Table 2's ranges
/// span a population (min to max), so a right detection on an unusual face fails one or two,
/// and a point on a shallow feature can be unstable alone; three or more mean the face frame
/// or the points are probably wrong (figures: docs/measurements.md).
pub const SUSPECT_FAILED_CHECKS: usize = 3;

/// A left/right pair (eye, nose or mouth corners) whose heights differ by more than this (mm,
/// twice [`LEVEL_MAX_MM`]) makes a detection suspect on its own: the face frame's roll is the
/// symmetry line's, and true eye and nose corner pairs differ by at most 3.1 mm. A smile lifts
/// a mouth corner about 7 mm (the mouth widens by about 27 % and its corners move up and out
/// at about 47°, Am J Orthod Dentofacial Orthop 2005;128:8–15), so a one-sided smile leaves
/// the pair less than this apart (on the benchmark's gestures at most 7.2 mm).
pub const SUSPECT_LEVEL_MM: f64 = 2.0 * LEVEL_MAX_MM;

/// Why a detection is suspect (empty: it is not), from the localisation and the head's yaw
/// against the line of sight, degrees: its face-likeness is below
/// [`localise::LocaliseParams::face_likeness_min`] (not a face, or most of it missing), the
/// head is turned into a profile ([`PROFILE_MIN_YAW_DEG`]), one of the nine anatomical points
/// (all but cheeks and forehead, which are region borders) had to be guessed at its Table 2
/// average position, [`SUSPECT_FAILED_CHECKS`] or more of `report`'s Table 2 and level
/// checks fail or its anatomical points are unstable, or a left/right pair's heights differ
/// by more than [`SUSPECT_LEVEL_MM`].
pub fn suspect_reasons(
    localisation: Option<(&localise::Localisation, f64)>,
    report: &LandmarkReport,
    params: &localise::LocaliseParams,
) -> Vec<String> {
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
    let anatomical: Vec<&str> = (report.guessed_anatomical().iter())
        .map(|p| p.name())
        .collect();
    if !anatomical.is_empty() {
        out.push(format!(
            "not found, placed at the Table 2 average position: {}",
            anatomical.join(", ")
        ));
    }
    let failed = report.failed_checks();
    let unstable = report.unstable_points();
    if failed.len() + unstable.len() >= SUSPECT_FAILED_CHECKS {
        let mut what = Vec::new();
        if !failed.is_empty() {
            what.push(format!(
                "Table 2 and level checks fail: {}",
                failed.join(", ")
            ));
        }
        if !unstable.is_empty() {
            let names: Vec<&str> = unstable.iter().map(|p| p.name()).collect();
            what.push(format!(
                "views tilted {CONSENSUS_TILT_DEG}° put these more than \
                 {UNSTABLE_SPREAD_MM} mm apart: {}",
                names.join(", ")
            ));
        }
        out.push(format!(
            "{} problems ({}): the face frame or these points are probably wrong",
            failed.len() + unstable.len(),
            what.join("; ")
        ));
    }
    let skewed: Vec<String> = (report.level.iter())
        .filter(|l| l.difference_mm.abs() > SUSPECT_LEVEL_MM)
        .map(|l| format!("{} {:.1} mm", l.name, l.difference_mm.abs()))
        .collect();
    if !skewed.is_empty() {
        out.push(format!(
            "left and right heights differ by more than {SUSPECT_LEVEL_MM} mm ({}): one point \
             of the pair is off",
            skewed.join(", ")
        ));
    }
    out
}
