//! A finished run read back for viewers (`meshflow.napari`): the surface it lies on, its own
//! arrays and documents, and the recording the surface was sampled from.
//!
//! Everything goes through the library's file policy, as `meshflow advect` and `analyze` read a
//! run: the manifest is checked ([`RunManifest::read_run`]), the surface is the run's recorded
//! solve input (relative to the run, its outside files fingerprinted, [`SolveInput::resolve`]),
//! the run's files are read only as its own ([`run_file`]: no link out of it) and only those its
//! manifest lists, each size checked against the memory limit before anything is allocated.

use crate::convert::{faces_array, frames_array};
use crate::load::image_array;
use crate::to_py_err;
use meshflow::format::{read_file_at_most, read_npy_float, IoError};
use meshflow::load::{load_geometry, load_sequence, LoadOptions, LoadedGeometry, LoadedSequence};
use meshflow::run::{run_file, RecordingRecord, RunManifest, SolveInput};
use meshflow::Error;
use numpy::ndarray::ArrayD;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// The most bytes of a run's text document (summary.json, track_errors.csv, track.json).
const DOCUMENT_MOST_BYTES: u64 = 1 << 30;

/// What [`read_run`] reads, before it becomes Python objects.
struct ReadRun {
    manifest: RunManifest,
    surface: Surface,
    /// `(name, shape, values)` of the float arrays asked for that the run lists.
    arrays: Vec<(String, Vec<usize>, Vec<f64>)>,
    documents: Vec<(String, String)>,
    recording: Option<(PathBuf, RecordingRecord)>,
}

/// The run `run`: a dict with `command` (the first command's name: `solve`, `analyze`,
/// `advect`, `track`, `surface`), `files` (as listed), `surface` (`positions` (K, V, 3),
/// `faces` (F, 3), `intensity` (K, V) or (K, V, C) or `None`, `times`, `vertex_map` (V_file,):
/// the mesh of the recorded solve input, or of the run itself when it is a sequence),
/// `arrays` (each of `arrays` the run lists: float64, as stored), `documents` (each of
/// `documents` the run lists, as text) and `recording` (`path`, `shape` (z, y, x),
/// `voxel_size` (x, y, z), `origin`, `channel`, `resolution_level`; or `None`).
#[pyfunction]
#[pyo3(signature = (run, arrays, documents))]
pub(crate) fn read_run<'py>(
    py: Python<'py>,
    run: PathBuf,
    arrays: Vec<String>,
    documents: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let read = py
        .detach(|| read(&run, &arrays, &documents))
        .map_err(to_py_err)?;
    let out = PyDict::new(py);
    let command = read
        .manifest
        .commands
        .first()
        .and_then(|c| c.get(1))
        .cloned();
    out.set_item("command", command.unwrap_or_default())?;
    out.set_item("files", read.manifest.files.clone())?;
    out.set_item("surface", surface_dict(py, &read.surface)?)?;
    let stored = PyDict::new(py);
    for (name, shape, values) in read.arrays {
        let array = ArrayD::from_shape_vec(shape, values).expect("the header's shape");
        stored.set_item(name, array.into_pyarray(py))?;
    }
    out.set_item("arrays", stored)?;
    out.set_item("documents", read.documents.into_py_dict(py)?)?;
    let recording = match read.recording {
        None => None,
        Some((path, record)) => {
            let dict = PyDict::new(py);
            dict.set_item("path", path)?;
            dict.set_item("shape", record.shape.to_vec())?;
            dict.set_item("voxel_size", record.voxel_size.to_vec())?;
            dict.set_item("origin", record.origin.to_vec())?;
            dict.set_item("channel", record.channel)?;
            dict.set_item("resolution_level", record.resolution_level)?;
            Some(dict)
        }
    };
    out.set_item("recording", recording)?;
    Ok(out)
}

trait IntoDict {
    fn into_py_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>>;
}

impl IntoDict for Vec<(String, String)> {
    fn into_py_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let dict = PyDict::new(py);
        for (name, text) in self {
            dict.set_item(name, text)?;
        }
        Ok(dict)
    }
}

fn read(run: &Path, arrays: &[String], documents: &[String]) -> Result<ReadRun, Error> {
    let manifest = RunManifest::read_run(run)?;
    let (surface, sequence_dir) = match manifest.solve.clone() {
        Some(record) => {
            let input = SolveInput::resolve(run, &manifest, record)?;
            let dir = input.input.is_dir().then(|| input.input.clone());
            (Surface::Sequence(input.load()?), dir)
        }
        None => (own_sequence(run, &manifest)?, Some(run.to_path_buf())),
    };
    let listed = |name: &String| manifest.files.contains(name);
    let arrays = (arrays.iter().filter(|n| listed(n)))
        .map(|name| {
            let array = read_npy_float(&run_file(run, name)?)?;
            let shape = array.shape.iter().map(|&n| n as usize).collect();
            Ok((name.clone(), shape, array.data))
        })
        .collect::<Result<_, IoError>>()?;
    let documents = (documents.iter().filter(|n| listed(n)))
        .map(|name| {
            let file = run_file(run, name)?;
            let bytes = read_file_at_most(&file, DOCUMENT_MOST_BYTES, "a run's document")?;
            let text = String::from_utf8(bytes)
                .map_err(|_| IoError::format(&file, "not UTF-8 text: not meshflow's"))?;
            Ok((name.clone(), text))
        })
        .collect::<Result<_, IoError>>()?;
    let recording = match sequence_dir {
        Some(dir) if meshflow::run::RunManifest::read(&dir).is_some() => {
            RecordingRecord::of_sequence(&dir)?
        }
        _ => None,
    };
    Ok(ReadRun {
        manifest,
        surface,
        arrays,
        documents,
        recording,
    })
}

/// The surface a run lies on: a sequence with its image, or surfaces alone.
enum Surface {
    Sequence(LoadedSequence),
    Geometry(LoadedGeometry),
}

/// A run without a solve record that is itself a sequence (`meshflow track`, `surface`): read
/// with its image when it lists one, else its surfaces alone.
fn own_sequence(run: &Path, manifest: &RunManifest) -> Result<Surface, Error> {
    let options = LoadOptions::default();
    match manifest
        .files
        .iter()
        .any(|f| f == meshflow::format::INTENSITY)
    {
        true => Ok(Surface::Sequence(load_sequence(run, &options)?)),
        false => Ok(Surface::Geometry(load_geometry(run, &options)?)),
    }
}

fn surface_dict<'py>(py: Python<'py>, surface: &Surface) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let (map, times) = match surface {
        Surface::Sequence(loaded) => {
            let sequence = &loaded.sequence;
            let positions: Vec<Vec<_>> = (0..sequence.n_frames())
                .map(|k| sequence.positions(k).map(<[_]>::to_vec).unwrap_or_default())
                .collect();
            dict.set_item("positions", frames_array(&positions).into_pyarray(py))?;
            dict.set_item(
                "faces",
                faces_array(sequence.mesh().faces()).into_pyarray(py),
            )?;
            dict.set_item("intensity", image_array(py, sequence))?;
            (&loaded.vertex_map, sequence.times().to_vec())
        }
        Surface::Geometry(loaded) => {
            dict.set_item(
                "positions",
                frames_array(&loaded.positions).into_pyarray(py),
            )?;
            dict.set_item("faces", faces_array(loaded.mesh.faces()).into_pyarray(py))?;
            dict.set_item("intensity", py.None())?;
            let count = loaded.positions.len();
            let times =
                (loaded.times.clone()).unwrap_or_else(|| (0..count).map(|k| k as f64).collect());
            (&loaded.vertex_map, times)
        }
    };
    dict.set_item("times", times.into_pyarray(py))?;
    let map = numpy::ndarray::Array1::from(map.to_npy());
    dict.set_item("vertex_map", map.into_pyarray(py))?;
    Ok(dict)
}

/// Writes a moving surface (`positions` (K, V, 3), `faces` (F, 3), grey `values` (K, V) or
/// none, `times` (K,)) and, where given, vectors at its vertices (`vectors` (S, V, 3), NaN where
/// none) into the directory `out` as an NPY sequence that `meshflow solve OUT` reads, with
/// `surface_KKKK.vtu` and `surface.pvd` for ParaView (point data `intensity`, `flow`), staged
/// and renamed into place whole as every meshflow output (`force` as the CLI's `--force`).
#[pyfunction]
#[pyo3(signature = (out, positions, faces, values, times, vectors, force))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_sequence(
    py: Python<'_>,
    out: PathBuf,
    positions: numpy::PyReadonlyArray3<f64>,
    faces: numpy::PyReadonlyArray2<i64>,
    values: Option<numpy::PyReadonlyArray2<f64>>,
    times: Vec<f64>,
    vectors: Option<numpy::PyReadonlyArray3<f64>>,
    force: bool,
) -> PyResult<()> {
    let positions = crate::convert::read_positions(&positions);
    let faces = crate::convert::read_faces(&faces)?;
    let values: Option<Vec<Vec<f64>>> = values.map(|v| {
        let rows = v.as_array();
        rows.outer_iter().map(|r| r.to_vec()).collect()
    });
    let vectors = vectors.map(|v| crate::convert::read_positions(&v));
    let overwrite = match force {
        true => meshflow::run::Overwrite::Force,
        false => meshflow::run::Overwrite::EarlierRun,
    };
    let surface = Written {
        positions: &positions,
        faces: &faces,
        values: values.as_deref(),
        times: &times,
        vectors: vectors.as_deref(),
    };
    py.detach(|| surface.write(&out, overwrite))
        .map_err(to_py_err)
}

/// What [`write_sequence`] writes.
struct Written<'a> {
    positions: &'a [Vec<nalgebra::Vector3<f64>>],
    faces: &'a [[u32; 3]],
    values: Option<&'a [Vec<f64>]>,
    times: &'a [f64],
    vectors: Option<&'a [Vec<nalgebra::Vector3<f64>>]>,
}

impl Written<'_> {
    fn write(&self, out: &Path, overwrite: meshflow::run::Overwrite) -> Result<(), Error> {
        use meshflow::format::vtk::{write_pvd, write_vtu, PointArray};
        use meshflow::format::write_npy_sequence;
        let mut staged = meshflow::run::StagedDir::create(out, overwrite)?;
        staged.record_command(["python", "-c", "meshflow.napari: write_layers(...)"]);
        let dir = staged.path().to_path_buf();
        let in_target = |e| staged.in_target(e);
        write_npy_sequence(&dir, self.positions, self.faces, self.values, self.times)
            .map_err(in_target)?;
        let mut datasets = Vec::with_capacity(self.positions.len());
        for (k, frame) in self.positions.iter().enumerate() {
            let name = format!("surface_{k:04}.vtu");
            let grey = self.values.map(|v| v[k].clone());
            let flow: Option<Vec<f64>> = self
                .vectors
                .and_then(|v| v.get(k))
                .map(|u| u.iter().flat_map(|u| [u.x, u.y, u.z]).collect());
            let mut arrays = Vec::new();
            if let Some(grey) = &grey {
                arrays.push(PointArray {
                    name: "intensity",
                    components: 1,
                    values: grey,
                });
            }
            if let Some(flow) = &flow {
                arrays.push(PointArray {
                    name: "flow",
                    components: 3,
                    values: flow,
                });
            }
            write_vtu(&dir.join(&name), frame, self.faces, &arrays).map_err(in_target)?;
            datasets.push((self.times[k], name));
        }
        write_pvd(&dir.join("surface.pvd"), &datasets).map_err(in_target)?;
        staged.commit()?;
        Ok(())
    }
}
