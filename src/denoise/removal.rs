//! The default filter's last step: vertices it could not repair are removed instead of left
//! in place ([`super::DenoiseParams::remove_unrepairable`]).
//!
//! A spike whose support is itself spiked cannot be moved back: a rim vertex has only a
//! one-sided ring, and a cluster of 2–6 spiked neighbours on the rim or on a steep side is
//! its own support. Moving such vertices towards a fit guesses (and on the clean synthetic
//! twins the rim phase moved real lip and silhouette vertices by 8–12 mm), so here they are
//! taken out of the mesh, as scan clean-up tools do with spikes, and downstream steps treat
//! the gap as a hole (registration and range images fill holes). Four tests, in order:
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
//! 3. **Cluster members** ([`complete_clusters`]). Peeling can take the wrong vertices of a
//!    cluster on a rim or a steep side: the members drag their neighbours' fits, so a real
//!    neighbour looks worst and goes while 2–3 members ~6 mm off stay, each within 3 mm of a
//!    fit its fellow members support. Around every vertex peeled more than
//!    [`CLUSTER_SEED_MIN_RESIDUAL_MM`] off, each 2-ring vertex is fitted from its
//!    surroundings without that 2-ring; one missing by more than [`CLUSTER_MAX_MISS_MM`] goes.
//! 4. **Repairs that guessed** ([`check_repairs`]). A vertex the filter moved was put on the
//!    fit of its ring; where that ring does not predict itself (a lip fissure's end, a pit
//!    among spiked neighbours), the new position is a guess: the lip pits the filter
//!    "repaired" by 5.8 mm and cluster members left 2.0–3.5 mm off were such. Each kept,
//!    unmoved 1-ring neighbour is predicted from the vertex's 3-ring; under
//!    [`REPAIR_CHECK_MIN_NEIGHBOURS`] predictions or a miss over
//!    [`REPAIR_CHECK_MAX_MISS_MM`] and the vertex is removed. Over the benchmark's 4,582
//!    moved vertices the largest miss has median 0.23 mm and 95th percentile 0.56 mm; the
//!    bad repairs missed by 1.5–2.8 mm or had at most one prediction.
//!
//! Interior spikes the filter did repair have small residuals and stay. Measured on 100
//! synthetic scans (`facesynth eval-denoise`, seed 2024, 1.58 M vertices), tests 1–2 alone
//! → all four: vertices > 2 mm off 11 → 2 (max 5.86 → 4.98 mm), spike vertices removed
//! 404 → 819 (more of the repaired ones now go; ~4,900 were injected), other vertices
//! 679 → 716 (0.05 %), vertices of the clean twins 602 → 630 (0.04 %), most on the rims of
//! the eye, nostril and lip gaps. On `--subjects 10 --seed 1` (50 scans; looked at while
//! choosing the thresholds, so not a clean hold-out): > 2 mm 7 → 0 (max 6.74 → 1.03 mm),
//! clean twins 332 → 348. The two left: a rim spike (4.98 mm)
//! whose fit follows it within 2.1 mm once its real neighbours were peeled, and an interior
//! 4.9 mm pit the step-edge test keeps; letting residuals over 5 mm through that test
//! removes the pit but costs 148 more real-scan vertices and 21 of the clean twins, so it
//! is not done. The feature points do not suffer (`eval-landmarks`, seeds 31–33: every
//! neutral mean error within 0.035 mm of before, all 9 within 10 mm 178 → 178 neutral and
//! 238 → 239 expression scans; 37 of 450 scans change a point, as removing a vertex
//! changes the shape index around it). On the 29 real GavabDB scans in
//! `../shared/data/gavabdb`: 950 of 353,597 vertices (0.27 %; 1 to 188 a scan; 782 with
//! tests 1–2), most along steep silhouettes seen at a grazing angle (the chin's underside,
//! ears) and in hair; cara1_sonrisa loses the most (116 → 188), a line of rim vertices
//! under the chin. The filter moves few vertices on them (41 on cara1_sonrisa, a handful on
//! the others), mostly in rough neighbourhoods whose points miss each other's fits by
//! 1.6–6.7 mm (median a scan), so test 4 removes nearly all of those: 8 moved vertices are
//! left on the 29 scans, cara1_frontal1 has none (24 removed, 13 with tests 1–2). Of their
//! 377 feature points one moves: cara1_izquierda's cheek_right
//! (a profile the detector already fails on, with warnings). Measuring the residual along
//! the fitted surface's normal instead of z keeps those (50 instead of 116 on
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
/// A peeled vertex further off its fit than this (mm) is taken for a spike and its 2-ring
/// is searched for the rest of its cluster (test 3).
pub const CLUSTER_SEED_MIN_RESIDUAL_MM: f64 = 5.0;
/// A vertex beside such a spike that misses the fit of its surroundings without the spike's
/// block by more than this (mm) is a cluster member (test 3).
pub const CLUSTER_MAX_MISS_MM: f64 = 4.0;
/// Rings around a cluster candidate that its fit is taken from (the 2-ring block excluded).
const CLUSTER_FIT_RINGS: usize = 4;
/// A repaired vertex's neighbourhood must predict its unmoved 1-ring neighbours within this
/// (mm) (test 4; 98 % of the benchmark's moved vertices are within 1.03 mm).
pub const REPAIR_CHECK_MAX_MISS_MM: f64 = 1.0;
/// … and at least this many of them (a repair inside a cluster has fewer).
pub const REPAIR_CHECK_MIN_NEIGHBOURS: usize = 2;

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
    complete_clusters(positions, topology, &residual, &mut removed, &mut fit);
    check_repairs(positions, topology, rings3, moved, &mut removed, &mut fit);
    removed
}

/// Test 3 of the module docs: around each vertex peeled with a residual over
/// [`CLUSTER_SEED_MIN_RESIDUAL_MM`], every kept vertex of its 2-ring (a grid's 5 × 5 block)
/// whose height, fitted from its [`CLUSTER_FIT_RINGS`]-ring without that block, misses by more
/// than [`CLUSTER_MAX_MISS_MM`] is removed too. One pass: a second found nothing more on the
/// benchmark and cost more real vertices.
fn complete_clusters(
    positions: &[DVec3],
    topology: &Topology,
    residual: &[f64],
    removed: &mut [bool],
    fit: &mut QuadricFit,
) {
    let n = positions.len();
    let (mut scratch, mut block, mut ring) = (vec![false; n], Vec::new(), Vec::new());
    let mut in_block = vec![false; n];
    let mut extra = Vec::new();
    let seeds = (0..n).filter(|&v| removed[v] && residual[v].abs() > CLUSTER_SEED_MIN_RESIDUAL_MM);
    for seed in seeds {
        topology.k_ring(seed, 2, &mut scratch, &mut block);
        for &u in &block {
            in_block[u as usize] = true;
        }
        for &u in &block {
            let u = u as usize;
            if removed[u] {
                continue;
            }
            topology.k_ring(u, CLUSTER_FIT_RINGS, &mut scratch, &mut ring);
            let keep = |w: usize| !removed[w] && !in_block[w];
            if let Some((z, _, _)) = fit.predict(positions, positions[u], &ring, keep)
                && (positions[u].z - z).abs() > CLUSTER_MAX_MISS_MM
            {
                extra.push(u);
            }
        }
        for &u in &block {
            in_block[u as usize] = false;
        }
    }
    for u in extra {
        removed[u] = true;
    }
}

/// Test 4 of the module docs: a vertex the filter moved stays only where its neighbourhood
/// predicts itself: each kept, unmoved 1-ring neighbour is predicted from the vertex's
/// 3-ring (the vertex, the neighbour and moved vertices left out); fewer than
/// [`REPAIR_CHECK_MIN_NEIGHBOURS`] predictions, or one missing by more than
/// [`REPAIR_CHECK_MAX_MISS_MM`], and the repair was a guess, so the vertex is removed.
fn check_repairs(
    positions: &[DVec3],
    topology: &Topology,
    rings3: &Rings,
    moved: &[bool],
    removed: &mut [bool],
    fit: &mut QuadricFit,
) {
    for v in 0..positions.len() {
        if !moved[v] || removed[v] || topology.is_boundary[v] {
            continue;
        }
        let (mut worst_mm, mut count) = (0.0f64, 0);
        for &u in topology.neighbours(v) {
            let u = u as usize;
            if moved[u] || removed[u] {
                continue;
            }
            // `v` itself is moved, so it is left out with the other moved vertices.
            let keep = |w: usize| w != u && !moved[w] && !removed[w];
            if let Some((z, _, _)) = fit.predict(positions, positions[u], rings3.of(v), keep) {
                worst_mm = worst_mm.max((positions[u].z - z).abs());
                count += 1;
            }
        }
        if count < REPAIR_CHECK_MIN_NEIGHBOURS || worst_mm > REPAIR_CHECK_MAX_MISS_MM {
            removed[v] = true;
        }
    }
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

#[cfg(test)]
mod tests {
    use super::super::tests::grid;
    use super::*;

    /// A gently curved 21 × 21 patch (1 mm spacing), as a face's cheek.
    fn patch() -> (Vec<DVec3>, Topology) {
        let mesh = grid(21, 21, |x, y| {
            0.02 * (x - 10.0).powi(2) + 0.01 * (y - 10.0).powi(2)
        });
        let topology = Topology::new(&mesh);
        (mesh.positions_mm, topology)
    }

    fn at(i: usize, j: usize) -> usize {
        j * 21 + i
    }

    /// The members a peeled spike leaves behind go; a smooth surface around it, or a seed
    /// under the spike threshold, loses nothing.
    #[test]
    fn cluster_members_beside_a_peeled_spike_are_removed() {
        let (mut p, topology) = patch();
        let mut fit = QuadricFit::default();
        let seed = at(10, 10);
        let n = p.len();
        let mut residual = vec![0.0; n];
        residual[seed] = -8.0;
        let peeled = || {
            let mut r = vec![false; n];
            r[seed] = true;
            r
        };
        // No other member: nothing more is removed.
        let mut removed = peeled();
        complete_clusters(&p, &topology, &residual, &mut removed, &mut fit);
        assert_eq!(removed.iter().filter(|&&r| r).count(), 1);
        // Two members 6 and 5 mm down (one a diagonal neighbour): both go, nothing else.
        let members = [at(11, 10), at(11, 11)];
        p[members[0]].z -= 6.0;
        p[members[1]].z -= 5.0;
        let mut removed = peeled();
        complete_clusters(&p, &topology, &residual, &mut removed, &mut fit);
        let gone: Vec<usize> = (0..n).filter(|&v| removed[v] && v != seed).collect();
        assert_eq!(gone, members);
        // The same, seeded by a vertex peeled at 4 mm (not taken for a spike): no search.
        residual[seed] = -4.0;
        let mut removed = peeled();
        complete_clusters(&p, &topology, &residual, &mut removed, &mut fit);
        assert_eq!(removed.iter().filter(|&&r| r).count(), 1);
    }

    /// A repaired vertex on a smooth surface stays; one whose neighbourhood is rough (its
    /// ring does not predict itself) or made of other repairs goes.
    #[test]
    fn repairs_are_kept_only_where_the_neighbourhood_predicts_itself() {
        let (mut p, topology) = patch();
        let rings3 = Rings::new(&topology, 3);
        let mut fit = QuadricFit::default();
        let n = p.len();
        let v = at(10, 10);
        let mut moved = vec![false; n];
        moved[v] = true;
        let run = |p: &[DVec3], moved: &[bool], fit: &mut QuadricFit| {
            let mut removed = vec![false; n];
            check_repairs(p, &topology, &rings3, moved, &mut removed, fit);
            removed
        };
        assert!(
            !run(&p, &moved, &mut fit)[v],
            "a repair on a smooth patch is kept"
        );
        // Every 1-ring neighbour moved too (a cluster repaired from itself): removed.
        let mut cluster = moved.clone();
        for &u in topology.neighbours(v) {
            cluster[u as usize] = true;
        }
        assert!(run(&p, &cluster, &mut fit)[v]);
        // A 2 mm checkerboard over the 3-ring: no fit predicts a neighbour within 1 mm.
        for j in 7..=13 {
            for i in 7..=13 {
                p[at(i, j)].z += if (i + j) % 2 == 0 { 1.0 } else { -1.0 };
            }
        }
        assert!(run(&p, &moved, &mut fit)[v]);
    }
}
