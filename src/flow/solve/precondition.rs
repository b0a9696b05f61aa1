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

/// Exact slab solves swept through time: with `D` the slab blocks (Cholesky factors) and `L`
/// the links below the diagonal, the forward sweep applies `(D + L)⁻¹`,
/// `z_s = D_s⁻¹ (r_s − X_{s−1} z_{s−1})`, the backward sweep `(D + Lᵀ)⁻¹`.
///
/// A sweep is sequential in time, so the slabs are split into `chunks` contiguous runs swept
/// in parallel, each ignoring the links that leave it (block Jacobi between chunks): one core
/// per chunk for a few more iterations. Forward and backward sweeps stay each other's
/// transposes.
///
/// When the factors of all slabs would not fit in memory, runs of `slabs_per_factor`
/// neighbouring slabs share the factor of their mean block: `D_s` is then replaced by a
/// neighbour average, still symmetric positive definite, so the sweeps remain a valid
/// preconditioner (a weaker one, as the slabs differ).
pub struct SlabSweeps<T: Precision> {
    factors: Vec<CholeskyFactor<T>>,
    slabs_per_factor: usize,
    slabs_per_chunk: usize,
}

impl<T: Precision> SlabSweeps<T> {
    /// `factors[g]` must factor the mean of blocks `g·slabs_per_factor ..` (up to
    /// `slabs_per_factor` of them) of the `n_slabs` slabs of the system the sweeps are applied
    /// to.
    pub fn new(
        factors: Vec<CholeskyFactor<T>>,
        slabs_per_factor: usize,
        n_slabs: usize,
        chunks: usize,
    ) -> Self {
        assert_eq!(
            factors.len(),
            n_slabs.div_ceil(slabs_per_factor),
            "one factor per group"
        );
        Self {
            factors,
            slabs_per_factor,
            slabs_per_chunk: n_slabs.div_ceil(chunks.max(1)).max(1),
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

    /// `z ← (D + L)⁻¹ z`.
    pub fn forward(&self, system: &SpaceTimeSystem, z: &mut [f64]) {
        self.per_chunk(system, z, |first, zc| self.forward_chunk(system, first, zc));
    }

    /// `z ← (D + Lᵀ)⁻¹ z`.
    pub fn backward(&self, system: &SpaceTimeSystem, z: &mut [f64]) {
        self.per_chunk(system, z, |first, zc| {
            self.backward_chunk(system, first, zc)
        });
    }

    /// `z ← (D + Lᵀ)⁻¹ D (D + L)⁻¹ z`, the symmetric Gauss–Seidel sweep, with the backward
    /// half written as `z_s ← z_s − D_s⁻¹ X_sᵀ z_{s+1}` (no product with `D`).
    pub fn symmetric(&self, system: &SpaceTimeSystem, z: &mut [f64]) {
        self.per_chunk(system, z, |first, zc| {
            self.forward_chunk(system, first, zc);
            let n = system.slab_dimension();
            let mut coupled = vec![0.0; n];
            let mut work = self.factors[0].workspace(Par::Seq);
            let coupled_slabs = if system.has_links() { zc.len() / n } else { 1 };
            for k in (0..coupled_slabs - 1).rev() {
                let (head, tail) = zc.split_at_mut((k + 1) * n);
                coupled.fill(0.0);
                system.link_transpose_mul(first + k, &tail[..n], &mut coupled);
                self.factor(first + k)
                    .solve_with(&mut coupled, &mut work, Par::Seq);
                subtract(&mut head[k * n..], &coupled);
            }
        });
    }

    fn per_chunk(
        &self,
        system: &SpaceTimeSystem,
        z: &mut [f64],
        sweep: impl Fn(usize, &mut [f64]) + Sync,
    ) {
        let chunk = self.slabs_per_chunk * system.slab_dimension();
        z.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, zc)| sweep(c * self.slabs_per_chunk, zc));
    }

    fn forward_chunk(&self, system: &SpaceTimeSystem, first: usize, z: &mut [f64]) {
        let n = system.slab_dimension();
        let mut coupled = vec![0.0; n];
        let mut work = self.factors[0].workspace(Par::Seq);
        for k in 0..z.len() / n {
            let (done, rest) = z.split_at_mut(k * n);
            if k > 0 && system.has_links() {
                coupled.fill(0.0);
                system.link_mul(first + k - 1, &done[(k - 1) * n..], &mut coupled);
                subtract(&mut rest[..n], &coupled);
            }
            self.factor(first + k)
                .solve_with(&mut rest[..n], &mut work, Par::Seq);
        }
    }

    fn backward_chunk(&self, system: &SpaceTimeSystem, first: usize, z: &mut [f64]) {
        let n = system.slab_dimension();
        let count = z.len() / n;
        let mut coupled = vec![0.0; n];
        let mut work = self.factors[0].workspace(Par::Seq);
        for k in (0..count).rev() {
            let (head, tail) = z.split_at_mut((k + 1) * n);
            if k + 1 < count && system.has_links() {
                coupled.fill(0.0);
                system.link_transpose_mul(first + k, &tail[..n], &mut coupled);
                subtract(&mut head[k * n..], &coupled);
            }
            self.factor(first + k)
                .solve_with(&mut head[k * n..], &mut work, Par::Seq);
        }
    }
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
