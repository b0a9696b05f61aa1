//! Reading a finished solve back: its input, loaded as the solve loaded it, and its flow.
//!
//! A solve records in its manifest what it read and how ([`SolveRecord`]: the input and the
//! [`LoadOptions`]), its paths relative to the run directory itself. A later command
//! (`advect`, `analyze`, Python) treats that record as untrusted, like a file named inside
//! another file ([`crate::format::resolve_linked`]): an absolute path, or a record whose paths
//! are relative to some other directory (an earlier version's), is read only with
//! `--allow-external-files`; and every file it then reads outside the run must be one the run
//! fingerprinted, unchanged ([`SolveInput::of_run`], [`RunManifest::check_inputs`]), so an
//! edited manifest can make it read neither elsewhere nor something else. Files inside the
//! run are read only as the run's own ([`run_file`]).

use super::guard::resolve;
use super::{RunManifest, RUN_MANIFEST};
use crate::flow::MeshSequence;
use crate::format::{quoted, read_npy_float, resolve_linked, IoError};
use crate::limits::{linked_files, LinkedFiles};
use crate::load::{load_sequence, LoadOptions, LoadedSequence};
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use std::path::{Component, Path, PathBuf};

/// What a solve read, as its manifest records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolveRecord {
    /// The input (relative to [`Self::relative_to`]); `None` when the run holds its input
    /// itself (a flow computed from arrays: [`super::write_run_input`]).
    pub input: Option<PathBuf>,
    /// How it was loaded (`--intensity` relative to [`Self::relative_to`], like `input`).
    pub load: LoadOptions,
    /// What relative paths are relative to (records of earlier versions: the solve's working
    /// directory).
    #[serde(default)]
    pub relative_to: RecordBase,
}

/// What the relative paths of a [`SolveRecord`] are relative to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RecordBase {
    /// The working directory of the solve ([`RunManifest::directory`]): paths as the user
    /// named them (earlier versions).
    #[default]
    WorkingDirectory,
    /// The run directory: the record stays true wherever the run is read from.
    Run,
}

impl SolveRecord {
    /// The record of a solve that named `input` and `load`'s paths from the current working
    /// directory, for the run that will be at `run`: its paths relative to the run.
    pub fn new(input: Option<&Path>, load: LoadOptions, run: &Path) -> Self {
        let run = resolve(run);
        let from_run = |path: &Path| relative_path(&run, &resolve(path));
        Self {
            input: input.map(from_run),
            load: LoadOptions {
                intensity: load.intensity.as_deref().map(from_run),
                ..load
            },
            relative_to: RecordBase::Run,
        }
    }
}

/// A finished solve's input, resolved: where it is now and how to load it.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveInput {
    pub input: PathBuf,
    pub load: LoadOptions,
}

impl SolveInput {
    /// The input of the solve whose output is `run`, from the record in its manifest.
    pub fn of_run(run: &Path) -> Result<Self, IoError> {
        let manifest = RunManifest::read_run(run)?;
        let Some(record) = manifest.solve.clone() else {
            let why = "its manifest records no solve: not the output of `meshflow solve`, \
                       or written by an earlier version (solve again)";
            return Err(IoError::format(run, why));
        };
        Self::resolve(run, &manifest, record)
    }

    /// `record` of the run `run` (whose manifest is `manifest`): relative paths against the
    /// run (or, for an earlier version's record and with `--allow-external-files`, the solve's
    /// working directory), and the files outside the run checked against what the run
    /// recorded of them ([`RunManifest::check_inputs`]) before anything else reads them.
    pub fn resolve(
        run: &Path,
        manifest: &RunManifest,
        record: SolveRecord,
    ) -> Result<Self, IoError> {
        let base = record_base(run, manifest, record.relative_to)?;
        let named = |field: &str, path: &Path| -> Result<PathBuf, IoError> {
            if path.is_absolute() && linked_files() == LinkedFiles::Contained {
                let why = format!(
                    "its {field} {} is an absolute path: a run names its inputs relative to \
                     itself (--allow-external-files reads it)",
                    quoted(&path.to_string_lossy())
                );
                return Err(IoError::format(run.join(RUN_MANIFEST), why));
            }
            Ok(base.join(path))
        };
        let mut load = record.load;
        let input = match record.input {
            None => {
                load.intensity = None;
                run.to_path_buf()
            }
            Some(input) => {
                load.intensity = match load.intensity {
                    Some(file) => Some(named("intensity", &file)?),
                    None => None,
                };
                named("solve input", &input)?
            }
        };
        let resolved = Self { input, load };
        let external = resolved.external_inputs(run);
        if !external.is_empty() {
            manifest.check_inputs(run, &external)?;
        }
        Ok(resolved)
    }

    /// The files outside `run` that its solve read.
    pub fn external_inputs(&self, run: &Path) -> Vec<&Path> {
        std::iter::once(self.input.as_path())
            .chain(self.load.intensity.as_deref())
            .filter(|path| *path != run)
            .collect()
    }

    /// The input loaded again, as the solve loaded it.
    pub fn load(&self) -> Result<LoadedSequence, crate::Error> {
        load_sequence(&self.input, &self.load)
    }
}

/// The microscope recording a sequence was sampled from (`meshflow sample` writes it into the
/// sequence directory's manifest): what a viewer needs to show the surface over it, in the
/// physical coordinates of the surface (`x = o + (i d_x, j d_y, k d_z)`, [`crate::volume`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordingRecord {
    /// The recording (NPY or TIFF file, directory of them, OME-Zarr store), relative to the
    /// sequence directory.
    pub path: PathBuf,
    /// The frames' `(n_z, n_y, n_x)` when sampled: a recording that no longer has it is not
    /// the one sampled.
    pub shape: [usize; 3],
    /// `(d_x, d_y, d_z)` as sampled (given, or from the files' metadata).
    pub voxel_size: [f64; 3],
    /// The centre of voxel `(0, 0, 0)`, an OME-Zarr image's own translation included.
    pub origin: [f64; 3],
    /// The channel of an OME-Zarr store or ImageJ hyperstack (`None`: 0).
    pub channel: Option<usize>,
    /// The OME-Zarr resolution level sampled (0: the finest).
    pub resolution_level: usize,
}

impl RecordingRecord {
    /// `recording` (named from the current working directory) as the manifest of the sequence
    /// directory `sequence` records it: relative to `sequence`.
    pub fn path_from(sequence: &Path, recording: &Path) -> PathBuf {
        relative_path(&resolve(sequence), &resolve(recording))
    }

    /// The recording `sequence`'s manifest names, where it is now: relative to `sequence`, an
    /// absolute path only with `--allow-external-files` (a record is untrusted, like a solve
    /// record); `None` when the manifest names none.
    pub fn of_sequence(sequence: &Path) -> Result<Option<(PathBuf, Self)>, IoError> {
        let manifest = RunManifest::read_run(sequence)?;
        let Some(record) = manifest.recording else {
            return Ok(None);
        };
        if record.path.is_absolute() && linked_files() == LinkedFiles::Contained {
            let why = format!(
                "its recording {} is an absolute path: a sequence names its recording relative \
                 to itself (--allow-external-files reads it)",
                quoted(&record.path.to_string_lossy())
            );
            return Err(IoError::format(sequence.join(RUN_MANIFEST), why));
        }
        Ok(Some((sequence.join(&record.path), record)))
    }
}

/// The directory a record's relative paths start from: the run, or for an earlier version's
/// record (relative to the solve's working directory, which the manifest itself names) that
/// directory, only with `--allow-external-files`.
fn record_base(run: &Path, manifest: &RunManifest, base: RecordBase) -> Result<PathBuf, IoError> {
    match (base, linked_files(), &manifest.directory) {
        (RecordBase::Run, _, _) => Ok(run.to_path_buf()),
        (RecordBase::WorkingDirectory, LinkedFiles::Anywhere, Some(directory)) => {
            Ok(directory.clone())
        }
        (RecordBase::WorkingDirectory, LinkedFiles::Anywhere, None) => Ok(PathBuf::new()),
        (RecordBase::WorkingDirectory, LinkedFiles::Contained, _) => Err(IoError::format(
            run.join(RUN_MANIFEST),
            "records its solve's inputs relative to a working directory that it names itself \
             (an earlier meshflow wrote it, or it was edited): solve again, or \
             --allow-external-files to read them as recorded",
        )),
    }
}

/// The path that leads from the directory `from` to `to`, both absolute and without `.` or
/// `..` (as [`resolve`] gives them): `..` for each of `from`'s components past their common
/// start, then the rest of `to`.
fn relative_path(from: &Path, to: &Path) -> PathBuf {
    let (from, to): (Vec<Component>, Vec<Component>) =
        (from.components().collect(), to.components().collect());
    let common = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
    let up = std::iter::repeat_n(Component::ParentDir, from.len() - common);
    let path: PathBuf = up.chain(to[common..].iter().copied()).collect();
    match path.as_os_str().is_empty() {
        true => PathBuf::from("."),
        false => path,
    }
}

/// The file `name` of the run `run`, as the run's own: a regular file inside the run, also
/// after links are followed (a `flow_intrinsic.npy` or `no_data.npy` linked to a file outside
/// is refused; `--allow-external-files` follows such links).
pub fn run_file(run: &Path, name: &str) -> Result<PathBuf, IoError> {
    resolve_linked(&run.join(RUN_MANIFEST), "the run's file", name, name)
}

/// `flow_intrinsic.npy` of the run `run` whose input is `loaded`: `flow[s][i]`, slab `s` at
/// mesh vertex `i`, in vertex frames.
pub fn read_flow(run: &Path, loaded: &LoadedSequence) -> Result<Vec<Vec<Vector2<f64>>>, IoError> {
    let file = run_file(run, "flow_intrinsic.npy")?;
    let array = read_npy_float(&file)?;
    let map = &loaded.vertex_map;
    let (s, v) = (loaded.sequence.n_slabs(), map.n_file_vertices());
    if array.shape != [s as u64, v as u64, 2] {
        return Err(IoError::format(
            &file,
            format!(
                "shape {:?}, expected ({s}, {v}, 2) for the run's input (was it changed since?)",
                array.shape
            ),
        ));
    }
    if let Some(at) = array.data.iter().position(|v| !v.is_finite()) {
        let (slab, vertex) = (at / (2 * v), at / 2 % v);
        let why = format!(
            "slab {slab}, vertex {vertex} holds {}: not a flow",
            array.data[at]
        );
        return Err(IoError::format(&file, why));
    }
    if let Some(why) = first_flow_out_of_reach(&array.data, v, &loaded.sequence) {
        return Err(IoError::format(&file, why));
    }
    Ok((0..s)
        .map(|slab| {
            (0..map.n_mesh_vertices())
                .map(|m| {
                    let row = 2 * (slab * v + map.representative(m));
                    Vector2::new(array.data[row], array.data[row + 1])
                })
                .collect()
        })
        .collect())
}

/// How far a flow may carry a point in one slab, in diameters of the surface's bounding box:
/// further is no motion on the surface but a corrupt or rescaled file (a flow × 1e305 would
/// advect to infinity).
pub const FLOW_REACH: f64 = 1e3;

/// Where the flow `data` (slabs × `v` file vertices × 2, vertex frames) moves a point over
/// [`FLOW_REACH`] diameters of `sequence`'s first frame in one slab, as a sentence; `None`
/// where it does not, or the sequence has no positions.
fn first_flow_out_of_reach(data: &[f64], v: usize, sequence: &MeshSequence) -> Option<String> {
    let positions = sequence.positions(0)?;
    let diameter = crate::geometry::bounding_diameter(positions);
    let (at, step) = (data.chunks_exact(2).enumerate())
        .map(|(at, u)| (at, u[0].hypot(u[1]) * sequence.slab_duration(at / v)))
        .find(|(_, step)| *step > FLOW_REACH * diameter)?;
    Some(format!(
        "slab {}, vertex {} moves {step:.3e} in one slab, over {FLOW_REACH}× the surface's \
         diameter {diameter:.3e}: not a flow on it",
        at / v,
        at % v
    ))
}
