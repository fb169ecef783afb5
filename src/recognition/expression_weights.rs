//! Expression weights (ours, beside the paper's Fisherfaces): the synthetic expressions tell
//! *where* a face changes with expression, even where they do not reproduce *how* a real
//! expression changes it, so the range-image samples they move most count least.
//!
//! For every sample k of the range image, σ²_k is the mean squared change that the synthetic
//! expressions make there, `synthetic − its own gallery scan`, over all synthetic gallery
//! samples; it is taken as the median over the sample's 3 × 3 neighbourhood, so a single sample
//! that hole filling set differently in two images does not get a weight of its own. The weight
//! is
//!
//! ```text
//! w_k = 1 / sqrt(1 + σ²_k / s²)        s = ExpressionWeightParams::scale_mm
//! ```
//!
//! — 1 where the expressions do not move the face, about `s / σ_k` where they move it by much
//! more than `s`: a diagonal whitening by the expressions' own spread. Every range image (the
//! gallery, its synthetic expressions, learned deviations and the probes) is multiplied by `w`
//! before Fisherfaces. The LDA already whitens the within-class scatter, but only inside the
//! span of the gallery samples: a probe's real laugh or gesture differs from the FEM's in
//! directions that span does not hold, and those pass unweighted. The weights damp every
//! change in the regions that expressions move (mouth, cheeks, jaw; the nose and the upper
//! forehead keep 0.6–1), whatever its direction.
//!
//! The weights exist only with synthetic expressions; a gallery of neutral scans alone is
//! scored unweighted, as the paper does. Measured gains in rank-1, the full table and the
//! choice of `s`: `docs/measurements.md`, "Recognition protocol" and "Figures moved from the
//! code's comments".

use super::range_image::{RangeImageParams, neighbourhood_median};
use super::sample::Sample;
use crate::{Error, Result};
use serde::Serialize;
use std::collections::HashMap;

/// Parameters of [`expression_weights`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ExpressionWeightParams {
    /// `s`, mm (> 0): a sample the expressions move by an RMS of `s` gets weight 1/√2.
    /// Default 0.5 mm (a few times the scanner noise; measured on two 61-subject sets,
    /// 0.1–0.5 mm give rank-1 91.4–92.2 %, 1 mm 90.2 / 89.3 %, 2 mm 88.1 %).
    pub scale_mm: f64,
}

impl Default for ExpressionWeightParams {
    fn default() -> Self {
        ExpressionWeightParams { scale_mm: 0.5 }
    }
}

impl ExpressionWeightParams {
    pub fn validate(&self) -> Result<()> {
        if !(self.scale_mm > 0.0 && self.scale_mm.is_finite()) {
            return Err(Error::algorithm(
                "expression weights",
                format!("scale_mm must be > 0, got {}", self.scale_mm),
            ));
        }
        Ok(())
    }
}

/// The weight of every range-image sample (row-major, `range.len()` long) from the synthetic
/// samples and the gallery scans they were made from (matched by subject). `None` when no
/// synthetic sample has a gallery scan of its subject.
pub fn expression_weights(
    gallery: &[Sample],
    synthetic: &[Sample],
    range: &RangeImageParams,
    params: &ExpressionWeightParams,
) -> Result<Option<Vec<f64>>> {
    params.validate()?;
    let n = range.len();
    let neutral: HashMap<&str, &[f64]> = gallery
        .iter()
        .map(|g| (g.subject.as_str(), g.features.as_slice()))
        .collect();
    let mut sum = vec![0.0; n];
    let mut count = 0usize;
    for s in synthetic {
        let Some(g) = neutral.get(s.subject.as_str()) else {
            continue;
        };
        if s.features.len() != n || g.len() != n {
            return Err(Error::algorithm(
                "expression weights",
                format!(
                    "{}: {} samples, the range image has {n}",
                    s.path.display(),
                    s.features.len()
                ),
            ));
        }
        for ((acc, a), b) in sum.iter_mut().zip(&s.features).zip(g.iter()) {
            *acc += (a - b) * (a - b);
        }
        count += 1;
    }
    if count == 0 {
        return Ok(None);
    }
    let variance: Vec<f64> = sum.iter().map(|s| s / count as f64).collect();
    let variance = median_3x3(&variance, range.cols, range.rows);
    let s2 = params.scale_mm * params.scale_mm;
    Ok(Some(
        variance
            .iter()
            .map(|v| 1.0 / (1.0 + v / s2).sqrt())
            .collect(),
    ))
}

/// Multiplies `features` by `weights` sample by sample.
pub fn apply(weights: &[f64], features: &mut [f64]) {
    debug_assert_eq!(weights.len(), features.len());
    for (f, w) in features.iter_mut().zip(weights) {
        *f *= w;
    }
}

/// `features` multiplied by `weights` sample by sample.
pub fn weighted(weights: &[f64], features: &[f64]) -> Vec<f64> {
    let mut out = features.to_vec();
    apply(weights, &mut out);
    out
}

/// Median of each value's 3 × 3 neighbourhood (fewer at the borders) on a `cols × rows` grid.
fn median_3x3(values: &[f64], cols: usize, rows: usize) -> Vec<f64> {
    let mut window = Vec::with_capacity(9);
    (0..rows)
        .flat_map(|j| (0..cols).map(move |i| (i, j)))
        .map(|ij| neighbourhood_median(values, (cols, rows), ij, 1, &mut window))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn sample(subject: &str, features: Vec<f64>) -> Sample {
        Sample {
            subject: subject.into(),
            kind: "synthetic".into(),
            path: PathBuf::from(format!("{subject}.ply")),
            features,
        }
    }

    fn grid(cols: usize, rows: usize) -> RangeImageParams {
        RangeImageParams {
            cols,
            rows,
            ..RangeImageParams::default()
        }
    }

    #[test]
    fn weights_follow_the_expressions_spread() {
        // 6 × 5 grid; the expressions move the lower 2 rows by ±1 mm and ±3 mm, nothing else.
        let (cols, rows) = (6, 5);
        let range = grid(cols, rows);
        let neutral_a: Vec<f64> = (0..cols * rows).map(|k| k as f64).collect();
        let neutral_b: Vec<f64> = (0..cols * rows).map(|k| -(k as f64)).collect();
        let moved = |base: &[f64], d: f64| -> Vec<f64> {
            base.iter()
                .enumerate()
                .map(|(k, z)| if k / cols >= 3 { z + d } else { *z })
                .collect()
        };
        let gallery = vec![
            sample("a", neutral_a.clone()),
            sample("b", neutral_b.clone()),
        ];
        let synthetic = vec![
            sample("a", moved(&neutral_a, 1.0)),
            sample("b", moved(&neutral_b, -3.0)),
        ];
        let params = ExpressionWeightParams { scale_mm: 0.5 };
        let w = expression_weights(&gallery, &synthetic, &range, &params)
            .unwrap()
            .unwrap();
        // σ² = (1 + 9) / 2 = 5 mm² in rows 3–4 (the 3×3 median keeps a 2-row band), 0 above.
        let expected = 1.0 / (1.0f64 + 5.0 / 0.25).sqrt();
        for (k, wk) in w.iter().enumerate() {
            let want = if k / cols >= 3 { expected } else { 1.0 };
            assert!((wk - want).abs() < 1e-12, "sample {k}: {wk} vs {want}");
        }
    }

    #[test]
    fn a_lone_hole_sample_does_not_get_its_own_weight() {
        let (cols, rows) = (5, 5);
        let range = grid(cols, rows);
        let neutral = vec![0.0; cols * rows];
        let mut expr = neutral.clone();
        expr[2 * cols + 2] = 20.0; // one sample filled differently
        let w = expression_weights(
            &[sample("a", neutral)],
            &[sample("a", expr)],
            &range,
            &ExpressionWeightParams::default(),
        )
        .unwrap()
        .unwrap();
        assert!(w.iter().all(|&x| x == 1.0));
    }

    #[test]
    fn no_matching_gallery_scan_means_no_weights() {
        let range = grid(3, 3);
        let w = expression_weights(
            &[sample("a", vec![0.0; 9])],
            &[sample("b", vec![1.0; 9])],
            &range,
            &ExpressionWeightParams::default(),
        )
        .unwrap();
        assert!(w.is_none());
    }

    #[test]
    fn a_bad_scale_is_refused() {
        let range = grid(3, 3);
        for s in [0.0, -1.0, f64::NAN] {
            let e = expression_weights(&[], &[], &range, &ExpressionWeightParams { scale_mm: s });
            assert!(e.is_err(), "scale {s} accepted");
        }
    }
}
