//! The robust local fit the default filter predicts a vertex from: a quadric height field over
//! the ring, L1-reweighted, by consensus of random subsets, or trimmed.

use super::*;

/// Least-squares quadric (or plane) fit of a height field over a vertex's ring, with one
/// trimming pass ([`Estimator::RobustQuadric`]).
#[derive(Default)]
pub(super) struct QuadricFit {
    /// Ring points relative to the vertex: (x, y, z).
    pub(super) pts: Vec<DVec3>,
    pub(super) keep: Vec<bool>,
    /// Least-squares weights (1 = plain least squares; the L1 reweighting changes them).
    pub(super) weight: Vec<f64>,
    pub(super) res: Vec<f64>,
    /// The consensus fit's subsets for a ring of `n` points, at index `n`: the pseudo-random
    /// sequence depends on `n` alone, so each is drawn once per fit object.
    pub(super) subsets: Vec<Vec<[u32; QUADRIC_MIN_POINTS]>>,
}

/// Fewest ring points for a quadric fit (6 unknowns) and for a plane fit (3 unknowns).
pub(super) const QUADRIC_MIN_POINTS: usize = 9;
pub(super) const PLANE_MIN_POINTS: usize = 4;
/// L1 (least absolute deviations) reweighting rounds used when a plain fit leaves a rough
/// ring (σ̂ above [`TRIM_MIN_MM`]): a spike cluster inside the ring pulls a least-squares
/// fit towards it, the L1 fit is not pulled by a minority of outliers in z.
pub(super) const L1_ROUNDS: usize = 10;
/// A vertex is eligible only if its change is at least this many times the ring's own
/// roughness (90th percentile of the ring residuals below half the change): a spike stands
/// out of a smooth ring, a vertex on a crease or lip edge the quadric cannot follow has
/// ring neighbours almost as far off as itself.
pub(super) const RING_ROUGHNESS_RATIO: f64 = 3.0;
/// A first fit with a ring residual above this (mm) is redone by L1 reweighting.
pub(super) const L1_TRIGGER_MM: f64 = 2.0;
/// Random subsets tried by the consensus fit, and the residual (mm) within which a ring point
/// agrees with a candidate quadric (scanner noise σ ≈ 0.15 mm, plus what a quadric cannot
/// follow over a 3-ring).
pub(super) const CONSENSUS_TRIALS: usize = 48;
pub(super) const CONSENSUS_TOLERANCE_MM: f64 = 1.5;
/// Ring points with a residual above `max(TRIM_SIGMAS σ̂, TRIM_MIN_MM)` are left out of the
/// refit.
pub(super) const TRIM_SIGMAS: f64 = 3.0;
pub(super) const TRIM_MIN_MM: f64 = 1.0;

impl QuadricFit {
    /// Takes the ring points `use_point` admits, relative to `p`, all kept, unit weights.
    pub(super) fn load(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool,
    ) {
        self.pts.clear();
        self.pts.extend(
            ring.iter()
                .filter(|&&u| use_point(u as usize))
                .map(|&u| positions[u as usize] - p),
        );
        self.keep.clear();
        self.keep.resize(self.pts.len(), true);
        self.weight.clear();
        self.weight.resize(self.pts.len(), 1.0);
    }

    /// The height [`QuadricFit::predict`] would give at `p`, computed the cheap way when the
    /// ring is smooth: one least-squares fit that leaves every ring point within
    /// [`TRIM_MIN_MM`] is what `predict` keeps (no L1, no consensus, nothing trimmed), so the
    /// height is the same. `None` when the ring is not that smooth (call `predict`).
    pub(super) fn predict_smooth(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool,
    ) -> Option<f64> {
        self.load(positions, p, ring, use_point);
        let (z, c) = self.solve()?;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for q in &self.pts {
            if (q.z - eval_quadric(&c, q.x, q.y)).abs() > TRIM_MIN_MM {
                return None;
            }
            (lo, hi) = (lo.min(q.z), hi.max(q.z));
        }
        let span = hi - lo;
        (z >= lo - span - 1.0 && z <= hi + span + 1.0).then_some(p.z + z)
    }

    /// The fitted height at `p`: [`Self::predict_smooth`] where the ring is smooth, else
    /// [`Self::predict`]'s.
    pub(super) fn height(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool + Copy,
    ) -> Option<f64> {
        self.predict_smooth(positions, p, ring, use_point)
            .or_else(|| {
                self.predict(positions, p, ring, use_point)
                    .map(|(z, _, _)| z)
            })
    }

    /// The fitted height at `p`, the robust residual scale σ̂ of the kept ring points and the
    /// ring's roughness on the scale of the change (see [`RING_ROUGHNESS_RATIO`]), or `None`
    /// when the ring cannot support a fit.
    pub(super) fn predict(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool,
    ) -> Option<(f64, f64, f64)> {
        self.load(positions, p, ring, use_point);
        let mut z = self.solve()?;
        let rough = self
            .pts
            .iter()
            .any(|q| (q.z - eval_quadric(&z.1, q.x, q.y)).abs() > L1_TRIGGER_MM);
        if rough {
            for _ in 0..L1_ROUNDS {
                for (i, q) in self.pts.iter().enumerate() {
                    let r = (q.z - eval_quadric(&z.1, q.x, q.y)).abs();
                    self.weight[i] = 1.0 / r.max(0.05);
                }
                z = self.solve()?;
            }
            self.weight.fill(1.0);
            // A spike cluster can hold a third of a rim vertex's ring, more than L1 resists:
            // a consensus fit (random 9-point subsets, the quadric most points agree with)
            // is not pulled by any minority.
            if let Some(c) = self.consensus()
                && self.inliers(&c.1, 0) > self.inliers(&z.1, 0)
            {
                z = c;
            }
        }
        let sigma = self.trim(z.1);
        if self.keep.iter().any(|k| !k) {
            z = self.solve()?;
        }
        let sigma = self.sigma_of(z.1).min(sigma);
        // A wild extrapolation (thin strips, one-sided rims): not trusted.
        let (lo, hi) = self
            .pts
            .iter()
            .zip(&self.keep)
            .filter(|(_, k)| **k)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (q, _)| {
                (lo.min(q.z), hi.max(q.z))
            });
        let span = hi - lo;
        if !(z.0 >= lo - span - 1.0 && z.0 <= hi + span + 1.0) {
            return None;
        }
        // How rough the ring is on the scale of this change: the 90th percentile of the ring
        // residuals below half the change (a cluster's other spikes are above it).
        let d = z.0.abs();
        self.res.clear();
        for q in &self.pts {
            let r = (q.z - eval_quadric(&z.1, q.x, q.y)).abs();
            if r < 0.5 * d {
                self.res.push(r);
            }
        }
        let rough = if self.res.is_empty() {
            0.0
        } else {
            let k = (0.9 * (self.res.len() - 1) as f64).round() as usize;
            *self.res.select_nth_unstable_by(k, f64::total_cmp).1
        };
        Some((p.z + z.0, sigma, rough))
    }

    /// Ring points within [`CONSENSUS_TOLERANCE_MM`] of the quadric `coef`, counted until the
    /// count can no longer exceed `beat` (0: the whole count).
    pub(super) fn inliers(&self, coef: &[f64; 6], beat: usize) -> usize {
        let n = self.pts.len();
        let mut count = 0;
        for (seen, q) in self.pts.iter().enumerate() {
            if count + (n - seen) <= beat {
                break;
            }
            if (q.z - eval_quadric(coef, q.x, q.y)).abs() < CONSENSUS_TOLERANCE_MM {
                count += 1;
            }
        }
        count
    }

    /// Consensus fit: of [`CONSENSUS_TRIALS`] least-squares quadrics through random
    /// [`QUADRIC_MIN_POINTS`]-point subsets (a fixed pseudo-random sequence, so runs repeat),
    /// the one with the most inliers, refitted to its inliers. Leaves `keep` all set.
    pub(super) fn consensus(&mut self) -> Option<(f64, [f64; 6])> {
        let n = self.pts.len();
        if n < 2 * QUADRIC_MIN_POINTS {
            return None;
        }
        if self.subsets.len() <= n {
            self.subsets.resize(n + 1, Vec::new());
        }
        if self.subsets[n].is_empty() {
            self.subsets[n] = consensus_subsets(n);
        }
        let mut best: Option<(usize, [f64; 6])> = None;
        for subset in &self.subsets[n] {
            let Some(c) = fit_terms::<6>(subset.iter().map(|&i| (self.pts[i as usize], 1.0)))
            else {
                continue;
            };
            // Only a count above the best so far matters.
            let count = self.inliers(&c, best.map_or(0, |(b, _)| b));
            if best.is_none_or(|(b, _)| count > b) {
                best = Some((count, c));
            }
        }
        let (_, c) = best?;
        for (q, k) in self.pts.iter().zip(self.keep.iter_mut()) {
            *k = (q.z - eval_quadric(&c, q.x, q.y)).abs() < CONSENSUS_TOLERANCE_MM;
        }
        let refit = self.solve();
        self.keep.fill(true);
        refit
    }

    /// Robust σ̂ (1.4826 · median |residual|) of the kept points under `coef`.
    pub(super) fn sigma_of(&mut self, coef: [f64; 6]) -> f64 {
        self.res.clear();
        for (q, k) in self.pts.iter().zip(&self.keep) {
            if *k {
                self.res.push((q.z - eval_quadric(&coef, q.x, q.y)).abs());
            }
        }
        if self.res.is_empty() {
            return 0.0;
        }
        1.4826 * median(&mut self.res)
    }

    /// Drops the points whose residual is above the trimming limit; returns σ̂ before.
    pub(super) fn trim(&mut self, coef: [f64; 6]) -> f64 {
        let sigma = self.sigma_of(coef);
        let limit = (TRIM_SIGMAS * sigma).max(TRIM_MIN_MM);
        for (q, k) in self.pts.iter().zip(self.keep.iter_mut()) {
            if (q.z - eval_quadric(&coef, q.x, q.y)).abs() > limit {
                *k = false;
            }
        }
        sigma
    }

    /// Least squares over the kept points: a quadric if there are enough and it is well
    /// conditioned, else a plane. Returns (height at the origin, coefficients).
    pub(super) fn solve(&self) -> Option<(f64, [f64; 6])> {
        let count = self.keep.iter().filter(|k| **k).count();
        if count >= QUADRIC_MIN_POINTS
            && let Some(c) = self.solve_terms::<6>()
        {
            return Some((c[0], c));
        }
        if count >= PLANE_MIN_POINTS
            && let Some(c) = self.solve_terms::<3>()
        {
            return Some((c[0], [c[0], c[1], c[2], 0.0, 0.0, 0.0]));
        }
        None
    }

    /// [`fit_terms`] over the kept points with their weights.
    pub(super) fn solve_terms<const K: usize>(&self) -> Option<[f64; K]> {
        fit_terms::<K>(
            self.pts
                .iter()
                .zip(&self.keep)
                .zip(&self.weight)
                .filter(|((_, k), _)| **k)
                .map(|((q, _), w)| (*q, *w)),
        )
    }
}

/// [`CONSENSUS_TRIALS`] distinct-index subsets of [`QUADRIC_MIN_POINTS`] ring points out of
/// `n`, each in ring order (a fixed xorshift sequence seeded by `n`, so runs repeat).
pub(super) fn consensus_subsets(n: usize) -> Vec<[u32; QUADRIC_MIN_POINTS]> {
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15 ^ n as u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    (0..CONSENSUS_TRIALS)
        .map(|_| {
            let mut subset = [0u32; QUADRIC_MIN_POINTS];
            let mut chosen = 0;
            while chosen < QUADRIC_MIN_POINTS {
                let i = (next() % n as u64) as u32;
                if !subset[..chosen].contains(&i) {
                    subset[chosen] = i;
                    chosen += 1;
                }
            }
            // Ring order, as a mask over the ring would visit them, so the sums are the
            // same; an index list spares a mispredicted branch per ring point.
            subset.sort_unstable();
            subset
        })
        .collect()
}

/// Weighted least squares for the first `K` terms of `[1, x, y, x², xy, y²]` through points
/// (x, y, z) with weights, in coordinates scaled by the points' RMS radius; `None` if
/// (nearly) singular.
pub(super) fn fit_terms<const K: usize>(
    points: impl Iterator<Item = (DVec3, f64)> + Clone,
) -> Option<[f64; K]> {
    let (mut r2, mut n) = (0.0, 0.0);
    for (q, _) in points.clone() {
        r2 += q.x * q.x + q.y * q.y;
        n += 1.0;
    }
    let scale = (r2 / n).sqrt();
    if !(scale > 1e-9) {
        return None;
    }
    // Upper triangle of AᵀWA and AᵀWz, then an in-place Cholesky: this runs ~10⁵ times
    // per scan (L1 rounds, consensus trials), so it avoids generic matrix temporaries.
    let mut ata = [[0.0f64; K]; K];
    let mut atb = [0.0f64; K];
    for (q, w) in points {
        let (x, y) = (q.x / scale, q.y / scale);
        let all = quadric_terms(x, y);
        for i in 0..K {
            let wi = w * all[i];
            for j in i..K {
                ata[i][j] += wi * all[j];
            }
            atb[i] += wi * q.z;
        }
    }
    // Cholesky A = LLᵀ, L stored in the lower triangle (row i, column j ≤ i).
    let mut l = [[0.0f64; K]; K];
    for j in 0..K {
        let mut d = ata[j][j];
        for m in 0..j {
            d -= l[j][m] * l[j][m];
        }
        if !(d > 0.0) {
            return None;
        }
        let d = d.sqrt();
        l[j][j] = d;
        for i in j + 1..K {
            let mut s = ata[j][i];
            for m in 0..j {
                s -= l[i][m] * l[j][m];
            }
            l[i][j] = s / d;
        }
    }
    let (dmin, dmax) = (0..K).fold((f64::INFINITY, 0.0f64), |(lo, hi), i| {
        (lo.min(l[i][i]), hi.max(l[i][i]))
    });
    // Diagonal of the factor ~ singular values' square roots: reject condition > ~1e8.
    if !(dmin > 1e-4 * dmax) {
        return None;
    }
    // Forward (L u = b) then back (Lᵀ c = u) substitution.
    let mut c = atb;
    for i in 0..K {
        for m in 0..i {
            c[i] -= l[i][m] * c[m];
        }
        c[i] /= l[i][i];
    }
    for i in (0..K).rev() {
        for m in i + 1..K {
            c[i] -= l[m][i] * c[m];
        }
        c[i] /= l[i][i];
    }
    let unscale = [
        1.0,
        1.0 / scale,
        1.0 / scale,
        1.0 / (scale * scale),
        1.0 / (scale * scale),
        1.0 / (scale * scale),
    ];
    Some(std::array::from_fn(|i| c[i] * unscale[i]))
}

/// The quadric's terms `[1, x, y, x², xy, y²]` at (x, y): one row of the fit's design matrix.
pub(super) fn quadric_terms(x: f64, y: f64) -> [f64; 6] {
    [1.0, x, y, x * x, x * y, y * y]
}

pub(super) fn eval_quadric(c: &[f64; 6], x: f64, y: f64) -> f64 {
    c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y
}
