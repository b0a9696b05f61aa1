//! `meshflow surface`: point clouds per frame (cell centres, landmarks), or the bright voxels of
//! volumes, → a moving surface with fixed connectivity (an NPY sequence that `meshflow sample`
//! and `meshflow solve` read), by a smoothing-spline height over a fitted sphere or a plane
//! (`meshflow::surface`); or, with `--shape closed`, the object found in the volumes, tracked.

use crate::args::{ForceArg, VolumePlacement};
use crate::progress::during;
use meshflow::accuracy::{default_match_distance, Tracks};
use meshflow::format::format_number;
use meshflow::format::{write_atomically, write_npy, write_npy_sequence, IoError};
use meshflow::run::{refuse_output_over_inputs, OutputKind, Overwrite, StagedDir};
use meshflow::surface::voxels::voxel_spacing;
use meshflow::surface::{
    find_surface_consuming, foreground_points, FoundSurface, IsosurfaceOptions, Level,
};
use meshflow::surface::{fit_surface, fit_surface_weighted, read_points, FitOptions};
use meshflow::surface::{FittedSurface, ForegroundPoints, Reference};
use meshflow::track::{track_as_they_come, TrackEvent, TrackFrame, TrackOptions, Tracked};
use meshflow::volume::{VolumeOptions, VolumeStream};
use meshflow::Error;
use std::path::{Path, PathBuf};

/// What `surface` needs from the command line.
pub struct SurfaceRequest<'a> {
    pub points: &'a Path,
    pub out: &'a Path,
    pub options: FitOptions,
    pub times: Option<Vec<f64>>,
    pub overwrite: Overwrite,
    /// `Some`: the input is volumes, whose bright voxels are the points
    /// ([`meshflow::surface::foreground_points`]).
    pub volumes: Option<(VolumeOptions, IsosurfaceOptions)>,
}

/// The points of each frame, and with volumes their weights, reports and the smoothing's unit.
struct FitInput {
    frames: Vec<Vec<nalgebra::Vector3<f64>>>,
    voxels: Option<(Vec<Vec<f64>>, Vec<ForegroundPoints>, f64)>,
}

impl FitInput {
    fn read(request: &SurfaceRequest) -> Result<Self, Error> {
        let Some((placement, finding)) = &request.volumes else {
            let frames = during(format!("reading {}", request.points.display()), || {
                read_points(request.points)
            })?;
            return Ok(Self {
                frames,
                voxels: None,
            });
        };
        let stream = VolumeStream::open(request.points, placement)?;
        let bar =
            crate::progress::count_progress(stream.n_frames() as u64, "finding the bright voxels");
        let (mut frames, mut weights, mut reports, mut length) = (vec![], vec![], vec![], 0.0);
        for read in stream {
            let (volume, _) = read?;
            length = voxel_spacing(&volume);
            let frame = frames.len();
            let mut found = foreground_points(&volume, finding).map_err(|e| {
                Error::from(e).in_file(format!("{} (frame {frame})", request.points.display()))
            })?;
            frames.push(std::mem::take(&mut found.points));
            weights.push(std::mem::take(&mut found.weights));
            reports.push(found);
            bar.inc(1);
        }
        bar.finish();
        Ok(Self {
            frames,
            voxels: Some((weights, reports, length)),
        })
    }

    fn fit(&self, options: &FitOptions) -> Result<FittedSurface, meshflow::surface::SurfaceError> {
        match &self.voxels {
            None => fit_surface(&self.frames, options),
            Some((weights, _, length)) => {
                fit_surface_weighted(&self.frames, weights, *length, options)
            }
        }
    }
}

/// What `surface --shape closed` needs from the command line.
pub struct ClosedRequest<'a> {
    pub volumes: &'a Path,
    pub out: &'a Path,
    pub placement: VolumeOptions,
    pub finding: IsosurfaceOptions,
    /// About this many vertices in the tracked mesh; `None`: [`DEFAULT_VERTICES`], or fewer
    /// where edges would be shorter than the smoothing's σ.
    pub vertices: Option<usize>,
    /// How the tracked mesh follows the frames' surfaces (`reference_vertices` and
    /// `keep_uncovered` are set from `vertices` and the surface being closed).
    pub tracking: TrackOptions,
    pub times: Option<Vec<f64>>,
    pub overwrite: Overwrite,
}

/// The tracked mesh's size when `--vertices` is not given (as for surfaces through points).
const DEFAULT_VERTICES: usize = 16000;

/// `meshflow surface VOLUMES --shape closed`: each frame's surface found in its volume
/// ([`find_surface`]), then one reference of about `vertices` vertices tracked through them
/// (`meshflow track`'s machinery), written as an NPY sequence with `surface.json`.
pub fn run_closed(request: ClosedRequest) -> Result<(), Error> {
    let staged = staged_output(
        request.volumes,
        request.out,
        request.overwrite,
        &request.times,
    )?;
    // Frames are read one at a time and dropped once their surface is found.
    let mut stream = VolumeStream::open(request.volumes, &request.placement)?;
    let n_frames = stream.n_frames();
    if n_frames < 2 {
        return Err(crate::usage(format!(
            "{} holds {n_frames} frame: a moving surface needs 2 frames at least (one frame's surface: meshflow.find_surface in Python)",
            request.volumes.display()
        )));
    }
    // From the files' headers: a wrong --times fails before any reading.
    if let Some(times) = request.times.as_ref().filter(|t| t.len() != n_frames) {
        return Err(crate::usage(format!(
            "--times gives {} times for the {n_frames} frames of {}",
            times.len(),
            request.volumes.display()
        )));
    }
    // Each frame's surface is tracked as soon as it is found, then dropped: memory holds one
    // volume and two frames' surfaces whatever the recording's length.
    let bar = crate::progress::count_progress(n_frames as u64, "finding and tracking surfaces");
    let mut found: Vec<FoundSurface> = Vec::with_capacity(n_frames);
    let mut next = |found: &mut Vec<FoundSurface>| -> Result<Option<TrackFrame>, Error> {
        let Some(read) = stream.next() else {
            return Ok(None);
        };
        let (volume, file) = read?;
        let k = found.len();
        if let Some((missing, chunks)) = stream.missing_chunks() {
            let volumes = request.volumes;
            bar.suspend(|| crate::sample::report_missing_chunks(volumes, k, missing, chunks));
        }
        if k == 0 {
            let source = stream.voxel_size_source().expect("known after a frame");
            bar.suspend(|| crate::sample::report_voxel_size(request.volumes, source));
        }
        // The closing starts where earlier frames needed it: the same object, closed alike,
        // keeps its shape from frame to frame.
        // So does the smoothing, where frame 0's foreground was porous.
        let widest = found.iter().map(|f| f.closing_radius).fold(0.0, f64::max);
        let smoothest = found.iter().map(|f| f.smoothing).fold(0.0, f64::max);
        let finding = IsosurfaceOptions {
            closing: request.finding.closing.or((widest > 0.0).then_some(widest)),
            smoothing: (request.finding.smoothing).or((k > 0).then_some(smoothest)),
            ..request.finding
        };
        let mut surface = find_surface_consuming(volume, &finding)
            .map_err(|e| Error::from(e).in_file(format!("{} (frame {k})", file.display())))?;
        bar.suspend(|| {
            stdout_line!("  frame {k:3}: {}", describe_found(&surface));
            for warning in surface.warnings() {
                stderr_line!("meshflow: warning: frame {k}: {warning}");
            }
        });
        // The mesh moves to the tracker; `found` keeps the report (`vertices`, `faces`).
        let frame = TrackFrame {
            intensity: vec![0.0; surface.positions.len()],
            positions: std::mem::take(&mut surface.positions),
            faces: std::mem::take(&mut surface.faces),
        };
        found.push(surface);
        Ok(Some(frame))
    };
    let first = next(&mut found)?.expect("a recording has a frame");
    // Surface nets' triangles are slivers where the surface cuts a voxel's corner: the
    // reference is always a simplified, cleaned mesh, at most half of frame 0's vertices.
    // By default, no finer than the smoothing: the frames' surfaces are not known below σ,
    // and a finer mesh tracks their noise (and folds there).
    let coarsest = triangle_mesh_vertices(
        meshflow::geometry::surface_area(&first.faces, &first.positions),
        found[0].smoothing,
    );
    let asked = request.vertices.unwrap_or(DEFAULT_VERTICES.min(coarsest));
    let vertices = asked.min(found[0].vertices / 2);
    if vertices < asked {
        bar.suspend(|| {
            stdout_line!(
                "frame 0's surface has {} vertices: the tracked mesh gets {vertices} (half; \
                 {asked} were asked)",
                found[0].vertices,
            )
        });
    }
    // A closed surface has no boundary to trim at: a vertex whose normal misses the next
    // frame's surface takes its closest point.
    let options = TrackOptions {
        reference_vertices: Some(vertices),
        keep_uncovered: true,
        keep_coordinates: true,
        ..request.tracking
    };
    let mut failure: Option<Error> = None;
    let tracked = {
        let mut rest = std::iter::from_fn(|| match next(&mut found) {
            Ok(frame) => frame,
            Err(e) => {
                failure = Some(e);
                None
            }
        });
        let mut on_event = |event: TrackEvent| crate::track::show_event(&bar, event);
        track_as_they_come(first, &mut rest, request.times, &options, &mut on_event)
    };
    bar.finish();
    if let Some(error) = failure {
        return Err(error);
    }
    let tracked = tracked?;
    let faults = check_frames(
        &tracked,
        &found,
        request.finding.genus,
        request.tracking.keep_going,
    )?;
    write_closed(&staged, &tracked, &found, &faults).map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    crate::track::print_summary(&tracked, request.out);
    Ok(())
}

/// Edges whose triangles face opposite ways, a frame of the tracked mesh at a time: where the
/// mesh folded over itself ([`meshflow::geometry::folds::folded_edges`]).
#[derive(serde::Serialize)]
struct FoldedFrame {
    frame: usize,
    folded_edges: usize,
}

/// The share of the tracked mesh's edges that may be folded in a frame before it is an error
/// (without `--keep-going`): a lone crease is a warning, a tangle is not written.
const FOLDS_TOLERATED: f64 = 1e-3;

/// The tracked mesh checked before anything is written: one closed, connected manifold (its
/// connectivity was built as one) of the genus found in frame 0, and no frame folded over
/// itself. Folds at more than [`FOLDS_TOLERATED`] of the edges are an error naming the frame;
/// fewer (or with `--keep-going`, any) are warnings, listed in `surface.json`.
fn check_frames(
    tracked: &Tracked,
    found: &[FoundSurface],
    genus: usize,
    keep_going: bool,
) -> Result<Vec<FoldedFrame>, Error> {
    let sequence = &tracked.sequence;
    let mesh = sequence.mesh();
    let components = mesh.connected_components().len();
    let tracked_genus = (2 - mesh.euler_characteristic()) / 2;
    let wanted = found.first().map_or(genus, |f| f.genus);
    if !mesh.is_closed() || components != 1 || tracked_genus != wanted as i64 {
        return Err(crate::usage(format!(
            "frame 0: the tracked mesh is {} with {components} component(s) and genus \
             {tracked_genus}, where frame 0's surface is closed, connected and of genus \
             {wanted}; try other --vertices",
            if mesh.is_closed() { "closed" } else { "open" }
        )));
    }
    let mut faults = vec![];
    let tolerated = (FOLDS_TOLERATED * mesh.n_edges() as f64).floor() as usize;
    for k in 0..sequence.n_frames() {
        let positions = sequence.positions(k).expect("tracked in R^3");
        let folded = meshflow::geometry::folds::folded_halfedges(mesh, positions).len();
        if folded == 0 {
            continue;
        }
        if folded > tolerated && !keep_going {
            return Err(crate::usage(format!(
                "frame {k}: the tracked mesh folds over itself at {folded} of its {} edges \
                 (their triangles face opposite ways); try fewer --vertices, or --keep-going \
                 to write it anyway",
                mesh.n_edges()
            )));
        }
        faults.push(FoldedFrame {
            frame: k,
            folded_edges: folded,
        });
    }
    Ok(faults)
}

/// About how many vertices a mesh of equilateral triangles of side `edge` has over `area`:
/// two triangles of `√3/4 edge²` per vertex.
fn triangle_mesh_vertices(area: f64, edge: f64) -> usize {
    (area / (3f64.sqrt() / 2.0 * edge * edge)).round().max(4.0) as usize
}

/// One frame's line: what `surface.json` records of it.
fn describe_found(s: &FoundSurface) -> String {
    format!(
        "threshold {:.4e}; the largest component holds {:.1} % of the {} voxels above it \
         ({} filled in) after smoothing by {:.3e}; {}; {} vertices, {} faces, genus {}; {}",
        s.threshold,
        100.0 * s.component_share,
        s.foreground_voxels,
        s.filled_voxels,
        s.smoothing,
        match (s.closing_radius, s.slices_filled) {
            (0.0, false) => "no closing".to_string(),
            (0.0, true) => format!(
                "the slices' holes filled ({} closings tried)",
                s.closings_tried.len()
            ),
            (r, slices) => format!(
                "gaps closed at radius {r:.3e}{} ({} tried)",
                if slices {
                    " and the slices' holes filled"
                } else {
                    ""
                },
                s.closings_tried.len()
            ),
        },
        s.vertices,
        s.faces_count,
        s.genus,
        match s.layer_vertices {
            0 => "solid: the surface is its boundary".to_string(),
            n => format!(
                "{n} vertices moved to the middle of a bright layer {:.3e} thick",
                s.layer_thickness
            ),
        }
    )
}

/// positions.npy, faces.npy, times.txt and surface.json (the frames' surfaces and the
/// tracking).
fn write_closed(
    staged: &StagedDir,
    tracked: &Tracked,
    found: &[FoundSurface],
    folds: &[FoldedFrame],
) -> Result<(), Error> {
    let dir = staged.path();
    let sequence = &tracked.sequence;
    let positions: Vec<_> = (0..sequence.n_frames())
        .map(|k| sequence.positions(k).expect("tracked in R^3").to_vec())
        .collect();
    let faces = sequence.mesh().faces();
    write_npy_sequence(dir, &positions, faces, None, sequence.times())?;
    let warnings: Vec<String> = (found.iter().enumerate())
        .flat_map(|(k, s)| {
            s.warnings()
                .into_iter()
                .map(move |w| format!("frame {k}: {w}"))
        })
        .chain(folds.iter().map(|f| {
            format!(
                "frame {}: the tracked mesh folds over itself at {} edge(s)",
                f.frame, f.folded_edges
            )
        }))
        .collect();
    let mesh = sequence.mesh();
    let report = serde_json::json!({
        "shape": "closed",
        "vertices": mesh.n_vertices(),
        "faces": faces.len(),
        "genus": (2 - mesh.euler_characteristic()) / 2,
        "folds": folds,
        "frames": found,
        "tracking": tracked.report,
        "warnings": warnings,
    });
    let report = serde_json::to_string_pretty(&report).expect("a report serializes");
    write_atomically(&dir.join("surface.json"), |w| {
        use std::io::Write;
        writeln!(w, "{report}")
    })?;
    Ok(())
}

pub fn run(request: SurfaceRequest) -> Result<(), Error> {
    let staged = staged_output(
        request.points,
        request.out,
        request.overwrite,
        &request.times,
    )?;
    let input = FitInput::read(&request)?;
    let frames = &input.frames;
    let fitted = during(
        format!(
            "fitting a surface through {}",
            crate::plural(frames.len(), "frame")
        ),
        || input.fit(&request.options),
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
    let voxels = input
        .voxels
        .as_ref()
        .map(|(_, reports, length)| (&reports[..], *length));
    write_outputs(&staged, &fitted, &times, voxels).map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    print_report(&fitted, request.points, request.out, voxels);
    Ok(())
}

/// The output directory, refused before anything is read when it would replace `input` or
/// `--times` is not a time series.
fn staged_output(
    input: &Path,
    out: &Path,
    overwrite: Overwrite,
    times: &Option<Vec<f64>>,
) -> Result<StagedDir, Error> {
    if let Some(times) = times {
        check_times(times)?;
    }
    let mut staged = StagedDir::create_apart_from(&[input], out, overwrite)?;
    staged.record_command(crate::command_line());
    Ok(staged)
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

/// From volumes: each frame's bright voxels, and the smoothing's unit length.
type VoxelReport<'a> = Option<(&'a [ForegroundPoints], f64)>;

/// positions.npy, faces.npy, times.txt and surface.json.
fn write_outputs(
    staged: &StagedDir,
    fitted: &FittedSurface,
    times: &[f64],
    voxels: VoxelReport,
) -> Result<(), Error> {
    let dir = staged.path();
    write_npy_sequence(dir, &fitted.positions, &fitted.faces, None, times)?;
    let mut report = serde_json::json!({
        "reference": fitted.reference,
        "vertices": fitted.positions[0].len(),
        "faces": fitted.faces.len(),
        "mean_edge_length": fitted.mean_edge_length(),
        "mean_point_spacing": fitted.mean_point_spacing,
        "lambda": fitted.lambda,
        "frames": fitted.frames,
    });
    if let Some((found, length)) = voxels {
        report["volumes"] = serde_json::json!({ "smoothing_unit": length, "frames": found });
    }
    let report = serde_json::to_string_pretty(&report).expect("a report serializes");
    write_atomically(&dir.join("surface.json"), |w| {
        use std::io::Write;
        writeln!(w, "{report}")
    })?;
    Ok(())
}

fn print_report(fitted: &FittedSurface, points: &Path, out: &Path, voxels: VoxelReport) {
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
    stdout_line!(
        "{}: {} -> {reference}: {} vertices, {} faces, mean edge {:.3e} -> {}",
        points.display(),
        crate::plural(fitted.positions.len(), "frame"),
        fitted.positions[0].len(),
        fitted.faces.len(),
        fitted.mean_edge_length(),
        out.display()
    );
    for (k, fit) in fitted.frames.iter().enumerate() {
        let found = match voxels {
            Some((found, _)) => format!(
                "threshold {}: {} bright voxels ({:.1} %), every {} a point: ",
                format_number(found[k].threshold),
                found[k].foreground_voxels,
                100.0 * found[k].foreground_share,
                found[k].stride
            ),
            None => String::new(),
        };
        stdout_line!(
            "  frame {k:3}: {found}{} points ({} outside the surface), height residual rms {:.3e}, max {:.3e}",
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
    stdout_line!(
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
    /// The boundary of the object in 3-D images (the input is volumes): an embryo, a gut, an
    /// organoid
    Closed,
}

#[derive(clap::Args)]
pub(crate) struct SurfaceArgs {
    /// Points per frame: a directory or quoted glob of (N, 3) .npy or .csv files (natural
    /// order), or one (frames, N, 3) .npy (NaN rows dropped). Or volumes: a (Z, Y, X) or
    /// (K, Z, Y, X) .npy, TIFF stacks or ImageJ hyperstacks, an OME-Zarr image, or a directory
    /// or quoted glob of .npy/.tif files; with --shape closed, or with TIFF or OME-Zarr input or
    /// a volume flag (--voxel-size, --origin, --level, --smooth, --channel,
    /// --resolution-level) the spline is fitted through their bright voxels
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
    /// About this many vertices (with --shape closed, at most half of frame 0's surface)
    /// [default: 16000]
    #[arg(long, value_name = "N", alias = "reference-vertices")]
    pub(crate) vertices: Option<usize>,
    /// Smoothing length in mean point spacings (through volumes' bright voxels: in 8 of the
    /// largest voxel sides): height variations shorter than it are smoothed away (0: as close
    /// to the points as the mesh allows)
    #[arg(long, value_name = "SPACINGS", default_value_t = meshflow::surface::DEFAULT_SMOOTHING, allow_negative_numbers = true)]
    pub(crate) smoothing: f64,
    /// How far the mesh reaches beyond the outermost point, in mean point spacings
    #[arg(long, value_name = "SPACINGS", default_value_t = meshflow::surface::DEFAULT_MARGIN, allow_negative_numbers = true)]
    pub(crate) margin: f64,
    /// Frame times t0,t1,… [default: 0,1,2,…]
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub(crate) times: Option<Vec<f64>>,
    /// Volumes: the threshold of the smoothed image, a value or auto (Otsu's); a probability
    /// map works at 0.5
    #[arg(long, value_name = "auto|VALUE", allow_negative_numbers = true)]
    pub(crate) level: Option<meshflow::surface::Level>,
    /// Volumes: Gaussian smoothing of each volume first, σ in physical units [default: the
    /// largest voxel side]
    #[arg(long, value_name = "SIGMA", allow_negative_numbers = true)]
    pub(crate) smooth: Option<f64>,
    /// With --shape closed: the number of handles the object has (0, the default: a sphere's
    /// topology, as an embryo or organoid); gaps in its bright layer are closed until the
    /// surface has at most this many
    #[arg(long, value_name = "N")]
    pub(crate) genus: Option<usize>,
    /// With --shape closed: the radius of the ball that first closes the gaps of the object's
    /// bright layer (dim cells, the dark gaps between nuclei), physical units; concavities
    /// narrower than it are closed too [default: none where the layer has no gaps, else a
    /// quarter of the object's smallest extent for genus 0, growing until the surface has
    /// --genus handles and the object is filled]
    #[arg(long, value_name = "RADIUS")]
    pub(crate) closing: Option<f64>,
    /// With --shape closed: how the reference follows the frames' surfaces
    #[command(flatten)]
    pub(crate) tracking: crate::track::TrackingArgs,
    #[command(flatten)]
    pub(crate) placement: VolumePlacement,
}

impl SurfaceArgs {
    /// `--shape closed`: what finding the surface in volumes needs.
    pub(crate) fn closed_request(&self) -> Result<ClosedRequest<'_>, Error> {
        let defaults = FitOptions::default();
        let stray = [
            (self.whole_sphere, "--whole-sphere"),
            (self.edge_length.is_some(), "--edge-length"),
            (self.smoothing != defaults.smoothing, "--smoothing"),
            (self.margin != defaults.margin, "--margin"),
        ];
        if let Some((_, flag)) = stray.iter().find(|(given, _)| *given) {
            let why = format!("{flag} applies to surfaces through points, not --shape closed");
            return Err(crate::usage(why));
        }
        Ok(ClosedRequest {
            volumes: &self.points,
            out: &self.out,
            placement: self.placement.options()?,
            finding: IsosurfaceOptions {
                smoothing: self.smooth,
                level: self.level.unwrap_or(Level::Otsu),
                genus: self.genus.unwrap_or(0),
                closing: self.closing,
            },
            vertices: self.vertices,
            tracking: self.tracking.options(meshflow::track::Alignment::Rigid),
            times: self.times.clone(),
            overwrite: self.force.overwrite(),
        })
    }

    /// `--shape sphere-like|graph`: what fitting a surface through points, or through the
    /// bright voxels of volumes, needs. The input is volumes when it is TIFF or a volume flag
    /// (`--voxel-size`, `--origin`, `--level`, `--smooth`) is given.
    pub(crate) fn points_request(&self) -> Result<SurfaceRequest<'_>, Error> {
        if self.genus.is_some() || self.closing.is_some() {
            return Err(crate::usage(
                "--genus and --closing apply to --shape closed (a surface through points has a sphere's or a disc's topology)".into(),
            ));
        }
        if let Some(flag) = self.tracking.given().first() {
            return Err(crate::usage(format!(
                "{flag} applies to --shape closed, whose frames' surfaces are tracked (a surface \
                 through points is one mesh moved by its fitted heights)"
            )));
        }
        let volume_flags = [
            self.level.is_some(),
            self.smooth.is_some(),
            self.placement.voxel_size.is_some(),
            self.placement.origin.is_some(),
            self.placement.channel.is_some(),
            self.placement.resolution_level > 0,
        ];
        let extension = (self.points.extension()).map(|e| e.to_string_lossy().to_lowercase());
        let tiff = matches!(extension.as_deref(), Some("tif" | "tiff"));
        let image = tiff || meshflow::volume::is_ome_zarr(&self.points);
        let volumes = (image || volume_flags.contains(&true)).then(|| -> Result<_, Error> {
            let finding = IsosurfaceOptions {
                smoothing: self.smooth,
                level: self.level.unwrap_or(Level::Otsu),
                ..IsosurfaceOptions::default()
            };
            Ok((self.placement.options()?, finding))
        });
        Ok(SurfaceRequest {
            points: &self.points,
            out: &self.out,
            options: self.options(),
            times: self.times.clone(),
            overwrite: self.force.overwrite(),
            volumes: volumes.transpose()?,
        })
    }

    pub(crate) fn options(&self) -> meshflow::surface::FitOptions {
        use meshflow::surface::{FitOptions, Resolution, Shape};
        FitOptions {
            shape: match self.shape {
                ShapeArg::SphereLike => Shape::SphereLike {
                    whole: self.whole_sphere,
                },
                ShapeArg::Graph | ShapeArg::Closed => Shape::Graph,
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
