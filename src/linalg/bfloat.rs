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
//! Why written by hand: faer's triangular solves are generic over faer's scalar types, and
//! bfloat16 is not one (nor does any sparse crate solve with a compressed factor). The kernels
//! below walk faer's own symbolic structure, supernodal or simplicial, so the ordering and fill
//! are those of the `f32` factor.

use super::cholesky::{CholeskyFactor, FactorEntries};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use std::sync::Arc;

/// `L Lᵀ ≈ A` with `L` in bfloat16 (the `f32` factor's entries rounded to nearest, ties to
/// even).
pub struct Bf16Factor {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<u16>,
}

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
    /// Rounds an `f32` factor's entries; its symbolic analysis is shared.
    pub fn new(factor: &CholeskyFactor<f32>) -> Self {
        Self {
            symbolic: factor.symbolic().clone(),
            values: factor.values().iter().map(|&v| to_bf16(v)).collect(),
        }
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
        work.resize(2 * n, 0.0);
        let (y, scratch) = work.split_at_mut(n);
        let perm = self.symbolic.perm().map(|p| p.arrays());
        gather(y, x, perm.map(|(forward, _)| forward), |v| v as f32);
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let structure = Supernodes::of(s);
                structure.lower_solve(&self.values, y, scratch);
                structure.upper_solve(&self.values, y, scratch);
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

/// faer's supernodal layout: supernode `s` holds columns `begin[s]..end[s]`, its values
/// column-major with `w + m` rows (`w` its columns: the dense lower triangle on top; `m` the
/// rows of its pattern below) from `value_start[s]`.
struct Supernodes<'a> {
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    begin: &'a [usize],
    end: &'a [usize],
    value_start: &'a [usize],
}

impl<'a> Supernodes<'a> {
    fn of(symbolic: &'a SymbolicSupernodalCholesky<usize>) -> Self {
        Self {
            symbolic,
            begin: symbolic.supernode_begin(),
            end: symbolic.supernode_end(),
            value_start: symbolic.col_ptr_for_val(),
        }
    }

    fn len(&self) -> usize {
        self.begin.len()
    }

    /// `(first column, width, rows below, values)` of supernode `s`.
    fn supernode<'v>(&self, s: usize, values: &'v [u16]) -> (usize, usize, &'a [usize], &'v [u16]) {
        let below = self.symbolic.supernode(s).pattern();
        let values = &values[self.value_start[s]..self.value_start[s + 1]];
        (self.begin[s], self.end[s] - self.begin[s], below, values)
    }

    /// `y ← L⁻¹ y`: per supernode, the dense triangle, then its rows below take
    /// `L_below y_s` off (gathered in `scratch`).
    fn lower_solve(&self, values: &[u16], y: &mut [f32], scratch: &mut [f32]) {
        for s in 0..self.len() {
            let (first, w, below, l) = self.supernode(s, values);
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
            for (&r, u) in below.iter().zip(update.iter()) {
                y[r] -= u;
            }
        }
    }

    /// `y ← L⁻ᵀ y`: supernodes in reverse, each column's dot product with the rows below
    /// (gathered once per supernode) and the triangle's later columns.
    fn upper_solve(&self, values: &[u16], y: &mut [f32], scratch: &mut [f32]) {
        for s in (0..self.len()).rev() {
            let (first, w, below, l) = self.supernode(s, values);
            let ld = w + below.len();
            let gathered = &mut scratch[..below.len()];
            gathered.iter_mut().zip(below).for_each(|(g, &r)| *g = y[r]);
            for j in (0..w).rev() {
                let column = &l[j * ld..(j + 1) * ld];
                let within = dot(&column[j + 1..w], &y[first + j + 1..first + w]);
                let sum = within + dot(&column[w..], gathered);
                y[first + j] = (y[first + j] - sum) / widen(column[j]);
            }
        }
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
    /// each edge's block a rotation, as for tangent fields): symmetric positive definite.
    fn grid_block(n1: usize, n2: usize) -> SparseColMat<usize, f64> {
        let vertex = |i: usize, j: usize| (i % n1) * n2 + j % n2;
        let mut triplets = Vec::new();
        for i in 0..n1 {
            for j in 0..n2 {
                let v = vertex(i, j);
                for d in 0..2 {
                    triplets.push(Triplet::new(2 * v + d, 2 * v + d, 4.1));
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

    /// The `f32` factor of [`grid_block`].
    fn grid_factor(n1: usize, n2: usize) -> CholeskyFactor<f32> {
        let block = grid_block(n1, n2);
        let symbolic = analyze(block.symbolic(), 2);
        CholeskyFactor::<f32>::new(&symbolic, block.as_ref(), Par::Seq).unwrap()
    }

    /// The bfloat16 solve equals faer's `f32` solve with the same (rounded) entries, up to
    /// `f32` rounding, for the supernodal and the simplicial layout.
    #[test]
    fn solves_as_faer_does_with_the_rounded_entries() {
        for (n1, n2, supernodal) in [(64, 48, true), (8, 6, false)] {
            let factor = grid_factor(n1, n2);
            let is_supernodal =
                matches!(factor.symbolic().raw(), SymbolicCholeskyRaw::Supernodal(_));
            assert_eq!(is_supernodal, supernodal, "{n1}×{n2}: layout");
            let compressed = Bf16Factor::new(&factor);
            let rounded: Vec<f32> = compressed.values.iter().map(|&h| widen(h)).collect();
            let reference = CholeskyFactor::from_parts(factor.symbolic().clone(), rounded);
            let b: Vec<f64> = (0..factor.symbolic().nrows())
                .map(|i| (0.37 * i as f64).sin())
                .collect();
            let (mut x, mut y) = (b.clone(), b.clone());
            compressed.solve_in_place(&mut x, &mut Vec::new());
            reference.solve_in_place(&mut y, Par::Seq);
            let norm = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
            let difference: Vec<f64> = x.iter().zip(&y).map(|(x, y)| x - y).collect();
            let relative = norm(&difference) / norm(&y);
            assert!(
                relative < 1e-5,
                "{n1}×{n2}: differs from faer by {relative:e}"
            );
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
    /// the last-level cache holds), solved in turn on each of two threads (`cargo test
    /// --release bfloat::tests::timing -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn timing() {
        use rayon::prelude::*;
        let factor = grid_factor(128, 95);
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
                let mut x: Vec<f64> = (0..n).map(|i| (0.37 * i as f64).sin()).collect();
                let mut work = factor.workspace(Par::Seq);
                for f in copies.iter().cycle().take(100) {
                    f.solve_with(&mut x, &mut work, Par::Seq);
                }
            });
            let f32_ms = start.elapsed().as_secs_f64() * 10.0;
            let start = std::time::Instant::now();
            (0..2).into_par_iter().for_each(|_| {
                let mut x: Vec<f64> = (0..n).map(|i| (0.37 * i as f64).sin()).collect();
                let mut work = Vec::new();
                for f in compressed.iter().cycle().take(100) {
                    f.solve_in_place(&mut x, &mut work);
                }
            });
            let bf16_ms = start.elapsed().as_secs_f64() * 10.0;
            println!(
                "round {round}: per solve on each of 2 threads: f32 {f32_ms:.3} ms, bf16 \
                 {bf16_ms:.3} ms ({} entries)",
                factor.values().len()
            );
        }
    }
}
