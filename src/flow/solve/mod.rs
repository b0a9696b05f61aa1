//! Solving `A u = b` for the space-time system.
//!
//! - **Direct**: one sparse Cholesky of the whole system. Exact, but the factor of a
//!   space-time system grows far faster than the system; used for small problems.
//! - **Slab-wise direct** (`α = ∞`): the slabs decouple; one factorization per slab, in
//!   parallel.
//! - **PCG with slab Gauss–Seidel**: conjugate gradients preconditioned by a symmetric block
//!   Gauss–Seidel sweep in time whose blocks are exact per-slab Cholesky factors (one symbolic
//!   analysis, numeric factorizations in parallel). The factors are stored in single
//!   precision (half the memory and memory traffic; CG itself runs in double precision, so
//!   only the convergence rate could suffer), in double precision when a block is too
//!   ill-conditioned for that. Iteration counts stay flat under spatial refinement; they grow
//!   when the time coupling dominates (small `α`).
//! - **PCG with Jacobi**: no factors at all; the fallback when the slab factors would not fit
//!   the memory budget.

mod cholesky;
mod pcg;
mod precondition;

use super::system::{dot, SpaceTimeSystem};
use super::{FlowError, FlowParams, SolverChoice};
use cholesky::{analyze, CholeskyFactor, Precision};
use faer::Par;
use precondition::{Jacobi, SlabGaussSeidel};
use rayon::prelude::*;
use std::time::Instant;

/// The method that produced a solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverMethod {
    Direct,
    SlabwiseDirect,
    PcgSlabGaussSeidel,
    PcgJacobi,
}

impl std::fmt::Display for SolverMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SolverMethod::Direct => "direct",
            SolverMethod::SlabwiseDirect => "slab-wise direct",
            SolverMethod::PcgSlabGaussSeidel => "PCG (slab Gauss-Seidel)",
            SolverMethod::PcgJacobi => "PCG (Jacobi)",
        })
    }
}

/// Progress reports from a running solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolveEvent {
    /// Factorizing `slabs` diagonal blocks (or the whole system when `slabs == 0`).
    Factorizing { slabs: usize },
    Iteration {
        iteration: usize,
        relative_residual: f64,
    },
}

/// `u` with how it was found.
#[derive(Clone, Debug)]
pub struct Solution {
    pub u: Vec<f64>,
    pub method: SolverMethod,
    pub iterations: usize,
    /// `‖b − Au‖ / ‖b‖`, recomputed from the returned `u` (0 when `b = 0`).
    pub relative_residual: f64,
    pub factor_seconds: f64,
    /// Stored entries of all Cholesky factors used.
    pub factor_entries: usize,
}

/// Solves the system with the method `params.solver` asks for (see the module docs).
pub fn solve(
    system: &SpaceTimeSystem,
    params: &FlowParams,
    observer: &(dyn Fn(SolveEvent) + Sync),
) -> Result<Solution, FlowError> {
    let b = system.rhs();
    if b.iter().all(|&v| v == 0.0) {
        // A static image: u = 0 is the exact minimizer (E ≥ 0 = E(0) minus the constant).
        return Ok(Solution {
            u: vec![0.0; b.len()],
            method: SolverMethod::Direct,
            iterations: 0,
            relative_residual: 0.0,
            factor_seconds: 0.0,
            factor_entries: 0,
        });
    }
    // One symbolic analysis serves every slab; only the slab-wise methods need it.
    let slab_symbolic = std::cell::LazyCell::new(|| analyze(system.block(0).symbolic()));
    // Budgeted at f64 size, the worst case of the single-precision factors' fallback.
    let factor_bytes = || slab_symbolic.len_val() * system.n_slabs() * std::mem::size_of::<f64>();
    let method = match params.solver {
        SolverChoice::Auto if !system.has_links() => SolverMethod::SlabwiseDirect,
        SolverChoice::Auto if system.dimension() <= params.direct_limit => SolverMethod::Direct,
        SolverChoice::Auto if factor_bytes() <= params.factor_memory_limit => {
            SolverMethod::PcgSlabGaussSeidel
        }
        SolverChoice::Auto => SolverMethod::PcgJacobi,
        SolverChoice::Direct => SolverMethod::Direct,
        SolverChoice::PcgSlabGaussSeidel => SolverMethod::PcgSlabGaussSeidel,
        SolverChoice::PcgJacobi => SolverMethod::PcgJacobi,
    };
    let start = Instant::now();
    let mut solution = match method {
        SolverMethod::Direct => direct(system, observer)?,
        SolverMethod::SlabwiseDirect => slabwise_direct(system, &slab_symbolic, observer)?,
        SolverMethod::PcgSlabGaussSeidel => {
            observer(SolveEvent::Factorizing {
                slabs: system.n_slabs(),
            });
            // Single-precision factors suffice for a preconditioner; f64 if a block is too
            // ill-conditioned for them.
            match factor_slabs::<f32>(system, &slab_symbolic) {
                Ok(factors) => slab_gauss_seidel(system, factors, start, params, observer)?,
                Err(_) => slab_gauss_seidel(
                    system,
                    factor_slabs::<f64>(system, &slab_symbolic)?,
                    start,
                    params,
                    observer,
                )?,
            }
        }
        SolverMethod::PcgJacobi => iterate(system, &Jacobi::new(system), params, observer)?,
    };
    solution.method = method;
    solution.relative_residual = relative_residual(system, &solution.u);
    Ok(solution)
}

fn relative_residual(system: &SpaceTimeSystem, u: &[f64]) -> f64 {
    let b = system.rhs();
    let mut r = vec![0.0; u.len()];
    system.apply(u, &mut r);
    r.iter_mut().zip(b).for_each(|(r, b)| *r = b - *r);
    (dot(&r, &r) / dot(b, b)).sqrt()
}

fn iterate(
    system: &SpaceTimeSystem,
    preconditioner: &dyn pcg::Preconditioner,
    params: &FlowParams,
    observer: &(dyn Fn(SolveEvent) + Sync),
) -> Result<Solution, FlowError> {
    let outcome = pcg::pcg(
        system,
        system.rhs(),
        preconditioner,
        params.tolerance,
        params.max_iterations,
        observer,
    );
    let solution = Solution {
        u: outcome.x,
        method: SolverMethod::PcgJacobi,
        iterations: outcome.iterations,
        relative_residual: f64::NAN,
        factor_seconds: 0.0,
        factor_entries: 0,
    };
    if outcome.converged {
        Ok(solution)
    } else {
        Err(FlowError::NotConverged {
            iterations: outcome.iterations,
            residual: relative_residual(system, &solution.u),
            tolerance: params.tolerance,
        })
    }
}

fn factorization_error(what: String) -> impl Fn(String) -> FlowError {
    move |detail| FlowError::Factorization {
        what: what.clone(),
        detail,
    }
}

/// Cholesky factors of every diagonal block, in parallel, each single-threaded.
fn factor_slabs<T: Precision>(
    system: &SpaceTimeSystem,
    symbolic: &std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>,
) -> Result<Vec<CholeskyFactor<T>>, FlowError> {
    (0..system.n_slabs())
        .into_par_iter()
        .map(|s| {
            CholeskyFactor::new(symbolic, system.block(s), Par::Seq)
                .map_err(factorization_error(format!("slab {s}")))
        })
        .collect()
}

/// PCG with the slab Gauss–Seidel preconditioner built from `factors` (factored since `start`).
fn slab_gauss_seidel<T: Precision>(
    system: &SpaceTimeSystem,
    factors: Vec<CholeskyFactor<T>>,
    start: Instant,
    params: &FlowParams,
    observer: &(dyn Fn(SolveEvent) + Sync),
) -> Result<Solution, FlowError> {
    let factor_seconds = start.elapsed().as_secs_f64();
    let factor_entries = factors.iter().map(CholeskyFactor::stored_entries).sum();
    let preconditioner = SlabGaussSeidel::new(system, factors, rayon::current_num_threads());
    let mut solution = iterate(system, &preconditioner, params, observer)?;
    solution.factor_seconds = factor_seconds;
    solution.factor_entries = factor_entries;
    Ok(solution)
}

fn direct(
    system: &SpaceTimeSystem,
    observer: &(dyn Fn(SolveEvent) + Sync),
) -> Result<Solution, FlowError> {
    observer(SolveEvent::Factorizing { slabs: 0 });
    let start = Instant::now();
    let matrix = system.to_sparse();
    let symbolic = analyze(matrix.symbolic());
    let par = Par::rayon(rayon::current_num_threads());
    let factor = CholeskyFactor::<f64>::new(&symbolic, matrix.as_ref(), par)
        .map_err(factorization_error("the space-time system".into()))?;
    let factor_seconds = start.elapsed().as_secs_f64();
    let mut u = system.rhs().to_vec();
    factor.solve_in_place(&mut u, par);
    Ok(Solution {
        u,
        method: SolverMethod::Direct,
        iterations: 1,
        relative_residual: f64::NAN,
        factor_seconds,
        factor_entries: factor.stored_entries(),
    })
}

fn slabwise_direct(
    system: &SpaceTimeSystem,
    symbolic: &std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>,
    observer: &(dyn Fn(SolveEvent) + Sync),
) -> Result<Solution, FlowError> {
    observer(SolveEvent::Factorizing {
        slabs: system.n_slabs(),
    });
    let start = Instant::now();
    let n = system.slab_dimension();
    let mut u = system.rhs().to_vec();
    let entries: Vec<usize> = u
        .par_chunks_mut(n)
        .enumerate()
        .map(|(s, us)| {
            let factor = CholeskyFactor::<f64>::new(symbolic, system.block(s), Par::Seq)
                .map_err(factorization_error(format!("slab {s}")))?;
            factor.solve_in_place(us, Par::Seq);
            Ok(factor.stored_entries())
        })
        .collect::<Result<_, FlowError>>()?;
    Ok(Solution {
        u,
        method: SolverMethod::SlabwiseDirect,
        iterations: 1,
        relative_residual: f64::NAN,
        factor_seconds: start.elapsed().as_secs_f64(),
        factor_entries: entries.iter().sum(),
    })
}
