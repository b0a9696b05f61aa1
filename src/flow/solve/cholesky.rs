//! Sparse Cholesky factors through faer's low-level API, so that many factorizations can run
//! in parallel under rayon, each single-threaded (`Par::Seq`), sharing one symbolic analysis.

use crate::fem::SparseMatrixRef;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::SymbolicSparseColMatRef;
use faer::{Conj, MatMut, Par, Side};
use std::sync::Arc;

/// The symbolic analysis (AMD ordering, elimination tree, fill) of a sparsity pattern.
pub fn analyze(pattern: SymbolicSparseColMatRef<'_, usize>) -> Arc<SymbolicCholesky<usize>> {
    let symbolic =
        factorize_symbolic_cholesky(pattern, Side::Lower, Default::default(), Default::default())
            .expect("symbolic Cholesky needs only memory");
    Arc::new(symbolic)
}

/// `L Lᵀ = A` for one symmetric positive definite matrix with the analysed pattern.
pub struct CholeskyFactor {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl CholeskyFactor {
    /// Factors `matrix`; `Err` carries faer's reason when it is not numerically positive definite.
    pub fn new(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
        par: Par,
    ) -> Result<Self, String> {
        let mut values = vec![0.0; symbolic.len_val()];
        let scratch = symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default());
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut values,
                matrix,
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut MemBuffer::new(scratch)),
                Default::default(),
            )
            .map_err(|e| format!("{e:?}"))?;
        Ok(Self {
            symbolic: symbolic.clone(),
            values,
        })
    }

    /// Overwrites `x` with `A⁻¹ x`.
    pub fn solve_in_place(&self, x: &mut [f64], par: Par) {
        let n = x.len();
        let scratch = self.symbolic.solve_in_place_scratch::<f64>(1, par);
        LltRef::<'_, usize, f64>::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, n, 1),
            par,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
    }

    /// Stored entries of `L`.
    pub fn stored_entries(&self) -> usize {
        self.values.len()
    }
}
