//! Preconditioners for the block-tridiagonal space-time system.

use super::cholesky::CholeskyFactor;
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
pub struct SlabGaussSeidel<'a> {
    system: &'a SpaceTimeSystem,
    factors: Vec<CholeskyFactor>,
    par: Par,
}

impl<'a> SlabGaussSeidel<'a> {
    /// `factors[s]` must factor `system.block(s)`; slab solves run with parallelism `par`.
    pub fn new(system: &'a SpaceTimeSystem, factors: Vec<CholeskyFactor>, par: Par) -> Self {
        Self {
            system,
            factors,
            par,
        }
    }
}

impl Preconditioner for SlabGaussSeidel<'_> {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        let n = self.system.slab_dimension();
        let n_slabs = self.system.n_slabs();
        z.copy_from_slice(r);
        let mut coupled = vec![0.0; n];
        for s in 0..n_slabs {
            let (done, rest) = z.split_at_mut(s * n);
            let zs = &mut rest[..n];
            if s > 0 {
                coupled.fill(0.0);
                self.system
                    .link_mul(s - 1, &done[(s - 1) * n..], &mut coupled);
                zs.iter_mut().zip(&coupled).for_each(|(z, c)| *z -= c);
            }
            self.factors[s].solve_in_place(zs, self.par);
        }
        for s in (0..n_slabs.saturating_sub(1)).rev() {
            let (head, tail) = z.split_at_mut((s + 1) * n);
            coupled.fill(0.0);
            self.system.link_transpose_mul(s, &tail[..n], &mut coupled);
            self.factors[s].solve_in_place(&mut coupled, self.par);
            head[s * n..]
                .iter_mut()
                .zip(&coupled)
                .for_each(|(z, c)| *z -= c);
        }
    }
}
