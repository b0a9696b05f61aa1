//! The linear solves of an outer iteration — coarse-to-fine warping ([`super::warp`]) and the
//! reweighting of robust smoothness ([`super::robust`]) — in one process or over ranks.
//!
//! Both outer iterations change only slab-local data between their solves (a slab's warped
//! images, a slab's per-face smoothness weights), computed from that slab's flow. So they run
//! unchanged on one rank's time window: each rank updates its own slabs and every solve is
//! collective. [`SlabSolver`] is that difference: which slabs are this process's and how their
//! system is solved; the few scalars the iterations decide on (the robust energy) are summed
//! over processes with [`SlabSolver::sum`].

use super::motion::{check_linearization, MotionCheck};
use super::problem::{FlowProblem, FlowResult, SolveStep, Timings};
use super::robust::FirstSolve::Given;
use super::solve::{FactorReuse, InRun, RunFactors};
use super::{robust, warp, DataScales, FlowError, FlowParams, MeshSequence};
use super::{Slab, SolveEvent, SolveObserver, Warping, Weights};
use std::borrow::Cow;
use std::ops::Range;
use std::time::Instant;

/// Runs the solves of an outer iteration.
pub(super) trait SlabSolver {
    /// The frames this process holds: the whole sequence, or one time window's frames.
    fn frames(&self) -> &MeshSequence;

    /// The slabs of [`SlabSolver::frames`] this process solves for (the others only lend their
    /// geometry to the time links at the window's ends).
    fn own(&self) -> Range<usize>;

    /// Minimizes the model of `params` on the frames' slabs `slabs` (all of them, in order); the
    /// result's flow is that of [`SlabSolver::own`], its energy terms the whole sequence's.
    /// The solve is warm-started from `previous`, the run's previous result (of the own
    /// slabs), when given ([`FlowProblem::solve_from`]), and takes or keeps slab factors as
    /// `reuse` says ([`FactorReuse`]). Collective over ranks.
    fn solve(
        &self,
        params: &FlowParams,
        slabs: Vec<Slab>,
        previous: Option<&FlowResult>,
        reuse: FactorReuse,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError>;

    /// Sums `values` over all processes (nothing to do in one).
    fn sum(&self, values: &mut [f64]);
}

/// What an outer iteration starts from: the problem's parameters, the weights and scales its
/// original data resolved, and the seconds its assembly took.
#[derive(Clone, Copy)]
pub(super) struct OuterStart<'a> {
    pub params: &'a FlowParams,
    pub weights: Weights,
    pub scales: DataScales,
    pub assembly_seconds: f64,
}

impl OuterStart<'_> {
    /// The parameters with the weights fixed at the original data's, so that warped or
    /// reweighted slabs do not re-resolve them, and the check for large motions off (the solves
    /// of an outer iteration are its steps, not new problems).
    pub fn fixed_params(&self) -> FlowParams {
        FlowParams {
            alpha: super::Weight::Value(self.weights.alpha),
            beta: super::Weight::Value(self.weights.beta),
            gamma: super::Weight::Value(self.weights.gamma),
            detect_large_motion: false,
            ..self.params.clone()
        }
    }
}

/// Whether the minimization of `params` starts with one plain linear solve whose flow
/// [`after_first_solve`] takes on: with the check for large motions, unless warping is asked
/// for.
pub(super) fn checks_motion(params: &FlowParams) -> bool {
    params.detect_large_motion && !params.warping.is_active()
}

/// What follows the first linear solve `first` (of the quadratic, unwarped model) when the
/// motion is checked ([`checks_motion`]): the check of its linearization
/// ([`super::motion`]) on the own slabs (`slab(i)` the `i`-th own one, with the original
/// images); if the motion is large, the coarse-to-fine solve of [`Warping::LARGE_MOTION`] (its
/// timings led by `first`'s); otherwise the robust reweighting from `first` when the
/// parameters ask for it (`robust_slabs()`: all the frames' slabs), or `first` itself. The
/// result carries the check.
pub(super) fn after_first_solve<'a>(
    solver: &dyn SlabSolver,
    start: &OuterStart,
    first: FlowResult,
    slab: &(dyn Fn(usize) -> Cow<'a, Slab> + Sync),
    robust_slabs: impl FnOnce() -> Vec<Slab>,
    observer: &dyn SolveObserver,
) -> Result<FlowResult, FlowError> {
    let channel_weights = start
        .params
        .channel_weights_for(solver.frames().n_channels())?;
    let check = check_linearization(solver, slab, &first, &channel_weights)?;
    if check.is_large() {
        observer.notify(SolveEvent::LargeMotion {
            linearization_error: check.linearization_error,
            threshold: check.threshold,
        })?;
        let params = FlowParams {
            warping: Warping::LARGE_MOTION,
            ..start.params.clone()
        };
        let warping = OuterStart {
            params: &params,
            ..*start
        };
        let mut result = warp::coarse_to_fine(solver, &warping, observer)?;
        let iterations = first.iterations_in_all();
        (result.timings).lead_with("linear solve, checked", &first.timings, iterations);
        result.motion_check = Some(MotionCheck {
            warped: true,
            ..check
        });
        return Ok(result);
    }
    let mut result = match start.params.is_robust() {
        true => robust::reweighted(
            solver,
            start,
            robust_slabs(),
            Given(Box::new(first)),
            observer,
        )?,
        false => first,
    };
    result.motion_check = Some(check);
    Ok(result)
}

/// The whole sequence in one process, with what its solves hand on to each other
/// ([`RunFactors`]): the pool their `f32` slab factors are recycled through, so that a run's
/// next solve factors into pages mapped already (at paper size a factor is 36 MB, 9,000 pages
/// that each fault on first touch), and the factors a warp keeps for the next.
pub(super) struct WholeSequence<'a> {
    sequence: &'a MeshSequence,
    pub factors: RunFactors,
}

impl<'a> WholeSequence<'a> {
    pub fn new(sequence: &'a MeshSequence) -> Self {
        Self {
            sequence,
            factors: RunFactors::new(sequence.n_slabs()),
        }
    }
}

impl SlabSolver for WholeSequence<'_> {
    fn frames(&self) -> &MeshSequence {
        self.sequence
    }

    fn own(&self) -> Range<usize> {
        0..self.sequence.n_slabs()
    }

    fn solve(
        &self,
        params: &FlowParams,
        slabs: Vec<Slab>,
        previous: Option<&FlowResult>,
        reuse: FactorReuse,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError> {
        let problem = FlowProblem::from_slabs(self.sequence, params, slabs)?;
        let factors = &self.factors;
        problem.solve_in_run(previous, Some(InRun { factors, reuse }), observer)
    }

    fn sum(&self, _: &mut [f64]) {}
}

/// The clock of a run of several solves (warping, reweighting): its [`Timings`], step by step.
pub(super) struct RunClock {
    /// The assembly before the run's first solve, counted in its total.
    assembly_seconds: f64,
    start: Instant,
    step: Instant,
    timings: Timings,
}

impl RunClock {
    /// Starts a run whose assembly took `assembly_seconds` already.
    pub fn start(assembly_seconds: f64) -> Self {
        let now = Instant::now();
        RunClock {
            assembly_seconds,
            start: now,
            step: now,
            timings: Timings {
                assembly: assembly_seconds,
                ..Timings::default()
            },
        }
    }

    /// A step begins now (the first one begins with the run).
    pub fn begin_step(&mut self) {
        self.step = Instant::now();
    }

    /// The step begun last ends with `part`, its solve, recorded as `label`.
    pub fn end_step(&mut self, label: String, part: &FlowResult) {
        let seconds = self.step.elapsed().as_secs_f64();
        let timings = &mut self.timings;
        timings.assembly += part.timings.assembly;
        timings.factorization += part.timings.factorization;
        timings.solve += part.timings.solve;
        timings.steps.push(SolveStep {
            label,
            seconds,
            iterations: part.iterations_in_all(),
        });
    }

    /// The run's timings, `total` from the first assembly to now.
    pub fn finish(mut self) -> Timings {
        self.timings.total = self.assembly_seconds + self.start.elapsed().as_secs_f64();
        self.timings
    }
}
