//! Tests of the removal: spike clusters, rims, step edges, repairs, fragments.

use super::*;
use crate::Mesh;
use crate::test_support::grid;

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
    let no_moves = vec![false; n];
    let seeds = |p: &[DVec3], input: &[DVec3], residual: &[f64], moved: &[bool]| {
        cluster_seeds(p, input, &topology, residual, &peeled(), moved)
    };
    // No other member: nothing more is removed.
    let mut removed = peeled();
    let s = seeds(&p, &p, &residual, &no_moves);
    complete_clusters(&p, &topology, &s, &mut removed, &mut fit);
    assert_eq!(removed.iter().filter(|&&r| r).count(), 1);
    // Two members 6 and 5 mm down (one a diagonal neighbour): both go, nothing else.
    let members = [at(11, 10), at(11, 11)];
    p[members[0]].z -= 6.0;
    p[members[1]].z -= 5.0;
    let mut removed = peeled();
    let s = seeds(&p, &p, &residual, &no_moves);
    complete_clusters(&p, &topology, &s, &mut removed, &mut fit);
    let gone: Vec<usize> = (0..n).filter(|&v| removed[v] && v != seed).collect();
    assert_eq!(gone, members);
    // The same, seeded by an interior vertex peeled at 4.5 mm (not taken for a spike: a
    // slot's floor can be that far off its walls' fit): no search.
    residual[seed] = -4.5;
    let s = seeds(&p, &p, &residual, &no_moves);
    assert!(!s.iter().any(|&x| x));
    // A kept vertex the filter moved back 8 mm (a repaired spike) seeds the search too;
    // one moved back 1 mm does not.
    let repaired = at(10, 11);
    let mut input = p.clone();
    input[repaired].z += 8.0;
    let mut moved = no_moves.clone();
    moved[repaired] = true;
    let s = seeds(&p, &input, &residual, &moved);
    assert_eq!((0..n).filter(|&v| s[v]).collect::<Vec<_>>(), vec![repaired]);
    let mut removed = peeled();
    complete_clusters(&p, &topology, &s, &mut removed, &mut fit);
    let gone: Vec<usize> = (0..n).filter(|&v| removed[v] && v != seed).collect();
    assert_eq!(gone, members);
    input[repaired].z -= 7.0;
    assert!(!seeds(&p, &input, &residual, &moved).iter().any(|&x| x));
}

/// On the rim a peeled vertex 4–5 mm off its fit seeds the search (its cluster held the
/// fit up); one 3.5 mm off does not.
#[test]
fn a_rim_vertex_peeled_under_the_spike_threshold_seeds_the_cluster_search() {
    let (mut p, topology) = patch();
    let mut fit = QuadricFit::default();
    let n = p.len();
    let seed = at(0, 10);
    assert!(topology.is_boundary[seed]);
    let members = [at(1, 10), at(1, 11)];
    p[members[0]].z += 6.0;
    p[members[1]].z += 5.0;
    let mut peeled = vec![false; n];
    peeled[seed] = true;
    let mut residual = vec![0.0; n];
    residual[seed] = 4.5;
    let no_moves = vec![false; n];
    let s = cluster_seeds(&p, &p, &topology, &residual, &peeled, &no_moves);
    assert_eq!((0..n).filter(|&v| s[v]).collect::<Vec<_>>(), vec![seed]);
    let mut removed = peeled.clone();
    complete_clusters(&p, &topology, &s, &mut removed, &mut fit);
    let gone: Vec<usize> = (0..n).filter(|&v| removed[v] && v != seed).collect();
    assert_eq!(gone, members);
    residual[seed] = 3.5;
    let s = cluster_seeds(&p, &p, &topology, &residual, &peeled, &no_moves);
    assert!(!s.iter().any(|&x| x));
}

/// Peeling takes the worst of each 1-ring; a worse neighbour blocks a vertex unless it is
/// removed or one the step-edge test keeps (it would never go, so the vertex never would).
#[test]
fn a_kept_step_edge_neighbour_does_not_block_peeling() {
    let (_, topology) = patch();
    let n = topology.vertex_count();
    let (v, u) = (at(10, 10), at(11, 10));
    let mut residual = vec![0.0; n];
    residual[v] = -3.5;
    residual[u] = 5.0;
    let mut removed = vec![false; n];
    let run = |residual: &[f64], removed: &[bool], keeps: Option<usize>| {
        peel_candidates(&topology, residual, removed, 3.0, &mut |x| Some(x) == keeps)
    };
    assert_eq!(run(&residual, &removed, None), vec![u]);
    assert_eq!(run(&residual, &removed, Some(u)), vec![v]);
    assert_eq!(run(&residual, &removed, Some(v)), vec![u]);
    removed[u] = true;
    assert_eq!(run(&residual, &removed, None), vec![v]);
    // Under the threshold nothing goes, whatever blocks it.
    residual[v] = -2.9;
    assert!(run(&residual, &removed, None).is_empty());
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

/// A steep 21 × 21 slope (2.5 mm of height per 1 mm step), as a cheek seen at a grazing
/// angle, with an optional 5 mm step along y = 10.5 (a lid crease across the patch).
fn slope(step_mm: f64) -> (Vec<DVec3>, Topology) {
    let mesh = grid(21, 21, |x, y| {
        2.5 * x + 0.01 * (y - 10.0).powi(2) + if y > 10.5 { step_mm } else { 0.0 }
    });
    let topology = Topology::new(&mesh);
    (mesh.positions_mm, topology)
}

/// A corner of the rim (2 kept neighbours) on a steep slope stays, however steep; spiked
/// 5 mm up or down it goes, 2.5 mm it stays. A vertex with 3 kept neighbours, or one
/// with a neighbour that has no continuation in line, is not judged.
#[test]
fn a_spiked_corner_of_the_rim_is_removed() {
    let (mut p, topology) = slope(0.0);
    let n = p.len();
    let corner = at(0, 0);
    assert_eq!(topology.neighbours(corner).len(), 2);
    let run = |p: &[DVec3], removed: &[bool]| {
        let mut r = removed.to_vec();
        dangling_corners(p, &topology, 3.0, &mut r);
        (0..n).filter(|&v| r[v] && !removed[v]).collect::<Vec<_>>()
    };
    let none = vec![false; n];
    assert!(
        run(&p, &none).is_empty(),
        "a clean steep slope loses nothing"
    );
    for (dz, goes) in [(5.0, true), (-5.0, true), (2.5, false), (-2.5, false)] {
        let mut q = p.clone();
        q[corner].z += dz;
        let expected = if goes { vec![corner] } else { vec![] };
        assert_eq!(run(&q, &none), expected, "corner spiked {dz} mm");
    }
    // On the bottom edge a vertex has 3 neighbours: peeling judges it, not this test.
    let edge = at(10, 0);
    assert_eq!(topology.neighbours(edge).len(), 3);
    p[edge].z += 5.0;
    assert!(run(&p, &none).is_empty());
    // Its neighbour (11, 0) removed, it is a corner of the rim and goes ...
    let mut removed = none.clone();
    removed[at(11, 0)] = true;
    assert_eq!(run(&p, &removed), vec![edge]);
    // ... unless a neighbour has nothing in line beyond it (the vertex above it removed).
    removed[at(10, 2)] = true;
    assert!(run(&p, &removed).is_empty());
}

/// A 2-vertex cluster 5 mm down on a steep slope jumps by at most 7.5 mm over its border
/// edges (under [`JUMP_MM`]) but bends against both continuations: cut off and removed.
/// The clean slope, and a long 5 mm step across it, lose nothing.
#[test]
fn a_cluster_on_a_steep_slope_is_cut_off_by_its_bends() {
    let count = |p: &[DVec3], t: &Topology| jump_pieces(p, t).iter().filter(|&&r| r).count();
    let (mut p, topology) = slope(0.0);
    assert_eq!(count(&p, &topology), 0, "a clean slope");
    let (a, b) = (at(10, 5), at(11, 5));
    for v in [a, b] {
        p[v].z -= 5.0;
    }
    let jump = topology
        .neighbours(a)
        .iter()
        .map(|&u| (p[u as usize].z - p[a].z).abs())
        .fold(0.0, f64::max);
    assert!(
        jump <= JUMP_MM,
        "the depth-jump test alone would not cut it: {jump}"
    );
    let removed = jump_pieces(&p, &topology);
    assert!(removed[a] && removed[b]);
    assert_eq!(removed.iter().filter(|&&r| r).count(), 2);
    let (p, topology) = slope(5.0);
    assert_eq!(count(&p, &topology), 0, "a step that runs across the patch");
}

/// A fragment of 2 × 4 vertices goes whatever its depth; one of 3 × 3, or the patch,
/// stays.
#[test]
fn isolated_fragments_smaller_than_a_full_ring_are_removed() {
    let mut mesh = grid(21, 21, |_, _| 0.0);
    let mut faces: Vec<Vec<u32>> = mesh.faces.iter().map(|f| f.to_vec()).collect();
    let n = mesh.positions_mm.len() as u32;
    // Blocks beside the patch (in its plane: depth does not matter).
    let mut block = |x0: f64, y0: f64, w: u32, h: u32| {
        let first = mesh.positions_mm.len() as u32;
        for j in 0..h {
            for i in 0..w {
                mesh.positions_mm
                    .push(DVec3::new(x0 + i as f64, y0 + j as f64, 0.0));
            }
        }
        for j in 0..h - 1 {
            for i in 0..w - 1 {
                let v = first + j * w + i;
                faces.push(vec![v, v + 1, v + 1 + w, v + w]);
            }
        }
    };
    block(30.0, 0.0, 4, 2);
    block(30.0, 5.0, 3, 3);
    let mesh = Mesh::from_faces(mesh.positions_mm, faces);
    let removed = jump_pieces(&mesh.positions_mm, &Topology::new(&mesh));
    let gone: Vec<u32> = (0..mesh.positions_mm.len() as u32)
        .filter(|&v| removed[v as usize])
        .collect();
    assert_eq!(gone, (n..n + 8).collect::<Vec<_>>());
    // A mesh that is one quad is not emptied.
    let quad = grid(2, 2, |_, _| 0.0);
    let removed = jump_pieces(&quad.positions_mm, &Topology::new(&quad));
    assert!(removed.iter().all(|&r| !r));
}

/// A peeled vertex that its kept ring fits is put back; a peeled spike is not, nor a
/// vertex further off than [`RESTORE_MAX_MM`].
#[test]
fn peeled_vertices_the_kept_surface_fits_are_put_back() {
    let (mut p, topology) = patch();
    let rings3 = Rings::new(&topology, 3);
    let mut fit = QuadricFit::default();
    let n = p.len();
    let mut scratch = Scratch::new(n, 3.0);
    let (real, spike) = (at(6, 10), at(14, 10));
    p[spike].z += 6.0;
    let mut removed = vec![false; n];
    removed[real] = true;
    removed[spike] = true;
    let mut again = |p: &[DVec3], candidates: &[usize]| {
        fitting_again(
            p,
            &topology,
            &rings3,
            candidates,
            &removed,
            &mut fit,
            &mut scratch,
        )
    };
    let back = again(&p, &[real, spike]);
    assert_eq!(back, vec![real]);
    // A vertex 2.5 mm off (under the 3 mm peel threshold, over the 1.5 mm to come back).
    p[real].z += 2.5;
    let back = again(&p, &[real]);
    assert!(back.is_empty(), "{back:?}");
    p[real].z -= 2.5;
    // The robust fit sees through a 3 × 3 cluster 6 mm up in the ring (9 of its 24
    // points): the real vertex still comes back, the spike still does not.
    for j in 9..=11 {
        for i in 7..=9 {
            p[at(i, j)].z += 6.0;
        }
    }
    let back = again(&p, &[real, spike]);
    assert_eq!(back, vec![real]);
}

/// Removals that cut off a 2 × 4 block (8 vertices) take it too; a 3 × 3 block (9) or
/// the rest of the patch stays, and a patch left with nothing larger keeps its pieces.
#[test]
fn fragments_the_removals_leave_are_removed() {
    let (_, topology) = patch();
    let n = 21 * 21;
    // Cut a ring of removed vertices around a block in the corner.
    let cut = |w: usize, h: usize| {
        let mut removed = vec![false; n];
        for j in 0..=h {
            removed[at(w, j)] = true;
        }
        for i in 0..=w {
            removed[at(i, h)] = true;
        }
        removed
    };
    let mut removed = cut(2, 4);
    let before = removed.clone();
    leftover_fragments(&topology, &mut removed);
    for j in 0..4 {
        for i in 0..2 {
            assert!(removed[at(i, j)], "({i}, {j})");
        }
    }
    let newly = (0..n).filter(|&v| removed[v] && !before[v]).count();
    assert_eq!(newly, 8);
    let mut removed = cut(3, 3);
    let before = removed.clone();
    leftover_fragments(&topology, &mut removed);
    assert_eq!(removed, before);
    // Only pieces of 2 × 2 left: nothing more goes.
    let mut removed: Vec<bool> = (0..n).map(|v| v % 21 % 3 == 2 || v / 21 % 3 == 2).collect();
    let before = removed.clone();
    leftover_fragments(&topology, &mut removed);
    assert_eq!(removed, before);
}

/// A 4 mm repair goes whatever is near it; a 2.9 mm repair stays, and with an infinite
/// limit every repair stays.
#[test]
fn large_repairs_are_removed() {
    let (p, _) = patch();
    let n = p.len();
    let v = at(10, 10);
    let mut input = p.clone();
    input[v].z -= 4.0;
    let mut moved = vec![false; n];
    moved[v] = true;
    let run = |input: &[DVec3], limit_mm: f64| {
        let mut removed = vec![false; n];
        large_repairs(&p, input, &moved, limit_mm, &mut removed);
        assert!(removed.iter().enumerate().all(|(u, &r)| u == v || !r));
        removed[v]
    };
    assert!(run(&input, 3.0));
    assert!(!run(&input, f64::INFINITY));
    input[v].z += 1.1;
    assert!(!run(&input, 3.0), "a 2.9 mm repair");
}
