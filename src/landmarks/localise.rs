//! Face localisation: where the face is in a scan and how the head is turned, found before the
//! paper's nine steps so that they run on a frontal, upright face.
//!
//! The paper's steps assume a frontal face in the scanner frame, and its step 1 takes the
//! biggest front-facing region as the face. Real scans break both: a torso, collar or shoulders
//! in view can be bigger than the face or protrude further than the nose; heads are pitched,
//! rolled and turned; meshes from other tools come y-up or facing −z. So candidates for the face
//! are generated and each is scored by how face-like it is:
//!
//! 1. **Orientations.** The scanner frame first (face towards +z, y up). Where no candidate
//!    there is face-like (below [`LocaliseParams::face_likeness_min`]), the 23 other
//!    axis-aligned frames are tried too (face towards ±x, ±y, ±z, up along one of the other
//!    two axes), and the best candidate of all wins.
//! 2. **Nose candidates** per orientation: the peaks of protrusion (depth minus the mean depth
//!    on a circle of [`LocaliseParams::probe_radius_mm`] around it, as in step 2) on a 3 mm
//!    depth grid, at most [`LocaliseParams::candidates`] per orientation, 30 mm apart, each
//!    moved to the local maximum of depth it climbs to (a vertex, not a cell centre). A nose
//!    protrudes 15–25 mm from the cheeks, lip and brow at that radius; a chin, a collar or a
//!    shoulder can protrude as far, which is why the candidates are scored and not trusted.
//! 3. **Fit** of the generic face's upper part (every vertex above [`TEMPLATE_MIN_Y_MM`]:
//!    forehead, eyes, nose, upper cheeks, which an expression moves little) from each
//!    candidate: iterated closest points, pairs trimmed at 15, then 9, then 6 mm; Horn's closed
//!    form (point-to-point) first, then Gauss–Newton on point-to-plane distances, which lets
//!    the template slide into place along the surface. Rotation, translation and an isotropic
//!    scale within 0.8–1.25 (faces differ in size by about ±10 %).
//! 4. **Face-likeness**: the fraction of the whole generic face (every 12th vertex) within
//!    [`LocaliseParams::inlier_mm`] of the scan after the fit. It is 0 for no face and near 1
//!    for a complete face of average shape; holes (eyes lost by the scanner), hair over the
//!    forehead, an expression and a face far from average lower it (real frontal scans score
//!    0.55–0.87; wrong candidates up to ~0.6).
//! 5. **Decision**: the three best distinct candidates (a fit started in the scanner frame
//!    ranked [`SCANNER_FRAME_PRIOR`] higher: most scans are frontal, and a wrong fit can score
//!    as high as the right one on an unusual face) are refitted on the surface with a dense
//!    template (every 3rd vertex) and scored again, best first ([`localise_finalists`]); the
//!    first is the face, unless another within `PLAUSIBILITY_TIE` of it gives the feature steps
//!    an anatomically more plausible result, or the first's result is suspect and a face-like
//!    finalist ranked lower gives a more plausible one (`super::detect`).
//!
//! The winning fit gives the face frame: the rotation that turns the scan so that the face looks
//! along +z with its forehead up ([`Localisation::face_from_scan`]). Differences from the
//! paper: it has no such search (its scans are frontal by construction).

use crate::generic_face;
use crate::mesh::Mesh;
use crate::mesh::SurfaceIndex;
use crate::registration::horn_absolute_orientation;
use crate::{Error, Result};
use glam::{DMat3, DVec2, DVec3};
use std::sync::OnceLock;

mod axes;
mod fit;

pub use axes::{AxisFrame, facing_and_up, nearest_axis_frame, yaw_pitch_roll_deg};
use fit::{IcpStage, Pose, VERTEX_GRID_CELL_MM, VertexGrid, icp, score};

/// Template points are the generic face's vertices above this height (nose tip at 0), mm: the
/// upper lip and below move with expressions and the jaw.
pub const TEMPLATE_MIN_Y_MM: f64 = -20.0;

/// Parameters of [`localise`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocaliseParams {
    /// Nose candidates kept per orientation. Default 4.
    pub candidates: usize,
    /// Radius of the protrusion probe, mm. Default 25 (the nose's base half-width).
    pub probe_radius_mm: f64,
    /// Smallest protrusion of a nose candidate, mm. Default 8.
    pub min_protrusion_mm: f64,
    /// A template point within this distance of the scan after the fit counts as matched, mm.
    /// Default 4 (faces differ from the average by a few mm; non-faces by tens).
    pub inlier_mm: f64,
    /// Below this face-likeness the scanner frame is not trusted and the other orientations are
    /// searched; below it after the search the detection is suspect. Default 0.5.
    pub face_likeness_min: f64,
    /// Search the other 23 axis-aligned orientations when the scanner frame gives no face.
    /// Default true; false trusts the scanner frame (face towards +z, y up).
    pub search_orientations: bool,
    /// The file's axes where the user knows them (`--facing`, `--up`): the face looks along
    /// `facing` with its forehead towards `up`, and no other axis frame is searched. Default
    /// `None`: the scanner frame first, then the search.
    pub axes: Option<AxisFrame>,
}

impl Default for LocaliseParams {
    fn default() -> Self {
        LocaliseParams {
            candidates: 4,
            probe_radius_mm: 25.0,
            min_protrusion_mm: 8.0,
            inlier_mm: 4.0,
            face_likeness_min: 0.5,
            search_orientations: true,
            axes: None,
        }
    }
}

/// Where the face is and how it is turned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Localisation {
    /// Rotation from the scan frame into the face frame: the face looks along +z, its forehead
    /// towards +y, the subject's left towards +x.
    pub face_from_scan: DMat3,
    /// The generic face's nose tip after the fit, in the scan frame, mm (a prior for step 2).
    pub nose_tip_in_scan: DVec3,
    /// The face's size against the generic face's (the fit's isotropic scale, within
    /// 0.8–1.25).
    pub scale: f64,
    /// Fraction of the template within [`LocaliseParams::inlier_mm`] of the scan, 0–1.
    pub face_likeness: f64,
    /// RMS distance of the matched template points, mm.
    pub rms_mm: f64,
    /// The axis-aligned orientation the winning candidate started from
    /// (`face_from_scan` ≈ this, up to the head's own pose).
    pub start: AxisFrame,
    /// Nose candidates fitted.
    pub candidates_fitted: usize,
}

impl Localisation {
    /// How much the scan point `p` (scan frame, mm) belongs to the face found, 0–1, by its
    /// distance from the fitted nose tip: 1 within the generic face's radius about its nose tip
    /// (127 mm, scaled to this face) less [`COVER_TAPER_MM`], falling linearly to 0 at that
    /// radius. A torso, shoulders or a hair cap beyond it get 0. Only the nose tip of the fit
    /// counts, not its turn, and the fall is gradual, so that the weighted sums this feeds
    /// follow a rotation of the data (measured: weighting by the generic face's extent in its
    /// own plane, which turns with the fit, moved a rotated copy's points up to 7.6 mm).
    pub fn coverage(&self, p: DVec3) -> f64 {
        static RADIUS_MM: OnceLock<f64> = OnceLock::new();
        let radius = *RADIUS_MM.get_or_init(|| {
            template(1, false)
                .iter()
                .map(|(p, _)| p.length())
                .fold(0.0, f64::max)
        });
        let d = (p - self.nose_tip_in_scan).length() / self.scale;
        ((radius - d) / COVER_TAPER_MM).clamp(0.0, 1.0)
    }
}

/// The width of [`Localisation::coverage`]'s fall to the generic face's radius, mm.
pub const COVER_TAPER_MM: f64 = 20.0;

/// Template points with their unit normals (generic face frame: nose tip at the origin, looking
/// +z, y up), mm: every `step`-th generic vertex, above [`TEMPLATE_MIN_Y_MM`] only where `upper`.
fn template(step: usize, upper: bool) -> Vec<(DVec3, DVec3)> {
    static GENERIC: OnceLock<Vec<(DVec3, DVec3)>> = OnceLock::new();
    GENERIC
        .get_or_init(|| {
            let mesh = generic_face::build().mesh;
            mesh.positions_mm.into_iter().zip(mesh.normals).collect()
        })
        .iter()
        .copied()
        .filter(|(p, _)| !upper || p.y >= TEMPLATE_MIN_Y_MM)
        .step_by(step)
        .collect()
}

/// Every candidate is fitted with a sparse template (every 12th point); the finalists are
/// refitted and scored with a dense one (every 3rd).
const COARSE_STEP: usize = 12;
const FINE_STEP: usize = 3;
/// A scanner-frame fit at least this face-like ends the search (real frontal scans: 0.6–0.85
/// with the whole template).
const CONFIDENT_FACE_LIKENESS: f64 = 0.7;
/// Added to the face-likeness of a fit started in the scanner frame when candidates are
/// ranked: another must be this much more face-like to win.
const SCANNER_FRAME_PRIOR: f64 = 0.1;
/// Coarse fits refitted and scored on the surface: the best this many distinct ones.
const FINALISTS: usize = 3;
/// Two fits are the same where their nose tips lie within this distance, mm, and their viewing
/// directions within ~18° (cosine).
pub const DISTINCT_FIT_MM: f64 = 10.0;
const DISTINCT_FIT_COS: f64 = 0.95;
/// ICP schedules of the candidates' fits and of the finalists' refits.
const COARSE_SCHEDULE: [IcpStage; 3] = [
    IcpStage::points(6, 15.0),
    IcpStage::points(6, 9.0),
    IcpStage::plane(6, 6.0),
];
const FINE_SCHEDULE: [IcpStage; 2] = [IcpStage::points(6, 10.0), IcpStage::plane(8, 6.0)];

/// A candidate's fit.
#[derive(Debug, Clone, Copy)]
struct Fit {
    /// Face-likeness (coarse: on the vertices, sparse template; refit: on the surface, dense).
    likeness: f64,
    pose: Pose,
    start: AxisFrame,
    /// Started from the scanner frame itself (not tilted, not another axis frame).
    scanner_frame: bool,
}

/// The start frames, in stages: the scanner frame (or the given axes); it with the head
/// pitched ±30° or turned ±35° (the fit's reach from a start is about that); the 23 other axis
/// frames (not with given axes).
fn stages(params: &LocaliseParams) -> Vec<Vec<(DMat3, AxisFrame)>> {
    let base = params.axes.unwrap_or(AxisFrame::SCANNER);
    let mut out = vec![vec![(base.face_from_scan(), base)]];
    if params.search_orientations || params.axes.is_some() {
        let tilted = [
            DMat3::from_rotation_x(30f64.to_radians()),
            DMat3::from_rotation_x(-30f64.to_radians()),
            DMat3::from_rotation_y(35f64.to_radians()),
            DMat3::from_rotation_y(-35f64.to_radians()),
        ];
        out.push(
            tilted
                .iter()
                .map(|&r| (r * base.face_from_scan(), base))
                .collect(),
        );
    }
    if params.search_orientations && params.axes.is_none() {
        out.push(
            AxisFrame::all()
                .into_iter()
                .skip(1)
                .map(|f| (f.face_from_scan(), f))
                .collect(),
        );
    }
    out
}

/// The finalists of the search, refitted on the surface, best first, each with its rank
/// (face-likeness plus [`SCANNER_FRAME_PRIOR`] for a fit started in the scanner frame). Fails
/// only when nothing in any orientation protrudes like a nose; a scan whose best candidate is
/// not face-like gets that candidate with its low face-likeness (the caller flags it).
pub fn localise_finalists(
    mesh: &Mesh,
    params: &LocaliseParams,
) -> Result<Vec<(Localisation, f64)>> {
    let index = SurfaceIndex::new(mesh, 2.0);
    let vertices = VertexGrid::new(&mesh.positions_mm, VERTEX_GRID_CELL_MM);
    let coarse = template(COARSE_STEP, true);
    let coarse_all = template(COARSE_STEP, false);
    let mut fits: Vec<Fit> = Vec::new();
    let best_coarse = |fits: &[Fit]| {
        fits.iter()
            .map(|f| f.likeness)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    for (k, stage) in stages(params).into_iter().enumerate() {
        // The scanner frame is trusted outright only with a clearly face-like fit; the tilted
        // starts are tried otherwise (a strongly pitched head needs them); the other axis
        // frames only where still nothing is face-like.
        let enough = if k == 1 {
            CONFIDENT_FACE_LIKENESS
        } else {
            params.face_likeness_min
        };
        if k > 0 && best_coarse(&fits) >= enough {
            break;
        }
        for (face_from_scan, start) in stage {
            for tip in nose_candidates(mesh, face_from_scan, params) {
                let scan_from_face = face_from_scan.transpose();
                let from = Pose {
                    rot: scan_from_face,
                    scale: 1.0,
                    shift: tip,
                };
                let Some(pose) = icp(&vertices, &coarse, from, &COARSE_SCHEDULE) else {
                    continue;
                };
                let (likeness, _) = score(&vertices, &coarse_all, pose, params.inlier_mm);
                fits.push(Fit {
                    likeness,
                    pose,
                    start,
                    scanner_frame: k == 0,
                });
            }
        }
    }
    let fitted = fits.len();
    // A face found in the scanner frame is preferred unless another is clearly more face-like:
    // most scans are frontal, and an average face fitted to a face far from average (or with
    // an expression) scores ~0.5, as a fit slid onto a cheek or turned onto the forehead can.
    let ranked = |f: &Fit| {
        f.likeness
            + if f.scanner_frame {
                SCANNER_FRAME_PRIOR
            } else {
                0.0
            }
    };
    // The coarse fits rank the candidates; the best few distinct ones are refitted on the
    // surface with the dense template, and the refit decides.
    fits.sort_by(|a, b| ranked(b).total_cmp(&ranked(a)));
    let mut finalists: Vec<Fit> = Vec::new();
    for f in fits {
        let same = |g: &Fit| {
            g.pose.shift.distance(f.pose.shift) < DISTINCT_FIT_MM
                && (g.pose.rot.transpose() * f.pose.rot).z_axis.z > DISTINCT_FIT_COS
        };
        if finalists.len() < FINALISTS && !finalists.iter().any(same) {
            finalists.push(f);
        }
    }
    let fine = template(FINE_STEP, true);
    let fine_all = template(FINE_STEP, false);
    let mut refits: Vec<(Localisation, f64)> = finalists
        .into_iter()
        .map(|f| {
            let pose = icp(&index, &fine, f.pose, &FINE_SCHEDULE).unwrap_or(f.pose);
            let (likeness, rms_mm) = score(&index, &fine_all, pose, params.inlier_mm);
            let refit = Fit {
                likeness,
                pose,
                ..f
            };
            let found = Localisation {
                face_from_scan: pose.rot.transpose(),
                nose_tip_in_scan: pose.shift,
                scale: pose.scale,
                face_likeness: likeness,
                rms_mm,
                start: f.start,
                candidates_fitted: fitted,
            };
            (found, ranked(&refit))
        })
        .collect();
    if refits.is_empty() {
        return Err(Error::algorithm(
            "landmarks: face localisation",
            "nothing protrudes like a nose in any orientation of the scan",
        ));
    }
    refits.sort_by(|a, b| b.1.total_cmp(&a.1));
    Ok(refits)
}

/// Protrusion peaks of the mesh seen through `face_from_scan`, in the scan frame.
fn nose_candidates(mesh: &Mesh, face_from_scan: DMat3, params: &LocaliseParams) -> Vec<DVec3> {
    const CELL: f64 = 3.0;
    const DIRS: usize = 16;
    const SEPARATION_MM: f64 = 30.0;
    let pts: Vec<DVec3> = mesh
        .positions_mm
        .iter()
        .map(|&p| face_from_scan * p)
        .collect();
    let Some((lo, hi)) = bounds(&pts) else {
        return Vec::new();
    };
    let nx = ((hi.x - lo.x) / CELL) as usize + 1;
    let ny = ((hi.y - lo.y) / CELL) as usize + 1;
    if nx.saturating_mul(ny) > 4_000_000 {
        return Vec::new();
    }
    // Front-most depth per cell: what a scanner looking along −z would see.
    let mut top = vec![f64::NEG_INFINITY; nx * ny];
    let mut top_vertex = vec![usize::MAX; nx * ny];
    let cell_of = |q: DVec2| -> usize {
        let i = (((q.x - lo.x) / CELL) as usize).min(nx - 1);
        let j = (((q.y - lo.y) / CELL) as usize).min(ny - 1);
        j * nx + i
    };
    for (v, p) in pts.iter().enumerate() {
        let k = cell_of(p.truncate());
        if p.z > top[k] {
            top[k] = p.z;
            top_vertex[k] = v;
        }
    }
    let at = |q: DVec2| -> Option<f64> {
        if q.x < lo.x || q.y < lo.y || q.x > hi.x || q.y > hi.y {
            return None;
        }
        let z = top[cell_of(q)];
        (z > f64::NEG_INFINITY).then_some(z)
    };
    let r = params.probe_radius_mm;
    let circle: Vec<DVec2> = (0..DIRS)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / DIRS as f64;
            DVec2::new(a.cos(), a.sin()) * r
        })
        .collect();
    // (protrusion, cell, cell centre)
    let mut peaks: Vec<(f64, usize, DVec2)> = Vec::new();
    for (k, &z) in top.iter().enumerate() {
        if z == f64::NEG_INFINITY {
            continue;
        }
        let c = lo.truncate() + DVec2::new((k % nx) as f64 + 0.5, (k / nx) as f64 + 0.5) * CELL;
        let ring: Vec<f64> = circle.iter().filter_map(|d| at(c + *d)).collect();
        // Most of the circle must lie on the surface, and none of it in front of the peak.
        if ring.len() * 8 < DIRS * 5 || ring.iter().any(|&h| h > z) {
            continue;
        }
        let protrusion = z - ring.iter().sum::<f64>() / ring.len() as f64;
        if protrusion >= params.min_protrusion_mm {
            peaks.push((protrusion, k, c));
        }
    }
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept: Vec<(usize, DVec2)> = Vec::new();
    for (_, k, c) in peaks {
        if kept.iter().all(|(_, d)| (*d - c).length() >= SEPARATION_MM) {
            kept.push((k, c));
            if kept.len() == params.candidates {
                break;
            }
        }
    }
    // Each kept cell climbs to the front-most of its eight neighbours until none is further in
    // front, and the candidate is that cell's front-most vertex: the local maximum of depth,
    // which lies where it lies however the cells fall. A cell centre is up to 2 mm off it and
    // moves with the scan's bounds (a torso or a hair cap far from the face), and fits started
    // 3 mm apart can settle on different parts of a face (docs/measurements.md, "Nose
    // candidates at local maxima of depth").
    let climb = |mut k: usize| loop {
        let (i, j) = (k % nx, k / nx);
        let mut best = k;
        for b in j.saturating_sub(1)..(j + 2).min(ny) {
            for a in i.saturating_sub(1)..(i + 2).min(nx) {
                if top[b * nx + a] > top[best] {
                    best = b * nx + a;
                }
            }
        }
        if best == k {
            return k;
        }
        k = best;
    };
    let mut tips: Vec<usize> = Vec::new();
    for (k, _) in kept {
        let v = top_vertex[climb(k)];
        if !tips.contains(&v) {
            tips.push(v);
        }
    }
    tips.into_iter().map(|v| mesh.positions_mm[v]).collect()
}

fn bounds(pts: &[DVec3]) -> Option<(DVec3, DVec3)> {
    let first = *pts.first()?;
    Some(
        pts.iter()
            .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_24_axis_frames_are_distinct_rotations() {
        let frames = AxisFrame::all();
        assert_eq!(frames.len(), 24);
        for (i, a) in frames.iter().enumerate() {
            let r = a.face_from_scan();
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            assert_eq!(nearest_axis_frame(r), *a);
            for b in &frames[i + 1..] {
                assert_ne!(r, b.face_from_scan());
            }
        }
        assert_eq!(AxisFrame::SCANNER.face_from_scan(), DMat3::IDENTITY);
    }

    #[test]
    fn a_surface_far_from_the_face_does_not_move_the_nose_candidates() {
        let mut mesh = generic_face::build().mesh;
        for p in &mut mesh.positions_mm {
            *p += DVec3::new(0.7, 1.1, 0.0);
        }
        let params = LocaliseParams::default();
        let alone = nose_candidates(&mesh, DMat3::IDENTITY, &params);
        assert!(!alone.is_empty());
        // One vertex 200 mm below and beside the face: it widens the bounds by a distance that
        // is not a whole number of cells, and cannot be a peak itself (no surface around it).
        let (lo, _) = mesh.bbox_mm().unwrap();
        mesh.positions_mm.push(lo - DVec3::new(200.5, 150.8, 0.0));
        mesh.normals.push(DVec3::Z);
        assert_eq!(nose_candidates(&mesh, DMat3::IDENTITY, &params), alone);
    }

    #[test]
    fn the_nose_candidate_is_the_front_most_vertex_wherever_the_cells_fall() {
        let generic = generic_face::build().mesh;
        let params = LocaliseParams::default();
        for shift_mm in [0.0, 0.7, 1.4, 2.1] {
            let offset = DVec3::new(shift_mm, -shift_mm, 0.0);
            let mut mesh = generic.clone();
            for p in &mut mesh.positions_mm {
                *p += offset;
            }
            let front = mesh
                .positions_mm
                .iter()
                .copied()
                .max_by(|a, b| a.z.total_cmp(&b.z))
                .unwrap();
            let tips = nose_candidates(&mesh, DMat3::IDENTITY, &params);
            assert!(
                tips.contains(&front),
                "shift {shift_mm}: {tips:?}, front {front}"
            );
        }
    }

    #[test]
    fn the_generic_face_is_found_in_any_axis_frame_and_pose() {
        let generic = generic_face::build().mesh;
        let extra = DMat3::from_euler(glam::EulerRot::YXZ, 0.3, -0.2, 0.25);
        for frame in [
            AxisFrame::SCANNER,
            AxisFrame { facing: 5, up: 2 },
            AxisFrame { facing: 4, up: 0 },
        ] {
            let scan_from_face = (extra * frame.face_from_scan()).transpose();
            let mut mesh = generic.clone();
            let offset = DVec3::new(40.0, -300.0, 1000.0);
            for p in &mut mesh.positions_mm {
                *p = scan_from_face * *p + offset;
            }
            let found = localise_finalists(&mesh, &LocaliseParams::default()).unwrap()[0].0;
            assert!(found.face_likeness > 0.95, "{found:?}");
            // The template's own surface: the fit must land on the exact pose.
            assert!(
                (found.nose_tip_in_scan - offset).length() < 0.5,
                "{found:?}"
            );
            let err = (found.face_from_scan * scan_from_face - DMat3::IDENTITY).abs();
            assert!(err.to_cols_array().iter().all(|&e| e < 0.01), "{found:?}");
        }
    }
}
