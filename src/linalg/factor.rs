//! The factors a preconditioner's slab solves use, by the precision they are stored in:
//! [`SlabFactor`] over faer's `f64` and `f32` factors and the bfloat16 ones of
//! [`super::bfloat`].
//!
//! A slab sweep solves with every factor once per half sweep, one thread per solve, and its
//! time is what the factors' bytes take to stream from memory. `f32` factors are exact enough
//! that slab Gauss–Seidel converges as with `f64`; bfloat16 reads half as much and leaves
//! multigrid in time's iterations as they were, but costs slab Gauss–Seidel iterations where the
//! slab solves alone almost solve the system (large `α`): its rounding, about `2⁻⁹` per entry,
//! is then what the iterations reduce. So each kind of factor says which one multigrid uses
//! ([`SlabFactor::Compressed`]).

use super::bfloat::Bf16Factor;
use super::cholesky::{CholeskyFactor, FactorEntries, Precision, SparseMatrixRef};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::Par;
use std::cell::Cell;
use std::sync::Arc;

/// A factor that a preconditioner solves with, one thread per solve.
pub trait SlabFactor: Sized + Send + Sync {
    /// Bytes each stored entry of `L` takes.
    const ENTRY_BYTES: usize;
    /// Bytes one factor of the analysed pattern takes at most (the memory budget's unit).
    fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        symbolic.len_val() * Self::ENTRY_BYTES
    }
    /// How the entries are stored, for the solver's reasons.
    const NAME: &'static str;
    /// The factor multigrid's levels use when slab Gauss–Seidel started with this one.
    type Compressed: SlabFactor;
    /// Factors `matrix`, single-threaded; `Err` carries the reason it is not numerically
    /// positive definite.
    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
    ) -> Result<Self, String>;
    /// `x ← A⁻¹ x`, single-threaded.
    fn solve(&self, x: &mut [f64]);
    fn entries(&self) -> FactorEntries;
    fn compress(self) -> Self::Compressed;
}

/// What a precision of faer's factors becomes for multigrid's levels.
pub trait Compressible: Precision + Send + Sync {
    type Compressed: SlabFactor;
    const NAME: &'static str;
    fn compress(factor: CholeskyFactor<Self>) -> Self::Compressed;
}

impl Compressible for f64 {
    type Compressed = CholeskyFactor<f64>;
    const NAME: &'static str = "double precision";

    /// Double precision is the fallback for blocks too ill-conditioned for single: kept.
    fn compress(factor: CholeskyFactor<f64>) -> Self::Compressed {
        factor
    }
}

impl Compressible for f32 {
    type Compressed = Bf16Factor;
    const NAME: &'static str = "single precision";

    fn compress(factor: CholeskyFactor<f32>) -> Bf16Factor {
        Bf16Factor::new(&factor)
    }
}

impl<T: Compressible> SlabFactor for CholeskyFactor<T> {
    const ENTRY_BYTES: usize = std::mem::size_of::<T>();
    const NAME: &'static str = T::NAME;
    type Compressed = T::Compressed;

    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
    ) -> Result<Self, String> {
        Self::new(symbolic, matrix, Par::Seq)
    }

    fn solve(&self, x: &mut [f64]) {
        self.solve_in_place(x, Par::Seq)
    }

    fn entries(&self) -> FactorEntries {
        CholeskyFactor::entries(self)
    }

    fn compress(self) -> T::Compressed {
        T::compress(self)
    }
}

impl SlabFactor for Bf16Factor {
    const ENTRY_BYTES: usize = 2;
    const NAME: &'static str = "bfloat16";
    type Compressed = Self;

    fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        Bf16Factor::bytes_at_most(symbolic)
    }

    /// Factors in `f32` (faer), then rounds.
    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
    ) -> Result<Self, String> {
        CholeskyFactor::<f32>::new(symbolic, matrix, Par::Seq).map(|f| Self::new(&f))
    }

    /// With one scratch buffer per thread: a fresh one per solve would be fresh pages. The
    /// buffer is taken out of the thread for the solve, not borrowed: a solve that splits its
    /// tree over two threads (`rayon::join`) may run another slab's solve on this thread while
    /// it waits, and that one then starts a buffer of its own.
    fn solve(&self, x: &mut [f64]) {
        thread_local! {
            static WORK: Cell<Vec<f32>> = const { Cell::new(Vec::new()) };
        }
        let mut work = WORK.take();
        self.solve_in_place(x, &mut work);
        WORK.set(work);
    }

    fn entries(&self) -> FactorEntries {
        Bf16Factor::entries(self)
    }

    fn compress(self) -> Self {
        self
    }
}
