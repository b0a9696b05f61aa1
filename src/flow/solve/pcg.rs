//! Preconditioned conjugate gradients on the space-time system, with a rayon matvec.

use super::{SolveEvent, SolveObserver};
use crate::flow::system::{dot, SpaceTimeSystem};
use crate::flow::FlowError;
use rayon::prelude::*;

/// `z ≈ A⁻¹ r` for a symmetric positive definite approximation of `A⁻¹`.
pub trait Preconditioner: Sync {
    fn apply(&self, r: &[f64], z: &mut [f64]);
}

/// When CG stops, and how its iterations are numbered in the reports.
#[derive(Clone, Copy, Debug)]
pub struct Stop {
    /// Stop when `‖b − Ax‖ ≤ tolerance · ‖b‖`.
    pub tolerance: f64,
    /// Iterations counted so far (by an earlier run this one continues); reported numbers
    /// continue from here, and `max_iterations` counts them too.
    pub done: usize,
    pub max_iterations: usize,
    /// `Some((k, n))`: give up after `k` iterations of this run when their rate projects more
    /// than `n` iterations to the tolerance ([`CgOutcome::projected_iterations`]).
    pub give_up: Option<(usize, f64)>,
}

/// Result of a CG run: iterate, iterations (including `Stop::done`), the last recursive
/// residual `‖r‖/‖b‖`, and whether it met the tolerance.
pub struct CgOutcome {
    pub x: Vec<f64>,
    pub iterations: usize,
    pub relative_residual: f64,
    /// `‖r‖/‖b‖` after this run's first iteration (that of `x` for a run of none).
    pub first_residual: f64,
    pub converged: bool,
}

impl CgOutcome {
    /// The iterations this run (after `done_before`) would take to `tolerance`.
    pub fn projected_iterations(&self, tolerance: f64, done_before: usize) -> f64 {
        let ran = self.iterations - done_before;
        projected_iterations(ran, self.first_residual, self.relative_residual)(tolerance)
    }
}

/// Solves `A x = b` from `x` (CG restarted there) until the tolerance or the iteration limit
/// ([`FlowError::Interrupted`] when the observer stops it).
pub fn pcg(
    system: &SpaceTimeSystem,
    b: &[f64],
    mut x: Vec<f64>,
    preconditioner: &dyn Preconditioner,
    stop: Stop,
    observer: &dyn SolveObserver,
) -> Result<CgOutcome, FlowError> {
    let n = b.len();
    let b_norm = dot(b, b).sqrt();
    let mut r = vec![0.0; n];
    system.apply(&x, &mut r);
    r.par_iter_mut().zip(b).for_each(|(r, b)| *r = b - *r);
    let mut relative = dot(&r, &r).sqrt() / b_norm;
    let mut z = vec![0.0; n];
    preconditioner.apply(&r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = dot(&r, &z);
    let mut iteration = stop.done;
    let mut first_residual = relative;
    while relative > stop.tolerance && relative.is_finite() && iteration < stop.max_iterations {
        iteration += 1;
        system.apply(&p, &mut ap);
        let step = rz / dot(&p, &ap);
        axpy(step, &p, &mut x);
        axpy(-step, &ap, &mut r);
        relative = dot(&r, &r).sqrt() / b_norm;
        if iteration == stop.done + 1 {
            first_residual = relative;
        }
        observer.notify(SolveEvent::Iteration {
            iteration,
            relative_residual: relative,
        })?;
        if relative <= stop.tolerance {
            break;
        }
        if let Some((probe, limit)) = stop.give_up {
            let projected = projected_iterations(iteration - stop.done, first_residual, relative);
            if iteration - stop.done == probe && projected(stop.tolerance) > limit {
                break;
            }
        }
        preconditioner.apply(&r, &mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        p.par_iter_mut()
            .zip(&z)
            .for_each(|(p, z)| *p = z + beta * *p);
    }
    Ok(CgOutcome {
        x,
        iterations: iteration,
        relative_residual: relative,
        first_residual,
        converged: relative <= stop.tolerance,
    })
}

/// `y += a x`.
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.par_iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

/// The iterations to a tolerance at the rate from iteration 1 to `ran` (the first drop is
/// typically steeper than the rest): `∞` without progress.
fn projected_iterations(ran: usize, first: f64, last: f64) -> impl Fn(f64) -> f64 {
    let rate = (last / first).powf(1.0 / (ran as f64 - 1.0));
    move |tolerance| match rate < 1.0 && ran > 1 {
        true => 1.0 + (tolerance / first).ln() / rate.ln(),
        false => f64::INFINITY,
    }
}
