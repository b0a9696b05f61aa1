//! The space-time solve over time windows held by separate ranks: conjugate gradients
//! preconditioned by the odd–even slab sweeps, each rank holding only its window's blocks,
//! links and factors ([`SystemWindow`], assembled by [`crate::flow::window`]).
//!
//! The sweeps are the same preconditioner whatever the split (even slabs, then odd ones, by
//! their index in the whole sequence), so the iterates equal the single process's
//! `pcg-slab-gauss-seidel` up to the order of the dot products' sums, and the iteration count
//! does not depend on the number of ranks. What crosses ranks: the dot products (a sum over
//! ranks), and before each product with `A` and each coupled half sweep one slab vector to each
//! neighbouring rank ([`TimeRanks::exchange`]). How the ranks talk is the caller's: MPI on a
//! cluster, threads in the tests.
//!
//! Not yet here: multigrid in time across ranks (its coarse levels pair slabs within a window
//! and agglomerate across ranks, `docs/scaling.md`), so small `α` needs many iterations.

use super::cholesky::{analyze, CholeskyFactor};
use super::factorization_error;
use super::precondition::{add, SlabSweeps, Surroundings};
use crate::flow::system::{dot, SystemWindow};
use crate::flow::{FlowError, FlowParams};
use crate::flow::{LinkMatrix, SpaceTimeSystem};
use faer::Par;
use rayon::prelude::*;

/// The collective operations a rank of a distributed solve needs. Every rank calls them in
/// the same order, from one thread (MPI communicators are not `Sync`; the parallel loops
/// here never touch them).
pub trait TimeRanks {
    /// This rank's window holds slabs `first_slab ..` of the sequence.
    fn first_slab(&self) -> usize;
    /// `values` ← their sum over all ranks.
    fn sum(&self, values: &mut [f64]);
    /// Sends `first` (the window's first slab) to the rank before and `last` (its last slab)
    /// to the rank after; returns what they sent: the last slab of the rank before, the first
    /// slab of the rank after (`None` at the sequence's ends).
    fn exchange(&self, first: &[f64], last: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>);
}

/// A rank's part of the solution.
#[derive(Clone, Debug)]
pub struct WindowSolution {
    /// The window's slabs' unknowns.
    pub u: Vec<f64>,
    pub iterations: usize,
    /// CG's recursive residual `‖r‖ / ‖b‖` of the whole system (the same on every rank).
    pub relative_residual: f64,
}

/// Solves the whole system of which `window` is this rank's part; every rank calls it. An
/// error on one rank only (a slab that does not factorize) leaves the others
/// waiting in a collective: the caller ends the job (`MPI_Abort`), as `examples/mpi_solve.rs`
/// does.
pub fn solve_window(
    window: &SystemWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
) -> Result<WindowSolution, FlowError> {
    let system = &window.system;
    let symbolic = analyze(system.block(0).symbolic(), 2);
    let first = ranks.first_slab();
    let factors = (0..system.n_slabs())
        .into_par_iter()
        .map(|s| {
            CholeskyFactor::<f32>::new(&symbolic, system.block(s), Par::Seq)
                .map_err(factorization_error(format!("slab {}", first + s)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let parts = WindowParts {
        window,
        ranks,
        sweeps: SlabSweeps::new(factors, 1, system.n_slabs()),
    };
    parts.pcg(params)
}

/// A rank's window, its slab sweeps and the other ranks.
struct WindowParts<'a> {
    window: &'a SystemWindow,
    ranks: &'a dyn TimeRanks,
    sweeps: SlabSweeps<f32>,
}

impl WindowParts<'_> {
    fn n(&self) -> usize {
        self.window.system.slab_dimension()
    }

    /// `Σ_ranks x·y`.
    fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        let mut value = [dot(x, y)];
        self.ranks.sum(&mut value);
        value[0]
    }

    /// The neighbouring ranks' boundary slabs of `x`.
    fn halo(&self, x: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        let n = self.n();
        self.ranks.exchange(&x[..n], &x[x.len() - n..])
    }

    /// `y = (A x)` on this window's slabs.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let (before, after) = self.beyond(x);
        self.window.system.apply(x, y);
        let (n, last) = (self.n(), y.len() - self.n());
        if let Some(term) = before {
            add(&mut y[..n], &term);
        }
        if let Some(term) = after {
            add(&mut y[last..], &term);
        }
    }

    /// The symmetric odd–even Gauss–Seidel sweep on the window, its neighbours' slabs
    /// reaching in through the boundary links ([`Surroundings`]).
    fn precondition(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        self.sweeps.symmetric(&self.window.system, z, self);
    }

    fn pcg(&self, params: &FlowParams) -> Result<WindowSolution, FlowError> {
        let b = self.window.system.rhs();
        let b_norm = self.dot(b, b).sqrt();
        let mut x = vec![0.0; b.len()];
        let mut r = b.to_vec();
        let mut z = vec![0.0; b.len()];
        let mut ap = vec![0.0; b.len()];
        let mut relative = if b_norm > 0.0 { 1.0 } else { 0.0 };
        self.precondition(&r, &mut z);
        let mut p = z.clone();
        let mut rz = self.dot(&r, &z);
        let mut iterations = 0;
        while relative > params.tolerance && iterations < params.max_iterations {
            iterations += 1;
            self.apply(&p, &mut ap);
            let step = rz / self.dot(&p, &ap);
            x.iter_mut().zip(&p).for_each(|(x, p)| *x += step * p);
            r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= step * a);
            relative = self.dot(&r, &r).sqrt() / b_norm;
            if !relative.is_finite() || relative <= params.tolerance {
                break;
            }
            self.precondition(&r, &mut z);
            let rz_next = self.dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            p.iter_mut().zip(&z).for_each(|(p, z)| *p = z + beta * *p);
        }
        match relative <= params.tolerance {
            true => Ok(WindowSolution {
                u: x,
                iterations,
                relative_residual: relative,
            }),
            false => Err(FlowError::NotConverged {
                iterations,
                residual: relative,
                tolerance: params.tolerance,
            }),
        }
    }
}

impl Surroundings for WindowParts<'_> {
    fn first_slab(&self) -> usize {
        self.ranks.first_slab()
    }

    fn coupled(&self, system: &SpaceTimeSystem) -> bool {
        system.has_links() || self.window.link_before.is_some() || self.window.link_after.is_some()
    }

    /// The neighbouring ranks' boundary slabs through the boundary links.
    fn beyond(&self, z: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        let (before, after) = self.halo(z);
        let pattern = self.window.system.pattern();
        let times = |link: &Option<LinkMatrix>, x: Option<Vec<f64>>, transposed: bool| {
            let (link, x) = (link.as_ref()?, x?);
            let mut term = vec![0.0; x.len()];
            match transposed {
                false => link.mul(pattern, &x, &mut term),
                true => link.transpose_mul(pattern, &x, &mut term),
            }
            Some(term)
        };
        (
            times(&self.window.link_before, before, false),
            times(&self.window.link_after, after, true),
        )
    }
}

/// [`TimeRanks`] over an MPI communicator (the `mpi` feature): sums by all-reduce, the
/// neighbour exchange as blocking sends and receives ordered by rank parity (even ranks send
/// first, odd ranks receive first), which cannot deadlock along a chain.
#[cfg(feature = "mpi")]
pub struct MpiRanks<'a, C: mpi::topology::Communicator> {
    pub communicator: &'a C,
    pub first_slab: usize,
}

#[cfg(feature = "mpi")]
impl<C: mpi::topology::Communicator> TimeRanks for MpiRanks<'_, C> {
    fn first_slab(&self) -> usize {
        self.first_slab
    }

    fn sum(&self, values: &mut [f64]) {
        use mpi::collective::{CommunicatorCollectives, SystemOperation};
        let mine = values.to_vec();
        self.communicator
            .all_reduce_into(&mine[..], values, SystemOperation::sum());
    }

    fn exchange(&self, first: &[f64], last: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        use mpi::point_to_point::{Destination, Source};
        let (rank, size) = (self.communicator.rank(), self.communicator.size());
        let before = (rank > 0).then(|| self.communicator.process_at_rank(rank - 1));
        let after = (rank + 1 < size).then(|| self.communicator.process_at_rank(rank + 1));
        let receive = |p: Option<mpi::topology::Process<'_>>| p.map(|p| p.receive_vec::<f64>().0);
        // `last` passes to the right, then `first` to the left.
        if rank % 2 == 0 {
            after.inspect(|p| p.send(last));
            let from_before = receive(before);
            before.inspect(|p| p.send(first));
            (from_before, receive(after))
        } else {
            let from_before = receive(before);
            after.inspect(|p| p.send(last));
            let from_after = receive(after);
            before.inspect(|p| p.send(first));
            (from_before, from_after)
        }
    }
}
