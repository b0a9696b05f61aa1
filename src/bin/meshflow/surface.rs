//! `meshflow surface`: point clouds per frame (cell centres, landmarks) → a moving surface with
//! fixed connectivity (an NPY sequence that `meshflow sample` and `meshflow solve` read), by a
//! smoothing-spline height over a fitted sphere or a plane (`meshflow::surface`).

use crate::args::ForceArg;
use crate::progress::during;
use meshflow::accuracy::{default_match_distance, Tracks};
use meshflow::format::{write_atomically, write_npy, write_npy_sequence, IoError};
use meshflow::run::{refuse_output_over_inputs, OutputKind, Overwrite, StagedDir};
use meshflow::surface::{fit_surface, read_points, FitOptions, FittedSurface, Reference};
use meshflow::Error;
use std::path::{Path, PathBuf};

/// What `surface` needs from the command line.
pub struct SurfaceRequest<'a> {
    pub points: &'a Path,
    pub out: &'a Path,
    pub options: FitOptions,
    pub times: Option<Vec<f64>>,
    pub overwrite: Overwrite,
}

pub fn run(request: SurfaceRequest) -> Result<(), Error> {
    if let Some(times) = &request.times {
        check_times(times)?;
    }
    let mut staged =
        StagedDir::create_apart_from(&[request.points], request.out, request.overwrite)?;
    staged.record_command(crate::command_line());
    let frames = during(format!("reading {}", request.points.display()), || {
        read_points(request.points)
    })?;
    let fitted = during(
        format!("fitting a surface through {} frames", frames.len()),
        || fit_surface(&frames, &request.options),
    )
    .map_err(|e| Error::from(e).in_file(request.points))?;
    let times = match request.times {
        Some(times) if times.len() != frames.len() => {
            return Err(crate::usage(format!(
                "--times gives {} times for the {} frames of {}",
                times.len(),
                frames.len(),
                request.points.display()
            )))
        }
        Some(times) => times,
        None => (0..frames.len()).map(|k| k as f64).collect(),
    };
    write_outputs(&staged, &fitted, &times).map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    print_report(&fitted, request.points, request.out);
    Ok(())
}

/// `--times`: finite and increasing (a frame's time orders the slabs and sets their
/// durations).
fn check_times(times: &[f64]) -> Result<(), Error> {
    if let Some(k) = times.iter().position(|t| !t.is_finite()) {
        return Err(crate::usage(format!(
            "--times: time {k} is {}; times must be finite numbers",
            times[k]
        )));
    }
    match times.windows(2).position(|pair| pair[1] <= pair[0]) {
        Some(k) => Err(crate::usage(format!(
            "--times: time {} ({}) does not come after time {k} ({}); times must increase",
            k + 1,
            times[k + 1],
            times[k]
        ))),
        None => Ok(()),
    }
}

/// positions.npy, faces.npy, times.txt and surface.json.
fn write_outputs(staged: &StagedDir, fitted: &FittedSurface, times: &[f64]) -> Result<(), Error> {
    let dir = staged.path();
    write_npy_sequence(dir, &fitted.positions, &fitted.faces, None, times)?;
    let report = serde_json::json!({
        "reference": fitted.reference,
        "vertices": fitted.positions[0].len(),
        "faces": fitted.faces.len(),
        "mean_edge_length": fitted.mean_edge_length(),
        "mean_point_spacing": fitted.mean_point_spacing,
        "lambda": fitted.lambda,
        "frames": fitted.frames,
    });
    let report = serde_json::to_string_pretty(&report).expect("a report serializes");
    write_atomically(&dir.join("surface.json"), |w| {
        use std::io::Write;
        writeln!(w, "{report}")
    })?;
    Ok(())
}

fn print_report(fitted: &FittedSurface, points: &Path, out: &Path) {
    let reference = match &fitted.reference {
        Reference::Sphere {
            centre,
            radius,
            cap_degrees,
            ..
        } => format!(
            "a height over the sphere of radius {radius:.4e} about ({:.4e}, {:.4e}, {:.4e}){}",
            centre[0],
            centre[1],
            centre[2],
            match cap_degrees {
                Some(angle) => format!(", cap of {angle:.1}°"),
                None => ", whole".to_string(),
            }
        ),
        Reference::Plane { .. } => "a height over the plane z = 0".to_string(),
    };
    println!(
        "{}: {} frames -> {reference}: {} vertices, {} faces, mean edge {:.3e} -> {}",
        points.display(),
        fitted.positions.len(),
        fitted.positions[0].len(),
        fitted.faces.len(),
        fitted.mean_edge_length(),
        out.display()
    );
    for (k, fit) in fitted.frames.iter().enumerate() {
        println!(
            "  frame {k:3}: {} points ({} outside the surface), height residual rms {:.3e}, max {:.3e}",
            fit.points, fit.dropped, fit.rms_residual, fit.max_residual
        );
    }
}

/// `meshflow match`: tracks from point clouds by mutual nearest neighbours. The output is
/// checked against the inputs and `--max-distance` before anything is read, the
/// `frames × tracks` array against the memory limit before it is allocated.
pub fn write_tracks(points: &Path, out: &Path, max_distance: Option<f64>) -> Result<(), Error> {
    refuse_output_over_inputs(out, OutputKind::File, &[points])?;
    if let Some(d) = max_distance.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(crate::usage(format!(
            "--max-distance must be a positive length, got {d}"
        )));
    }
    let frames = during(format!("reading {}", points.display()), || {
        read_points(points)
    })?;
    let in_points = |e: meshflow::accuracy::AccuracyError| Error::from(e).in_file(points);
    let bound = match max_distance {
        Some(d) => d,
        None => default_match_distance(&frames).map_err(in_points)?,
    };
    let check_size = |k: usize, tracks: usize| -> Result<(), Error> {
        // The positions and the array written from them: 2 × 3 float64 an entry.
        let what = format!("the tracks ({k} frames × {tracks} tracks)");
        meshflow::limits::check_items(what, (k as u64).saturating_mul(tracks as u64), 48)
            .map_err(|e| IoError::too_large(points, e).into())
    };
    let tracks = Tracks::matched(&frames, Some(bound), check_size).map_err(|e| match e {
        Error::Accuracy(e) => in_points(e),
        other => other,
    })?;
    let (shape, values) = tracks.to_array();
    write_npy(out, &shape, &values)?;
    let pairs = tracks.pairs_per_slab();
    println!(
        "{}: {} frames of {} points -> {} tracks, matched within {bound:.4e}: {} pairs per slab -> {}",
        points.display(),
        frames.len(),
        count_range(frames.iter().map(Vec::len)),
        tracks.n_tracks(),
        count_range(pairs.iter().copied()),
        out.display()
    );
    Ok(())
}

/// "5" or "3–7": the range of some counts.
fn count_range(counts: impl Iterator<Item = usize> + Clone) -> String {
    let (low, high) = (counts.clone().min().unwrap_or(0), counts.max().unwrap_or(0));
    match low == high {
        true => low.to_string(),
        false => format!("{low}–{high}"),
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub(crate) enum ShapeArg {
    /// A height over a sphere fitted to frame 0's points
    SphereLike,
    /// z = h(x, y) over the plane
    Graph,
}

#[derive(clap::Args)]
pub(crate) struct SurfaceArgs {
    /// Points per frame: a directory or quoted glob of (N, 3) .npy or .csv files (natural
    /// order), or one (frames, N, 3) .npy (NaN rows dropped)
    pub(crate) points: PathBuf,
    /// Output directory (an NPY sequence)
    #[arg(long)]
    pub(crate) out: PathBuf,
    #[command(flatten)]
    pub(crate) force: ForceArg,
    /// The reference the height is measured from
    #[arg(long, value_enum, default_value = "sphere-like")]
    pub(crate) shape: ShapeArg,
    /// With sphere-like: the whole sphere instead of the cap the points cover
    #[arg(long)]
    pub(crate) whole_sphere: bool,
    /// Mean edge length of the mesh, in the points' units
    #[arg(
        long,
        value_name = "LENGTH",
        conflicts_with = "vertices",
        allow_negative_numbers = true
    )]
    pub(crate) edge_length: Option<f64>,
    /// About this many vertices [default: 16000]
    #[arg(long, value_name = "N")]
    pub(crate) vertices: Option<usize>,
    /// Smoothing length in mean point spacings: height variations shorter than it are smoothed
    /// away (0: as close to the points as the mesh allows)
    #[arg(long, value_name = "SPACINGS", default_value_t = meshflow::surface::DEFAULT_SMOOTHING, allow_negative_numbers = true)]
    pub(crate) smoothing: f64,
    /// How far the mesh reaches beyond the outermost point, in mean point spacings
    #[arg(long, value_name = "SPACINGS", default_value_t = meshflow::surface::DEFAULT_MARGIN, allow_negative_numbers = true)]
    pub(crate) margin: f64,
    /// Frame times t0,t1,… [default: 0,1,2,…]
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub(crate) times: Option<Vec<f64>>,
}

impl SurfaceArgs {
    pub(crate) fn options(&self) -> meshflow::surface::FitOptions {
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
