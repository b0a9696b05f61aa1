//! The factors a preconditioner's slab solves use, by the precision they are stored in:
//! [`SlabFactor`] over faer's `f64` factors and the packed `f32` and bfloat16 ones of
//! [`super::packed`].
//!
//! A slab sweep solves with every factor once per half sweep, one thread per solve (two where
//! another is free and the tree splits). `f32` factors are exact enough that slab Gauss–Seidel
//! converges as with `f64`; bfloat16 reads half as much and leaves multigrid in time's
//! iterations as they were, but costs slab Gauss–Seidel iterations where the slab solves
//! alone almost solve the system (large `α`): its rounding, about `2⁻⁹` per entry, is then what
//! the iterations reduce. So each kind of factor says which one multigrid uses
//! ([`SlabFactor::Compressed`]).

use super::bfloat::{Bf16, Bf16Factor};
use super::cholesky::{CholeskyFactor, FactorEntries, SparseMatrixRef};
use super::packed::{Entry, Halves, PackedFactor};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::Par;
use std::cell::Cell;
use std::sync::Arc;

/// A factor that a preconditioner solves with.
pub trait SlabFactor: Sized + Send + Sync {
    /// Bytes each stored entry of `L` takes.
    const ENTRY_BYTES: usize;
    /// Bytes one factor of the analysed pattern takes at most (the memory budget's unit).
    fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize;
    /// How the entries are stored, for the solver's reasons.
    const NAME: &'static str;
    /// Whether solves come close enough to the block's inverse to eliminate slabs with them
    /// (`crate::flow::solve::reduced`): `f32` and `f64` entries do, bfloat16's rounding
    /// (`2⁻⁹` per entry) would leave each elimination that far from exact.
    const ELIMINATES: bool = Self::ENTRY_BYTES >= 4;
    /// The factor multigrid's levels use when slab Gauss–Seidel started with this one.
    type Compressed: SlabFactor;
    /// Factors `matrix`, single-threaded; `Err` carries the reason it is not numerically
    /// positive definite.
    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
    ) -> Result<Self, String>;
    /// `x ← A⁻¹ x`, on two threads where `halves` says so and the factor can.
    fn solve(&self, x: &mut [f64], halves: Halves);
    fn entries(&self) -> FactorEntries;
    fn compress(self) -> Self::Compressed;
}

/// Double precision, the fallback for blocks too ill-conditioned for single: faer's factor
/// and solve, kept as it is on multigrid's levels.
impl SlabFactor for CholeskyFactor<f64> {
    const ENTRY_BYTES: usize = 8;
    const NAME: &'static str = "double precision";
    type Compressed = Self;

    fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        symbolic.len_val() * Self::ENTRY_BYTES
    }

    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
    ) -> Result<Self, String> {
        Self::new(symbolic, matrix, Par::Seq)
    }

    fn solve(&self, x: &mut [f64], _: Halves) {
        self.solve_in_place(x, Par::Seq)
    }

    fn entries(&self) -> FactorEntries {
        CholeskyFactor::entries(self)
    }

    fn compress(self) -> Self {
        self
    }
}

/// What a packed factor's entries make of faer's `f32` factor, and what multigrid's levels
/// make of it.
pub trait PackedEntry: Entry {
    const NAME: &'static str;
    type Compressed: SlabFactor;
    fn pack(factor: CholeskyFactor<f32>) -> PackedFactor<Self>;
    fn compress(factor: PackedFactor<Self>) -> Self::Compressed;
}

impl PackedEntry for f32 {
    const NAME: &'static str = "single precision";
    type Compressed = Bf16Factor;

    fn pack(factor: CholeskyFactor<f32>) -> PackedFactor<f32> {
        PackedFactor::new(factor)
    }

    fn compress(factor: PackedFactor<f32>) -> Bf16Factor {
        Bf16Factor::rounding(factor.symbolic(), &factor.column_major_values())
    }
}

impl PackedEntry for Bf16 {
    const NAME: &'static str = "bfloat16";
    type Compressed = Bf16Factor;

    fn pack(factor: CholeskyFactor<f32>) -> Bf16Factor {
        Bf16Factor::rounding(factor.symbolic(), factor.values())
    }

    fn compress(factor: Bf16Factor) -> Bf16Factor {
        factor
    }
}

impl<E: PackedEntry> SlabFactor for PackedFactor<E> {
    const ENTRY_BYTES: usize = E::BYTES;
    const NAME: &'static str = E::NAME;
    type Compressed = E::Compressed;

    fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        PackedFactor::<E>::bytes_at_most(symbolic)
    }

    /// Factors in `f32` (faer), then packs.
    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
    ) -> Result<Self, String> {
        CholeskyFactor::<f32>::new(symbolic, matrix, Par::Seq).map(E::pack)
    }

    /// With one scratch buffer per thread: a fresh one per solve would be fresh pages. The
    /// buffer is taken out of the thread for the solve, not borrowed: a solve that splits its
    /// tree over two threads (`rayon::join`) may run another slab's solve on this thread while
    /// it waits, and that one then starts a buffer of its own.
    fn solve(&self, x: &mut [f64], halves: Halves) {
        thread_local! {
            static WORK: Cell<Vec<f32>> = const { Cell::new(Vec::new()) };
        }
        let mut work = WORK.take();
        self.solve_in_place(x, &mut work, halves);
        WORK.set(work);
    }

    fn entries(&self) -> FactorEntries {
        PackedFactor::entries(self)
    }

    fn compress(self) -> E::Compressed {
        E::compress(self)
    }
}
