//! The paper's Table 1 baselines: the plain uniform Laplacian (`p ← p + λ (avg(N) − p)`) and
//! Taubin's λ|μ smoothing (a λ step, then a μ < 0 step that undoes the shrinking), over the
//! same filter neighbours as the median-Laplacian filter.

use super::*;

/// Runs [`DenoiseParams::iterations`] baseline iterations (Laplacian, or Taubin's λ then μ)
/// on `positions`, calling `observe(iteration, positions)` after each; returns how many ran.
pub(super) fn smooth(
    positions: &mut [DVec3],
    nb: &FilterNeighbours,
    params: &DenoiseParams,
    mut observe: impl FnMut(usize, &[DVec3]),
) -> usize {
    let mut scratch = vec![DVec3::ZERO; positions.len()];
    for it in 1..=params.iterations {
        laplacian_step(positions, &mut scratch, nb, params.lambda);
        if params.method == DenoiseMethod::Taubin {
            laplacian_step(positions, &mut scratch, nb, params.mu);
        }
        observe(it, positions);
    }
    params.iterations
}

/// One uniform Laplacian step `p ← p + factor · (avg(N) − p)` (Jacobi: all from the old
/// positions). Held vertices (no filter neighbours) stay.
fn laplacian_step(
    positions: &mut [DVec3],
    scratch: &mut [DVec3],
    nb: &FilterNeighbours,
    factor: f64,
) {
    scratch.copy_from_slice(positions);
    for (v, p) in positions.iter_mut().enumerate() {
        let ring = nb.of(v);
        if ring.is_empty() {
            continue;
        }
        let sum: DVec3 = ring.iter().map(|&u| scratch[u as usize]).sum();
        let avg = sum / ring.len() as f64;
        *p += factor * (avg - scratch[v]);
    }
}
