//! The cached sparse Cholesky factorization of the reduced stiffness matrix (faer 0.24,
//! supernodal/simplicial chosen by faer, AMD ordering).
//!
//! Like geometry-central's heat method: the symbolic analysis is done once per sparsity pattern,
//! the numeric factorization once per set of values, and every right-hand side after that is two
//! triangular solves. Refactor only when geometry, materials or fixed nodes change.

use crate::{FemError, Result};
use faer::Side;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

/// A symmetric positive definite matrix's `L Lᵀ` factor, reusable for any number of solves.
#[derive(Debug, Clone)]
pub struct CachedCholesky {
    symbolic: SymbolicLlt<usize>,
    numeric: Option<Llt<usize, f64>>,
    dim: usize,
}

impl CachedCholesky {
    /// Symbolic analysis (ordering, elimination tree, supernodes) of the upper-triangle CSC
    /// pattern `col_ptr`/`row_idx` (rows sorted within each column).
    pub fn analyze(dim: usize, col_ptr: &[usize], row_idx: &[usize]) -> Result<Self> {
        let pattern = SymbolicSparseColMatRef::new_checked(dim, dim, col_ptr, None, row_idx);
        let symbolic = SymbolicLlt::try_new(pattern, Side::Upper)
            .map_err(|e| FemError::NotPositiveDefinite(format!("symbolic analysis: {e:?}")))?;
        Ok(CachedCholesky {
            symbolic,
            numeric: None,
            dim,
        })
    }

    /// Numeric factorization of the matrix with the analysed pattern and these `values`.
    /// Errors (instead of producing NaNs later) when the matrix is not positive definite.
    pub fn factor(&mut self, col_ptr: &[usize], row_idx: &[usize], values: &[f64]) -> Result<()> {
        self.numeric = None;
        if values.iter().any(|v| !v.is_finite()) {
            return Err(FemError::NonFinite("stiffness matrix").into());
        }
        let pattern =
            SymbolicSparseColMatRef::new_checked(self.dim, self.dim, col_ptr, None, row_idx);
        let matrix = SparseColMatRef::new(pattern, values);
        let llt = Llt::try_new_with_symbolic(self.symbolic.clone(), matrix, Side::Upper)
            .map_err(|e| FemError::NotPositiveDefinite(format!("{e:?}")))?;
        self.numeric = Some(llt);
        Ok(())
    }

    /// Drops the numeric factor (the matrix values changed); the symbolic analysis stays.
    pub fn invalidate(&mut self) {
        self.numeric = None;
    }

    /// Whether [`factor`](Self::factor) has succeeded since the last change.
    pub fn is_factored(&self) -> bool {
        self.numeric.is_some()
    }

    /// Matrix size.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Solves `K x = b` in place (`rhs` holds `b` on entry, `x` on exit).
    pub fn solve_in_place(&self, rhs: &mut [f64]) -> Result<()> {
        let llt = self
            .numeric
            .as_ref()
            .ok_or(FemError::Definition("solve before factor".into()))?;
        assert_eq!(rhs.len(), self.dim);
        llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(rhs, self.dim, 1));
        if rhs.iter().any(|v| !v.is_finite()) {
            return Err(FemError::NonFinite("displacement").into());
        }
        Ok(())
    }

    /// Solves several right-hand sides stored column-major (`dim × count`) in one call.
    pub fn solve_many_in_place(&self, rhs: &mut [f64], count: usize) -> Result<()> {
        let llt = self
            .numeric
            .as_ref()
            .ok_or(FemError::Definition("solve before factor".into()))?;
        assert_eq!(rhs.len(), self.dim * count);
        llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(
            rhs, self.dim, count,
        ));
        if rhs.iter().any(|v| !v.is_finite()) {
            return Err(FemError::NonFinite("displacement").into());
        }
        Ok(())
    }
}
