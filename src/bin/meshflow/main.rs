//! The `meshflow` command line. Every failure is one line on stderr and a non-zero exit code.

/// `println!` that leaves out a line it cannot write: a run's product is its files, and a
/// reader that has gone (`meshflow solve … | head`) must not stop it (`println!` panics on a
/// closed pipe).
macro_rules! stdout_line {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// [`stdout_line!`] on stderr: progress, warnings and errors.
macro_rules! stderr_line {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

mod advect;
mod analyze;
mod args;
mod operators;
mod pictures;
mod progress;
#[cfg(feature = "mpi")]
mod ranks;
mod run;
mod sample;
mod solve;
mod surface;
mod track;
mod usage;

use args::{ForceArg, MeshArgs};
use clap::{Parser, Subcommand};
use meshflow::run::OutputFormat;
use pictures::{PictureArgs, ViewArgs};
use sample::SampleArgs;
use solve::{solve_command, SolveArgs};
use std::path::PathBuf;
use std::process::ExitCode;
use surface::SurfaceArgs;
use track::TrackArgs;

#[derive(Parser)]
#[command(
    name = "meshflow",
    version,
    about = "Optical flow on moving surfaces (intrinsic P1 tangent-field FEM)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// No progress on stderr (results, warnings and errors still print). Without it, progress
    /// is drawn as bars on a terminal and written as plain time-stamped lines to a log or pipe
    #[arg(long, global = true)]
    quiet: bool,
    /// Memory this run may take, e.g. 1.5G, 800M (suffixes K, M, G, T): sizes that input
    /// files declare are checked against it before anything is allocated, and the solver's
    /// factors take at most 35 % of it [default: the machine's physical memory]
    #[arg(long, global = true, value_name = "SIZE", value_parser = meshflow::limits::parse_size)]
    memory_limit: Option<u64>,
    /// Read files that input files name (glTF buffers and images, OBJ material libraries and
    /// textures, an OME-Zarr store's files, a run's recorded inputs and own files) also
    /// outside the naming file's directory: absolute paths, '..' and links that lead out (for
    /// trusted data only)
    #[arg(long, global = true)]
    allow_external_files: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Write the finite-element operators of a mesh for SciPy/MATLAB: cotan.mtx (V×V cotan
    /// Laplacian), mass_scalar.mtx (V×V P1 mass), stiffness.mtx (2V×2V connection Laplacian),
    /// mass.mtx (2V×2V vector mass) and frames.npy (V×2×3 vertex frames in R^3), over the mesh
    /// vertices (welded, unused ones dropped, split by --repair), with vertex_map.npy (the mesh
    /// vertex of each file vertex, −1 if dropped) when they differ from the file's.
    Operators {
        /// Triangle mesh (.obj, .ply, .gltf, .glb)
        mesh: PathBuf,
        /// Output directory (created if missing; an earlier meshflow output there is replaced)
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        building: MeshArgs,
        #[command(flatten)]
        force: ForceArg,
    },
    /// Compute the optical flow of a mesh sequence. INPUT is a directory of .obj/.ply/.gltf/.glb
    /// frames (natural order, same faces), a glob ('dir/frame_*.ply'), one .gltf/.glb animation
    /// (morph targets, skin), or a directory with positions.npy, faces.npy, intensity.npy. Grey values come
    /// from vertex colours, textures, a PLY property or --intensity; times from --times,
    /// the glTF animation, a times.txt beside the frames, or 0,1,2,… Writes flow.npy (S×V×3),
    /// flow_intrinsic.npy (S×V×2), flow_SSSS.vtu + flow.pvd (ParaView), flow.glb and
    /// summary.json; with --ground-truth also the errors against the known flow; with --png the
    /// pictures of `meshflow render`.
    Solve(Box<SolveArgs>),
    /// Turn frames that each have their own triangulation (a segmentation meshed per time
    /// point, a 4D scan, a remeshing simulation) into one moving mesh with fixed connectivity:
    /// from frame to frame every vertex of the reference mesh moves along its
    /// (corner-angle-weighted) normal to the next frame's surface, then the mesh is relaxed on
    /// that surface as rigidly as possible against the previous frame so that it does not fold
    /// (--relax none: normal motion only); --align takes a sample's drift out, and reference
    /// vertices beyond a frame's boundary are trimmed away. Writes positions.npy, faces.npy,
    /// intensity.npy and times.txt, which `meshflow solve DIR` reads, and track.json (per
    /// frame: steps, relaxation, edge-length changes, flipped triangles, misses, alignment).
    Track(Box<TrackArgs>),
    /// Follow points through a finished `solve` run along its flow (straightest geodesics of
    /// each slab, from every mesh vertex): writes trajectories.npy (frames × vertices × 3, on
    /// each frame), trajectory_faces.npy and trajectory_barycentric.npy (where they are as
    /// mesh points), and the sequence reparametrized by the flow (positions.npy, faces.npy,
    /// intensity.npy, times.txt: the image the vertices see as they move, nearly static for a
    /// good flow; its change per frame is printed). The input is read again as the run's
    /// solve command read it.
    Advect {
        /// Output directory of `meshflow solve`
        run: PathBuf,
        /// Output directory
        #[arg(long)]
        out: PathBuf,
        /// Points to follow instead of the vertices: a float .npy of shape (N, 3), each taken
        /// to its closest point on frame 0's surface (then only the paths are written)
        #[arg(long, value_name = "FILE.npy")]
        seeds: Option<PathBuf>,
        #[command(flatten)]
        force: ForceArg,
    },
    /// What a finished `solve` run's flow tells, per slab on the slab's mean geometry:
    /// divergence and curl (per face, and per vertex in the weak form), the Helmholtz–Hodge
    /// parts of the face-wise flow (exact ∇φ, co-exact J∇ψ, harmonic) with their potentials,
    /// and the tissue's rate of deformation (the mesh's own motion plus the flow: areal growth
    /// rate, shear rate, principal rates and directions). Writes NPY arrays, analysis_SSSS.vtu
    /// and analysis.pvd (point and cell data) and summary.json (per slab: area, mean speed,
    /// divergence, curl, areal and shear rate, energy of each Hodge part), and prints the table.
    Analyze {
        /// Output directory of `meshflow solve`
        run: PathBuf,
        /// Output directory
        #[arg(long)]
        out: PathBuf,
        /// Output files: npy, vtu or both (summary.json is always written)
        #[arg(long, value_delimiter = ',', default_value = "npy,vtu")]
        format: Vec<OutputFormat>,
        /// Also draw PNG pictures: divergence_SSSS.png, curl_SSSS.png, areal_rate_SSSS.png
        /// (diverging colours, one symmetric range per quantity for the whole run) and
        /// time_series.png (the means over the surface per slab)
        #[arg(long)]
        png: bool,
        /// With --png: draw the fields smoothed along the surface over LENGTH first (a Gaussian
        /// of that standard deviation, in the surface's units), to see the tissue-scale pattern
        /// behind per-cell detail
        #[arg(long, value_name = "LENGTH", requires = "png", value_parser = pictures::parse_positive)]
        tissue_scale: Option<f64>,
        #[command(flatten)]
        force: ForceArg,
        #[command(flatten)]
        pictures: ViewArgs,
    },
    /// Fit a moving surface through points per frame (cell centres, landmarks; physical
    /// units), or through the bright voxels of 3-D images (volumes, with --voxel-size): a
    /// smoothing-spline height over a sphere fitted to frame 0's points (the cap they cover,
    /// or --whole-sphere) or over the plane z = 0 (--shape graph); or, with --shape closed,
    /// the surface of the object found in the volumes, tracked into one mesh. Writes positions.npy, faces.npy and times.txt, which `meshflow sample` and
    /// `meshflow solve` read, and surface.json (the reference and the fit's residuals, or the
    /// thresholds and components, per frame).
    Surface(Box<SurfaceArgs>),
    /// Chain point clouds per frame (cell centres, beads) into tracks by mutual nearest
    /// neighbours between consecutive frames: a (frames, points, 3) .npy with NaN where a
    /// track has no point, for `meshflow solve --ground-truth-tracks`.
    Match {
        /// Points per frame: a directory or quoted glob of (N, 3) .npy or .csv files
        points: PathBuf,
        /// Output .npy
        #[arg(long, value_name = "TRACKS.npy")]
        out: PathBuf,
        /// Largest distance between matched points [default: half the median
        /// nearest-neighbour distance of the first frame]
        #[arg(long, value_name = "LENGTH", allow_negative_numbers = true)]
        max_distance: Option<f64>,
    },
    /// Carry a microscope recording onto a moving surface: per vertex and frame, the volume
    /// (trilinear) along the vertex normal over a shell, reduced to one value (the maximum by
    /// default: a maximum-intensity projection). Writes intensity.npy (frames × file vertices)
    /// into the sequence's directory, or --out. Vertices whose shell leaves the volume get 0 and
    /// are counted in a warning.
    Sample(Box<SampleArgs>),
    /// Draw PNG pictures of the slabs of a `solve` output directory (read from flow.pvd and its
    /// flow_SSSS.vtu files): grey_SSSS.png (the image on the surface), flow_SSSS.png (flow
    /// directions on the screen, Middlebury colour wheel, with its legend), arrows_SSSS.png and,
    /// when the output has a ground truth, angular_error_SSSS.png. One camera and one flow scale
    /// for all slabs; the view and up axis of the solve unless given. Drawn into DIR, the new
    /// pictures replace the earlier ones.
    Render {
        /// Output directory of `meshflow solve`
        dir: PathBuf,
        /// Where to write the pictures (default: DIR)
        #[arg(long)]
        out: Option<PathBuf>,
        #[command(flatten)]
        force: ForceArg,
        #[command(flatten)]
        pictures: PictureArgs,
    },
}

/// A usage error found after parsing, as a library error (one line, exit 1).
fn usage(message: String) -> meshflow::Error {
    meshflow::volume::VolumeError::Setting(message).into()
}

fn main() -> ExitCode {
    report_panics_in_one_line();
    // A panic is a bug, but still one line and exit 1: unwinding drops the outputs being
    // staged, so nothing half-written stays.
    std::panic::catch_unwind(run_command).unwrap_or(ExitCode::FAILURE)
}

/// Panics print the first one's message and place as one line, instead of the default
/// message and backtrace hint (rayon's threads may panic more than once for one fault).
fn report_panics_in_one_line() {
    static REPORTED: std::sync::Once = std::sync::Once::new();
    std::panic::set_hook(Box::new(|info| {
        REPORTED.call_once(|| {
            let message = (info.payload().downcast_ref::<&str>().copied())
                .or(info.payload().downcast_ref::<String>().map(String::as_str))
                .unwrap_or("no message");
            let place = info.location().map(|l| format!(" at {}:{}", l.file(), l.line()));
            let message = meshflow::format::quoted(message);
            stderr_line!(
                "meshflow: error: internal error {message}{}; please report it with the command line",
                place.unwrap_or_default()
            );
        });
    }));
}

/// The command line's command, run; its error as one line.
fn run_command() -> ExitCode {
    let cli = match Cli::try_parse().and_then(check_usage) {
        Ok(cli) => cli,
        Err(error) => return usage::usage_error(error),
    };
    progress::configure(cli.quiet);
    if let Some(bytes) = cli.memory_limit {
        meshflow::limits::set_memory_limit(bytes);
    }
    if cli.allow_external_files {
        meshflow::limits::set_linked_files(meshflow::limits::LinkedFiles::Anywhere);
    }
    remove_staging_on_signals();
    #[cfg(feature = "mpi")]
    if !matches!(cli.command, Command::Solve(_)) && ranks::launched_as_one_of_several() {
        stderr_line!("meshflow: error: only `meshflow solve` runs over several ranks; run the other commands in one process");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Operators {
            mesh,
            out,
            building,
            force,
        } => operators::write_operators(&mesh, &out, &building.options(), force.overwrite()),
        Command::Solve(args) => solve_command(&args),
        Command::Advect {
            run,
            out,
            seeds,
            force,
        } => advect::advect(&run, &out, seeds.as_deref(), force.overwrite()),
        Command::Analyze {
            run,
            out,
            format,
            png,
            tissue_scale,
            force,
            pictures,
        } => analyze::analyze(analyze::AnalyzeRequest {
            run: &run,
            out: &out,
            overwrite: force.overwrite(),
            formats: &format,
            pictures: png.then_some(&pictures),
            tissue_scale,
        }),
        Command::Track(args) => track::run(track::TrackRequest {
            input: &args.input,
            out: &args.out,
            reference: args.reference.as_deref(),
            options: args.options(),
            times: args.times.clone(),
            load: args.load_options(),
            overwrite: args.force.overwrite(),
        }),
        Command::Sample(args) => args.request().and_then(sample::run),
        Command::Surface(args) if matches!(args.shape, surface::ShapeArg::Closed) => {
            args.closed_request().and_then(surface::run_closed)
        }
        Command::Surface(args) => args.points_request().and_then(surface::run),
        Command::Match {
            points,
            out,
            max_distance,
        } => surface::write_tracks(&points, &out, max_distance),
        Command::Render {
            dir,
            out,
            force,
            pictures,
        } => pictures::render_output(&dir, out.as_deref(), force.overwrite(), &pictures),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            stderr_line!("meshflow: error: {error}");
            ExitCode::FAILURE
        }
    }
}

/// On SIGINT (Ctrl-C), SIGTERM or SIGHUP: remove the outputs being staged, say so in one line
/// and exit with 130, instead of leaving `.OUT.partial-PID` behind.
fn remove_staging_on_signals() {
    let installed = ctrlc::set_handler(|| {
        meshflow::run::remove_live_staging();
        stderr_line!("meshflow: interrupted: nothing was written");
        std::process::exit(130);
    });
    if let Err(error) = installed {
        stderr_line!("meshflow: warning: cannot handle interruptions ({error})");
    }
}

/// This command line, as recorded in an output's manifest (the program as `meshflow`).
pub fn command_line() -> Vec<String> {
    std::iter::once("meshflow".to_string())
        .chain(std::env::args().skip(1))
        .collect()
}

/// Usage rules that clap's attributes do not express.
fn check_usage(cli: Cli) -> Result<Cli, clap::Error> {
    use clap::CommandFactory;
    let (pictures, png) = match &cli.command {
        Command::Solve(args) => (Some(&*args.pictures), args.png),
        Command::Analyze { pictures, png, .. } => (Some(pictures), *png),
        _ => (None, true),
    };
    if let Command::Analyze { format, .. } = &cli.command {
        if format.contains(&OutputFormat::Glb) {
            return Err(Cli::command().error(
                clap::error::ErrorKind::InvalidValue,
                "--format of analyze takes npy and vtu (the analysis has no glTF output)",
            ));
        }
    }
    if let Some(pictures) = pictures {
        if pictures.chooses_slabs() && !png {
            return Err(Cli::command().error(
                clap::error::ErrorKind::MissingRequiredArgument,
                "--slabs chooses the pictures of --png; add --png",
            ));
        }
    }
    Ok(cli)
}

/// "1 slab", "3 slabs": a count and its noun (a regular one).
pub(crate) fn plural(n: usize, noun: &str) -> String {
    match n {
        1 => format!("1 {noun}"),
        n => format!("{n} {noun}s"),
    }
}

/// " (welded N duplicate vertices)" after a vertex count, or nothing.
fn welded_note(n_welded: usize) -> String {
    match n_welded {
        0 => String::new(),
        1 => " (welded 1 duplicate vertex)".into(),
        n => format!(" (welded {n} duplicate vertices)"),
    }
}

/// One `meshflow: warning: …` line per warning, on stderr.
fn print_warnings(warnings: &[meshflow::load::LoadWarning]) {
    for warning in warnings {
        stderr_line!("meshflow: warning: {warning}");
    }
}
