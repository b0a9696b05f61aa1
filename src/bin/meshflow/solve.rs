//! `meshflow solve`: read a sequence, compute its flow, write the outputs (and pictures).

use crate::args::{ForceArg, MeshArgs};
use crate::pictures;
use crate::pictures::PictureArgs;
use crate::progress::{during, solver_progress};
use meshflow::accuracy::{
    check_embedded, compare_result, score_result, FlowErrors, TrackSummary, Tracks,
};
use meshflow::flow::distributed::TimeRanks;
use meshflow::flow::window::{flow_of_own_slabs, flow_over_ranks, TimeWindow};
use meshflow::flow::{
    Boundary, FlowDriven, FlowError, FlowOptions, FlowParams, FlowProblem, FlowResult,
    MeshSequence, Scale, SolveEvent, SolveObserver, SolverChoice, TimeCoupling, Weight, Weights,
};
use meshflow::format::read_npy_float;
use meshflow::load::{load_frames, load_sequence};
use meshflow::load::{read_ground_truth, LoadOptions, LoadedSequence};
use meshflow::render::{result_views, write_track_error_pictures, UpChoice, View};
use meshflow::run::GroundTruthReport;
use meshflow::run::{write_flow_outputs, Scores, SolveRecord, StagedDir, TrackReport};
use meshflow::run::{write_flow_over_ranks, OutputFormat};
use meshflow::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// The parameters of the solve's flags ([`FlowOptions::params`]).
fn flow_params(args: &SolveArgs) -> Result<FlowParams, Error> {
    Ok(args.flow_options().params()?)
}

/// `meshflow solve`; with `ranks` (under `mpirun`, the `mpi` feature) this is rank 0 of a
/// solve over time windows: it reads, reports and writes, the ranks solve together
/// ([`solve_on_rank`] on the others).
pub fn solve(args: &SolveArgs, ranks: Option<&dyn TimeRanks>) -> Result<(), Error> {
    let params = flow_params(args)?;
    // Before any long computation: fail now if the output cannot be written or would replace
    // files that are not an earlier meshflow output.
    let inputs = args.input_files();
    let mut out = StagedDir::create_apart_from(&inputs, &args.out, args.force.overwrite())?;
    out.record_command(crate::command_line());
    out.record_inputs(&inputs)?;
    out.record_solve(args.solve_record());
    if let Some(ranks) = ranks.filter(|_| streams_outputs(args)) {
        return solve_streamed(args, ranks, &params, out);
    }
    // Over ranks, the others read their windows' frames and weld with rank 0 (`load_frames`).
    if ranks.is_some_and(|ranks| ranks.size() > 1) {
        stdout_line!("{}", gathering_note(args));
    }
    let loaded = during(
        format!("reading {}", args.input.display()),
        || match ranks {
            None => load_sequence(&args.input, &args.load_options()),
            Some(ranks) => load_frames(&args.input, &args.load_options(), None, &|v| ranks.sum(v)),
        },
    )?;
    crate::print_warnings(&loaded.warnings);
    let sequence = &loaded.sequence;
    print_input(args, &loaded);
    let slabs = match args.png {
        true => args.pictures.slabs(sequence.n_slabs())?,
        false => Vec::new(),
    };
    let view = args
        .pictures
        .announced_view(&UpChoice::of_sequence(&loaded));
    let truth = args
        .ground_truth
        .as_deref()
        .map(|file| read_truth(file, &loaded))
        .transpose()?;
    let tracks = args
        .ground_truth_tracks
        .as_deref()
        .map(|file| read_tracks(file, sequence))
        .transpose()?;
    let progress = solver_progress(params.tolerance);
    let result = match ranks {
        None => during("assembling the space-time system", || {
            FlowProblem::new(sequence, &params)
        })
        .and_then(|problem| problem.solve(&|event| show(&progress, event))),
        Some(ranks) => {
            progress.println(solving_over(ranks, sequence.n_slabs()));
            on_first_rank(sequence, ranks, &params, &|event| show(&progress, event))
        }
    };
    progress.finish();
    let result = result?;
    let report = truth
        .map(|(file, truth)| -> Result<_, Error> {
            let in_file = |e: meshflow::accuracy::AccuracyError| Error::from(e).in_file(&file);
            let errors = compare_result(sequence, &result, &truth).map_err(in_file)?;
            let zero_flow = FlowErrors::zero_flow(sequence, &truth).map_err(in_file)?;
            Ok(GroundTruthReport {
                file,
                errors,
                zero_flow,
            })
        })
        .transpose()?;
    let track_report = tracks
        .map(|(file, tracks)| -> Result<_, Error> {
            let scores = score_result(sequence, &result, &tracks)
                .map_err(|e| Error::from(e).in_file(&file))?;
            Ok(TrackReport { file, scores })
        })
        .transpose()?;
    let scores = Scores {
        flow: report.as_ref(),
        tracks: track_report.as_ref(),
    };
    during(format!("writing {}", args.out.display()), || {
        write_flow_outputs(&out, &loaded, &params, &result, &args.format, scores, &view)
    })?;
    let pictures = match args.png {
        true => Pictures {
            slabs: &slabs,
            view,
            args: &args.pictures,
        }
        .draw(out.path(), &loaded, &result, scores)
        .map_err(|e| out.error_in_target(e))?,
        false => Vec::new(),
    };
    out.commit()?;
    print_result(
        args,
        (sequence.n_frames(), sequence.mesh().n_vertices()),
        &params,
        &result,
    );
    if args.png {
        stdout_line!(
            "pictures: {} PNG files for {} slab{} in {}",
            pictures.len(),
            slabs.len(),
            if slabs.len() == 1 { "" } else { "s" },
            args.out.display()
        );
    }
    if let Some(report) = &report {
        stdout_line!("{}", describe_errors("ground truth: flow", &report.errors));
        stdout_line!(
            "{}",
            describe_errors("         zero flow", &report.zero_flow)
        );
    }
    if let Some(report) = &track_report {
        stdout_line!("{}", describe_track_scores(&report.scores.overall));
    }
    Ok(())
}

/// A rank other than 0 of `mpirun -n R meshflow solve …`: reads its time window's frames
/// only (welding with the others), solves it with them, prints nothing (rank 0 reports and
/// writes).
#[cfg(feature = "mpi")]
pub fn solve_on_rank(args: &SolveArgs, ranks: &dyn TimeRanks) -> Result<(), Error> {
    let params = flow_params(args)?;
    let (window, loaded) = read_window(args, ranks)?;
    let sequence = &loaded.sequence;
    match streams_outputs(args) {
        true => {
            let result = flow_of_own_slabs(sequence, &window, ranks, &params, &|_| {})?;
            meshflow::run::send_own_slabs(&loaded, &window, ranks, &result);
        }
        false => {
            flow_over_ranks(sequence, &window, ranks, &params, &|_| {})?;
        }
    }
    Ok(())
}

/// The input as read: its source, mesh size, welding and channels.
fn print_input(args: &SolveArgs, loaded: &LoadedSequence) {
    let sequence = &loaded.sequence;
    stdout_line!(
        "{}: {}, {} vertices, {} faces{}{}",
        args.input.display(),
        loaded.source.describe(),
        sequence.mesh().n_vertices(),
        sequence.mesh().n_faces(),
        crate::welded_note(loaded.vertex_map.n_welded()),
        match sequence.n_channels() {
            1 => String::new(),
            c => format!(", {c} image channels"),
        }
    );
}

/// The solve's outcome: sizes, solver, energy, time, weights and steps.
fn print_result(
    args: &SolveArgs,
    (n_frames, n_vertices): (usize, usize),
    params: &FlowParams,
    result: &FlowResult,
) {
    stdout_line!(
        "{}: {} frames x {} vertices -> {}; {} solver, {} iterations, residual {:.1e}; energy {:.4e} (zero flow {:.4e}); {:.2} s -> {}",
        args.input.display(),
        n_frames,
        n_vertices,
        crate::plural(n_frames - 1, "slab"),
        result.method,
        result.iterations_in_all(),
        result.relative_residual,
        result.energy,
        result.energy_at_zero,
        result.timings.total,
        args.out.display()
    );
    stdout_line!(
        "{}",
        describe_weights(&result.weights, params, result.intrinsic.len())
    );
    stdout_line!("solver: {}", describe_solver(result));
    if !result.timings.steps.is_empty() {
        stdout_line!("{}", describe_steps(result));
    }
    if let Some(line) = describe_anisotropy(params, result) {
        stdout_line!("{line}");
    }
    if let Some(check) = &result.motion_check {
        stdout_line!("{}", describe_motion_check(check));
    }
    if result.reweightings > 0 {
        stdout_line!("{}", describe_robust(params, result));
    }
}

/// The check of the linear model, in one line.
fn describe_motion_check(check: &meshflow::flow::MotionCheck) -> String {
    let error = check.linearization_error;
    match check.warped {
        true => format!(
            "large motion: the linear model's error against the warped images is {error:.2} \
             (above {}), so the flow was solved coarse to fine (--large-motion); \
             --no-large-motion keeps the single linear solve",
            check.threshold
        ),
        false => format!(
            "small motion: the linear model's error against the warped images is {error:.2} \
             (warping from {}; --large-motion forces it)",
            check.threshold
        ),
    }
}

/// The robust penalties and their reweighted solves, in one line.
fn describe_robust(params: &FlowParams, result: &FlowResult) -> String {
    let mut penalties = Vec::new();
    if params.robust_smoothness.is_some() {
        penalties.push(format!(
            "robust smoothness ({}{})",
            match params.flow_driven {
                FlowDriven::Isotropic => "flow-driven isotropic",
                FlowDriven::Anisotropic => "flow-driven anisotropic",
            },
            describe_range("ε", params.robust_smoothness, &result.robust_scales)
                .map_or(String::new(), |range| format!(", {range}")),
        ));
    }
    if let Some(range) = describe_range("ε", params.robust_data, &result.robust_data_scales) {
        penalties.push(format!("robust data term ({range})"));
    }
    format!(
        "{}: {} reweighted solves until the energy settled",
        penalties.join(" and "),
        result.reweightings
    )
}

/// `name = value` as given, or `auto`'s range over the slabs as used (`values`).
fn describe_range(name: &str, scale: Option<Scale>, values: &[f64]) -> Option<String> {
    let (low, high) = (values.iter().copied())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), c| {
            (l.min(c), h.max(c))
        });
    Some(match (scale?, values.is_empty()) {
        (Scale::Value(value), _) => format!("{name} = {value:.4}"),
        (Scale::Auto, true) => format!("{name} = auto"),
        (Scale::Auto, false) if low == high => format!("{name} = {low:.4} (auto)"),
        (Scale::Auto, false) => format!("{name} = {low:.4}–{high:.4} over the slabs (auto)"),
    })
}

/// The image-driven tensors' contrast `λ` as used: given, or `auto`'s range over the slabs.
fn describe_anisotropy(params: &FlowParams, result: &FlowResult) -> Option<String> {
    let anisotropy = params.anisotropy.as_ref()?;
    let contrasts = &result.anisotropic_contrasts;
    let lambda = describe_range("λ", Some(anisotropy.lambda), contrasts)?;
    let sigma = match anisotropy.sigma {
        Some(sigma) => format!("σ = {sigma}"),
        None => "σ = the mean edge length".to_string(),
    };
    let in_time = match anisotropy.in_time {
        true => ", in time too",
        false => "",
    };
    Some(format!(
        "image-driven anisotropic smoothness: {lambda}, presmoothing {sigma}{in_time}"
    ))
}

/// Whether the ranks of a solve over ranks can write its outputs slab by slab, each sending its
/// own to rank 0 ([`write_flow_over_ranks`]), so that no rank reads or holds more than its
/// window: all outputs but `flow.glb`, pictures and ground-truth scores, which need every
/// frame at once on rank 0 (it then reads the whole input and gathers the whole flow).
fn streams_outputs(args: &SolveArgs) -> bool {
    !args.format.contains(&OutputFormat::Glb)
        && !args.png
        && args.ground_truth.is_none()
        && args.ground_truth_tracks.is_none()
}

/// Why rank 0 reads all frames and gathers the whole flow, and how to avoid it.
fn gathering_note(args: &SolveArgs) -> String {
    let mut needs = Vec::new();
    if args.format.contains(&OutputFormat::Glb) {
        needs.push("flow.glb");
    }
    if args.png {
        needs.push("--png");
    }
    if args.ground_truth.is_some() || args.ground_truth_tracks.is_some() {
        needs.push("the ground-truth scores");
    }
    let (verb, them) = match needs.len() {
        1 => ("needs", "it"),
        _ => ("need", "them"),
    };
    format!(
        "ranks: {} {verb} every frame at once, so rank 0 reads the whole input and gathers the \
         whole flow; without {them} (e.g. --format npy,vtu) every rank holds only its window",
        needs.join(" and ")
    )
}

/// Rank 0 of a solve over ranks whose outputs stream ([`streams_outputs`]): it reads its
/// window only, like every rank, and writes the slabs as their ranks send them.
fn solve_streamed(
    args: &SolveArgs,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    out: StagedDir,
) -> Result<(), Error> {
    let reading = format!("reading {} (rank 0's window)", args.input.display());
    let (window, loaded) = during(reading, || read_window(args, ranks))?;
    crate::print_warnings(&loaded.warnings);
    print_input(args, &loaded);
    let view = args
        .pictures
        .announced_view(&UpChoice::of_sequence(&loaded));
    let progress = solver_progress(params.tolerance);
    progress.println(solving_over(ranks, window.n_slabs_in_all));
    let observer = |event| show(&progress, event);
    let result = flow_of_own_slabs(&loaded.sequence, &window, ranks, params, &observer);
    progress.finish();
    let result = result?;
    let written = during(format!("writing {}", args.out.display()), || {
        let formats = &args.format;
        write_flow_over_ranks(
            &out, &loaded, &window, ranks, params, &result, formats, &view,
        )
    })?;
    crate::print_warnings(written.static_image.as_slice());
    out.commit()?;
    let n_vertices = loaded.sequence.mesh().n_vertices();
    print_result(args, (written.n_frames, n_vertices), params, &result);
    Ok(())
}

/// What rank 0 says before a solve over ranks.
fn solving_over(ranks: &dyn TimeRanks, n_slabs: usize) -> String {
    format!(
        "solving over {} ranks (time windows of about {})",
        ranks.size(),
        crate::plural(n_slabs.div_ceil(ranks.size()), "slab")
    )
}

/// This rank's window of the sequence at `args.input` and its frames, welded alike on all
/// ranks ([`load_frames`]).
fn read_window(
    args: &SolveArgs,
    ranks: &dyn TimeRanks,
) -> Result<(TimeWindow, LoadedSequence), Error> {
    let options = args.load_options();
    let n_frames = meshflow::load::count_frames(&args.input, &options)?;
    if n_frames < 2 {
        return Err(FlowError::TooFewFrames(n_frames).into());
    }
    let window = window_of_rank(ranks, n_frames - 1)?;
    let frames = Some(window.frames());
    let loaded = load_frames(&args.input, &options, frames, &|v| ranks.sum(v))?;
    Ok((window, loaded))
}

/// Rank 0's part of the flow over ranks: its window's frames of the whole `sequence`, the
/// solve (`flow_over_ranks`); the whole result.
fn on_first_rank(
    sequence: &MeshSequence,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    observer: &dyn SolveObserver,
) -> Result<FlowResult, FlowError> {
    let window = window_of_rank(ranks, sequence.n_slabs())?;
    let frames = sequence.frames(window.frames())?;
    let result = flow_over_ranks(&frames, &window, ranks, params, observer)?;
    Ok(result.expect("rank 0 gathers the flow"))
}

/// This rank's slabs of `n_slabs`; an error with more ranks than slabs.
fn window_of_rank(ranks: &dyn TimeRanks, n_slabs: usize) -> Result<TimeWindow, FlowError> {
    if ranks.size() > n_slabs {
        return Err(FlowError::TooManyRanks {
            ranks: ranks.size(),
            slabs: n_slabs,
        });
    }
    Ok(TimeWindow::of_rank(ranks.rank(), ranks.size(), n_slabs))
}

/// The solver's progress on the terminal (or in the log).
fn show(progress: &crate::progress::Progress, event: SolveEvent) {
    match event {
        SolveEvent::Factorizing { slabs } => progress.announce(match slabs {
            0 => "factorizing the space-time system".to_string(),
            n => format!("factorizing {}", crate::plural(n, "slab")),
        }),
        SolveEvent::Warp {
            level,
            warp,
            solve,
            solves,
        } => progress.println(format!(
            "warping: solve {solve} of {solves} (level {level}, warp {})",
            warp + 1
        )),
        SolveEvent::LargeMotion {
            linearization_error,
            threshold,
        } => progress.println(format!(
            "the motion is large for the linear model (linearization error {linearization_error:.2} \
             > {threshold}): solving again coarse to fine, as --large-motion does \
             (--no-large-motion keeps the linear solve)"
        )),
        SolveEvent::Iteration {
            iteration,
            relative_residual,
        } => {
            progress.set_position((-relative_residual.log10()).clamp(0.0, 16.0) as u64);
            progress.set_message(format!(
                "CG iteration {iteration}, residual {relative_residual:.1e}"
            ));
        }
    }
}

/// `--ground-truth-tracks`, read and checked against the sequence before the solve.
fn read_tracks(file: &Path, sequence: &MeshSequence) -> Result<(PathBuf, Tracks), Error> {
    let in_file = |e: Error| e.in_file(file);
    check_embedded(sequence).map_err(|e| in_file(e.into()))?;
    let array = read_npy_float(file)?;
    let tracks = Tracks::from_array(&array.shape, &array.data).map_err(|e| in_file(e.into()))?;
    tracks.check_for(sequence).map_err(|e| in_file(e.into()))?;
    Ok((file.to_path_buf(), tracks))
}

/// One line of scores at tracked points (see `meshflow::accuracy::tracks`).
pub fn describe_track_scores(s: &TrackSummary) -> String {
    format!(
        "tracked points: {} pairs, endpoint error mean {:.3} / median {:.3} (zero flow {:.3} / {:.3}: {:.2}×), direction error mean {:.1}° / median {:.1}° at {} that moved, median speed ratio {:.2}",
        s.points,
        s.mean_endpoint,
        s.median_endpoint,
        s.zero_mean_endpoint,
        s.zero_median_endpoint,
        s.endpoint_ratio(),
        s.mean_direction_degrees,
        s.median_direction_degrees,
        s.moving,
        s.median_speed_ratio,
    )
}

/// `truth[s][i]`: the known R^3 flow of slab `s` at mesh vertex `i`.
type TrueFlow = Vec<Vec<Vector3<f64>>>;

/// The `--ground-truth` flow on the welded vertices, read before the solve so that a bad file
/// fails at once.
fn read_truth(file: &Path, loaded: &LoadedSequence) -> Result<(PathBuf, TrueFlow), Error> {
    check_embedded(&loaded.sequence).map_err(|e| Error::from(e).in_file(file))?;
    let truth = read_ground_truth(file, &loaded.vertex_map, loaded.sequence.n_slabs())?;
    Ok((file.to_path_buf(), truth))
}

/// `--png`: which slabs, seen how.
struct Pictures<'a> {
    slabs: &'a [usize],
    view: View,
    args: &'a pictures::PictureArgs,
}

impl Pictures<'_> {
    /// Draws the slabs, from the flow in memory, into the staged output `dir`.
    fn draw(
        &self,
        dir: &Path,
        loaded: &LoadedSequence,
        result: &FlowResult,
        scores: Scores,
    ) -> Result<Vec<PathBuf>, Error> {
        let sequence = &loaded.sequence;
        let errors = scores.flow.map(|r| r.errors.angular_degrees.as_slice());
        let mut views = result_views(sequence, result, errors)?;
        let no_data = loaded.slab_no_data();
        for view in &mut views {
            view.no_data = no_data.as_ref().map(|mask| &mask[view.slab][..]);
        }
        let faces = sequence.mesh().faces();
        let mut written = pictures::draw(dir, faces, &views, self.slabs, self.args, self.view)?;
        if let Some(tracks) = scores.tracks {
            let points = &tracks.scores.points;
            let options = self.args.options(self.view);
            written.extend(write_track_error_pictures(
                dir, faces, &views, self.slabs, points, &options,
            )?);
        }
        Ok(written)
    }
}

/// One line with the weights used, and the unit-free scales they came from.
fn describe_weights(weights: &Weights, params: &FlowParams, n_slabs: usize) -> String {
    let origin = |weight: Weight, relative: &str| match weight {
        Weight::Value(_) => String::new(),
        Weight::Relative(x) => format!(" ({relative} {x})"),
    };
    let alpha = match (n_slabs, weights.alpha.is_finite()) {
        (1, _) => "α unused (one slab: nothing to couple in time)".to_string(),
        (_, false) => "α = ∞ (frame by frame: no coupling in time)".to_string(),
        _ => format!(
            "α = {:.4e}{}",
            weights.alpha,
            origin(params.alpha, "time scale")
        ),
    };
    format!(
        "weights: γ = {:.4e}{}, {alpha}, β = {:.4e}{}",
        weights.gamma,
        origin(params.gamma, "spread"),
        weights.beta,
        origin(params.beta, "speed penalty"),
    )
}

/// One line of scores against a ground truth (see `meshflow::accuracy`).
fn describe_errors(label: &str, errors: &FlowErrors) -> String {
    format!(
        "{label}: angular error {:.2}° (displacements in mean edge lengths), direction error {:.2}° where it moves ({:.0} % of the surface), relative endpoint error {:.1} %, median speed ratio {:.2}",
        errors.mean_angular_degrees,
        errors.mean_direction_degrees,
        100.0 * errors.moving_fraction,
        100.0 * errors.relative_endpoint,
        errors.median_speed_ratio,
    )
}

/// `6 solves (level 1, warp 1: 5.1 s, 40 iterations; …)`: each solve's share of a run of several.
fn describe_steps(result: &FlowResult) -> String {
    let steps: Vec<String> = result
        .timings
        .steps
        .iter()
        .map(|s| {
            format!(
                "{}: {:.2} s, {} iterations",
                s.label, s.seconds, s.iterations
            )
        })
        .collect();
    format!("{} solves ({})", steps.len(), steps.join("; "))
}

/// `PCG (multigrid in time), 5 time levels: <why>`.
fn describe_solver(result: &FlowResult) -> String {
    match result.time_levels {
        1 => format!("{}: {}", result.method, result.solver_reason),
        n => format!(
            "{}, {n} time levels: {}",
            result.method, result.solver_reason
        ),
    }
}

#[derive(clap::Args)]
pub(crate) struct SolveArgs {
    /// Frames directory, glob (quoted), .gltf/.glb animation, or NPY directory
    pub(crate) input: PathBuf,
    /// Output directory (created if missing; an earlier meshflow output there is replaced as a
    /// whole)
    #[arg(long)]
    pub(crate) out: PathBuf,
    #[command(flatten)]
    pub(crate) force: ForceArg,
    /// Spatial smoothing scale in mean edge lengths, unit-free: sets γ = (SPREAD·h̄·S)² from
    /// the mean edge length h̄ and the image's gradient scale S [default: 0.5]
    #[arg(
        long,
        value_name = "EDGES",
        allow_negative_numbers = true,
        conflicts_with = "gamma"
    )]
    pub(crate) spread: Option<f64>,
    /// Temporal smoothing scale in frames, unit-free: sets α = √γ / (S·FRAMES·Δt̄); 0 for
    /// frame-by-frame flow [default: 1]
    #[arg(
        long,
        value_name = "FRAMES",
        allow_negative_numbers = true,
        conflicts_with = "alpha"
    )]
    pub(crate) time_scale: Option<f64>,
    /// Relative penalty on the speed, unit-free: sets β = B·S² [default: 0]
    #[arg(
        long,
        value_name = "B",
        allow_negative_numbers = true,
        conflicts_with = "beta"
    )]
    pub(crate) speed_penalty: Option<f64>,
    /// The paper's α as a number (a speed in the data's units; inf: frame-by-frame flow),
    /// instead of --time-scale
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) alpha: Option<f64>,
    /// The paper's β as a number (weight of |u|², in the data's units), instead of
    /// --speed-penalty
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) beta: Option<f64>,
    /// The paper's γ as a number (weight of |∇u|², in grey-value units squared), instead of
    /// --spread
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) gamma: Option<f64>,
    /// What γ weighs: covariant (the paper's |∇u|²), strain (|Sym ∇u|², zero on rigid
    /// motions of the surface: a texture turning with it is not pulled towards rest) or
    /// embedded (|∇u|² of u as an R^3 field, Kirisits–Lang–Scherzer: adds |II(u,·)|²)
    #[arg(long, default_value = "covariant")]
    pub(crate) regularizer: meshflow::flow::Regularizer,
    /// With --regularizer strain: add D·|∇u|² (the covariant term, relative to γ) [default: 0]
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    pub(crate) dirichlet_mix: Option<f64>,
    /// Image-driven anisotropic smoothness (Nagel–Enkelmann): smooth the flow along image
    /// edges, less across them; LAMBDA (grey value per length, > 0) is the edge contrast at
    /// which smoothing across falls to 2/3 (large: the isotropic |∇u|²), auto 1.5 × each
    /// slab's contrast-weighted median contrast. Covariant and strain regularizers; the image
    /// is presmoothed over --anisotropic-sigma
    #[arg(long, value_name = "LAMBDA|auto", allow_negative_numbers = true)]
    pub(crate) anisotropic: Option<meshflow::flow::Scale>,
    /// With --anisotropic: the width (a length, ≥ 0; 0: none) over which the image is smoothed
    /// on the surface before its edges steer the smoothing [default: the mean edge length]
    #[arg(
        long,
        value_name = "SIGMA",
        allow_negative_numbers = true,
        requires = "anisotropic"
    )]
    pub(crate) anisotropic_sigma: Option<f64>,
    /// With --anisotropic: weigh the coupling in time by the space-time tensor's time entry,
    /// weaker where the image changes fast in time (measured: within 1 % of without on
    /// examples/motion_boundaries)
    #[arg(long, requires = "anisotropic")]
    pub(crate) anisotropic_in_time: bool,
    /// Robust (Charbonnier) smoothness for flows with discontinuities (cells moving on a
    /// still background): the smoothness grows like 2·EPS·|∇u| beyond |∇u| = EPS instead of
    /// quadratically (EPS in 1/time units, or auto: per slab twice the median |∇u| of a first
    /// quadratic solve; reweighted solves until the energy settles)
    #[arg(long, value_name = "EPS|auto", allow_negative_numbers = true)]
    pub(crate) robust_smoothness: Option<meshflow::flow::Scale>,
    /// Robust (Charbonnier) data term, the smooth TV-L1: each face's residual ∂_t I + dI(u)
    /// costs 2·EPS·|residual| beyond EPS instead of its square, so that where the image breaks
    /// brightness constancy (cells appearing, occlusions, noise) it pulls less (EPS in grey value
    /// per time, or auto: the residual that a flow wrong by a tenth of an edge length per frame
    /// leaves at the image's typical gradient; reweighted solves until the energy settles)
    #[arg(long, value_name = "EPS|auto", allow_negative_numbers = true)]
    pub(crate) robust_data: Option<meshflow::flow::Scale>,
    /// With warping: replace the flow each warp is linearized around by its weighted median
    /// over each vertex's star (Sun, Roth & Black's median filtering between warps)
    #[arg(long)]
    pub(crate) median_filter: bool,
    /// Combined local-global data term (Bruhn, Weickert & Schnörr): the flow at a vertex
    /// explains the brightness change of its neighbourhood, the motion tensor averaged over a
    /// Gaussian of standard deviation RHO (a length on the surface), so that sparse bright
    /// cells inform their dark surroundings
    #[arg(long, value_name = "RHO")]
    pub(crate) local_integration: Option<f64>,
    /// With --robust-smoothness: isotropic (the penalty of |∇u|, one weight per face) or
    /// anisotropic (of each principal direction of ∇u: the flow may jump across a boundary
    /// and stay smooth along it; with --anisotropic, along the image's edges)
    #[arg(long, default_value = "isotropic", value_name = "KIND")]
    pub(crate) flow_driven: meshflow::flow::FlowDriven,
    /// neumann or dirichlet (u = 0 on the boundary)
    #[arg(long, default_value = "neumann")]
    pub(crate) boundary: Boundary,
    /// lumped or consistent discretization of the time term
    #[arg(long, default_value = "lumped")]
    pub(crate) time_coupling: TimeCoupling,
    /// auto, direct, pcg-slab-gauss-seidel, pcg-time-multigrid or pcg-jacobi
    #[arg(long, default_value = "auto")]
    pub(crate) solver: SolverChoice,
    /// Coarse-to-fine warping for large motions: image scales, coarsest first (1: the paper's
    /// single linear solve) [default: 1, or 4 with --large-motion]
    #[arg(long, value_name = "N")]
    pub(crate) levels: Option<usize>,
    /// Warps (re-linearizations, each one solve of the whole sequence) per level [default: 0,
    /// 1 with --levels above 1, 2 with --large-motion]
    #[arg(long, value_name = "M")]
    pub(crate) warps: Option<usize>,
    /// Motions larger than the image's features (a texture turning by several triangle widths
    /// per frame): coarse-to-fine symmetric warping with 4 levels and 2 warps each (8 solves).
    /// Without it (and without --levels) the solve checks its linear flow against the warped
    /// images and warps by itself when the motion is too large for the linear model
    #[arg(long, conflicts_with = "no_large_motion")]
    pub(crate) large_motion: bool,
    /// Never warp by itself: the paper's single linear solve, however large the motion
    #[arg(long)]
    pub(crate) no_large_motion: bool,
    /// Relative residual at which the iterative solver stops
    #[arg(long, default_value_t = FlowParams::default().tolerance, allow_negative_numbers = true)]
    pub(crate) tolerance: f64,
    /// The image as a float32, float64, uint8 or uint16 .npy of shape (frames, file vertices), or (frames,
    /// file vertices, channels), instead of the files' colours
    #[arg(long)]
    pub(crate) intensity: Option<PathBuf>,
    /// Image channels: auto (every channel the input has: RGB for colours, one for grey
    /// colours and values), rgb, luma (Rec. 709) or grey (mean of the channels)
    #[arg(long, default_value = "auto")]
    pub(crate) channels: meshflow::load::Channels,
    /// Weight of each image channel in the data term, w1,w2,… (one per channel) [default: 1
    /// each]
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "W",
        allow_negative_numbers = true
    )]
    pub(crate) channel_weights: Option<Vec<f64>>,
    /// PLY vertex property holding the grey values (instead of the colours)
    #[arg(long)]
    pub(crate) intensity_attribute: Option<String>,
    /// Frame times t0,t1,… (default: from the files or times.txt, else 0,1,2,…)
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub(crate) times: Option<Vec<f64>>,
    /// Resample a glTF animation at N frames per unit of time (default: its keyframes)
    #[arg(long, value_name = "N")]
    pub(crate) fps: Option<f64>,
    /// The glTF animation (clip) to read, by name or index (default: the first that moves the
    /// mesh: its morph weights, skin joints or node transforms)
    #[arg(long, value_name = "NAME|INDEX")]
    pub(crate) animation: Option<String>,
    #[command(flatten)]
    pub(crate) building: MeshArgs,
    /// Known flow to measure the result against: .npy (slabs, vertices in the files, 3), float64
    /// or float32, R^3 vectors on frame s. Adds angular_error/endpoint_error to the .vtu files,
    /// angular_error.npy, endpoint_error.npy and "ground_truth" in summary.json
    #[arg(long, value_name = "FILE.npy")]
    pub(crate) ground_truth: Option<PathBuf>,
    /// Points whose motion is known (tracked cells, beads, landmarks): .npy (frames, points, 3)
    /// of positions, NaN where a point is not tracked (`meshflow match` makes one from point
    /// clouds). Scores the flow's tangential displacement at them against the zero flow's:
    /// "ground_truth_tracks" in summary.json
    #[arg(long, value_name = "TRACKS.npy")]
    pub(crate) ground_truth_tracks: Option<PathBuf>,
    /// Output files: any of npy, vtu, glb (summary.json is always written). Under mpirun,
    /// without glb (and --png, ground truth) the ranks stream their slabs to rank 0 and none
    /// holds more than its time window
    #[arg(long, value_delimiter = ',', default_value = "npy,vtu,glb")]
    pub(crate) format: Vec<OutputFormat>,
    /// Also draw the pictures of `meshflow render` (of every slab, or those of --slabs)
    #[arg(long)]
    pub(crate) png: bool,
    #[command(flatten)]
    pub(crate) pictures: PictureArgs,
}

impl SolveArgs {
    /// How `solve` reads its input (`advect` reads it again the same way).
    pub(crate) fn load_options(&self) -> LoadOptions {
        LoadOptions {
            intensity: self.intensity.clone(),
            channels: self.channels,
            intensity_attribute: self.intensity_attribute.clone(),
            times: self.times.clone(),
            fps: self.fps,
            animation: self.animation.clone(),
            ..self.building.options()
        }
    }

    /// What the solve reads, as its output's manifest records it for later commands: the
    /// input (`None` when it is the output itself: a run that holds its input) and how it is
    /// loaded.
    pub(crate) fn solve_record(&self) -> SolveRecord {
        let input = (self.input != self.out).then_some(self.input.as_path());
        SolveRecord::new(input, self.load_options(), &self.out)
    }

    /// The files and directories the solve reads: its input, `--intensity`, `--ground-truth`
    /// and `--ground-truth-tracks`.
    pub(crate) fn input_files(&self) -> Vec<&std::path::Path> {
        std::iter::once(self.input.as_path())
            .chain(self.intensity.as_deref())
            .chain(self.ground_truth.as_deref())
            .chain(self.ground_truth_tracks.as_deref())
            .collect()
    }

    /// The solve's flags, one setting each.
    pub(crate) fn flow_options(&self) -> FlowOptions {
        FlowOptions {
            alpha: self.alpha,
            time_scale: self.time_scale,
            beta: self.beta,
            speed_penalty: self.speed_penalty,
            gamma: self.gamma,
            spread: self.spread,
            regularizer: self.regularizer,
            dirichlet_mix: self.dirichlet_mix,
            anisotropic: self.anisotropic,
            anisotropic_sigma: self.anisotropic_sigma,
            anisotropic_in_time: self.anisotropic_in_time,
            robust_smoothness: self.robust_smoothness,
            flow_driven: self.flow_driven,
            robust_data: self.robust_data,
            median_filter: self.median_filter,
            local_integration: self.local_integration,
            detect_large_motion: !self.no_large_motion,
            channel_weights: self.channel_weights.clone(),
            boundary: self.boundary,
            time_coupling: self.time_coupling,
            solver: self.solver,
            tolerance: self.tolerance,
            levels: self.levels,
            warps: self.warps,
            large_motion: self.large_motion,
        }
    }
}

/// `meshflow solve`: in one process, or over the ranks `mpirun` started (the `mpi` feature).
pub(crate) fn solve_command(args: &SolveArgs) -> Result<(), meshflow::Error> {
    #[cfg(feature = "mpi")]
    return crate::ranks::solve(args);
    #[cfg(not(feature = "mpi"))]
    solve(args, None)
}
