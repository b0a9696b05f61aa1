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
use std::sync::{Arc, Mutex, PoisonError};

/// `f32` buffers of factors given up (faer's output of a factor rounded to bfloat16, an `f32`
/// factor rounded, its column-major copy), for the next factorizations to write into. A new
/// buffer maps each of its pages on first touch, a page fault apiece (several microseconds on
/// a virtual machine); one taken from here has its pages mapped already. It holds at most
/// `capacity` buffers (one per thread that factors at once), and dropping it frees them.
pub struct SpareValues {
    buffers: Mutex<Vec<Vec<f32>>>,
    capacity: usize,
}

impl SpareValues {
    /// Room for one buffer per thread of the current rayon pool.
    pub fn per_thread() -> Self {
        Self::with_capacity(rayon::current_num_threads())
    }

    /// Room for `capacity` buffers: e.g. all kept factors of a solve, for the next solve of a
    /// run to factor into ([`SlabFactor::recycle`]).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            buffers: Mutex::new(Vec::new()),
            capacity,
        }
    }

    /// A spare buffer (empty if none is left): its contents are to be overwritten.
    pub fn take(&self) -> Vec<f32> {
        self.lock().pop().unwrap_or_default()
    }

    /// Keeps `buffer` for a later [`Self::take`], or frees it when the spares are full.
    pub fn give(&self, buffer: Vec<f32>) {
        let mut buffers = self.lock();
        if buffers.len() < self.capacity {
            buffers.push(buffer);
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Vec<f32>>> {
        self.buffers.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A factor that a preconditioner solves with (`'static`: a run's solves hand factors on as
/// `Any`, `crate::flow::solve::run`).
pub trait SlabFactor: Sized + Send + Sync + 'static {
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
    /// Factors `matrix`, single-threaded, with the buffers of `spare` where it needs `f32`
    /// ones; `Err` carries the reason it is not numerically positive definite.
    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
        spare: &SpareValues,
    ) -> Result<Self, String>;
    /// `x ← A⁻¹ x`, on two threads where `halves` says so and the factor can.
    fn solve(&self, x: &mut [f64], halves: Halves);
    fn entries(&self) -> FactorEntries;
    /// The factor in the precision of [`Self::Compressed`], the buffers it gives up to `spare`.
    fn compress(self, spare: &SpareValues) -> Self::Compressed;
    /// Whether the factor keeps the `f32` buffer it factored into (and gives none back while it
    /// factors), so that [`Self::recycle`] returns it for another factorization of the pattern.
    const RECYCLES: bool = false;
    /// Gives up the factor, its `f32` buffer (where [`Self::RECYCLES`]) to `spare`.
    fn recycle(self, _spare: &SpareValues) {}
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
        _: &SpareValues,
    ) -> Result<Self, String> {
        Self::new(symbolic, matrix, Par::Seq)
    }

    fn solve(&self, x: &mut [f64], _: Halves) {
        self.solve_in_place(x, Par::Seq)
    }

    fn entries(&self) -> FactorEntries {
        CholeskyFactor::entries(self)
    }

    fn compress(self, _: &SpareValues) -> Self {
        self
    }
}

/// What a packed factor's entries make of faer's `f32` factor, and what multigrid's levels
/// make of it.
pub trait PackedEntry: Entry {
    const NAME: &'static str;
    type Compressed: SlabFactor;
    /// The packed factor of faer's `factor`, whose buffer goes to `spare` if not kept.
    fn pack(factor: CholeskyFactor<f32>, spare: &SpareValues) -> PackedFactor<Self>;
    fn compress(factor: PackedFactor<Self>, spare: &SpareValues) -> Self::Compressed;
    /// [`SlabFactor::RECYCLES`].
    const RECYCLES: bool;
    /// [`SlabFactor::recycle`].
    fn recycle(factor: PackedFactor<Self>, spare: &SpareValues);
}

impl PackedEntry for f32 {
    const NAME: &'static str = "single precision";
    type Compressed = Bf16Factor;

    fn pack(factor: CholeskyFactor<f32>, _: &SpareValues) -> PackedFactor<f32> {
        PackedFactor::new(factor)
    }

    fn compress(factor: PackedFactor<f32>, spare: &SpareValues) -> Bf16Factor {
        let mut column_major = spare.take();
        factor.column_major_values_into(&mut column_major);
        let rounded = Bf16Factor::rounding(factor.symbolic(), &column_major);
        spare.give(column_major);
        spare.give(factor.into_values());
        rounded
    }

    const RECYCLES: bool = true;

    fn recycle(factor: PackedFactor<f32>, spare: &SpareValues) {
        spare.give(factor.into_values());
    }
}

impl PackedEntry for Bf16 {
    const NAME: &'static str = "bfloat16";
    type Compressed = Bf16Factor;

    fn pack(factor: CholeskyFactor<f32>, spare: &SpareValues) -> Bf16Factor {
        let rounded = Bf16Factor::rounding(factor.symbolic(), factor.values());
        spare.give(factor.into_parts().1);
        rounded
    }

    fn compress(factor: Bf16Factor, _: &SpareValues) -> Bf16Factor {
        factor
    }

    const RECYCLES: bool = false;

    fn recycle(_: Bf16Factor, _: &SpareValues) {}
}

impl<E: PackedEntry> SlabFactor for PackedFactor<E> {
    const ENTRY_BYTES: usize = E::BYTES;
    const NAME: &'static str = E::NAME;
    type Compressed = E::Compressed;

    fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        PackedFactor::<E>::bytes_at_most(symbolic)
    }

    /// Factors in `f32` (faer, into a spare buffer), then packs.
    fn factor(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
        spare: &SpareValues,
    ) -> Result<Self, String> {
        CholeskyFactor::<f32>::new_in(symbolic, matrix, Par::Seq, spare.take())
            .map(|factor| E::pack(factor, spare))
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

    fn compress(self, spare: &SpareValues) -> E::Compressed {
        E::compress(self, spare)
    }

    const RECYCLES: bool = E::RECYCLES;

    fn recycle(self, spare: &SpareValues) {
        E::recycle(self, spare)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::cholesky::analyze;
    use crate::linalg::packed::tests::grid_block;

    /// Two different blocks of one pattern: the grid with two diagonals.
    fn two_blocks() -> (
        Arc<SymbolicCholesky<usize>>,
        [faer::sparse::SparseColMat<usize, f64>; 2],
    ) {
        let blocks = [grid_block(12, 10, 4.1), grid_block(12, 10, 40.0)];
        (analyze(blocks[0].symbolic(), 2), blocks)
    }

    #[test]
    fn a_factor_written_over_another_is_the_factor() {
        let (symbolic, [a, b]) = two_blocks();
        let fresh = CholeskyFactor::<f32>::new(&symbolic, a.as_ref(), Par::Seq).unwrap();
        let other = CholeskyFactor::<f32>::new(&symbolic, b.as_ref(), Par::Seq).unwrap();
        assert_ne!(fresh.values(), other.values());
        let (_, used) = other.into_parts();
        let over = CholeskyFactor::<f32>::new_in(&symbolic, a.as_ref(), Par::Seq, used).unwrap();
        assert_eq!(over.values(), fresh.values());
    }

    #[test]
    fn spare_buffers_give_the_same_packed_and_rounded_factors() {
        let (symbolic, [a, b]) = two_blocks();
        let none = SpareValues::per_thread();
        let fresh_bf16 = Bf16Factor::factor(&symbolic, a.as_ref(), &none).unwrap();
        let fresh_f32 = PackedFactor::<f32>::factor(&symbolic, a.as_ref(), &none).unwrap();
        let reference = fresh_f32.column_major_values();
        let fresh_rounded = fresh_f32.compress(&none);

        // Spares holding another block's factor and its column-major copy.
        let spare = SpareValues {
            buffers: Mutex::new(Vec::new()),
            capacity: 2,
        };
        let other = PackedFactor::<f32>::factor(&symbolic, b.as_ref(), &spare).unwrap();
        let _ = other.compress(&spare);
        assert_eq!(spare.lock().len(), 2);
        let bf16 = Bf16Factor::factor(&symbolic, a.as_ref(), &spare).unwrap();
        assert_eq!(bf16.column_major_values(), fresh_bf16.column_major_values());
        let packed = PackedFactor::<f32>::factor(&symbolic, a.as_ref(), &spare).unwrap();
        assert_eq!(packed.column_major_values(), reference);
        let rounded = packed.compress(&spare);
        assert_eq!(
            rounded.column_major_values(),
            fresh_rounded.column_major_values()
        );
    }

    /// A run's next solve factors into the buffers of the last one's `f32` factors: a factor
    /// recycled gives its buffer back (bfloat16 factors keep none), and the factor written into
    /// it equals a fresh one; factoring takes from the pool and gives nothing back.
    #[test]
    fn recycled_factors_give_their_buffers_to_the_next_factorization() {
        let (symbolic, [a, b]) = two_blocks();
        let none = SpareValues::per_thread();
        let fresh = PackedFactor::<f32>::factor(&symbolic, a.as_ref(), &none).unwrap();
        let run = SpareValues::with_capacity(4);
        Bf16Factor::factor(&symbolic, b.as_ref(), &none)
            .unwrap()
            .recycle(&run);
        assert!(run.lock().is_empty());
        let last = PackedFactor::<f32>::factor(&symbolic, b.as_ref(), &none).unwrap();
        last.recycle(&run);
        assert_eq!(run.lock().len(), 1);
        const { assert!(PackedFactor::<f32>::RECYCLES && !Bf16Factor::RECYCLES) };
        let next = PackedFactor::<f32>::factor(&symbolic, a.as_ref(), &run).unwrap();
        assert!(run.lock().is_empty());
        assert_eq!(next.column_major_values(), fresh.column_major_values());
    }

    #[test]
    fn spares_keep_at_most_their_capacity() {
        let spare = SpareValues {
            buffers: Mutex::new(Vec::new()),
            capacity: 2,
        };
        assert!(spare.take().is_empty());
        (1..=3).for_each(|n| spare.give(vec![1.0; n]));
        let lengths: Vec<usize> = (0..3).map(|_| spare.take().len()).collect();
        assert_eq!(lengths, [2, 1, 0]);
    }
}
