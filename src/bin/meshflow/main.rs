//! The `meshflow` command line. Every failure is one line on stderr and a non-zero exit code.

mod advect;
mod analyze;
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

use clap::{Parser, Subcommand};
use meshflow::flow::{Boundary, FlowParams, SolverChoice, TimeCoupling};
use meshflow::io::{FrameFormat, LoadOptions, OutputFormat, Overwrite};
use pictures::PictureArgs;
use std::path::PathBuf;
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
    /// textures) also outside the naming file's directory: absolute paths and '..' (for
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
        #[command(flatten)]
        force: ForceArg,
        #[command(flatten)]
        pictures: PictureArgs,
    },
    /// Fit a moving surface through points per frame (cell centres, landmarks; physical
    /// units): a smoothing-spline height over a sphere fitted to frame 0's points (the cap they
    /// cover, or --whole-sphere) or over the plane z = 0 (--shape graph). Writes positions.npy,
    /// faces.npy and times.txt, which `meshflow sample` and `meshflow solve` read, and
    /// surface.json (the reference, the fit's residuals per frame).
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

#[derive(clap::Args)]
struct ForceArg {
    /// Write into the output directory even if it holds files that meshflow did not write
    /// (they stay; without --force such a directory is refused)
    #[arg(long)]
    force: bool,
}

impl ForceArg {
    fn overwrite(&self) -> Overwrite {
        match self.force {
            true => Overwrite::Force,
            false => Overwrite::EarlierRun,
        }
    }
}

#[derive(clap::Args)]
struct SolveArgs {
    /// Frames directory, glob (quoted), .gltf/.glb animation, or NPY directory
    input: PathBuf,
    /// Output directory (created if missing; an earlier meshflow output there is replaced as a
    /// whole)
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: ForceArg,
    /// Spatial smoothing scale in mean edge lengths, unit-free: sets γ = (SPREAD·h̄·S)² from
    /// the mean edge length h̄ and the image's gradient scale S [default: 0.5]
    #[arg(
        long,
        value_name = "EDGES",
        allow_negative_numbers = true,
        conflicts_with = "gamma"
    )]
    spread: Option<f64>,
    /// Temporal smoothing scale in frames, unit-free: sets α = √γ / (S·FRAMES·Δt̄); 0 for
    /// frame-by-frame flow [default: 1]
    #[arg(
        long,
        value_name = "FRAMES",
        allow_negative_numbers = true,
        conflicts_with = "alpha"
    )]
    time_scale: Option<f64>,
    /// Relative penalty on the speed, unit-free: sets β = B·S² [default: 0]
    #[arg(
        long,
        value_name = "B",
        allow_negative_numbers = true,
        conflicts_with = "beta"
    )]
    speed_penalty: Option<f64>,
    /// The paper's α as a number (a speed in the data's units; inf: frame-by-frame flow),
    /// instead of --time-scale
    #[arg(long, allow_negative_numbers = true)]
    alpha: Option<f64>,
    /// The paper's β as a number (weight of |u|², in the data's units), instead of
    /// --speed-penalty
    #[arg(long, allow_negative_numbers = true)]
    beta: Option<f64>,
    /// The paper's γ as a number (weight of |∇u|², in grey-value units squared), instead of
    /// --spread
    #[arg(long, allow_negative_numbers = true)]
    gamma: Option<f64>,
    /// What γ weighs: covariant (the paper's |∇u|²), strain (|Sym ∇u|², zero on rigid
    /// motions of the surface: a texture turning with it is not pulled towards rest) or
    /// embedded (|∇u|² of u as an R^3 field, Kirisits–Lang–Scherzer: adds |II(u,·)|²)
    #[arg(long, default_value = "covariant")]
    regularizer: meshflow::flow::Regularizer,
    /// With --regularizer strain: add D·|∇u|² (the covariant term, relative to γ) [default: 0]
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    dirichlet_mix: Option<f64>,
    /// Image-driven anisotropic smoothness (Nagel–Enkelmann): smooth the flow along image
    /// edges, less across them; LAMBDA (grey value per length, > 0) is the edge contrast at
    /// which smoothing across falls to 2/3 (large: the isotropic |∇u|²), auto 1.5 × each
    /// slab's contrast-weighted median contrast. Covariant and strain regularizers; the image
    /// is presmoothed over --anisotropic-sigma
    #[arg(long, value_name = "LAMBDA|auto", allow_negative_numbers = true)]
    anisotropic: Option<meshflow::flow::Scale>,
    /// With --anisotropic: the width (a length, ≥ 0; 0: none) over which the image is smoothed
    /// on the surface before its edges steer the smoothing [default: the mean edge length]
    #[arg(
        long,
        value_name = "SIGMA",
        allow_negative_numbers = true,
        requires = "anisotropic"
    )]
    anisotropic_sigma: Option<f64>,
    /// With --anisotropic: weigh the coupling in time by the space-time tensor's time entry,
    /// weaker where the image changes fast in time (measured: within 1 % of without on
    /// examples/motion_boundaries)
    #[arg(long, requires = "anisotropic")]
    anisotropic_in_time: bool,
    /// Robust (Charbonnier) smoothness for flows with discontinuities (cells moving on a
    /// still background): the smoothness grows like 2·EPS·|∇u| beyond |∇u| = EPS instead of
    /// quadratically (EPS in 1/time units, or auto: per slab twice the median |∇u| of a first
    /// quadratic solve; reweighted solves until the energy settles)
    #[arg(long, value_name = "EPS|auto", allow_negative_numbers = true)]
    robust_smoothness: Option<meshflow::flow::Scale>,
    /// With --robust-smoothness: isotropic (the penalty of |∇u|, one weight per face) or
    /// anisotropic (of each principal direction of ∇u: the flow may jump across a boundary
    /// and stay smooth along it; with --anisotropic, along the image's edges)
    #[arg(long, default_value = "isotropic", value_name = "KIND")]
    flow_driven: meshflow::flow::FlowDriven,
    /// neumann or dirichlet (u = 0 on the boundary)
    #[arg(long, default_value = "neumann")]
    boundary: Boundary,
    /// lumped or consistent discretization of the time term
    #[arg(long, default_value = "lumped")]
    time_coupling: TimeCoupling,
    /// auto, direct, pcg-slab-gauss-seidel, pcg-time-multigrid or pcg-jacobi
    #[arg(long, default_value = "auto")]
    solver: SolverChoice,
    /// Coarse-to-fine warping for large motions: image scales, coarsest first (1: the paper's
    /// single linear solve) [default: 1, or 4 with --large-motion]
    #[arg(long, value_name = "N")]
    levels: Option<usize>,
    /// Warps (re-linearizations, each one solve of the whole sequence) per level [default: 0,
    /// 1 with --levels above 1, 2 with --large-motion]
    #[arg(long, value_name = "M")]
    warps: Option<usize>,
    /// Motions larger than the image's features (a texture turning by several triangle widths
    /// per frame): coarse-to-fine symmetric warping with 4 levels and 2 warps each (8 solves)
    #[arg(long)]
    large_motion: bool,
    /// Relative residual at which the iterative solver stops
    #[arg(long, default_value_t = FlowParams::default().tolerance, allow_negative_numbers = true)]
    tolerance: f64,
    /// The image as a float32, float64, uint8 or uint16 .npy of shape (frames, file vertices), or (frames,
    /// file vertices, channels), instead of the files' colours
    #[arg(long)]
    intensity: Option<PathBuf>,
    /// Image channels: auto (every channel the input has: RGB for colours, one for grey
    /// colours and values), rgb, luma (Rec. 709) or grey (mean of the channels)
    #[arg(long, default_value = "auto")]
    channels: meshflow::io::Channels,
    /// Weight of each image channel in the data term, w1,w2,… (one per channel) [default: 1
    /// each]
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "W",
        allow_negative_numbers = true
    )]
    channel_weights: Option<Vec<f64>>,
    /// PLY vertex property holding the grey values (instead of the colours)
    #[arg(long)]
    intensity_attribute: Option<String>,
    /// Frame times t0,t1,… (default: from the files or times.txt, else 0,1,2,…)
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    times: Option<Vec<f64>>,
    /// Resample a glTF animation at N frames per unit of time (default: its keyframes)
    #[arg(long, value_name = "N")]
    fps: Option<f64>,
    /// The glTF animation (clip) to read, by name or index (default: the first that moves the
    /// mesh: its morph weights, skin joints or node transforms)
    #[arg(long, value_name = "NAME|INDEX")]
    animation: Option<String>,
    #[command(flatten)]
    building: MeshArgs,
    /// Known flow to measure the result against: .npy (slabs, vertices in the files, 3), float64
    /// or float32, R^3 vectors on frame s. Adds angular_error/endpoint_error to the .vtu files,
    /// angular_error.npy, endpoint_error.npy and "ground_truth" in summary.json
    #[arg(long, value_name = "FILE.npy")]
    ground_truth: Option<PathBuf>,
    /// Points whose motion is known (tracked cells, beads, landmarks): .npy (frames, points, 3)
    /// of positions, NaN where a point is not tracked (`meshflow match` makes one from point
    /// clouds). Scores the flow's tangential displacement at them against the zero flow's:
    /// "ground_truth_tracks" in summary.json
    #[arg(long, value_name = "TRACKS.npy")]
    ground_truth_tracks: Option<PathBuf>,
    /// Output files: any of npy, vtu, glb (summary.json is always written). Under mpirun,
    /// without glb (and --png, ground truth) the ranks stream their slabs to rank 0 and none
    /// holds more than its time window
    #[arg(long, value_delimiter = ',', default_value = "npy,vtu,glb")]
    format: Vec<OutputFormat>,
    /// Also draw the pictures of `meshflow render` (of every slab, or those of --slabs)
    #[arg(long)]
    png: bool,
    #[command(flatten)]
    pictures: PictureArgs,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ShapeArg {
    /// A height over a sphere fitted to frame 0's points
    SphereLike,
    /// z = h(x, y) over the plane
    Graph,
}

#[derive(clap::Args)]
struct SurfaceArgs {
    /// Points per frame: a directory or quoted glob of (N, 3) .npy or .csv files (natural
    /// order), or one (frames, N, 3) .npy (NaN rows dropped)
    points: PathBuf,
    /// Output directory (an NPY sequence)
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: ForceArg,
    /// The reference the height is measured from
    #[arg(long, value_enum, default_value = "sphere-like")]
    shape: ShapeArg,
    /// With sphere-like: the whole sphere instead of the cap the points cover
    #[arg(long)]
    whole_sphere: bool,
    /// Mean edge length of the mesh, in the points' units
    #[arg(
        long,
        value_name = "LENGTH",
        conflicts_with = "vertices",
        allow_negative_numbers = true
    )]
    edge_length: Option<f64>,
    /// About this many vertices [default: 16000]
    #[arg(long, value_name = "N")]
    vertices: Option<usize>,
    /// Smoothing length in mean point spacings: height variations shorter than it are smoothed
    /// away (0: as close to the points as the mesh allows)
    #[arg(long, value_name = "SPACINGS", default_value_t = meshflow::surface::DEFAULT_SMOOTHING, allow_negative_numbers = true)]
    smoothing: f64,
    /// How far the mesh reaches beyond the outermost point, in mean point spacings
    #[arg(long, value_name = "SPACINGS", default_value_t = meshflow::surface::DEFAULT_MARGIN, allow_negative_numbers = true)]
    margin: f64,
    /// Frame times t0,t1,… [default: 0,1,2,…]
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    times: Option<Vec<f64>>,
}

impl SurfaceArgs {
    fn options(&self) -> meshflow::surface::FitOptions {
        use meshflow::surface::{FitOptions, Resolution, Shape};
        FitOptions {
            shape: match self.shape {
                ShapeArg::SphereLike => Shape::SphereLike {
                    whole: self.whole_sphere,
                },
                ShapeArg::Graph => Shape::Graph,
            },
            resolution: match (self.edge_length, self.vertices) {
                (Some(length), _) => Resolution::EdgeLength(length),
                (None, Some(n)) => Resolution::Vertices(n),
                (None, None) => FitOptions::default().resolution,
            },
            smoothing: self.smoothing,
            margin: self.margin,
        }
    }
}

#[derive(clap::Args)]
struct SampleArgs {
    /// Volumes, one per frame: a .npy (Z, Y, X) or (K, Z, Y, X), a .tif/.tiff stack (pages =
    /// z), or a directory or quoted glob of them (natural order)
    volumes: PathBuf,
    /// The moving surface: any sequence `solve` reads (an image is not needed), e.g. the
    /// output of `meshflow surface` or `meshflow track`
    sequence: PathBuf,
    /// Output .npy [default: SEQUENCE/intensity.npy]
    #[arg(long, value_name = "FILE.npy")]
    out: Option<PathBuf>,
    /// Voxel size x,y,z in the surface's units [default: from ImageJ TIFF metadata, else
    /// 1,1,1]
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    voxel_size: Option<Vec<f64>>,
    /// Position of voxel (0, 0, 0), x,y,z
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    origin: Option<Vec<f64>>,
    /// How far the shell reaches inside and outside along the normal, in the surface's units
    /// [default: two of the largest voxel sides each way]
    #[arg(
        long,
        value_name = "INSIDE,OUTSIDE",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    shell: Option<Vec<f64>>,
    /// Samples across the --shell, evenly spaced; only with --shell (the default shell has 9)
    /// [default: 9]
    #[arg(long, value_name = "N", requires = "shell")]
    layers: Option<usize>,
    /// max (maximum-intensity projection), mean, or layer:L (sample L, 0 the innermost)
    #[arg(long, default_value = "max")]
    reduce: meshflow::volume::Reduce,
    /// Gaussian smoothing of each volume first, σ in the surface's units (0: none)
    /// [default: 2 of the smallest voxel sides]
    #[arg(long, value_name = "SIGMA", allow_negative_numbers = true)]
    smooth: Option<f64>,
    #[command(flatten)]
    building: MeshArgs,
}

impl SampleArgs {
    fn request(&self) -> Result<sample::SampleRequest<'_>, meshflow::Error> {
        let triple = |values: &Option<Vec<f64>>, name: &str| -> Result<_, meshflow::Error> {
            match values.as_deref() {
                None => Ok(None),
                Some(&[x, y, z]) => Ok(Some(nalgebra::Vector3::new(x, y, z))),
                Some(other) => Err(usage(format!(
                    "{name} takes three numbers x,y,z, got {}",
                    other.len()
                ))),
            }
        };
        let shell = match self.shell.as_deref() {
            None => None,
            Some(&[inside, outside]) => Some(meshflow::volume::Shell {
                inside,
                outside,
                layers: self
                    .layers
                    .unwrap_or(meshflow::volume::sample::DEFAULT_LAYERS),
            }),
            Some(other) => {
                return Err(usage(format!(
                    "--shell takes two distances INSIDE,OUTSIDE, got {} numbers",
                    other.len()
                )))
            }
        };
        Ok(sample::SampleRequest {
            volumes: &self.volumes,
            sequence: &self.sequence,
            out: self.out.as_deref(),
            volume: meshflow::volume::VolumeOptions {
                voxel_size: triple(&self.voxel_size, "--voxel-size")?,
                origin: triple(&self.origin, "--origin")?.unwrap_or_default(),
            },
            sampling: meshflow::volume::SampleOptions {
                smoothing: self.smooth,
                shell,
                reduce: self.reduce,
            },
            load: self.building.options(),
        })
    }
}

/// A usage error found after parsing, as a library error (one line, exit 1).
fn usage(message: String) -> meshflow::Error {
    meshflow::volume::VolumeError::Setting(message).into()
}

#[derive(clap::Args)]
struct TrackArgs {
    /// Frames directory, glob (quoted), .gltf/.glb animation, or NPY directory; frames may
    /// differ in vertices and triangles
    input: PathBuf,
    /// Output directory (an NPY sequence for `meshflow solve`)
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: ForceArg,
    /// The mesh to move (on or near frame 0's surface; default: frame 0's own mesh)
    #[arg(long, value_name = "MESH")]
    reference: Option<PathBuf>,
    /// Largest normal step per frame, in the data's length unit; a vertex farther from the next
    /// surface is an error [default: 10 % of frame 0's bounding-box diagonal]
    #[arg(long, value_name = "LENGTH", allow_negative_numbers = true)]
    max_step: Option<f64>,
    /// Go on past vertices beyond --max-step (they take the closest point) and flipped
    /// triangles, counting them in the report, instead of stopping with an error
    #[arg(long)]
    keep_going: bool,
    /// Frame times t0,t1,… (default: times.txt beside the frames or the glTF animation's,
    /// else 0,1,2,…)
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    times: Option<Vec<f64>>,
    /// Track a reference of about N vertices made from frame 0 (or from --reference) by
    /// simplification: faster, and it folds less than a fine segmentation mesh
    #[arg(long, value_name = "N")]
    reference_vertices: Option<usize>,
    /// After each normal step, relax the mesh on the new surface as rigidly as possible
    /// against the previous frame (arap), or move vertices along their normals only (none,
    /// the paper's normal motion)
    #[arg(long, value_name = "KIND", default_value = "arap")]
    relax: RelaxKind,
    /// Relaxation steps per frame (with --relax arap)
    #[arg(long, value_name = "N", default_value_t = meshflow::track::Relaxation::DEFAULT_ITERATIONS)]
    relax_iterations: usize,
    /// Take out the motion of the whole sample between frames before tracking: rigid,
    /// similarity (also uniform scale) or none; the transforms are in track.json
    #[arg(long, value_name = "KIND", default_value = "none")]
    align: meshflow::track::Alignment,
    /// Keep reference vertices beyond a frame's boundary (they take the closest point on it)
    /// instead of trimming the reference to the part every frame covers
    #[arg(long)]
    keep_uncovered: bool,
    /// The image as a float .npy of shape (frames, vertices) or (frames, vertices, channels)
    /// when every frame has as many vertices, or a directory of one .npy per frame, (vertices,)
    /// or (vertices, channels), in natural order; instead of the files' colours
    #[arg(long, value_name = "FILE.npy|DIR")]
    intensity: Option<PathBuf>,
    /// PLY vertex property holding the grey values (instead of the colours)
    #[arg(long)]
    intensity_attribute: Option<String>,
    /// Image channels: auto (every channel the input has), rgb, luma (Rec. 709) or grey (mean)
    #[arg(long, default_value = "auto")]
    channels: meshflow::io::Channels,
    #[command(flatten)]
    building: MeshArgs,
}

/// `--relax`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum RelaxKind {
    Arap,
    None,
}

impl TrackArgs {
    fn options(&self) -> meshflow::track::TrackOptions {
        use meshflow::track::Relaxation;
        meshflow::track::TrackOptions {
            max_step: self.max_step,
            keep_going: self.keep_going,
            reference: None,
            reference_vertices: self.reference_vertices,
            relaxation: match self.relax {
                RelaxKind::Arap => Relaxation::Arap {
                    iterations: self.relax_iterations,
                },
                RelaxKind::None => Relaxation::None,
            },
            alignment: self.align,
            keep_uncovered: self.keep_uncovered,
        }
    }

    fn load_options(&self) -> LoadOptions {
        LoadOptions {
            intensity: self.intensity.clone(),
            intensity_attribute: self.intensity_attribute.clone(),
            channels: self.channels,
            ..self.building.options()
        }
    }
}

impl SolveArgs {
    /// How `solve` reads its input (`advect` reads it again the same way).
    fn load_options(&self) -> LoadOptions {
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

    /// The files and directories the solve reads: its input, `--intensity`, `--ground-truth`
    /// and `--ground-truth-tracks`.
    fn input_files(&self) -> Vec<&std::path::Path> {
        std::iter::once(self.input.as_path())
            .chain(self.intensity.as_deref())
            .chain(self.ground_truth.as_deref())
            .chain(self.ground_truth_tracks.as_deref())
            .collect()
    }

    /// `--regularizer` with `--dirichlet-mix`.
    fn regularizer(&self) -> Result<meshflow::flow::Regularizer, meshflow::flow::FlowError> {
        meshflow::flow::Regularizer::with_mix(self.regularizer, self.dirichlet_mix)
    }

    /// `--levels`, `--warps` and `--large-motion` as one setting.
    fn warping(&self) -> meshflow::flow::Warping {
        meshflow::flow::Warping::from_options(self.levels, self.warps, self.large_motion)
    }
}

/// How the mesh is built from the files' faces (`solve` and `operators`).
#[derive(clap::Args)]
struct MeshArgs {
    /// Keep coincident vertices apart (default: weld seam copies, which exporters split at
    /// texture seams: coincident vertices joined by coincident edges, never where the surface
    /// only touches itself)
    #[arg(long)]
    no_weld: bool,
    /// Welding distance relative to the bounding-box diagonal of frame 0 (0: bitwise equal
    /// positions)
    #[arg(long, value_name = "REL", default_value_t = LoadOptions::DEFAULT_WELD_TOLERANCE, allow_negative_numbers = true)]
    weld_tolerance: f64,
    /// Split non-manifold edges and vertices into manifold pieces, cut non-orientable surfaces
    /// open, drop faces with a repeated vertex and duplicate faces (default: refuse them)
    #[arg(long)]
    repair: bool,
}

impl MeshArgs {
    fn options(&self) -> LoadOptions {
        LoadOptions {
            weld: !self.no_weld,
            weld_tolerance: self.weld_tolerance,
            repair: self.repair,
            ..LoadOptions::default()
        }
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse().and_then(check_usage) {
        Ok(cli) => cli,
        Err(error) => return usage_error(error),
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
        eprintln!("meshflow: error: only `meshflow solve` runs over several ranks; run the other commands in one process");
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
            force,
            pictures,
        } => analyze::analyze(analyze::AnalyzeRequest {
            run: &run,
            out: &out,
            overwrite: force.overwrite(),
            formats: &format,
            pictures: png.then_some(&pictures),
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
        Command::Surface(args) => surface::run(surface::SurfaceRequest {
            points: &args.points,
            out: &args.out,
            options: args.options(),
            times: args.times.clone(),
            overwrite: args.force.overwrite(),
        }),
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
            eprintln!("meshflow: error: {error}");
            ExitCode::FAILURE
        }
    }
}

/// `meshflow solve`: in one process, or over the ranks `mpirun` started (the `mpi` feature).
fn solve_command(args: &SolveArgs) -> Result<(), meshflow::Error> {
    #[cfg(feature = "mpi")]
    return ranks::solve(args);
    #[cfg(not(feature = "mpi"))]
    solve::solve(args, None)
}

/// On SIGINT (Ctrl-C), SIGTERM or SIGHUP: remove the outputs being staged, say so in one line
/// and exit with 130, instead of leaving `.OUT.partial-PID` behind.
fn remove_staging_on_signals() {
    let installed = ctrlc::set_handler(|| {
        meshflow::io::remove_live_staging();
        eprintln!("meshflow: interrupted: nothing was written");
        std::process::exit(130);
    });
    if let Err(error) = installed {
        eprintln!("meshflow: warning: cannot handle interruptions ({error})");
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
        Command::Solve(args) => (Some(&args.pictures), args.png),
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

/// " (welded N duplicate vertices)" after a vertex count, or nothing.
fn welded_note(n_welded: usize) -> String {
    match n_welded {
        0 => String::new(),
        1 => " (welded 1 duplicate vertex)".into(),
        n => format!(" (welded {n} duplicate vertices)"),
    }
}

/// One `meshflow: warning: …` line per warning, on stderr.
fn print_warnings(warnings: &[meshflow::io::LoadWarning]) {
    for warning in warnings {
        eprintln!("meshflow: warning: {warning}");
    }
}

/// `--help` and `--version` print as usual; a usage error becomes one line, exit code 2.
fn usage_error(error: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        error.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        error.exit();
    }
    let text = error.render().to_string();
    let message: Vec<&str> = text
        .lines()
        .take_while(|line| !line.starts_with("Usage:"))
        .map(str::trim)
        .filter(|line| !line.is_empty() && !line.starts_with("For more information"))
        .collect();
    let hint = glob_hint(&error).unwrap_or_default();
    eprintln!(
        "meshflow: {}{hint} (see meshflow --help)",
        message.join(" ")
    );
    ExitCode::from(2)
}

/// When an unexpected argument is a mesh file, the shell has most likely expanded an unquoted
/// glob into many arguments: a hint to quote it, or to give the directory.
fn glob_hint(error: &clap::Error) -> Option<String> {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if error.kind() != ErrorKind::UnknownArgument {
        return None;
    }
    let Some(ContextValue::String(argument)) = error.get(ContextKind::InvalidArg) else {
        return None;
    };
    let path = std::path::Path::new(argument);
    FrameFormat::of(path)?;
    let extension = path.extension()?.to_string_lossy();
    let directory = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.display().to_string(),
        _ => ".".to_string(),
    };
    Some(format!(
        "; it looks like the shell expanded a glob into many files: quote it \
         ('{directory}/*.{extension}') or give the directory ({directory})"
    ))
}
