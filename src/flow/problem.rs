//! The flow problem of one sequence: [`FlowProblem`] assembles the space-time system of
//! `docs/discretization.md` for a sequence and parameters, [`compute_flow`] minimizes it (one
//! linear solve, or the outer loops of warping and robust reweighting) and returns a
//! [`FlowResult`] with the fields, the energy, the solver's figures and [`Timings`].

use super::outer::{self, OuterStart, WholeSequence};
use super::robust::FirstSolve::{From, Given};
use super::solve::{FactorReuse, InRun};
use super::{energy, robust, slab, solve, uniqueness, warp};
use super::{DataScales, EnergyTerms, FlowError, FlowParams, MeshSequence, Slab};
use super::{MotionCheck, SolveObserver, SolverMethod, SpaceTimeSystem, Weights};
use crate::connection::{push_forward, vertex_frames_in_r3};
use crate::mesh::Mesh;
use nalgebra::{Vector2, Vector3};
use std::borrow::Cow;
use std::time::Instant;

/// Wall-clock seconds spent in each phase. A run of several linear solves (coarse-to-fine
/// warping, robust reweighting) sums the phases over all of them, `total` is the whole run's
/// wall time, and `steps` lists each solve's share.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Slab geometry, connection, element matrices and global assembly.
    pub assembly: f64,
    /// Cholesky factorizations (included in `solve`).
    pub factorization: f64,
    pub solve: f64,
    pub total: f64,
    /// The solves of a run of several, in order (empty for a single solve).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub steps: Vec<SolveStep>,
}

/// One linear solve of a run of several: what it was, its wall time (including what it
/// needed first, e.g. warping the images) and its solver iterations.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SolveStep {
    /// E.g. `"level 1, warp 2"` or `"reweighting 3"`.
    pub label: String,
    pub seconds: f64,
    pub iterations: usize,
}

/// The flow of a sequence and how it was computed.
#[derive(Clone, Debug)]
pub struct FlowResult {
    /// `intrinsic[s][i]`: the flow of slab `s` at vertex `i`, in the vertex frame of slab `s`.
    pub intrinsic: Vec<Vec<Vector2<f64>>>,
    /// `vectors[s][i]`: the same in R^3, on frame `s` (`docs/discretization.md` §8); `None` for
    /// an intrinsic sequence.
    pub vectors: Option<Vec<Vec<Vector3<f64>>>>,
    /// With coarse-to-fine warping: `warped_residual[s][i] = I⁺_i − I⁻_i`, the grey-value change
    /// that remains between the two frames of slab `s` read halfway along the final flow
    /// ([`warp`]; with several channels, the weighted root mean square over them); `None` for
    /// the single linear solve.
    pub warped_residual: Option<Vec<Vec<f64>>>,
    /// Reweighted solves of the robust smoothness (0 for the quadratic model; with warping,
    /// those of the last warp).
    pub reweightings: usize,
    /// `E(u)` at the solution (with robust smoothness: of the last quadratic model, its
    /// weights lagged).
    pub energy: f64,
    pub energy_terms: EnergyTerms,
    /// `E(0)`: the data term of the zero flow.
    pub energy_at_zero: f64,
    /// `α`, `β`, `γ` as used, in the data's units (relative weights resolved).
    pub weights: Weights,
    /// The data's scales that resolved them.
    pub scales: DataScales,
    pub relative_residual: f64,
    /// Iterations of the (last) linear solve; [`FlowResult::iterations_in_all`] counts all.
    pub iterations: usize,
    pub method: SolverMethod,
    /// Why `method`: the rule the `auto` choice applied, with the figures it compared.
    pub solver_reason: String,
    /// Levels of multigrid in time the solver used (1: none).
    pub time_levels: usize,
    /// Stored entries of the Cholesky factors the solver used.
    pub factor_entries: usize,
    /// How many of them are subnormal numbers: 0 when the solver flushed them
    /// ([`crate::subnormals`], the default).
    pub subnormal_factor_entries: usize,
    /// `[λ_min, λ_max]` of the preconditioned operator as the (last) CG run saw it (Ritz
    /// values; `λ_max/λ_min` estimates the condition number behind the iteration count).
    /// `None` for direct solves.
    pub preconditioned_spectrum: Option<[f64; 2]>,
    /// Per slab, the contrast `λ` of the image-driven anisotropic tensors (`auto` resolved);
    /// empty without them, and over ranks.
    pub anisotropic_contrasts: Vec<f64>,
    /// Per slab, the scale `ε` of robust smoothness (`auto` resolved); empty without it, and
    /// over ranks.
    pub robust_scales: Vec<f64>,
    /// Per slab, the scale `ε` of the robust data term (`auto` resolved); empty without it,
    /// and over ranks.
    pub robust_data_scales: Vec<f64>,
    /// The check of the linear model against the images warped by its flow
    /// ([`FlowParams::detect_large_motion`]); `None` where it did not run (warping asked for,
    /// or the check off).
    pub motion_check: Option<MotionCheck>,
    pub timings: Timings,
}

impl Timings {
    /// These timings of a run, led by the solve `first` before it (labelled `label`): its
    /// phases added, its own time a first step.
    pub(super) fn lead_with(&mut self, label: &str, part: &Timings, iterations: usize) {
        self.factorization += part.factorization;
        self.solve += part.solve;
        self.total += part.total - part.assembly;
        let step = SolveStep {
            label: label.to_string(),
            seconds: part.total - part.assembly,
            iterations,
        };
        self.steps.insert(0, step);
    }
}

impl FlowResult {
    /// The result of one linear solve: its flow (intrinsic, in R^3), energy terms and `E(0)`,
    /// the weights and scales it was assembled with, and its timings.
    #[allow(clippy::type_complexity)]
    pub(crate) fn of_solve(
        solution: solve::Solution,
        (intrinsic, vectors): (Vec<Vec<Vector2<f64>>>, Option<Vec<Vec<Vector3<f64>>>>),
        (energy_terms, energy_at_zero): (EnergyTerms, f64),
        (weights, scales): (Weights, DataScales),
        timings: Timings,
    ) -> Self {
        FlowResult {
            energy: energy_terms.total(),
            energy_terms,
            energy_at_zero,
            weights,
            scales,
            relative_residual: solution.relative_residual,
            iterations: solution.iterations,
            method: solution.method,
            solver_reason: solution.reason,
            time_levels: solution.time_levels,
            factor_entries: solution.factor_entries.stored,
            subnormal_factor_entries: solution.factor_entries.subnormal,
            preconditioned_spectrum: solution.spectrum,
            timings,
            intrinsic,
            vectors,
            warped_residual: None,
            anisotropic_contrasts: Vec::new(),
            robust_scales: Vec::new(),
            robust_data_scales: Vec::new(),
            motion_check: None,
            reweightings: 0,
        }
    }

    /// Where a run's next solve starts after this one ([`solve::WarmStart`]): its flow, its method.
    pub(super) fn next_start(&self) -> solve::WarmStart {
        solve::WarmStart {
            u: flat_unknowns(&self.intrinsic),
            method: self.method,
        }
    }

    /// Solver iterations over all the run's solves (`iterations` is the last solve's).
    pub fn iterations_in_all(&self) -> usize {
        match self.timings.steps.as_slice() {
            [] => self.iterations,
            steps => steps.iter().map(|s| s.iterations).sum(),
        }
    }
}

/// Slab geometry and connection kept after assembly up to this many bytes (estimated at 150
/// bytes per face and slab and 8 per halfedge); beyond it they are rebuilt for the energy
/// terms and the push-forward, in one pass that builds each slab about once more (it was three
/// times: on the 200-frame torus that pass took 8.8 s, 19× the 20-frame one), which bounds the
/// memory per frame.
pub const KEEP_SLABS_BYTES: usize = 1 << 30;

/// The bytes `slabs` slabs' geometry and connections take on `mesh`: per face the triangle
/// (80), the corner rotations (48), its share of the edge lengths and vertex arrays (about 20),
/// and 8 per halfedge (the polar angles).
pub(super) fn kept_slab_bytes(mesh: &Mesh, slabs: usize) -> usize {
    slabs * (150 * mesh.n_faces() + 8 * mesh.n_halfedges())
}

/// A sequence with parameters, assembled: the energy and its linear system, ready to solve.
pub struct FlowProblem<'a> {
    sequence: &'a MeshSequence,
    params: FlowParams,
    weights: Weights,
    scales: DataScales,
    /// Kept while they take at most [`KEEP_SLABS_BYTES`]; rebuilt from the sequence when
    /// needed otherwise, so that long sequences hold only the system and its factors.
    slabs: Option<Vec<Slab>>,
    /// [`FlowResult::anisotropic_contrasts`].
    contrasts: Vec<f64>,
    system: SpaceTimeSystem,
    assembly_seconds: f64,
}

impl<'a> FlowProblem<'a> {
    /// Validates the parameters, builds the slabs, resolves the weights with the data's scales,
    /// assembles the space-time system, and checks that the minimizer is unique.
    pub fn new(sequence: &'a MeshSequence, params: &FlowParams) -> Result<Self, FlowError> {
        params.validate()?;
        check_system_memory(sequence)?;
        let channel_weights = params.channel_weights_for(sequence.n_channels())?;
        let slabs = slab::build_slabs(sequence, &channel_weights)?;
        Self::with_slabs(sequence, params, slabs, true)
    }

    /// The problem with given slabs (e.g. warped ones, [`super::warped_slab`]), which it keeps.
    pub fn from_slabs(
        sequence: &'a MeshSequence,
        params: &FlowParams,
        slabs: Vec<Slab>,
    ) -> Result<Self, FlowError> {
        if slabs.len() != sequence.n_slabs() {
            return Err(FlowError::CountMismatch {
                what: "slabs",
                expected: sequence.n_slabs(),
                got: slabs.len(),
            });
        }
        Self::with_slabs(sequence, params, slabs, false)
    }

    /// `rebuildable`: the slabs are the sequence's own, so they may be dropped past
    /// [`KEEP_SLABS_BYTES`] and rebuilt when needed.
    fn with_slabs(
        sequence: &'a MeshSequence,
        params: &FlowParams,
        mut slabs: Vec<Slab>,
        rebuildable: bool,
    ) -> Result<Self, FlowError> {
        params.validate()?;
        slab::complete_slabs(&mut slabs, sequence, params)?;
        let start = Instant::now();
        let scales = DataScales::measure(sequence.mesh(), &slabs);
        let weights = params.weights(&scales)?;
        let links = slab::time_links(&slabs, &weights);
        let mesh = sequence.mesh();
        let checked = uniqueness::CheckedSlabs {
            slabs: &slabs,
            links: &links,
            own: 0..slabs.len(),
            offset: 0,
        };
        let one = solve::distributed::OneProcess;
        uniqueness::check_unique_minimizer(mesh, &checked, params, &weights, &one)?;
        let analysis = sequence.slab_symbolic_cache();
        let system = SpaceTimeSystem::assemble(mesh, &slabs, &links, params, &weights, analysis);
        let slab_bytes = kept_slab_bytes(mesh, slabs.len());
        let contrasts = slabs.iter().filter_map(|slab| slab.contrast).collect();
        let slabs = match slab_bytes <= KEEP_SLABS_BYTES || !rebuildable {
            true => Some(slabs),
            false => {
                // Before the solver's factors take their place.
                drop(slabs);
                crate::limits::release_free_memory();
                None
            }
        };
        Ok(Self {
            contrasts,
            sequence,
            params: params.clone(),
            weights,
            scales,
            slabs,
            system,
            assembly_seconds: start.elapsed().as_secs_f64(),
        })
    }

    pub fn system(&self) -> &SpaceTimeSystem {
        &self.system
    }

    /// All slabs (rebuilt when the problem did not keep them, see [`KEEP_SLABS_BYTES`]).
    pub fn slabs(&self) -> Cow<'_, [Slab]> {
        match &self.slabs {
            Some(slabs) => Cow::Borrowed(slabs),
            None => Cow::Owned(
                (0..self.system.n_slabs())
                    .map(|s| self.slab(s).into_owned())
                    .collect(),
            ),
        }
    }

    /// Slab `s`, kept or rebuilt.
    pub fn slab(&self, s: usize) -> Cow<'_, Slab> {
        match &self.slabs {
            Some(slabs) => Cow::Borrowed(&slabs[s]),
            None => {
                let weights = self.params.channel_weights_for(self.sequence.n_channels());
                let mut slab = Slab::new(self.sequence, s, &weights.expect("checked in new"))
                    .expect("the slabs were built once already");
                slab.complete(self.sequence, s, &self.params)
                    .expect("completed once already");
                Cow::Owned(slab)
            }
        }
    }

    /// `α`, `β`, `γ` in the data's units, relative weights resolved.
    pub fn weights(&self) -> &Weights {
        &self.weights
    }

    /// The data's scales that resolved the relative weights.
    pub fn scales(&self) -> &DataScales {
        &self.scales
    }

    /// The energy terms at `u` (slab-major, `2V` values per slab), evaluated face by face.
    pub fn energy_terms(&self, u: &[f64]) -> EnergyTerms {
        energy::energy_terms(
            self.sequence.mesh(),
            &|s| self.slab(s),
            (&self.params, &self.weights),
            u,
            u.len() / self.system.slab_dimension(),
        )
    }

    pub fn sequence(&self) -> &'a MeshSequence {
        self.sequence
    }

    pub fn params(&self) -> &FlowParams {
        &self.params
    }

    /// Minimizes the energy (coarse to fine when [`FlowParams::warping`] asks for it);
    /// `observer` receives progress reports.
    pub fn solve(&self, observer: &dyn SolveObserver) -> Result<FlowResult, FlowError> {
        self.solve_from(None, observer)
    }

    /// [`Self::solve`] warm-started from `previous`, the result of a problem on the same
    /// sequence whose system differs a little (as warping and robust reweighting run their
    /// solves): the iterative solvers start from its flow instead of zero, and `auto` goes
    /// straight to multigrid in time where `previous` needed it ([`solve::WarmStart`]). A start that
    /// already meets the tolerance is returned before anything is factored (0 iterations); the
    /// direct solvers ignore it. With robust reweighting, the first solve starts there; with
    /// warping, `previous` is not used (the first solve's images are warped by the zero flow),
    /// and each later solve starts from the last one's result.
    ///
    /// At paper size with `--large-motion` (8 solves) the warm starts took 184 iterations to
    /// 124 and the run from 62.3–67.4 to 60.8–61.5 s on 2 cores (docs/scaling.md, "Warm starts
    /// across a run's solves").
    pub fn solve_from(
        &self,
        previous: Option<&FlowResult>,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError> {
        self.solve_in_run(previous, None, observer)
    }

    /// [`Self::solve_from`] as one solve of `run`, whose slab factors take their buffers from
    /// the run's pool and hand them on ([`solve::solve`]).
    pub(super) fn solve_in_run(
        &self,
        previous: Option<&FlowResult>,
        run: Option<InRun<'_>>,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError> {
        let mut result = self.minimize(previous, run, observer)?;
        result.anisotropic_contrasts = self.contrasts.clone();
        Ok(result)
    }

    /// [`Self::solve_in_run`] but for the contrasts.
    fn minimize(
        &self,
        previous: Option<&FlowResult>,
        run: Option<InRun<'_>>,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError> {
        let outer = OuterStart {
            params: &self.params,
            weights: self.weights,
            scales: self.scales,
            assembly_seconds: self.assembly_seconds,
        };
        let whole = WholeSequence::new(self.sequence);
        if self.params.warping.is_active() {
            return warp::coarse_to_fine(&whole, &outer, observer);
        }
        let robust_slabs = || self.slabs().into_owned();
        // The robust reweightings precondition with the first solve's factors.
        let keep = InRun {
            factors: &whole.factors,
            reuse: FactorReuse {
                take: false,
                keep: true,
            },
        };
        let robust = self.params.is_robust();
        if robust && run.is_some() {
            // A step of an outer run (a warp): reweighted from its own first solve, as on ranks.
            return robust::reweighted(&whole, &outer, robust_slabs(), From(previous), observer);
        }
        let run = if robust { Some(keep) } else { run };
        if !outer::checks_motion(&self.params) {
            let first = self.linear_solve(previous, run, observer)?;
            return match robust {
                true => robust::reweighted(
                    &whole,
                    &outer,
                    robust_slabs(),
                    Given(Box::new(first)),
                    observer,
                ),
                false => Ok(first),
            };
        }
        let first = self.linear_solve(previous, run, observer)?;
        let slab = |s| self.slab(s);
        outer::after_first_solve(&whole, &outer, first, &slab, robust_slabs, observer)
    }

    /// One solve of the assembled system (the quadratic model, unwarped), warm-started from
    /// `previous` when given, as one of `run` when given.
    fn linear_solve(
        &self,
        previous: Option<&FlowResult>,
        run: Option<InRun<'_>>,
        observer: &dyn SolveObserver,
    ) -> Result<FlowResult, FlowError> {
        let first = previous.map(FlowResult::next_start);
        let start = Instant::now();
        let (system, params) = (&self.system, &self.params);
        let solution = solve::solve(system, params, first.as_ref(), run, observer)?;
        let solve_seconds = start.elapsed().as_secs_f64();
        let intrinsic = intrinsic_fields(&solution.u, self.system.slab_dimension());
        let weighting = (&self.params, &self.weights);
        let slab = |s| self.slab(s);
        let (energy_terms, vectors) =
            energy_and_vectors(self.sequence, &slab, 0, weighting, &solution.u, &intrinsic);
        let timings = Timings {
            assembly: self.assembly_seconds,
            factorization: solution.factor_seconds,
            solve: solve_seconds,
            total: self.assembly_seconds + start.elapsed().as_secs_f64(),
            steps: Vec::new(),
        };
        Ok(FlowResult::of_solve(
            solution,
            (intrinsic, vectors),
            (energy_terms, self.system.constant()),
            (self.weights, self.scales),
            timings,
        ))
    }
}

/// The per-slab fields of slab-major unknowns `u` (`slab_dimension = 2V` values per slab, two
/// per vertex).
pub(super) fn intrinsic_fields(u: &[f64], slab_dimension: usize) -> Vec<Vec<Vector2<f64>>> {
    (u.chunks(slab_dimension))
        .map(|us| us.chunks(2).map(|c| Vector2::new(c[0], c[1])).collect())
        .collect()
}

/// The slab-major unknowns of per-slab fields, the inverse of [`intrinsic_fields`].
pub(super) fn flat_unknowns(fields: &[Vec<Vector2<f64>>]) -> Vec<f64> {
    (fields.iter().flatten()).flat_map(|u| [u.x, u.y]).collect()
}

/// The energy terms at `u` of the slabs `0..intrinsic.len()` (and their links to the next slab
/// where `u` has it) and, for embedded sequences, their flows `intrinsic` in R^3, slab `s` on
/// `frames`' frame `first + s`, with `slab(s)` kept or rebuilt: one pass over the slabs, so
/// that a long sequence, which rebuilds them, builds each about once
/// ([`energy::energy_terms_visiting`]).
pub(super) fn energy_and_vectors<'a>(
    frames: &MeshSequence,
    slab: &(dyn Fn(usize) -> Cow<'a, Slab> + Sync),
    first: usize,
    weighting: (&FlowParams, &Weights),
    u: &[f64],
    intrinsic: &[Vec<Vector2<f64>>],
) -> (EnergyTerms, Option<Vec<Vec<Vector3<f64>>>>) {
    let mesh = frames.mesh();
    let (terms, vectors) =
        energy::energy_terms_visiting(mesh, slab, weighting, u, intrinsic.len(), &|s, slab| {
            let positions = frames.positions(first + s)?;
            Some(slab_vectors(mesh, slab, positions, &intrinsic[s]))
        });
    (terms, vectors.into_iter().collect())
}

/// The flow `u` of `slab` in R^3 on the slab's first frame, at `positions`.
pub(super) fn slab_vectors(
    mesh: &Mesh,
    slab: &Slab,
    positions: &[Vector3<f64>],
    u: &[Vector2<f64>],
) -> Vec<Vector3<f64>> {
    let frames = vertex_frames_in_r3(mesh, &slab.geometry, &slab.connection, positions)
        .expect("positions were validated with the sequence");
    push_forward(&frames, u)
}

/// Bytes per unknown that the space-time system takes besides the slab factors (blocks,
/// links, CG's vectors): a lower bound from the 200-frame torus of `docs/scaling.md`, 7.24 GB
/// peak with 4.08 GB of factors over 19.3 M unknowns (≈ 164 B, of which the diagonal blocks'
/// vertex blocks `i ≥ j` take 64 B).
const SYSTEM_BYTES_PER_UNKNOWN: u64 = 140;

/// Refuses, before anything is assembled, a sequence whose system cannot fit the memory limit
/// even without factors.
fn check_system_memory(sequence: &MeshSequence) -> Result<(), crate::limits::OverBudget> {
    let (slabs, vertices) = (
        sequence.n_slabs() as u64,
        sequence.mesh().n_vertices() as u64,
    );
    let unknowns = 2 * vertices * slabs;
    let what = format!(
        "the space-time system of {slabs} slabs × {vertices} vertices ({unknowns} unknowns, \
         {SYSTEM_BYTES_PER_UNKNOWN} bytes each at least)"
    );
    crate::limits::check_items(what, unknowns, SYSTEM_BYTES_PER_UNKNOWN)
}

/// The flow of `sequence`: [`FlowProblem::new`] then [`FlowProblem::solve`], silently.
pub fn compute_flow(sequence: &MeshSequence, params: &FlowParams) -> Result<FlowResult, FlowError> {
    FlowProblem::new(sequence, params)?.solve(&|_| {})
}
