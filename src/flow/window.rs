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
//! energy, gathered into one [`FlowResult`] on rank 0.
//!
//! Not done per window: the check that the minimizer is unique (`uniqueness`), which couples
//! all slabs (a singular system then shows as a solver that does not converge); coarse-to-fine
//! warping and robust smoothness, whose outer iterations are not distributed yet.

use super::distributed::{gather_to_first, next_rank_first_slab, solve_window, TimeRanks};
use super::energy::energy_terms;
use super::slab::{build_slabs, embed_where_needed, time_links, Slab};
use super::system::SystemWindow;
use super::{intrinsic_fields, slab_vectors, EnergyTerms, FlowResult, SolveObserver, Timings};
use super::{DataScales, FlowError, FlowParams, MeshSequence, ScaleSums, SpaceTimeSystem};
use super::{Weights, KEEP_SLABS_BYTES};
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;
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

/// The slabs of one time window, built from its frames ([`window_frames`]).
pub struct WindowSlabs {
    /// The slabs of the frames, from slab `offset` on.
    slabs: Vec<Slab>,
    offset: usize,
    window: TimeWindow,
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
        let mut slabs = build_slabs(frames, &channel_weights)?;
        embed_where_needed(&mut slabs, frames, params)?;
        Ok(WindowSlabs {
            slabs,
            offset,
            window,
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
        let weights = params.weights(scales)?;
        let links = time_links(&self.slabs, &weights);
        let system =
            SpaceTimeSystem::assemble(frames.mesh(), &self.slabs, &links, params, &weights);
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
    /// window's unknowns `u` followed by the next slab's where there is one.
    fn energy_terms(
        &self,
        frames: &MeshSequence,
        params: &FlowParams,
        weights: &Weights,
        u: &[f64],
    ) -> EnergyTerms {
        let first = self.window.slabs.start - self.offset;
        let slab = |s: usize| self.slab(frames, params, first + s);
        let counted = self.window.slabs.len();
        energy_terms(frames.mesh(), &slab, (params, weights), u, counted)
    }

    /// The window's flow in R^3 (`None` for an intrinsic sequence).
    fn vectors(
        &self,
        frames: &MeshSequence,
        params: &FlowParams,
        intrinsic: &[Vec<Vector2<f64>>],
    ) -> Option<Vec<Vec<Vector3<f64>>>> {
        let first = self.window.slabs.start - self.offset;
        (intrinsic.par_iter().enumerate())
            .map(|(s, u)| {
                let positions = frames.positions(first + s)?;
                let slab = self.slab(frames, params, first + s);
                Some(slab_vectors(frames.mesh(), &slab, positions, u))
            })
            .collect()
    }

    /// Drops the slabs when they take more than [`KEEP_SLABS_BYTES`] (as [`super::FlowProblem`]
    /// does): the energy and the flow in R^3 rebuild them one at a time after the solve.
    fn release_large(&mut self, frames: &MeshSequence) {
        let mesh = frames.mesh();
        let bytes = self.slabs.len() * (200 * mesh.n_faces() + 8 * mesh.n_halfedges());
        if bytes > KEEP_SLABS_BYTES {
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
        if params.regularizer.needs_embedding() {
            slab.embed(frames, local).expect("embedded once already");
        }
        Cow::Owned(slab)
    }
}

/// The flow of a sequence computed by ranks that each hold one time window: every rank calls
/// it with its window and the sequence's frames [`TimeWindow::frames`] (`frames`, numbered from
/// the window's first frame). Rank 0 returns the whole [`FlowResult`], equal to a single
/// process's up to the solver's tolerance (the same preconditioner; sums in another order);
/// the others return `None`. Timings are rank 0's; `factor_entries` are summed over ranks.
///
/// Not distributed (an error on every rank): coarse-to-fine warping, robust smoothness, and
/// the `direct` and `pcg-jacobi` solvers ([`FlowError::NotDistributed`]). An error on one rank
/// only (e.g. a broken frame of its window) leaves the others waiting: the caller ends the
/// job, as `meshflow solve` under `mpirun` does with `MPI_Abort`.
pub fn flow_over_ranks(
    frames: &MeshSequence,
    window: &TimeWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    observer: &dyn SolveObserver,
) -> Result<Option<FlowResult>, FlowError> {
    if params.warping.is_active() {
        return Err(FlowError::NotDistributed {
            what: "coarse-to-fine warping (--large-motion)",
        });
    }
    if params.robust_smoothness.is_some() {
        return Err(FlowError::NotDistributed {
            what: "robust smoothness (--robust-smoothness)",
        });
    }
    let start = Instant::now();
    let slabs = WindowSlabs::new(frames, window.frames().start, window.clone(), params)?;
    let mut sums = slabs.scale_sums(frames).to_array();
    ranks.sum(&mut sums);
    let scales = ScaleSums::from_array(sums).scales();
    let system = slabs.assemble(frames, params, &scales)?;
    let mut slabs = slabs;
    slabs.release_large(frames);
    let assembly = start.elapsed().as_secs_f64();
    let solution = solve_window(&system, ranks, params, observer)?;
    let solve = start.elapsed().as_secs_f64() - assembly;
    let n = system.system.slab_dimension();
    let mut u = solution.u.clone();
    u.extend(next_rank_first_slab(ranks, &u[..n]).unwrap_or_default());
    let weights = params.weights(&scales)?;
    let terms = slabs.energy_terms(frames, params, &weights, &u);
    let mut energies = [
        terms.data,
        terms.speed,
        terms.spatial,
        terms.temporal,
        system.system.constant(),
    ];
    ranks.sum(&mut energies);
    let intrinsic = intrinsic_fields(&solution.u, n);
    let vectors = slabs.vectors(frames, params, &intrinsic);
    let mut message = solution.u.clone();
    message.extend(
        vectors
            .iter()
            .flatten()
            .flatten()
            .flat_map(|v| [v.x, v.y, v.z]),
    );
    let Some(all) = gather_to_first(ranks, &message) else {
        return Ok(None);
    };
    let (intrinsic, vectors) = unpack_flow(&all, n / 2, vectors.is_some());
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
    Ok(Some(FlowResult::of_solve(
        solution,
        (intrinsic, vectors),
        (energy_terms, energy_at_zero),
        (weights, scales),
        timings,
    )))
}

/// The flow of all slabs from the ranks' messages (each: its slabs' intrinsic values, `2V`
/// per slab, then their vectors in R^3, `3V` per slab, when `embedded`).
#[allow(clippy::type_complexity)]
fn unpack_flow(
    messages: &[Vec<f64>],
    n_vertices: usize,
    embedded: bool,
) -> (Vec<Vec<Vector2<f64>>>, Option<Vec<Vec<Vector3<f64>>>>) {
    let per_slab = match embedded {
        true => 5 * n_vertices,
        false => 2 * n_vertices,
    };
    let mut intrinsic = Vec::new();
    let mut vectors = Vec::new();
    for message in messages {
        let own = message.len() / per_slab;
        let (u, v) = message.split_at(own * 2 * n_vertices);
        intrinsic.extend(intrinsic_fields(u, 2 * n_vertices));
        vectors.extend(v.chunks(3 * n_vertices).map(|s| {
            s.chunks(3)
                .map(|c| Vector3::new(c[0], c[1], c[2]))
                .collect::<Vec<_>>()
        }));
    }
    (intrinsic, embedded.then_some(vectors))
}
