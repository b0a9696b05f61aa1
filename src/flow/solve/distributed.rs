//! The space-time solve over time windows held by separate ranks: conjugate gradients
//! preconditioned by the odd–even slab sweeps or by multigrid in time, each rank holding only
//! its window's blocks, links and factors ([`SystemWindow`], assembled by
//! [`crate::flow::window`]).
//!
//! **The same preconditioners as one process.** The odd–even sweeps solve the even slabs, then
//! the odd ones, by their index in the whole sequence, whatever the split; the multigrid in time
//! pairs slabs `(2k, 2k + 1)` of the whole sequence as the multigrid in time of one process
//! does, and halves the coarse links that cross ranks as it halves the others. The V-cycle is
//! the one process's code (`multigrid::v_cycle`); a rank gives it its windows of the levels and
//! transfers that talk to the neighbouring ranks (`multigrid::CycleLevels`). So the iterates
//! equal the single process's up to the order of the dot products' sums, and the iteration count
//! does not depend on the number of ranks.
//!
//! **Coarse levels gather onto fewer ranks.** Coarse slab `k` belongs to the rank that owns
//! slab `2k`: a window `[a, b)` has the coarse window `[⌈a/2⌉, ⌈b/2⌉)`. A window that starts at
//! an odd slab lends that slab's block and link to the rank before once, when the levels are
//! built, and in every cycle its residual (restriction) and receives its correction back
//! (prolongation); a window that ends at an odd slab borrows the same from the rank after
//! (`SystemWindow::merge_slab_pairs`). As levels coarsen, windows shrink to nothing and their
//! ranks fall idle, until the one slab of the coarsest level lies on rank 0: ranks pair up
//! level by level, a binary tree over time.
//!
//! **What crosses ranks:** the dot products (a sum over ranks); before each product with `A`
//! and each coupled half sweep one slab vector to each neighbouring rank that holds slabs of
//! the level; at each level of a cycle at most one slab vector each way between neighbours for
//! restriction and prolongation. Messages between neighbours follow a fixed order (the lower
//! rank of a pair sends first; even positions in the chain talk to the right first), so blocking
//! sends cannot deadlock. How the ranks talk is the caller's ([`TimeRanks`]): MPI on a cluster
//! (`MpiRanks`, feature `mpi`), threads in the tests.

use super::multigrid::{level_slab_counts, prolong_add, restrict, v_cycle, CycleLevels};
use super::pcg::{self, Operator, Preconditioner};
use super::precondition::{add, SlabSweeps, Surroundings};
use super::run::{InRun, WithLevels};
use super::{factorization_error, Solution, SolveObserver, SolverMethod};
use super::{gauss_seidel_verdict, levels_keep_precision, probe_give_up};
use super::{MetStart, Preconditioning, WarmStart, KEPT, MULTIGRID_AS_BEFORE};
use crate::flow::system::{dot, SystemWindow};
use crate::flow::{FlowError, FlowParams, LinkMatrix, SolverChoice, SpaceTimeSystem};
use crate::linalg::cholesky::{CholeskyFactor, FactorEntries};
use crate::linalg::factor::{SlabFactor, SpareValues};
use crate::linalg::packed::PackedFactor;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use nalgebra::Matrix2;
use rayon::prelude::*;
use std::borrow::Cow;
use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

/// The messages a rank of a distributed solve sends and receives. Every rank calls them in
/// the same order, from one thread (MPI communicators are not `Sync`; the parallel loops here
/// never touch them).
pub trait TimeRanks {
    fn rank(&self) -> usize;
    fn size(&self) -> usize;
    /// `values` ← their sum over all ranks (every rank calls it).
    fn sum(&self, values: &mut [f64]);
    /// Sends `values` to rank `to` (may block until `to` receives them).
    fn send(&self, to: usize, values: &[f64]);
    /// The next values rank `from` sent to this one.
    fn receive(&self, from: usize) -> Vec<f64>;
}

/// This rank's neighbours among the ranks whose windows hold slabs at one level.
#[derive(Clone, Copy, Debug)]
struct Chain {
    before: Option<usize>,
    after: Option<usize>,
    /// Position among those ranks (its parity orders the messages).
    position: usize,
}

impl Chain {
    fn new(windows: &[Range<usize>], rank: usize) -> Self {
        let holding = |r: &usize| !windows[*r].is_empty();
        Chain {
            before: (0..rank).rev().find(holding),
            after: (rank + 1..windows.len()).find(holding),
            position: (0..rank).filter(holding).count(),
        }
    }

    /// One round of messages with the neighbours: sends what is given, receives what is asked
    /// for (the neighbour's call mirrors this one). On each pair the lower rank sends first;
    /// even positions talk to the right first, odd ones to the left, so no cycle of blocking
    /// sends can form along the chain.
    fn talk(
        &self,
        ranks: &dyn TimeRanks,
        messages: Messages<'_>,
    ) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        let left = || {
            let before = self.before?;
            let received = messages.from_before.then(|| ranks.receive(before));
            messages.to_before.inspect(|m| ranks.send(before, m));
            received
        };
        let right = || {
            let after = self.after?;
            messages.to_after.inspect(|m| ranks.send(after, m));
            messages.from_after.then(|| ranks.receive(after))
        };
        match self.position % 2 {
            0 => {
                let from_after = right();
                (left(), from_after)
            }
            _ => {
                let from_before = left();
                (from_before, right())
            }
        }
    }
}

/// What one [`Chain::talk`] sends to and expects from the neighbours.
#[derive(Clone, Copy, Default)]
struct Messages<'a> {
    to_before: Option<&'a [f64]>,
    to_after: Option<&'a [f64]>,
    from_before: bool,
    from_after: bool,
}

/// One level of a rank before factorization: its window, its neighbours and the pair
/// transports to the next level (none at the coarsest or where the window pairs no slabs).
/// The fine level borrows the caller's window (no copy of the largest system).
struct LevelPlan<'a> {
    window: Cow<'a, SystemWindow>,
    chain: Chain,
    transports: Vec<Vec<Matrix2<f64>>>,
}

impl LevelPlan<'_> {
    fn view<'v>(&'v self, ranks: &'v dyn TimeRanks) -> LevelView<'v> {
        LevelView {
            window: &self.window,
            chain: self.chain,
            ranks,
        }
    }
}

/// A [`LevelPlan`] with the slab sweeps of its window and its share of the seconds their
/// factorization took.
struct Level<'a, F: SlabFactor> {
    plan: LevelPlan<'a>,
    sweeps: SlabSweeps<F>,
    factor_seconds: f64,
}

/// A level's window and its neighbours, as an operator and as the sweeps' surroundings.
struct LevelView<'a> {
    window: &'a SystemWindow,
    chain: Chain,
    ranks: &'a dyn TimeRanks,
}

impl LevelView<'_> {
    fn n(&self) -> usize {
        self.window.system.slab_dimension()
    }

    /// The neighbouring ranks' boundary slabs of `x`.
    fn halo(&self, x: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        let n = self.n();
        let messages = Messages {
            to_before: Some(&x[..n]),
            to_after: Some(&x[x.len() - n..]),
            from_before: true,
            from_after: true,
        };
        self.chain.talk(self.ranks, messages)
    }
}

impl Operator for LevelView<'_> {
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

    /// `Σ_ranks x·y`.
    fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        let mut value = [dot(x, y)];
        self.ranks.sum(&mut value);
        value[0]
    }
}

impl Surroundings for LevelView<'_> {
    fn first_slab(&self) -> usize {
        self.window.slabs.start
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

/// A rank's levels and the other ranks: the symmetric odd–even Gauss–Seidel sweep (one level
/// in all) or one V-cycle of multigrid in time.
struct WindowPreconditioner<'a, 'w, F: SlabFactor> {
    levels: &'a [Level<'w, F>],
    /// Levels of the whole hierarchy (this rank may hold fewer: it falls idle below them;
    /// 1: the sweeps alone).
    n_levels_in_all: usize,
    ranks: &'a dyn TimeRanks,
}

impl<F: SlabFactor> WindowPreconditioner<'_, '_, F> {
    fn view(&self, l: usize) -> LevelView<'_> {
        self.levels[l].plan.view(self.ranks)
    }
}

/// The V-cycle's levels on a rank ([`super::multigrid`]): the pairs that straddle two windows
/// are restricted and prolonged across the ranks.
impl<F: SlabFactor> CycleLevels<F> for WindowPreconditioner<'_, '_, F> {
    fn n_levels(&self) -> usize {
        self.n_levels_in_all
    }

    fn holds(&self, l: usize) -> bool {
        l < self.levels.len()
    }

    fn system(&self, l: usize) -> &SpaceTimeSystem {
        &self.levels[l].plan.window.system
    }

    fn sweeps(&self, l: usize) -> &SlabSweeps<F> {
        &self.levels[l].sweeps
    }

    fn with_view<R>(&self, l: usize, f: impl FnOnce(&dyn Operator, &dyn Surroundings) -> R) -> R {
        let view = self.view(l);
        f(&view, &view)
    }

    /// Lends the first slab's residual to the rank before when its window starts at an odd
    /// slab, borrows the rank after's when it ends at one, and restricts its pairs.
    fn restrict(&self, l: usize, r: &[f64]) -> Vec<f64> {
        let plan = &self.levels[l].plan;
        let n = self.system(l).slab_dimension();
        let lent = plan.window.lends_first();
        let (_, borrowed) = plan.chain.talk(
            self.ranks,
            Messages {
                to_before: lent.then(|| &r[..n]),
                from_after: plan.window.borrows_next(),
                ..Default::default()
            },
        );
        let mut paired = r[usize::from(lent) * n..].to_vec();
        paired.extend(borrowed.unwrap_or_default());
        restrict(&plan.transports, &paired, n)
    }

    /// Prolongs onto its pairs, returns the borrowed slab's share to the rank after and takes
    /// the lent slab's from the rank before.
    fn prolong_add(&self, l: usize, coarse: &[f64], z: &mut [f64]) {
        let plan = &self.levels[l].plan;
        let n = self.system(l).slab_dimension();
        let (lent, borrows) = (plan.window.lends_first(), plan.window.borrows_next());
        let own = z.len() - usize::from(lent) * n;
        let mut increment = vec![0.0; own + usize::from(borrows) * n];
        prolong_add(&plan.transports, coarse, &mut increment, n);
        let (from_before, _) = plan.chain.talk(
            self.ranks,
            Messages {
                to_after: borrows.then(|| &increment[own..]),
                from_before: lent,
                ..Default::default()
            },
        );
        add(&mut z[usize::from(lent) * n..], &increment[..own]);
        if let Some(correction) = from_before {
            add(&mut z[..n], &correction);
        }
    }
}

impl<F: SlabFactor> Preconditioner for WindowPreconditioner<'_, '_, F> {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        match self.n_levels_in_all > 1 {
            true => v_cycle(self, 0, r, z),
            false => {
                z.copy_from_slice(r);
                self.levels[0].sweeps.symmetric(
                    &self.levels[0].plan.window.system,
                    z,
                    &self.view(0),
                );
            }
        }
    }
}

/// Solves the whole system of which `window` is this rank's part; every rank calls it with
/// its window (the windows in rank order, each at least one slab, covering the sequence).
/// Returns this rank's part of the solution (`u` on its slabs; the rest of the `Solution` is the
/// same on every rank).
///
/// `params.solver`: `pcg-slab-gauss-seidel` and `pcg-time-multigrid` as in one process;
/// `auto` probes the sweeps and builds the multigrid levels when they are too slow, as one
/// process does for a system above the direct solver's limit (a distributed solve is never
/// direct); `direct` and `pcg-jacobi` are not distributed ([`FlowError::NotDistributed`]).
///
/// An error on one rank only (a slab that factorizes on no precision) is reported on every
/// rank, the others naming no slab; the caller ends the job (`MPI_Abort`), as `meshflow solve`
/// under `mpirun` does.
///
/// `start`, when given, is a warm start as in one process ([`WarmStart`]), its `u` this rank's
/// part: a start that meets the tolerance over all ranks is the solution.
///
/// Subnormal numbers are flushed on each rank ([`crate::subnormals`]).
pub fn solve_window(
    window: &SystemWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    start: Option<&WarmStart>,
    observer: &dyn SolveObserver,
) -> Result<Solution, FlowError> {
    solve_window_in_run(window, ranks, params, start, None, observer)
}

/// [`solve_window`] as one solve of `run`, whose slab factors take their buffers from the
/// run's pool and are kept for its next solve or taken from its previous one as [`InRun`]
/// says (the same decision on every rank), as in one process ([`super::solve`]).
pub(crate) fn solve_window_in_run(
    window: &SystemWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    start: Option<&WarmStart>,
    run: Option<InRun<'_>>,
    observer: &dyn SolveObserver,
) -> Result<Solution, FlowError> {
    let from = (start, run);
    crate::subnormals::flushed(|| solve_window_flushed(window, ranks, params, from, observer))
}

fn solve_window_flushed(
    window: &SystemWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    (start, run): (Option<&WarmStart>, Option<InRun<'_>>),
    observer: &dyn SolveObserver,
) -> Result<Solution, FlowError> {
    let multigrid = match params.solver {
        SolverChoice::Auto => match WarmStart::auto(start) {
            Preconditioning::MultigridAsBefore => Some(true),
            _ => None,
        },
        SolverChoice::PcgSlabGaussSeidel => Some(false),
        SolverChoice::PcgTimeMultigrid => Some(true),
        SolverChoice::Direct => {
            return Err(FlowError::NotDistributed {
                what: "the solver direct",
            })
        }
        SolverChoice::PcgJacobi => {
            return Err(FlowError::NotDistributed {
                what: "the solver pcg-jacobi",
            })
        }
    };
    let windows = all_windows(window, ranks)?;
    let job = WindowJob {
        window,
        windows: &windows,
        ranks,
        params,
        start: start.map(|s| s.u.as_slice()),
        observer,
        multigrid,
        run,
        kept: false,
    };
    let b = window.system.rhs();
    let operator = job.fine_plan();
    let operator = operator.view(ranks);
    if operator.dot(b, b) == 0.0 {
        return Ok(Solution::zero(b.len()));
    }
    if let Some(met) = MetStart::of(&operator, b, params, start) {
        return Ok(met.solution(match multigrid {
            Some(true) => SolverMethod::PcgTimeMultigrid,
            _ => SolverMethod::PcgSlabGaussSeidel,
        }));
    }
    let kept = |run: InRun<'_>| run.take_kept(super::shape(&window.system), WindowKept { job });
    if let Some(solution) = run.and_then(kept) {
        return solution;
    }
    // Single-precision factors (bfloat16 for multigrid's levels, as in one process) suffice for
    // a preconditioner; f64 if a block of any level is too ill-conditioned (on any rank: the
    // failure is summed).
    match job.run::<PackedFactor<f32>>() {
        Err(FlowError::Factorization { .. }) => job.run::<CholeskyFactor<f64>>(),
        other => other,
    }
}

/// Where multigrid continues the sweeps' run: its iterate, its stop (iterations so far) and
/// why it switched.
struct Continuation {
    x: Vec<f64>,
    stop: pcg::Stop,
    reason: String,
}

/// What a rank's solve needs, whatever the factors' precision.
#[derive(Clone, Copy)]
struct WindowJob<'a> {
    window: &'a SystemWindow,
    windows: &'a [Range<usize>],
    ranks: &'a dyn TimeRanks,
    params: &'a FlowParams,
    /// This rank's part of CG's first iterate; zero when `None`.
    start: Option<&'a [f64]>,
    observer: &'a dyn SolveObserver,
    /// `Some(true)`: multigrid; `Some(false)`: the sweeps; `None`: the sweeps, then multigrid
    /// if they are too slow.
    multigrid: Option<bool>,
    /// The run the solve is one of.
    run: Option<InRun<'a>>,
    /// Whether the factors are kept from the run's previous solve ([`super::run`]).
    kept: bool,
}

/// The sweeps or multigrid in time with the levels the run's previous solve kept.
struct WindowKept<'a> {
    job: WindowJob<'a>,
}

impl WithLevels for WindowKept<'_> {
    type Output = Result<Solution, FlowError>;

    fn with<F: SlabFactor>(self, levels: Vec<SlabSweeps<F>>) -> Self::Output {
        let job = WindowJob {
            kept: true,
            ..self.job
        };
        let level = |(plan, sweeps)| Level {
            plan,
            sweeps,
            factor_seconds: 0.0,
        };
        // Decided alike on every rank: a rank whose windows of the coarse levels are empty
        // holds fewer levels than the others.
        if job.multigrid != Some(true) {
            let fine = levels
                .into_iter()
                .next()
                .map(|l| level((job.fine_plan(), l)));
            return job.iterate(fine.into_iter().collect());
        }
        let (plans, n_levels_in_all) = build_levels(job.window, job.windows, job.ranks);
        let start = Continuation {
            x: job.first_iterate(),
            stop: pcg::Stop::new(job.params.tolerance, job.params.max_iterations),
            reason: job.reason(job.multigrid_why()),
        };
        let levels = plans.into_iter().zip(levels).map(level).collect();
        job.multigrid_over(levels, n_levels_in_all, start)
    }
}

impl<'a> WindowJob<'a> {
    fn fine_plan(&self) -> LevelPlan<'a> {
        LevelPlan {
            window: Cow::Borrowed(self.window),
            chain: Chain::new(self.windows, self.ranks.rank()),
            transports: Vec::new(),
        }
    }

    /// The fine level's factors; CG with the sweeps or the probe of `auto`; the coarse levels
    /// and their factors only when multigrid is asked for or the probe finds the sweeps too
    /// slow (as one process does).
    fn run<F: SlabFactor>(&self) -> Result<Solution, FlowError> {
        let symbolic = self.window.system.slab_symbolic();
        let fine = vec![self.fine_plan()];
        let per_thread = SpareValues::per_thread();
        let spare = super::run::spare_for::<F>(self.run, &per_thread);
        let levels = factor_levels::<F>(fine, symbolic, self.ranks, spare)?;
        self.iterate(levels)
    }

    /// CG from the fine level's factors `levels` (one level), as [`Self::run`] says.
    fn iterate<F: SlabFactor>(&self, mut levels: Vec<Level<'a, F>>) -> Result<Solution, FlowError> {
        let symbolic = self.window.system.slab_symbolic();
        let stop = pcg::Stop::new(self.params.tolerance, self.params.max_iterations);
        let (x, done, reason) = match self.multigrid {
            Some(true) => (self.first_iterate(), 0, self.reason(self.multigrid_why())),
            sweeps_or_auto => {
                let probe = pcg::Stop {
                    give_up: sweeps_or_auto
                        .is_none()
                        .then(|| probe_give_up(self.params.tolerance, self.start.is_some())),
                    ..stop
                };
                let outcome = self.pcg(&levels, 1, self.first_iterate(), probe)?;
                let verdict = gauss_seidel_verdict(&outcome);
                if sweeps_or_auto == Some(false) || outcome.gave_up.is_none() {
                    let reason = match sweeps_or_auto {
                        Some(false) => self.reason("asked for"),
                        _ => self.reason(&verdict),
                    };
                    let method = SolverMethod::PcgSlabGaussSeidel;
                    let solution = self.finish(outcome, method, reason, &levels, 1);
                    self.hand_on(levels);
                    return solution;
                }
                (outcome.x, outcome.iterations, self.reason(&verdict))
            }
        };
        let factored = levels.pop().expect("the fine level");
        let start = Continuation {
            x,
            stop: pcg::Stop { done, ..stop },
            reason,
        };
        let seconds = factored.factor_seconds;
        let spare = SpareValues::per_thread();
        match levels_keep_precision::<F>(symbolic, self.window.n_slabs_in_all) {
            true => self.multigrid(factored.sweeps, seconds, symbolic, start, spare),
            false => {
                let compressed = factored.sweeps.compress(&spare);
                self.multigrid(compressed, seconds, symbolic, start, spare)
            }
        }
    }

    /// CG with multigrid in time from `start`, the fine level's sweeps given (factored in
    /// `fine_seconds`) and the coarse levels factored as type `F` (into `spare`'s buffers,
    /// freed before CG).
    fn multigrid<F: SlabFactor>(
        &self,
        fine: SlabSweeps<F>,
        fine_seconds: f64,
        symbolic: &Arc<SymbolicCholesky<usize>>,
        start: Continuation,
        spare: SpareValues,
    ) -> Result<Solution, FlowError> {
        let (plans, n_levels_in_all) = build_levels(self.window, self.windows, self.ranks);
        let mut plans = plans.into_iter();
        let fine = Level {
            plan: plans.next().expect("the fine level"),
            sweeps: fine,
            factor_seconds: fine_seconds,
        };
        let coarse = factor_levels::<F>(plans.collect(), symbolic, self.ranks, &spare)?;
        drop(spare);
        let levels: Vec<Level<'_, F>> = std::iter::once(fine).chain(coarse).collect();
        self.multigrid_over(levels, n_levels_in_all, start)
    }

    /// CG with multigrid in time over `levels` from `start`; the levels' sweeps handed on to
    /// the run at the end.
    fn multigrid_over<F: SlabFactor>(
        &self,
        levels: Vec<Level<'_, F>>,
        n_levels_in_all: usize,
        start: Continuation,
    ) -> Result<Solution, FlowError> {
        let Continuation { x, stop, reason } = start;
        let outcome = self.pcg(&levels, n_levels_in_all, x, stop)?;
        let method = SolverMethod::PcgTimeMultigrid;
        let solution = self.finish(outcome, method, reason, &levels, n_levels_in_all);
        self.hand_on(levels);
        solution
    }

    /// This rank's part of CG's first iterate.
    fn first_iterate(&self) -> Vec<f64> {
        let n = self.window.system.rhs().len();
        self.start.map_or_else(|| vec![0.0; n], <[f64]>::to_vec)
    }

    /// Why multigrid in time runs from the start.
    fn multigrid_why(&self) -> &'static str {
        match self.params.solver {
            SolverChoice::Auto => MULTIGRID_AS_BEFORE,
            _ => "asked for",
        }
    }

    /// `why`, with where the factors came from when they are kept.
    fn reason(&self, why: &str) -> String {
        match self.kept {
            true => format!("{why}; {KEPT}"),
            false => why.to_string(),
        }
    }

    /// The solve's `levels` to the run: kept for the next solve, or their buffers recycled.
    fn hand_on<F: SlabFactor>(&self, levels: Vec<Level<'_, F>>) {
        if let Some(run) = self.run {
            let sweeps = levels.into_iter().map(|l| l.sweeps).collect();
            run.hand_on(sweeps, super::shape(&self.window.system));
        }
    }

    /// CG from `x` on the whole system, preconditioned by multigrid in time over `levels`
    /// (the sweeps alone for one level).
    fn pcg<F: SlabFactor>(
        &self,
        levels: &[Level<'_, F>],
        n_levels_in_all: usize,
        x: Vec<f64>,
        stop: pcg::Stop,
    ) -> Result<pcg::CgOutcome, FlowError> {
        let preconditioner = WindowPreconditioner {
            levels,
            n_levels_in_all,
            ranks: self.ranks,
        };
        let operator = levels[0].plan.view(self.ranks);
        let b = self.window.system.rhs();
        pcg::pcg(&operator, b, x, &preconditioner, stop, self.observer)
    }

    /// The [`Solution`] of a CG run, its residual recomputed from `u` over all ranks.
    fn finish<F: SlabFactor>(
        &self,
        outcome: pcg::CgOutcome,
        method: SolverMethod,
        reason: String,
        levels: &[Level<'_, F>],
        time_levels: usize,
    ) -> Result<Solution, FlowError> {
        let own: FactorEntries = levels.iter().map(|l| l.sweeps.entries()).sum();
        let mut entries = [own.stored as f64, own.subnormal as f64];
        self.ranks.sum(&mut entries);
        let factor_seconds = levels.iter().map(|l| l.factor_seconds).sum();
        let mut solution = Solution::iterated(
            outcome,
            method,
            format!("{reason}; factors in {}; over ranks", F::NAME),
        );
        solution = solution.converged(self.params)?;
        let operator = levels[0].plan.view(self.ranks);
        let b = self.window.system.rhs();
        solution.relative_residual = super::relative_residual(&operator, b, &solution.u);
        solution.factor_seconds = factor_seconds;
        solution.factor_entries = FactorEntries {
            stored: entries[0] as usize,
            subnormal: entries[1] as usize,
        };
        solution.time_levels = time_levels;
        Ok(solution)
    }
}

/// Every rank's window, from one sum; checks that they tile the sequence in rank order.
fn all_windows(
    window: &SystemWindow,
    ranks: &dyn TimeRanks,
) -> Result<Vec<Range<usize>>, FlowError> {
    let bounds = [window.slabs.start as f64, window.slabs.end as f64];
    let windows: Vec<Range<usize>> = (all_gather(ranks, &bounds).iter())
        .map(|b| b[0] as usize..b[1] as usize)
        .collect();
    let tiled = windows.iter().all(|w| !w.is_empty())
        && windows.first().map(|w| w.start) == Some(0)
        && windows.last().map(|w| w.end) == Some(window.n_slabs_in_all)
        && windows.windows(2).all(|p| p[0].end == p[1].start);
    match tiled {
        true => Ok(windows),
        false => Err(FlowError::CountMismatch {
            what:
                "slabs covered by the ranks' windows (each rank needs at least one slab, in order)",
            expected: window.n_slabs_in_all,
            got: windows.iter().map(|w| w.len()).sum(),
        }),
    }
}

/// This rank's windows of the time levels, finest first, and the number of levels in all
/// (halving the slabs until one is left; one level for slabs not coupled in time).
fn build_levels<'a>(
    fine: &'a SystemWindow,
    windows: &[Range<usize>],
    ranks: &dyn TimeRanks,
) -> (Vec<LevelPlan<'a>>, usize) {
    let view = LevelView {
        window: fine,
        chain: Chain::new(windows, ranks.rank()),
        ranks,
    };
    let coupled = view.coupled(&fine.system);
    let n_levels_in_all = match coupled {
        true => level_slab_counts(fine.n_slabs_in_all).len(),
        false => 1,
    };
    let mut levels = Vec::new();
    let (mut window, mut windows) = (Cow::Borrowed(fine), windows.to_vec());
    for l in 0..n_levels_in_all {
        let chain = Chain::new(&windows, ranks.rank());
        if l + 1 == n_levels_in_all {
            levels.push(LevelPlan {
                window,
                chain,
                transports: Vec::new(),
            });
            break;
        }
        let lent = window.lends_first().then(|| window.first_slab_message());
        let (_, borrowed) = chain.talk(
            ranks,
            Messages {
                to_before: lent.as_deref(),
                from_after: window.borrows_next(),
                ..Default::default()
            },
        );
        let (mut coarse, transports) = window.merge_slab_pairs(borrowed.as_deref());
        windows = windows
            .iter()
            .map(|w| w.start.div_ceil(2)..w.end.div_ceil(2))
            .collect();
        levels.push(LevelPlan {
            window,
            chain,
            transports,
        });
        if coarse.slabs.is_empty() {
            break;
        }
        let link = coarse.link_after.as_ref().map(LinkMatrix::to_message);
        let (before, _) = Chain::new(&windows, ranks.rank()).talk(
            ranks,
            Messages {
                to_after: link.as_deref(),
                from_before: coarse.slabs.start > 0,
                ..Default::default()
            },
        );
        coarse.set_coarse_link_before(before.as_deref().and_then(LinkMatrix::from_message));
        window = Cow::Owned(coarse);
    }
    (levels, n_levels_in_all)
}

/// The levels of `plans` with their slab factors in precision `T` (in `spare`'s buffers where
/// it has some); an error on any rank fails them on all (so that all ranks retry in double
/// precision together).
fn factor_levels<'a, F: SlabFactor>(
    plans: Vec<LevelPlan<'a>>,
    symbolic: &Arc<SymbolicCholesky<usize>>,
    ranks: &dyn TimeRanks,
    spare: &SpareValues,
) -> Result<Vec<Level<'a, F>>, FlowError> {
    let start = Instant::now();
    let slabs: Vec<(usize, usize)> = (plans.iter().enumerate())
        .flat_map(|(l, p)| (0..p.window.system.n_slabs()).map(move |s| (l, s)))
        .collect();
    let factors = slabs
        .par_iter()
        .map(|&(l, s)| {
            let window = &plans[l].window;
            let slab = window.slabs.start + s;
            let what = match window {
                Cow::Borrowed(_) => format!("slab {slab}"),
                Cow::Owned(_) => format!("merged slab {slab} of a coarse time level"),
            };
            F::factor(symbolic, window.system.block(s), spare).map_err(factorization_error(what))
        })
        .collect::<Result<Vec<_>, _>>();
    let mut failed = [f64::from(u8::from(factors.is_err()))];
    ranks.sum(&mut failed);
    let mut factors = match (factors, failed[0] > 0.0) {
        (Err(error), _) => return Err(error),
        (Ok(_), true) => {
            return Err(factorization_error("a slab on another rank".into())(
                "see that rank's error".into(),
            ))
        }
        (Ok(factors), false) => factors.into_iter(),
    };
    let seconds = start.elapsed().as_secs_f64() / plans.len().max(1) as f64;
    Ok(plans
        .into_iter()
        .map(|plan| {
            let n = plan.window.system.n_slabs();
            let sweeps = SlabSweeps::new(factors.by_ref().take(n).collect(), 1, n);
            Level {
                plan,
                sweeps,
                factor_seconds: seconds,
            }
        })
        .collect())
}

/// The first slab of the next rank's window (`None` on the last rank), for this rank's
/// `first` slab sent to the rank before: every rank calls it.
pub(crate) fn next_rank_first_slab(ranks: &dyn TimeRanks, first: &[f64]) -> Option<Vec<f64>> {
    let chain = Chain::new(&vec![0..1; ranks.size()], ranks.rank());
    let messages = Messages {
        to_before: Some(first),
        from_after: true,
        ..Default::default()
    };
    chain.talk(ranks, messages).1
}

/// A computation in one process seen as ranks: one rank, whose sums are its own values. For
/// the code written once for both (e.g. the check that the minimizer is unique); it sends no
/// messages.
pub struct OneProcess;

impl TimeRanks for OneProcess {
    fn rank(&self) -> usize {
        0
    }

    fn size(&self) -> usize {
        1
    }

    fn sum(&self, _: &mut [f64]) {}

    fn send(&self, _: usize, _: &[f64]) {
        unreachable!("one process has no other rank to send to")
    }

    fn receive(&self, _: usize) -> Vec<f64> {
        unreachable!("one process has no other rank to receive from")
    }
}

/// Every rank's `values` (as many on each) on every rank, in rank order: one sum over slots
/// in which each rank fills its own (adding zeros changes no value); collective.
pub(crate) fn all_gather(ranks: &dyn TimeRanks, values: &[f64]) -> Vec<Vec<f64>> {
    let k = values.len();
    if k == 0 {
        return vec![Vec::new(); ranks.size()];
    }
    let mut slots = vec![0.0; k * ranks.size()];
    slots[k * ranks.rank()..k * (ranks.rank() + 1)].copy_from_slice(values);
    ranks.sum(&mut slots);
    slots.chunks(k).map(<[f64]>::to_vec).collect()
}

/// Every rank's `values` on rank 0, in rank order (`None` on the other ranks): every rank
/// calls it.
pub fn gather_to_first(ranks: &dyn TimeRanks, values: &[f64]) -> Option<Vec<Vec<f64>>> {
    match ranks.rank() {
        0 => Some(
            std::iter::once(values.to_vec())
                .chain((1..ranks.size()).map(|r| ranks.receive(r)))
                .collect(),
        ),
        _ => {
            ranks.send(0, values);
            None
        }
    }
}

/// Makes a panic on this rank end the whole MPI job (`MPI_Abort` after the panic's message)
/// instead of leaving the other ranks waiting in a collective.
#[cfg(feature = "mpi")]
pub fn abort_job_on_panic() {
    use mpi::topology::{Communicator, SimpleCommunicator};
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        hook(info);
        SimpleCommunicator::world().abort(101);
    }));
}

/// [`TimeRanks`] over an MPI communicator (the `mpi` feature): sums by all-reduce, messages as
/// blocking standard-mode sends ([`Chain::talk`] orders them so that they cannot deadlock).
#[cfg(feature = "mpi")]
pub struct MpiRanks<'a, C: mpi::topology::Communicator> {
    pub communicator: &'a C,
}

#[cfg(feature = "mpi")]
impl<C: mpi::topology::Communicator> TimeRanks for MpiRanks<'_, C> {
    fn rank(&self) -> usize {
        self.communicator.rank() as usize
    }

    fn size(&self) -> usize {
        self.communicator.size() as usize
    }

    fn sum(&self, values: &mut [f64]) {
        use mpi::collective::{CommunicatorCollectives, SystemOperation};
        let mine = values.to_vec();
        self.communicator
            .all_reduce_into(&mine[..], values, SystemOperation::sum());
    }

    fn send(&self, to: usize, values: &[f64]) {
        use mpi::point_to_point::Destination;
        self.communicator.process_at_rank(to as i32).send(values);
    }

    fn receive(&self, from: usize) -> Vec<f64> {
        use mpi::point_to_point::Source;
        self.communicator
            .process_at_rank(from as i32)
            .receive_vec::<f64>()
            .0
    }
}
