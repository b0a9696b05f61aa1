//! Writing a computed flow: NPY arrays, ParaView files, a glTF animation and a JSON summary.
//!
//! NPY arrays are in the **files' vertex numbering** (`V_file` rows, through the
//! [`crate::load::VertexMap`]): welded copies repeat their mesh vertex's value, vertices the loader
//! dropped are NaN, a file vertex split by `--repair` has the value of its first piece. VTU and
//! glTF files are meshes and hold the `V` mesh vertices.
//!
//! | file | contents |
//! |---|---|
//! | `flow.npy` | (S, V_file, 3) float64: R^3 flow vectors of slab `s` at the vertices of frame `s`, one row per vertex of the input files (NaN for dropped vertices) |
//! | `flow_intrinsic.npy` | (S, V_file, 2) float64: components in the vertex frames |
//! | `velocity.npy` | (S, V_file, 3) float64: the material's velocity, the mesh's own motion over the slab plus the flow ([`crate::flow::tissue_velocity`]); the flow alone is relative to the mesh, which a tracked or animated mesh may also slide |
//! | `no_data.npy` | (S, V_file) uint8, when the image came with a no-data mask (`meshflow sample` writes one where a vertex's shell left the recording): 1 where frame `s` or `s+1` has no data at the vertex, so the slab's flow there is the regularizer's continuation of its surroundings, not a measurement; also the VTU point data `no_data` and grey in pictures |
//! | `vertex_map.npy` | (V_file,) int64: mesh vertex of each file vertex, −1 if dropped; only when that is not the identity |
//! | `angular_error.npy`, `endpoint_error.npy`, `direction_error.npy` | (S, V_file) float64, with a ground truth: per-vertex AE (degrees, on displacements in mean edge lengths), EPE (velocity units) and direction error (degrees, NaN where the truth does not move) ([`crate::accuracy`]) |
//! | `flow_SSSS.vtu`, `flow.pvd` | ParaView: frame `s` (mesh vertices) with point data `flow`, `velocity`, `flow_intrinsic`, `speed`, `intensity` (the mean of the channels for a colour or multi-channel image, whose channels are `image`; and `angular_error`, `endpoint_error`, `direction_error` with a ground truth; `warped_residual` with warping); the `.pvd` plays the slabs at their start times |
//! | `flow.glb` | the frames as a morph-target animation, coloured by the flow as `flow_SSSS.png` shows it (Middlebury colour of the direction seen from the given [`View`], scaled by a robust maximum speed) |
//! | `track_errors.csv`, `track_errors.vtu` | with tracked points (`--ground-truth-tracks`): every scored point's true and computed displacement and errors ([`super::write_track_errors`]) |
//! | `summary.json` | energy and its terms, residual, iterations, image `channels`, solver with the reason for it (`solver_reason`) and its `time_levels`, sizes, input, timings, dropped vertices and warnings, the `view` of the pictures and colours; the parameters as given (`params`, each weight `{"value": x}` or `{"relative": x}`), the weights used (`weights`: α, β, γ in the data's units) and the data's scales that resolved them (`scales`); with a ground truth, `ground_truth`: its file, the space-time means (AE, direction error, relative EPE, speed ratio, EPE) and maxima, per slab the same, and `zero_flow`, the zero flow's scores; with tracked points (`--ground-truth-tracks`), `ground_truth_tracks`: its file, points, moving points, mean and median endpoint error of the flow and of the zero flow (`zero_mean_endpoint`, …), `endpoint_ratio`, mean and median direction error, median speed ratio, median distance of the points from the surface, and the same per slab |
//!
//! Slab `s` spans `[t_s, t_{s+1}]`; `S = K − 1` slabs for `K` frames.
//!
//! A flow computed from arrays (the Python package) has no input file to read again; its run
//! also holds the sequence, in the files' numbering ([`write_run_input`]: `positions.npy`,
//! `faces.npy`, `intensity.npy`, `times.txt`), and records `meshflow solve OUT --out OUT`, so
//! that `meshflow advect OUT` finds its input in the run itself.

use super::StagedDir;
use crate::accuracy::{FlowErrors, TrackScores, TrackSummary};
use crate::flow::{FlowParams, FlowResult, MeshSequence};
use crate::format::gltf::{write_glb_animation, AnimationFrame};
use crate::format::vtk::{write_pvd, write_vtu_with_cells, NamedArray, PointArray};
use crate::format::{write_atomically, write_no_data, write_npy, IoError, NpyRows, NO_DATA};
use crate::load::{LoadWarning, LoadedSequence, VertexMap};
use crate::render::color_wheel::robust_max;
use crate::render::{screen_flow_colors, Camera, View};
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;
use std::borrow::Cow;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// The file groups [`write_flow_outputs`] can write; `summary.json` is always written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// `flow.npy`, `flow_intrinsic.npy` (and `vertex_map.npy`).
    Npy,
    /// `flow_SSSS.vtu` and `flow.pvd`.
    Vtu,
    /// `flow.glb`.
    Glb,
}

impl OutputFormat {
    pub const ALL: [OutputFormat; 3] = [Self::Npy, Self::Vtu, Self::Glb];
}

impl FromStr for OutputFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "npy" => Ok(Self::Npy),
            "vtu" | "vtk" | "paraview" => Ok(Self::Vtu),
            "glb" | "gltf" => Ok(Self::Glb),
            other => Err(format!("unknown output format '{other}' (npy, vtu, glb)")),
        }
    }
}

/// The computed flow measured against a known one, written with the outputs.
#[derive(Clone, Debug)]
pub struct GroundTruthReport {
    /// Where the true flow came from.
    pub file: PathBuf,
    pub errors: FlowErrors,
    /// The zero flow's scores against the same truth: the baseline.
    pub zero_flow: FlowErrors,
}

/// The computed flow scored at tracked points (cells, beads, landmarks).
#[derive(Clone, Debug)]
pub struct TrackReport {
    /// Where the tracks came from.
    pub file: PathBuf,
    pub scores: TrackScores,
}

/// What a flow is scored against, written with the outputs: a known flow, tracked points.
#[derive(Clone, Copy, Debug, Default)]
pub struct Scores<'a> {
    pub flow: Option<&'a GroundTruthReport>,
    pub tracks: Option<&'a TrackReport>,
}

/// Writes the outputs of `result` for `loaded` into `out` (see the module table), with the
/// errors against a ground truth when there is one; `flow.glb` is coloured as pictures from
/// `view` show the flow (e.g. `UpChoice::of_sequence(loaded).view()`), and
/// `summary.json` records `view`.
pub fn write_flow_outputs(
    out: &StagedDir,
    loaded: &LoadedSequence,
    params: &FlowParams,
    result: &FlowResult,
    formats: &[OutputFormat],
    scores: Scores,
    view: &View,
) -> Result<(), IoError> {
    write_all(out.path(), loaded, params, result, formats, scores, view)
        .map_err(|e| out.in_target(e))
}

fn write_all(
    dir: &Path,
    loaded: &LoadedSequence,
    params: &FlowParams,
    result: &FlowResult,
    formats: &[OutputFormat],
    scores: Scores,
    view: &View,
) -> Result<(), IoError> {
    let sequence = &loaded.sequence;
    let errors = scores.flow.map(|g| &g.errors);
    let embedded = result.vectors.is_some();
    let mesh = (&loaded.vertex_map, sequence.mesh().faces());
    let mut files = SlabFiles::create(dir, mesh, formats, sequence.n_slabs(), embedded)?;
    let no_data = loaded.slab_no_data();
    let slabs: Vec<SlabOutput> = (0..sequence.n_slabs())
        .map(|s| SlabOutput {
            no_data: no_data.as_ref().map(|mask| Cow::Borrowed(&mask[s][..])),
            ..SlabOutput::of_result(sequence, s, result, s, errors)
        })
        .collect();
    // The binary glTF beside the slabs' files, on the other threads.
    let glb = embedded && formats.contains(&OutputFormat::Glb);
    let mut glb_written = Ok(());
    let max_speed = rayon::in_place_scope(|scope| {
        if glb {
            let glb_written = &mut glb_written;
            scope.spawn(move |_| {
                *glb_written = write_flow_glb(&dir.join("flow.glb"), sequence, result, view)
            });
        }
        files.add_all(&slabs).and_then(|()| files.finish())
    })?;
    glb_written?;
    if let (true, Some(no_data)) = (formats.contains(&OutputFormat::Npy), &no_data) {
        let rows: Vec<Vec<bool>> = no_data
            .iter()
            .map(|m| loaded.vertex_map.file_rows(m, false))
            .collect();
        write_no_data(&dir.join(NO_DATA), &rows)?;
    }
    if let (true, Some(errors)) = (formats.contains(&OutputFormat::Npy), errors) {
        write_error_npy(dir, &loaded.vertex_map, errors)?;
    }
    if let Some(tracks) = scores.tracks {
        let vtu = formats.contains(&OutputFormat::Vtu);
        super::write_track_errors(dir, &tracks.scores, vtu)?;
    }
    let facts = SequenceFacts::of(sequence, &loaded.warnings, max_speed);
    write_summary(
        dir,
        summary_of(&facts, loaded, params, result, scores),
        view,
    )
}

/// `summary.json`: `summary` with the `view` of the pictures.
pub(super) fn write_summary(
    dir: &Path,
    mut summary: serde_json::Value,
    view: &View,
) -> Result<(), IoError> {
    summary["view"] = serde_json::to_value(view).expect("views serialize");
    write_atomically(&dir.join("summary.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &summary).map_err(std::io::Error::other)?;
        writeln!(w)
    })
}

/// One slab's outputs: its first frame (time, positions, image) and its flow there. Borrowed
/// from a whole result ([`SlabOutput::of_result`]) or owned, as received from the rank that
/// computed it ([`super::flow_over_ranks`]).
#[derive(Clone, Debug)]
pub(super) struct SlabOutput<'a> {
    pub time: f64,
    pub positions: Option<Cow<'a, [Vector3<f64>]>>,
    /// The grey value ([`MeshSequence::intensities`]) and, with several, the channels.
    pub intensity: Cow<'a, [f64]>,
    pub channels: Option<Cow<'a, [Vec<f64>]>>,
    pub intrinsic: Cow<'a, [Vector2<f64>]>,
    pub vectors: Option<Cow<'a, [Vector3<f64>]>>,
    pub velocity: Option<Vec<Vector3<f64>>>,
    pub warped_residual: Option<Cow<'a, [f64]>>,
    /// Against a ground truth: angular, endpoint and direction errors.
    pub errors: Option<[&'a [f64]; 3]>,
    /// Vertices without data in the slab ([`LoadedSequence::slab_no_data`]).
    pub no_data: Option<Cow<'a, [bool]>>,
}

impl<'a> SlabOutput<'a> {
    /// Frame `k` of `sequence` alone (no flow): its time, positions and image.
    pub fn frame(sequence: &'a MeshSequence, k: usize) -> Self {
        SlabOutput {
            time: sequence.times()[k],
            positions: sequence.positions(k).map(Cow::Borrowed),
            intensity: Cow::Borrowed(sequence.intensities(k)),
            channels: (sequence.n_channels() > 1).then(|| Cow::Borrowed(sequence.channels(k))),
            intrinsic: Cow::Borrowed(&[]),
            vectors: None,
            velocity: None,
            warped_residual: None,
            errors: None,
            no_data: None,
        }
    }

    /// Slab `slab` of `result` (its `slab`-th slab), on frame `frame` of `sequence`.
    pub fn of_result(
        sequence: &'a MeshSequence,
        frame: usize,
        result: &'a FlowResult,
        slab: usize,
        errors: Option<&'a FlowErrors>,
    ) -> Self {
        let vectors = result.vectors.as_ref().map(|v| v[slab].as_slice());
        let residual = result.warped_residual.as_ref();
        SlabOutput {
            intrinsic: Cow::Borrowed(&result.intrinsic[slab]),
            vectors: vectors.map(Cow::Borrowed),
            velocity: vectors.map(|u| crate::flow::slab_velocity(sequence, frame, u)),
            warped_residual: residual.map(|r| Cow::Borrowed(&r[slab][..])),
            errors: errors.map(|e| {
                [
                    &e.angular_degrees[slab],
                    &e.endpoint[slab],
                    &e.direction_degrees[slab],
                ]
                .map(Vec::as_slice)
            }),
            ..Self::frame(sequence, frame)
        }
    }

    fn max_speed(&self) -> f64 {
        max_speed(&self.intrinsic, self.vectors.as_deref())
    }

    /// The image's channels (the grey values when there is one).
    pub fn channels_or_grey(&self) -> Vec<Vec<f64>> {
        match &self.channels {
            Some(channels) => channels.to_vec(),
            None => vec![self.intensity.to_vec()],
        }
    }

    /// The point arrays of its `flow_SSSS.vtu` (see the module table).
    fn vtu_arrays(&self, vectors: &[Vector3<f64>], velocity: &[Vector3<f64>]) -> Vec<NamedArray> {
        let speed: Vec<f64> = vectors.iter().map(|u| u.norm()).collect();
        let mut arrays = vec![
            NamedArray::vectors("flow", vectors),
            NamedArray::vectors("velocity", velocity),
            NamedArray::vectors2("flow_intrinsic", &self.intrinsic),
            NamedArray::scalars("speed", &speed),
            NamedArray::scalars("intensity", &self.intensity),
        ];
        if let Some(channels) = &self.channels {
            arrays.push(NamedArray::channels("image", channels));
        }
        if let Some(residual) = &self.warped_residual {
            arrays.push(NamedArray::scalars("warped_residual", residual));
        }
        if let Some(no_data) = &self.no_data {
            let flags: Vec<f64> = no_data.iter().map(|&m| m as u8 as f64).collect();
            arrays.push(NamedArray::scalars("no_data", &flags));
        }
        if let Some([angular, endpoint, direction]) = self.errors {
            arrays.extend([
                NamedArray::scalars("angular_error", angular),
                NamedArray::scalars("endpoint_error", endpoint),
                NamedArray::scalars("direction_error", direction),
            ]);
        }
        arrays
    }
}

/// The largest speed of a slab's flow: of its R³ vectors, or of the intrinsic flow without them.
fn max_speed(intrinsic: &[Vector2<f64>], vectors: Option<&[Vector3<f64>]>) -> f64 {
    match vectors {
        Some(vectors) => vectors.iter().map(|u| u.norm()).fold(0.0, f64::max),
        None => intrinsic.iter().map(|u| u.norm()).fold(0.0, f64::max),
    }
}

/// The per-slab files of a flow, filled slab by slab in order: the rows of `flow_intrinsic.npy`,
/// `flow.npy` and `velocity.npy`, one `flow_SSSS.vtu` per slab, and at the end `flow.pvd` and
/// `vertex_map.npy`. No slab is kept after it is written.
pub(super) struct SlabFiles<'a> {
    dir: &'a Path,
    map: &'a VertexMap,
    faces: &'a [[u32; 3]],
    /// `flow_intrinsic.npy`, and for an embedded sequence `flow.npy` and `velocity.npy`.
    npy: Option<(NpyRows, Option<[NpyRows; 2]>)>,
    vtu: bool,
    datasets: Vec<(f64, String)>,
    max_speed: f64,
}

impl<'a> SlabFiles<'a> {
    pub fn create(
        dir: &'a Path,
        (map, faces): (&'a VertexMap, &'a [[u32; 3]]),
        formats: &[OutputFormat],
        n_slabs: usize,
        embedded: bool,
    ) -> Result<Self, IoError> {
        let (s, v) = (n_slabs as u64, map.n_file_vertices() as u64);
        let npy = match formats.contains(&OutputFormat::Npy) {
            true => Some((
                NpyRows::create(&dir.join("flow_intrinsic.npy"), &[s, v, 2])?,
                match embedded {
                    true => Some([
                        NpyRows::create(&dir.join("flow.npy"), &[s, v, 3])?,
                        NpyRows::create(&dir.join("velocity.npy"), &[s, v, 3])?,
                    ]),
                    false => None,
                },
            )),
            false => None,
        };
        Ok(SlabFiles {
            dir,
            map,
            faces,
            npy,
            vtu: embedded && formats.contains(&OutputFormat::Vtu),
            datasets: Vec::with_capacity(n_slabs),
            max_speed: 0.0,
        })
    }

    /// Slab `s`, the one after the last added.
    pub fn add(&mut self, s: usize, slab: &SlabOutput) -> Result<(), IoError> {
        self.add_rows(slab)?;
        if let Some(dataset) = self.vtu.then(|| slab_vtu(self.dir, self.faces, s, slab)) {
            self.datasets.extend(dataset?);
        }
        Ok(())
    }

    /// All slabs, from the first: their NPY rows in order, their VTU files in parallel (one
    /// file per slab, each on its own thread; the paper-size torus writes 19 of 13 MB).
    pub fn add_all(&mut self, slabs: &[SlabOutput]) -> Result<(), IoError> {
        slabs.iter().try_for_each(|slab| self.add_rows(slab))?;
        if self.vtu {
            let (dir, faces) = (self.dir, self.faces);
            let datasets: Vec<Option<(f64, String)>> = (slabs.par_iter().enumerate())
                .map(|(s, slab)| slab_vtu(dir, faces, s, slab))
                .collect::<Result<_, _>>()?;
            self.datasets.extend(datasets.into_iter().flatten());
        }
        Ok(())
    }

    /// The slab's rows of the NPY arrays, and its speed.
    fn add_rows(&mut self, slab: &SlabOutput) -> Result<(), IoError> {
        self.max_speed = self.max_speed.max(slab.max_speed());
        let map = self.map;
        if let Some((intrinsic, vectors)) = &mut self.npy {
            let rows = map.file_rows(&slab.intrinsic, Vector2::repeat(f64::NAN));
            intrinsic.extend(rows.iter().flat_map(|u| [u.x, u.y]))?;
            if let (Some(files), Some(u), Some(v)) = (vectors, &slab.vectors, &slab.velocity) {
                for (file, values) in files.iter_mut().zip([&u[..], &v[..]]) {
                    let rows = map.file_rows(values, Vector3::repeat(f64::NAN));
                    file.extend(rows.iter().flat_map(|u| [u.x, u.y, u.z]))?;
                }
            }
        }
        Ok(())
    }

    /// Closes the files; the largest speed of all slabs.
    pub fn finish(self) -> Result<f64, IoError> {
        if let Some((intrinsic, vectors)) = self.npy {
            intrinsic.finish()?;
            for file in vectors.into_iter().flatten() {
                file.finish()?;
            }
            if !self.map.is_identity() {
                let table = self.map.to_npy();
                let path = self.dir.join("vertex_map.npy");
                write_npy(&path, &[table.len() as u64], &table)?;
            }
        }
        if self.vtu {
            write_pvd(&self.dir.join("flow.pvd"), &self.datasets)?;
        }
        Ok(self.max_speed)
    }
}

/// `flow_SSSS.vtu` of slab `s` in `dir`, where the slab has positions and vectors: its time
/// and file name for the PVD.
fn slab_vtu(
    dir: &Path,
    faces: &[[u32; 3]],
    s: usize,
    slab: &SlabOutput,
) -> Result<Option<(f64, String)>, IoError> {
    match (&slab.positions, &slab.vectors, &slab.velocity) {
        (Some(positions), Some(u), Some(v)) => {
            let arrays = slab.vtu_arrays(u, v);
            let file = write_slab_vtu(dir, "flow", s, positions, faces, &arrays, &[])?;
            Ok(Some((slab.time, file)))
        }
        _ => Ok(None),
    }
}

/// `angular_error.npy`, `endpoint_error.npy` and `direction_error.npy`, (S, V_file).
fn write_error_npy(dir: &Path, map: &VertexMap, errors: &FlowErrors) -> Result<(), IoError> {
    for (name, values) in [
        ("angular_error.npy", &errors.angular_degrees),
        ("endpoint_error.npy", &errors.endpoint),
        ("direction_error.npy", &errors.direction_degrees),
    ] {
        let shape = [values.len() as u64, map.n_file_vertices() as u64];
        let rows: Vec<f64> = values
            .iter()
            .flat_map(|slab| map.file_rows(slab, f64::NAN))
            .collect();
        write_npy(&dir.join(name), &shape, &rows)?;
    }
    Ok(())
}

/// A sequence's slabs for ParaView: `NAME_SSSS.vtu` with the positions of frame `s`, the mesh's
/// triangles and the point arrays `arrays(s)`, for every slab `s`, and `NAME.pvd` playing them
/// at the slab start times. The sequence must be embedded.
pub fn write_slab_vtus(
    dir: &Path,
    name: &str,
    sequence: &MeshSequence,
    mut arrays: impl FnMut(usize) -> Vec<NamedArray>,
) -> Result<(), IoError> {
    write_slab_vtus_with_cells(dir, name, sequence, |s| (arrays(s), Vec::new()))
}

/// [`write_slab_vtus`] with per-triangle arrays: `arrays(s)` gives slab `s`'s point arrays and
/// cell arrays.
pub fn write_slab_vtus_with_cells(
    dir: &Path,
    name: &str,
    sequence: &MeshSequence,
    mut arrays: impl FnMut(usize) -> (Vec<NamedArray>, Vec<NamedArray>),
) -> Result<(), IoError> {
    let mut datasets = Vec::with_capacity(sequence.n_slabs());
    for s in 0..sequence.n_slabs() {
        let positions = sequence.positions(s).ok_or_else(|| {
            IoError::format(
                dir.join(format!("{name}_{s:04}.vtu")),
                "an intrinsic sequence has no positions to write",
            )
        })?;
        let (points, cells) = arrays(s);
        let faces = sequence.mesh().faces();
        let file = write_slab_vtu(dir, name, s, positions, faces, &points, &cells)?;
        datasets.push((sequence.times()[s], file));
    }
    write_pvd(&dir.join(format!("{name}.pvd")), &datasets)
}

/// `NAME_SSSS.vtu` of slab `s`; its file name.
fn write_slab_vtu(
    dir: &Path,
    name: &str,
    s: usize,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    points: &[NamedArray],
    cells: &[NamedArray],
) -> Result<String, IoError> {
    let file = format!("{name}_{s:04}.vtu");
    let point_data: Vec<PointArray> = points.iter().map(NamedArray::as_point_array).collect();
    let cell_data: Vec<PointArray> = cells.iter().map(NamedArray::as_point_array).collect();
    write_vtu_with_cells(&dir.join(&file), positions, faces, &point_data, &cell_data)?;
    Ok(file)
}

/// All frames as a morph animation; frame `k` is coloured by slab `min(k, S − 1)` with the
/// colours of `flow_SSSS.png` ([`screen_flow_colors`] seen from `view`, scaled by the robust
/// maximum speed): a surface has no global tangent frame, so a view is what makes hues
/// comparable between vertices.
fn write_flow_glb(
    path: &Path,
    sequence: &MeshSequence,
    result: &FlowResult,
    view: &View,
) -> Result<(), IoError> {
    let vectors = result.vectors.as_ref().expect("embedded sequence");
    let all_positions: Vec<Vector3<f64>> = (0..sequence.n_frames())
        .flat_map(|k| {
            sequence
                .positions(k)
                .expect("embedded sequence")
                .iter()
                .copied()
        })
        .collect();
    let camera = Camera::framing(&all_positions, *view, 960, 720);
    let speeds: Vec<f64> = vectors.iter().flatten().map(|u| u.norm()).collect();
    let scale = robust_max(&speeds);
    let colors: Vec<Vec<[f64; 3]>> = vectors
        .iter()
        .map(|v| screen_flow_colors(&camera, v, scale))
        .collect();
    let frames: Vec<AnimationFrame> = (0..sequence.n_frames())
        .map(|k| AnimationFrame {
            time: sequence.times()[k],
            positions: sequence.positions(k).expect("embedded sequence"),
            colors: &colors[k.min(colors.len() - 1)],
        })
        .collect();
    write_glb_animation(path, sequence.mesh().faces(), &frames)
}

/// What `summary.json` says about the whole sequence and its flow beyond the result's own
/// figures: what a writer that streams the slabs learns as they pass
/// ([`super::write_flow_over_ranks`]), a whole sequence at once ([`SequenceFacts::of`]).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct SequenceFacts {
    pub n_frames: usize,
    pub n_vertices: usize,
    pub n_faces: usize,
    pub n_channels: usize,
    pub times: Vec<f64>,
    pub warnings: Vec<String>,
    pub max_speed: f64,
}

impl SequenceFacts {
    pub fn of(sequence: &MeshSequence, warnings: &[LoadWarning], max_speed: f64) -> Self {
        SequenceFacts {
            n_frames: sequence.n_frames(),
            n_vertices: sequence.mesh().n_vertices(),
            n_faces: sequence.mesh().n_faces(),
            n_channels: sequence.n_channels(),
            times: sequence.times().to_vec(),
            warnings: warnings.iter().map(ToString::to_string).collect(),
            max_speed,
        }
    }
}

/// The summary written next to the flow.
pub fn summary_json(
    loaded: &LoadedSequence,
    params: &FlowParams,
    result: &FlowResult,
    scores: Scores,
) -> serde_json::Value {
    let vectors = |s: usize| result.vectors.as_ref().map(|v| v[s].as_slice());
    let max_speed = (result.intrinsic.iter().enumerate())
        .map(|(s, intrinsic)| max_speed(intrinsic, vectors(s)))
        .fold(0.0, f64::max);
    let facts = SequenceFacts::of(&loaded.sequence, &loaded.warnings, max_speed);
    summary_of(&facts, loaded, params, result, scores)
}

/// [`summary_json`] with the whole sequence's `facts`.
pub(super) fn summary_of(
    facts: &SequenceFacts,
    loaded: &LoadedSequence,
    params: &FlowParams,
    result: &FlowResult,
    scores: Scores,
) -> serde_json::Value {
    let files: Vec<String> = loaded
        .source
        .files()
        .iter()
        .map(|f| f.to_string_lossy().into_owned())
        .collect();
    let mut summary = serde_json::json!({
        "input": loaded.source.describe(),
        "input_files": files,
        "welded_vertices": loaded.vertex_map.n_welded(),
        "dropped_vertices": loaded.vertex_map.n_dropped(),
        "warnings": facts.warnings,
        "energy": result.energy,
        "energy_terms": result.energy_terms,
        "energy_at_zero": result.energy_at_zero,
        "relative_residual": result.relative_residual,
        "iterations": result.iterations,
        "reweightings": result.reweightings,
        "solver": result.method,
        "solver_reason": result.solver_reason,
        "time_levels": result.time_levels,
        "factor_entries": result.factor_entries,
        "subnormal_factor_entries": result.subnormal_factor_entries,
        "preconditioned_spectrum": result.preconditioned_spectrum,
        "frames": facts.n_frames,
        "slabs": facts.n_frames - 1,
        "vertices": facts.n_vertices,
        "faces": facts.n_faces,
        "channels": facts.n_channels,
        "times": facts.times,
        "max_speed": facts.max_speed,
        "params": params,
        "weights": result.weights,
        "scales": result.scales,
        "seconds": result.timings,
    });
    if !result.anisotropic_contrasts.is_empty() {
        summary["anisotropic_contrasts"] = serde_json::json!(result.anisotropic_contrasts);
    }
    if !result.robust_data_scales.is_empty() {
        summary["robust_data_scales"] = serde_json::json!(result.robust_data_scales);
    }
    if let Some(check) = &result.motion_check {
        summary["large_motion"] = serde_json::json!(check);
    }
    if !result.robust_scales.is_empty() {
        summary["robust_scales"] = serde_json::json!(result.robust_scales);
    }
    if let Some(ground_truth) = scores.flow {
        summary["ground_truth"] = ground_truth_json(ground_truth);
    }
    if let Some(tracks) = scores.tracks {
        summary["ground_truth_tracks"] = tracks_json(tracks);
    }
    summary
}

/// `ground_truth_tracks`: the file and [`track_scores_json`].
fn tracks_json(report: &TrackReport) -> serde_json::Value {
    let mut json = track_scores_json(&report.scores);
    json["file"] = report.file.to_string_lossy().into();
    json
}

/// The scores at tracked points, overall and per slab (`slabs`), beside the zero flow's
/// ([`crate::accuracy::TrackSummary`] defines them); undefined ones (no point moved) as `null`.
pub fn track_scores_json(scores: &TrackScores) -> serde_json::Value {
    let summary = |s: &TrackSummary| {
        // serde_json writes NaN as null.
        let mut json = serde_json::to_value(s).expect("summaries serialize");
        json["endpoint_ratio"] = finite_or_null(s.endpoint_ratio());
        json
    };
    let mut json = summary(&scores.overall);
    json["slabs"] = scores.slabs.iter().map(summary).collect();
    json
}

/// The scores of the computed flow and of the zero flow, overall and per slab
/// ([`crate::accuracy`] defines them).
fn ground_truth_json(ground_truth: &GroundTruthReport) -> serde_json::Value {
    let errors = &ground_truth.errors;
    let slabs: Vec<serde_json::Value> = errors
        .slabs
        .iter()
        .map(|slab| {
            serde_json::json!({
                "duration": slab.duration,
                "area": slab.area,
                "edge_length": slab.edge_length,
                "mean_angular_error_degrees": slab.mean_angular_degrees,
                "mean_direction_error_degrees": finite_or_null(slab.mean_direction_degrees),
                "relative_endpoint_error": finite_or_null(slab.relative_endpoint),
                "mean_endpoint_error": slab.mean_endpoint,
                "max_angular_error_degrees": slab.max_angular_degrees,
                "max_endpoint_error": slab.max_endpoint,
            })
        })
        .collect();
    let mut json = error_summary_json(errors);
    json["file"] = ground_truth.file.to_string_lossy().into();
    json["slabs"] = slabs.into();
    json["zero_flow"] = error_summary_json(&ground_truth.zero_flow);
    json
}

/// The space-time summaries of one comparison; undefined ones (nothing moves) as `null`.
fn error_summary_json(errors: &FlowErrors) -> serde_json::Value {
    serde_json::json!({
        "mean_angular_error_degrees": errors.mean_angular_degrees,
        "mean_direction_error_degrees": finite_or_null(errors.mean_direction_degrees),
        "relative_endpoint_error": finite_or_null(errors.relative_endpoint),
        "median_speed_ratio": finite_or_null(errors.median_speed_ratio),
        "moving_fraction": errors.moving_fraction,
        "mean_endpoint_error": errors.mean_endpoint,
        "max_angular_error_degrees": errors.max_angular_degrees,
        "max_endpoint_error": errors.max_endpoint,
    })
}

fn finite_or_null(x: f64) -> serde_json::Value {
    match x.is_finite() {
        true => x.into(),
        false => serde_json::Value::Null,
    }
}

/// Writes `loaded`'s sequence into `dir` as an NPY sequence in the files' numbering:
/// positions of the file vertices (welded copies at their mesh vertex, dropped vertices at the
/// origin: they stay unused), the faces over each mesh vertex's representative file vertex, the
/// grey values and `times.txt`. Read again, it gives the same mesh, and the run's
/// `flow_intrinsic.npy` rows fit it.
pub fn write_run_input(dir: &Path, loaded: &LoadedSequence) -> Result<(), IoError> {
    let (sequence, map) = (&loaded.sequence, &loaded.vertex_map);
    let frames = 0..sequence.n_frames();
    let positions: Vec<Vec<Vector3<f64>>> = frames
        .clone()
        .map(|k| {
            let mesh_positions = sequence.positions(k).ok_or_else(|| {
                IoError::format(dir, "a sequence of edge lengths has no positions to write")
            })?;
            Ok(map.file_rows(mesh_positions, Vector3::zeros()))
        })
        .collect::<Result<_, IoError>>()?;
    let faces = map.file_faces(sequence.mesh().faces());
    let grey: Vec<Vec<f64>> = frames
        .map(|k| map.file_rows(sequence.intensities(k), 0.0))
        .collect();
    crate::format::write_npy_sequence(dir, &positions, &faces, Some(&grey), sequence.times())
}
