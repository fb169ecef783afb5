//! Step 3, what the projection could not place: why each unmatched vertex is unmatched, and
//! the harmonic fill of their radial offsets from the matched vertices around them.

use crate::mesh::{Mesh, Topology};

/// Why a generic vertex was filled in rather than projected onto the scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unmatched {
    /// Its ray missed the scan, in a patch of misses open to the generic face's outer border:
    /// beyond the scan's edge (hair the scanner did not see, the neck or ears cut off).
    OutsideScan,
    /// Its ray missed the scan in a patch enclosed by projected vertices: a hole in the scan
    /// (eyes, nostrils, a dropout).
    Hole,
    /// The ray hit the scan more than [`super::RegistrationParams::max_offset_mm`] from the warped
    /// face: hair, an ear or a collar in front of or behind the skin.
    FarSurface,
    /// Its offset differs from its neighbours' median by more than
    /// [`super::RegistrationParams::outlier_mm`]: a spike or a strand of hair.
    Outlier,
}

impl Unmatched {
    pub const ALL: [Unmatched; 4] = [
        Unmatched::OutsideScan,
        Unmatched::Hole,
        Unmatched::FarSurface,
        Unmatched::Outlier,
    ];

    /// The name the reports use.
    pub fn name(self) -> &'static str {
        match self {
            Unmatched::OutsideScan => "outside_scan",
            Unmatched::Hole => "hole",
            Unmatched::FarSurface => "far_surface",
            Unmatched::Outlier => "outlier",
        }
    }
}

/// Turns the misses ([`Unmatched::Hole`] so far) that connect, through misses, to the
/// generic face's outer border (its longest boundary loop) into [`Unmatched::OutsideScan`]:
/// a patch of misses enclosed by projected vertices is a hole in the scan, one open to the
/// border lies beyond the scan's edge.
pub(super) fn mark_outside_scan(mesh: &Mesh, topo: &Topology, reason: &mut [Option<Unmatched>]) {
    let Some(outer) = crate::generic_face::boundary_loops(mesh)
        .into_iter()
        .max_by_key(|l| l.len())
    else {
        return;
    };
    let mut queue: Vec<usize> = outer
        .iter()
        .map(|&v| v as usize)
        .filter(|&v| reason[v] == Some(Unmatched::Hole))
        .collect();
    for &v in &queue {
        reason[v] = Some(Unmatched::OutsideScan);
    }
    while let Some(v) = queue.pop() {
        for &u in topo.neighbours(v) {
            let u = u as usize;
            if reason[u] == Some(Unmatched::Hole) {
                reason[u] = Some(Unmatched::OutsideScan);
                queue.push(u);
            }
        }
    }
}

/// Harmonic fill: unknown values (`known[v] == false`) become the average of their neighbours
/// (Gauss–Seidel to convergence), known values stay. Unknown vertices with no known vertex in
/// their connected component get 0.
pub(super) fn harmonic_fill(topo: &Topology, known: &[bool], values: &mut [f64]) {
    let n = values.len();
    let unknown: Vec<usize> = (0..n).filter(|&v| !known[v]).collect();
    if unknown.is_empty() {
        return;
    }
    // Initial guess by breadth-first layers from the known rim (also finds orphans).
    let mut set = known.to_vec();
    let mut frontier: Vec<usize> = unknown.clone();
    loop {
        let mut next = Vec::new();
        let mut newly = Vec::new();
        for &v in &frontier {
            let (mut sum, mut cnt) = (0.0, 0usize);
            for &u in topo.neighbours(v) {
                if set[u as usize] {
                    sum += values[u as usize];
                    cnt += 1;
                }
            }
            if cnt > 0 {
                newly.push((v, sum / cnt as f64));
            } else {
                next.push(v);
            }
        }
        if newly.is_empty() {
            for v in next {
                values[v] = 0.0;
            }
            break;
        }
        for (v, x) in newly {
            values[v] = x;
            set[v] = true;
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    for _ in 0..5000 {
        let mut change: f64 = 0.0;
        for &v in &unknown {
            let nb = topo.neighbours(v);
            if nb.is_empty() {
                continue;
            }
            let avg = nb.iter().map(|&u| values[u as usize]).sum::<f64>() / nb.len() as f64;
            change = change.max((avg - values[v]).abs());
            values[v] = avg;
        }
        if change < 1e-6 {
            break;
        }
    }
}
