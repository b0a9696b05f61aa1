//! Time windows: the slabs `[a, b)` of a sequence assembled from its frames `a − 1 … b + 1`
//! alone, equal to the same slabs of the whole problem — what each rank of a solve distributed
//! over time would assemble (`docs/scaling.md`).
//!
//! A slab's diagonal block carries the diagonal parts of both its time links, and a link needs
//! both slabs' geometry and image, so a window needs one slab beyond each end (where there is
//! one): frames `a − 1 ..= b + 1`. The weights depend on the data's scales over *all* slabs;
//! each window measures its own slabs' [`ScaleSums`], and their sum (one all-reduce) gives the
//! scales every window assembles with.
//!
//! [`flow_over_ranks`] is the whole computation on one rank: its window's slabs, the scales
//! summed over ranks, the distributed solve ([`super::distributed`]), its slabs' flow and
//! energy, gathered into one [`FlowResult`] on rank 0; [`flow_of_own_slabs`] is the same
//! without the gathering, for a writer that streams the slabs
//! ([`crate::run::write_flow_over_ranks`]).
//!
//! Coarse-to-fine warping and robust smoothness change only slab-local data between their
//! solves, so each rank warps or reweights its own slabs (`flow::outer`). The check that
//! the minimizer is unique (`β = 0`, `FlowError::Singular`) runs over the ranks before each solve:
//! each checks its own slabs and links and the parts that couple all slabs are summed.

use super::distributed::{gather_to_first, next_rank_first_slab, solve_window_in_run, TimeRanks};
use super::outer::{after_first_solve, checks_motion, OuterStart, SlabSolver};
use super::problem::{
    energy_and_vectors, intrinsic_fields, kept_slab_bytes, FlowResult, Timings, KEEP_SLABS_BYTES,
};
use super::robust::{reweighted, FirstSolve::From};
use super::slab::{build_slabs, complete_slabs, time_links, Slab};
use super::solve::{FactorReuse, InRun, RunFactors};
use super::system::SystemWindow;
use super::uniqueness::{check_unique_minimizer, CheckedSlabs};
use super::warp::coarse_to_fine;
use super::Weights;
use super::{DataScales, FlowError, FlowParams, MeshSequence, ScaleSums, SpaceTimeSystem};
use super::{EnergyTerms, SolveObserver};
use nalgebra::{Vector2, Vector3};
use std::borrow::Cow;
use std::ops::Range;
use std::time::Instant;

/// The slabs `[a, b)` of a sequence of `n_slabs_in_all` slabs that one rank holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TimeWindow {
    pub slabs: Range<usize>,
    pub n_slabs_in_all: usize,
}

impl TimeWindow {
    /// The window of rank `rank` of `ranks` when the slabs are split into runs as even as
    /// possible: `[rank · S / R, (rank + 1) · S / R)`.
    pub fn of_rank(rank: usize, ranks: usize, n_slabs_in_all: usize) -> Self {
        TimeWindow {
            slabs: rank * n_slabs_in_all / ranks..(rank + 1) * n_slabs_in_all / ranks,
            n_slabs_in_all,
        }
    }

    /// The frames its slabs need: `a − 1 ..= b + 1`, within the sequence's `S + 1` frames.
    pub fn frames(&self) -> Range<usize> {
        self.slabs.start.saturating_sub(1)..(self.slabs.end + 2).min(self.n_slabs_in_all + 1)
    }
}

/// The slabs of one time window, built from its frames ([`TimeWindow::frames`]).
pub struct WindowSlabs {
    /// The slabs of the frames, from slab `offset` on.
    slabs: Vec<Slab>,
    offset: usize,
    window: TimeWindow,
    /// The slabs are the frames' own (not warped or reweighted), so they may be dropped and
    /// rebuilt from the frames.
    rebuildable: bool,
}

impl WindowSlabs {
    /// `frames` holds the whole sequence's frames `offset ..` (at least those of
    /// [`TimeWindow::frames`]).
    pub fn new(
        frames: &MeshSequence,
        offset: usize,
        window: TimeWindow,
        params: &FlowParams,
    ) -> Result<Self, FlowError> {
        params.validate()?;
        let slabs = &window.slabs;
        let held = offset..offset + frames.n_slabs();
        if slabs.is_empty() || slabs.start < held.start || slabs.end > held.end {
            return Err(FlowError::CountMismatch {
                what: "slabs of the window's frames",
                expected: slabs.end.saturating_sub(offset),
                got: frames.n_slabs(),
            });
        }
        let channel_weights = params.channel_weights_for(frames.n_channels())?;
        let slabs = build_slabs(frames, &channel_weights)?;
        let mut window = Self::with_slabs(frames, offset, window, params, slabs)?;
        window.rebuildable = true;
        Ok(window)
    }

    /// The window with given slabs of all its frames (e.g. warped ones), which it keeps.
    fn with_slabs(
        frames: &MeshSequence,
        offset: usize,
        window: TimeWindow,
        params: &FlowParams,
        mut slabs: Vec<Slab>,
    ) -> Result<Self, FlowError> {
        if slabs.len() != frames.n_slabs() {
            return Err(FlowError::CountMismatch {
                what: "slabs of the window's frames",
                expected: frames.n_slabs(),
                got: slabs.len(),
            });
        }
        complete_slabs(&mut slabs, frames, params)?;
        Ok(WindowSlabs {
            slabs,
            offset,
            window,
            rebuildable: false,
        })
    }

    /// The window's own slabs (not the ones beyond its ends).
    fn own(&self) -> &[Slab] {
        &self.slabs[self.local(&self.window.slabs)]
    }

    /// The window's share of the data's scales.
    pub fn scale_sums(&self, frames: &MeshSequence) -> ScaleSums {
        ScaleSums::measure(frames.mesh(), self.own())
    }

    /// The window's blocks, links and right-hand side with the whole sequence's `scales`.
    pub fn assemble(
        &self,
        frames: &MeshSequence,
        params: &FlowParams,
        scales: &DataScales,
    ) -> Result<SystemWindow, FlowError> {
        self.assemble_checked(frames, params, scales, None)
    }

    /// [`WindowSlabs::assemble`], after [`check_unique_minimizer`] over `ranks` (collective)
    /// when there are any.
    fn assemble_checked(
        &self,
        frames: &MeshSequence,
        params: &FlowParams,
        scales: &DataScales,
        check_over: Option<&dyn TimeRanks>,
    ) -> Result<SystemWindow, FlowError> {
        let weights = params.weights(scales)?;
        let links = time_links(&self.slabs, &weights);
        if let Some(ranks) = check_over {
            let checked = CheckedSlabs {
                slabs: &self.slabs,
                links: &links,
                own: self.local(&self.window.slabs),
                offset: self.offset,
            };
            check_unique_minimizer(frames.mesh(), &checked, params, &weights, ranks)?;
        }
        let analysis = frames.slab_symbolic_cache();
        let system = SpaceTimeSystem::assemble(
            frames.mesh(),
            &self.slabs,
            &links,
            params,
            &weights,
            analysis,
        );
        let mut window = system.into_window(self.local(&self.window.slabs));
        window.slabs = self.window.slabs.clone();
        window.n_slabs_in_all = self.window.n_slabs_in_all;
        Ok(window)
    }

    /// Global slabs as indices into the window's frames' slabs.
    fn local(&self, slabs: &Range<usize>) -> Range<usize> {
        slabs.start - self.offset..slabs.end - self.offset
    }
}

impl WindowSlabs {
    /// The energy terms of the window's slabs and of their links to the next slab, for the
    /// window's unknowns `u` followed by the next slab's where there is one, and the window's
    /// flow `intrinsic` in R^3 (`None` for an intrinsic sequence), in one pass.
    fn energy_and_vectors(
        &self,
        frames: &MeshSequence,
        weighting: (&FlowParams, &Weights),
        u: &[f64],
        intrinsic: &[Vec<Vector2<f64>>],
    ) -> (EnergyTerms, Option<Vec<Vec<Vector3<f64>>>>) {
        let first = self.window.slabs.start - self.offset;
        let slab = |s: usize| self.slab(frames, weighting.0, first + s);
        energy_and_vectors(frames, &slab, first, weighting, u, intrinsic)
    }

    /// Drops the slabs when they take more than [`KEEP_SLABS_BYTES`] (as [`super::FlowProblem`]
    /// does): the energy and the flow in R^3 rebuild them one at a time after the solve.
    fn release_large(&mut self, frames: &MeshSequence) {
        let bytes = kept_slab_bytes(frames.mesh(), self.slabs.len());
        if self.rebuildable && bytes > KEEP_SLABS_BYTES {
            self.slabs = Vec::new();
        }
    }

    /// Slab `local` of the window's frames, kept or rebuilt.
    fn slab(&self, frames: &MeshSequence, params: &FlowParams, local: usize) -> Cow<'_, Slab> {
        if let Some(slab) = self.slabs.get(local) {
            return Cow::Borrowed(slab);
        }
        let weights = params.channel_weights_for(frames.n_channels());
        let mut slab = Slab::new(frames, local, &weights.expect("checked when built"))
            .expect("the slabs were built once already");
        slab.complete(frames, local, params)
            .expect("completed once already");
        Cow::Owned(slab)
    }
}

/// The flow of a sequence computed by ranks that each hold one time window: every rank calls
/// it with its window and the sequence's frames [`TimeWindow::frames`] (`frames`, numbered from
/// the window's first frame). Rank 0 returns the whole [`FlowResult`], equal to a single
/// process's up to the solver's tolerance (the same preconditioner; sums in another order);
/// the others return `None`. Timings are rank 0's; `factor_entries` are summed over ranks.
///
/// Coarse-to-fine warping and robust smoothness run as in one process (`flow::outer`):
/// each rank warps or reweights its own slabs between the collective solves. Not distributed
/// (an error on every rank): the `direct` and `pcg-jacobi` solvers
/// ([`FlowError::NotDistributed`]). An error on one rank only (e.g. a broken frame of its
/// window) leaves the others waiting: the caller ends the job, as `meshflow solve` under
/// `mpirun` does with `MPI_Abort`.
pub fn flow_over_ranks(
    frames: &MeshSequence,
    window: &TimeWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    observer: &dyn SolveObserver,
) -> Result<Option<FlowResult>, FlowError> {
    let result = flow_of_own_slabs(frames, window, ranks, params, observer)?;
    Ok(gather_result(ranks, result))
}

/// [`flow_over_ranks`] without the gathering: every rank returns the [`FlowResult`] of its
/// own slabs `window.slabs` (their flow, R³ vectors, warped residual), with the whole
/// sequence's energy, iterations and weights (equal on every rank; timings are each rank's
/// own). What a writer that streams the slabs to their files needs
/// ([`crate::run::write_flow_over_ranks`]): no rank ever holds the whole flow.
pub fn flow_of_own_slabs(
    frames: &MeshSequence,
    window: &TimeWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    observer: &dyn SolveObserver,
) -> Result<FlowResult, FlowError> {
    let start = Instant::now();
    let offset = window.frames().start;
    let mut slabs = WindowSlabs::new(frames, offset, window.clone(), params)?;
    let mut sums = slabs.scale_sums(frames).to_array();
    ranks.sum(&mut sums);
    let scales = ScaleSums::from_array(sums).scales();
    let solver = RankWindow {
        frames,
        window,
        ranks,
        scales,
        factors: RunFactors::new(window.slabs.len()),
    };
    let outer = OuterStart {
        params,
        weights: params.weights(&scales)?,
        scales,
        assembly_seconds: start.elapsed().as_secs_f64(),
    };
    if params.warping.is_active() {
        drop(slabs); // warping builds its own slabs from the images
        return coarse_to_fine(&solver, &outer, observer);
    }
    if !checks_motion(params) {
        if params.is_robust() {
            return reweighted(&solver, &outer, slabs.slabs, From(None), observer);
        }
        return solver.solve_window_slabs(&mut slabs, params, (None, None), observer, start);
    }
    let robust = params.is_robust().then(|| slabs.slabs.clone());
    let first = solver.solve_window_slabs(&mut slabs, params, (None, None), observer, start)?;
    let own = solver.own();
    let slab = |i: usize| slabs.slab(frames, params, own.start + i);
    let robust_slabs = || robust.expect("kept when robust");
    after_first_solve(&solver, &outer, first, &slab, robust_slabs, observer)
}

/// One rank's time window as the [`SlabSolver`] of warping and reweighting.
struct RankWindow<'a> {
    frames: &'a MeshSequence,
    window: &'a TimeWindow,
    ranks: &'a dyn TimeRanks,
    /// The whole sequence's data scales.
    scales: DataScales,
    /// What the window's solves hand on to each other.
    factors: RunFactors,
}

impl SlabSolver for RankWindow<'_> {
    fn frames(&self) -> &MeshSequence {
        self.frames
    }

    fn own(&self) -> Range<usize> {
        let offset = self.window.frames().start;
        self.window.slabs.start - offset..self.window.slabs.end - offset
    }

    fn solve(
        &self,
        params: &FlowParams,
        slabs: Vec<Slab>,
        previous: Option<&FlowResult>,
        reuse: FactorReuse,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError> {
        let start = Instant::now();
        if params.is_robust() {
            let outer = OuterStart {
                params,
                weights: params.weights(&self.scales)?,
                scales: self.scales,
                assembly_seconds: 0.0,
            };
            return reweighted(self, &outer, slabs, From(previous), observer);
        }
        let offset = self.window.frames().start;
        let mut slabs =
            WindowSlabs::with_slabs(self.frames, offset, self.window.clone(), params, slabs)?;
        let run = InRun {
            factors: &self.factors,
            reuse,
        };
        self.solve_window_slabs(&mut slabs, params, (previous, Some(run)), observer, start)
    }

    fn sum(&self, values: &mut [f64]) {
        self.ranks.sum(values);
    }
}

impl RankWindow<'_> {
    /// One linear solve over all ranks of the window's `slabs`, begun at `start`, warm-started
    /// from `previous` (of the own slabs) when given, as one of `run` when given: the result of
    /// the window's own slabs (its flow theirs, its energy terms summed over ranks).
    fn solve_window_slabs(
        &self,
        slabs: &mut WindowSlabs,
        params: &FlowParams,
        (previous, run): (Option<&FlowResult>, Option<InRun<'_>>),
        observer: &dyn SolveObserver,
        start: Instant,
    ) -> Result<FlowResult, FlowError> {
        let (frames, ranks) = (self.frames, self.ranks);
        let system = slabs.assemble_checked(frames, params, &self.scales, Some(ranks))?;
        slabs.release_large(frames);
        let assembly = start.elapsed().as_secs_f64();
        let first = previous.map(FlowResult::next_start);
        let solution = solve_window_in_run(&system, ranks, params, first.as_ref(), run, observer)?;
        let solve = start.elapsed().as_secs_f64() - assembly;
        let n = system.system.slab_dimension();
        let mut u = solution.u.clone();
        u.extend(next_rank_first_slab(ranks, &u[..n]).unwrap_or_default());
        let weights = params.weights(&self.scales)?;
        let intrinsic = intrinsic_fields(&solution.u, n);
        let (terms, vectors) = slabs.energy_and_vectors(frames, (params, &weights), &u, &intrinsic);
        let mut energies = [
            terms.data,
            terms.speed,
            terms.spatial,
            terms.temporal,
            system.system.constant(),
        ];
        ranks.sum(&mut energies);
        let [data, speed, spatial, temporal, energy_at_zero] = energies;
        let energy_terms = EnergyTerms {
            data,
            speed,
            spatial,
            temporal,
        };
        let timings = Timings {
            assembly,
            factorization: solution.factor_seconds,
            solve,
            total: start.elapsed().as_secs_f64(),
            steps: Vec::new(),
        };
        Ok(FlowResult::of_solve(
            solution,
            (intrinsic, vectors),
            (energy_terms, energy_at_zero),
            (weights, self.scales),
            timings,
        ))
    }
}

/// The whole result on rank 0 from every rank's result of its own slabs (`None` on the
/// others): the per-slab fields — flow, flow in R^3, warped residual — gathered in rank order.
fn gather_result(ranks: &dyn TimeRanks, mut result: FlowResult) -> Option<FlowResult> {
    let intrinsic = gather_fields(ranks, &result.intrinsic, |v| [v.x, v.y]);
    let vectors = (result.vectors.as_ref()).map(|v| gather_fields(ranks, v, |v| [v.x, v.y, v.z]));
    let residual = (result.warped_residual.as_ref()).map(|r| gather_fields(ranks, r, |&r| [r]));
    result.intrinsic = intrinsic?
        .into_iter()
        .map(|s| s.chunks(2).map(|c| Vector2::new(c[0], c[1])).collect())
        .collect();
    result.vectors = vectors.map(|v| {
        (v.expect("gathered on rank 0").into_iter())
            .map(|s| {
                s.chunks(3)
                    .map(|c| Vector3::new(c[0], c[1], c[2]))
                    .collect()
            })
            .collect()
    });
    result.warped_residual = residual.map(|r| r.expect("gathered on rank 0"));
    Some(result)
}

/// Per-slab fields of every rank, in rank order, on rank 0 (`None` on the others), each slab's
/// values flattened by `values`; collective.
fn gather_fields<T, const K: usize>(
    ranks: &dyn TimeRanks,
    slabs: &[Vec<T>],
    values: impl Fn(&T) -> [f64; K],
) -> Option<Vec<Vec<f64>>> {
    let per_slab = K * slabs.first().map_or(0, Vec::len);
    let message: Vec<f64> = slabs.iter().flatten().flat_map(&values).collect();
    let all = gather_to_first(ranks, &message)?;
    Some(
        (all.iter().flatten().copied().collect::<Vec<_>>())
            .chunks(per_slab)
            .map(<[f64]>::to_vec)
            .collect(),
    )
}
