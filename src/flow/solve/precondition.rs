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

/// Symmetric block Gauss–Seidel in time: `P = (D + L) D⁻¹ (D + Lᵀ)` with `D` the slab blocks
/// (exact Cholesky factors) and `L` the links below the diagonal. A forward sweep
/// `y_s = D_s⁻¹ (r_s − X_{s−1} y_{s−1})` then a backward sweep `z_s = y_s − D_s⁻¹ X_sᵀ z_{s+1}`.
///
/// The sweep is sequential in time, so the slabs are split into `chunks` contiguous runs swept
/// in parallel, each ignoring the links that leave it (block Jacobi between chunks): one core
/// per chunk for a few more iterations.
pub struct SlabGaussSeidel<'a, T: Precision> {
    system: &'a SpaceTimeSystem,
    factors: Vec<CholeskyFactor<T>>,
    slabs_per_chunk: usize,
}

impl<'a, T: Precision> SlabGaussSeidel<'a, T> {
    /// `factors[s]` must factor `system.block(s)`.
    pub fn new(
        system: &'a SpaceTimeSystem,
        factors: Vec<CholeskyFactor<T>>,
        chunks: usize,
    ) -> Self {
        let slabs_per_chunk = system.n_slabs().div_ceil(chunks.max(1));
        Self {
            system,
            factors,
            slabs_per_chunk,
        }
    }

    /// The sweep over slabs `first..first + z.len() / n`, with `z = r` on entry.
    fn sweep(&self, first: usize, z: &mut [f64]) {
        let n = self.system.slab_dimension();
        let count = z.len() / n;
        let mut coupled = vec![0.0; n];
        for k in 0..count {
            let (done, rest) = z.split_at_mut(k * n);
            let zs = &mut rest[..n];
            if k > 0 {
                coupled.fill(0.0);
                self.system
                    .link_mul(first + k - 1, &done[(k - 1) * n..], &mut coupled);
                zs.iter_mut().zip(&coupled).for_each(|(z, c)| *z -= c);
            }
            self.factors[first + k].solve_in_place(zs, Par::Seq);
        }
        for k in (0..count.saturating_sub(1)).rev() {
            let (head, tail) = z.split_at_mut((k + 1) * n);
            coupled.fill(0.0);
            self.system
                .link_transpose_mul(first + k, &tail[..n], &mut coupled);
            self.factors[first + k].solve_in_place(&mut coupled, Par::Seq);
            head[k * n..]
                .iter_mut()
                .zip(&coupled)
                .for_each(|(z, c)| *z -= c);
        }
    }
}

impl<T: Precision> Preconditioner for SlabGaussSeidel<'_, T> {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        let chunk = self.slabs_per_chunk * self.system.slab_dimension();
        z.copy_from_slice(r);
        z.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, zc)| self.sweep(c * self.slabs_per_chunk, zc));
    }
}
