//! Cholesky factors stored in bfloat16 ([`Bf16`]), for preconditioners where reading less
//! of `L` is worth its rounding.
//!
//! A slab solve of the flow's preconditioners streams its factor `L` twice (`L y = b`, then
//! `Lᵀ x = y`) and does two flops per entry read. Storing `L` in bfloat16 (the top half of an
//! `f32`: 8 significant bits, `f32`'s exponent range) halves what each solve reads and what the
//! factors hold. The factor is computed in `f32` by faer and rounded once
//! ([`PackedFactor::packing`]); the solves ([`super::packed`]) widen each entry back to `f32` (a
//! 16-bit shift) and accumulate in `f32`.
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

use super::packed::{Entry, PackedFactor};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use std::sync::Arc;

/// A Cholesky factor in bfloat16, its small rows dropped.
pub type Bf16Factor = PackedFactor<Bf16>;

/// A bfloat16 number: the top 16 bits of an `f32`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(transparent)]
pub struct Bf16(u16);

impl Entry for Bf16 {
    const BYTES: usize = 2;

    /// Rounded to nearest, ties to even (no NaN reaches here: a factor holds finite numbers).
    fn narrow(x: f32) -> Self {
        let bits = x.to_bits();
        let rounding = 0x7fff + ((bits >> 16) & 1);
        Self((bits.wrapping_add(rounding) >> 16) as u16)
    }

    #[inline(always)]
    fn widen(self) -> f32 {
        f32::from_bits((self.0 as u32) << 16)
    }
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

impl Bf16Factor {
    /// An `f32` factor's entries `values` (faer's layout for `symbolic`) rounded to bfloat16,
    /// its rows below [`DROP_TOLERANCE`] dropped.
    pub fn rounding(symbolic: &Arc<SymbolicCholesky<usize>>, values: &[f32]) -> Self {
        Self::packing(symbolic, values, DROP_TOLERANCE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::cholesky::CholeskyFactor;
    use crate::linalg::packed::tests::{mass_factor, relative_difference, sines};
    use crate::linalg::packed::Halves;
    use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
    use faer::Par;

    /// `x` rounded to bfloat16 and back.
    fn round(x: f32) -> f32 {
        Bf16::narrow(x).widen()
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
                let compressed = Bf16Factor::packing(factor.symbolic(), factor.values(), tolerance);
                let (kept, zeroed) = zero_small_rows(&factor, tolerance);
                assert_eq!(
                    compressed.column_major_values().len(),
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
                let rounded = kept.iter().map(|&v| round(v)).collect();
                let reference = CholeskyFactor::from_parts(factor.symbolic().clone(), rounded);
                let b = sines(factor.symbolic().nrows(), 0);
                let (mut x, mut y) = (b.clone(), b.clone());
                compressed.solve_in_place(&mut x, &mut Vec::new(), Halves::Parallel);
                reference.solve_in_place(&mut y, Par::Seq);
                let relative = relative_difference(&x, &y);
                assert!(relative < 1e-5, "{case}: differs from faer by {relative:e}");
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
                    Some(t) => Bf16Factor::packing(factor.symbolic(), factor.values(), t)
                        .solve_in_place(&mut x, &mut Vec::new(), Halves::Parallel),
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

    /// Rounding to bfloat16 is to nearest, ties to even, on the top 16 bits.
    #[test]
    fn rounds_to_nearest_even() {
        assert_eq!(Bf16::narrow(1.0), Bf16(0x3f80));
        assert_eq!(round(1.0 + 1.0 / 512.0), 1.0); // a tie: down to even
        assert_eq!(round(1.0 + 3.0 / 512.0), 1.0 + 4.0 / 512.0); // a tie: up to even
        assert_eq!(round(1.0 + 1.1 / 256.0), 1.0 + 1.0 / 128.0);
        assert_eq!(round(-2.5e-30).signum(), -1.0);
        let x = 1234.567f32;
        assert!(((round(x) - x) / x).abs() <= 1.0 / 256.0);
    }
}
