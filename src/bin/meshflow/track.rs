//! `meshflow track`: frames with their own triangulations → one fixed-connectivity sequence
//! (NPY directory that `solve` reads), by normal motion and relaxation (`meshflow::track`).
//!
//! The image goes along channel by channel: every tracked vertex lands on a triangle of each
//! frame ([`Tracked::landings`]), where each channel of that frame is interpolated.

use crate::args::{ForceArg, MeshArgs};
use crate::progress::{count_progress, Progress};
use meshflow::format::{
    frame_files, read_npy_image, write_atomically, write_intensity_array, write_npy_sequence,
    IoError, VertexValues, INTENSITY,
};
use meshflow::load::{
    load_mesh, load_sequence, read_intensity_array, read_mesh_with, read_times_file,
    select_channels, LoadOptions, SequenceSource,
};
use meshflow::run::{Overwrite, StagedDir};
use meshflow::shapes::Surface;
use meshflow::track::{
    track_with_progress, FrameReport, TrackEvent, TrackFrame, TrackOptions, Tracked,
};
use meshflow::Error;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// What `track` needs from the command line.
pub struct TrackRequest<'a> {
    pub input: &'a Path,
    pub out: &'a Path,
    pub reference: Option<&'a Path>,
    pub options: TrackOptions,
    pub times: Option<Vec<f64>>,
    pub load: LoadOptions,
    pub overwrite: Overwrite,
}

impl TrackRequest<'_> {
    /// The files and directories `track` reads: the frames, `--reference` and `--intensity`.
    fn inputs(&self) -> Vec<&Path> {
        std::iter::once(self.input)
            .chain(self.reference)
            .chain(self.load.intensity.as_deref())
            .collect()
    }
}

pub fn run(request: TrackRequest) -> Result<(), Error> {
    let mut staged =
        StagedDir::create_apart_from(&request.inputs(), request.out, request.overwrite)?;
    staged.record_command(crate::command_line());
    let input = crate::progress::during(format!("reading {}", request.input.display()), || {
        read_frames(request.input, &request.load)
    })?;
    let channels = frame_channels(&input, &request.load)?;
    let frames: Vec<TrackFrame> = (input.frames.iter().zip(&channels))
        .map(|(frame, channels)| TrackFrame {
            intensity: match channels {
                Some(c) => VertexValues::Channels(c.clone()).to_grey(),
                None => vec![0.0; frame.positions.len()],
            },
            positions: frame.positions.clone(),
            faces: frame.faces.clone(),
        })
        .collect();
    let options = TrackOptions {
        reference: reference_mesh(request.reference, &request.load)?,
        ..request.options
    };
    print_header(request.input, &frames, &options);
    let times = request.times.or(input.times);
    let tracked = tracked_with_progress(&frames, times, &options)?;
    let image = channels
        .iter()
        .all(Option::is_some)
        .then(|| carry_image(&tracked, &frames, &channels));
    write_outputs(&staged, &tracked, image.as_deref()).map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    print_summary(&tracked, request.out);
    if image.is_none() {
        stderr_line!(
            "meshflow: warning: the frames have no image (vertex colours, texture or a PLY \
             property): intensity.npy not written, and `meshflow solve` on the result will need \
             --intensity FILE.npy of shape (frames, {} vertices); or track again with \
             --intensity or --intensity-attribute",
            tracked.sequence.mesh().n_vertices()
        );
    }
    Ok(())
}

/// What `track` reads: the frames (each file its own mesh) with their images as stored, times
/// from a `times.txt` or the glTF animation, and the file of frame 0 (the default reference).
struct InputFrames {
    frames: Vec<Surface>,
    images: Vec<Option<VertexValues>>,
    times: Option<Vec<f64>>,
    files: Vec<PathBuf>,
}

fn read_frames(input: &Path, load: &LoadOptions) -> Result<InputFrames, Error> {
    let source = SequenceSource::detect(input)?;
    match &source {
        SequenceSource::Frames { files, .. } => {
            let read: Vec<(Surface, Option<VertexValues>)> = files
                .par_iter()
                .map(|file| {
                    let mesh = read_mesh_with(file, load)?;
                    let surface = Surface {
                        positions: mesh.positions,
                        faces: mesh.faces,
                    };
                    Ok((surface, mesh.image))
                })
                .collect::<Result<_, Error>>()?;
            let times_file = source.times_file().expect("frames are files");
            let (frames, images) = read.into_iter().unzip();
            Ok(InputFrames {
                frames,
                images,
                times: read_times_file(&times_file)?,
                files: files.clone(),
            })
        }
        // One connectivity already: tracking re-parametrizes it by normal motion.
        SequenceSource::GltfAnimation(file) | SequenceSource::Npy(file) => {
            let loaded = load_sequence(input, load)?;
            let sequence = &loaded.sequence;
            let k = sequence.n_frames();
            let frames = (0..k)
                .map(|k| Surface {
                    positions: sequence.positions(k).expect("read from files").to_vec(),
                    faces: sequence.mesh().faces().to_vec(),
                })
                .collect();
            Ok(InputFrames {
                frames,
                images: (0..k)
                    .map(|k| Some(VertexValues::Channels(sequence.channels(k).to_vec())))
                    .collect(),
                times: Some(sequence.times().to_vec()),
                files: vec![file.clone(); k],
            })
        }
        SequenceSource::Arrays => unreachable!("detect() finds files"),
    }
}

/// Each frame's image channels `[c][i]` as `--intensity` and `--channels` choose; `None` for
/// frames without an image.
fn frame_channels(
    input: &InputFrames,
    load: &LoadOptions,
) -> Result<Vec<Option<Vec<Vec<f64>>>>, Error> {
    let sizes: Vec<usize> = input.frames.iter().map(|f| f.positions.len()).collect();
    let (values, file) = match &load.intensity {
        Some(file) => (intensity_values(file, &sizes)?, file.as_path()),
        None => match input.images.iter().position(Option::is_none) {
            Some(k) if input.images.iter().any(Option::is_some) => {
                return Err(IoError::format(
                    &input.files[k],
                    "this frame has no image (vertex colours, texture or property) but others do",
                )
                .into())
            }
            Some(_) => return Ok(vec![None; sizes.len()]),
            None => (
                input.images.iter().flatten().cloned().collect(),
                input.files[0].as_path(),
            ),
        },
    };
    for (k, (v, &n)) in values.iter().zip(&sizes).enumerate() {
        if let Some(got) = v.wrong_length(n) {
            let message = format!("frame {k} has {got} image values for {n} vertices");
            return Err(IoError::format(file, message).into());
        }
    }
    let images = select_channels(values, load.channels).map_err(|m| IoError::format(file, m))?;
    Ok(images.into_frames().into_iter().map(Some).collect())
}

/// `--intensity`: one array (K, V) or (K, V, C) when every frame has V vertices, or a
/// directory of one array per frame, (V_k,) or (V_k, C) (their sizes are checked by the
/// caller, with the frames').
fn intensity_values(path: &Path, sizes: &[usize]) -> Result<Vec<VertexValues>, Error> {
    if path.is_dir() {
        let is_npy = |p: &Path| p.extension().is_some_and(|e| e == "npy");
        let files = frame_files(path, is_npy, ".npy arrays")?;
        if files.len() != sizes.len() {
            let message = format!("{} .npy files for {} frames", files.len(), sizes.len());
            return Err(IoError::format(path, message).into());
        }
        return files.iter().map(|file| frame_values(file)).collect();
    }
    if let Some(other) = sizes.iter().position(|&n| n != sizes[0]) {
        let message = format!(
            "one array cannot hold frames of different sizes (frame 0 has {} vertices, frame \
             {other} has {}): give a directory with one .npy per frame",
            sizes[0], sizes[other]
        );
        return Err(IoError::format(path, message).into());
    }
    Ok(read_intensity_array(path, sizes.len(), sizes[0])?)
}

/// One frame's image from its own `.npy`, (V,) or (V, C).
fn frame_values(file: &Path) -> Result<VertexValues, Error> {
    let array = read_npy_image(file)?;
    let channels = match array.shape[..] {
        [_] => None,
        [_, c] => Some(c as usize),
        _ => {
            let message = format!(
                "shape {:?}, expected (vertices,) or (vertices, channels)",
                array.shape
            );
            return Err(IoError::format(file, message).into());
        }
    };
    Ok(VertexValues::from_rows(array.data, channels))
}

/// `--reference`, read as `solve` reads a mesh.
fn reference_mesh(file: Option<&Path>, load: &LoadOptions) -> Result<Option<Surface>, Error> {
    let Some(file) = file else {
        return Ok(None);
    };
    let reference = load_mesh(file, load)?;
    crate::print_warnings(&reference.warnings);
    Ok(Some(Surface {
        faces: reference.mesh.faces().to_vec(),
        positions: reference.positions,
    }))
}

/// Frame `k`'s channels interpolated where each tracked vertex landed: `[k][c][i]`.
fn carry_image(
    tracked: &Tracked,
    frames: &[TrackFrame],
    channels: &[Option<Vec<Vec<f64>>>],
) -> Vec<Vec<Vec<f64>>> {
    (tracked.landings.iter().zip(frames).zip(channels))
        .map(|((landing, frame), channels)| {
            let channels = channels.as_ref().expect("every frame has an image");
            channels
                .iter()
                .map(|values| {
                    landing
                        .iter()
                        .map(|p| {
                            let corners = frame.faces[p.face];
                            (0..3)
                                .map(|c| p.barycentric[c] * values[corners[c] as usize])
                                .sum()
                        })
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// positions.npy, faces.npy, intensity.npy ((K, V) or (K, V, C)), times.txt and track.json.
fn write_outputs(
    staged: &StagedDir,
    tracked: &Tracked,
    image: Option<&[Vec<Vec<f64>>]>,
) -> Result<(), Error> {
    let dir = staged.path();
    let sequence = &tracked.sequence;
    let positions: Vec<_> = (0..sequence.n_frames())
        .map(|f| sequence.positions(f).expect("tracked in R^3").to_vec())
        .collect();
    write_npy_sequence(
        dir,
        &positions,
        sequence.mesh().faces(),
        None,
        sequence.times(),
    )?;
    if let Some(image) = image {
        write_intensity_array(&dir.join(INTENSITY), image)?;
    }
    let report = serde_json::to_string_pretty(&tracked.report).expect("a report serializes");
    write_atomically(&dir.join("track.json"), |w| {
        use std::io::Write;
        writeln!(w, "{report}")
    })?;
    Ok(())
}

fn print_header(input: &Path, frames: &[TrackFrame], options: &TrackOptions) {
    let reference = match (&options.reference, options.reference_vertices) {
        (_, Some(n)) => format!("a reference of about {n} vertices"),
        (Some(r), None) => format!("the given reference ({} vertices)", r.positions.len()),
        (None, None) => format!("frame 0's mesh ({} vertices)", frames[0].positions.len()),
    };
    let relaxation = match options.relaxation {
        meshflow::track::Relaxation::None => "normal motion only".to_string(),
        meshflow::track::Relaxation::Arap { iterations } => {
            format!("normal motion and ARAP relaxation ({iterations} steps)")
        }
    };
    stdout_line!(
        "{}: tracking {} frames by {relaxation}, {reference}, align {:?}; per frame, against \
         the previous frame (frame 0: the reference projected onto frame 0; worst_*_change: \
         against the reference):",
        input.display(),
        frames.len(),
        options.alignment
    );
}

pub(crate) fn print_summary(tracked: &Tracked, out: &Path) {
    let mesh = tracked.sequence.mesh();
    stdout_line!(
        "{} frames tracked on {} vertices, {} faces (step bound {:.3e}) -> {}",
        tracked.sequence.n_frames(),
        mesh.n_vertices(),
        mesh.n_faces(),
        tracked.report.max_step_bound,
        out.display()
    );
    for warning in &tracked.report.warnings {
        stderr_line!("meshflow: warning: {warning}");
    }
}

/// [`track_with_progress`] with a progress bar and a line per frame (and per trimming of the
/// reference), as `meshflow track` prints them.
pub(crate) fn tracked_with_progress(
    frames: &[TrackFrame],
    times: Option<Vec<f64>>,
    options: &TrackOptions,
) -> Result<Tracked, Error> {
    let bar = count_progress(frames.len() as u64, "tracking frames");
    let tracked = track_with_progress(frames, times, options, &mut |e| show_event(&bar, e));
    bar.finish();
    Ok(tracked?)
}

/// A tracking event on the terminal: a line per frame, counted on `bar`, and a line per
/// trimming of the reference, which starts the count again.
pub(crate) fn show_event(bar: &Progress, event: TrackEvent) {
    match event {
        TrackEvent::Frame(report) => {
            bar.suspend(|| stdout_line!("  {}", describe(report)));
            bar.inc(1);
        }
        TrackEvent::Trimmed {
            frame,
            uncovered,
            remaining,
        } => {
            bar.suspend(|| {
                stdout_line!(
                    "  frame {frame:3}: {uncovered} reference vertices lie beyond the frame's \
                     boundary: trimmed to {remaining} vertices, tracking again from frame 0"
                )
            });
            bar.set_position(0);
        }
    }
}

/// One frame's line, with track.json's names.
fn describe(r: &FrameReport) -> String {
    let mut line = format!(
        "frame {:3}: mean_step {:.3e} max_step {:.3e}; mean_relaxation {:.3e} max_relaxation \
         {:.3e}; edge_log_ratio_p99 {:.3} edge_log_ratio_max {:.3}; flipped_triangles {}; \
         max_off_surface {:.1e}; \
         misses {} (fallbacks {}, beyond_max_step {}); worst_edge_change {:.1} %, \
         worst_area_change {:.1} %",
        r.frame,
        r.mean_step,
        r.max_step,
        r.mean_relaxation,
        r.max_relaxation,
        r.edge_log_ratio_p99,
        r.edge_log_ratio_max,
        r.flipped_triangles,
        r.max_off_surface,
        r.misses,
        r.fallbacks,
        r.beyond_max_step,
        100.0 * r.worst_edge_change,
        100.0 * r.worst_area_change,
    );
    if let Some(a) = &r.alignment {
        let what = match a.applied {
            true => "alignment",
            false => "rigid fit (not applied)",
        };
        line += &format!(
            "; {what}: rotation_degrees {:.2}, translation {:.3e}, scale {:.4}, \
             median_distance {:.3e} -> {:.3e}",
            a.rotation_degrees,
            nalgebra::Vector3::from(a.translation).norm(),
            a.scale,
            a.median_distance_before,
            a.median_distance_after
        );
    }
    line
}

#[derive(clap::Args)]
pub(crate) struct TrackArgs {
    /// Frames directory, glob (quoted), .gltf/.glb animation, or NPY directory; frames may
    /// differ in vertices and triangles
    pub(crate) input: PathBuf,
    /// Output directory (an NPY sequence for `meshflow solve`)
    #[arg(long)]
    pub(crate) out: PathBuf,
    #[command(flatten)]
    pub(crate) force: ForceArg,
    /// The mesh to move (on or near frame 0's surface; default: frame 0's own mesh)
    #[arg(long, value_name = "MESH")]
    pub(crate) reference: Option<PathBuf>,
    /// Frame times t0,t1,… (default: times.txt beside the frames or the glTF animation's,
    /// else 0,1,2,…)
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub(crate) times: Option<Vec<f64>>,
    /// Track a reference of about N vertices made from frame 0 (or from --reference) by
    /// simplification: faster, and it folds less than a fine segmentation mesh
    #[arg(long, value_name = "N")]
    pub(crate) reference_vertices: Option<usize>,
    #[command(flatten)]
    pub(crate) tracking: TrackingArgs,
    /// Keep reference vertices beyond a frame's boundary (they take the closest point on it)
    /// instead of trimming the reference to the part every frame covers
    #[arg(long)]
    pub(crate) keep_uncovered: bool,
    /// The image as a float .npy of shape (frames, vertices) or (frames, vertices, channels)
    /// when every frame has as many vertices, or a directory of one .npy per frame, (vertices,)
    /// or (vertices, channels), in natural order; instead of the files' colours
    #[arg(long, value_name = "FILE.npy|DIR")]
    pub(crate) intensity: Option<PathBuf>,
    /// PLY vertex property holding the grey values (instead of the colours)
    #[arg(long)]
    pub(crate) intensity_attribute: Option<String>,
    /// Image channels: auto (every channel the input has), rgb, luma (Rec. 709) or grey (mean)
    #[arg(long, default_value = "auto")]
    pub(crate) channels: meshflow::load::Channels,
    #[command(flatten)]
    pub(crate) building: MeshArgs,
}

/// How frames' surfaces are followed: `track`'s and `surface --shape closed`'s flags, declared
/// once.
#[derive(clap::Args)]
pub(crate) struct TrackingArgs {
    /// Largest normal step per frame, in the data's length unit; a vertex farther from the next
    /// surface is an error [default: 10 % of frame 0's bounding-box diagonal]
    #[arg(long, value_name = "LENGTH", allow_negative_numbers = true)]
    pub(crate) max_step: Option<f64>,
    /// Go on past vertices beyond --max-step (they take the closest point) and flipped
    /// triangles, counting them in the report, instead of stopping with an error
    #[arg(long)]
    pub(crate) keep_going: bool,
    /// After each normal step, relax the mesh on the new surface as rigidly as possible
    /// against the previous frame (arap), or move vertices along their normals only (none,
    /// the paper's normal motion)
    #[arg(long, value_name = "KIND", default_value = "arap")]
    pub(crate) relax: RelaxKind,
    /// Relaxation steps per frame (with --relax arap)
    #[arg(long, value_name = "N", default_value_t = meshflow::track::Relaxation::DEFAULT_ITERATIONS)]
    pub(crate) relax_iterations: usize,
    /// The motion of the whole sample between frames, fitted before tracking: rigid,
    /// similarity (also uniform scale) or none. `track` takes it out (the transforms are in
    /// track.json); `surface --shape closed` starts each frame's step from it, keeping the
    /// recording's coordinates [default: none for track, rigid for surface]
    #[arg(long, value_name = "KIND")]
    pub(crate) align: Option<meshflow::track::Alignment>,
}

impl TrackingArgs {
    /// The flags given with other than their default values.
    pub(crate) fn given(&self) -> Vec<&'static str> {
        let relax_iterations = meshflow::track::Relaxation::DEFAULT_ITERATIONS;
        [
            (self.max_step.is_some(), "--max-step"),
            (self.keep_going, "--keep-going"),
            (matches!(self.relax, RelaxKind::None), "--relax"),
            (
                self.relax_iterations != relax_iterations,
                "--relax-iterations",
            ),
            (self.align.is_some(), "--align"),
        ]
        .into_iter()
        .filter_map(|(given, flag)| given.then_some(flag))
        .collect()
    }

    /// These flags' part of the tracker's options, `--align` by default `align`; the rest as
    /// `TrackOptions::default()`.
    pub(crate) fn options(
        &self,
        align: meshflow::track::Alignment,
    ) -> meshflow::track::TrackOptions {
        use meshflow::track::Relaxation;
        meshflow::track::TrackOptions {
            max_step: self.max_step,
            keep_going: self.keep_going,
            relaxation: match self.relax {
                RelaxKind::Arap => Relaxation::Arap {
                    iterations: self.relax_iterations,
                },
                RelaxKind::None => Relaxation::None,
            },
            alignment: self.align.unwrap_or(align),
            ..meshflow::track::TrackOptions::default()
        }
    }
}

/// `--relax`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum RelaxKind {
    Arap,
    None,
}

impl TrackArgs {
    pub(crate) fn options(&self) -> meshflow::track::TrackOptions {
        meshflow::track::TrackOptions {
            reference_vertices: self.reference_vertices,
            keep_uncovered: self.keep_uncovered,
            ..self.tracking.options(meshflow::track::Alignment::None)
        }
    }

    pub(crate) fn load_options(&self) -> LoadOptions {
        LoadOptions {
            intensity: self.intensity.clone(),
            intensity_attribute: self.intensity_attribute.clone(),
            channels: self.channels,
            ..self.building.options()
        }
    }
}
