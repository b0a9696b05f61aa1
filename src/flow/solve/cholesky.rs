//! Sparse Cholesky factors through faer's low-level API, so that many factorizations can run
//! in parallel under rayon, each single-threaded (`Par::Seq`), sharing one symbolic analysis.

use crate::fem::SparseMatrixRef;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use std::sync::Arc;

/// The symbolic analysis (AMD ordering, elimination tree, fill) of a sparsity pattern.
pub fn analyze(pattern: SymbolicSparseColMatRef<'_, usize>) -> Arc<SymbolicCholesky<usize>> {
    let symbolic =
        factorize_symbolic_cholesky(pattern, Side::Lower, Default::default(), Default::default())
            .expect("symbolic Cholesky needs only memory");
    Arc::new(symbolic)
}

/// A floating-point type the factors can be stored in; the system stays in `f64`.
pub trait Precision: faer::traits::ComplexField + Copy {
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
}

impl Precision for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
}

impl Precision for f32 {
    fn from_f64(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
}

/// `L Lᵀ = A` for one symmetric positive definite matrix with the analysed pattern, stored in
/// precision `T` (`f32` halves the memory and the memory traffic of a preconditioner's solves).
pub struct CholeskyFactor<T = f64> {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<T>,
}

impl<T: Precision> CholeskyFactor<T> {
    /// Factors `matrix` (rounded to `T`); `Err` carries faer's reason when it is not
    /// numerically positive definite.
    pub fn new(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
        par: Par,
    ) -> Result<Self, String> {
        let (pattern, entries) = matrix.parts();
        let rounded: Vec<T> = entries.iter().map(|&v| T::from_f64(v)).collect();
        let mut values = vec![T::from_f64(0.0); symbolic.len_val()];
        let scratch = symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default());
        symbolic
            .factorize_numeric_llt::<T>(
                &mut values,
                SparseColMatRef::new(pattern, &rounded),
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

    /// Overwrites `x` with `A⁻¹ x` (computed in precision `T`).
    pub fn solve_in_place(&self, x: &mut [f64], par: Par) {
        let n = x.len();
        let mut rhs: Vec<T> = x.iter().map(|&v| T::from_f64(v)).collect();
        let scratch = self.symbolic.solve_in_place_scratch::<T>(1, par);
        LltRef::<'_, usize, T>::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut rhs, n, 1),
            par,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
        x.iter_mut().zip(&rhs).for_each(|(x, r)| *x = r.to_f64());
    }

    /// Stored entries of `L`.
    pub fn stored_entries(&self) -> usize {
        self.values.len()
    }
}
