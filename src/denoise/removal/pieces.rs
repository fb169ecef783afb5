//! Test 1's pieces: the mesh cut at depth jumps and bends, and its connected pieces.

use super::*;

/// Test 1 of the module docs: the vertices of small pieces cut off by depth jumps, and of
/// isolated fragments.
pub fn jump_pieces(positions: &[DVec3], topology: &Topology) -> Vec<bool> {
    let whole = pieces(topology, |_, _| true);
    let cut = pieces(topology, |v, u| {
        (positions[u].z - positions[v].z).abs() <= JUMP_MM
            && bend_mm(positions, topology, v, u) <= BEND_MM
    });
    let island_max = island_limit(&whole);
    (0..positions.len())
        .map(|v| {
            let small = cut.size[cut.label[v] as usize];
            let whole = whole.size[whole.label[v] as usize];
            (small <= JUMP_PIECE_MAX_VERTICES && whole >= 3 * small) || whole <= island_max
        })
        .collect()
}

/// Cosine of the largest angle between an edge and the edge that continues it for
/// [`bend_mm`] and [`dangling_corners`] (about 25°).
pub(super) const CONTINUATION_MIN_COS: f64 = 0.9;
/// An edge whose slope differs from both edges continuing it by more than this, in mm of
/// height over the edge's length, is a step (test 1).
pub const BEND_MM: f64 = 3.5;

/// How much edge `v`–`u` bends away from the edges that continue it on either side, in mm of
/// height over its length: the smaller of the two slope changes (a spike's border edge
/// changes slope against both, a crease's edge against one at most). 0 where neither side
/// has a continuation.
pub(super) fn bend_mm(positions: &[DVec3], topology: &Topology, v: usize, u: usize) -> f64 {
    let (a, b) = (positions[v], positions[u]);
    let run = (b - a).truncate().length();
    if run <= 0.0 {
        return 0.0;
    }
    let slope = (b.z - a.z) / run;
    // The slope change from this edge to the edge that continues it past `from`, away from
    // `at` (slopes taken in the a → b direction, so `sign` is -1 on a's side).
    let change = |at: DVec3, from: usize, sign: f64| -> Option<f64> {
        let p = positions[from];
        in_line(positions, topology, from, (p - at).truncate() / run)
            .map(|(t, len, _)| (sign * (positions[t].z - p.z) / len - slope).abs() * run)
            .min_by(f64::total_cmp)
    };
    match (change(a, u, 1.0), change(b, v, -1.0)) {
        (Some(x), Some(y)) => x.min(y),
        _ => 0.0,
    }
}

/// The neighbours of `from` that continue the xy direction `dir` (a unit vector) past it,
/// within [`CONTINUATION_MIN_COS`]: each with its xy distance from `from` and the cosine.
pub(super) fn in_line<'a>(
    positions: &'a [DVec3],
    topology: &'a Topology,
    from: usize,
    dir: DVec2,
) -> impl Iterator<Item = (usize, f64, f64)> + 'a {
    let p = positions[from];
    topology.neighbours(from).iter().filter_map(move |&t| {
        let d = (positions[t as usize] - p).truncate();
        let len = d.length();
        (len > 0.0 && d.dot(dir) / len >= CONTINUATION_MIN_COS)
            .then(|| (t as usize, len, d.dot(dir) / len))
    })
}

/// Connected pieces of the mesh through the edges `joined` keeps.
pub(super) struct Pieces {
    pub(super) label: Vec<u32>,
    pub(super) size: Vec<usize>,
}

pub(super) fn pieces(topology: &Topology, joined: impl Fn(usize, usize) -> bool) -> Pieces {
    let n = topology.is_boundary.len();
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
                if label[u] == u32::MAX && joined(v, u) {
                    label[u] = id;
                    stack.push(u);
                }
            }
        }
        size.push(count);
    }
    Pieces { label, size }
}
