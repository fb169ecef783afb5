//! The cached sparse Cholesky factorization of the reduced stiffness matrix (faer 0.24's
//! supernodal `L Lᵀ`, AMD ordering) and the triangular solves that reuse it.
//!
//! Like geometry-central's heat method: the symbolic analysis is done once per sparsity pattern,
//! the numeric factorization once per set of values, and every right-hand side after that is two
//! triangular solves. Refactor only when geometry, materials or fixed nodes change.
//!
//! Two choices here are measured, not assumed (this 2-core machine, the generic face, 20,058
//! DOF, 3.45 M factor entries; `facesynth bench fem`, 7 runs paired with the previous build by
//! `farm-bench`, medians on a noisy day):
//! - faer runs **sequentially** (`Par::Seq`): its rayon-parallel factorization was the slower
//!   one on 2 cores. Factorization 215 → 122 ms, factorization + 22-actuator basis
//!   323 → 160 ms (the basis splits its columns over the two cores, each half one blocked
//!   faer solve). On a quiet machine: 52–80 ms factorization, 37–53 ms basis.
//! - A **single** right-hand side (the editor re-solving one muscle) is solved by our own
//!   supernodal sweep, split over two threads along the elimination tree (see [`SolvePlan`]):
//!   one solve streams the whole factor twice (55 MB), so it is bound by memory bandwidth,
//!   which two cores raise by about 1.4× here. 9.3 → 6.2 ms median (best run 3.9 ms; 4.1–4.3 ms
//!   on a quiet machine, where faer's own sequential solve took ~5 ms).
//! - A **local** right-hand side (one muscle's load) runs the forward sweep only over the
//!   supernodes on its elimination-tree paths ([`SolvePlan::reach`]), sequentially, when that
//!   is less than the split sweep's critical path; the backward sweep stays whole. Paired
//!   `farm-bench -n 7` against the previous build: one solve 4.82 → 3.28 ms median (pair
//!   ratios 0.56–0.89), 4× elements 23.4 → 15.1 ms.
//! - Each factorization is checked by one probe solve; see [`REFINE_ABOVE_RELATIVE_RESIDUAL`].

use crate::fem::assembly::symmetric_upper_multiply;
use crate::{FemError, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymbolicCholeskyRaw, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Par, Side};
use std::ops::Range;
use std::sync::Arc;

/// A symmetric positive definite matrix's `L Lᵀ` factor, reusable for any number of solves.
#[derive(Debug, Clone)]
pub struct CachedCholesky {
    symbolic: Arc<SymbolicCholesky<usize>>,
    /// The supernodal layout and the two-thread split, when faer chose a supernodal factor.
    plan: Option<Arc<SolvePlan>>,
    /// `L`'s values in faer's layout; `None` until [`factor`](Self::factor) succeeds.
    values: Option<Vec<f64>>,
    /// The factored matrix (upper CSC), kept when its probe solve says single solves need a
    /// residual check (see [`REFINE_ABOVE_RELATIVE_RESIDUAL`]).
    matrix: Option<Arc<UpperCsc>>,
    /// The probe solve's relative residual after the last factorization.
    probe_residual: Option<f64>,
    dim: usize,
}

/// A symmetric matrix's upper triangle in CSC form.
#[derive(Debug)]
struct UpperCsc {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
}

/// `b − A x` for the upper-triangle CSC matrix `(col_ptr, row_idx, values)`.
fn residual(
    col_ptr: &[usize],
    row_idx: &[usize],
    values: &[f64],
    x: &[f64],
    b: &[f64],
) -> Vec<f64> {
    let mut r = vec![0.0; b.len()];
    symmetric_upper_multiply(col_ptr, row_idx, values, x, &mut r);
    r.iter_mut().zip(b).for_each(|(r, b)| *r = b - *r);
    r
}

impl UpperCsc {
    fn residual(&self, x: &[f64], b: &[f64]) -> Vec<f64> {
        residual(&self.col_ptr, &self.row_idx, &self.values, x, b)
    }
}

/// After each factorization one probe solve (a pseudo-random `b`) measures the relative residual
/// ‖b − K x‖ / ‖b‖ the factor achieves. Above this, every single solve checks its own
/// residual and takes one step of iterative refinement when it is above it too. The face
/// probes at ~5e-14 and skips the check (a product with K costs ~1.5 ms, a third of a solve);
/// a slender 40 × 8 × 8 cantilever (κ ~ 1e9) probes at ~1e-10 and refines.
pub const REFINE_ABOVE_RELATIVE_RESIDUAL: f64 = 1e-12;

impl CachedCholesky {
    /// Symbolic analysis (ordering, elimination tree, supernodes) of the upper-triangle CSC
    /// pattern `col_ptr`/`row_idx` (rows sorted within each column).
    pub fn analyze(dim: usize, col_ptr: &[usize], row_idx: &[usize]) -> Result<Self> {
        let pattern = SymbolicSparseColMatRef::new_checked(dim, dim, col_ptr, None, row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Upper,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| FemError::NotPositiveDefinite(format!("symbolic analysis: {e:?}")))?;
        let plan = SolvePlan::new(&symbolic).map(Arc::new);
        Ok(CachedCholesky {
            symbolic: Arc::new(symbolic),
            plan,
            values: None,
            matrix: None,
            probe_residual: None,
            dim,
        })
    }

    /// Numeric factorization of the matrix with the analysed pattern and these `values`.
    /// Errors (instead of producing NaNs later) when the matrix is not positive definite.
    pub fn factor(&mut self, col_ptr: &[usize], row_idx: &[usize], values: &[f64]) -> Result<()> {
        self.invalidate();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(FemError::NonFinite("stiffness matrix").into());
        }
        let pattern =
            SymbolicSparseColMatRef::new_checked(self.dim, self.dim, col_ptr, None, row_idx);
        let matrix = SparseColMatRef::new(pattern, values);
        let mut l_values = vec![0.0; self.symbolic.len_val()];
        let mut scratch = MemBuffer::new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        self.symbolic
            .factorize_numeric_llt(
                &mut l_values,
                matrix,
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut scratch),
                Default::default(),
            )
            .map_err(|e| FemError::NotPositiveDefinite(format!("{e:?}")))?;
        // A pseudo-random right-hand side excites every mode (a smooth one, e.g. K·1, can
        // probe far below what a point load then gets).
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let b: Vec<f64> = (0..self.dim)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let mut x = b.clone();
        self.solve_once(&l_values, &mut x);
        let probe = norm(&residual(col_ptr, row_idx, values, &x, &b)) / norm(&b);
        if !probe.is_finite() {
            return Err(FemError::NonFinite("displacement").into());
        }
        self.values = Some(l_values);
        self.probe_residual = Some(probe);
        // Only a factor that needs the check keeps a copy of the matrix.
        self.matrix = (probe > REFINE_ABOVE_RELATIVE_RESIDUAL).then(|| {
            Arc::new(UpperCsc {
                col_ptr: col_ptr.to_vec(),
                row_idx: row_idx.to_vec(),
                values: values.to_vec(),
            })
        });
        Ok(())
    }

    /// Drops the numeric factor (the matrix values changed); the symbolic analysis stays.
    pub fn invalidate(&mut self) {
        self.values = None;
        self.matrix = None;
        self.probe_residual = None;
    }

    /// Whether [`factor`](Self::factor) has succeeded since the last change.
    pub fn is_factored(&self) -> bool {
        self.values.is_some()
    }

    /// Matrix size.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Entries of the factor `L` (what one solve streams through twice).
    pub fn factor_entries(&self) -> usize {
        self.symbolic.len_val()
    }

    /// How the single-RHS solve splits the factor's entries: (serial part, each half). `None`
    /// for a simplicial factor; halves of 0 when the factor is too small to split.
    pub fn split_entries(&self) -> Option<(usize, [usize; 2])> {
        self.plan.as_ref().map(|plan| plan.split_entries())
    }

    fn l_values(&self) -> Result<&[f64]> {
        self.values
            .as_deref()
            .ok_or_else(|| FemError::Definition("solve before factor".into()).into())
    }

    /// The probe solve's relative residual after the last factorization (see
    /// [`REFINE_ABOVE_RELATIVE_RESIDUAL`]).
    pub fn probe_residual(&self) -> Option<f64> {
        self.probe_residual
    }

    /// Solves `K x = b` in place (`rhs` holds `b` on entry, `x` on exit), refined once where
    /// the factor's probe asked for it (see [`REFINE_ABOVE_RELATIVE_RESIDUAL`]).
    pub fn solve_in_place(&self, rhs: &mut [f64]) -> Result<()> {
        let l = self.l_values()?;
        assert_eq!(rhs.len(), self.dim);
        let b = self.matrix.as_ref().map(|_| rhs.to_vec());
        self.solve_once(l, rhs);
        finite(rhs)?;
        if let Some(b) = b {
            self.refine(l, rhs, &b);
            finite(rhs)?;
        }
        Ok(())
    }

    /// One step of iterative refinement of `x` for `K x = b` if its residual is above
    /// [`REFINE_ABOVE_RELATIVE_RESIDUAL`] (only for factors whose probe kept the matrix).
    fn refine(&self, l: &[f64], x: &mut [f64], b: &[f64]) {
        let Some(matrix) = &self.matrix else {
            return;
        };
        let mut r = matrix.residual(x, b);
        if norm(&r) > REFINE_ABOVE_RELATIVE_RESIDUAL * norm(b) {
            self.solve_once(l, &mut r);
            x.iter_mut().zip(&r).for_each(|(x, d)| *x += d);
        }
    }

    fn solve_once(&self, l: &[f64], rhs: &mut [f64]) {
        match &self.plan {
            Some(plan) => plan.solve(l, rhs),
            None => self.faer_solve(l, rhs, 1),
        }
    }

    /// Solves several right-hand sides stored column-major (`dim × count`) in one call.
    pub fn solve_many_in_place(&self, rhs: &mut [f64], count: usize) -> Result<()> {
        let l = self.l_values()?;
        assert_eq!(rhs.len(), self.dim * count);
        let b = self.matrix.as_ref().map(|_| rhs.to_vec());
        if count >= 2 && self.plan.as_ref().is_some_and(|p| !p.halves[0].is_empty()) {
            // Half the columns per core: each pass over `L` then serves half as many columns.
            let (a, b) = rhs.split_at_mut(self.dim * (count / 2));
            rayon::join(
                || self.faer_solve(l, a, count / 2),
                || self.faer_solve(l, b, count - count / 2),
            );
        } else {
            self.faer_solve(l, rhs, count);
        }
        finite(rhs)?;
        if let Some(b) = b {
            let n = self.dim;
            for (x, b) in rhs.chunks_exact_mut(n).zip(b.chunks_exact(n)) {
                self.refine(l, x, b);
            }
            finite(rhs)?;
        }
        Ok(())
    }

    /// faer's blocked supernodal (or simplicial) solve, sequential.
    fn faer_solve(&self, l: &[f64], rhs: &mut [f64], count: usize) {
        let mut scratch =
            MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(count, Par::Seq));
        LltRef::<usize, f64>::new(&self.symbolic, l).solve_in_place_with_conj(
            Conj::No,
            faer::MatMut::from_column_major_slice_mut(rhs, self.dim, count),
            Par::Seq,
            MemStack::new(&mut scratch),
        );
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn finite(x: &[f64]) -> Result<()> {
    if x.iter().any(|v| !v.is_finite()) {
        return Err(FemError::NonFinite("displacement").into());
    }
    Ok(())
}

/// The supernodal factor's layout (copied from faer's symbolic analysis) and a split of its
/// elimination tree into two sets of independent subtrees plus the serial part above them.
///
/// Supernode `s` holds columns `begin[s]..begin[s + 1]` of the permuted `L`, stored
/// column-major as a dense block of `width + rows.len()` rows: the lower triangle of its
/// diagonal block, then the rows below the block, whose indices `rows` all belong to ancestors
/// of `s`. faer numbers supernodes children-first, so every subtree is a contiguous range.
///
/// Forward sweep: each thread runs its subtrees on its own copy of `x`; their updates to the
/// serial part's rows are summed; then the serial part runs. Backward sweep: the serial part
/// first, then each thread its subtrees, reading only ancestor rows, which are final by then.
#[derive(Debug)]
pub struct SolvePlan {
    begin: Vec<usize>,
    row_ptr: Vec<usize>,
    val_ptr: Vec<usize>,
    rows: Vec<usize>,
    /// `perm[i]`: the original index of permuted row `i`.
    perm: Vec<usize>,
    /// Supernode ranges (whole subtrees) run by each of the two threads.
    halves: [Vec<Range<usize>>; 2],
    /// Supernodes above the split, in increasing order.
    serial: Vec<usize>,
    /// The longest below-block row list (scratch size).
    max_rows: usize,
    /// `owner[c]`: the supernode holding permuted column `c`.
    owner: Vec<usize>,
    /// Each supernode's parent in the elimination tree (`None` for a root).
    parent: Vec<Option<usize>>,
    /// Factor entries on the split forward sweep's critical path (serial part + the larger
    /// half; all entries when unsplit): a sparse right-hand side whose reach is smaller than
    /// this takes the sequential sparse sweep instead ([`SolvePlan::reach`]).
    forward_critical_entries: usize,
}

/// Below this many factor entries the two-thread split is not worth a thread hand-off.
const PARALLEL_MIN_ENTRIES: usize = 200_000;

impl SolvePlan {
    /// `None` when faer chose a simplicial factor (small or very sparse matrices).
    fn new(symbolic: &SymbolicCholesky<usize>) -> Option<SolvePlan> {
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        let n = sn.nrows();
        let count = sn.n_supernodes();
        let mut begin = sn.supernode_begin().to_vec();
        begin.push(n);
        let perm = match symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        let mut plan = SolvePlan {
            begin,
            row_ptr: sn.col_ptr_for_row_idx().to_vec(),
            val_ptr: sn.col_ptr_for_val().to_vec(),
            rows: sn.row_idx().to_vec(),
            perm,
            halves: [vec![], vec![]],
            serial: (0..count).collect(),
            max_rows: 0,
            owner: vec![0; n],
            parent: vec![None; count],
            forward_critical_entries: 0,
        };
        plan.max_rows = (0..count).map(|s| plan.below(s).len()).max().unwrap_or(0);
        for s in 0..count {
            let columns = plan.begin[s]..plan.begin[s + 1];
            plan.owner[columns].fill(s);
        }
        plan.parent = (0..count)
            .map(|s| plan.below(s).iter().min().map(|&r| plan.owner[r]))
            .collect();
        // Children-first numbering makes subtrees contiguous (the split) and increasing order
        // a valid forward order (the sparse sweep); faer numbers so, but check it.
        let children_first = (0..count).all(|s| plan.parent[s].is_none_or(|p| p > s));
        if children_first {
            if plan.val_ptr[count] >= PARALLEL_MIN_ENTRIES {
                plan.split();
            }
            let (serial, halves) = plan.split_entries();
            plan.forward_critical_entries = serial + halves[0].max(halves[1]);
        }
        Some(plan)
    }

    /// The split's factor entries: (serial part, each half); (all, [0, 0]) when unsplit.
    fn split_entries(&self) -> (usize, [usize; 2]) {
        let entries = |r: Range<usize>| self.val_ptr[r.end] - self.val_ptr[r.start];
        if self.halves[0].is_empty() {
            return (entries(0..self.count()), [0, 0]);
        }
        let serial = self.serial.iter().map(|&s| entries(s..s + 1)).sum();
        let half = |h: usize| -> usize { self.halves[h].iter().cloned().map(entries).sum() };
        (serial, [half(0), half(1)])
    }

    /// The supernodes the forward sweep must visit for a right-hand side `x` (permuted): those
    /// holding a non-zero entry and all their ancestors, in increasing (children-first) order,
    /// with their factor entries. Every other supernode's part of `L⁻¹ x` is zero, so a load
    /// on a few nodes (one muscle) touches only their elimination-tree paths.
    fn reach(&self, x: &[f64]) -> (Vec<usize>, usize) {
        let count = self.count();
        let mut marked = vec![false; count];
        for (c, _) in x.iter().enumerate().filter(|(_, v)| **v != 0.0) {
            let mut s = Some(self.owner[c]);
            while let Some(t) = s {
                if std::mem::replace(&mut marked[t], true) {
                    break;
                }
                s = self.parent[t];
            }
        }
        let visit: Vec<usize> = (0..count).filter(|&s| marked[s]).collect();
        let entries = visit
            .iter()
            .map(|&s| self.val_ptr[s + 1] - self.val_ptr[s])
            .sum();
        (visit, entries)
    }

    fn count(&self) -> usize {
        self.begin.len() - 1
    }

    fn below(&self, s: usize) -> &[usize] {
        &self.rows[self.row_ptr[s]..self.row_ptr[s + 1]]
    }

    /// Chooses the two halves: start from the roots and keep opening the heaviest subtree
    /// (its root joins the serial part) while that lowers `serial + max(half)`, the solve's
    /// critical path in factor entries. The halves are filled largest-first.
    fn split(&mut self) {
        let count = self.count();
        let parent = &self.parent;
        let mut first = (0..count).collect::<Vec<_>>();
        let mut work: Vec<usize> = (0..count)
            .map(|s| self.val_ptr[s + 1] - self.val_ptr[s])
            .collect();
        let mut children = vec![vec![]; count];
        for s in 0..count {
            if let Some(p) = parent[s] {
                first[p] = first[p].min(first[s]);
                work[p] += work[s];
                children[p].push(s);
            }
        }
        let own = |s: usize| self.val_ptr[s + 1] - self.val_ptr[s];
        let assign = |frontier: &[usize]| {
            let mut sorted = frontier.to_vec();
            sorted.sort_by_key(|&s| std::cmp::Reverse(work[s]));
            let mut halves: [Vec<usize>; 2] = [vec![], vec![]];
            let mut load = [0usize; 2];
            for s in sorted {
                let h = if load[0] <= load[1] { 0 } else { 1 };
                load[h] += work[s];
                halves[h].push(s);
            }
            (halves, load)
        };
        let mut frontier: Vec<usize> = (0..count).filter(|&s| parent[s].is_none()).collect();
        let mut opened = vec![];
        let mut serial_work = 0;
        let mut best: Option<(usize, Vec<usize>, [Vec<usize>; 2])> = None;
        for _ in 0..count.min(256) {
            let (halves, load) = assign(&frontier);
            let cost = serial_work + load[0].max(load[1]);
            if best.as_ref().is_none_or(|(c, ..)| cost < *c) {
                best = Some((cost, opened.clone(), halves));
            }
            let Some((i, _)) = frontier.iter().enumerate().max_by_key(|&(_, &s)| work[s]) else {
                break;
            };
            let s = frontier.swap_remove(i);
            serial_work += own(s);
            opened.push(s);
            frontier.extend(children[s].iter().copied());
        }
        let Some((_, mut serial, halves)) = best else {
            return;
        };
        if halves.iter().any(|h| h.is_empty()) {
            return;
        }
        serial.sort_unstable();
        self.serial = serial;
        self.halves = halves.map(|roots| roots.iter().map(|&s| first[s]..s + 1).collect());
    }

    /// `L Lᵀ x = b` in place.
    fn solve(&self, l: &[f64], rhs: &mut [f64]) {
        let mut x: Vec<f64> = self.perm.iter().map(|&p| rhs[p]).collect();
        let mut tmp = vec![0.0; self.max_rows];
        let split = !self.halves[0].is_empty();
        let (visit, reach_entries) = self.reach(&x);
        if reach_entries < self.forward_critical_entries {
            // Sparse right-hand side: the forward sweep only along its elimination-tree paths
            // (sequential; it beats the split sweep's critical path).
            visit
                .iter()
                .for_each(|&s| self.forward(l, s, &mut x, &mut tmp));
        } else if split {
            self.forward_split(l, &mut x, &mut tmp);
        } else {
            // Unsplit, the serial part is every supernode.
            self.serial
                .iter()
                .for_each(|&s| self.forward(l, s, &mut x, &mut tmp));
        }
        self.serial
            .iter()
            .rev()
            .for_each(|&s| self.backward(l, s, &mut x, &mut tmp));
        if split {
            self.backward_split(l, &mut x);
        }
        for (i, &p) in self.perm.iter().enumerate() {
            rhs[p] = x[i];
        }
    }

    fn columns<'a>(
        &'a self,
        ranges: &'a [Range<usize>],
    ) -> impl Iterator<Item = Range<usize>> + 'a {
        ranges
            .iter()
            .map(|r| self.begin[r.start]..self.begin[r.end])
    }

    fn forward_split(&self, l: &[f64], x: &mut [f64], tmp: &mut [f64]) {
        let serial_rows = || {
            self.serial
                .iter()
                .map(|&s| self.begin[s]..self.begin[s + 1])
        };
        let run = |half: &[Range<usize>]| {
            // The serial rows start at 0, so each half returns only its own updates to them
            // (adding them to x keeps the sequential sweep's rounding, unlike a + b − x).
            let mut own = x.to_vec();
            serial_rows().for_each(|rows| own[rows].fill(0.0));
            let mut tmp = vec![0.0; self.max_rows];
            for r in half {
                r.clone()
                    .for_each(|s| self.forward(l, s, &mut own, &mut tmp));
            }
            own
        };
        let (a, b) = rayon::join(|| run(&self.halves[0]), || run(&self.halves[1]));
        for i in serial_rows().flatten() {
            x[i] += a[i] + b[i];
        }
        for (h, own) in [&a, &b].into_iter().enumerate() {
            for cols in self.columns(&self.halves[h]) {
                x[cols.clone()].copy_from_slice(&own[cols]);
            }
        }
        self.serial.iter().for_each(|&s| self.forward(l, s, x, tmp));
    }

    fn backward_split(&self, l: &[f64], x: &mut [f64]) {
        let run = |half: &[Range<usize>]| {
            let mut own = x.to_vec();
            let mut tmp = vec![0.0; self.max_rows];
            for r in half.iter().rev() {
                r.clone()
                    .rev()
                    .for_each(|s| self.backward(l, s, &mut own, &mut tmp));
            }
            own
        };
        let (a, b) = rayon::join(|| run(&self.halves[0]), || run(&self.halves[1]));
        for (h, own) in [&a, &b].into_iter().enumerate() {
            for cols in self.columns(&self.halves[h]) {
                x[cols.clone()].copy_from_slice(&own[cols]);
            }
        }
    }

    /// Supernode `s`'s block: (first column, width, below-block rows, column-major values).
    fn block<'a>(&'a self, l: &'a [f64], s: usize) -> (usize, usize, &'a [usize], &'a [f64]) {
        let start = self.begin[s];
        let width = self.begin[s + 1] - start;
        (
            start,
            width,
            self.below(s),
            &l[self.val_ptr[s]..self.val_ptr[s + 1]],
        )
    }

    /// Forward step `L_s y = x` for supernode `s`, then the update of the rows below.
    fn forward(&self, l: &[f64], s: usize, x: &mut [f64], tmp: &mut [f64]) {
        let (start, width, below, vals) = self.block(l, s);
        let m = width + below.len();
        let xs = &mut x[start..start + width];
        for j in 0..width {
            let col = &vals[j * m..j * m + width];
            let xj = xs[j] / col[j];
            xs[j] = xj;
            for (xi, lij) in xs[j + 1..].iter_mut().zip(&col[j + 1..]) {
                *xi -= lij * xj;
            }
        }
        let tmp = &mut tmp[..below.len()];
        tmp.fill(0.0);
        // Four columns per pass over `tmp`: the loop then streams `L` at memory speed.
        let mut j = 0;
        while j + 4 <= width {
            let c = |k: usize| &vals[(j + k) * m + width..(j + k + 1) * m];
            let (c0, c1, c2, c3) = (c(0), c(1), c(2), c(3));
            let (x0, x1, x2, x3) = (xs[j], xs[j + 1], xs[j + 2], xs[j + 3]);
            for i in 0..tmp.len() {
                tmp[i] += c0[i] * x0 + c1[i] * x1 + c2[i] * x2 + c3[i] * x3;
            }
            j += 4;
        }
        for (k, &xk) in xs.iter().enumerate().skip(j) {
            let c = &vals[k * m + width..(k + 1) * m];
            for (t, lik) in tmp.iter_mut().zip(c) {
                *t += lik * xk;
            }
        }
        for (t, &r) in tmp.iter().zip(below) {
            x[r] -= t;
        }
    }

    /// Backward step `L_sᵀ x = y − (rows below)ᵀ x_below` for supernode `s`.
    fn backward(&self, l: &[f64], s: usize, x: &mut [f64], tmp: &mut [f64]) {
        let (start, width, below, vals) = self.block(l, s);
        let m = width + below.len();
        let tmp = &mut tmp[..below.len()];
        for (t, &r) in tmp.iter_mut().zip(below) {
            *t = x[r];
        }
        let xs = &mut x[start..start + width];
        let mut j = 0;
        while j + 4 <= width {
            let c = |k: usize| &vals[(j + k) * m + width..(j + k + 1) * m];
            let (c0, c1, c2, c3) = (c(0), c(1), c(2), c(3));
            // Two partial sums per column (even and odd rows), as a SIMD dot would keep.
            let mut acc = [[0.0; 4]; 2];
            for (i, &t) in tmp.iter().enumerate() {
                let a = &mut acc[i & 1];
                a[0] += c0[i] * t;
                a[1] += c1[i] * t;
                a[2] += c2[i] * t;
                a[3] += c3[i] * t;
            }
            for k in 0..4 {
                xs[j + k] -= acc[0][k] + acc[1][k];
            }
            j += 4;
        }
        for k in j..width {
            xs[k] -= dot(&vals[k * m + width..(k + 1) * m], tmp);
        }
        for j in (0..width).rev() {
            let col = &vals[j * m..j * m + width];
            let xj = (xs[j] - dot(&col[j + 1..], &xs[j + 1..])) / col[j];
            xs[j] = xj;
        }
    }
}

/// Dot product with four partial sums (one sum is bound by the add latency, not memory).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2D grid of 3-DOF nodes, each coupled to its 8 neighbours (diagonally dominant, so
    /// SPD): its elimination tree branches like the face's, so the plan can split it.
    fn grid(side: usize) -> (usize, Vec<usize>, Vec<usize>, Vec<f64>) {
        let n = 3 * side * side;
        let (mut col_ptr, mut row_idx, mut values) = (vec![0], vec![], vec![]);
        for j in 0..n {
            let (nj, dj) = (j / 3, j % 3);
            let (aj, bj) = (nj / side, nj % side);
            for i in j.saturating_sub(3 * (side + 2))..=j {
                let (ni, di) = (i / 3, i % 3);
                let (ai, bi) = (ni / side, ni % side);
                if ai.abs_diff(aj) > 1 || bi.abs_diff(bj) > 1 {
                    continue;
                }
                row_idx.push(i);
                values.push(if i == j {
                    30.0
                } else {
                    -1.0 / (1.0 + (di + dj + ai + bi) as f64 % 3.0)
                });
            }
            col_ptr.push(row_idx.len());
        }
        (n, col_ptr, row_idx, values)
    }

    #[test]
    fn the_split_single_solve_matches_faer_and_solves_the_system() {
        let (n, cp, ri, v) = grid(60);
        let mut chol = CachedCholesky::analyze(n, &cp, &ri).unwrap();
        chol.factor(&cp, &ri, &v).unwrap();
        let plan = chol.plan.as_ref().expect("supernodal");
        // Well conditioned: the probe needs no refinement, so this compares the bare sweeps.
        assert!(chol.probe_residual().unwrap() < REFINE_ABOVE_RELATIVE_RESIDUAL);
        assert!(!plan.halves[0].is_empty() && !plan.halves[1].is_empty());
        let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
        solves_like_faer(&chol, (&cp, &ri, &v), &b);
    }

    /// Our single-RHS solve of `b` has a tight residual and matches faer's blocked solve;
    /// returns the largest |x| of faer's answer (the comparison's scale).
    fn solves_like_faer(
        chol: &CachedCholesky,
        (cp, ri, v): (&[usize], &[usize], &[f64]),
        b: &[f64],
    ) -> f64 {
        let mut ours = b.to_vec();
        chol.solve_in_place(&mut ours).unwrap();
        let mut theirs = b.to_vec();
        chol.solve_many_in_place(&mut theirs, 1).unwrap();
        assert!(norm(&residual(cp, ri, v, &ours, b)) / norm(b) < 1e-13);
        let scale = theirs.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (a, t) in ours.iter().zip(&theirs) {
            assert!((a - t).abs() <= 1e-12 * scale);
        }
        scale
    }

    #[test]
    fn a_local_load_takes_the_sparse_forward_sweep_and_gives_the_same_answer() {
        let (n, cp, ri, v) = grid(60);
        let mut chol = CachedCholesky::analyze(n, &cp, &ri).unwrap();
        chol.factor(&cp, &ri, &v).unwrap();
        let plan = chol.plan.as_ref().expect("supernodal");
        // A load on three DOFs of one corner node, as a muscle loads a few skin nodes.
        let mut b = vec![0.0; n];
        b[..3].copy_from_slice(&[1.0, -2.0, 0.5]);
        let permuted: Vec<f64> = plan.perm.iter().map(|&p| b[p]).collect();
        let (visit, entries) = plan.reach(&permuted);
        assert!(entries < plan.forward_critical_entries, "{entries}");
        assert!(visit.windows(2).all(|w| w[0] < w[1]) && visit.len() < plan.count());
        // Every supernode with a non-zero right-hand side is visited, with its ancestors.
        for &s in &visit {
            assert!(plan.parent[s].is_none_or(|p| visit.binary_search(&p).is_ok()));
        }
        assert!(solves_like_faer(&chol, (&cp, &ri, &v), &b) > 0.0);
        // A load everywhere reaches every supernode (the split dense sweep then runs).
        let full: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
        assert_eq!(plan.reach(&full).0.len(), plan.count());
    }
}
