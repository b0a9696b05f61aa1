//! Preconditioned conjugate gradients on the space-time system, with a rayon matvec.

use super::SolveEvent;
use crate::flow::system::{dot, SpaceTimeSystem};
use rayon::prelude::*;

/// `z ≈ A⁻¹ r` for a symmetric positive definite approximation of `A⁻¹`.
pub trait Preconditioner: Sync {
    fn apply(&self, r: &[f64], z: &mut [f64]);
}

/// Result of a CG run: solution, iterations, and the recursive residual estimate.
pub struct CgOutcome {
    pub x: Vec<f64>,
    pub iterations: usize,
    pub converged: bool,
}

/// Solves `A x = b` from `x = 0` until `‖r‖ ≤ tolerance · ‖b‖` or `max_iterations`.
pub fn pcg(
    system: &SpaceTimeSystem,
    b: &[f64],
    preconditioner: &dyn Preconditioner,
    tolerance: f64,
    max_iterations: usize,
    observer: &(dyn Fn(SolveEvent) + Sync),
) -> CgOutcome {
    let n = b.len();
    let b_norm = dot(b, b).sqrt();
    let mut x = vec![0.0; n];
    let mut r = b.to_vec();
    let mut z = vec![0.0; n];
    preconditioner.apply(&r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = dot(&r, &z);
    for iteration in 1..=max_iterations {
        system.apply(&p, &mut ap);
        let step = rz / dot(&p, &ap);
        axpy(step, &p, &mut x);
        axpy(-step, &ap, &mut r);
        let relative = dot(&r, &r).sqrt() / b_norm;
        observer(SolveEvent::Iteration {
            iteration,
            relative_residual: relative,
        });
        if relative <= tolerance || !relative.is_finite() {
            return CgOutcome {
                x,
                iterations: iteration,
                converged: relative <= tolerance,
            };
        }
        preconditioner.apply(&r, &mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        p.par_iter_mut()
            .zip(&z)
            .for_each(|(p, z)| *p = z + beta * *p);
    }
    CgOutcome {
        x,
        iterations: max_iterations,
        converged: false,
    }
}

/// `y += a x`.
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.par_iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}
