//! Cholesky factors stored in bfloat16, for preconditioners whose solves are bound by memory
//! bandwidth.
//!
//! A slab solve of the flow's preconditioners streams its factor `L` twice (`L y = b`, then
//! `Lᵀ x = y`) and does two flops per entry read: on two cores it runs at the memory's speed,
//! not the arithmetic's (`flow::solve`, "Where the time goes"). Storing `L` in bfloat16 (the top
//! half of an `f32`: 8 significant bits, `f32`'s exponent range) halves what each solve reads.
//! The factor is computed in `f32` by faer and rounded once; the solves widen each entry back
//! to `f32` (a 16-bit shift) and accumulate in `f32`.
//!
//! `L̃ L̃ᵀ` with the rounded `L̃` is symmetric positive definite whatever the rounding (its
//! diagonal stays positive), so it is a valid block of a CG preconditioner; it only differs
//! from the block by about `2⁻⁹` relative per entry of `L`. Measured on the 128×95×20 torus
//! (`bench_solver`): multigrid's iterations unchanged (one more at `α = 0.001`, `γ = 1`); slab
//! Gauss–Seidel 19 → 21 at `α = γ = 1` and 3 → 7 at `α = 10`, which is why the sweeps keep `f32`
//! while it fits the budget (`flow::solve`, "Factor precision").
//!
//! **Small rows dropped.** A row of a supernode's panel (the rows of `L` below its dense
//! triangle) is not stored when all its entries there are below [`DROP_TOLERANCE`] (`2⁻¹⁰`)
//! times the row's pivot `L_rr`, which each such entry perturbs less than rounding `L_rr` itself
//! does. `L̃ L̃ᵀ` stays symmetric positive definite (`L̃` is still triangular with a positive
//! diagonal), so it remains a valid preconditioner block; one bit per panel row says which rows
//! are kept, and the solves skip the rest. Where the time coupling dominates a slab block
//! (`D ≈ 2cM` at small `α`), `L` decays fast away from the diagonal: on the 128×95×20 torus at
//! `α = 0.01` the multigrid levels keep 36–47 % of their entries (`α = 1`: 84–89 %), with the
//! same iterations over `bench_solver`'s table. Solve with factorization at `α = γ = 0.01`:
//! 2.00 → 1.66 s (medians of 3 alternating runs, a quiet hour; 2.58 → 2.40 s in a noisy one),
//! 2.61 → 2.11 s on the 16-core Xeon limited to 2 cores. At 200 frames
//! (`bench_paper_torus -- 255 190 200`, bfloat16 slab Gauss–Seidel at `α = 1`): 7 iterations
//! either way, solve 37.9 → 31.9 s, peak 7.24 → 7.21 GB. The solves do not speed up in
//! proportion to what they read: most supernodes of a nested-dissection order are one vertex
//! wide, and their per-row work (gathering, scattering) stays.
//!
//! A solve runs the two halves of the elimination tree under its top separators on two threads
//! when another is free ([`TreeSplit`]): multigrid's coarse levels have fewer slabs than cores,
//! and a lone slab solve then reads its factor at both cores' bandwidth (`bench_solver`,
//! `α = γ = 0.01`: solve 2.02–2.09 → 1.96–2.02 s, four alternating runs).
//!
//! Why written by hand: faer's triangular solves are generic over faer's scalar types, and
//! bfloat16 is not one (nor does any sparse crate solve with a compressed factor). The kernels
//! below walk faer's own symbolic structure, supernodal or simplicial, so the ordering and fill
//! are those of the `f32` factor, less the dropped rows.

use super::cholesky::{CholeskyFactor, FactorEntries};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use std::ops::Range;
use std::sync::Arc;

/// `L Lᵀ ≈ A` with `L` in bfloat16 (the `f32` factor's entries rounded to nearest, ties to
/// even, its small rows dropped: [`DROP_TOLERANCE`]).
pub struct Bf16Factor {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<u16>,
    /// The rows kept below each supernode (supernodal layout only).
    kept: Option<KeptRows>,
    /// The elimination tree's two largest independent parts, solved on two threads.
    split: Option<TreeSplit>,
}

/// A row of `L` below a supernode's triangle is dropped when all its entries there are below
/// this fraction of the row's pivot `L_rr`: each such entry then changes the row by less than
/// rounding the pivot itself to bfloat16 may (`2⁻⁹ L_rr`).
///
/// Where the time coupling dominates a slab block (`D ≈ 2cM` at small `α`), `L` decays fast
/// away from the diagonal and most of the fill is below it: on the 128×95×20 torus at
/// `α = 0.01` 53–64 % of each level's entries (`α = 1`: 11–16 %). Multigrid's iterations over
/// the `bench_solver` table were the same with `2⁻¹⁰`, `10⁻³`, `2·10⁻³` and `10⁻⁴`; `4·10⁻³`
/// cost up to 3 (`α = 0.001`, `γ = 1`: 9 → 12).
pub const DROP_TOLERANCE: f32 = 1.0 / 1024.0;

/// `x` rounded to bfloat16, to nearest with ties to even (no NaN reaches here: a factor
/// holds finite numbers).
fn to_bf16(x: f32) -> u16 {
    let bits = x.to_bits();
    let rounding = 0x7fff + ((bits >> 16) & 1);
    (bits.wrapping_add(rounding) >> 16) as u16
}

#[inline(always)]
fn widen(h: u16) -> f32 {
    f32::from_bits((h as u32) << 16)
}

impl Bf16Factor {
    /// Rounds an `f32` factor's entries and drops the rows below [`DROP_TOLERANCE`]; its
    /// symbolic analysis is shared.
    pub fn new(factor: &CholeskyFactor<f32>) -> Self {
        Self::dropping(factor, DROP_TOLERANCE)
    }

    /// [`Self::new`] with rows dropped below `tolerance` times their pivot (none at 0).
    fn dropping(factor: &CholeskyFactor<f32>, tolerance: f32) -> Self {
        let (values, kept, split) = match factor.symbolic().raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let (kept, values) = KeptRows::rounding(s, factor.values(), tolerance);
                let split = TreeSplit::of(&Supernodes::of(s, &kept));
                (values, Some(kept), split)
            }
            SymbolicCholeskyRaw::Simplicial(_) => (
                factor.values().iter().map(|&v| to_bf16(v)).collect(),
                None,
                None,
            ),
        };
        Self {
            symbolic: factor.symbolic().clone(),
            values,
            kept,
            split,
        }
    }

    /// Bytes a factor of `symbolic`'s pattern takes at most: every entry kept, and which rows
    /// are (a bit per panel row, two offsets per supernode).
    pub fn bytes_at_most(symbolic: &SymbolicCholesky<usize>) -> usize {
        let bookkeeping = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let supernodes = s.supernode_begin().len();
                let words: usize = (0..supernodes)
                    .map(|k| s.supernode(k).pattern().len().div_ceil(64))
                    .sum();
                8 * words + 16 * (supernodes + 1)
            }
            SymbolicCholeskyRaw::Simplicial(_) => 0,
        };
        2 * symbolic.len_val() + bookkeeping
    }

    /// Stored entries of `L` (bfloat16 has no subnormals left once `f32`'s were flushed).
    pub fn entries(&self) -> FactorEntries {
        FactorEntries {
            stored: self.values.len(),
            subnormal: self
                .values
                .iter()
                .filter(|&&h| widen(h).is_subnormal())
                .count(),
        }
    }

    /// Overwrites `x` with `(L Lᵀ)⁻¹ x`, in `f32` arithmetic; `work` holds one permuted copy
    /// of `x` and the supernodes' scratch (reused across solves).
    pub fn solve_in_place(&self, x: &mut [f64], work: &mut Vec<f32>) {
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
                let structure = Supernodes::of(s, kept);
                match &self.split {
                    Some(split) => split.solve(&structure, &self.values, y, scratch),
                    None => {
                        structure.lower_solve(&self.values, y, scratch);
                        structure.upper_solve(&self.values, y, scratch);
                    }
                }
            }
            SymbolicCholeskyRaw::Simplicial(s) => {
                let (columns, rows) = (s.col_ptr(), s.row_idx());
                simplicial_lower_solve(columns, rows, &self.values, y);
                simplicial_upper_solve(columns, rows, &self.values, y);
            }
        }
        gather(x, y, perm.map(|(_, inverse)| inverse), f64::from);
    }
}

/// `to[i] = convert(from[index[i]])`, or `convert(from[i])` without an index: the permutation
/// into the factor's ordering and back out of it.
fn gather<S: Copy, T>(to: &mut [T], from: &[S], index: Option<&[usize]>, convert: impl Fn(S) -> T) {
    match index {
        Some(index) => (to.iter_mut().zip(index)).for_each(|(t, &i)| *t = convert(from[i])),
        None => (to.iter_mut().zip(from)).for_each(|(t, &f)| *t = convert(f)),
    }
}

/// faer's supernodal layout, less the dropped rows: supernode `s` holds columns
/// `begin[s]..end[s]`, its values column-major with `w + m` rows (`w` its columns: the dense
/// lower triangle on top; `m` the rows of its pattern below that the factor keeps) from
/// `kept.value_start[s]`.
struct Supernodes<'a> {
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    begin: &'a [usize],
    end: &'a [usize],
    kept: &'a KeptRows,
}

/// Which rows of each supernode's pattern below its triangle a factor keeps (one bit per
/// row, from word `word_start[s]`), and where the supernode's values start.
struct KeptRows {
    bits: Vec<u64>,
    word_start: Vec<usize>,
    value_start: Vec<usize>,
}

impl KeptRows {
    /// Rounds `values` to bfloat16, keeping a row below a supernode's triangle only where one of
    /// its entries is at least `tolerance` times the row's pivot.
    fn rounding(
        symbolic: &SymbolicSupernodalCholesky<usize>,
        values: &[f32],
        tolerance: f32,
    ) -> (Self, Vec<u16>) {
        let (begin, end, start) = (
            symbolic.supernode_begin(),
            symbolic.supernode_end(),
            symbolic.col_ptr_for_val(),
        );
        let pivots = Self::pivots(symbolic, values);
        let mut kept = Self {
            bits: Vec::new(),
            word_start: vec![0],
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
                rounded.extend(column[..w].iter().map(|&v| to_bf16(v)));
                rounded.extend(rows.iter().map(|&i| to_bf16(column[w + i])));
            }
            kept.word_start.push(kept.bits.len());
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

    /// `visit(k, r)` for the `k`-th kept row, `r`; a word whose rows are all kept is walked
    /// without its bits (the common case where nothing is dropped).
    #[inline(always)]
    fn for_each(&self, mut visit: impl FnMut(usize, usize)) {
        if self.len == self.pattern.len() {
            self.pattern
                .iter()
                .enumerate()
                .for_each(|(k, &r)| visit(k, r));
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
    fn of(symbolic: &'a SymbolicSupernodalCholesky<usize>, kept: &'a KeptRows) -> Self {
        Self {
            symbolic,
            begin: symbolic.supernode_begin(),
            end: symbolic.supernode_end(),
            kept,
        }
    }

    fn len(&self) -> usize {
        self.begin.len()
    }

    /// `(first column, width, rows below, values)` of supernode `s`.
    fn supernode<'v>(&self, s: usize, values: &'v [u16]) -> (usize, usize, Below<'a>, &'v [u16]) {
        let (w, kept) = (self.end[s] - self.begin[s], self.kept);
        let values = &values[kept.value_start[s]..kept.value_start[s + 1]];
        let below = Below {
            pattern: self.symbolic.supernode(s).pattern(),
            bits: &kept.bits[kept.word_start[s]..kept.word_start[s + 1]],
            len: values.len() / w - w,
        };
        (self.begin[s], w, below, values)
    }

    /// `y ← L⁻¹ y`: per supernode, the dense triangle, then its rows below take
    /// `L_below y_s` off (gathered in `scratch`).
    fn lower_solve(&self, values: &[u16], y: &mut [f32], scratch: &mut [f32]) {
        let mut columns = Columns::all(y);
        self.lower_solve_part(0..self.len(), values, &mut columns, scratch);
    }

    /// [`Self::lower_solve`] over the supernodes `part`, whose columns and descendants' are
    /// `columns.own`; what they take off their ancestors' columns is added to `columns.beyond`.
    fn lower_solve_part(
        &self,
        part: Range<usize>,
        values: &[u16],
        columns: &mut Columns<'_>,
        scratch: &mut [f32],
    ) {
        for s in part {
            let (first, w, below, l) = self.supernode(s, values);
            let first = first - columns.offset;
            let y = &mut *columns.own;
            let ld = w + below.len();
            let update = &mut scratch[..below.len()];
            update.fill(0.0);
            for j in 0..w {
                let column = &l[j * ld..(j + 1) * ld];
                let yj = y[first + j] / widen(column[j]);
                y[first + j] = yj;
                axpy(&mut y[first + j + 1..first + w], &column[j + 1..w], -yj);
                axpy(update, &column[w..], yj);
            }
            below.for_each(|k, r| columns.take_off(r, update[k]));
        }
    }

    /// `y ← L⁻ᵀ y`: supernodes in reverse, each column's dot product with the rows below
    /// (gathered once per supernode) and the triangle's later columns.
    fn upper_solve(&self, values: &[u16], y: &mut [f32], scratch: &mut [f32]) {
        self.upper_solve_part(0..self.len(), values, (y, 0), (&[], 0), scratch);
    }

    /// [`Self::upper_solve`] over the supernodes `part`, whose columns and descendants' are
    /// `own` (from column `offset`), reading their ancestors' solved columns in `beyond` (from
    /// column `beyond_start`).
    fn upper_solve_part(
        &self,
        part: Range<usize>,
        values: &[u16],
        (own, offset): (&mut [f32], usize),
        (beyond, beyond_start): (&[f32], usize),
        scratch: &mut [f32],
    ) {
        let end = offset + own.len();
        for s in part.rev() {
            let (first, w, below, l) = self.supernode(s, values);
            let first = first - offset;
            let ld = w + below.len();
            let gathered = &mut scratch[..below.len()];
            below.for_each(|k, r| {
                gathered[k] = match r < end {
                    true => own[r - offset],
                    false => beyond[r - beyond_start],
                }
            });
            for j in (0..w).rev() {
                let column = &l[j * ld..(j + 1) * ld];
                let within = dot(&column[j + 1..w], &own[first + j + 1..first + w]);
                let sum = within + dot(&column[w..], gathered);
                own[first + j] = (own[first + j] - sum) / widen(column[j]);
            }
        }
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

    /// `y_r −= u`.
    fn take_off(&mut self, r: usize, u: f32) {
        match r < self.offset + self.own.len() {
            true => self.own[r - self.offset] -= u,
            false => self.beyond[r - self.beyond_start] += u,
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
    fn solve(
        &self,
        supernodes: &Supernodes<'_>,
        values: &[u16],
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
struct SplitSolve<'a> {
    split: &'a TreeSplit,
    supernodes: &'a Supernodes<'a>,
    values: &'a [u16],
    second: usize,
    top: usize,
}

impl SplitSolve<'_> {
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

/// Lanes of the widened sums: enough independent accumulators for the compiler to keep
/// a vector register's worth of products in flight.
const LANES: usize = 16;

/// `update += l · a`.
fn axpy(update: &mut [f32], l: &[u16], a: f32) {
    let mut u = update.chunks_exact_mut(LANES);
    let mut h = l.chunks_exact(LANES);
    for (u, h) in (&mut u).zip(&mut h) {
        for k in 0..LANES {
            u[k] += widen(h[k]) * a;
        }
    }
    for (u, &h) in u.into_remainder().iter_mut().zip(h.remainder()) {
        *u += widen(h) * a;
    }
}

/// `l · g`.
fn dot(l: &[u16], g: &[f32]) -> f32 {
    let mut lanes = [0.0f32; LANES];
    let (h, v) = (l.chunks_exact(LANES), g.chunks_exact(LANES));
    let tail: f32 = (h.remainder().iter())
        .zip(v.remainder())
        .map(|(&h, &v)| widen(h) * v)
        .sum();
    for (h, v) in h.zip(v) {
        for k in 0..LANES {
            lanes[k] += widen(h[k]) * v[k];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// `y ← L⁻¹ y` for faer's simplicial (CSC, diagonal first in each column) layout.
fn simplicial_lower_solve(columns: &[usize], rows: &[usize], values: &[u16], y: &mut [f32]) {
    for j in 0..y.len() {
        let range = columns[j]..columns[j + 1];
        let yj = y[j] / widen(values[range.start]);
        y[j] = yj;
        for (&r, &h) in rows[range.clone()].iter().zip(&values[range]).skip(1) {
            y[r] -= widen(h) * yj;
        }
    }
}

/// `y ← L⁻ᵀ y` for the simplicial layout.
fn simplicial_upper_solve(columns: &[usize], rows: &[usize], values: &[u16], y: &mut [f32]) {
    for j in (0..y.len()).rev() {
        let range = columns[j]..columns[j + 1];
        let sum: f32 = (rows[range.clone()].iter().zip(&values[range.clone()]))
            .skip(1)
            .map(|(&r, &h)| widen(h) * y[r])
            .sum();
        y[j] = (y[j] - sum) / widen(values[range.start]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::cholesky::analyze;
    use faer::sparse::{SparseColMat, Triplet};
    use faer::Par;

    /// A connection Laplacian plus mass on an `n1 × n2` periodic grid (two DOFs per vertex,
    /// each edge's block a rotation, as for tangent fields), `diagonal` on the diagonal
    /// (`4 + mass`): symmetric positive definite.
    fn grid_block(n1: usize, n2: usize, diagonal: f64) -> SparseColMat<usize, f64> {
        let vertex = |i: usize, j: usize| (i % n1) * n2 + j % n2;
        let mut triplets = Vec::new();
        for i in 0..n1 {
            for j in 0..n2 {
                let v = vertex(i, j);
                for d in 0..2 {
                    triplets.push(Triplet::new(2 * v + d, 2 * v + d, diagonal));
                }
                for (k, w) in [vertex(i + 1, j), vertex(i, j + 1)].into_iter().enumerate() {
                    let angle = 0.3 * (v + k) as f64;
                    let (c, s) = (angle.cos(), angle.sin());
                    for (a, b, x) in [(0, 0, c), (0, 1, -s), (1, 0, s), (1, 1, c)] {
                        triplets.push(Triplet::new(2 * v + a, 2 * w + b, -x));
                        triplets.push(Triplet::new(2 * w + b, 2 * v + a, -x));
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(2 * n1 * n2, 2 * n1 * n2, &triplets).unwrap()
    }

    /// The `f32` factor of [`grid_block`] with a small mass (diagonal 4.1): `L` decays slowly.
    fn grid_factor(n1: usize, n2: usize) -> CholeskyFactor<f32> {
        mass_factor(n1, n2, 4.1)
    }

    /// The `f32` factor of [`grid_block`].
    fn mass_factor(n1: usize, n2: usize, diagonal: f64) -> CholeskyFactor<f32> {
        let block = grid_block(n1, n2, diagonal);
        let symbolic = analyze(block.symbolic(), 2);
        CholeskyFactor::<f32>::new(&symbolic, block.as_ref(), Par::Seq).unwrap()
    }

    /// `sin(0.37 (i + shift))` for `i < n`: a right-hand side with every column's share.
    fn sines(n: usize, shift: usize) -> Vec<f64> {
        (0..n).map(|i| (0.37 * (i + shift) as f64).sin()).collect()
    }

    /// `‖x − y‖ / ‖y‖`.
    fn relative_difference(x: &[f64], y: &[f64]) -> f64 {
        let squared: f64 = x.iter().zip(y).map(|(x, y)| (x - y) * (x - y)).sum();
        (squared / y.iter().map(|y| y * y).sum::<f64>()).sqrt()
    }

    /// `factor`'s entries with every row below a supernode's triangle zeroed where all its
    /// entries there are below `tolerance` times the row's pivot, and how many were zeroed:
    /// the dropping rule, entry by entry in faer's own layout.
    fn zero_small_rows(factor: &CholeskyFactor<f32>, tolerance: f32) -> (Vec<f32>, usize) {
        let mut values = factor.values().to_vec();
        let SymbolicCholeskyRaw::Supernodal(symbolic) = factor.symbolic().raw() else {
            return (values, 0);
        };
        let start = symbolic.col_ptr_for_val();
        let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
        let ld = |s: usize| end[s] - begin[s] + symbolic.supernode(s).pattern().len();
        let pivot = |c: usize| {
            let s = end.partition_point(|&e| e <= c);
            let j = c - begin[s];
            factor.values()[start[s] + j * ld(s) + j]
        };
        let mut zeroed = 0;
        for s in 0..begin.len() {
            let w = end[s] - begin[s];
            for (i, &r) in symbolic.supernode(s).pattern().iter().enumerate() {
                let at = |j: usize| start[s] + j * ld(s) + w + i;
                if (0..w).all(|j| values[at(j)].abs() < tolerance * pivot(r)) {
                    (0..w).for_each(|j| values[at(j)] = 0.0);
                    zeroed += w;
                }
            }
        }
        (values, zeroed)
    }

    /// The bfloat16 solve equals faer's `f32` solve with the same entries (rounded, the small
    /// rows zeroed), up to `f32` rounding, for the supernodal and the simplicial layout, with
    /// and without dropping. A large mass (diagonal 40) makes `L` decay fast, and most of it
    /// drops; the stored entries are exactly those not dropped.
    #[test]
    fn solves_as_faer_does_with_the_rounded_entries() {
        for (n1, n2, supernodal) in [(64, 48, true), (8, 6, false)] {
            for (diagonal, tolerance) in [(4.1, 0.0), (4.1, DROP_TOLERANCE), (40.0, DROP_TOLERANCE)]
            {
                let case = format!("{n1}×{n2}, diagonal {diagonal}, tolerance {tolerance}");
                let factor = mass_factor(n1, n2, diagonal);
                let is_supernodal =
                    matches!(factor.symbolic().raw(), SymbolicCholeskyRaw::Supernodal(_));
                assert_eq!(is_supernodal, supernodal, "{case}: layout");
                let compressed = Bf16Factor::dropping(&factor, tolerance);
                let (kept, zeroed) = zero_small_rows(&factor, tolerance);
                assert_eq!(
                    compressed.values.len(),
                    kept.len() - zeroed,
                    "{case}: stored"
                );
                if diagonal > 10.0 && supernodal {
                    assert!(
                        2 * zeroed > kept.len(),
                        "{case}: {zeroed} of {} dropped",
                        kept.len()
                    );
                }
                let rounded = kept.iter().map(|&v| widen(to_bf16(v))).collect();
                let reference = CholeskyFactor::from_parts(factor.symbolic().clone(), rounded);
                let b = sines(factor.symbolic().nrows(), 0);
                let (mut x, mut y) = (b.clone(), b.clone());
                compressed.solve_in_place(&mut x, &mut Vec::new());
                reference.solve_in_place(&mut y, Par::Seq);
                let relative = relative_difference(&x, &y);
                assert!(relative < 1e-5, "{case}: differs from faer by {relative:e}");
            }
        }
    }

    /// Bytes `factor` holds (its entries and which rows it keeps).
    fn held_bytes(factor: &Bf16Factor) -> usize {
        let kept = factor.kept.as_ref().map_or(0, |k| {
            8 * (k.bits.len() + k.word_start.len() + k.value_start.len())
        });
        2 * factor.values.len() + kept
    }

    /// A factor's bytes stay within [`Bf16Factor::bytes_at_most`], the memory budget's count,
    /// with nothing dropped (equal then) and with most rows dropped (about half of it).
    #[test]
    fn bytes_stay_within_the_budget_count() {
        for (diagonal, tolerance) in [(4.1, 0.0), (40.0, DROP_TOLERANCE)] {
            let factor = mass_factor(64, 48, diagonal);
            let bound = Bf16Factor::bytes_at_most(factor.symbolic());
            let bytes = held_bytes(&Bf16Factor::dropping(&factor, tolerance));
            match tolerance == 0.0 {
                true => assert_eq!(bytes, bound, "diagonal {diagonal}"),
                false => assert!(
                    3 * bytes < 2 * bound,
                    "diagonal {diagonal}: {bytes} of {bound}"
                ),
            }
        }
    }

    /// Dropping below [`DROP_TOLERANCE`] moves a solve no further from the exact `f32` one
    /// than rounding to bfloat16 does, where it drops most of `L` (diagonal 40) and where it
    /// drops little (4.1).
    #[test]
    fn dropping_costs_no_more_than_rounding() {
        for diagonal in [4.1, 40.0] {
            let factor = mass_factor(64, 48, diagonal);
            let b = sines(factor.symbolic().nrows(), 3);
            let solve = |tolerance: Option<f32>| {
                let mut x = b.clone();
                match tolerance {
                    Some(t) => {
                        Bf16Factor::dropping(&factor, t).solve_in_place(&mut x, &mut Vec::new())
                    }
                    None => factor.solve_in_place(&mut x, Par::Seq),
                }
                x
            };
            let exact = solve(None);
            let rounding = relative_difference(&solve(Some(0.0)), &exact);
            let dropping = relative_difference(&solve(Some(DROP_TOLERANCE)), &exact);
            println!(
                "diagonal {diagonal}: rounding {rounding:e}, rounding and dropping {dropping:e}"
            );
            assert!(
                dropping <= 2.0 * rounding,
                "diagonal {diagonal}: {dropping:e} against {rounding:e}"
            );
        }
    }

    /// On a nested-dissection order the elimination tree splits into two subtrees of at least
    /// a tenth of the entries each, and the solve over them on two threads equals the
    /// sequential one up to `f32` rounding (the subtrees' sums on the top's columns are added
    /// in another order).
    #[test]
    fn two_subtrees_solve_as_one() {
        let factor = grid_factor(64, 48);
        let split = Bf16Factor::new(&factor);
        let parts = split.split.clone().expect("a grid's tree splits in two");
        let entries = |r: &Range<usize>| match factor.symbolic().raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                s.col_ptr_for_val()[r.end] - s.col_ptr_for_val()[r.start]
            }
            _ => unreachable!(),
        };
        let all = split.values.len();
        for part in [&parts.first, &parts.second] {
            assert!(10 * entries(part) >= all, "{part:?} holds too few of {all}");
        }
        let sequential = Bf16Factor {
            split: None,
            ..Bf16Factor::new(&factor)
        };
        let b = sines(factor.symbolic().nrows(), 0);
        let (mut x, mut y) = (b.clone(), b);
        split.solve_in_place(&mut x, &mut Vec::new());
        sequential.solve_in_place(&mut y, &mut Vec::new());
        let largest = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let difference = (x.iter().zip(&y)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            difference <= 1e-5 * largest,
            "differs by {difference:e} of {largest:e}"
        );
    }

    /// Slab solves from a parallel loop, each splitting its tree over two threads
    /// (`rayon::join`): a thread waiting for its other half runs another slab's solve, which
    /// must not find the thread's scratch buffer borrowed ("RefCell already borrowed" on 16
    /// threads before the buffer was taken out for the solve). Each result equals the lone
    /// solve's exactly.
    #[test]
    fn nested_solves_on_one_thread_share_no_scratch() {
        use crate::linalg::factor::SlabFactor;
        use rayon::prelude::*;
        let factor = Bf16Factor::new(&grid_factor(64, 48));
        assert!(factor.split.is_some(), "the solve splits its tree");
        let n = factor.symbolic.nrows();
        let lone: Vec<Vec<f64>> = (0..64)
            .map(|k| {
                let mut x = sines(n, k);
                factor.solve_in_place(&mut x, &mut Vec::new());
                x
            })
            .collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(8)
            .build()
            .unwrap();
        for _ in 0..20 {
            let solved: Vec<Vec<f64>> = pool.install(|| {
                (0..64)
                    .into_par_iter()
                    .map(|k| {
                        let mut x = sines(n, k);
                        SlabFactor::solve(&factor, &mut x);
                        x
                    })
                    .collect()
            });
            assert_eq!(solved, lone);
        }
    }

    /// Rounding to bfloat16 is to nearest, ties to even, on the top 16 bits.
    #[test]
    fn rounds_to_nearest_even() {
        assert_eq!(to_bf16(1.0), 0x3f80);
        assert_eq!(widen(to_bf16(1.0 + 1.0 / 512.0)), 1.0); // a tie: down to even
        assert_eq!(widen(to_bf16(1.0 + 3.0 / 512.0)), 1.0 + 4.0 / 512.0); // a tie: up to even
        assert_eq!(widen(to_bf16(1.0 + 1.1 / 256.0)), 1.0 + 1.0 / 128.0);
        assert_eq!(widen(to_bf16(-2.5e-30)).signum(), -1.0);
        let x = 1234.567f32;
        assert!(((widen(to_bf16(x)) - x) / x).abs() <= 1.0 / 256.0);
    }

    /// Timing of slab solves, bfloat16 against faer's `f32`: 20 copies of a factor (more than
    /// the last-level cache holds), solved in turn on each of two threads, for a block whose
    /// `L` decays slowly (diagonal 4.1: little drops) and one whose `L` decays fast (40)
    /// (`cargo test --release bfloat::tests::timing -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn timing() {
        for diagonal in [4.1, 40.0] {
            println!("diagonal {diagonal}");
            time_solves(&mass_factor(128, 95, diagonal));
        }
    }

    fn time_solves(factor: &CholeskyFactor<f32>) {
        use rayon::prelude::*;
        let n = factor.symbolic().nrows();
        let copies: Vec<CholeskyFactor<f32>> = (0..20)
            .map(|_| {
                CholeskyFactor::from_parts(factor.symbolic().clone(), factor.values().to_vec())
            })
            .collect();
        let compressed: Vec<Bf16Factor> = copies.iter().map(Bf16Factor::new).collect();
        for round in 0..3 {
            let start = std::time::Instant::now();
            (0..2).into_par_iter().for_each(|_| {
                let mut x = sines(n, 0);
                let mut work = factor.workspace(Par::Seq);
                for f in copies.iter().cycle().take(100) {
                    f.solve_with(&mut x, &mut work, Par::Seq);
                }
            });
            let f32_ms = start.elapsed().as_secs_f64() * 10.0;
            let start = std::time::Instant::now();
            (0..2).into_par_iter().for_each(|_| {
                let mut x = sines(n, 0);
                let mut work = Vec::new();
                for f in compressed.iter().cycle().take(100) {
                    f.solve_in_place(&mut x, &mut work);
                }
            });
            let bf16_ms = start.elapsed().as_secs_f64() * 10.0;
            println!(
                "round {round}: per solve on each of 2 threads: f32 {f32_ms:.3} ms, bf16 \
                 {bf16_ms:.3} ms ({} entries, {} kept)",
                factor.values().len(),
                compressed[0].values.len()
            );
        }
    }
}
