//! The default filter's last step: vertices it could not repair are removed instead of left
//! in place ([`super::DenoiseParams::remove_unrepairable`]).
//!
//! A spike whose support is itself spiked cannot be moved back: a rim vertex has only a
//! one-sided ring, and a cluster of 2–6 spiked neighbours on the rim or on a steep side is
//! its own support. Moving such vertices towards a fit guesses (and on the clean synthetic
//! twins the rim phase moved real lip and silhouette vertices by 8–12 mm), so here they are
//! taken out of the mesh, as scan clean-up tools do with spikes, and downstream steps treat
//! the gap as a hole (registration and range images fill holes). Seven tests, in order:
//!
//! 1. **Depth-jump pieces.** Edges whose depth jump exceeds [`JUMP_MM`] are cut (the scanner
//!    does not build faces that span more than ~8 mm of depth; such a face in a file was made
//!    by a spike), and so are edges whose slope differs from the edges continuing them on
//!    both sides by more than [`BEND_MM`] of height over the edge ([`bend_mm`]): on a steep
//!    side a 5 mm spike jumps by less than 8 mm but bends against both continuations, a
//!    crease bends against one at most. A piece of at most [`JUMP_PIECE_MAX_VERTICES`]
//!    vertices cut off from a piece at least three times its size is a spike cluster. A
//!    fragment of at most [`ISLAND_MAX_VERTICES`] vertices joined to nothing else goes too,
//!    whatever its depth (as scan clean-up tools drop isolated pieces): it has no ring to
//!    judge it by, and a spike cluster that covers it whole is not found otherwise.
//! 2. **Peeling.** Every vertex's height is compared with a robust quadric fit of its 3-ring
//!    (the vertex and vertices already removed left out; the filter's consensus / L1 /
//!    trimmed fit, see `QuadricFit`). A vertex off by more than
//!    [`super::DenoiseParams::removal_residual_mm`] that is the worst of its 1-ring (not
//!    counting neighbours the step-edge test keeps, which are never peeled) is
//!    removed; the rings around it are refitted and the test repeats, so a cluster is peeled
//!    from its worst member inwards while its neighbours' fits are not blamed for it. An
//!    interior vertex that shares a plane with a third of its ring (the step-edge test the
//!    filter uses, `on_real_surface`, where the plane's support must reach round a
//!    vertex no neighbour is near, [`PEEL_SUPPORT_MIN_SPAN_DEG`]) is a crease or lid edge
//!    and stays: measured, that keeps
//!    a third of the real vertices this step would otherwise take (906 → 602 on the clean
//!    twins of 100 scans) for 2 more vertices left > 2 mm off (9 → 11). Peeling is greedy,
//!    so once it stops, every peeled vertex that the kept surface now fits within
//!    [`RESTORE_MAX_MM`] is put back ([`fitting_again`]; each at most once) and peeling
//!    resumes around it: a real rim vertex whose ring held a cluster looked worst and went
//!    first. A rim vertex less than a spike's height
//!    ([`CLUSTER_SEED_MIN_RESIDUAL_MM`]) off its 3-ring fit is judged by the fit of its
//!    [`RIM_FIT_RINGS`]-ring instead, against [`RIM_FIT_MARGIN_MM`] more: on a rim the 3-ring
//!    is one-sided and small, so a spike cluster there is much of its own members' support.
//! 3. **Cluster members** ([`complete_clusters`]). Peeling can take the wrong vertices of a
//!    cluster on a rim or a steep side: the members drag their neighbours' fits, so a real
//!    neighbour looks worst and goes while 2–3 members ~6 mm off stay, each within 3 mm of a
//!    fit its fellow members support. Around every vertex peeled, or moved back by the
//!    filter, more than [`CLUSTER_SEED_MIN_RESIDUAL_MM`] (on or beside a rim
//!    [`CLUSTER_SEED_MIN_OFF_MM`]; [`cluster_seeds`]), each 2-ring vertex is fitted from its
//!    surroundings without that 2-ring; one missing by more than [`CLUSTER_MAX_MISS_MM`]
//!    goes.
//! 4. **Repairs that guessed** ([`check_repairs`]). A vertex the filter moved was put on the
//!    fit of its ring; where that ring does not predict itself (a lip fissure's end, a pit
//!    among spiked neighbours), the new position is a guess: the lip pits the filter
//!    "repaired" by 5.8 mm and cluster members left 2.0–3.5 mm off were such. Each kept,
//!    unmoved 1-ring neighbour is predicted from the vertex's 3-ring; under
//!    [`REPAIR_CHECK_MIN_NEIGHBOURS`] predictions or a miss over
//!    [`REPAIR_CHECK_MAX_MISS_MM`] and the vertex is removed. Over the benchmark's 4,582
//!    moved vertices the largest miss has median 0.23 mm and 95th percentile 0.56 mm; the
//!    bad repairs missed by 1.5–2.8 mm or had at most one prediction.
//! 5. **Large repairs** ([`large_repairs`]). A vertex the filter moved further than
//!    [`super::DenoiseParams::repair_max_mm`] (3 mm) goes too. A spike's sample holds no
//!    information, so removing a repaired one loses nothing measured (the hole is filled
//!    downstream as the repair was); a real one-vertex pit (a lid or lip line, where the
//!    scanner sees pits 4–6 mm deep) that the filter lifted is a guess of that size. Taking
//!    only the repairs with a removed vertex in their 2-ring left real pits lifted by up to
//!    4 mm.
//! 6. **Dangling corners** ([`dangling_corners`]). A kept vertex left with at most
//!    [`DANGLING_MAX_NEIGHBOURS`] kept neighbours (a corner of the rim, often one the
//!    removals made) that misses the straight continuation of every one of its edges by more
//!    than [`super::DenoiseParams::removal_residual_mm`], all on the same side, goes. Such a
//!    corner has too small a ring for the fits of test 2 to tell a spike from
//!    the surface; a line through the neighbour and the next vertex in line beyond it does.
//! 7. **Leftover fragments** ([`leftover_fragments`]). Where the removals cut a piece of at
//!    most [`ISLAND_MAX_VERTICES`] kept vertices off from everything else (a hair island
//!    whose real vertices were peeled around its spike cluster), it goes as test 1's
//!    fragments do.
//!
//! Measured figures (vertices left more than 2 mm off per seed, removed counts, real scans,
//! the rules tried and not kept): `docs/measurements.md`, "Denoising: removal".

use super::{DenoiseParams, QuadricFit, Rings, on_real_surface};
use crate::mesh::{Polygons, Topology};
use glam::{DVec2, DVec3};

mod pieces;
#[cfg(test)]
mod tests;

use pieces::*;
pub use pieces::{BEND_MM, jump_pieces};

/// An edge with a larger depth jump (mm) does not join two samples of one surface.
pub const JUMP_MM: f64 = 8.0;
/// Largest piece cut off by depth jumps that counts as a spike cluster (synth_gavab's
/// clusters have 2–6 vertices).
pub const JUMP_PIECE_MAX_VERTICES: usize = 6;
/// Largest isolated fragment (a piece of the mesh joined to nothing else) that is removed
/// whatever its depth (tests 1 and 7): smaller than a 3 × 3 block of samples, so no vertex of
/// it has a full ring to be judged by.
pub const ISLAND_MAX_VERTICES: usize = 8;
/// A peeled vertex whose kept 3-ring fits it within this (mm) is put back: 10 σ of the
/// scanner noise, half the peeling threshold.
const RESTORE_MAX_MM: f64 = 1.5;
/// A rim vertex is judged by the fit of this many rings around it (test 2): its 3-ring is
/// one-sided and small, so members of a spike cluster on the rim are much of each other's
/// support, and the wider fit is the interior's opinion.
const RIM_FIT_RINGS: usize = 4;
/// … against the peeling threshold plus this (mm): a wider quadric follows a rim's turn
/// less closely (3.0 mm instead of 3.5 cost twice the real vertices for one more found).
const RIM_FIT_MARGIN_MM: f64 = 0.5;
/// Rounds of peeling (a cluster of 6 needs at most 6).
const PEEL_ROUNDS: usize = 10;
/// A ring too thin for a fit (a rim tip) is widened to this many rings.
const FALLBACK_RINGS: usize = 5;
/// Interior vertices the filter's own last fit put closer than this (mm) are not refitted.
const SCREEN_MM: f64 = 1.0;
/// A peeled vertex further off its fit than this (mm) is taken for a spike and its 2-ring
/// is searched for the rest of its cluster (test 3).
pub const CLUSTER_SEED_MIN_RESIDUAL_MM: f64 = 5.0;
/// A vertex on the rim or beside it that was peeled further off its fit than this (mm), or
/// moved back further by the filter, seeds test 3's search too (elsewhere
/// [`CLUSTER_SEED_MIN_RESIDUAL_MM`]). On a rim a member's
/// one-sided fit holds the rest of its cluster, so a 5 mm spike can be peeled at 4–5 mm;
/// inside, 4 mm would take the floor of a slot beside a spike in it.
pub const CLUSTER_SEED_MIN_OFF_MM: f64 = 4.0;
/// A vertex beside such a spike that misses the fit of its surroundings without the spike's
/// block by more than this (mm) is a cluster member (test 3): low enough to take spiked
/// step-side vertices 3.4–3.9 mm off.
pub const CLUSTER_MAX_MISS_MM: f64 = 3.3;
/// Rings around a cluster candidate that its fit is taken from (the 2-ring block excluded).
const CLUSTER_FIT_RINGS: usize = 4;
/// A repaired vertex's neighbourhood must predict its unmoved 1-ring neighbours within this
/// (mm) (test 4; 98 % of the benchmark's moved vertices are within 1.03 mm).
pub const REPAIR_CHECK_MAX_MISS_MM: f64 = 1.0;
/// Test 2's step-edge test asks the plane's supporting ring points to span at least this
/// angle around a vertex that no 1-ring neighbour comes within the peeling threshold of
/// (all above it, or all below: [`support_span_asked`]), degrees. A vertex on one side of a
/// real crease or lid edge has support along the edge both ways (180° or more); a spike
/// pushed into a slot (a closed lid's fissure) can share a plane with the slot's wall on one
/// side only (seen: 8 of 24 points over 126°, 5.1 mm below the fissure). Asked of every
/// vertex it took a notch in a step edge (test
/// `a_step_edge_is_not_taken_for_a_spike`) and 44 real-scan vertices (nostril and canthus
/// pits, one feature point moved 2 mm); asked by the filter too, it let the filter move real
/// canthus pits (cara1_gesto: two feature points moved 1.4–1.6 mm).
pub const PEEL_SUPPORT_MIN_SPAN_DEG: f64 = 150.0;
/// … and at least this many of them (a repair inside a cluster has fewer).
pub const REPAIR_CHECK_MIN_NEIGHBOURS: usize = 2;
/// Test 6: a kept vertex with at most this many kept neighbours is a corner judged by the
/// continuations of its edges.
pub const DANGLING_MAX_NEIGHBOURS: usize = 2;

/// Which vertices of the filtered `positions` to remove (see the module docs).
/// `filter_change_mm` is the filter's last estimate of each vertex's change (current for
/// every interior vertex once the filter has stopped), `moved` what the filter moved.
pub(super) fn unrepairable(
    positions: &[DVec3],
    input: &[DVec3],
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
    let mut scratch = Scratch::new(n, params.removal_residual_mm);
    // The step-edge test, asked only of interior vertices that would otherwise go (it tries
    // 276 planes); positions do not change while peeling, so each answer is kept.
    let mut real_surface: Vec<Option<bool>> = vec![None; n];
    let jumped = removed.clone();
    let mut restored = vec![false; n];
    loop {
        for _ in 0..PEEL_ROUNDS {
            for v in 0..n {
                if removed[v] || !dirty[v] {
                    continue;
                }
                dirty[v] = false;
                residual[v] = fit_residual(
                    positions,
                    topology,
                    rings3,
                    v,
                    &removed,
                    &mut fit,
                    &mut scratch,
                );
            }
            // A vertex the step-edge test keeps stays whatever its residual.
            let mut stays = |v: usize| {
                !topology.is_boundary[v]
                    && *real_surface[v].get_or_insert_with(|| {
                        on_real_surface(
                            positions,
                            v,
                            rings3.of(v),
                            support_span_asked(positions, topology, v, params),
                        )
                    })
            };
            let worst = peel_candidates(
                topology,
                &residual,
                &removed,
                params.removal_residual_mm,
                &mut stays,
            );
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
        let candidates: Vec<usize> = (0..n)
            .filter(|&v| removed[v] && !jumped[v] && !restored[v])
            .collect();
        let back = fitting_again(
            positions,
            topology,
            rings3,
            &candidates,
            &removed,
            &mut fit,
            &mut scratch,
        );
        if back.is_empty() {
            break;
        }
        for v in back {
            removed[v] = false;
            restored[v] = true;
            dirty[v] = true;
            for &u in rings3.of(v) {
                dirty[u as usize] = true;
            }
        }
    }
    let seed = cluster_seeds(positions, input, topology, &residual, &removed, moved);
    complete_clusters(positions, topology, &seed, &mut removed, &mut fit);
    check_repairs(positions, topology, rings3, moved, &mut removed, &mut fit);
    large_repairs(positions, input, moved, params.repair_max_mm, &mut removed);
    dangling_corners(
        positions,
        topology,
        params.removal_residual_mm,
        &mut removed,
    );
    leftover_fragments(topology, &mut removed);
    removed
}

/// Test 6 of the module docs: kept vertices with at most [`DANGLING_MAX_NEIGHBOURS`] kept
/// neighbours that miss, by more than `threshold_mm` and on the same side, the line through
/// each kept neighbour and that neighbour's kept neighbour in line beyond it
/// ([`CONTINUATION_MIN_COS`]). A neighbour without such a continuation says nothing, and
/// the vertex stays.
fn dangling_corners(
    positions: &[DVec3],
    topology: &Topology,
    threshold_mm: f64,
    removed: &mut [bool],
) {
    let before: &[bool] = removed;
    // How far `v` is above the line through its neighbour `u` and the kept vertex in line
    // beyond it (the one most nearly in line); `None` where there is none.
    let miss = |v: usize, u: usize| -> Option<f64> {
        let (pv, pu) = (positions[v], positions[u]);
        let len = (pu - pv).truncate().length();
        if len <= 0.0 {
            return None;
        }
        in_line(positions, topology, u, (pu - pv).truncate() / len)
            .filter(|&(w, _, _)| !before[w])
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(w, run, _)| pv.z - (pu.z + (pu.z - positions[w].z) / run * len))
    };
    let dangling: Vec<usize> = (0..positions.len())
        .filter(|&v| {
            let kept = || {
                topology
                    .neighbours(v)
                    .iter()
                    .map(|&u| u as usize)
                    .filter(|&u| !before[u])
            };
            let count = kept().count();
            if before[v] || count == 0 || count > DANGLING_MAX_NEIGHBOURS {
                return false;
            }
            let (mut above, mut below) = (true, true);
            for u in kept() {
                let Some(d) = miss(v, u) else {
                    return false;
                };
                above &= d > threshold_mm;
                below &= d < -threshold_mm;
            }
            above || below
        })
        .collect();
    for v in dangling {
        removed[v] = true;
    }
}

/// Test 2's vertices to peel this round: kept vertices more than `threshold_mm` off their fit
/// that are the worst of their 1-ring and that `stays` does not keep. A neighbour that
/// stays does not count in "worst": it is never peeled, so it would block the vertex for
/// good.
fn peel_candidates(
    topology: &Topology,
    residual: &[f64],
    removed: &[bool],
    threshold_mm: f64,
    stays: &mut impl FnMut(usize) -> bool,
) -> Vec<usize> {
    let mut worst = Vec::new();
    for v in 0..residual.len() {
        let r = residual[v].abs();
        if removed[v] || r <= threshold_mm {
            continue;
        }
        let blocked = topology.neighbours(v).iter().any(|&u| {
            let u = u as usize;
            !removed[u] && residual[u].abs() > r && !stays(u)
        });
        if !blocked && !stays(v) {
            worst.push(v);
        }
    }
    worst
}

/// The span test 2 asks of a vertex's step-edge plane: [`PEEL_SUPPORT_MIN_SPAN_DEG`] for a
/// vertex more than the peeling threshold above, or below, every 1-ring neighbour (a pit
/// or peak no neighbour shares), else none (a notch in a step edge has a neighbour at its
/// own level on the low side).
fn support_span_asked(
    positions: &[DVec3],
    topology: &Topology,
    v: usize,
    params: &DenoiseParams,
) -> Option<f64> {
    let z = positions[v].z;
    let t = params.removal_residual_mm;
    let nb = topology.neighbours(v);
    let rise = |u: &u32| positions[*u as usize].z - z;
    let above = nb.iter().all(|u| rise(u) > t);
    let below = nb.iter().all(|u| rise(u) < -t);
    (!nb.is_empty() && (above || below)).then_some(PEEL_SUPPORT_MIN_SPAN_DEG)
}

/// Test 6 of the module docs: pieces of at most [`ISLAND_MAX_VERTICES`] kept vertices that
/// the removals left joined to nothing else go too (not when no larger piece is left).
fn leftover_fragments(topology: &Topology, removed: &mut [bool]) {
    // Removed vertices are pieces of one, which never decide the limit.
    let kept = pieces(topology, |v, u| !removed[v] && !removed[u]);
    let limit = island_limit(&kept);
    for (v, r) in removed.iter_mut().enumerate() {
        *r |= kept.size[kept.label[v] as usize] <= limit;
    }
}

/// The largest fragment removed whatever its depth: [`ISLAND_MAX_VERTICES`], or 0 where no
/// piece is larger (a mesh that is all fragments, such as a test triangle, is not emptied).
fn island_limit(p: &Pieces) -> usize {
    if p.size.iter().any(|&s| s > ISLAND_MAX_VERTICES) {
        ISLAND_MAX_VERTICES
    } else {
        0
    }
}

/// Buffers for widening a ring ([`FALLBACK_RINGS`], [`RIM_FIT_RINGS`]), and the peeling
/// threshold a rim vertex's wider fit is scaled for (mm).
struct Scratch {
    seen: Vec<bool>,
    wide: Vec<u32>,
    residual_mm: f64,
}

impl Scratch {
    fn new(n: usize, residual_mm: f64) -> Self {
        Self {
            seen: vec![false; n],
            wide: Vec::new(),
            residual_mm,
        }
    }
}

/// How far vertex `v` lies above (+) or below the robust quadric fit of its kept 3-ring
/// (rings never hold `v` itself), mm; a ring too thin for a fit is widened to [`FALLBACK_RINGS`] rings.
/// A rim vertex less than a spike ([`CLUSTER_SEED_MIN_RESIDUAL_MM`]) off that fit is measured
/// against its [`RIM_FIT_RINGS`]-ring instead, the result scaled so that the peeling
/// threshold (`scratch.residual_mm`) means [`RIM_FIT_MARGIN_MM`] more of it.
fn fit_residual(
    positions: &[DVec3],
    topology: &Topology,
    rings3: &Rings,
    v: usize,
    removed: &[bool],
    fit: &mut QuadricFit,
    scratch: &mut Scratch,
) -> f64 {
    let p = positions[v];
    let keep = |u: usize| !removed[u];
    let estimate = fit.height(positions, p, rings3.of(v), keep).or_else(|| {
        topology.k_ring(v, FALLBACK_RINGS, &mut scratch.seen, &mut scratch.wide);
        fit.predict(positions, p, &scratch.wide, keep)
            .map(|(z, _, _)| z)
    });
    // No fit at all (a tiny island): nothing to judge it by, so it stays.
    let near = estimate.map_or(0.0, |z| p.z - z);
    if !topology.is_boundary[v] || near.abs() > CLUSTER_SEED_MIN_RESIDUAL_MM {
        return near;
    }
    topology.k_ring(v, RIM_FIT_RINGS, &mut scratch.seen, &mut scratch.wide);
    let t = scratch.residual_mm;
    fit.height(positions, p, &scratch.wide, keep)
        .map_or(near, |z| (p.z - z) * t / (t + RIM_FIT_MARGIN_MM))
}

/// Test 2's second look: the `candidates` (peeled vertices) that the kept surface around
/// them now fits within [`RESTORE_MAX_MM`]. Peeling is greedy: where a cluster sat in a real
/// vertex's ring, that vertex could look worst and go first; once the cluster is gone its
/// ring is clean support again.
fn fitting_again(
    positions: &[DVec3],
    topology: &Topology,
    rings3: &Rings,
    candidates: &[usize],
    removed: &[bool],
    fit: &mut QuadricFit,
    scratch: &mut Scratch,
) -> Vec<usize> {
    candidates
        .iter()
        .copied()
        .filter(|&v| {
            fit_residual(positions, topology, rings3, v, removed, fit, scratch).abs()
                <= RESTORE_MAX_MM
        })
        .collect()
}

/// Test 3's seeds: vertices peeled more than [`CLUSTER_SEED_MIN_RESIDUAL_MM`] off their
/// fit ([`CLUSTER_SEED_MIN_OFF_MM`] on or beside the rim), and kept vertices the filter moved
/// back by more than that (a spike it repaired is as much a cluster's member as one peeled).
fn cluster_seeds(
    positions: &[DVec3],
    input: &[DVec3],
    topology: &Topology,
    residual: &[f64],
    removed: &[bool],
    moved: &[bool],
) -> Vec<bool> {
    (0..positions.len())
        .map(|v| {
            let off_mm = if removed[v] {
                residual[v]
            } else if moved[v] {
                input[v].z - positions[v].z
            } else {
                0.0
            };
            off_mm.abs() > CLUSTER_SEED_MIN_RESIDUAL_MM
                || (off_mm.abs() > CLUSTER_SEED_MIN_OFF_MM && topology.touches_boundary(v))
        })
        .collect()
}

/// Test 3 of the module docs: around each seed ([`cluster_seeds`]), every kept vertex of its
/// 2-ring (a grid's 5 × 5 block) whose height, fitted from its [`CLUSTER_FIT_RINGS`]-ring
/// without that block, misses by more than [`CLUSTER_MAX_MISS_MM`] is removed too. One pass:
/// a second found nothing more on the benchmark and cost more real vertices.
fn complete_clusters(
    positions: &[DVec3],
    topology: &Topology,
    seed: &[bool],
    removed: &mut [bool],
    fit: &mut QuadricFit,
) {
    let n = positions.len();
    let (mut scratch, mut block, mut ring) = (vec![false; n], Vec::new(), Vec::new());
    let mut in_block = vec![false; n];
    let mut extra = Vec::new();
    for s in (0..n).filter(|&v| seed[v]) {
        topology.k_ring(s, 2, &mut scratch, &mut block);
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

/// Test 5 of the module docs: a vertex the filter moved further than `repair_max_mm` is
/// removed.
fn large_repairs(
    positions: &[DVec3],
    input: &[DVec3],
    moved: &[bool],
    repair_max_mm: f64,
    removed: &mut [bool],
) {
    for (v, r) in removed.iter_mut().enumerate() {
        *r |= moved[v] && positions[v].distance(input[v]) > repair_max_mm;
    }
}

/// Adds to `removed` every vertex that would be left without a face: a polygon keeps its
/// corners that are not removed and goes when fewer than 3 are left (as
/// [`crate::mesh::Mesh::retain_vertices`] does), so a rim tip whose only face lost a corner
/// goes too.
pub(crate) fn add_orphans(faces: &Polygons, removed: &mut [bool]) {
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
