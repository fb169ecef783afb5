//! Feature-point detection: accuracy on generated scans with ground truth (a regression bound
//! a little looser than measured), robustness to pose, real GavabDB scans, and typed errors on
//! meshes without a face.

use crate::common;

use facesynth::feature_points::FeaturePoint;
use facesynth::ground_truth::ScanTruth;
use facesynth::landmarks::{self, LandmarkParams, eval};
use facesynth::{Mesh, denoise, io};
use glam::{DMat3, DVec3};

fn denoised(path: &std::path::Path) -> Mesh {
    let mut m = io::read_mesh(path).unwrap();
    denoise::denoise(&mut m, &denoise::DenoiseParams::default()).unwrap();
    m
}

/// A scan of the small generated set (4 subjects, seed 3), denoised, with its ground truth and
/// its true nose tip.
fn generated_scan(stem: &str) -> (Mesh, ScanTruth, DVec3) {
    let dir = common::synth_dataset(4, 3, false);
    let mesh = denoised(&dir.join(format!("{stem}.wrl")));
    let truth = ScanTruth::load(&dir.join(format!("{stem}.json"))).unwrap();
    let tip = DVec3::from_array(truth.feature_point(FeaturePoint::NoseTip).unwrap().xyz_mm);
    (mesh, truth, tip)
}

/// The default parameters' evaluation of the small generated set, made once for the tests
/// that use it.
fn default_report() -> &'static eval::EvalReport {
    static REPORT: std::sync::OnceLock<eval::EvalReport> = std::sync::OnceLock::new();
    REPORT.get_or_init(|| {
        let dir = common::synth_dataset(4, 3, false);
        eval::evaluate_dir(&dir, true, &LandmarkParams::default()).unwrap()
    })
}

#[test]
fn generated_scans_meet_the_measured_accuracy() {
    let report = default_report();
    let s = report.summary();
    let n = &s.neutral;
    assert_eq!(n.scans, 8);
    assert_eq!(n.detected, 8, "{:#?}", report.scans);
    // 8 scans: measured 8/8, worst point 8.8 mm; the bounds allow one near miss (20-subject seeds:
    // 39–40 of 40, docs/measurements.md).
    assert!(
        n.success_rate >= 0.875,
        "neutral success {}",
        n.success_rate
    );
    for (name, p) in &n.points {
        assert!(
            p.max_mm <= 12.0,
            "{name}: worst neutral error {} mm",
            p.max_mm
        );
    }
    let mean = |name: &str| n.points[name].mean_mm;
    assert!(mean("nose_tip") <= 3.0, "nose tip {}", mean("nose_tip"));
    for p in ["inner_eye_left", "inner_eye_right"] {
        // Measured 2.91 / 2.11 on this set; 1.7–3.2 on 20-subject seeds.
        assert!(mean(p) <= 3.5, "{p} {}", mean(p));
    }
    for p in ["outer_eye_left", "outer_eye_right"] {
        // Measured 2.14 / 1.59 on this set.
        assert!(mean(p) <= 3.0, "{p} {}", mean(p));
    }
    let eyes = [
        "inner_eye_left",
        "inner_eye_right",
        "outer_eye_left",
        "outer_eye_right",
    ];
    // The face-frame error vectors: as long as the errors, and they show the one systematic
    // offset the module docs report (the inner-eye point lies above the benchmark's canthus;
    // here 1.9 / 1.0 mm).
    for scan in &report.scans {
        for (name, e) in &scan.errors_mm {
            let o = scan.offsets_mm[name];
            let len = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
            assert!((len - e).abs() < 1e-9, "{} {name}: {o:?} vs {e}", scan.stem);
        }
    }
    for p in ["inner_eye_left", "inner_eye_right"] {
        let up = n.points[p].mean_offset_mm[1];
        assert!(up > 0.5, "{p}: mean vertical offset {up} mm");
    }
    let eye_mean = eyes.iter().map(|p| mean(p)).sum::<f64>() / 4.0;
    assert!(eye_mean <= 2.8, "eye corners {eye_mean}"); // measured 2.19
    for (p, st) in &n.points {
        let bound = 6.0;
        assert!(st.mean_mm <= bound, "{p} mean {} mm", st.mean_mm);
    }
    let e = &s.expression;
    assert_eq!(e.scans, 12);
    assert!(e.detected >= 11);
    assert!(e.points["nose_tip"].mean_mm <= 3.5);
    // Measured 12 of 12; the bound allows two misses.
    assert!(
        e.success_rate >= 0.83,
        "expression success {}",
        e.success_rate
    );
}

/// The fissure step of step 3 (`LandmarkParams::inner_eye_at_fissure`) against the concave
/// region's pit alone, on the same scans: closer to the ground truth on both sides.
#[test]
fn inner_eye_corners_at_the_fissure_end_are_closer_to_the_truth() {
    let pit_only = LandmarkParams {
        inner_eye_at_fissure: false,
        ..LandmarkParams::default()
    };
    assert_closer_with_defaults(&pit_only, ["inner_eye_left", "inner_eye_right"]);
}

/// The fissure step of step 4 (`LandmarkParams::outer_eye_at_fissure`) against the concave
/// vertex nearest the average corner position alone: closer to the ground truth on both
/// sides (measured on this set: neutral 3.61 / 3.30 → 2.35 / 1.32 mm, expressions 2.50 /
/// 3.06 → 1.01 / 2.03).
#[test]
fn outer_eye_corners_at_the_fissure_end_are_closer_to_the_truth() {
    let prior_only = LandmarkParams {
        outer_eye_at_fissure: false,
        ..LandmarkParams::default()
    };
    assert_closer_with_defaults(&prior_only, ["outer_eye_left", "outer_eye_right"]);
}

/// On the small generated set, the default parameters put `points` no farther from the ground
/// truth than `without` does, on neutral and on expression scans, and closer on at least one
/// of the two (with the descriptors' 10 mm reach the pit is already at the left fissure's end
/// on the neutral scans: 2.88 mm either way; expressions 3.57 → 3.18 mm).
fn assert_closer_with_defaults(without: &LandmarkParams, points: [&str; 2]) {
    let dir = common::synth_dataset(4, 3, false);
    let before = eval::evaluate_dir(&dir, true, without).unwrap().summary();
    let after = default_report().summary();
    for p in points {
        let all = |s: &eval::Summary| {
            let (n, e) = (&s.neutral.points[p], &s.expression.points[p]);
            (n.mean_mm, e.mean_mm)
        };
        let (b, a) = (all(&before), all(&after));
        println!(
            "{p}: neutral {:.2} -> {:.2}, expressions {:.2} -> {:.2}",
            b.0, a.0, b.1, a.1
        );
        assert!(
            a.0 <= b.0 && a.1 <= b.1 && (a.0 < b.0 || a.1 < b.1),
            "{p}: {b:?} -> {a:?}"
        );
    }
}

/// Rotates a scan and its ground truth about the nose tip and checks the nose tip and the eye
/// corners still come out right (within 6 mm), and the other scored points within 10 mm,
/// for ±10° roll, yaw and pitch (measured: worst 6.7 mm, the chin).
#[test]
fn detection_follows_ten_degree_rotations() {
    let (base, truth, tip) = generated_scan("subj001_frontal1");
    let pivot = tip - DVec3::new(0.0, 0.0, 90.0); // about the head, as the poses are
    let a = 10f64.to_radians();
    let level = landmarks::detect(&base, &LandmarkParams::default()).unwrap();
    let level_roll = level.symmetry_roll_deg.expect("a symmetry line");
    for (what, r) in [
        ("roll +10", DMat3::from_rotation_z(a)),
        ("roll -10", DMat3::from_rotation_z(-a)),
        ("yaw +10", DMat3::from_rotation_y(a)),
        ("yaw -10", DMat3::from_rotation_y(-a)),
        ("pitch +10", DMat3::from_rotation_x(a)),
        ("pitch -10", DMat3::from_rotation_x(-a)),
    ] {
        let mut m = base.clone();
        for p in &mut m.positions_mm {
            *p = pivot + r * (*p - pivot);
        }
        m.update_normals();
        let found = landmarks::detect(&m, &LandmarkParams::default())
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        // The steps run in the located face's frame, so the roll is taken out before them: the
        // symmetry line stays level, and the localisation reports the roll applied.
        let sym = found.symmetry_roll_deg.expect("a symmetry line");
        assert!(
            (sym - level_roll).abs() <= 2.5,
            "{what}: symmetry roll {sym:.1}°, level {level_roll:.1}°"
        );
        let roll = |r: &landmarks::LandmarkReport| {
            landmarks::localise::yaw_pitch_roll_deg(r.localisation.unwrap().face_from_scan).2
        };
        let turned = if what.starts_with("roll") {
            what[5..].parse::<f64>().unwrap()
        } else {
            0.0
        };
        assert!(
            (roll(&found) - roll(&level) - turned).abs() <= 1.5,
            "{what}: localised roll {:.1}°, level {:.1}°",
            roll(&found),
            roll(&level)
        );
        for (p, xyz, _) in truth.feature_points() {
            let want = pivot + r * (xyz - pivot);
            let err = (found.landmarks.get(p) - want).length();
            let bound = match p {
                FeaturePoint::NoseTip
                | FeaturePoint::InnerEyeLeft
                | FeaturePoint::InnerEyeRight => 6.0,
                _ => 10.0,
            };
            assert!(err <= bound, "{what}: {p} off by {err:.1} mm");
        }
    }
}

/// A nose cut off from the rest of the face (a hole on the bridge and steep sides did that on
/// a benchmark scan: the tip was then sought on the hole's rim, 39 mm off) is still found: a
/// 3 mm moat around the nose leaves it an island the face surrounds.
#[test]
fn a_nose_cut_off_by_a_moat_is_still_the_nose() {
    let (base, _, tip) = generated_scan("subj002_frontal1");
    let mut moated = base.clone();
    let keep: Vec<bool> = moated
        .positions_mm
        .iter()
        .map(|p| {
            let r = (p.truncate() - tip.truncate()).length();
            !(18.0..21.0).contains(&r)
        })
        .collect();
    moated.retain_vertices(&keep);
    let found = landmarks::detect(&moated, &LandmarkParams::default()).unwrap();
    let err = (found.landmarks.get(FeaturePoint::NoseTip) - tip).length();
    assert!(err < 4.0, "nose tip off by {err:.1} mm");
}

#[test]
fn real_scans_whose_biggest_eye_region_is_a_crease_keep_a_level_face() {
    use FeaturePoint::*;
    // On these two real scans one side's biggest concave region beside the nose bridge is a
    // lid crease, which tilted the eye line by 20° or more (the roll limit) and took the mouth
    // and nose corners with it. The located face's frame and its symmetry line set the frame,
    // and the inner corners come from the regions that agree with it.
    for name in [
        "pointclouds/cara9_frontal2.txt",
        "pointclouds/cara46_frontal1_filtered_raw.txt",
    ] {
        let r =
            landmarks::detect(&denoised(&common::gavab(name)), &LandmarkParams::default()).unwrap();
        let sym = r.symmetry_roll_deg.expect("symmetry roll found");
        let eyes = r.landmarks.get(InnerEyeLeft) - r.landmarks.get(InnerEyeRight);
        let eye_roll = eyes.y.atan2(eyes.x).to_degrees();
        assert!(
            (eye_roll - sym).abs() < 5.0 && sym.abs() < 10.0 && r.roll_deg == sym,
            "{name}: eye line {eye_roll:.1}°, symmetry {sym:.1}°, frame {:.1}°",
            r.roll_deg
        );
        let g = |p| r.landmarks.get(p);
        for (a, b) in [
            (MouthCornerLeft, MouthCornerRight),
            (NoseCornerLeft, NoseCornerRight),
        ] {
            let dy = (g(a).y - g(b).y).abs();
            assert!(dy < 8.0, "{name}: {a} and {b} {dy:.1} mm apart in height");
        }
        assert!(g(MouthCornerLeft).y < g(NoseCornerLeft).y);
        assert!(g(MouthCornerRight).y < g(NoseCornerRight).y);
    }
}

#[test]
fn real_gavabdb_frontal_scan_gives_an_anatomically_ordered_face() {
    use FeaturePoint::*;
    let m = denoised(&common::gavab("cara1_frontal1.wrl"));
    let r = landmarks::detect(&m, &LandmarkParams::default()).unwrap();
    let g = |p| r.landmarks.get(p);
    // Subject's left is +x; eyes above the nose tip, mouth below, chin lowest.
    assert!(g(InnerEyeLeft).x > g(NoseTip).x && g(NoseTip).x > g(InnerEyeRight).x);
    assert!(g(OuterEyeLeft).x > g(InnerEyeLeft).x && g(OuterEyeRight).x < g(InnerEyeRight).x);
    assert!(g(InnerEyeLeft).y > g(NoseTip).y && g(InnerEyeRight).y > g(NoseTip).y);
    assert!(g(MouthCornerLeft).y < g(NoseCornerLeft).y && g(Chin).y < g(MouthCornerLeft).y);
    assert!(g(Forehead).y > g(InnerEyeLeft).y);
    // The nose tip is the most protruding of the points.
    for (p, x) in r.landmarks.iter() {
        assert!(
            p == NoseTip || x.z < g(NoseTip).z,
            "{p} in front of the nose tip"
        );
    }
    assert_eq!(r.distances.len(), 9);
    assert_eq!(r.level.len(), 4);
    assert!(r.level.iter().all(|l| l.in_range), "{:?}", r.level);
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

#[test]
fn real_scans_with_one_eye_corner_off_are_flagged_by_the_level_check() {
    // Seen in a zoomed eye picture beside the independent detector's points: cara52_frontal2's
    // left inner corner sits ~5 mm below the canthus, on the side of the nose, the right one
    // ~3 mm above its canthus. No other concave region gives a level pair, so detection keeps
    // them; the level check flags the inner pair (measured 10.8 mm apart in height; 6.3 with
    // 5 descriptor rings and the line of sight over every surface near the face).
    let name = "pointclouds/cara52_frontal2_filtered_raw.txt";
    let r = landmarks::detect(&denoised(&common::gavab(name)), &LandmarkParams::default()).unwrap();
    let inner = r.level.iter().find(|l| l.name == "inner_eye").unwrap();
    assert!(
        !inner.in_range && inner.difference_mm.abs() > landmarks::LEVEL_MAX_MM,
        "{name}: inner corners {:.1} mm apart in height",
        inner.difference_mm
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w.starts_with("inner_eye_left/inner_eye_right")),
        "{name}: {:?}",
        r.warnings
    );
    // cara48_frontal1's left corner was on the nose's flank, 8–10 mm low, in the scanner frame;
    // in the located face's frame it is on the eye (4.4 mm from the independent detector's) and
    // the pair is level, so nothing is flagged.
    let name = "pointclouds/cara48_frontal1_filtered_raw.txt";
    let r = landmarks::detect(&denoised(&common::gavab(name)), &LandmarkParams::default()).unwrap();
    let inner = r.level.iter().find(|l| l.name == "inner_eye").unwrap();
    assert!(inner.in_range, "{name}: {inner:?}");
    assert!(
        !r.warnings
            .iter()
            .any(|w| w.starts_with("inner_eye_left/inner_eye_right")),
        "{name}: {:?}",
        r.warnings
    );
}

#[test]
fn a_generic_face_fit_far_from_the_detected_nose_tip_is_reported() {
    // cara48_frontal1's fit of the generic face slid down the face (its nose tip on the upper
    // lip, 25.7 mm from the detected one, which the independent detector puts 5.1 mm from its
    // own); the steps still found the face, so only a warning says that the orientation
    // figures are that fit's. cara1_frontal1's fit lies on the nose (1.4 mm).
    for (name, slid) in [
        ("pointclouds/cara48_frontal1_filtered_raw.txt", true),
        ("cara1_frontal1.wrl", false),
    ] {
        let r =
            landmarks::detect(&denoised(&common::gavab(name)), &LandmarkParams::default()).unwrap();
        let off_mm = r.fit_nose_tip_offset_mm().unwrap();
        let warned =
            (r.warnings.iter()).any(|w| w.starts_with("face localisation: the generic face's fit"));
        assert_eq!(
            off_mm > landmarks::FIT_NOSE_TIP_WARN_MM,
            slid,
            "{name}: the fit's nose tip is {off_mm:.1} mm from the detected one"
        );
        assert_eq!(warned, slid, "{name}: {:?}", r.warnings);
    }
}

#[test]
fn a_suspect_best_ranked_face_gives_way_to_a_lower_ranked_plausible_one() {
    // A broad smile on a face far from the average (generated seed 359, subj001_sonrisa): the
    // generic face's fit slid a face's length down onto the chin, started in the scanner
    // frame, outranks the right fit (a tilted start) by the scanner-frame prior, and the steps
    // inside it give a suspect face. The lower-ranked finalist then gets the steps too.
    let dir = common::synth_dataset(2, 359, false);
    let mesh = denoised(&dir.join("subj001_sonrisa.wrl"));
    let truth = ScanTruth::load(&dir.join("subj001_sonrisa.json")).unwrap();
    let tip = DVec3::from_array(truth.feature_point(FeaturePoint::NoseTip).unwrap().xyz_mm);
    let params = landmarks::localise::LocaliseParams::default();
    let finalists = landmarks::localise::localise_finalists(&mesh, &params).unwrap();
    let (first, first_rank) = finalists[0];
    assert!(
        first.nose_tip_in_scan.distance(tip) > 40.0,
        "the best-ranked fit is no longer the slid one: {first:?}"
    );
    // The fit nearest the truth (an average face fitted to a smile: its nose tip lies ~15 mm
    // off) ranks outside the tie.
    let (near, near_rank) = (finalists.iter())
        .min_by(|a, b| {
            let d = |f: &landmarks::localise::Localisation| f.nose_tip_in_scan.distance(tip);
            d(&a.0).total_cmp(&d(&b.0))
        })
        .unwrap();
    assert!(
        near.nose_tip_in_scan.distance(tip) < 20.0,
        "no finalist near the nose: {finalists:?}"
    );
    assert!(
        *near_rank < first_rank - landmarks::PLAUSIBILITY_TIE,
        "the nearest fit ties with the slid one ({near_rank} vs {first_rank})"
    );
    let r = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
    for (p, truth_mm, _) in truth.feature_points() {
        let off_mm = r.landmarks.get(p).distance(truth_mm);
        assert!(
            off_mm < eval::SUCCESS_RADIUS_MM,
            "{}: {off_mm:.1} mm from the truth; suspect: {:?}",
            p.name(),
            r.suspect
        );
    }
    // The user is told which fit was kept, and why.
    assert!(
        (r.warnings.iter()).any(|w| w.contains("a lower-ranked fit")),
        "{:?}",
        r.warnings
    );
    assert!(r.suspect.is_empty(), "{:?}", r.suspect);
}

#[test]
fn a_lower_ranked_fit_of_the_same_face_does_not_lift_a_suspect_flag() {
    // Generated seed 379, subj004_frontal1 (mouth and chin low for Table 2): the face is found
    // twice, from the scanner frame (within the tie) and from a tilted start 2–5° apart (the
    // prior puts it outside). The steps inside the former fail three Table 2 checks; inside the
    // latter, with the nose tip 3.7 mm lower, they pass. That is no evidence that the former
    // frame was wrong, so its result stands, flagged.
    let dir = common::synth_dataset(5, 379, false);
    let mesh = denoised(&dir.join("subj004_frontal1.wrl"));
    let params = landmarks::localise::LocaliseParams::default();
    let finalists = landmarks::localise::localise_finalists(&mesh, &params).unwrap();
    let r = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
    let kept = r.localisation.unwrap().nose_tip_in_scan;
    let rank_of = |tip: DVec3| {
        let found = finalists
            .iter()
            .find(|(f, _)| f.nose_tip_in_scan.distance(tip) < 1e-9);
        found.expect("the result's fit is a finalist").1
    };
    let tie = finalists[0].1 - landmarks::PLAUSIBILITY_TIE;
    assert!(
        finalists.iter().any(|(f, rank)| {
            *rank < tie
                && f.face_likeness >= params.face_likeness_min
                && f.nose_tip_in_scan.distance(kept) < landmarks::localise::DISTINCT_FIT_MM
        }),
        "no lower-ranked face-like fit of the same face: {finalists:?}"
    );
    assert!(rank_of(kept) >= tie, "a lower-ranked fit won: {kept}");
    assert!(!r.suspect.is_empty(), "{:?}", r.distances);
}

#[test]
fn meshes_without_a_face_are_typed_errors() {
    // A flat plate: nothing protrudes like a nose.
    let mut p = Vec::new();
    let n = 80;
    for j in 0..n {
        for i in 0..n {
            p.push(DVec3::new(i as f64 * 2.0, j as f64 * 2.0, 0.0));
        }
    }
    let mut f = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let k = (j * n + i) as u32;
            f.push([k, k + 1, k + 1 + n as u32, k + n as u32]);
        }
    }
    let plate = Mesh::from_faces(p.clone(), f.clone());
    let e = landmarks::detect(&plate, &LandmarkParams::default()).unwrap_err();
    assert!(e.to_string().contains("protrudes like a nose"), "{e}");
    // Facing away from the scanner: no orientation shows a nose either.
    let back = Mesh::from_faces(p.clone(), f.iter().map(|q| [q[0], q[3], q[2], q[1]]));
    let e = landmarks::detect(&back, &LandmarkParams::default()).unwrap_err();
    assert!(e.to_string().contains("protrudes like a nose"), "{e}");
    // Without localisation (the paper's steps on the scan as it is): no face region.
    let paper = LandmarkParams {
        localise: None,
        ..LandmarkParams::default()
    };
    let back = Mesh::from_faces(p, f.iter().map(|q| [q[0], q[3], q[2], q[1]]));
    let e = landmarks::detect(&back, &paper).unwrap_err();
    assert!(e.to_string().contains("segmentation"), "{e}");
    // An empty mesh.
    assert!(landmarks::detect(&Mesh::default(), &LandmarkParams::default()).is_err());
}

/// The descriptors' fit reaches the same millimetres at any sampling: 10 mm is 5 rings of a
/// 2 mm grid and 10 of a 1 mm grid; the rings stay within their bounds on extreme grids; with
/// no reach the given rings are used whatever the spacing.
#[test]
fn descriptor_rings_follow_the_sampling() {
    let params = LandmarkParams::default();
    for (step_mm, rings) in [
        (2.0, 5),
        (1.0, 10),
        (0.25, landmarks::MAX_DESCRIPTOR_RINGS),
        (20.0, landmarks::MIN_DESCRIPTOR_RINGS),
    ] {
        let mut plate = Mesh::default();
        add_patch(
            &mut plate,
            (0.0, 40.0 * step_mm),
            (0.0, 40.0 * step_mm),
            step_mm,
            &|_, _| 0.0,
        );
        assert_eq!(
            params.curvature_for(&plate, None).rings,
            rings,
            "{step_mm} mm"
        );
        let fixed = LandmarkParams {
            descriptor_reach_mm: None,
            ..params
        };
        assert_eq!(
            fixed.curvature_for(&plate, None).rings,
            params.curvature.rings
        );
    }
}

/// `mesh` with every triangle split into four at its edge midpoints: the same piecewise-linear
/// surface sampled at half the spacing.
fn split_one_to_four(mesh: &Mesh) -> Mesh {
    let mut positions = mesh.positions_mm.clone();
    let mut mids = std::collections::HashMap::new();
    let mut mid = |a: u32, b: u32| {
        *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
            positions.push((mesh.positions_mm[a as usize] + mesh.positions_mm[b as usize]) / 2.0);
            positions.len() as u32 - 1
        })
    };
    let mut faces = Vec::new();
    for [a, b, c] in mesh.triangles() {
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        faces.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    Mesh::from_faces(positions, faces)
}

/// A scanner that samples the face twice as densely gives the same points: real scans split
/// 1 → 4 (GavabDB's ~1.7 mm spacing becomes ~0.85 mm, a structured-light scanner's) are
/// detected like the scans themselves, because the descriptors' fit reaches the same
/// millimetres (`LandmarkParams::descriptor_reach_mm`). Measured: no anatomical point moves
/// more than 4.4 (cara1_sonrisa) and 3.0 mm (cara48_frontal1), neither is suspect; with 5
/// rings whatever the spacing, a mouth corner moved 14.1 mm (suspect) and an inner eye corner
/// 11.2 mm. On the 34 real scans the median of the largest move is 4.5 mm
/// (`scripts/resample_real.py`).
#[test]
fn a_scan_sampled_twice_as_densely_gives_the_same_points() {
    for path in [
        common::gavab("cara1_sonrisa.wrl"),
        common::gavab("pointclouds/cara48_frontal1_filtered_raw.txt"),
    ] {
        let raw = io::read_mesh(&path).unwrap();
        let mut dense = split_one_to_four(&raw);
        denoise::denoise(&mut dense, &denoise::DenoiseParams::default()).unwrap();
        let plain = landmarks::detect(&denoised(&path), &LandmarkParams::default()).unwrap();
        let found = landmarks::detect(&dense, &LandmarkParams::default()).unwrap();
        assert!(found.suspect.is_empty(), "{path:?}: {:?}", found.suspect);
        // The report gives the sampling: about half the spacing (more where the split turned
        // quads into triangles, whose diagonals are edges too: cara1_sonrisa 0.57), about twice
        // the rings.
        let (d, p) = (found.descriptors.unwrap(), plain.descriptors.unwrap());
        let half = d.spacing_mm / p.spacing_mm;
        assert!((0.45..0.6).contains(&half), "{path:?}: {d:?} against {p:?}");
        assert!(
            d.rings.abs_diff(2 * p.rings) <= 1,
            "{path:?}: {d:?} against {p:?}"
        );
        for p in FeaturePoint::ALL
            .into_iter()
            .filter(|p| !FeaturePoint::BORDER.contains(p))
        {
            let moved = found.landmarks.get(p).distance(plain.landmarks.get(p));
            assert!(moved < 6.0, "{path:?}: {} moved {moved:.1} mm", p.name());
        }
    }
}

/// Something that protrudes like a nose but is no face (a round bump, an elongated ridge on a
/// plate 180 mm wide) is detected, but the detection is suspect for its face-likeness (measured
/// 0.21 and 0.24; real faces 0.44–0.85), not only for the points it had to guess.
#[test]
fn a_bump_that_protrudes_like_a_nose_is_not_face_like() {
    let bump = |x: f64, y: f64| 20.0 * (-(x * x + y * y) / (2.0 * 12f64.powi(2))).exp();
    let ridge = |x: f64, y: f64| {
        25.0 * (-(x * x) / (2.0 * 10f64.powi(2)) - (y * y) / (2.0 * 25f64.powi(2))).exp()
    };
    for (name, z) in [
        ("bump", &bump as &dyn Fn(f64, f64) -> f64),
        ("ridge", &ridge),
    ] {
        let mut mesh = Mesh::default();
        add_patch(&mut mesh, (-90.0, 90.0), (-90.0, 90.0), 2.0, z);
        let report = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
        let likeness = report.localisation.unwrap().face_likeness;
        let params = landmarks::localise::LocaliseParams::default();
        assert!(likeness < params.face_likeness_min, "{name}: {likeness}");
        assert!(
            report
                .suspect
                .iter()
                .any(|r| r.starts_with("face-likeness")),
            "{name}: {:?}",
            report.suspect
        );
    }
}

#[test]
fn cheek_borders_are_level_and_where_the_generic_face_has_its_cheeks() {
    use FeaturePoint::*;
    // Generated neutral scans: the cheek points against the generic face's definition of
    // them (registration::truth_points: at the nose tip's height, 12 % of the outer-eye
    // distance beyond the outer eye corner). Measured 5.7 mm mean (xy) over 480 cheeks; the
    // paper's region centroid was 15.2 mm off.
    let dir = common::synth_dataset(4, 3, false);
    let mut errors = Vec::new();
    for s in 0..4 {
        let stem = format!("subj{s:03}_frontal1");
        let mesh = denoised(&dir.join(format!("{stem}.wrl")));
        let found = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
        let truth = facesynth::registration::truth_points(&dir.join(format!("{stem}.json")), &mesh)
            .unwrap();
        for p in [CheekLeft, CheekRight] {
            let d = found.landmarks.get(p) - truth.landmarks.get(p);
            errors.push(d.truncate().length());
        }
    }
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    assert!(mean < 9.0, "cheek xy errors {errors:?}");
    // Real scan cara2_frontal2: the region centroid put one cheek at eye height and the other
    // at mouth height (44 mm apart); the borders are now level and beside the outer eyes.
    let r = landmarks::detect(
        &denoised(&common::gavab("pointclouds/cara2_frontal2.txt")),
        &LandmarkParams::default(),
    )
    .unwrap();
    let g = |p| r.landmarks.get(p);
    assert!((g(CheekLeft).y - g(CheekRight).y).abs() < 5.0);
    // Beside the outer eye corners (the generic face's cheek is ~11 mm beyond them; the
    // strip starts 5 mm inside them). Measured 0.2 mm (left) and 9.6 mm (right).
    for (cheek, outer) in [(CheekLeft, OuterEyeLeft), (CheekRight, OuterEyeRight)] {
        let apart = (g(cheek).x - g(outer).x).abs();
        assert!(apart < 10.0, "{cheek:?} {apart} mm from {outer:?}");
    }
    assert!(g(CheekLeft).y < g(OuterEyeLeft).y && g(CheekLeft).y > g(MouthCornerLeft).y);
}

/// Real scans turned by known rotations (the head rolled, turned and pitched; the file's axes
/// y-up facing −z, z-up, rolled 90°) give the same points, turned back, within 2 mm: face
/// localisation finds the face's frame whatever the data's. The ten anatomical points within
/// 2 mm; the cheek borders and the forehead (region borders, found where a slope crosses a
/// threshold, which a 0.1–0.5° difference in the located frame moves) within 5 mm.
#[test]
fn real_scans_give_the_same_points_in_any_orientation() {
    use std::f64::consts::FRAC_PI_2;
    let deg = |d: f64| d.to_radians();
    let rotations = [
        ("roll +20", DMat3::from_rotation_z(deg(20.0))),
        ("roll -20", DMat3::from_rotation_z(deg(-20.0))),
        ("yaw +30", DMat3::from_rotation_y(deg(30.0))),
        ("yaw -30", DMat3::from_rotation_y(deg(-30.0))),
        ("pitch +25", DMat3::from_rotation_x(deg(25.0))),
        ("pitch -25", DMat3::from_rotation_x(deg(-25.0))),
        ("facing -z", DMat3::from_rotation_y(2.0 * FRAC_PI_2)),
        ("z up", DMat3::from_rotation_x(FRAC_PI_2)),
        ("rolled 90", DMat3::from_rotation_z(FRAC_PI_2)),
    ];
    let data = common::shared_dir().join("data");
    for name in [
        "gavabdb/cara1_frontal1.wrl",
        "gavabdb/cara1_abajo.wrl",
        "poldb/pol_2.wrl",
    ] {
        let base = denoised(&data.join(name));
        let level = landmarks::detect(&base, &LandmarkParams::default()).unwrap();
        let tip = level.landmarks.get(FeaturePoint::NoseTip);
        let pivot = tip - DVec3::new(0.0, 0.0, 90.0);
        for (what, r) in rotations {
            let mut m = base.clone();
            for p in &mut m.positions_mm {
                *p = r * (*p - pivot) + DVec3::new(10.0, -20.0, 30.0);
            }
            m.update_normals();
            let found = landmarks::detect(&m, &LandmarkParams::default())
                .unwrap_or_else(|e| panic!("{name} {what}: {e}"));
            let mut worst = (0.0, FeaturePoint::NoseTip);
            for p in FeaturePoint::ALL {
                let back = r.transpose() * (found.landmarks.get(p) - DVec3::new(10.0, -20.0, 30.0))
                    + pivot;
                let err = (back - level.landmarks.get(p)).length();
                println!("{name} {what}: {p} {err:.2} mm");
                // Anatomical points within 2 mm (measured 0.00); the region borders within
                // 5 mm (measured: cara1_abajo's forehead 1.97 mm, all else ≤ 0.3 mm).
                let bound = if FeaturePoint::BORDER.contains(&p) {
                    5.0
                } else {
                    2.0
                };
                if err > bound && err > worst.0 {
                    worst = (err, p);
                }
            }
            // Whether the points are suspect does not depend on the file's axes either (a face
            // towards −z is not a head turned 180°).
            assert_eq!(
                found.suspect.is_empty(),
                level.suspect.is_empty(),
                "{name} {what}: {:?} / {:?}",
                found.suspect,
                level.suspect
            );
            assert!(
                worst.0 == 0.0,
                "{name} {what}: {} off by {:.1} mm",
                worst.1,
                worst.0
            );
        }
    }
}

/// Adds a grid patch sampled every `step` mm over (x, y) ∈ [u0, u1] × [v0, v1] (scanner
/// frame), depth z(x, y), facing +z.
fn add_patch(m: &mut Mesh, u: (f64, f64), v: (f64, f64), step: f64, z: &dyn Fn(f64, f64) -> f64) {
    let (nu, nv) = (((u.1 - u.0) / step) as u32, ((v.1 - v.0) / step) as u32);
    let first = m.positions_mm.len() as u32;
    let mut faces = Vec::new();
    for j in 0..=nv {
        for i in 0..=nu {
            let (x, y) = (u.0 + step * i as f64, v.0 + step * j as f64);
            m.positions_mm.push(DVec3::new(x, y, z(x, y)));
            if i < nu && j < nv {
                let k = first + j * (nu + 1) + i;
                faces.push([k, k + 1, k + nu + 2, k + nu + 1]);
            }
        }
    }
    for f in faces {
        m.faces.push(&f);
    }
    m.update_normals();
}

/// Step 4's search box lies in the face plane; what lies far behind the eye there (the side of
/// the head, an ear, a spike cluster) is not the lateral canthus. With the skin beside the
/// right eye pressed flat and a concave dish 90 mm behind the eye, 16 mm lateral, inside the
/// box, neither the corner nor any tilted view's corner is put on the dish (one was, 94 mm
/// off, on a generated scan whose canthus had no concave region).
#[test]
fn a_concave_dish_far_behind_the_eye_is_not_the_outer_eye_corner() {
    let (mut mesh, truth, _) = generated_scan("subj000_frontal1");
    let at = |p| DVec3::from_array(truth.feature_point(p).unwrap().xyz_mm);
    let (outer, inner) = (
        at(FeaturePoint::OuterEyeRight),
        at(FeaturePoint::InnerEyeRight),
    );
    // The skin beside the right eye pressed flat (no concave region left in the box).
    for p in &mut mesh.positions_mm {
        let (lateral, up) = (inner.x - p.x, p.y - inner.y);
        if (8.0..60.0).contains(&lateral) && (-22.0..20.0).contains(&up) {
            p.z = inner.z - 6.0;
        }
    }
    mesh.update_normals();
    // A spherical cup of radius 8 mm (shape index 0), deepest at its centre.
    let centre = outer - DVec3::new(16.0, 0.0, 90.0);
    let cup = |x: f64, y: f64| {
        let d2 = (x - centre.x).powi(2) + (y - centre.y).powi(2);
        centre.z + 8.0 - (64.0 - d2.min(63.0)).sqrt()
    };
    add_patch(
        &mut mesh,
        (centre.x - 6.0, centre.x + 6.0),
        (centre.y - 6.0, centre.y + 6.0),
        1.0,
        &cup,
    );
    let found = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
    let corner = found.landmarks.get(FeaturePoint::OuterEyeRight);
    assert!(
        corner.z > inner.z - landmarks::OUTER_EYE_MAX_BEHIND_MM,
        "outer eye corner {corner} on the dish (inner corner {inner})"
    );
    // Nor in any of the consensus' tilted views: one there would lie ~90 mm from the others
    // (measured without the depth gate: 84 mm; with it: 14 mm, the flattened skin's edge).
    let spread = found.spread_mm.unwrap()[FeaturePoint::OuterEyeRight.index()];
    assert!(
        spread < 45.0,
        "a view put the corner on the dish: spread {spread:.0} mm"
    );
}

/// Made-harder real scans: a torso (a broad surface below the chin that bulges further towards
/// the scanner than the nose) or a hair cap (a bumpy dome over the forehead) added to a real
/// scan does not move the ten anatomical points by more than 2 mm. cara1_abajo looks down:
/// while the line of sight was the mean normal of the whole file, either clutter turned it and
/// moved the left inner eye corner 5.7 mm. cara5_gesto (a grimace, pitched 20°) is fitted
/// by the generic face differently from starts 3 mm apart: while the fits started from the
/// centres of grid cells counted from the scan's lowest corner, either clutter moved the
/// starts and the nose tip 2.3 mm.
#[test]
fn clutter_below_the_chin_or_over_the_forehead_does_not_move_the_points() {
    for name in [
        "cara1_frontal1.wrl",
        "cara1_abajo.wrl",
        "pointclouds/cara5_gesto.txt",
    ] {
        clutter_does_not_move_the_points(name);
    }
}

fn clutter_does_not_move_the_points(name: &str) {
    let base = denoised(&common::gavab(name));
    let level = landmarks::detect(&base, &LandmarkParams::default()).unwrap();
    let tip = level.landmarks.get(FeaturePoint::NoseTip);
    let chin = level.landmarks.get(FeaturePoint::Chin);
    let forehead = level.landmarks.get(FeaturePoint::Forehead);
    // Torso: 360 mm wide, from 40 mm below the chin down 200 mm, its front 15 mm in front of
    // the nose tip (a chest seen from a scanner level with the face), rounded to the sides.
    let mut torso = base.clone();
    let top = chin.y - 40.0;
    add_patch(
        &mut torso,
        (tip.x - 180.0, tip.x + 180.0),
        (top - 200.0, top),
        2.0,
        &|x, _| tip.z + 15.0 - ((x - tip.x) / 60.0).powi(2) * 10.0,
    );
    // Hair cap: a bumpy dome from 20 mm above the forehead point, 200 mm wide, 10 mm in front
    // of the brow's depth.
    let mut hair = base.clone();
    let low = forehead.y + 20.0;
    add_patch(
        &mut hair,
        (tip.x - 100.0, tip.x + 100.0),
        (low, low + 80.0),
        2.0,
        &|x, y| {
            forehead.z + 10.0 - ((x - tip.x) / 50.0).powi(2) * 8.0 - (y - low) * 0.3
                + 3.0 * (x * 0.3).sin() * (y * 0.25).cos()
        },
    );
    // The torso is clutter that fools the paper's steps alone (largest front-facing region,
    // most protruding point: measured 127 mm off).
    let paper = LandmarkParams {
        localise: None,
        ..LandmarkParams::default()
    };
    let fooled = landmarks::detect(&torso, &paper).map_or(f64::INFINITY, |r| {
        (r.landmarks.get(FeaturePoint::NoseTip) - tip).length()
    });
    assert!(
        fooled > 30.0,
        "{name}: the torso did not fool the paper's steps"
    );
    // A wall: a flat surface 360 × 200 mm, 300 mm beside the face and 200 mm behind the nose
    // tip, turned 45° (seen from the scanner). Before, it moved cara1_abajo's points 133 mm.
    let mut wall = base.clone();
    add_patch(
        &mut wall,
        (tip.x + 300.0, tip.x + 660.0),
        (tip.y - 100.0, tip.y + 100.0),
        2.0,
        &|x, _| tip.z - 200.0 + (x - tip.x - 300.0),
    );
    for (what, m) in [("torso", torso), ("hair cap", hair), ("wall", wall)] {
        let found = landmarks::detect(&m, &LandmarkParams::default())
            .unwrap_or_else(|e| panic!("{name} {what}: {e}"));
        for p in FeaturePoint::ALL {
            if FeaturePoint::BORDER.contains(&p) {
                continue;
            }
            let err = (found.landmarks.get(p) - level.landmarks.get(p)).length();
            assert!(err <= 2.0, "{name} {what}: {p} moved {err:.1} mm");
        }
        assert!(
            found.suspect.is_empty(),
            "{name} {what}: {:?}",
            found.suspect
        );
    }
}

/// Marks every Table 2 and level check of `report` as passed.
fn pass_every_check(report: &mut landmarks::LandmarkReport) {
    for d in &mut report.distances {
        d.in_range = true;
    }
    for l in &mut report.level {
        l.in_range = true;
    }
}

/// The detection on the small generated set's scan `stem`, every check marked as passed: a
/// report to edit into the cases of the suspect rules.
fn passing_report(stem: &str) -> landmarks::LandmarkReport {
    let (mesh, _, _) = generated_scan(stem);
    let mut report = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
    pass_every_check(&mut report);
    report
}

#[test]
fn three_failed_checks_or_unstable_points_make_a_detection_suspect() {
    let (mesh, _, _) = generated_scan("subj000_frontal1");
    let mut report = landmarks::detect(&mesh, &LandmarkParams::default()).unwrap();
    assert!(report.suspect.is_empty(), "{:?}", report.suspect);
    // From a detection whose checks all pass, fail one, two, then three Table 2 checks.
    pass_every_check(&mut report);
    let params = landmarks::localise::LocaliseParams::default();
    let fail = |report: &mut landmarks::LandmarkReport, k: usize| {
        report.distances[k].in_range = false;
        landmarks::suspect_reasons(None, report, &params)
    };
    assert!(
        fail(&mut report, 0).is_empty(),
        "one failed check is an unusual face"
    );
    assert!(
        fail(&mut report, 1).is_empty(),
        "two failed checks are an unusual face"
    );
    let reasons = fail(&mut report, 2);
    assert_eq!(reasons.len(), 1, "{reasons:?}");
    for d in &report.distances[..3] {
        assert!(
            reasons[0].contains(&d.name),
            "{} not named: {reasons:?}",
            d.name
        );
    }
    // Two failed checks and an anatomical point the tilted views disagree on are three
    // problems too; an unstable region border (the forehead) is not one.
    report.distances[2].in_range = true;
    let mut spread = [0.0; FeaturePoint::COUNT];
    spread[FeaturePoint::Forehead.index()] = 40.0;
    report.spread_mm = Some(spread);
    assert!(landmarks::suspect_reasons(None, &report, &params).is_empty());
    spread[FeaturePoint::InnerEyeLeft.index()] = landmarks::UNSTABLE_SPREAD_MM + 1.0;
    report.spread_mm = Some(spread);
    let reasons = landmarks::suspect_reasons(None, &report, &params);
    assert_eq!(reasons.len(), 1, "{reasons:?}");
    assert!(reasons[0].contains("apart: inner_eye_left)"), "{reasons:?}");
}

/// The rule by which a lower-ranked localisation finalist replaces a suspect result, on one
/// detection's report edited: failed checks, a moved nose tip, a suspect reason.
#[test]
fn a_second_opinion_needs_fewer_problems_no_suspicion_and_the_nose_elsewhere() {
    let mut plain = passing_report("subj000_frontal1");
    plain.suspect.clear();
    let params = landmarks::localise::LocaliseParams::default();
    let suspect = |mut r: landmarks::LandmarkReport| {
        for d in &mut r.distances[..landmarks::SUSPECT_FAILED_CHECKS] {
            d.in_range = false;
        }
        r.suspect = landmarks::suspect_reasons(None, &r, &params);
        assert!(!r.suspect.is_empty());
        r
    };
    let moved = |by_mm: f64| {
        let mut r = plain.clone();
        let tip = r.landmarks.get(FeaturePoint::NoseTip);
        r.landmarks
            .set(FeaturePoint::NoseTip, tip + DVec3::new(0.0, by_mm, 0.0));
        r
    };
    let first = suspect(plain.clone());
    let far = landmarks::localise::DISTINCT_FIT_MM + 5.0;
    assert!(landmarks::second_opinion_wins(&first, &moved(far)));
    // The same nose: another frame whose checks pass is no evidence.
    let near = landmarks::localise::DISTINCT_FIT_MM - 5.0;
    assert!(!landmarks::second_opinion_wins(&first, &moved(near)));
    // Suspect itself, or no more plausible: no better than the first.
    assert!(!landmarks::second_opinion_wins(
        &first,
        &suspect(moved(far))
    ));
    let mut guessed = moved(far);
    guessed.suspect.push("a guessed anatomical point".into());
    assert!(!landmarks::second_opinion_wins(&first, &guessed));
}

/// A left/right pair (eye, nose or mouth corners) whose heights differ by more than
/// `SUSPECT_LEVEL_MM` makes a detection suspect alone; just under it (a one-sided smile lifts
/// one mouth corner about 7 mm), it is one failed check among others.
#[test]
fn a_pair_far_from_level_makes_a_detection_suspect_alone() {
    let report = passing_report("subj000_frontal1");
    let params = landmarks::localise::LocaliseParams::default();
    let limit = landmarks::SUSPECT_LEVEL_MM;
    for k in 0..report.level.len() {
        for (difference, suspect) in [(limit - 0.5, false), (-limit - 0.5, true)] {
            let mut r = report.clone();
            r.level[k].difference_mm = difference;
            r.level[k].in_range = false;
            let reasons = landmarks::suspect_reasons(None, &r, &params);
            assert_eq!(
                !reasons.is_empty(),
                suspect,
                "{} {difference}: {reasons:?}",
                r.level[k].name
            );
            if suspect {
                assert!(reasons[0].contains(r.level[k].name), "{reasons:?}");
            }
        }
    }
}

#[test]
fn implausibility_counts_failed_checks_guesses_and_unstable_anatomical_points() {
    use FeaturePoint::*;
    let mut report = passing_report("subj001_frontal1");
    report.guessed.clear();
    let mut spread = [0.0; FeaturePoint::COUNT];
    report.spread_mm = Some(spread);
    assert_eq!(landmarks::implausibility(&report), 0);
    report.distances[0].in_range = false;
    report.level[0].in_range = false;
    assert_eq!(landmarks::implausibility(&report), 2);
    // Region borders (forehead, cheeks) count neither guessed nor unstable; the chin does.
    report.guessed = vec![Forehead, Chin];
    spread[CheekLeft.index()] = 50.0;
    spread[OuterEyeLeft.index()] = landmarks::UNSTABLE_SPREAD_MM + 1.0;
    spread[OuterEyeRight.index()] = landmarks::UNSTABLE_SPREAD_MM;
    report.spread_mm = Some(spread);
    assert_eq!(landmarks::implausibility(&report), 4);
}
