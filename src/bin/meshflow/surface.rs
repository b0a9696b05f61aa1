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
use meshflow::surface::ClosedSequence;
use meshflow::surface::{closed_sequence, ClosedError, ClosedEvent, ClosedOptions};
use meshflow::surface::{fit_surface, fit_surface_weighted, read_points, FitOptions};
use meshflow::surface::{foreground_points, FoundSurface, IsosurfaceOptions, Level};
use meshflow::surface::{FittedSurface, ForegroundPoints, Reference};
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
    pub options: ClosedOptions,
    pub overwrite: Overwrite,
}

/// `meshflow surface VOLUMES --shape closed`: each frame's surface found in its volume, then
/// one reference tracked through them ([`closed_sequence`]), written as an NPY sequence with
/// `surface.json`.
pub fn run_closed(request: ClosedRequest) -> Result<(), Error> {
    let staged = staged_output(
        request.volumes,
        request.out,
        request.overwrite,
        &request.options.times,
    )?;
    let mut stream = VolumeStream::open(request.volumes, &request.placement)?;
    // From the files' headers: a wrong --times fails before any reading.
    let times = request.options.times.as_ref();
    if let Some(times) = times.filter(|t| t.len() != stream.n_frames()) {
        return Err(crate::usage(format!(
            "--times gives {} times for the {} frames of {}",
            times.len(),
            stream.n_frames(),
            request.volumes.display()
        )));
    }
    let bar =
        crate::progress::count_progress(stream.n_frames() as u64, "finding and tracking surfaces");
    let volumes = request.volumes;
    let mut on_event = |event: ClosedEvent| match event {
        ClosedEvent::VoxelSize(source) => {
            bar.suspend(|| crate::sample::report_voxel_size(volumes, source))
        }
        ClosedEvent::MissingChunks {
            frame,
            missing,
            chunks,
        } => bar.suspend(|| crate::sample::report_missing_chunks(volumes, frame, missing, chunks)),
        ClosedEvent::Found { frame, surface } => bar.suspend(|| {
            stdout_line!("  frame {frame:3}: {}", describe_found(surface));
            for warning in surface.warnings() {
                stderr_line!("meshflow: warning: frame {frame}: {warning}");
            }
        }),
        ClosedEvent::FewerVertices {
            vertices,
            asked,
            frame_vertices,
        } => bar.suspend(|| {
            stdout_line!(
                "frame 0's surface has {frame_vertices} vertices: the tracked mesh gets \
                 {vertices} (half; {asked} were asked)"
            )
        }),
        ClosedEvent::Track(event) => crate::track::show_event(&bar, event),
    };
    let closed = closed_sequence(&mut stream, &request.options, &mut on_event)
        .map_err(|e| in_volumes(e, volumes));
    bar.finish();
    let closed = closed?;
    write_closed(&staged, &closed).map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    crate::track::print_summary(&closed.tracked, request.out);
    Ok(())
}

/// Errors of the sequence as a whole name the recording.
fn in_volumes(error: Error, volumes: &Path) -> Error {
    match error {
        Error::Closed(ClosedError::OneFrame(_)) => error.in_file(volumes),
        other => other,
    }
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
fn write_closed(staged: &StagedDir, closed: &ClosedSequence) -> Result<(), Error> {
    let dir = staged.path();
    let sequence = &closed.tracked.sequence;
    let positions: Vec<_> = (0..sequence.n_frames())
        .map(|k| sequence.positions(k).expect("tracked in R^3").to_vec())
        .collect();
    let faces = sequence.mesh().faces();
    write_npy_sequence(dir, &positions, faces, None, sequence.times())?;
    let report = serde_json::to_string_pretty(&closed.report()).expect("a report serializes");
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
            options: ClosedOptions {
                finding: IsosurfaceOptions {
                    smoothing: self.smooth,
                    level: self.level.unwrap_or(Level::Otsu),
                    genus: self.genus.unwrap_or(0),
                    closing: self.closing,
                },
                vertices: self.vertices,
                tracking: self.tracking.options(meshflow::track::Alignment::Rigid),
                times: self.times.clone(),
            },
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
