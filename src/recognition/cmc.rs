//! Cumulative Match Characteristic (paper section 4, Figure 16): the fraction of probes whose
//! true identity is among the `r` closest gallery identities, for r = 1 … N (N gallery
//! identities). Ties count against the probe: rank = 1 + the number of other identities at a
//! distance ≤ the true identity's.

use serde::Serialize;
use std::collections::BTreeMap;

/// The rank (1-based) of `truth` among `distances` (one per gallery identity, smaller =
/// closer). Ties are pessimistic.
pub fn rank_of(distances: &[f64], truth: usize) -> usize {
    let d = distances[truth];
    1 + distances
        .iter()
        .enumerate()
        .filter(|&(k, &x)| k != truth && !(x > d))
        .count()
}

/// CMC curve from 1-based ranks: `curve[r − 1]` = fraction of ranks ≤ r, for r = 1 … `n`.
/// Non-decreasing; reaches 1 at r = n when every rank is ≤ n. Empty input gives zeros.
pub fn cmc_curve(ranks: &[usize], n: usize) -> Vec<f64> {
    let mut hist = vec![0usize; n];
    for &r in ranks {
        if (1..=n).contains(&r) {
            hist[r - 1] += 1;
        }
    }
    let total = ranks.len().max(1) as f64;
    let mut acc = 0usize;
    (0..n)
        .map(|r| {
            acc += hist[r];
            acc as f64 / total
        })
        .collect()
}

/// Recognition rates of one probe set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rates {
    pub probes: usize,
    /// Fraction recognised at rank 1.
    pub rank1: f64,
    /// Fraction recognised within the 5 best (rank ≤ min(5, N)).
    pub rank5: f64,
    /// CMC, rank 1 … N.
    pub cmc: Vec<f64>,
}

impl Rates {
    pub fn from_ranks(ranks: &[usize], n: usize) -> Rates {
        let cmc = cmc_curve(ranks, n);
        Rates {
            probes: ranks.len(),
            rank1: cmc.first().copied().unwrap_or(0.0),
            rank5: cmc.get(4.min(n.saturating_sub(1))).copied().unwrap_or(0.0),
            cmc,
        }
    }
}

/// Rates over all probes and per probe kind (`frontal2`, `sonrisa`, …).
pub fn rates_by_kind(ranks: &[(String, usize)], n: usize) -> (Rates, BTreeMap<String, Rates>) {
    let all: Vec<usize> = ranks.iter().map(|(_, r)| *r).collect();
    let mut by: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (kind, r) in ranks {
        by.entry(kind.clone()).or_default().push(*r);
    }
    (
        Rates::from_ranks(&all, n),
        by.into_iter()
            .map(|(k, v)| (k, Rates::from_ranks(&v, n)))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_counts_ties_against_the_probe() {
        assert_eq!(rank_of(&[0.5, 0.1, 0.9], 1), 1);
        assert_eq!(rank_of(&[0.5, 0.1, 0.9], 0), 2);
        assert_eq!(rank_of(&[0.5, 0.1, 0.9], 2), 3);
        assert_eq!(rank_of(&[0.3, 0.3, 0.3], 0), 3);
    }

    #[test]
    fn curve_is_monotone_and_reaches_one() {
        let ranks = [1, 1, 2, 5, 3, 1, 10, 4];
        let c = cmc_curve(&ranks, 10);
        assert_eq!(c.len(), 10);
        assert!(c.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(c[0], 3.0 / 8.0);
        assert_eq!(c[9], 1.0);
        let r = Rates::from_ranks(&ranks, 10);
        assert_eq!(r.rank5, 7.0 / 8.0);
    }

    #[test]
    fn by_kind_splits_probes() {
        let ranks = vec![
            ("a".to_string(), 1),
            ("b".to_string(), 2),
            ("a".to_string(), 3),
        ];
        let (all, by) = rates_by_kind(&ranks, 3);
        assert_eq!(all.probes, 3);
        assert_eq!(by["a"].probes, 2);
        assert_eq!(by["a"].rank1, 0.5);
        assert_eq!(by["b"].rank1, 0.0);
        assert_eq!(by["b"].cmc, vec![0.0, 1.0, 1.0]);
    }
}
