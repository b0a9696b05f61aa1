//! The `meshflow` command line. Every failure is one line on stderr and a non-zero exit code.

use clap::{Parser, Subcommand};
use meshflow::accuracy::{check_embedded, compare_result};
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::flow::{Boundary, FlowParams, FlowProblem, SolveEvent, SolverChoice, TimeCoupling};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{load_sequence, write_flow_outputs, LoadOptions, OutputFormat, StagedDir};
use meshflow::io::{read_ground_truth, GroundTruthReport, LoadedSequence};
use meshflow::io::{read_mesh, write_matrix_market, write_npy, IoError};
use meshflow::mesh::Mesh;
use meshflow::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "meshflow",
    version,
    about = "Optical flow on moving surfaces (intrinsic P1 tangent-field FEM)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write the finite-element operators of a mesh for SciPy/MATLAB: cotan.mtx (V×V cotan
    /// Laplacian), mass_scalar.mtx (V×V P1 mass), stiffness.mtx (2V×2V connection Laplacian),
    /// mass.mtx (2V×2V vector mass) and frames.npy (V×2×3 vertex frames in R^3).
    Operators {
        /// Triangle mesh (.obj, .ply, .gltf, .glb)
        mesh: PathBuf,
        /// Output directory (created if missing)
        #[arg(long)]
        out: PathBuf,
    },
    /// Compute the optical flow of a mesh sequence. INPUT is a directory of .obj/.ply/.gltf/.glb
    /// frames (natural order, same faces), a glob ('dir/frame_*.ply'), one .gltf/.glb morph
    /// animation, or a directory with positions.npy, faces.npy, intensity.npy. Grey values come
    /// from vertex colours, textures, a PLY property or --intensity; times from --times,
    /// the glTF animation, a times.txt beside the frames, or 0,1,2,… Writes flow.npy (S×V×3),
    /// flow_intrinsic.npy (S×V×2), flow_SSSS.vtu + flow.pvd (ParaView), flow.glb and
    /// summary.json; with --ground-truth also the errors against the known flow.
    Solve(SolveArgs),
}

#[derive(clap::Args)]
struct SolveArgs {
    /// Frames directory, glob, .gltf/.glb animation, or NPY directory
    input: PathBuf,
    /// Output directory (created if missing)
    #[arg(long)]
    out: PathBuf,
    /// Time regularity scale, a speed (inf: frame-by-frame flow)
    #[arg(long, default_value_t = FlowParams::default().alpha, allow_negative_numbers = true)]
    alpha: f64,
    /// Weight of |u|² (speed penalty)
    #[arg(long, default_value_t = FlowParams::default().beta, allow_negative_numbers = true)]
    beta: f64,
    /// Weight of the spatial smoothness |∇u|²
    #[arg(long, default_value_t = FlowParams::default().gamma, allow_negative_numbers = true)]
    gamma: f64,
    /// neumann or dirichlet (u = 0 on the boundary)
    #[arg(long, default_value = "neumann")]
    boundary: Boundary,
    /// lumped or consistent discretization of the time term
    #[arg(long, default_value = "lumped")]
    time_coupling: TimeCoupling,
    /// auto, direct, pcg-slab-gauss-seidel or pcg-jacobi
    #[arg(long, default_value = "auto")]
    solver: SolverChoice,
    /// Relative residual at which the iterative solver stops
    #[arg(long, default_value_t = FlowParams::default().tolerance, allow_negative_numbers = true)]
    tolerance: f64,
    /// Grey values as a float64 .npy of shape (frames, vertices) instead of vertex colours
    #[arg(long)]
    intensity: Option<PathBuf>,
    /// PLY vertex property holding the grey values (instead of the colours)
    #[arg(long)]
    intensity_attribute: Option<String>,
    /// Frame times t0,t1,… (default: from the files or times.txt, else 0,1,2,…)
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    times: Option<Vec<f64>>,
    /// Resample a glTF animation at N frames per unit of time (default: its keyframes)
    #[arg(long, value_name = "N")]
    fps: Option<f64>,
    /// Keep vertices that coincide in every frame apart (default: weld them, as exporters split
    /// vertices at texture seams)
    #[arg(long)]
    no_weld: bool,
    /// Known flow to measure the result against: .npy (slabs, vertices in the files, 3), float64
    /// or float32, R^3 vectors on frame s. Adds angular_error/endpoint_error to the .vtu files,
    /// angular_error.npy, endpoint_error.npy and "ground_truth" in summary.json
    #[arg(long, value_name = "FILE.npy")]
    ground_truth: Option<PathBuf>,
    /// Output files: any of npy, vtu, glb (summary.json is always written)
    #[arg(long, value_delimiter = ',', default_value = "npy,vtu,glb")]
    format: Vec<OutputFormat>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Operators { mesh, out } => write_operators(&mesh, &out),
        Command::Solve(args) => solve(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("meshflow: error: {error}");
            ExitCode::FAILURE
        }
    }
}

fn write_operators(mesh_path: &Path, out: &Path) -> Result<(), Error> {
    let obj = read_mesh(mesh_path)?;
    let in_file = |e: Error| e.in_file(mesh_path);
    let mesh = Mesh::new(obj.positions.len(), obj.faces).map_err(|e| in_file(e.into()))?;
    let geometry =
        IntrinsicGeometry::from_positions(&mesh, &obj.positions).map_err(|e| in_file(e.into()))?;
    let connection = Connection::new(&mesh, &geometry);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &obj.positions)
        .map_err(|e| in_file(e.into()))?;
    let matrices = fem::exported_operators(&mesh, &geometry, &connection);
    std::fs::create_dir_all(out).map_err(|e| IoError::File {
        path: out.to_path_buf(),
        source: e,
    })?;
    for (name, matrix) in &matrices {
        write_matrix_market(&out.join(format!("{name}.mtx")), matrix)?;
    }
    // frames.npy[i][k] = R^3 image of basis vector k of vertex i's frame.
    let frame_values: Vec<f64> = frames
        .iter()
        .flat_map(|p| {
            [p.column(0), p.column(1)]
                .into_iter()
                .flat_map(|c| [c[0], c[1], c[2]])
        })
        .collect();
    write_npy(
        &out.join("frames.npy"),
        &[mesh.n_vertices() as u64, 2, 3],
        &frame_values,
    )?;
    println!(
        "{}: {} vertices, {} faces, {} boundary vertices, Euler characteristic {} -> {}",
        mesh_path.display(),
        mesh.n_vertices(),
        mesh.n_faces(),
        (0..mesh.n_vertices())
            .filter(|&i| mesh.is_boundary_vertex(i))
            .count(),
        mesh.euler_characteristic(),
        out.display()
    );
    Ok(())
}

fn solve(args: &SolveArgs) -> Result<(), Error> {
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
        weld: !args.no_weld,
    };
    let reading = spinner(format!("reading {}", args.input.display()));
    let loaded = load_sequence(&args.input, &options);
    reading.finish_and_clear();
    let loaded = loaded?;
    let sequence = &loaded.sequence;
    println!(
        "{}: {}, {} vertices, {} faces{}",
        args.input.display(),
        loaded.source.describe(),
        sequence.mesh().n_vertices(),
        sequence.mesh().n_faces(),
        match loaded.welding.n_welded() {
            0 => String::new(),
            n => format!(" (welded {n} duplicate vertices)"),
        }
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
    let truth = read_ground_truth(file, &loaded.welding, loaded.sequence.n_slabs())?;
    Ok((file.to_path_buf(), truth))
}

/// A spinner with a message, for steps without a measure of progress; hidden when stderr is
/// not a terminal.
fn spinner(message: String) -> indicatif::ProgressBar {
    let spinner = indicatif::ProgressBar::new_spinner().with_message(message);
    spinner.enable_steady_tick(std::time::Duration::from_millis(200));
    spinner
}

/// A bar that fills with the digits of residual reduction; hidden when stderr is not a terminal.
fn solver_progress(tolerance: f64) -> indicatif::ProgressBar {
    let digits = (-tolerance.log10()).ceil() as u64;
    let bar = indicatif::ProgressBar::new(digits);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {msg}")
            .expect("valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}
