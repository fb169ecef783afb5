//! One run of the filter chosen by [`DenoiseParams::method`]: the median-Laplacian iteration
//! (with the quadric estimator's rim phase, last polish and removal) or a baseline.

use super::*;

/// Displacements at or below this count as "did not move", mm.
pub(crate) const STILL_MM: f64 = 1e-9;

/// Runs the filter on `positions`; `observe(iteration, positions)` is called after every
/// iteration (1-based), so a sweep over k costs one run (used by [`eval`]). Vertices to be
/// removed are only reported (`removed`, NaN displacement), not taken out: [`denoise`] does
/// that with the mesh.
pub fn run(
    positions: &mut [DVec3],
    nb: &FilterNeighbours,
    topology: &Topology,
    params: &DenoiseParams,
    observe: impl FnMut(usize, &[DVec3]),
) -> DenoiseReport {
    let filtered = filter(positions, nb, topology, params, observe);
    DenoiseReport::new(params.method, &filtered, positions)
}

/// What the filter did, before [`DenoiseReport::new`] sums it up (one entry per input vertex).
pub(super) struct Filtered {
    pub(super) input: Vec<DVec3>,
    pub(super) iterations_run: usize,
    pub(super) moved: Vec<bool>,
    /// Vertices to take out of the mesh (none unless removal is on).
    pub(super) removed: Vec<bool>,
}

pub(super) fn filter(
    positions: &mut [DVec3],
    nb: &FilterNeighbours,
    topology: &Topology,
    params: &DenoiseParams,
    mut observe: impl FnMut(usize, &[DVec3]),
) -> Filtered {
    let n = positions.len();
    assert_eq!(
        nb.vertex_count(),
        n,
        "filter neighbours do not fit the mesh"
    );
    let input = positions.to_vec();
    let mut moved = vec![false; n];
    let mut removed = vec![false; n];
    let mut iterations_run = 0;
    match params.method {
        DenoiseMethod::MedianLaplacian => {
            let mut work = MedianLaplacianWork::new(n, topology, params.estimator);
            // Iterations of the current phase; the quadric estimator does the rims once the
            // interior has settled or used its k, and the rim phase gets k of its own (else a
            // slowly converging interior would leave every rim spike untouched).
            let (mut it, mut phase_it) = (0, 0);
            loop {
                let count = if phase_it < params.iterations {
                    work.iterate(positions, &input, nb, topology, params, &mut moved)
                } else {
                    0
                };
                if count == 0 {
                    // With removal on, rim vertices are removed, never moved (see [`removal`]).
                    if work.rim_phase
                        || params.remove_unrepairable
                        || !work.start_rim_phase(topology)
                    {
                        break;
                    }
                    phase_it = 0;
                    continue;
                }
                phase_it += 1;
                it += 1;
                iterations_run += 1;
                observe(it, positions);
            }
            // k = 0 leaves the mesh as it is (the documented identity).
            if let Some(rings3) = work.rings3.as_ref().filter(|_| params.iterations > 0) {
                polish(positions, topology, rings3, &moved, &mut work.fit);
                if params.remove_unrepairable {
                    removed = removal::unrepairable(
                        positions, &input, topology, rings3, params, &work.disp, &moved,
                    );
                }
            }
        }
        DenoiseMethod::Laplacian | DenoiseMethod::Taubin => {
            iterations_run = baselines::smooth(positions, nb, params, observe);
            for (m, (p, q)) in moved.iter_mut().zip(positions.iter().zip(&input)) {
                *m = p.distance(*q) > STILL_MM;
            }
        }
    }
    Filtered {
        input,
        iterations_run,
        moved,
        removed,
    }
}

/// The quadric estimator's last pass: every interior vertex the filter moved is refitted
/// from the vertices of its 3-ring that it did not move. A spike cluster's members were
/// first estimated from rings that held the cluster's other spikes; once all are down, the
/// unmoved ring is clean support.
fn polish(
    positions: &mut [DVec3],
    topology: &Topology,
    rings3: &Rings,
    moved: &[bool],
    fit: &mut QuadricFit,
) {
    for v in 0..positions.len() {
        if !moved[v] || topology.is_boundary[v] {
            continue;
        }
        let p = positions[v];
        if let Some((z, _, _)) = fit.predict(positions, p, rings3.of(v), |u| !moved[u]) {
            positions[v].z = z;
        }
    }
}
