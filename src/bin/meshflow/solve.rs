//! `meshflow solve`: read a sequence, compute its flow, write the outputs (and pictures).

use crate::pictures;
use crate::progress::{solver_progress, spinner};
use crate::SolveArgs;
use meshflow::accuracy::{check_embedded, compare_result};
use meshflow::flow::{FlowParams, FlowProblem, FlowResult, SolveEvent};
use meshflow::io::{load_sequence, write_flow_outputs, LoadOptions, StagedDir};
use meshflow::io::{read_ground_truth, GroundTruthReport, LoadedSequence};
use meshflow::render::sequence_views;
use meshflow::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

pub fn solve(args: &SolveArgs) -> Result<(), Error> {
    let params = FlowParams {
        alpha: args.alpha,
        beta: args.beta,
        gamma: args.gamma,
        boundary: args.boundary,
        time_coupling: args.time_coupling,
        solver: args.solver,
        tolerance: args.tolerance,
        ..FlowParams::default()
    };
    params.validate()?;
    // Before any long computation: fail now if the output cannot be written.
    let out = StagedDir::new(&args.out)?;
    let options = LoadOptions {
        intensity: args.intensity.clone(),
        intensity_attribute: args.intensity_attribute.clone(),
        times: args.times.clone(),
        fps: args.fps,
        ..args.building.options()
    };
    let reading = spinner(format!("reading {}", args.input.display()));
    let loaded = load_sequence(&args.input, &options);
    reading.finish_and_clear();
    let loaded = loaded?;
    crate::print_warnings(&loaded.warnings);
    let sequence = &loaded.sequence;
    println!(
        "{}: {}, {} vertices, {} faces{}",
        args.input.display(),
        loaded.source.describe(),
        sequence.mesh().n_vertices(),
        sequence.mesh().n_faces(),
        crate::welded_note(loaded.vertex_map.n_welded())
    );
    let truth = args
        .ground_truth
        .as_deref()
        .map(|file| read_truth(file, &loaded))
        .transpose()?;
    let problem = FlowProblem::new(sequence, &params)?;
    let progress = solver_progress(params.tolerance);
    let result = problem.solve(&|event| match event {
        SolveEvent::Factorizing { slabs } => progress.set_message(match slabs {
            0 => "factorizing the space-time system".to_string(),
            n => format!("factorizing {n} slabs"),
        }),
        SolveEvent::Iteration {
            iteration,
            relative_residual,
        } => {
            progress.set_position((-relative_residual.log10()).clamp(0.0, 16.0) as u64);
            progress.set_message(format!(
                "CG iteration {iteration}, residual {relative_residual:.1e}"
            ));
        }
    });
    progress.finish_and_clear();
    let result = result?;
    let report = truth
        .map(|(file, truth)| -> Result<_, Error> {
            let errors = compare_result(sequence, &result, &truth)
                .map_err(|e| Error::from(e).in_file(&file))?;
            Ok(GroundTruthReport { file, errors })
        })
        .transpose()?;
    write_flow_outputs(
        &out,
        &loaded,
        &params,
        &result,
        &args.format,
        report.as_ref(),
    )?;
    if args.png {
        draw_pictures(
            out.path(),
            &loaded,
            &result,
            report.as_ref(),
            &args.pictures,
        )
        .map_err(|e| match e {
            Error::Io(e) => Error::Io(out.in_target(e)),
            other => other,
        })?;
    }
    out.commit()?;
    println!(
        "{}: {} frames x {} vertices -> {} slabs; {} solver, {} iterations, residual {:.1e}; energy {:.4e} (zero flow {:.4e}); {:.2} s -> {}",
        args.input.display(),
        sequence.n_frames(),
        sequence.mesh().n_vertices(),
        sequence.n_slabs(),
        result.method,
        result.iterations,
        result.relative_residual,
        result.energy,
        result.energy_at_zero,
        result.timings.total,
        args.out.display()
    );
    if let Some(report) = &report {
        println!(
            "ground truth: mean angular error {:.4}°, mean endpoint error {:.4e}",
            report.errors.mean_angular_degrees, report.errors.mean_endpoint
        );
    }
    Ok(())
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

/// `--png`: the pictures of every slab, from the flow in memory, into the staged output.
fn draw_pictures(
    dir: &Path,
    loaded: &LoadedSequence,
    result: &FlowResult,
    report: Option<&GroundTruthReport>,
    args: &pictures::PictureArgs,
) -> Result<(), Error> {
    let sequence = &loaded.sequence;
    let vectors = result
        .vectors
        .as_ref()
        .expect("sequences read from files are embedded");
    let errors = report.map(|r| r.errors.angular_degrees.as_slice());
    let views = sequence_views(sequence, vectors, errors, 0..sequence.n_slabs())?;
    pictures::draw(dir, sequence.mesh().faces(), &views, args)?;
    Ok(())
}
