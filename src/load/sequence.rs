//! Reading a [`MeshSequence`] from files, whatever the format.
//!
//! Every source (see [`SequenceSource`]) is first read into a [`RawSequence`] with the files'
//! own vertex numbering, checked frame by frame (same vertex count and faces as frame 0, finite
//! values), then turned into a mesh by the steps of [`super::prepare`] (welding, orientation,
//! repair, dropping unused vertices; the [`VertexMap`] keeps the files' numbering) and validated
//! as a [`MeshSequence`]. Errors name the file, and the frame, vertex or face at fault.
//!
//! The image comes from `--intensity` (a float32, float64, uint8 or uint16 `.npy` of shape (K, V), or (K, V, C)
//! for `C` channels, over the files' vertices, or over the mesh's where their counts differ) when given, else from each format's own data: OBJ
//! vertex colours or `map_Kd` texture, a PLY scalar property (`intensity_attribute`) or its
//! colours, glTF `COLOR_0` or base-colour texture, `intensity.npy` next to NPY arrays.
//! [`LoadOptions::channels`] chooses the channels (see [`super::channels`]). Frame times come from `--times`, else a glTF animation's keyframes, else a
//! `times.txt` next to the frames (numbers separated by white space or commas, `#` comments),
//! else `0, 1, 2, …`.

use super::input::{FrameFormat, SequenceSource, ARRAYS};
use super::prepare::{prepare_mesh, Prepared};
use super::warning::STATIC_IMAGE_TOLERANCE;
use super::{select_channels, LoadOptions, LoadWarning, VertexMap};
use crate::flow::{check_finite_intensities, FlowError, Images, MeshSequence};
use crate::format::gltf::{
    read_gltf_animation, read_gltf_animation_frames, read_gltf_frame, ImplicitClip,
};
use crate::format::ply::read_ply;
use crate::format::{read_intensity_rows, read_npy_sequence, VertexCount, IMAGE};
use crate::format::{read_obj, texture_colors};
use crate::format::{FrameMesh, IoError, RawSequence, TextureCache, VertexValues};
use crate::mesh::{Mesh, SumOverReaders};
use crate::Error;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A sequence read from files, with where it came from.
#[derive(Clone, Debug)]
pub struct LoadedSequence {
    pub sequence: MeshSequence,
    /// The path it was read from (a directory, a glob, a glTF file).
    pub path: PathBuf,
    pub source: SequenceSource,
    /// File vertices ↔ mesh vertices.
    pub vertex_map: VertexMap,
    /// The file each frame came from.
    pub frame_files: Vec<PathBuf>,
    /// What the loader noticed and worked around (see [`LoadWarning`]).
    pub warnings: Vec<LoadWarning>,
    /// Per frame and mesh vertex: no data there (`no_data.npy` beside the image, written by
    /// `meshflow sample`); `None` when the image has no such mask.
    pub no_data: Option<Vec<Vec<bool>>>,
}

/// Reads the sequence that `path` names (a directory, a glob, a glTF animation; see
/// [`SequenceSource`]).
pub fn load_sequence(path: &Path, options: &LoadOptions) -> Result<LoadedSequence, Error> {
    load_frames(path, options, None, &|_| {})
}

/// The frames `frames` (all with `None`) of the sequence that `path` names, numbered from the
/// range's start, at their own times: what one rank of a solve over time windows holds
/// ([`crate::flow::window`]). Frame files outside the range are not opened, except frame 0,
/// whose faces are the connectivity and whose positions the weld starts from; NPY arrays are
/// read by rows (the others skipped on disk), a glTF animation evaluated at those frames only. Every process reading some frames of one sequence
/// passes `sum` over all of them ([`SumOverReaders`]), so that they weld alike; warnings about
/// the whole sequence (a static image) are for a reader of all frames to give.
pub fn load_frames(
    path: &Path,
    options: &LoadOptions,
    frames: Option<Range<usize>>,
    sum: SumOverReaders,
) -> Result<LoadedSequence, Error> {
    let source = SequenceSource::detect(path)?;
    check_options(&source, options, path)?;
    let window = read_window(&source, options, frames, path)?;
    build_sequence(source, window, options, path, sum)
}

/// How many frames the sequence that `path` names has, reading as little as its format
/// allows (frame files: none; NPY arrays: their headers and faces; a glTF animation: its
/// mesh and animation, evaluated at no frame).
pub fn count_frames(path: &Path, options: &LoadOptions) -> Result<usize, Error> {
    let source = SequenceSource::detect(path)?;
    check_options(&source, options, path)?;
    Ok(match &source {
        SequenceSource::Frames { files, .. } => files.len(),
        SequenceSource::Npy(dir) => read_npy_sequence(dir, &|_| false)?.1,
        SequenceSource::GltfAnimation(file) => {
            read_gltf_animation_frames(file, &options.animation_options(), &|_| false)?.1
        }
        SequenceSource::Arrays => unreachable!("arrays are not read"),
    })
}

/// Some consecutive frames of a [`RawSequence`] (`raw` holds only those).
struct RawWindow {
    raw: RawSequence,
    /// The sequence's frames that `raw` holds.
    held: Range<usize>,
    n_frames_in_all: usize,
    /// Frame 0's positions when the window starts later: the weld's reference frame.
    frame_zero: Option<Vec<Vector3<f64>>>,
}

impl RawWindow {
    fn whole(raw: RawSequence) -> Self {
        RawWindow {
            n_frames_in_all: raw.positions.len(),
            held: 0..raw.positions.len(),
            raw,
            frame_zero: None,
        }
    }

    /// `raw` (frame 0, then the frames `frames` when they start later; else `frames`) as the
    /// window `frames`.
    fn of(mut raw: RawSequence, frames: Range<usize>, n_frames_in_all: usize) -> Self {
        let frame_zero = match frames.start {
            0 => None,
            _ => {
                let zero = raw.positions.remove(0);
                raw.sources.remove(0);
                if let Some(images) = &mut raw.images {
                    images.remove(0);
                }
                Some(zero)
            }
        };
        RawWindow {
            raw,
            held: frames,
            n_frames_in_all,
            frame_zero,
        }
    }

    /// The frames of all `values` (one per frame of the sequence) that the window holds.
    fn cut<T: Clone>(&self, values: &[T]) -> Vec<T> {
        values[self.held.clone()].to_vec()
    }

    fn is_whole(&self) -> bool {
        self.held.len() == self.n_frames_in_all
    }
}

/// Reads the frames `frames` of `source` (all with `None`) and frame 0, and no others: only
/// those files of a frame sequence, those rows of NPY arrays, a glTF animation at those frames.
fn read_window(
    source: &SequenceSource,
    options: &LoadOptions,
    frames: Option<Range<usize>>,
    path: &Path,
) -> Result<RawWindow, Error> {
    let Some(frames) = frames else {
        return Ok(RawWindow::whole(read_raw(source, options)?));
    };
    let in_range = |n_frames_in_all: usize| match frames.is_empty() || frames.end > n_frames_in_all
    {
        true => Err(IoError::format(
            path,
            format!("frames {frames:?} asked of a sequence of {n_frames_in_all} frames"),
        )),
        false => Ok(n_frames_in_all),
    };
    let is_read = |k: usize| k == 0 || frames.contains(&k);
    let (raw, n_frames_in_all) = match source {
        SequenceSource::Frames { format, files } => {
            let n_frames_in_all = in_range(files.len())?;
            let files: Vec<PathBuf> = (files.iter().enumerate())
                .filter(|&(k, _)| is_read(k))
                .map(|(_, f)| f.clone())
                .collect();
            (read_frames(*format, &files, options)?, n_frames_in_all)
        }
        SequenceSource::Npy(dir) => {
            let (raw, n_frames_in_all) = read_npy_sequence(dir, &is_read)?;
            (raw, in_range(n_frames_in_all)?)
        }
        SequenceSource::GltfAnimation(file) => {
            let animation = options.animation_options();
            let (raw, n_frames_in_all) = read_gltf_animation_frames(file, &animation, &is_read)?;
            (raw, in_range(n_frames_in_all)?)
        }
        SequenceSource::Arrays => unreachable!("arrays are not read"),
    };
    Ok(RawWindow::of(raw, frames, n_frames_in_all))
}

/// A sequence from arrays in memory, through the same steps as [`load_sequence`] (welding,
/// orientation, repair per `options`, channels per `options.channels`; the [`VertexMap`]
/// relates `positions`' numbering to the mesh's). `faces` index `positions[k]`; `images[k]` is
/// frame `k`'s image over the file vertices; `times = None` means `options.times`, else
/// `0, 1, 2, …`. Errors name the frame, vertex or face, and the argument
/// (`"arrays: frame 3: …"`).
pub fn sequence_from_arrays(
    faces: Vec<[u32; 3]>,
    positions: Vec<Vec<Vector3<f64>>>,
    images: Vec<VertexValues>,
    times: Option<Vec<f64>>,
    options: &LoadOptions,
) -> Result<LoadedSequence, Error> {
    let source = SequenceSource::Arrays;
    let path = Path::new(ARRAYS);
    check_options(&source, options, path)?;
    let raw = RawSequence {
        faces,
        sources: vec![path.to_path_buf(); positions.len()],
        positions,
        images: Some(images),
        times,
        implicit_clip: None,
    };
    build_sequence(source, RawWindow::whole(raw), options, path, &|_| {})
}

/// The steps after reading (module docs): mesh, image channels, times, sequence.
fn build_sequence(
    source: SequenceSource,
    window: RawWindow,
    options: &LoadOptions,
    path: &Path,
    sum: SumOverReaders,
) -> Result<LoadedSequence, Error> {
    let mut window = window;
    let RawSequence {
        faces,
        positions,
        images,
        times,
        sources: files,
        implicit_clip,
    } = std::mem::take(&mut window.raw);
    let mut warnings = clip_warnings(&source, implicit_clip);
    if window.n_frames_in_all < 2 {
        return Err(FlowError::TooFewFrames(window.n_frames_in_all).into());
    }
    let n_file_vertices = positions[0].len();
    check_frame_sizes(&positions, images.as_deref(), &files)?;
    let frame_zero = window.frame_zero.as_ref();
    let prepared = prepare_geometry(&faces, &positions, frame_zero, &files, options, sum)?;
    let vertex_map = prepared.vertex_map;
    let counts = [
        VertexCount::new(n_file_vertices, "vertices in the files"),
        VertexCount::new(prepared.mesh.n_vertices(), MESH_VERTICES),
    ];
    let (images, images_file, on_mesh) = match &options.intensity {
        Some(file) => {
            let held = |k: usize| window.held.contains(&k);
            let (images, count) = read_intensity_rows(IMAGE, file, window.n_frames_in_all, &counts, &held)?;
            (images, file.as_path(), count == 1)
        }
        None => (
            images.ok_or_else(|| {
                IoError::format(
                    &files[0],
                    "no grey values (vertex colours, texture or intensity property); give --intensity FILE.npy",
                )
            })?,
            files[0].as_path(),
            false,
        ),
    };
    let no_data = {
        let held = |k: usize| window.held.contains(&k);
        let n = window.n_frames_in_all;
        super::no_data::read_no_data(&source, options, n, &counts, &held, &vertex_map)?
    };
    let images = select_channels(images, options.channels)
        .map_err(|message| IoError::format(images_file, message))?;
    // Dropped vertices' values are never used.
    check_finite_intensities(&images, |i| on_mesh || vertex_map.mesh_vertex(i).is_some()).map_err(
        |e| match &options.intensity {
            Some(file) => Error::from(e).in_file(file),
            None => in_frame_file(e, &files),
        },
    )?;
    let times_file = source.times_file();
    let (times, times_from_file) = frame_times(&source, options, times)?;
    // Times for all frames (options, `times.txt`, a glTF animation's) are cut to the window's,
    // which keeps its own numbers without any; others fail validation below.
    let times = match times {
        Some(times) if times.len() == window.n_frames_in_all => Some(window.cut(&times)),
        None if !window.is_whole() => Some(window.held.clone().map(|k| k as f64).collect()),
        times => times,
    };
    let positions = positions.iter().map(|p| vertex_map.positions(p)).collect();
    let on_vertices = |values: &Vec<f64>| match on_mesh {
        true => values.clone(),
        false => vertex_map.mean_values(values),
    };
    let images = Images::from_channels(
        (images.into_frames().iter())
            .map(|channels| channels.iter().map(on_vertices).collect())
            .collect(),
    );
    let sequence =
        MeshSequence::with_images(prepared.mesh, positions, images, times).map_err(|e| {
            match (e, &times_file) {
                (e, Some(file)) if times_from_file && is_about_times(&e) => {
                    Error::from(e).in_file(file)
                }
                // Named as the option, where a path would name the file.
                (e, _) if options.times.is_some() && is_about_times(&e) => {
                    Error::from(e).in_file("--times")
                }
                (e, _) => in_frame_file(e, &files),
            }
        })?;
    warnings.extend(prepared.warnings);
    if window.is_whole() {
        warnings.extend(static_image_warning(&sequence, path));
    }
    Ok(LoadedSequence {
        sequence,
        path: path.to_path_buf(),
        source,
        vertex_map,
        frame_files: files,
        warnings,
        no_data,
    })
}

/// The warning for a glTF animation chosen among several without being named.
fn clip_warnings(source: &SequenceSource, implicit: Option<ImplicitClip>) -> Vec<LoadWarning> {
    match (source, implicit) {
        (SequenceSource::GltfAnimation(file), Some(clip)) => vec![LoadWarning::SeveralAnimations {
            file: file.clone(),
            clips: clip.clips,
            chosen: clip.chosen,
        }],
        _ => Vec::new(),
    }
}

/// The frame times: `options.times`, else the file's own (`read`, a glTF animation's), else a
/// `times.txt` beside the frames (`None` without any: 0, 1, 2, …); and whether they came from
/// that `times.txt`.
fn frame_times(
    source: &SequenceSource,
    options: &LoadOptions,
    read: Option<Vec<f64>>,
) -> Result<(Option<Vec<f64>>, bool), IoError> {
    Ok(match (&options.times, read, source.times_file()) {
        (Some(times), _, _) => (Some(times.clone()), false),
        (None, Some(times), _) => (Some(times), false),
        (None, None, Some(file)) => {
            let times = read_times_file(&file)?;
            let from_file = times.is_some();
            (times, from_file)
        }
        (None, None, None) => (None, false),
    })
}

/// A sequence's surfaces without an image, read and built as [`load_sequence`] builds them.
#[derive(Clone, Debug)]
pub struct LoadedGeometry {
    pub mesh: Mesh,
    /// `positions[k][i]`: mesh vertex `i` in frame `k`.
    pub positions: Vec<Vec<Vector3<f64>>>,
    /// File vertices ↔ mesh vertices.
    pub vertex_map: VertexMap,
    pub source: SequenceSource,
    /// The file each frame came from.
    pub frame_files: Vec<PathBuf>,
    /// The frame times as [`load_sequence`] finds them (`None`: 0, 1, 2, …); not validated.
    pub times: Option<Vec<f64>>,
    pub warnings: Vec<LoadWarning>,
}

/// The surfaces of the sequence that `path` names, without its image (which it need not
/// have): the mesh as [`load_sequence`] builds it from `options` (welding, orientation,
/// repair) and every frame's positions of its vertices. What `meshflow sample` carries an
/// image onto.
pub fn load_geometry(path: &Path, options: &LoadOptions) -> Result<LoadedGeometry, Error> {
    let source = SequenceSource::detect(path)?;
    let raw = read_raw(&source, options)?;
    let prepared = prepare_geometry(
        &raw.faces,
        &raw.positions,
        None,
        &raw.sources,
        options,
        &|_| {},
    )?;
    let vertex_map = prepared.vertex_map;
    let positions = raw
        .positions
        .iter()
        .map(|p| vertex_map.positions(p))
        .collect();
    let mut warnings = clip_warnings(&source, raw.implicit_clip);
    warnings.extend(prepared.warnings);
    let (times, _) = frame_times(&source, options, raw.times)?;
    Ok(LoadedGeometry {
        mesh: prepared.mesh,
        positions,
        vertex_map,
        source,
        frame_files: raw.sources,
        times,
        warnings,
    })
}

/// Frames of equal size with finite positions, and the mesh built from their faces.
/// With `frame_zero` (frame 0's positions, when `positions` are later frames only) the weld
/// starts from it; `sum` as in [`load_frames`].
fn prepare_geometry(
    faces: &[[u32; 3]],
    positions: &[Vec<Vector3<f64>>],
    frame_zero: Option<&Vec<Vector3<f64>>>,
    files: &[PathBuf],
    options: &LoadOptions,
    sum: SumOverReaders,
) -> Result<Prepared, Error> {
    check_frame_sizes(positions, None, files)?;
    check_finite_positions(positions).map_err(|e| in_frame_file(e, files))?;
    let weld_frames: Vec<&[Vector3<f64>]> = (frame_zero.into_iter())
        .chain(positions)
        .map(Vec::as_slice)
        .collect();
    prepare_mesh(&files[0], faces, &weld_frames, options, sum)
}

/// Every frame has as many positions (and grey values) as frame 0 has positions: readers
/// ensure it, arrays from a caller may not.
fn check_frame_sizes(
    positions: &[Vec<Vector3<f64>>],
    intensities: Option<&[VertexValues]>,
    files: &[PathBuf],
) -> Result<(), IoError> {
    let expected = positions[0].len();
    let wrong = |k: usize, message: String| Err(IoError::format(&files[k], message));
    if let Some(k) = positions.iter().position(|p| p.len() != expected) {
        let got = positions[k].len();
        return wrong(
            k,
            format!("frame {k} has {got} vertices, frame 0 has {expected}"),
        );
    }
    let Some(grey) = intensities else {
        return Ok(());
    };
    if grey.len() != positions.len() {
        let (got, frames) = (grey.len(), positions.len());
        return wrong(
            0,
            format!("{got} frames of grey values for {frames} frames"),
        );
    }
    match (grey.iter().enumerate()).find_map(|(k, g)| Some((k, g.wrong_length(expected)?))) {
        Some((k, got)) => wrong(
            k,
            format!("frame {k} has {got} grey values for {expected} vertices"),
        ),
        None => Ok(()),
    }
}

/// [`LoadWarning::StaticImage`] when every frame's image equals frame 0's (every channel, to
/// [`STATIC_IMAGE_TOLERANCE`] of its range) while some position changes (beyond round-off of
/// the surface's size).
fn static_image_warning(sequence: &MeshSequence, path: &Path) -> Option<LoadWarning> {
    let frame = |k: usize| (sequence.positions(k), sequence.channels(k));
    let mut check = StaticImageCheck::new(frame(0));
    (1..sequence.n_frames()).for_each(|k| check.add(frame(k)));
    check.warning(path)
}

/// [`static_image_warning`] taking the frames one at a time, in order from frame 0: what a
/// reader that sees each frame once (streamed from other ranks) can tell.
pub(crate) struct StaticImageCheck {
    /// Frame 0's positions (`None`: intrinsic) and channels.
    zero_positions: Option<Vec<Vector3<f64>>>,
    zero_channels: Vec<Vec<f64>>,
    /// Per channel: lowest and highest value, largest difference from frame 0.
    ranges: Vec<(f64, f64)>,
    differences: Vec<f64>,
    /// The largest coordinate of frame 0 (`None`: intrinsic, no warning) and whether any
    /// position moved beyond round-off of it.
    size: Option<f64>,
    moves: bool,
    frames: usize,
}

impl StaticImageCheck {
    pub fn new((positions, channels): (Option<&[Vector3<f64>]>, &[Vec<f64>])) -> Self {
        let mut check = StaticImageCheck {
            zero_positions: positions.map(<[_]>::to_vec),
            zero_channels: channels.to_vec(),
            ranges: vec![(f64::INFINITY, f64::NEG_INFINITY); channels.len()],
            differences: vec![0.0; channels.len()],
            size: positions.map(|p| p.iter().map(|p| p.amax()).fold(0.0, f64::max)),
            moves: false,
            frames: 0,
        };
        check.add((positions, channels));
        check
    }

    /// The next frame.
    pub fn add(&mut self, (positions, channels): (Option<&[Vector3<f64>]>, &[Vec<f64>])) {
        self.frames += 1;
        for (c, channel) in channels.iter().enumerate() {
            let (low, high) = &mut self.ranges[c];
            for &g in channel {
                (*low, *high) = (low.min(g), high.max(g));
            }
            let difference = (channel.iter().zip(&self.zero_channels[c]))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            self.differences[c] = self.differences[c].max(difference);
        }
        if let (Some(p), Some(q), Some(size)) = (positions, &self.zero_positions, self.size) {
            self.moves |= p.iter().zip(q).any(|(p, q)| (p - q).amax() > 1e-12 * size);
        }
    }

    /// The warning for the frames added, read from `path`.
    pub fn warning(&self, path: &Path) -> Option<LoadWarning> {
        self.size?;
        let same_image = (self.ranges.iter().zip(&self.differences))
            .all(|((low, high), d)| *d <= STATIC_IMAGE_TOLERANCE * (high - low));
        (same_image && self.moves).then(|| LoadWarning::StaticImage {
            file: path.to_path_buf(),
            frames: self.frames,
        })
    }
}

fn check_options(
    source: &SequenceSource,
    options: &LoadOptions,
    path: &Path,
) -> Result<(), IoError> {
    let is_animation = matches!(source, SequenceSource::GltfAnimation(_));
    if options.intensity.is_some() && matches!(source, SequenceSource::Arrays) {
        return Err(IoError::format(
            path,
            "--intensity (a grey-value file) applies to files; arrays carry their grey values",
        ));
    }
    let is_ply = matches!(
        source,
        SequenceSource::Frames {
            format: FrameFormat::Ply,
            ..
        }
    );
    if options.fps.is_some() && !is_animation {
        return Err(IoError::format(
            path,
            "--fps applies to a glTF animation (one .gltf/.glb file) only",
        ));
    }
    if let Some(fps) = options.fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
        return Err(IoError::format(
            path,
            format!("--fps must be a positive number, got {fps}"),
        ));
    }
    if options.animation.is_some() && !is_animation {
        return Err(IoError::format(
            path,
            "--animation applies to a glTF animation (one .gltf/.glb file) only",
        ));
    }
    if options.intensity_attribute.is_some() && !is_ply {
        return Err(IoError::format(
            path,
            "--intensity-attribute applies to PLY frames only",
        ));
    }
    Ok(())
}

fn read_raw(source: &SequenceSource, options: &LoadOptions) -> Result<RawSequence, Error> {
    match source {
        SequenceSource::Frames { format, files } => read_frames(*format, files, options),
        SequenceSource::GltfAnimation(file) => {
            Ok(read_gltf_animation(file, &options.animation_options())?)
        }
        SequenceSource::Npy(dir) => Ok(read_npy_sequence(dir, &|_| true)?.0),
        SequenceSource::Arrays => unreachable!("arrays are not read"),
    }
}

/// Reads the frame files in parallel and checks that they share one connectivity.
fn read_frames(
    format: FrameFormat,
    files: &[PathBuf],
    options: &LoadOptions,
) -> Result<RawSequence, Error> {
    let textures = TextureCache::default();
    // Collected in order, so the error reported is the first bad frame's, whatever the timing.
    let frames: Vec<Result<FrameMesh, IoError>> = files
        .par_iter()
        .map(|file| read_frame(format, file, options, &textures))
        .collect();
    let frames = frames.into_iter().collect::<Result<Vec<_>, _>>()?;
    let first = &frames[0];
    for (k, (frame, file)) in frames.iter().zip(files).enumerate().skip(1) {
        check_same_connectivity(first, frame, k).map_err(|m| IoError::format(file, m))?;
    }
    let all_missing = frames.iter().all(|f| f.image.is_none());
    let partly_missing = frames.iter().position(|f| f.image.is_none());
    if let Some(k) = partly_missing.filter(|_| !all_missing && options.intensity.is_none()) {
        return Err(IoError::format(
            &files[k],
            "this frame has no grey values (vertex colours, texture or intensity property) but others do",
        )
        .into());
    }
    let faces = frames[0].faces.clone();
    let (positions, images): (Vec<_>, Vec<_>) =
        frames.into_iter().map(|f| (f.positions, f.image)).unzip();
    Ok(RawSequence {
        faces,
        positions,
        images: images.into_iter().collect(),
        times: None,
        sources: files.to_vec(),
        implicit_clip: None,
    })
}

/// Reads one mesh file (`.obj`, `.ply`, `.gltf`, `.glb`) with its grey values, if any.
pub fn read_mesh(path: &Path) -> Result<FrameMesh, IoError> {
    read_mesh_with(path, &LoadOptions::default())
}

/// [`read_mesh`] with the image options of `options` (`intensity_attribute`; with
/// `intensity` set, a PLY without colours is not an error).
pub fn read_mesh_with(path: &Path, options: &LoadOptions) -> Result<FrameMesh, IoError> {
    let format = FrameFormat::of(path).ok_or_else(|| {
        IoError::format(
            path,
            "unknown mesh format (expected .obj, .ply, .gltf or .glb)",
        )
    })?;
    if options.intensity_attribute.is_some() && format != FrameFormat::Ply {
        return Err(IoError::format(
            path,
            "--intensity-attribute applies to PLY frames only",
        ));
    }
    read_frame(format, path, options, &TextureCache::default())
}

fn read_frame(
    format: FrameFormat,
    file: &Path,
    options: &LoadOptions,
    textures: &TextureCache,
) -> Result<FrameMesh, IoError> {
    match format {
        FrameFormat::Obj => {
            let obj = read_obj(file)?;
            let colors = match obj.colors {
                Some(colors) => Some(colors),
                None => texture_colors(&obj, file, textures)?,
            };
            Ok(FrameMesh {
                positions: obj.positions,
                faces: obj.faces,
                image: colors.map(VertexValues::Colors),
            })
        }
        FrameFormat::Ply => {
            let ply = read_ply(file)?;
            let untold = ply.colors.is_none() && options.intensity.is_none();
            let image = match &options.intensity_attribute {
                Some(name) => Some(VertexValues::Grey(ply_property(
                    ply.properties,
                    name,
                    file,
                )?)),
                None if untold && !ply.properties.is_empty() => {
                    // Without colours, a scalar property is most likely the grey value;
                    // one with fractional values rather than an integer id or label.
                    let names: Vec<&str> = ply.properties.iter().map(|(n, _)| n.as_str()).collect();
                    let likely = (ply.properties.iter())
                        .find(|(_, values)| values.iter().any(|v| v.fract() != 0.0))
                        .map_or(names[0], |(name, _)| name.as_str());
                    return Err(IoError::format(
                        file,
                        format!(
                            "no grey values: no vertex colours, but scalar vertex properties \
                             {}; use --intensity-attribute {likely} (or --intensity FILE.npy)",
                            names.join(", "),
                        ),
                    ));
                }
                None => ply.colors.map(VertexValues::Colors),
            };
            Ok(FrameMesh {
                positions: ply.positions,
                faces: ply.faces,
                image,
            })
        }
        FrameFormat::Gltf => read_gltf_frame(file),
    }
}

fn ply_property(
    properties: Vec<(String, Vec<f64>)>,
    name: &str,
    file: &Path,
) -> Result<Vec<f64>, IoError> {
    let names: Vec<String> = properties.iter().map(|(n, _)| n.clone()).collect();
    properties
        .into_iter()
        .find(|(n, _)| n == name)
        .map(|(_, values)| values)
        .ok_or_else(|| {
            IoError::format(
                file,
                match names.is_empty() {
                    true => format!("no vertex property '{name}' (the file has none besides positions and colours)"),
                    false => format!("no vertex property '{name}' (the file has: {})", names.join(", ")),
                },
            )
        })
}

fn is_about_times(error: &FlowError) -> bool {
    matches!(
        error,
        FlowError::NonIncreasingTimes { .. }
            | FlowError::NonFiniteTime { .. }
            | FlowError::CountMismatch {
                what: "frame times",
                ..
            }
    )
}

/// Attaches the file of the frame a sequence error names.
fn in_frame_file(error: FlowError, files: &[PathBuf]) -> Error {
    use crate::flow::FlowError::{Frame, NonFiniteIntensity};
    match &error {
        Frame { frame, .. } | NonFiniteIntensity { frame, .. } => {
            let file = files[*frame].clone();
            Error::from(error).in_file(file)
        }
        _ => error.into(),
    }
}

fn check_finite_positions(frames: &[Vec<Vector3<f64>>]) -> Result<(), FlowError> {
    for (frame, positions) in frames.iter().enumerate() {
        crate::geometry::check_finite_positions(positions)
            .map_err(|source| FlowError::Frame { frame, source })?;
    }
    Ok(())
}

/// Frames that differ in connectivity need tracking first: the hint every such error ends with.
const TRACK_HINT: &str =
    "frames meshed each on its own: run `meshflow track` on them first, then solve its output";

fn check_same_connectivity(first: &FrameMesh, frame: &FrameMesh, k: usize) -> Result<(), String> {
    // A file cut short while it was written or copied: its faces are the first of frame 0's,
    // or it stops before its faces.
    let (faces, all) = (frame.faces.len(), first.faces.len());
    let prefix = faces < all && frame.faces[..] == first.faces[..faces];
    let cut_in_vertices = faces == 0 && frame.positions.len() < first.positions.len();
    if prefix || cut_in_vertices {
        return Err(format!(
            "frame {k} looks truncated: it has {} vertices and {faces} faces, the first {faces} \
             of frame 0's {all} faces (frame 0 has {} vertices); the file was probably cut short",
            frame.positions.len(),
            first.positions.len()
        ));
    }
    if frame.positions.len() != first.positions.len() {
        return Err(format!(
            "frame {k} has {} vertices, frame 0 has {} ({TRACK_HINT})",
            frame.positions.len(),
            first.positions.len()
        ));
    }
    if frame.faces != first.faces {
        let face = frame
            .faces
            .iter()
            .zip(&first.faces)
            .position(|(a, b)| a != b)
            .unwrap_or(first.faces.len().min(frame.faces.len()));
        return Err(format!(
            "frame {k} has different faces than frame 0 (first difference at face {face}; {} vs \
             {} faces; {TRACK_HINT})",
            frame.faces.len(),
            first.faces.len()
        ));
    }
    Ok(())
}

/// What a `--intensity` array of mesh vertices is called in messages.
const MESH_VERTICES: &str =
    "vertices of the mesh, welded and cleaned, as load_sequence returns them";

/// Frame times from a `times.txt`, if there is one.
pub fn read_times_file(path: &Path) -> Result<Option<Vec<f64>>, IoError> {
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        _ => {}
    }
    // A regular file within the memory limit: a FIFO or device would never end.
    let bytes = crate::format::read_file(path)?;
    let text = std::str::from_utf8(&bytes).map_err(|_| IoError::format(path, "not UTF-8 text"))?;
    let mut times = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let content = line.split('#').next().unwrap_or_default();
        for token in content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let time = parse_time(token).map_err(|m| IoError::at_line(path, (number + 1, m)))?;
            times.push(time);
        }
    }
    Ok(Some(times))
}

/// One time of a times file: a finite number (NaN, infinities and overflowing values such as
/// 1e400 would order the frames arbitrarily).
fn parse_time(token: &str) -> Result<f64, String> {
    let shown: String = token.chars().take(40).collect();
    match token.parse::<f64>() {
        Ok(time) if time.is_finite() => Ok(time),
        Ok(_) => Err(format!("'{shown}' is not a finite time")),
        Err(_) => Err(format!("'{shown}' is not a number")),
    }
}
