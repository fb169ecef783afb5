//! The default filter's last step: vertices it could not repair are removed instead of left
//! in place ([`super::DenoiseParams::remove_unrepairable`]).
//!
//! A spike whose support is itself spiked cannot be moved back: a rim vertex has only a
//! one-sided ring, and a cluster of 2–6 spiked neighbours on the rim or on a steep side is
//! its own support. Moving such vertices towards a fit guesses (and on the clean synthetic
//! twins the rim phase moved real lip and silhouette vertices by 8–12 mm), so here they are
//! taken out of the mesh, as scan clean-up tools do with spikes, and downstream steps treat
//! the gap as a hole (registration and range images fill holes). Two tests, in order:
//!
//! 1. **Depth-jump pieces.** Edges whose depth jump exceeds [`JUMP_MM`] are cut (the scanner
//!    does not build faces that span more than ~8 mm of depth; such a face in a file was made
//!    by a spike). A piece of at most [`JUMP_PIECE_MAX_VERTICES`] vertices cut off from a
//!    piece at least three times its size is a spike cluster.
//! 2. **Peeling.** Every vertex's height is compared with a robust quadric fit of its 3-ring
//!    (the vertex and vertices already removed left out; the filter's consensus / L1 /
//!    trimmed fit, see `QuadricFit`). A vertex off by more than
//!    [`super::DenoiseParams::removal_residual_mm`] that is the worst of its 1-ring is
//!    removed; the rings around it are refitted and the test repeats, so a cluster is peeled
//!    from its worst member inwards while its neighbours' fits are not blamed for it. An
//!    interior vertex that shares a plane with a third of its ring (the step-edge test the
//!    filter uses, `on_real_surface`) is a crease or lid edge and stays: measured, that keeps
//!    a third of the real vertices this step would otherwise take (906 → 602 on the clean
//!    twins of 100 scans) for 2 more vertices left > 2 mm off (9 → 11).
//!
//! Interior spikes the filter did repair have small residuals and stay. Measured on 100
//! synthetic scans (`facesynth eval-denoise`, seed 2024, 1.58 M vertices): 404 spike and
//! 679 other vertices removed (0.07 %), and 602 vertices of the clean twins (0.04 %), most
//! on the rims of the eye, nostril and lip gaps; the feature points do not suffer
//! (`eval-landmarks`, 30 subjects: every mean error within 0.15 mm of before or better,
//! expression scans with all 9 points within 10 mm 77.8 → 84.4 %). On the 29 real GavabDB
//! scans in `../shared/data/gavabdb`: 782 of 353,597 vertices (0.22 %; 1 to 116 a scan),
//! most along steep silhouettes seen at a grazing angle (the chin's underside, ears) and in
//! hair; cara1_sonrisa loses the most, a line of rim vertices under the chin. Measuring the
//! residual along the fitted surface's normal instead of z keeps those (50 instead of 116 on
//! cara1_sonrisa) but leaves spikes on steep sides (98 vertices > 2 mm off on the benchmark
//! instead of 11), so it is not done.

use super::{DenoiseParams, QuadricFit, Rings, on_real_surface};
use crate::mesh::{Polygons, Topology};
use glam::DVec3;

/// An edge with a larger depth jump (mm) does not join two samples of one surface.
pub const JUMP_MM: f64 = 8.0;
/// Largest piece cut off by depth jumps that counts as a spike cluster (synth_gavab's
/// clusters have 2–6 vertices).
pub const JUMP_PIECE_MAX_VERTICES: usize = 6;
/// Rounds of peeling (a cluster of 6 needs at most 6).
const PEEL_ROUNDS: usize = 10;
/// A ring too thin for a fit (a rim tip) is widened to this many rings.
const FALLBACK_RINGS: usize = 5;
/// Interior vertices the filter's own last fit put closer than this (mm) are not refitted.
const SCREEN_MM: f64 = 1.0;

/// Which vertices of the filtered `positions` to remove (see the module docs).
/// `filter_change_mm` is the filter's last estimate of each vertex's change (current for
/// every interior vertex once the filter has stopped), `moved` what the filter moved.
pub(super) fn unrepairable(
    positions: &[DVec3],
    topology: &Topology,
    rings3: &Rings,
    params: &DenoiseParams,
    filter_change_mm: &[f64],
    moved: &[bool],
) -> Vec<bool> {
    let n = positions.len();
    let mut removed = jump_pieces(positions, topology);
    let mut fit = QuadricFit::default();
    // The filter has just fitted every interior vertex (from its 2-ring): those it found
    // within SCREEN_MM of their fit are not refitted here unless something near them moved,
    // and count with that change. Rims (never fitted by the filter) are all checked. On
    // cara1 this is 1,700 fits instead of 14,300 (peel 19 instead of 47 ms); the 100-scan
    // benchmark gives the same result either way.
    let mut residual = filter_change_mm.to_vec();
    let mut dirty: Vec<bool> = (0..n)
        .map(|v| topology.is_boundary[v] || filter_change_mm[v] >= SCREEN_MM)
        .collect();
    for v in (0..n).filter(|&v| moved[v]) {
        dirty[v] = true;
        for &u in rings3.of(v) {
            dirty[u as usize] = true;
        }
    }
    let (mut scratch, mut wide) = (vec![false; n], Vec::new());
    // The step-edge test, asked only of interior vertices that would otherwise go (it tries
    // 276 planes); positions do not change while peeling, so each answer is kept.
    let mut real_surface: Vec<Option<bool>> = vec![None; n];
    for _ in 0..PEEL_ROUNDS {
        for v in 0..n {
            if removed[v] || !dirty[v] {
                continue;
            }
            dirty[v] = false;
            let p = positions[v];
            let keep = |u: usize| !removed[u];
            if let Some(z) = fit.predict_smooth(positions, p, rings3.of(v), keep) {
                residual[v] = p.z - z;
                continue;
            }
            let estimate = fit.predict(positions, p, rings3.of(v), keep).or_else(|| {
                topology.k_ring(v, FALLBACK_RINGS, &mut scratch, &mut wide);
                fit.predict(positions, p, &wide, keep)
            });
            // No fit at all (a tiny island): nothing to judge it by, so it stays.
            residual[v] = estimate.map_or(0.0, |(z, _, _)| p.z - z);
        }
        let worst: Vec<usize> = (0..n)
            .filter(|&v| {
                !removed[v]
                    && residual[v].abs() > params.removal_residual_mm
                    && topology.neighbours(v).iter().all(|&u| {
                        removed[u as usize] || residual[u as usize].abs() <= residual[v].abs()
                    })
                    && (topology.is_boundary[v]
                        || !*real_surface[v]
                            .get_or_insert_with(|| on_real_surface(positions, v, rings3.of(v))))
            })
            .collect();
        if worst.is_empty() {
            break;
        }
        for v in worst {
            removed[v] = true;
            for &u in rings3.of(v) {
                dirty[u as usize] = true;
            }
        }
    }
    removed
}

/// Adds to `removed` every vertex that would be left without a face: a polygon keeps its
/// corners that are not removed and goes when fewer than 3 are left (as
/// [`crate::mesh::Mesh::retain_vertices`] does), so a rim tip whose only face lost a corner
/// goes too.
pub(super) fn add_orphans(faces: &Polygons, removed: &mut [bool]) {
    let mut used_before = vec![false; removed.len()];
    let mut used_after = vec![false; removed.len()];
    for f in faces.iter() {
        let survives = f.iter().filter(|&&v| !removed[v as usize]).count() >= 3;
        for &v in f {
            used_before[v as usize] = true;
            used_after[v as usize] |= survives;
        }
    }
    for (v, r) in removed.iter_mut().enumerate() {
        *r |= used_before[v] && !used_after[v];
    }
}

/// Test 1 of the module docs: the vertices of small pieces cut off by depth jumps.
pub fn jump_pieces(positions: &[DVec3], topology: &Topology) -> Vec<bool> {
    let whole = pieces(positions, topology, f64::INFINITY);
    let cut = pieces(positions, topology, JUMP_MM);
    (0..positions.len())
        .map(|v| {
            let small = cut.size[cut.label[v] as usize];
            small <= JUMP_PIECE_MAX_VERTICES && whole.size[whole.label[v] as usize] >= 3 * small
        })
        .collect()
}

/// Connected pieces of the mesh through edges whose depth jump is at most `max_jump_mm`.
struct Pieces {
    label: Vec<u32>,
    size: Vec<usize>,
}

fn pieces(positions: &[DVec3], topology: &Topology, max_jump_mm: f64) -> Pieces {
    let n = positions.len();
    let mut label = vec![u32::MAX; n];
    let mut size = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..n {
        if label[seed] != u32::MAX {
            continue;
        }
        let id = size.len() as u32;
        label[seed] = id;
        stack.push(seed);
        let mut count = 0;
        while let Some(v) = stack.pop() {
            count += 1;
            for &u in topology.neighbours(v) {
                let u = u as usize;
                if label[u] == u32::MAX && (positions[u].z - positions[v].z).abs() <= max_jump_mm {
                    label[u] = id;
                    stack.push(u);
                }
            }
        }
        size.push(count);
    }
    Pieces { label, size }
}
