//! Cholesky factors packed for the preconditioners' slab solves, and the triangular solves
//! with them: `L` stored as `f32` or bfloat16 entries ([`Entry`]), faer's supernodal factor
//! less the rows a factor leaves out ([`KeptRows`]) with its wide supernodes reordered into
//! the order their solves read them ([`layout`]), solved by meshflow's own kernels
//! ([`kernels`]).
//!
//! A slab solve `x ← (L Lᵀ)⁻¹ x` runs `L y = b` supernode by supernode (its dense triangle,
//! then its rows below take `L_below y_s` off their columns), then `Lᵀ x = y` in reverse (each
//! column's dot product with the solved rows below and the triangle's later columns), in `f32`
//! arithmetic on the permuted right-hand side.
//!
//! **Why written by hand.** faer's triangular solves are generic over faer's scalar types, and
//! bfloat16 is not one (nor does any sparse crate solve with a compressed factor). They also pay
//! a fixed cost per supernode (a dense triangular solve and a matrix–vector product through
//! faer's dispatch), and a nested-dissection order of a surface mesh makes most supernodes
//! one vertex (two columns) wide: the paper-size slab block (48,450 vertices) has 27,130
//! supernodes, 21,241 of them two columns wide with 18 rows below on average. The kernels here
//! take those rows' products straight into their columns (no scratch, no call), take the
//! wider supernodes four columns at a time, and run an AVX2 + FMA build where the processor
//! has one ([`Kernels`]).
//!
//! **Read in one run.** Most entries are in the wide supernodes (on the paper-size slab, 7.7 M
//! of 9.0 M). faer stores them column-major, so a pass over four columns reads four short runs
//! and the upper solve, which walks the supernodes backwards, starts each run anew: the
//! processor's prefetcher, which follows one run forwards or backwards, kept restarting. Stored
//! in blocks of four columns, tiles of eight rows ([`layout`]), and read forwards by the lower
//! solve and backwards by the upper one, a solve is two long runs over the factor. Per solve on
//! each of 2 cores, each thread solving with factors of its own (the fastest of 12 interleaved
//! rounds, `cargo test --release --lib packed::tests::timing -- --ignored --nocapture`,
//! 2026-11-28):
//!
//! | block (entries) | faer `f32` | packed `f32` | portable | bfloat16 (kept) |
//! |---|---|---|---|---|
//! | paper-size slab (9.0 M) | 15.7–15.9 ms | 6.6–6.8 ms | 7.8–8.1 ms | 5.5–6.0 ms (6.2 M) |
//! | 128×95 grid, diagonal 4.1 (1.23 M) | 2.7–2.8 ms | 1.0 ms | 1.4–1.5 ms | 0.82–0.84 ms |
//! | 128×95 grid, diagonal 40 (1.23 M) | 2.8–2.9 ms | 1.0–1.1 ms | 1.5–1.6 ms | 0.61–0.62 ms |
//!
//! **Not bound by the bytes.** A paper-size solve reads 72 MB, so two cores solve at about
//! 21 GB/s where they stream 27–45 GB/s (`examples/bench_floor.rs`), and one core alone at
//! 6.6–7.2 ms (before the narrow triangles were unrolled, [`kernels`]), 10–11 GB/s, where it
//! streams 22–28 GB/s. A lone tile loop streams at that rate; what is left is the work per
//! supernode, along the elimination tree's dependences: solving only the narrow supernodes
//! (24,221 of 27,130, 15 % of the entries) took 3.4–3.6 ms of a solve on one core, the wide
//! ones alone 6.4–7.0 ms, the two overlapping. Tried without gain (docs/scaling.md, "The
//! paper size against its floors"): software prefetching, the two subtrees' supernodes
//! interleaved on one thread, 2 MB pages. The bfloat16 factors gain less than their bytes for
//! the same reason: their work per supernode bounds them, not the bytes, nor the bits that mark
//! the rows they leave out, whose walk a list of the kept rows shortened by only 5–8 %.
//!
//! A solve may run the two halves of the elimination tree under its top separators on two
//! threads ([`TreeSplit`], [`Halves`]): multigrid's coarse levels have fewer slabs than cores,
//! and a lone slab solve then uses both cores (`bench_solver`, `α = γ = 0.01`: solve
//! 2.02–2.09 → 1.96–2.02 s, four alternating runs, with bfloat16 factors). Where every core
//! has a solve of its own the split only costs (the paper-size slab: 7.3 ms split against
//! 6.6–6.8), so a sweep splits only where its solves do not divide evenly among the threads.
//!
//! The kernels walk faer's own symbolic structure, supernodal or simplicial, so the ordering
//! and fill are those of the `f32` factor faer computed, less the rows left out.

mod kernels;
mod layout;

use super::cholesky::{CholeskyFactor, FactorEntries};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
pub use kernels::Kernels;
use std::ops::Range;
use std::sync::Arc;

/// How a packed factor stores an entry of `L`.
pub trait Entry: Copy + Default + Send + Sync + 'static {
    /// Bytes per entry.
    const BYTES: usize;
    /// The entry nearest `x`.
    fn narrow(x: f32) -> Self;
    /// The entry's value (exact).
    fn widen(self) -> f32;
}

impl Entry for f32 {
    const BYTES: usize = 4;

    fn narrow(x: f32) -> Self {
        x
    }

    #[inline(always)]
    fn widen(self) -> f32 {
        self
    }
}

/// `L Lᵀ ≈ A` with `L` stored as `E` (rows possibly left out: [`KeptRows`]), solved in `f32`.
pub struct PackedFactor<E> {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<E>,
    /// The rows kept below each supernode (supernodal layout only).
    kept: Option<KeptRows>,
    /// The elimination tree's two largest independent parts, solved on two threads.
    split: Option<TreeSplit>,
    kernels: Kernels,
}

impl PackedFactor<f32> {
    /// `factor` itself: its entries as faer computed them, every row kept.
    pub fn new(factor: CholeskyFactor<f32>) -> Self {
        let (symbolic, values) = factor.into_parts();
        let kept = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => Some(KeptRows::all(s)),
            SymbolicCholeskyRaw::Simplicial(_) => None,
        };
        Self::with_layout(symbolic, values, kept)
    }
}

impl<E: Entry> PackedFactor<E> {
    /// The factor with entries `values` (faer's layout for `symbolic`) rounded to `E`, leaving
    /// out each row below a supernode's triangle whose entries there are all below `tolerance`
    /// times the row's pivot `L_rr` (none at 0).
    pub fn packing(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        values: &[f32],
        tolerance: f32,
    ) -> Self {
        let (values, kept) = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let (kept, values) = KeptRows::packing(s, values, tolerance);
                (values, Some(kept))
            }
            SymbolicCholeskyRaw::Simplicial(_) => {
                (values.iter().map(|&v| E::narrow(v)).collect(), None)
            }
        };
        Self::with_layout(symbolic.clone(), values, kept)
    }

    /// The factor with `values` in faer's layout less the rows `kept` leaves out, its wide
    /// supernodes reordered into blocks ([`layout`]).
    fn with_layout(
        symbolic: Arc<SymbolicCholesky<usize>>,
        mut values: Vec<E>,
        mut kept: Option<KeptRows>,
    ) -> Self {
        if let (SymbolicCholeskyRaw::Supernodal(s), Some(kept)) = (symbolic.raw(), &mut kept) {
            layout::to_blocked(&mut values, &mut kept.value_start, shapes(s, &kept.rows));
        }
        let kernels = Kernels::detect();
        let split = match (symbolic.raw(), &kept) {
            (SymbolicCholeskyRaw::Supernodal(s), Some(kept)) => {
                TreeSplit::of(&Supernodes::of(s, kept, kernels))
            }
            _ => None,
        };
        Self {
            symbolic,
            values,
            kept,
            split,
            kernels,
        }
    }

    /// Bytes a factor of `symbolic`'s pattern takes at most: every entry kept, and which rows
    /// are (a bit per panel row, two offsets and a count per supernode).
    pub fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        let bookkeeping = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let supernodes = s.supernode_begin().len();
                let words: usize = (0..supernodes)
                    .map(|k| s.supernode(k).pattern().len().div_ceil(64))
                    .sum();
                8 * words + 20 * (supernodes + 1)
            }
            SymbolicCholeskyRaw::Simplicial(_) => 0,
        };
        E::BYTES * symbolic.len_val() + bookkeeping
    }

    /// Stored entries of `L`, and how many are subnormal.
    pub fn entries(&self) -> FactorEntries {
        FactorEntries {
            stored: self.values.len(),
            subnormal: self
                .values
                .iter()
                .filter(|v| v.widen().is_subnormal())
                .count(),
        }
    }

    /// The symbolic analysis the factor was computed with.
    pub fn symbolic(&self) -> &Arc<SymbolicCholesky<usize>> {
        &self.symbolic
    }

    /// [`Self::column_major_values_into`] a new vector.
    #[cfg(test)]
    pub fn column_major_values(&self) -> Vec<E> {
        let mut values = Vec::new();
        self.column_major_values_into(&mut values);
        values
    }

    /// The stored entries in faer's layout (less the rows left out), the unused upper halves
    /// of the supernodes' triangles zero, written over `out`.
    pub fn column_major_values_into(&self, out: &mut Vec<E>) {
        match (self.symbolic.raw(), &self.kept) {
            (SymbolicCholeskyRaw::Supernodal(s), Some(kept)) => {
                layout::to_column_major(&self.values, &kept.value_start, shapes(s, &kept.rows), out)
            }
            _ => {
                out.clear();
                out.extend_from_slice(&self.values);
            }
        }
    }

    /// The stored entries, the factor given up.
    pub fn into_values(self) -> Vec<E> {
        self.values
    }

    /// Overwrites `x` with `(L Lᵀ)⁻¹ x`, in `f32` arithmetic; `work` holds one permuted copy
    /// of `x` and the supernodes' scratch (reused across solves).
    pub fn solve_in_place(&self, x: &mut [f64], work: &mut Vec<f32>, halves: Halves) {
        let n = x.len();
        // No clearing: `y` is written whole below and each supernode sets its scratch first.
        work.resize(5 * n, 0.0);
        let (y, scratch) = work.split_at_mut(n);
        let perm = self.symbolic.perm().map(|p| p.arrays());
        gather(y, x, perm.map(|(forward, _)| forward), |v| v as f32);
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let kept = self
                    .kept
                    .as_ref()
                    .expect("a supernodal factor keeps its rows");
                let structure = Supernodes::of(s, kept, self.kernels);
                match (&self.split, halves) {
                    (Some(split), Halves::Parallel) => {
                        split.solve(&structure, &self.values, y, scratch)
                    }
                    _ => {
                        structure.lower_solve(&self.values, y, scratch);
                        structure.upper_solve(&self.values, y, scratch);
                    }
                }
            }
            SymbolicCholeskyRaw::Simplicial(s) => {
                let (columns, rows) = (s.col_ptr(), s.row_idx());
                kernels::simplicial_lower_solve(columns, rows, &self.values, y);
                kernels::simplicial_upper_solve(columns, rows, &self.values, y);
            }
        }
        gather(x, y, perm.map(|(_, inverse)| inverse), f64::from);
    }
}

/// Whether a solve runs the two halves of its elimination tree on two threads
/// ([`TreeSplit`]). Worth it only where a thread would otherwise wait: on the paper-size slab
/// block, with both cores busy solving, a split solve takes 7.3 ms against 6.6–6.8 ms
/// (`tests::timing`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Halves {
    Parallel,
    Sequential,
}

impl Halves {
    /// For one of `solves` solves that run together on rayon's threads: in parallel where
    /// they do not divide evenly among the threads (a thread would wait for the last ones).
    pub fn for_solves(solves: usize) -> Self {
        match solves % rayon::current_num_threads() {
            0 => Self::Sequential,
            _ => Self::Parallel,
        }
    }
}

/// `s ↦ (w, m)`: supernode `s`'s columns and the rows below it that a factor keeps (`rows`,
/// [`KeptRows`]), the shapes [`layout`] orders values by.
fn shapes<'a>(
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    rows: &'a [u32],
) -> impl Fn(usize) -> (usize, usize) + 'a {
    let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
    move |s| (end[s] - begin[s], rows[s] as usize)
}

/// `to[i] = convert(from[index[i]])`, or `convert(from[i])` without an index: the permutation
/// into the factor's ordering and back out of it.
fn gather<S: Copy, T>(to: &mut [T], from: &[S], index: Option<&[usize]>, convert: impl Fn(S) -> T) {
    match index {
        Some(index) => (to.iter_mut().zip(index)).for_each(|(t, &i)| *t = convert(from[i])),
        None => (to.iter_mut().zip(from)).for_each(|(t, &f)| *t = convert(f)),
    }
}

/// faer's supernodal structure, less the rows left out: supernode `s` holds columns
/// `begin[s]..end[s]` (`w` of them) and the `m` rows of its pattern below that the factor
/// keeps, its values from `kept.value_start[s]`: column-major with `w + m` rows (the dense
/// lower triangle on top) where narrow, in blocks where wide ([`layout`]).
struct Supernodes<'a> {
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    begin: &'a [usize],
    end: &'a [usize],
    kept: &'a KeptRows,
    kernels: Kernels,
}

/// Which rows of each supernode's pattern below its triangle a factor keeps (one bit per
/// row, from word `word_start[s]`; no words for a supernode that keeps them all), how many
/// (`rows[s]`: the solves need the count per supernode, and a division to get it from the
/// values' extent was on their path), and where the supernode's values start.
struct KeptRows {
    bits: Vec<u64>,
    word_start: Vec<usize>,
    rows: Vec<u32>,
    value_start: Vec<usize>,
}

impl KeptRows {
    /// Every row kept: faer's layout as it is.
    fn all(symbolic: &SymbolicSupernodalCholesky<usize>) -> Self {
        let value_start = symbolic.col_ptr_for_val().to_vec();
        let supernodes = symbolic.supernode_begin().len();
        Self {
            bits: Vec::new(),
            word_start: vec![0; value_start.len()],
            rows: (0..supernodes)
                .map(|s| symbolic.supernode(s).pattern().len() as u32)
                .collect(),
            value_start,
        }
    }

    /// Rounds `values` to `E`, keeping a row below a supernode's triangle only where one of
    /// its entries is at least `tolerance` times the row's pivot.
    fn packing<E: Entry>(
        symbolic: &SymbolicSupernodalCholesky<usize>,
        values: &[f32],
        tolerance: f32,
    ) -> (Self, Vec<E>) {
        let (begin, end, start) = (
            symbolic.supernode_begin(),
            symbolic.supernode_end(),
            symbolic.col_ptr_for_val(),
        );
        let pivots = Self::pivots(symbolic, values);
        let mut kept = Self {
            bits: Vec::new(),
            word_start: vec![0],
            rows: Vec::with_capacity(begin.len()),
            value_start: vec![0],
        };
        let mut rounded = Vec::with_capacity(values.len());
        let (mut rows, mut largest) = (Vec::new(), Vec::new());
        for s in 0..begin.len() {
            let below = symbolic.supernode(s).pattern();
            let w = end[s] - begin[s];
            let ld = w + below.len();
            let l = &values[start[s]..start[s + 1]];
            rows.clear();
            let words = kept.bits.len();
            kept.bits.resize(words + below.len().div_ceil(64), 0);
            largest.clear();
            largest.resize(below.len(), 0.0f32);
            for column in l.chunks_exact(ld) {
                (largest.iter_mut().zip(&column[w..])).for_each(|(m, v)| *m = m.max(v.abs()));
            }
            for (i, &r) in below.iter().enumerate() {
                if largest[i] >= tolerance * pivots[r] {
                    rows.push(i);
                    kept.bits[words + i / 64] |= 1 << (i % 64);
                }
            }
            for column in l.chunks_exact(ld) {
                rounded.extend(column[..w].iter().map(|&v| E::narrow(v)));
                rounded.extend(rows.iter().map(|&i| E::narrow(column[w + i])));
            }
            kept.word_start.push(kept.bits.len());
            kept.rows.push(rows.len() as u32);
            kept.value_start.push(rounded.len());
        }
        // Most of the capacity may be unused where much drops; it would stay reserved.
        rounded.shrink_to_fit();
        (kept, rounded)
    }

    /// `L_cc` for every column `c` (the diagonal of each supernode's triangle).
    fn pivots(symbolic: &SymbolicSupernodalCholesky<usize>, values: &[f32]) -> Vec<f32> {
        let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
        let start = symbolic.col_ptr_for_val();
        let mut pivots = vec![0.0f32; symbolic.nrows()];
        for s in 0..begin.len() {
            let w = end[s] - begin[s];
            let ld = (start[s + 1] - start[s]) / w;
            for j in 0..w {
                pivots[begin[s] + j] = values[start[s] + j * ld + j];
            }
        }
        pivots
    }
}

/// The rows a supernode keeps below its triangle: its pattern, filtered by a bit per row.
#[derive(Clone, Copy)]
struct Below<'a> {
    pattern: &'a [usize],
    bits: &'a [u64],
    len: usize,
}

impl<'a> Below<'a> {
    fn len(&self) -> usize {
        self.len
    }

    /// The rows, where all are kept.
    #[inline(always)]
    fn all(&self) -> Option<&'a [usize]> {
        (self.len == self.pattern.len()).then_some(self.pattern)
    }

    /// `visit(k, r)` for the `k`-th kept row, `r`; a word whose rows are all kept is walked
    /// without its bits (the common case where nothing is dropped).
    #[inline(always)]
    fn for_each(&self, mut visit: impl FnMut(usize, usize)) {
        if let Some(rows) = self.all() {
            rows.iter().enumerate().for_each(|(k, &r)| visit(k, r));
            return;
        }
        let mut k = 0;
        for (rows, &bits) in self.pattern.chunks(64).zip(self.bits) {
            if bits.count_ones() as usize == rows.len() {
                for &r in rows {
                    visit(k, r);
                    k += 1;
                }
            } else {
                let mut bits = bits;
                while bits != 0 {
                    visit(k, rows[bits.trailing_zeros() as usize]);
                    bits &= bits - 1;
                    k += 1;
                }
            }
        }
    }
}

impl<'a> Supernodes<'a> {
    fn of(
        symbolic: &'a SymbolicSupernodalCholesky<usize>,
        kept: &'a KeptRows,
        kernels: Kernels,
    ) -> Self {
        Self {
            symbolic,
            begin: symbolic.supernode_begin(),
            end: symbolic.supernode_end(),
            kept,
            kernels,
        }
    }

    fn len(&self) -> usize {
        self.begin.len()
    }

    /// `(first column, width, rows below, values)` of supernode `s`.
    #[inline(always)]
    fn supernode<'v, E>(&self, s: usize, values: &'v [E]) -> (usize, usize, Below<'a>, &'v [E]) {
        let (w, kept) = (self.end[s] - self.begin[s], self.kept);
        let values = &values[kept.value_start[s]..kept.value_start[s + 1]];
        let below = Below {
            pattern: self.symbolic.supernode(s).pattern(),
            bits: &kept.bits[kept.word_start[s]..kept.word_start[s + 1]],
            len: kept.rows[s] as usize,
        };
        (self.begin[s], w, below, values)
    }

    /// `y ← L⁻¹ y`.
    fn lower_solve<E: Entry>(&self, values: &[E], y: &mut [f32], scratch: &mut [f32]) {
        let mut columns = Columns::all(y);
        self.lower_solve_part(0..self.len(), values, &mut columns, scratch);
    }

    /// `y ← L⁻ᵀ y`.
    fn upper_solve<E: Entry>(&self, values: &[E], y: &mut [f32], scratch: &mut [f32]) {
        self.upper_solve_part(0..self.len(), values, (y, 0), (&[], 0), scratch);
    }

    /// The supernode holding column `c`.
    fn holding(&self, c: usize) -> usize {
        self.end.partition_point(|&e| e <= c)
    }
}

/// The columns a part of a triangular solve owns (from column `offset`), and the sums it
/// takes off its ancestors' columns (`beyond`, from column `beyond_start`).
struct Columns<'a> {
    own: &'a mut [f32],
    offset: usize,
    beyond: &'a mut [f32],
    beyond_start: usize,
}

impl<'a> Columns<'a> {
    /// All columns, nothing beyond.
    fn all(y: &'a mut [f32]) -> Self {
        let beyond_start = y.len();
        Self {
            own: y,
            offset: 0,
            beyond: &mut [],
            beyond_start,
        }
    }

    /// `y_r −= u`; `WHOLE` when the columns are all the solve's (from 0, nothing beyond).
    #[inline(always)]
    fn take_off<const WHOLE: bool>(&mut self, r: usize, u: f32) {
        match (WHOLE, r < self.offset + self.own.len()) {
            (true, _) => self.own[r] -= u,
            (false, true) => self.own[r - self.offset] -= u,
            (false, false) => self.beyond[r - self.beyond_start] += u,
        }
    }
}

/// Two subtrees of the supernodal elimination tree that share no column, and the supernodes
/// above both: with a nested-dissection order, the two halves of the mesh and the separators
/// between them. The triangular solves run the two subtrees on two threads and the top
/// alone: `L y = b` sums what each subtree takes off the top's columns, `Lᵀ x = y` reads the
/// top's solved columns in both. A lone slab solve (the coarse levels of multigrid in time,
/// with fewer slabs than cores) then reads its factor at two cores' bandwidth.
///
/// faer orders supernodes in postorder, so a subtree is a run of supernodes ending at its root,
/// and columns follow supernodes.
#[derive(Clone, Debug)]
struct TreeSplit {
    /// Supernodes of the first subtrees, of the second, and of the top.
    first: Range<usize>,
    second: Range<usize>,
    top: Range<usize>,
}

impl TreeSplit {
    /// The split below the first supernode with two or more children (descending from a
    /// single root), its children's subtrees parted where the factor entries are halved;
    /// `None` for a forest, a chain, or a part under a tenth of the entries.
    fn of(supernodes: &Supernodes<'_>) -> Option<Self> {
        let n = supernodes.len();
        let parent = |s: usize| {
            (supernodes.symbolic.supernode(s).pattern().first()).map(|&r| supernodes.holding(r))
        };
        let mut children = vec![Vec::new(); n];
        let mut roots = 0;
        for s in 0..n {
            match parent(s) {
                Some(p) => children[p].push(s),
                None => roots += 1,
            }
        }
        let mut top = n.checked_sub(1)?;
        while roots == 1 && children[top].len() == 1 {
            top = children[top][0];
        }
        let kids = &children[top];
        if roots != 1 || kids.len() < 2 || kids[kids.len() - 1] + 1 != top {
            return None;
        }
        let entries = |r: Range<usize>| {
            supernodes.kept.value_start[r.end] - supernodes.kept.value_start[r.start]
        };
        let below = entries(0..top);
        let cut = kids[..kids.len() - 1]
            .iter()
            .map(|&k| k + 1)
            .min_by_key(|&c| entries(0..c).abs_diff(below - entries(0..c)))?;
        let split = Self {
            first: 0..cut,
            second: cut..top,
            top: top..n,
        };
        // Postorder: every supernode of a part has its parent in the part or at the top's root.
        let closed = |part: &Range<usize>| {
            part.clone()
                .all(|s| parent(s).is_some_and(|p| part.contains(&p) || p == top))
        };
        if !closed(&split.first) || !closed(&split.second) {
            return None;
        }
        let smaller = entries(split.first.clone()).min(entries(split.second.clone()));
        (10 * smaller >= entries(0..n)).then_some(split)
    }

    /// `y ← (L Lᵀ)⁻¹ y` (`scratch`: at least `4n` values).
    fn solve<E: Entry>(
        &self,
        supernodes: &Supernodes<'_>,
        values: &[E],
        y: &mut [f32],
        scratch: &mut [f32],
    ) {
        let [second, top] = [self.second.start, self.top.start].map(|s| supernodes.begin[s]);
        let solve = SplitSolve {
            split: self,
            supernodes,
            values,
            second,
            top,
        };
        solve.lower(y, scratch);
        solve.upper(y, scratch);
    }
}

/// One factor's solve over a [`TreeSplit`]: its supernodes and values, and the first columns
/// of the second subtree and of the top.
struct SplitSolve<'a, E> {
    split: &'a TreeSplit,
    supernodes: &'a Supernodes<'a>,
    values: &'a [E],
    second: usize,
    top: usize,
}

impl<E: Entry> SplitSolve<'_, E> {
    /// [`Supernodes::lower_solve`] on two threads.
    fn lower(&self, y: &mut [f32], scratch: &mut [f32]) {
        let (supernodes, values, split) = (self.supernodes, self.values, self.split);
        let (a, b, n) = (self.second, self.top, y.len());
        let (scratch_first, rest) = scratch.split_at_mut(n);
        let (scratch_second, sums) = rest.split_at_mut(n);
        let (sums_first, sums_second) = sums[..2 * (n - b)].split_at_mut(n - b);
        sums_first.fill(0.0);
        sums_second.fill(0.0);
        let (first, rest) = y.split_at_mut(a);
        let (second, _) = rest.split_at_mut(b - a);
        let part = |own, offset, beyond| Columns {
            own,
            offset,
            beyond,
            beyond_start: b,
        };
        rayon::join(
            || {
                let mut columns = part(first, 0, sums_first);
                supernodes.lower_solve_part(
                    split.first.clone(),
                    values,
                    &mut columns,
                    scratch_first,
                )
            },
            || {
                let mut columns = part(second, a, sums_second);
                supernodes.lower_solve_part(
                    split.second.clone(),
                    values,
                    &mut columns,
                    scratch_second,
                )
            },
        );
        (y[b..].iter_mut())
            .zip(sums_first.iter().zip(sums_second.iter()))
            .for_each(|(y, (p, q))| *y -= p + q);
        let mut columns = Columns::all(y);
        supernodes.lower_solve_part(split.top.clone(), values, &mut columns, scratch_first);
    }

    /// [`Supernodes::upper_solve`]: the top alone, then the two subtrees on two threads.
    fn upper(&self, y: &mut [f32], scratch: &mut [f32]) {
        let (supernodes, values, split) = (self.supernodes, self.values, self.split);
        let (a, b, n) = (self.second, self.top, y.len());
        supernodes.upper_solve_part(split.top.clone(), values, (y, 0), (&[], n), scratch);
        let (scratch_first, rest) = scratch.split_at_mut(n);
        let scratch_second = &mut rest[..n];
        let (below, top) = y.split_at_mut(b);
        let (first, second) = below.split_at_mut(a);
        let top = &*top;
        // Each subtree's rows below lie in it or in the top, never in the other subtree.
        rayon::join(
            || {
                let (own, part) = ((first, 0), split.first.clone());
                supernodes.upper_solve_part(part, values, own, (top, b), scratch_first)
            },
            || {
                let (own, part) = ((second, a), split.second.clone());
                supernodes.upper_solve_part(part, values, own, (top, b), scratch_second)
            },
        );
    }
}

#[cfg(test)]
pub(crate) mod tests;
