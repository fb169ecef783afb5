//! Fisherfaces (paper section 3, eqs. 1–9): PCA to M − c dimensions, then LDA to c − 1.
//!
//! * Ψ (eq. 7) is the mean of the M training vectors Γ, A = [Γ₁ − Ψ … Γ_M − Ψ] (d × M).
//! * **PCA** (eqs. 3–4): the eigenvectors of S_T = A Aᵀ come from the M × M Gram matrix
//!   G = Aᵀ A (d ≫ M): G v = λ v ⇒ S_T (A v) = λ (A v), and u = A v / √λ has unit length.
//!   The leading M − c are kept (fewer if the data has lower rank), which makes S_w regular.
//! * **LDA** (eqs. 2, 5, 6, 8) in the PCA space: S_b w = λ S_w w, solved through the Cholesky
//!   factor S_w = L Lᵀ as the symmetric problem (L⁻¹ S_b L⁻ᵀ) y = λ y, w = L⁻ᵀ y; the c − 1
//!   leading w are kept, so the projected within-class scatter is the identity.
//! * U_opt = U_pca U_lda (eq. 1), Ω = (Γ − Ψ)ᵀ U_opt (eq. 9).
//!
//! With one training sample per class (M = c) S_w = 0 and LDA is undefined: the model falls
//! back to **Eigenfaces** (PCA to M − 1 dimensions) and says so in [`FisherModel::method`].

use crate::{Error, Result};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Col, Mat, MatRef, Par, Side};
use serde::Serialize;

/// How the projection was built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// PCA to M − c, then LDA to c − 1 (paper eqs. 1–9).
    Fisherfaces,
    /// PCA only, to M − 1 dimensions: one sample per class, so S_w = 0 and LDA is undefined.
    Eigenfaces,
}

/// Distance between projected faces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Metric {
    /// 1 − cos(angle); 0 for parallel vectors, 1 when either is zero.
    #[default]
    Cosine,
    /// ‖a − b‖.
    Euclidean,
}

impl Metric {
    pub fn name(self) -> &'static str {
        match self {
            Metric::Cosine => "cosine",
            Metric::Euclidean => "euclidean",
        }
    }

    /// Distance between two projected vectors of equal length.
    pub fn distance(self, a: &[f64], b: &[f64]) -> f64 {
        debug_assert_eq!(a.len(), b.len());
        match self {
            Metric::Euclidean => a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y) * (x - y))
                .sum::<f64>()
                .sqrt(),
            Metric::Cosine => {
                let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
                for (x, y) in a.iter().zip(b) {
                    ab += x * y;
                    aa += x * x;
                    bb += y * y;
                }
                if aa == 0.0 || bb == 0.0 {
                    1.0
                } else {
                    (1.0 - ab / (aa.sqrt() * bb.sqrt())).max(0.0)
                }
            }
        }
    }
}

/// Parameters of [`FisherModel::train`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FisherParams {
    /// PCA eigenvalues below this fraction of the largest count as zero (rank cut). Default
    /// 1e-10.
    pub rank_tolerance: f64,
    /// At most this many PCA dimensions before the LDA (default `None`: the paper's M − c).
    pub max_pca_dims: Option<usize>,
    /// Adds `λ · mean eigenvalue of S_w` to the diagonal of S_w (default 0: the paper's LDA).
    /// With one real scan per person and synthetic expressions of it, S_w holds only the
    /// expressions; directions where scans of one person differ by noise, pose or grid look
    /// noise-free to the LDA, and it amplifies them. A floor gives them their real variance.
    pub within_class_regularisation: f64,
}

impl Default for FisherParams {
    fn default() -> Self {
        FisherParams {
            rank_tolerance: 1e-10,
            max_pca_dims: None,
            within_class_regularisation: 0.0,
        }
    }
}

/// A trained projection Ω = (Γ − Ψ)ᵀ U_opt.
#[derive(Debug, Clone)]
pub struct FisherModel {
    /// Ψ, the training mean (length d).
    pub mean: Vec<f64>,
    /// U_opt (d × output dims).
    pub basis: Mat<f64>,
    pub method: Method,
    /// Dimensions kept by the PCA step (M − c, or M − 1 for Eigenfaces; less if rank-deficient).
    pub pca_dims: usize,
    /// Number of classes c.
    pub classes: usize,
    /// Number of training samples M.
    pub samples: usize,
}

impl FisherModel {
    /// Trains on `samples` (each of length d) with class `labels` (any ids; ≥ 2 classes).
    pub fn train(samples: &[Vec<f64>], labels: &[usize], params: &FisherParams) -> Result<Self> {
        Self::train_with_deviations(samples, labels, &[], params)
    }

    /// As [`Self::train`], plus known within-class **deviations** (each of length d, e.g.
    /// expression − neutral range images of people outside the gallery): each adds `c · δ δᵀ`
    /// (projected to the PCA space) to S_w, as if every one of the c classes had been seen
    /// with it, so the LDA learns to ignore those directions. They change neither Ψ, the PCA
    /// basis nor S_b. Used only by Fisherfaces (with one sample per class there is no PCA
    /// space of M − c dimensions to put them in; the model stays Eigenfaces).
    pub fn train_with_deviations(
        samples: &[Vec<f64>],
        labels: &[usize],
        deviations: &[Vec<f64>],
        params: &FisherParams,
    ) -> Result<Self> {
        let mut models = Self::train_variants(samples, labels, &[deviations], params)?;
        Ok(models.remove(0))
    }

    /// One model per set of within-class deviations (see [`Self::train_with_deviations`]),
    /// all on the same samples. The PCA — a Gram matrix and an eigen decomposition of M × M,
    /// the costly part — is computed once for all of them.
    pub fn train_variants<S: AsRef<[f64]>>(
        samples: &[S],
        labels: &[usize],
        deviation_sets: &[&[Vec<f64>]],
        params: &FisherParams,
    ) -> Result<Vec<Self>> {
        let pca = Pca::new(samples, labels, params)?;
        deviation_sets
            .iter()
            .map(|deviations| pca.lda(deviations, params))
            .collect()
    }
    /// Output dimensions (c − 1 for Fisherfaces).
    pub fn dims(&self) -> usize {
        self.basis.ncols()
    }

    /// Ω = (Γ − Ψ)ᵀ U_opt (eq. 9).
    pub fn project(&self, sample: &[f64]) -> Vec<f64> {
        let centred = Col::<f64>::from_fn(self.mean.len(), |i| sample[i] - self.mean[i]);
        let omega = self.basis.transpose() * &centred;
        omega.iter().copied().collect()
    }
}

/// The PCA stage of [`FisherModel`] training, shared by its LDA variants.
///
/// Everything is done in the M-dimensional sample space (the Gram matrix G = AᵀA of the
/// centred samples A, d × M), never with the d × k PCA basis U = A V itself: with
/// G = E Λ Eᵀ and V = E_k Λ_k^{-1/2}, the samples in PCA coordinates are UᵀA = Λ_k^{1/2} E_kᵀ,
/// a deviation δ is Uᵀδ = Vᵀ(Aᵀδ), and the final basis U W is A (V W). On the 61-subject
/// augmented gallery (d = 9,891, M = 1,159) that avoids two d × M × k products (~13 GFLOP
/// each). The dense algebra is faer's throughout (blocked, both cores): nalgebra's eigen
/// decomposition of G took 2.2 s against faer's 0.34–0.41 s here, and `tr_mul` with a tall
/// matrix 10 s.
struct Pca {
    mean: Vec<f64>,
    /// Centred samples A (d × M).
    a: Mat<f64>,
    /// V = E_k Λ_k^{-1/2} (M × k): U = A V.
    v: Mat<f64>,
    /// The samples in PCA coordinates, UᵀA = Λ_k^{1/2} E_kᵀ (k × M, zero mean).
    y: Mat<f64>,
    class_of: Vec<usize>,
    method: Method,
    classes: usize,
}

impl Pca {
    fn new<S: AsRef<[f64]>>(samples: &[S], labels: &[usize], params: &FisherParams) -> Result<Pca> {
        let m = samples.len();
        if m != labels.len() {
            return Err(Error::algorithm(
                "fisherfaces",
                format!("{m} samples but {} labels", labels.len()),
            ));
        }
        let mut ids: Vec<usize> = labels.to_vec();
        ids.sort_unstable();
        ids.dedup();
        let c = ids.len();
        if c < 2 {
            return Err(Error::algorithm(
                "fisherfaces",
                format!("need at least 2 classes, got {c}"),
            ));
        }
        let d = samples[0].as_ref().len();
        if d == 0 || samples.iter().any(|s| s.as_ref().len() != d) {
            return Err(Error::algorithm(
                "fisherfaces",
                "samples must be non-empty vectors of equal length",
            ));
        }
        if samples
            .iter()
            .flat_map(|s| s.as_ref())
            .any(|x| !x.is_finite())
        {
            return Err(Error::algorithm("fisherfaces", "a sample is not finite"));
        }
        let class_of: Vec<usize> = labels
            .iter()
            .map(|l| ids.binary_search(l).unwrap())
            .collect();
        let mut mean = vec![0.0; d];
        for s in samples {
            mean.iter_mut().zip(s.as_ref()).for_each(|(a, x)| *a += x);
        }
        mean.iter_mut().for_each(|a| *a /= m as f64);
        let a = Mat::<f64>::from_fn(d, m, |i, j| samples[j].as_ref()[i] - mean[i]);
        let method = if m > c {
            Method::Fisherfaces
        } else {
            Method::Eigenfaces
        };
        let want = match method {
            Method::Fisherfaces => m - c,
            Method::Eigenfaces => m - 1,
        }
        .min(params.max_pca_dims.unwrap_or(usize::MAX).max(1));
        // PCA through the Gram matrix (eigenvalues come in increasing order).
        let gram = a.transpose() * &a;
        let eig = eigen(&gram)?;
        let lambda = |i: usize| eig.S()[i];
        let top = lambda(m - 1).max(0.0);
        let kept: Vec<usize> = (0..m)
            .rev()
            .filter(|&i| lambda(i) > params.rank_tolerance * top && top > 0.0)
            .take(want)
            .collect();
        let k = kept.len();
        if k == 0 {
            return Err(Error::algorithm(
                "fisherfaces",
                "all training samples are identical (no variance)",
            ));
        }
        let e = eig.U();
        let v = Mat::<f64>::from_fn(m, k, |i, col| e[(i, kept[col])] / lambda(kept[col]).sqrt());
        let y = Mat::<f64>::from_fn(k, m, |row, j| e[(j, kept[row])] * lambda(kept[row]).sqrt());
        Ok(Pca {
            mean,
            a,
            v,
            y,
            class_of,
            method,
            classes: c,
        })
    }

    /// A (V W): the d × out basis for PCA-space directions W (k × out).
    fn basis(&self, w: MatRef<'_, f64>) -> Mat<f64> {
        let vw = &self.v * w;
        &self.a * vw
    }

    fn lda(&self, deviations: &[Vec<f64>], params: &FisherParams) -> Result<FisherModel> {
        let (d, m) = (self.a.nrows(), self.a.ncols());
        let (k, c) = (self.v.ncols(), self.classes);
        if deviations
            .iter()
            .any(|v| v.len() != d || v.iter().any(|x| !x.is_finite()))
        {
            return Err(Error::algorithm(
                "fisherfaces",
                "within-class deviations must be finite vectors of the samples' length",
            ));
        }
        let model = |basis: Mat<f64>| FisherModel {
            mean: self.mean.clone(),
            basis,
            method: self.method,
            pca_dims: k,
            classes: c,
            samples: m,
        };
        if self.method == Method::Eigenfaces {
            return Ok(model(self.basis(Mat::<f64>::identity(k, k).as_ref())));
        }
        let y = &self.y;
        let mut class_mean = Mat::<f64>::zeros(k, c);
        let mut count = vec![0usize; c];
        for (s, &cl) in self.class_of.iter().enumerate() {
            for i in 0..k {
                class_mean[(i, cl)] += y[(i, s)];
            }
            count[cl] += 1;
        }
        for (cl, &n) in count.iter().enumerate() {
            for i in 0..k {
                class_mean[(i, cl)] /= n as f64;
            }
        }
        // S_b = Σ n_c μ_c μ_cᵀ, as one product of the count-weighted means.
        let weighted = Mat::<f64>::from_fn(k, c, |i, cl| {
            class_mean[(i, cl)] * (count[cl] as f64).sqrt()
        });
        let sb = &weighted * weighted.transpose();
        let within =
            Mat::<f64>::from_fn(k, m, |i, s| y[(i, s)] - class_mean[(i, self.class_of[s])]);
        let mut sw = &within * within.transpose();
        if params.within_class_regularisation > 0.0 {
            let trace: f64 = (0..k).map(|i| sw[(i, i)]).sum();
            let floor = params.within_class_regularisation * trace / k as f64;
            for i in 0..k {
                sw[(i, i)] += floor;
            }
        }
        // The floor above is relative to the gallery's own scatter, so the learned deviations
        // come after it and do not raise it.
        if !deviations.is_empty() {
            let dm = Mat::<f64>::from_fn(d, deviations.len(), |i, j| deviations[j][i]);
            let p = self.v.transpose() * (self.a.transpose() * &dm); // Uᵀδ, k × n
            sw += (&p * p.transpose()) * faer::Scale(c as f64);
        }
        let singular = || {
            Error::algorithm(
                "fisherfaces",
                "within-class scatter is singular in the PCA space (duplicate samples?)",
            )
        };
        let llt = sw.llt(Side::Lower).map_err(|_| singular())?;
        let l = llt.L();
        // C = L⁻¹ S_b L⁻ᵀ, symmetric; its top eigenvectors z give W = L⁻ᵀ z.
        let mut x = sb.clone();
        solve_lower_triangular_in_place(l, x.as_mut(), Par::rayon(0));
        let mut cmat = x.transpose().to_owned();
        solve_lower_triangular_in_place(l, cmat.as_mut(), Par::rayon(0));
        let cmat = Mat::<f64>::from_fn(k, k, |i, j| 0.5 * (cmat[(i, j)] + cmat[(j, i)]));
        if cmat
            .col_iter()
            .flat_map(|col| col.iter().copied())
            .any(|v| !v.is_finite())
        {
            return Err(singular());
        }
        let e = eigen(&cmat)?;
        let out = (c - 1).min(k);
        let mut w = Mat::<f64>::from_fn(k, out, |i, col| e.U()[(i, k - 1 - col)]);
        solve_upper_triangular_in_place(l.transpose(), w.as_mut(), Par::rayon(0));
        Ok(model(self.basis(w.as_ref())))
    }
}

/// faer's symmetric eigen decomposition (eigenvalues increasing), as an algorithm error.
fn eigen(m: &Mat<f64>) -> Result<faer::linalg::solvers::SelfAdjointEigen<f64>> {
    m.self_adjoint_eigen(Side::Lower)
        .map_err(|e| Error::algorithm("fisherfaces", format!("eigen decomposition: {e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [−1, 1) (xorshift).
    fn noise(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// `classes` clusters in 200 dims: centres far apart along random directions, a large
    /// shared nuisance direction (within-class) that PCA alone would favour.
    fn clusters(classes: usize, per_class: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<usize>) {
        let mut st = seed;
        let d = 200;
        let centres: Vec<Vec<f64>> = (0..classes)
            .map(|_| (0..d).map(|_| noise(&mut st)).collect())
            .collect();
        let nuisance: Vec<f64> = (0..d).map(|_| noise(&mut st)).collect();
        let mut xs = Vec::new();
        let mut ls = Vec::new();
        for (cl, c) in centres.iter().enumerate() {
            for _ in 0..per_class {
                let t = 20.0 * noise(&mut st);
                xs.push(
                    (0..d)
                        .map(|i| c[i] + t * nuisance[i] + 0.05 * noise(&mut st))
                        .collect(),
                );
                ls.push(cl * 10 + 3);
            }
        }
        (xs, ls)
    }

    fn nearest(model: &FisherModel, gx: &[Vec<f64>], gl: &[usize], x: &[f64], m: Metric) -> usize {
        let p = model.project(x);
        let mut best = (f64::INFINITY, 0);
        for (g, &l) in gx.iter().zip(gl) {
            let dist = m.distance(&model.project(g), &p);
            if dist < best.0 {
                best = (dist, l);
            }
        }
        best.1
    }

    #[test]
    fn lda_separates_clusters_on_held_out_samples() {
        // Same seed → same centres and nuisance direction; samples 5..8 of every class in the
        // second draw are fresh, held-out samples.
        let (gx, gl) = clusters(8, 5, 7);
        let (all, all_l) = clusters(8, 8, 7);
        let model = FisherModel::train(&gx, &gl, &FisherParams::default()).unwrap();
        assert_eq!(model.method, Method::Fisherfaces);
        assert_eq!(model.pca_dims, 40 - 8);
        assert_eq!(model.dims(), 7);
        for m in [Metric::Cosine, Metric::Euclidean] {
            let held_out: Vec<usize> = (0..all.len()).filter(|k| k % 8 >= 5).collect();
            let correct = held_out
                .iter()
                .filter(|&&k| nearest(&model, &gx, &gl, &all[k], m) == all_l[k])
                .count();
            assert_eq!(
                correct,
                held_out.len(),
                "{m:?}: LDA must classify every held-out sample"
            );
        }
    }

    #[test]
    fn projected_within_class_scatter_is_identity() {
        let (gx, gl) = clusters(5, 6, 3);
        let model = FisherModel::train(&gx, &gl, &FisherParams::default()).unwrap();
        let proj: Vec<Vec<f64>> = gx.iter().map(|x| model.project(x)).collect();
        let k = model.dims();
        let mut sw = Mat::<f64>::zeros(k, k);
        for cl in 0..5 {
            let members: Vec<&Vec<f64>> =
                (0..30).filter(|&s| s / 6 == cl).map(|s| &proj[s]).collect();
            let mu: Vec<f64> = (0..k)
                .map(|i| members.iter().map(|p| p[i]).sum::<f64>() / members.len() as f64)
                .collect();
            for p in members {
                let dv = Col::<f64>::from_fn(k, |i| p[i] - mu[i]);
                sw += &dv * dv.transpose();
            }
        }
        let off = &sw - Mat::<f64>::identity(k, k);
        assert!(off.norm_max() < 1e-6, "{}", off.norm_max());
    }

    #[test]
    fn one_sample_per_class_falls_back_to_eigenfaces() {
        let (gx, gl) = clusters(6, 1, 11);
        let model = FisherModel::train(&gx, &gl, &FisherParams::default()).unwrap();
        assert_eq!(model.method, Method::Eigenfaces);
        assert_eq!(model.dims(), 5);
        // PCA basis is orthonormal.
        let g = model.basis.transpose() * &model.basis;
        assert!((&g - Mat::<f64>::identity(5, 5)).norm_max() < 1e-9);
        // A training sample is its own nearest neighbour.
        for (x, &l) in gx.iter().zip(&gl) {
            assert_eq!(nearest(&model, &gx, &gl, x, Metric::Euclidean), l);
        }
    }

    #[test]
    fn learned_deviations_teach_the_lda_a_direction_the_gallery_barely_shows() {
        // 10 classes, 4 samples each, that vary very little along a direction `e` (in the
        // gallery: an expression the synthesis makes too weakly); the within-class floor then
        // leaves `e` about as trusted as identity. Probes show `e` 40× stronger. Deviations
        // along `e` from other "people" make the LDA discount it.
        let d = 120;
        let mut st = 5u64;
        let centres: Vec<Vec<f64>> = (0..10)
            .map(|_| (0..d).map(|_| noise(&mut st)).collect())
            .collect();
        let e: Vec<f64> = (0..d).map(|_| noise(&mut st)).collect();
        let sample = |c: &[f64], t: f64, st: &mut u64| -> Vec<f64> {
            (0..d)
                .map(|i| c[i] + t * e[i] + 0.3 * noise(st))
                .collect::<Vec<f64>>()
        };
        let (mut gx, mut gl) = (Vec::new(), Vec::new());
        for (cl, c) in centres.iter().enumerate() {
            for t in [0.0, 0.1, 0.2, 0.3] {
                gx.push(sample(c, t, &mut st));
                gl.push(cl);
            }
        }
        let probes: Vec<(Vec<f64>, usize)> = centres
            .iter()
            .enumerate()
            .flat_map(|(cl, c)| {
                [
                    (sample(c, 12.0, &mut st), cl),
                    (sample(c, 15.0, &mut st), cl),
                ]
            })
            .collect();
        let deviations: Vec<Vec<f64>> = [10.0, 14.0, 18.0]
            .iter()
            .map(|t| (0..d).map(|i| t * e[i] + 0.3 * noise(&mut st)).collect())
            .collect();
        let params = FisherParams {
            within_class_regularisation: 3.0,
            ..FisherParams::default()
        };
        let correct = |model: &FisherModel| {
            probes
                .iter()
                .filter(|(x, l)| nearest(model, &gx, &gl, x, Metric::Cosine) == *l)
                .count()
        };
        let plain = FisherModel::train(&gx, &gl, &params).unwrap();
        let taught = FisherModel::train_with_deviations(&gx, &gl, &deviations, &params).unwrap();
        assert_eq!(taught.method, Method::Fisherfaces);
        assert_eq!(taught.pca_dims, plain.pca_dims);
        let (p, t) = (correct(&plain), correct(&taught));
        assert_eq!(
            t,
            probes.len(),
            "with the deviations every probe is found ({p} without)"
        );
        assert!(
            p < probes.len(),
            "the test needs probes the plain LDA misses"
        );
        // Variants sharing one PCA are the models trained one by one, in either order.
        let both = FisherModel::train_variants(&gx, &gl, &[&deviations, &[]], &params).unwrap();
        assert_eq!(both[0].basis, taught.basis);
        assert_eq!(both[1].basis, plain.basis);
        let bad = vec![vec![f64::NAN; d]];
        assert!(FisherModel::train_with_deviations(&gx, &gl, &bad, &params).is_err());
    }

    #[test]
    fn metric_properties() {
        let a = [1.0, 2.0, -3.0];
        assert_eq!(Metric::Cosine.distance(&a, &a), 0.0);
        assert_eq!(Metric::Euclidean.distance(&a, &a), 0.0);
        let b = [2.0, 4.0, -6.0];
        assert!(Metric::Cosine.distance(&a, &b).abs() < 1e-12);
        let c = [-1.0, -2.0, 3.0];
        assert!((Metric::Cosine.distance(&a, &c) - 2.0).abs() < 1e-12);
        assert!((Metric::Euclidean.distance(&[0.0, 0.0], &[3.0, 4.0]) - 5.0).abs() < 1e-12);
        assert_eq!(Metric::Cosine.distance(&[0.0; 3], &a), 1.0);
    }

    #[test]
    fn bad_input_is_an_error() {
        let (gx, _) = clusters(1, 4, 1);
        assert!(FisherModel::train(&gx, &[0, 0, 0, 0], &FisherParams::default()).is_err());
        assert!(FisherModel::train(&gx, &[0, 1], &FisherParams::default()).is_err());
    }
}
