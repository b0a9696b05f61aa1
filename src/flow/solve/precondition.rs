//! Preconditioners for the block-tridiagonal space-time system.

use super::cholesky::{CholeskyFactor, Precision};
use super::pcg::Preconditioner;
use crate::flow::system::SpaceTimeSystem;
use faer::Par;
use rayon::prelude::*;

/// `z = r / diag(A)`: no setup, no memory, iteration counts grow with refinement.
pub struct Jacobi {
    inverse_diagonal: Vec<f64>,
}

impl Jacobi {
    pub fn new(system: &SpaceTimeSystem) -> Self {
        Self {
            inverse_diagonal: system.diagonal().iter().map(|d| 1.0 / d).collect(),
        }
    }
}

impl Preconditioner for Jacobi {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.par_iter_mut()
            .zip(r)
            .zip(&self.inverse_diagonal)
            .for_each(|((z, r), d)| *z = r * d);
    }
}

/// Exact slab solves swept through time in odd–even order: with `D` the slab blocks
/// (Cholesky factors) and the slabs ordered even first, then odd, `L` the links below the
/// diagonal in that order (odd rows, even columns) and `U = Lᵀ`, the forward sweep applies
/// `(D + L)⁻¹`,
///
/// ```text
/// z_s = D_s⁻¹ r_s (s even),      z_s = D_s⁻¹ (r_s − X_{s−1} z_{s−1} − X_sᵀ z_{s+1}) (s odd),
/// ```
///
/// and the backward sweep `(D + U)⁻¹` the same with the parities exchanged. The slabs of one
/// parity do not touch each other, so each half sweep solves them all in parallel: the sweep
/// is parallel in time however few cores or however many ranks share the slabs, and stays an
/// exact block Gauss–Seidel sweep (of the reordered system).
///
/// Why not the lexicographic sweep split into one contiguous chunk per core (the first
/// release's choice): between chunks it is block *Jacobi*, and where the time coupling
/// dominates the slab blocks (`D_s ≈ c M`, `X_s ≈ −c M` in the dark, textureless parts of a
/// fluorescence recording, where only `γ L` and the coupling remain) block Jacobi maps the
/// error that alternates in time, `(e, −e)`, to about `−(e, −e)`: it does not smooth it, and
/// the coarse levels (constant in time) cannot see it. On the zebrafish recording (2 slabs on
/// 2 cores: one chunk per slab) multigrid in time took 158 iterations with chunks and 6
/// without.
///
/// When the factors of all slabs would not fit in memory, runs of `slabs_per_factor`
/// neighbouring slabs share the factor of their mean block: `D_s` is then replaced by a
/// neighbour average, still symmetric positive definite, so the sweeps remain a valid
/// preconditioner (a weaker one, as the slabs differ).
pub struct SlabSweeps<T: Precision> {
    factors: Vec<CholeskyFactor<T>>,
    slabs_per_factor: usize,
}

/// Which slabs a half sweep solves.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Parity {
    Even = 0,
    Odd = 1,
}

impl<T: Precision> SlabSweeps<T> {
    /// `factors[g]` must factor the mean of blocks `g·slabs_per_factor ..` (up to
    /// `slabs_per_factor` of them) of the `n_slabs` slabs of the system the sweeps are applied
    /// to.
    pub fn new(factors: Vec<CholeskyFactor<T>>, slabs_per_factor: usize, n_slabs: usize) -> Self {
        assert_eq!(
            factors.len(),
            n_slabs.div_ceil(slabs_per_factor),
            "one factor per group"
        );
        Self {
            factors,
            slabs_per_factor,
        }
    }

    fn factor(&self, slab: usize) -> &CholeskyFactor<T> {
        &self.factors[slab / self.slabs_per_factor]
    }

    /// Stored entries of all factors.
    pub fn stored_entries(&self) -> usize {
        self.factors
            .iter()
            .map(CholeskyFactor::stored_entries)
            .sum()
    }

    /// `z ← (D + L)⁻¹ z`: even slabs, then odd slabs with their even neighbours' values.
    pub fn forward(&self, system: &SpaceTimeSystem, z: &mut [f64]) {
        self.half_sweep(system, z, Parity::Even, false);
        self.half_sweep(system, z, Parity::Odd, true);
    }

    /// `z ← (D + U)⁻¹ z`: odd slabs, then even slabs with their odd neighbours' values.
    pub fn backward(&self, system: &SpaceTimeSystem, z: &mut [f64]) {
        self.half_sweep(system, z, Parity::Odd, false);
        self.half_sweep(system, z, Parity::Even, true);
    }

    /// `z ← (D + U)⁻¹ D (D + L)⁻¹ z`, the symmetric Gauss–Seidel sweep: the forward sweep, then
    /// `z_s ← z_s − D_s⁻¹ (X z)_s` for the even slabs (the odd ones keep their values).
    pub fn symmetric(&self, system: &SpaceTimeSystem, z: &mut [f64]) {
        self.forward(system, z);
        if !system.has_links() {
            return;
        }
        let coupled = self.neighbour_terms(system, z, Parity::Even);
        (slabs_of(z, system.slab_dimension(), Parity::Even).into_par_iter())
            .zip(coupled)
            .for_each(|((s, zs), mut c)| {
                self.factor(s).solve_in_place(&mut c, Par::Seq);
                subtract(zs, &c);
            });
    }

    /// Solves the slabs of `parity` in place, after subtracting their neighbours' coupling
    /// when `coupled`.
    fn half_sweep(&self, system: &SpaceTimeSystem, z: &mut [f64], parity: Parity, coupled: bool) {
        let terms =
            (coupled && system.has_links()).then(|| self.neighbour_terms(system, z, parity));
        let slabs = slabs_of(z, system.slab_dimension(), parity);
        slabs.into_par_iter().enumerate().for_each(|(k, (s, zs))| {
            if let Some(terms) = &terms {
                subtract(zs, &terms[k]);
            }
            self.factor(s).solve_in_place(zs, Par::Seq);
        });
    }

    /// `X_{s−1} z_{s−1} + X_sᵀ z_{s+1}` for each slab `s` of `parity`, in order.
    fn neighbour_terms(
        &self,
        system: &SpaceTimeSystem,
        z: &[f64],
        parity: Parity,
    ) -> Vec<Vec<f64>> {
        let n = system.slab_dimension();
        let slabs = system.n_slabs();
        (0..slabs)
            .into_par_iter()
            .filter(|s| s % 2 == parity as usize)
            .map(|s| {
                let mut c = vec![0.0; n];
                if s > 0 {
                    system.link_mul(s - 1, &z[(s - 1) * n..s * n], &mut c);
                }
                if s + 1 < slabs {
                    system.link_transpose_mul(s, &z[(s + 1) * n..(s + 2) * n], &mut c);
                }
                c
            })
            .collect()
    }
}

/// The slabs of `parity` as `(slab, values)`.
fn slabs_of(z: &mut [f64], n: usize, parity: Parity) -> Vec<(usize, &mut [f64])> {
    (z.chunks_mut(n).enumerate())
        .filter(|(s, _)| s % 2 == parity as usize)
        .collect()
}

fn subtract(z: &mut [f64], c: &[f64]) {
    z.iter_mut().zip(c).for_each(|(z, c)| *z -= c);
}

/// Symmetric block Gauss–Seidel in time, `P = (D + L) D⁻¹ (D + Lᵀ)`: one [`SlabSweeps`]
/// forward and back.
pub struct SlabGaussSeidel<'a, T: Precision> {
    system: &'a SpaceTimeSystem,
    sweeps: &'a SlabSweeps<T>,
}

impl<'a, T: Precision> SlabGaussSeidel<'a, T> {
    pub fn new(system: &'a SpaceTimeSystem, sweeps: &'a SlabSweeps<T>) -> Self {
        Self { system, sweeps }
    }
}

impl<T: Precision> Preconditioner for SlabGaussSeidel<'_, T> {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        self.sweeps.symmetric(self.system, z);
    }
}
