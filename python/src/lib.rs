//! `meshflow._meshflow`: the Rust half of the Python package (the NumPy-facing wrappers,
//! docstrings and argument checks are in `meshflow/__init__.py`).
//!
//! Every function takes arrays the Python half has already given their dtype (float64
//! positions and grey values, int64 faces, float32 volumes) and checked for shape; it copies
//! them into the library's types with the GIL held, then releases the GIL (`Python::detach`)
//! for everything long. Library errors become Python exceptions carrying the library's
//! one-line message ([`to_py_err`]); nothing here panics on user input.
//!
//! A running solve reacquires the GIL once per event (iteration, warp, factorization) to call
//! the `progress` callback and to check for Ctrl-C (`PyErr_CheckSignals`); either raising stops
//! the solve within one iteration, and the exception is re-raised ([`PythonObserver`]).

mod keywords;

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::flow::{
    Boundary, FlowError, FlowParams, FlowProblem, FlowResult, MeshSequence, Regularizer,
    SolveEvent, SolveObserver, SolverChoice, TimeCoupling, Warping, Weight,
};
use meshflow::format::{IoError, VertexValues};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::load::{
    load_geometry, load_sequence as load_files, mesh_from_arrays, sequence_from_arrays,
    LoadOptions, LoadedSequence, VertexMap,
};
use meshflow::mesh::Mesh;
use meshflow::render::{
    result_views, write_chosen_slab_pictures, FigureOptions, SlabSelection, UpAxis, UpChoice, View,
};
use meshflow::run::{
    write_flow_outputs, write_run_input, OutputFormat, Overwrite, SolveRecord, StagedDir,
};
use meshflow::surface::{FitOptions, Reference, Resolution, Shape};
use meshflow::volume::{Reduce, SampleOptions, SampledSequence, Shell, Volume};
use meshflow::{accuracy, fem, shapes, surface, track as tracking, volume, Error};
use nalgebra::{Matrix3x2, Vector2, Vector3};
use numpy::ndarray::{Array1, Array2, Array3, Array4};
use numpy::{
    IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyReadonlyArrayDyn,
};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Mutex;

/// The exception for a library error: `FileNotFoundError`, `PermissionError` or `OSError`
/// when the operating system refused a file, `ValueError` for everything else (bad data,
/// broken files, bad parameters). The message is the library's one line.
fn to_py_err(error: Error) -> PyErr {
    let message = keywords::in_python_words(&error.to_string());
    match os_error(&error).map(std::io::Error::kind) {
        Some(std::io::ErrorKind::NotFound) => PyFileNotFoundError::new_err(message),
        Some(std::io::ErrorKind::PermissionDenied) => PyPermissionError::new_err(message),
        Some(_) => PyOSError::new_err(message),
        None => PyValueError::new_err(message),
    }
}

/// The operating-system error at the root of `error`, if that is what it is.
fn os_error(error: &Error) -> Option<&std::io::Error> {
    fn in_io(error: &IoError) -> Option<&std::io::Error> {
        match error {
            IoError::File { source, .. } => Some(source),
            IoError::Referenced { source, .. } => in_io(source),
            _ => None,
        }
    }
    match error {
        Error::Io(io) => in_io(io),
        Error::InFile { source, .. } => os_error(source),
        _ => None,
    }
}

fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

// ---------------------------------------------------------------------------------------------
// Arrays in, arrays out.

fn read_positions(array: &PyReadonlyArray3<f64>) -> Vec<Vec<Vector3<f64>>> {
    array
        .as_array()
        .outer_iter()
        .map(read_points_view)
        .collect()
}

fn read_points(array: &PyReadonlyArray2<f64>) -> Vec<Vector3<f64>> {
    read_points_view(array.as_array())
}

fn read_points_view(frame: numpy::ndarray::ArrayView2<f64>) -> Vec<Vector3<f64>> {
    frame
        .outer_iter()
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .collect()
}

/// Each frame's image from a (K, V) grey or (K, V, C) channel array.
fn read_images(array: &PyReadonlyArrayDyn<f64>) -> PyResult<Vec<VertexValues>> {
    let array = array.as_array();
    match array.ndim() {
        2 => Ok(array
            .outer_iter()
            .map(|row| VertexValues::Grey(row.iter().copied().collect()))
            .collect()),
        3 => Ok(array
            .outer_iter()
            .map(|frame| {
                let channels = frame.axis_iter(numpy::ndarray::Axis(1));
                VertexValues::Channels(channels.map(|c| c.iter().copied().collect()).collect())
            })
            .collect()),
        n => Err(value_error(format!(
            "intensity has {n} dimensions, expected (frames, vertices) or (frames, vertices, channels)"
        ))),
    }
}

/// Faces as the library's `u32` triples; an index below 0 or beyond `u32` is named.
fn read_faces(array: &PyReadonlyArray2<i64>) -> PyResult<Vec<[u32; 3]>> {
    array
        .as_array()
        .outer_iter()
        .enumerate()
        .map(|(f, face)| {
            let index = |c: usize| {
                u32::try_from(face[c]).map_err(|_| {
                    value_error(format!(
                        "faces[{f}] names vertex {}, not a vertex index",
                        face[c]
                    ))
                })
            };
            Ok([index(0)?, index(1)?, index(2)?])
        })
        .collect()
}

/// `rows[s][i]` (per mesh vertex) as an (S, V_file, 3) array in the input numbering, NaN for
/// dropped vertices (as `flow.npy`).
fn file_vectors(map: &VertexMap, rows: &[Vec<Vector3<f64>>]) -> Array3<f64> {
    let v = map.n_file_vertices();
    let values = rows
        .iter()
        .flat_map(|slab| map.file_rows(slab, Vector3::repeat(f64::NAN)))
        .flat_map(|u| [u.x, u.y, u.z])
        .collect();
    Array3::from_shape_vec((rows.len(), v, 3), values).expect("S × V × 3 values")
}

fn file_intrinsic(map: &VertexMap, rows: &[Vec<Vector2<f64>>]) -> Array3<f64> {
    let v = map.n_file_vertices();
    let values = rows
        .iter()
        .flat_map(|slab| map.file_rows(slab, Vector2::repeat(f64::NAN)))
        .flat_map(|u| [u.x, u.y])
        .collect();
    Array3::from_shape_vec((rows.len(), v, 2), values).expect("S × V × 2 values")
}

fn file_scalars(map: &VertexMap, rows: &[Vec<f64>]) -> Array2<f64> {
    let v = map.n_file_vertices();
    let values = rows
        .iter()
        .flat_map(|slab| map.file_rows(slab, f64::NAN))
        .collect();
    Array2::from_shape_vec((rows.len(), v), values).expect("S × V values")
}

/// Frames `P_i = [e1, e2]` as rows: `frames[i][k]` is basis vector `k` of vertex `i` in R^3
/// (as `frames.npy`).
fn frame_rows(frames: &[Matrix3x2<f64>]) -> Vec<[f64; 6]> {
    frames
        .iter()
        .map(|p| {
            [
                p[(0, 0)],
                p[(1, 0)],
                p[(2, 0)],
                p[(0, 1)],
                p[(1, 1)],
                p[(2, 1)],
            ]
        })
        .collect()
}

/// `rows[k][n]` as a (K, N, 3) array.
fn frames_array(rows: &[Vec<Vector3<f64>>]) -> Array3<f64> {
    let n = rows.first().map_or(0, Vec::len);
    let values = rows
        .iter()
        .flatten()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    Array3::from_shape_vec((rows.len(), n, 3), values).expect("K × N × 3 values")
}

fn points_array(points: &[Vector3<f64>]) -> Array2<f64> {
    let values = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((points.len(), 3), values).expect("N × 3 values")
}

fn faces_array(faces: &[[u32; 3]]) -> Array2<i64> {
    let values = faces.iter().flatten().map(|&i| i as i64).collect();
    Array2::from_shape_vec((faces.len(), 3), values).expect("F × 3 indices")
}

// ---------------------------------------------------------------------------------------------
// Progress and Ctrl-C.

/// Calls the Python `progress` callback with each [`SolveEvent`] as a dict, and checks for
/// signals (Ctrl-C); the first exception either raises stops the solve and is kept for
/// re-raising.
struct PythonObserver {
    callback: Option<Py<PyAny>>,
    failure: Mutex<Option<PyErr>>,
}

impl PythonObserver {
    fn keep(&self, error: PyErr) {
        let mut failure = self.failure.lock().unwrap_or_else(|e| e.into_inner());
        failure.get_or_insert(error);
    }

    /// The exception that stopped the solve, if one did.
    fn take_failure(&self) -> Option<PyErr> {
        self.failure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }
}

fn event_dict<'py>(py: Python<'py>, event: SolveEvent) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    match event {
        SolveEvent::Factorizing { slabs } => {
            dict.set_item("kind", "factorizing")?;
            dict.set_item("slabs", slabs)?;
        }
        SolveEvent::Iteration {
            iteration,
            relative_residual,
        } => {
            dict.set_item("kind", "iteration")?;
            dict.set_item("iteration", iteration)?;
            dict.set_item("relative_residual", relative_residual)?;
        }
        SolveEvent::Warp {
            level,
            warp,
            solve,
            solves,
        } => {
            dict.set_item("kind", "warp")?;
            dict.set_item("level", level)?;
            dict.set_item("warp", warp)?;
            dict.set_item("solve", solve)?;
            dict.set_item("solves", solves)?;
        }
    }
    Ok(dict)
}

impl SolveObserver for PythonObserver {
    fn event(&self, event: SolveEvent) {
        let Some(callback) = &self.callback else {
            return;
        };
        Python::attach(|py| {
            let called = event_dict(py, event).and_then(|d| callback.call1(py, (d,)));
            if let Err(error) = called {
                self.keep(error);
            }
        });
    }

    fn interrupted(&self) -> bool {
        Python::attach(|py| {
            if let Err(error) = py.check_signals() {
                self.keep(error);
            }
        });
        self.failure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
    }
}

// ---------------------------------------------------------------------------------------------
// The flow.

/// The weights and choices of `compute_flow`, as the CLI's flags.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct ParamArgs {
    spread: Option<f64>,
    time_scale: Option<f64>,
    speed_penalty: Option<f64>,
    alpha: Option<f64>,
    beta: Option<f64>,
    gamma: Option<f64>,
    regularizer: String,
    dirichlet_mix: Option<f64>,
    anisotropic: Option<String>,
    anisotropic_sigma: Option<f64>,
    anisotropic_in_time: bool,
    robust_smoothness: Option<String>,
    flow_driven: String,
    channel_weights: Option<Vec<f64>>,
    boundary: String,
    time_coupling: String,
    solver: String,
    tolerance: f64,
    levels: Option<usize>,
    warps: Option<usize>,
    large_motion: bool,
}

impl ParamArgs {
    fn params(&self) -> PyResult<FlowParams> {
        let defaults = FlowParams::default();
        let weight =
            |value: Option<f64>, relative: Option<f64>, default: Weight, names: &str| match (
                value, relative,
            ) {
                (Some(_), Some(_)) => Err(value_error(format!("give one of {names}, not both"))),
                (Some(v), None) => Ok(Weight::Value(v)),
                (None, Some(r)) => Ok(Weight::Relative(r)),
                (None, None) => Ok(default),
            };
        let params = FlowParams {
            alpha: weight(
                self.alpha,
                self.time_scale,
                defaults.alpha,
                "alpha and time_scale",
            )?,
            beta: weight(
                self.beta,
                self.speed_penalty,
                defaults.beta,
                "beta and speed_penalty",
            )?,
            gamma: weight(self.gamma, self.spread, defaults.gamma, "gamma and spread")?,
            regularizer: Regularizer::with_mix(
                parse(&self.regularizer, "regularizer")?,
                self.dirichlet_mix,
            )
            .map_err(|e| to_py_err(e.into()))?,
            anisotropy: self.anisotropy()?,
            robust_smoothness: (self.robust_smoothness.as_deref())
                .map(|text| parse(text, "robust_smoothness"))
                .transpose()?,
            flow_driven: parse(&self.flow_driven, "flow_driven")?,
            channel_weights: self.channel_weights.clone(),
            boundary: parse::<Boundary>(&self.boundary, "boundary")?,
            time_coupling: parse::<TimeCoupling>(&self.time_coupling, "time_coupling")?,
            solver: parse::<SolverChoice>(&self.solver, "solver")?,
            tolerance: self.tolerance,
            warping: Warping::from_options(self.levels, self.warps, self.large_motion),
            ..defaults
        };
        params.validate().map_err(|e| to_py_err(Error::from(e)))?;
        Ok(params)
    }

    /// `anisotropic` (a number or "auto") with `anisotropic_sigma` and `anisotropic_in_time`.
    fn anisotropy(&self) -> PyResult<Option<meshflow::flow::Anisotropy>> {
        let Some(text) = self.anisotropic.as_deref() else {
            return match (self.anisotropic_sigma, self.anisotropic_in_time) {
                (Some(_), _) => Err(value_error("anisotropic_sigma needs anisotropic")),
                (_, true) => Err(value_error("anisotropic_in_time needs anisotropic")),
                (None, false) => Ok(None),
            };
        };
        Ok(Some(meshflow::flow::Anisotropy {
            sigma: self.anisotropic_sigma,
            in_time: self.anisotropic_in_time,
            ..meshflow::flow::Anisotropy::with(parse(text, "anisotropic")?)
        }))
    }
}

fn parse<T: std::str::FromStr>(text: &str, name: &str) -> PyResult<T>
where
    T::Err: std::fmt::Display,
{
    text.parse()
        .map_err(|e| value_error(format!("{name}: {e}")))
}

/// How meshes are built from faces (the CLI's `--no-weld`, `--weld-tolerance`, `--repair`)
/// and which image channels are used (`--channels`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct MeshArgs {
    weld: bool,
    weld_tolerance: f64,
    repair: bool,
    channels: String,
}

impl MeshArgs {
    fn options(&self) -> PyResult<LoadOptions> {
        Ok(LoadOptions {
            weld: self.weld,
            weld_tolerance: self.weld_tolerance,
            repair: self.repair,
            channels: parse(&self.channels, "channels")?,
            ..LoadOptions::default()
        })
    }
}

/// A computed flow: arrays in the input's vertex numbering, and what `write` needs.
#[pyclass(module = "meshflow._meshflow", frozen)]
struct Flow {
    loaded: LoadedSequence,
    params: FlowParams,
    result: FlowResult,
}

#[pymethods]
impl Flow {
    fn __repr__(&self) -> String {
        let sequence = &self.loaded.sequence;
        format!(
            "<meshflow.Flow: {} slabs × {} vertices, {} solver, {} iterations, energy {:.4e}>",
            sequence.n_slabs(),
            self.loaded.vertex_map.n_file_vertices(),
            self.result.method,
            self.result.iterations,
            self.result.energy
        )
    }

    /// (S, V, 3) float64: the flow of slab `s` in R^3 at the vertices of frame `s`.
    #[getter]
    fn vectors<'py>(&self, py: Python<'py>) -> Option<Bound<'py, numpy::PyArray3<f64>>> {
        let vectors = self.result.vectors.as_ref()?;
        Some(file_vectors(&self.loaded.vertex_map, vectors).into_pyarray(py))
    }

    /// (S, V, 2) float64: the same in the vertex frames.
    #[getter]
    fn intrinsic<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray3<f64>> {
        file_intrinsic(&self.loaded.vertex_map, &self.result.intrinsic).into_pyarray(py)
    }

    /// (S, V, 2, 3) float64: `frames[s, i, k]` is basis vector `k` of vertex `i`'s frame in
    /// R^3 on frame `s`, so `vectors[s, i] = intrinsic[s, i] @ frames[s, i]`.
    #[getter]
    fn frames<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray4<f64>>> {
        let sequence = &self.loaded.sequence;
        let map = &self.loaded.vertex_map;
        let mut values = Vec::with_capacity(sequence.n_slabs() * map.n_file_vertices() * 6);
        for s in 0..sequence.n_slabs() {
            let frames = sequence
                .slab_frames(s)
                .map_err(|e| to_py_err(e.into()))?
                .expect("sequences from arrays are embedded");
            values.extend(
                map.file_rows(&frame_rows(&frames), [f64::NAN; 6])
                    .into_iter()
                    .flatten(),
            );
        }
        let shape = (sequence.n_slabs(), map.n_file_vertices(), 2, 3);
        Ok(Array4::from_shape_vec(shape, values)
            .expect("S × V × 2 × 3 values")
            .into_pyarray(py))
    }

    /// (S, V) float64 with coarse-to-fine warping: `I⁺ − I⁻` along the final flow; else None.
    #[getter]
    fn warped_residual<'py>(&self, py: Python<'py>) -> Option<Bound<'py, numpy::PyArray2<f64>>> {
        let residual = self.result.warped_residual.as_ref()?;
        Some(file_scalars(&self.loaded.vertex_map, residual).into_pyarray(py))
    }

    /// (V_input,) int64: the mesh vertex of each input vertex, −1 if dropped.
    #[getter]
    fn vertex_map<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<i64>> {
        Array1::from(self.loaded.vertex_map.to_npy()).into_pyarray(py)
    }

    /// `E(u)` at the solution.
    #[getter]
    fn energy(&self) -> f64 {
        self.result.energy
    }

    /// `E(0)`: the data term of the zero flow.
    #[getter]
    fn energy_at_zero(&self) -> f64 {
        self.result.energy_at_zero
    }

    /// `‖b − Au‖ / ‖b‖` of the solution.
    #[getter]
    fn relative_residual(&self) -> f64 {
        self.result.relative_residual
    }

    /// Reweighted solves of the robust smoothness (0 for the quadratic model).
    #[getter]
    fn reweightings(&self) -> usize {
        self.result.reweightings
    }

    /// Per slab, the contrast `λ` of the image-driven anisotropic smoothness as used (`"auto"`
    /// resolved); empty without it.
    #[getter]
    fn anisotropic_contrasts(&self) -> Vec<f64> {
        self.result.anisotropic_contrasts.clone()
    }

    /// Per slab, the scale `ε` of robust smoothness as used (`"auto"` resolved); empty without
    /// it.
    #[getter]
    fn robust_scales(&self) -> Vec<f64> {
        self.result.robust_scales.clone()
    }

    /// Solver iterations (0 for a direct solve).
    #[getter]
    fn iterations(&self) -> usize {
        self.result.iterations
    }

    /// The method used, e.g. "PCG (multigrid in time)".
    #[getter]
    fn solver(&self) -> String {
        self.result.method.to_string()
    }

    /// Why the method: the rule `solver="auto"` applied, with its figures.
    #[getter]
    fn solver_reason(&self) -> String {
        self.result.solver_reason.clone()
    }

    /// `(λ_min, λ_max)` of the preconditioned operator as the (last) CG run saw it (its Ritz
    /// values: `λ_max / λ_min` estimates the condition number behind the iterations); `None`
    /// for a direct solve.
    #[getter]
    fn preconditioned_spectrum(&self) -> Option<(f64, f64)> {
        self.result
            .preconditioned_spectrum
            .map(|[low, high]| (low, high))
    }

    /// `{"data", "speed", "spatial", "temporal"}`: the energy's terms at the solution.
    #[getter]
    fn energy_terms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let terms = &self.result.energy_terms;
        let dict = PyDict::new(py);
        dict.set_item("data", terms.data)?;
        dict.set_item("speed", terms.speed)?;
        dict.set_item("spatial", terms.spatial)?;
        dict.set_item("temporal", terms.temporal)?;
        Ok(dict)
    }

    /// Wall-clock seconds: `assembly`, `factorization` (within `solve`), `solve`, `total`.
    #[getter]
    fn seconds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let timings = &self.result.timings;
        let dict = PyDict::new(py);
        dict.set_item("assembly", timings.assembly)?;
        dict.set_item("factorization", timings.factorization)?;
        dict.set_item("solve", timings.solve)?;
        dict.set_item("total", timings.total)?;
        Ok(dict)
    }

    /// What the flow tells (`meshflow analyze`): the arrays of `analysis_arrays` by name
    /// (vertex arrays (S, V_input), face arrays (S, F[, k]), R³ vectors on frame `s`), `faces`
    /// (F, 3) over input vertices, and `slabs`, summary.json's per-slab totals as JSON.
    fn analysis<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (arrays, summary) = py
            .detach(|| -> Result<_, Error> {
                let slabs = meshflow::analysis::analyze_flow(
                    &self.loaded.sequence,
                    &self.result.intrinsic,
                )?;
                let arrays = meshflow::run::analysis_arrays(&self.loaded, &slabs)?;
                let input = std::path::Path::new("arrays in memory");
                let summary = meshflow::run::analysis_json(&self.loaded.sequence, &slabs, input);
                Ok((arrays, summary))
            })
            .map_err(to_py_err)?;
        let dict = PyDict::new(py);
        for array in arrays {
            let shape: Vec<usize> = array.shape.iter().map(|&n| n as usize).collect();
            let values = numpy::ndarray::ArrayD::from_shape_vec(shape, array.values)
                .expect("shape and values agree");
            dict.set_item(array.name, values.into_pyarray(py))?;
        }
        let faces = meshflow::run::file_faces(&self.loaded);
        let faces = Array2::from_shape_vec((faces.len(), 3), faces.concat()).expect("F × 3");
        dict.set_item("faces", faces.into_pyarray(py))?;
        dict.set_item("slabs", summary["slabs"].to_string())?;
        Ok(dict)
    }

    /// (F, 3): the triangles over the mesh's vertices (welded numbering, as :func:`advect`'s
    /// vertex trajectories).
    #[getter]
    fn mesh_faces<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<i64>> {
        faces_array(self.loaded.sequence.mesh().faces()).into_pyarray(py)
    }

    /// (K,): the frame times.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.loaded.sequence.times().to_vec().into_pyarray(py)
    }

    /// The solves of a run of several (warps of `large_motion`, reweightings of
    /// `robust_smoothness`), each `{"label", "seconds", "iterations"}`; empty for one solve.
    #[getter]
    fn solves<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        (self.result.timings.steps.iter())
            .map(|step| {
                let dict = PyDict::new(py);
                dict.set_item("label", &step.label)?;
                dict.set_item("seconds", step.seconds)?;
                dict.set_item("iterations", step.iterations)?;
                Ok(dict)
            })
            .collect()
    }

    /// `alpha`, `beta`, `gamma` as used, in the data's units (relative weights resolved;
    /// `alpha` may be `inf`).
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let weights = &self.result.weights;
        let dict = PyDict::new(py);
        dict.set_item("alpha", weights.alpha)?;
        dict.set_item("beta", weights.beta)?;
        dict.set_item("gamma", weights.gamma)?;
        Ok(dict)
    }

    /// The flow scored at tracked points (`tracks` (K, N, 3), NaN where untracked): the
    /// summary as JSON (summary.json's `ground_truth_tracks`) and per-point arrays.
    fn score_tracks<'py>(
        &self,
        py: Python<'py>,
        tracks: PyReadonlyArray3<'py, f64>,
    ) -> PyResult<(String, Bound<'py, PyDict>)> {
        let array = tracks.as_array();
        let shape: Vec<u64> = array.shape().iter().map(|&n| n as u64).collect();
        let values: Vec<f64> = array.iter().copied().collect();
        let scores = py
            .detach(|| -> Result<_, Error> {
                let tracks = accuracy::Tracks::from_array(&shape, &values)?;
                Ok(accuracy::score_result(
                    &self.loaded.sequence,
                    &self.result,
                    &tracks,
                )?)
            })
            .map_err(to_py_err)?;
        let points = &scores.points;
        let column = |f: fn(&accuracy::TrackPoint) -> Vector3<f64>| {
            points_array(&points.iter().map(f).collect::<Vec<_>>()).into_pyarray(py)
        };
        let dict = PyDict::new(py);
        let indices = |f: fn(&accuracy::TrackPoint) -> usize| -> Vec<i64> {
            points.iter().map(|p| f(p) as i64).collect()
        };
        dict.set_item("slab", indices(|p| p.slab).into_pyarray(py))?;
        dict.set_item("track", indices(|p| p.track).into_pyarray(py))?;
        dict.set_item("position", column(|p| p.position))?;
        dict.set_item("truth", column(|p| p.truth))?;
        dict.set_item("computed", column(|p| p.computed))?;
        let values =
            |f: fn(&accuracy::TrackPoint) -> f64| -> Vec<f64> { points.iter().map(f).collect() };
        dict.set_item("endpoint", values(|p| p.endpoint).into_pyarray(py))?;
        dict.set_item(
            "direction_degrees",
            values(|p| p.direction_degrees).into_pyarray(py),
        )?;
        dict.set_item("distance", values(|p| p.distance).into_pyarray(py))?;
        let summary = meshflow::run::track_scores_json(&scores).to_string();
        Ok((summary, dict))
    }

    /// `summary.json` of the CLI, as a JSON string.
    fn summary_json(&self) -> String {
        meshflow::run::summary_json(&self.loaded, &self.params, &self.result, Default::default())
            .to_string()
    }

    /// Writes the CLI's outputs (`formats` of npy, vtu, glb; summary.json always) into `out`,
    /// staged and renamed into place whole.
    fn write(
        &self,
        py: Python<'_>,
        out: PathBuf,
        formats: Vec<String>,
        force: bool,
    ) -> PyResult<()> {
        let formats = formats
            .iter()
            .map(|f| parse::<OutputFormat>(f, "formats"))
            .collect::<PyResult<Vec<_>>>()?;
        let overwrite = match force {
            true => Overwrite::Force,
            false => Overwrite::EarlierRun,
        };
        py.detach(|| -> Result<(), Error> {
            let mut staged = StagedDir::create(&out, overwrite)?;
            // The run holds its input, so `meshflow advect OUT` reads it from there.
            staged.record_command(["python", "-c", "meshflow.write_outputs(...)"]);
            let load = LoadOptions::default();
            staged.record_solve(SolveRecord { input: None, load });
            write_run_input(staged.path(), &self.loaded).map_err(|e| staged.in_target(e))?;
            let view = self.view();
            write_flow_outputs(
                &staged,
                &self.loaded,
                &self.params,
                &self.result,
                &formats,
                Default::default(),
                &view,
            )?;
            staged.commit()?;
            Ok(())
        })
        .map_err(to_py_err)
    }

    /// The points `seeds` (N, 3; default: every mesh vertex) carried through all slabs along
    /// the flow, as `meshflow advect`.
    #[pyo3(signature = (seeds))]
    fn advect<'py>(
        &self,
        py: Python<'py>,
        seeds: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<TrajectoryArrays<'py>> {
        let points = seeds.as_ref().map(read_points);
        let sequence = &self.loaded.sequence;
        let (positions, trajectories, grey) = py
            .detach(|| -> Result<_, Error> {
                let seeds = match &points {
                    Some(points) => meshflow::flow::closest_seeds(sequence, points)?,
                    None => meshflow::flow::vertex_seeds(sequence),
                };
                let trajectories =
                    meshflow::flow::advect(sequence, &self.result.intrinsic, &seeds)?;
                let positions = trajectories
                    .positions(sequence)
                    .ok_or(FlowError::Intrinsic)?;
                let grey = trajectories.intensities(sequence);
                Ok((positions, trajectories, grey))
            })
            .map_err(to_py_err)?;
        let (k, n) = (positions.len(), positions[0].len());
        let points = || trajectories.points.iter().flatten();
        let faces = points().map(|p| p.face as i64).collect();
        let barycentric = points().flat_map(|p| p.barycentric).collect();
        Ok((
            frames_array(&positions).into_pyarray(py),
            Array2::from_shape_vec((k, n), faces)
                .expect("K × N")
                .into_pyarray(py),
            Array3::from_shape_vec((k, n, 3), barycentric)
                .expect("K × N × 3")
                .into_pyarray(py),
            Array2::from_shape_vec((k, n), grey.concat())
                .expect("K × N")
                .into_pyarray(py),
            Array1::from(trajectories.reached_boundary.clone()).into_pyarray(py),
        ))
    }

    /// Draws the chosen slabs (`"0,5,10-20,last"`, default all) as `meshflow render` does into
    /// the new output directory `out`: one camera and flow scale for the whole run. Returns
    /// the files written.
    #[pyo3(signature = (out, slabs, size, view, up, flow_scale, force))]
    #[allow(clippy::too_many_arguments)] // the Python signature
    fn render(
        &self,
        py: Python<'_>,
        out: PathBuf,
        slabs: Option<String>,
        size: (u32, u32),
        view: Option<String>,
        up: Option<String>,
        flow_scale: Option<f64>,
        force: bool,
    ) -> PyResult<Vec<PathBuf>> {
        let chosen = match slabs {
            Some(text) => parse::<SlabSelection>(&text, "slabs")?,
            None => SlabSelection::all(),
        };
        let mut seen = match view {
            Some(text) => parse::<View>(&text, "view")?,
            None => self.view(),
        };
        if let Some(text) = up {
            seen = seen.with_up(parse::<UpAxis>(&text, "up")?);
        }
        let options = FigureOptions {
            width: size.0,
            height: size.1,
            view: seen,
            flow_scale,
            ..FigureOptions::default()
        };
        let overwrite = match force {
            true => Overwrite::Force,
            false => Overwrite::EarlierRun,
        };
        let sequence = &self.loaded.sequence;
        py.detach(|| -> Result<Vec<PathBuf>, Error> {
            let chosen = chosen.resolve(sequence.n_slabs())?;
            let mut staged = StagedDir::create(&out, overwrite)?;
            staged.record_command(["python", "-c", "meshflow.render(...)"]);
            let views = result_views(sequence, &self.result, None)?;
            let faces = sequence.mesh().faces();
            let written =
                write_chosen_slab_pictures(staged.path(), faces, &views, &chosen, &options, &|| {})
                    .map_err(|e| staged.error_in_target(e))?;
            staged.commit()?;
            Ok(written
                .iter()
                .map(|file| out.join(file.file_name().expect("pictures are files")))
                .collect())
        })
        .map_err(to_py_err)
    }
}

/// Trajectories: positions (K, N, 3), faces (K, N), barycentric coordinates (K, N, 3), the
/// image at the points (K, N) and whether each reached the boundary (N,).
type TrajectoryArrays<'py> = (
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<i64>>,
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, numpy::PyArray1<bool>>,
);

impl Flow {
    /// The view of the pictures: the default angles and the input's up axis.
    fn view(&self) -> View {
        View::default().with_up(UpChoice::of_sequence(&self.loaded).axis)
    }
}

/// Builds the sequence, solves, and returns the [`Flow`]; the GIL is released throughout.
#[pyfunction]
#[pyo3(signature = (positions, faces, intensity, times, params, mesh, progress))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per array
fn compute_flow(
    py: Python<'_>,
    positions: PyReadonlyArray3<f64>,
    faces: PyReadonlyArray2<i64>,
    intensity: PyReadonlyArrayDyn<f64>,
    times: Option<PyReadonlyArray1<f64>>,
    params: ParamArgs,
    mesh: MeshArgs,
    progress: Option<Py<PyAny>>,
) -> PyResult<Flow> {
    let params = params.params()?;
    let faces = read_faces(&faces)?;
    let positions = read_positions(&positions);
    let intensities = read_images(&intensity)?;
    let times = times.map(|t| t.as_array().to_vec());
    let options = mesh.options()?;
    let observer = PythonObserver {
        callback: progress,
        failure: Mutex::new(None),
    };
    let solved = py.detach(|| -> Result<(LoadedSequence, FlowResult), Error> {
        let loaded = sequence_from_arrays(faces, positions, intensities, times, &options)?;
        let problem = FlowProblem::new(&loaded.sequence, &params)?;
        let result = problem.solve(&observer)?;
        Ok((loaded, result))
    });
    match solved {
        Ok((loaded, result)) => Ok(Flow {
            loaded,
            params,
            result,
        }),
        Err(Error::Flow(FlowError::Interrupted)) => Err(observer
            .take_failure()
            .unwrap_or_else(|| value_error("interrupted"))),
        Err(error) => Err(to_py_err(error)),
    }
}

// ---------------------------------------------------------------------------------------------
// Operators, files, tracking.

/// `(data, indices, indptr, shape)` of a CSC matrix, for `scipy.sparse.csc_matrix`.
type Csc<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    (usize, usize),
);

fn csc<'py>(py: Python<'py>, matrix: &fem::SparseMatrix) -> Csc<'py> {
    let (symbolic, values) = matrix.parts();
    let indices: Vec<i64> = symbolic.row_idx().iter().map(|&i| i as i64).collect();
    let indptr: Vec<i64> = symbolic.col_ptr().iter().map(|&i| i as i64).collect();
    (
        values.to_vec().into_pyarray(py),
        indices.into_pyarray(py),
        indptr.into_pyarray(py),
        (matrix.nrows(), matrix.ncols()),
    )
}

/// The operators of `meshflow operators` for one mesh: a dict of CSC parts (`cotan`,
/// `mass_scalar`, `stiffness`, `mass`), `frames` (V, 2, 3), `vertex_map` (V_input,).
#[pyfunction]
#[pyo3(signature = (positions, faces, mesh))]
fn operators<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray2<f64>,
    faces: PyReadonlyArray2<i64>,
    mesh: MeshArgs,
) -> PyResult<Bound<'py, PyDict>> {
    let faces = read_faces(&faces)?;
    let positions = read_points(&positions);
    let options = mesh.options()?;
    let built = py.detach(|| -> Result<_, Error> {
        let loaded = mesh_from_arrays(positions, &faces, &options)?;
        let (mesh, positions) = (&loaded.mesh, &loaded.positions);
        let geometry = IntrinsicGeometry::from_positions(mesh, positions)?;
        let connection = Connection::new(mesh, &geometry);
        let frames = vertex_frames_in_r3(mesh, &geometry, &connection, positions)?;
        let matrices = fem::exported_operators(mesh, &geometry, &connection);
        Ok((loaded.vertex_map, frames, matrices))
    });
    let (map, frames, matrices) = built.map_err(to_py_err)?;
    let out = PyDict::new(py);
    for (name, matrix) in &matrices {
        out.set_item(*name, csc(py, matrix))?;
    }
    let rows: Vec<f64> = frame_rows(&frames).into_iter().flatten().collect();
    let frames = Array3::from_shape_vec((frames.len(), 2, 3), rows).expect("V × 2 × 3 values");
    out.set_item("frames", frames.into_pyarray(py))?;
    out.set_item("vertex_map", Array1::from(map.to_npy()).into_pyarray(py))?;
    Ok(out)
}

/// A sequence as `meshflow solve` reads it: mesh arrays (welded numbering), grey values,
/// times, the vertex map, the loader's warnings and a description of the source.
type SequenceArrays<'py> = (
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<i64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    Vec<String>,
    String,
);

fn sequence_arrays<'py>(py: Python<'py>, loaded: &LoadedSequence) -> SequenceArrays<'py> {
    let sequence = &loaded.sequence;
    let positions: Vec<Vec<Vector3<f64>>> = (0..sequence.n_frames())
        .map(|f| {
            let frame = sequence.positions(f);
            frame.expect("sequences from files are embedded").to_vec()
        })
        .collect();
    (
        frames_array(&positions).into_pyarray(py),
        faces_array(sequence.mesh().faces()).into_pyarray(py),
        image_array(py, sequence),
        sequence.times().to_vec().into_pyarray(py),
        Array1::from(loaded.vertex_map.to_npy()).into_pyarray(py),
        loaded.warnings.iter().map(ToString::to_string).collect(),
        loaded.source.describe(),
    )
}

/// The sequence's image: (K, V) for one channel, (K, V, C) for several.
fn image_array<'py>(
    py: Python<'py>,
    sequence: &MeshSequence,
) -> Bound<'py, numpy::PyArrayDyn<f64>> {
    let (k, v, c) = (
        sequence.n_frames(),
        sequence.mesh().n_vertices(),
        sequence.n_channels(),
    );
    let values: Vec<f64> = (0..k)
        .flat_map(|f| {
            let channels = sequence.channels(f);
            (0..v).flat_map(move |i| channels.iter().map(move |channel| channel[i]))
        })
        .collect();
    let shape = match c {
        1 => vec![k, v],
        _ => vec![k, v, c],
    };
    numpy::ndarray::ArrayD::from_shape_vec(shape, values)
        .expect("K × V × C")
        .into_pyarray(py)
}

/// Reads what `meshflow solve INPUT` reads.
#[pyfunction]
#[pyo3(signature = (path, intensity, intensity_attribute, times, fps, animation, mesh))]
#[allow(clippy::too_many_arguments)]
fn load_sequence<'py>(
    py: Python<'py>,
    path: PathBuf,
    intensity: Option<PathBuf>,
    intensity_attribute: Option<String>,
    times: Option<Vec<f64>>,
    fps: Option<f64>,
    animation: Option<String>,
    mesh: MeshArgs,
) -> PyResult<SequenceArrays<'py>> {
    let options = LoadOptions {
        intensity,
        intensity_attribute,
        times,
        fps,
        animation,
        ..mesh.options()?
    };
    let loaded = py
        .detach(|| load_files(&path, &options))
        .map_err(to_py_err)?;
    Ok(sequence_arrays(py, &loaded))
}

/// A sequence's geometry without an image: positions (K, V, 3), faces (F, 3), times (K,) or
/// `None`, the vertex map, the loader's warnings and a description of the source.
type GeometryArrays<'py> = (
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<i64>>,
    Option<Vec<f64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    Vec<String>,
    String,
);

/// Reads the surfaces `meshflow solve INPUT` reads, without an image (which they need not have).
#[pyfunction]
#[pyo3(signature = (path, times, fps, animation, mesh))]
fn load_mesh_sequence<'py>(
    py: Python<'py>,
    path: PathBuf,
    times: Option<Vec<f64>>,
    fps: Option<f64>,
    animation: Option<String>,
    mesh: MeshArgs,
) -> PyResult<GeometryArrays<'py>> {
    let options = LoadOptions {
        times,
        fps,
        animation,
        ..mesh.options()?
    };
    let loaded = py
        .detach(|| load_geometry(&path, &options))
        .map_err(to_py_err)?;
    Ok((
        frames_array(&loaded.positions).into_pyarray(py),
        faces_array(loaded.mesh.faces()).into_pyarray(py),
        loaded.times,
        Array1::from(loaded.vertex_map.to_npy()).into_pyarray(py),
        loaded.warnings.iter().map(ToString::to_string).collect(),
        loaded.source.describe(),
    ))
}

/// The process's memory limit and linked-file policy (`--memory-limit`,
/// `--allow-external-files`): sets those given (`"default"`: the machine's physical memory),
/// returns both as they are then.
#[pyfunction]
#[pyo3(signature = (memory_limit=None, allow_external_files=None))]
fn limits(memory_limit: Option<&str>, allow_external_files: Option<bool>) -> PyResult<(u64, bool)> {
    use meshflow::limits::{self, LinkedFiles};
    match memory_limit {
        Some("default") => limits::set_memory_limit(0),
        Some(size) => limits::set_memory_limit(
            limits::parse_size(size)
                .map_err(|e| PyValueError::new_err(format!("memory_limit: {e}")))?,
        ),
        None => {}
    }
    if let Some(allow) = allow_external_files {
        limits::set_linked_files(match allow {
            true => LinkedFiles::Anywhere,
            false => LinkedFiles::Contained,
        });
    }
    Ok((
        limits::memory_limit(),
        limits::linked_files() == LinkedFiles::Anywhere,
    ))
}

/// The library's message `message` in the Python package's words (for tests).
#[pyfunction]
fn python_words(message: &str) -> String {
    keywords::in_python_words(message)
}

/// One frame for `track`: its own positions (V_k, 3), faces (F_k, 3) and grey values (V_k,).
type TrackFrameArgs<'py> = (
    PyReadonlyArray2<'py, f64>,
    PyReadonlyArray2<'py, i64>,
    Option<PyReadonlyArray1<'py, f64>>,
);

/// positions (K, V, 3), faces (F, 3), grey values (K, V), times (K,), the report as JSON.
type TrackedArrays<'py> = (
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<i64>>,
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
    String,
);

/// Point clouds per frame chained into tracks by mutual nearest neighbours: (K, N, 3), NaN
/// where a track has no point.
#[pyfunction]
#[pyo3(signature = (frames, max_distance))]
fn match_tracks<'py>(
    py: Python<'py>,
    frames: Vec<PyReadonlyArray2<'py, f64>>,
    max_distance: Option<f64>,
) -> PyResult<Bound<'py, numpy::PyArray3<f64>>> {
    let frames: Vec<Vec<Vector3<f64>>> = frames.iter().map(read_points).collect();
    let tracks = py
        .detach(|| accuracy::match_tracks(&frames, max_distance))
        .map_err(|e| to_py_err(e.into()))?;
    let (shape, values) = tracks.to_array();
    let shape = (shape[0] as usize, shape[1] as usize, 3);
    Ok(Array3::from_shape_vec(shape, values)
        .expect("K × N × 3")
        .into_pyarray(py))
}

/// `meshflow track` on frames in memory: the tracked sequence (positions, faces, grey values,
/// times) and the report as JSON.
#[pyfunction]
#[pyo3(signature = (frames, times, max_step, keep_going, reference, reference_vertices, relax_iterations, align, keep_uncovered))]
#[allow(clippy::too_many_arguments)]
fn track<'py>(
    py: Python<'py>,
    frames: Vec<TrackFrameArgs<'py>>,
    times: Option<Vec<f64>>,
    max_step: Option<f64>,
    keep_going: bool,
    reference: Option<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, i64>)>,
    reference_vertices: Option<usize>,
    relax_iterations: usize,
    align: &str,
    keep_uncovered: bool,
) -> PyResult<TrackedArrays<'py>> {
    let frames = frames
        .iter()
        .map(|(positions, faces, grey)| -> PyResult<_> {
            let positions = read_points(positions);
            let intensity = match grey {
                Some(grey) => grey.as_array().to_vec(),
                None => vec![0.0; positions.len()],
            };
            Ok(tracking::TrackFrame {
                faces: read_faces(faces)?,
                positions,
                intensity,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let reference = reference
        .map(|(positions, faces)| -> PyResult<_> {
            Ok(shapes::Surface {
                positions: read_points(&positions),
                faces: read_faces(&faces)?,
            })
        })
        .transpose()?;
    let options = tracking::TrackOptions {
        max_step,
        keep_going,
        reference,
        reference_vertices,
        relaxation: match relax_iterations {
            0 => tracking::Relaxation::None,
            iterations => tracking::Relaxation::Arap { iterations },
        },
        alignment: align.parse().map_err(PyValueError::new_err)?,
        keep_uncovered,
    };
    let tracked = py
        .detach(|| tracking::track(&frames, times, &options))
        .map_err(|e| to_py_err(e.into()))?;
    let sequence = &tracked.sequence;
    let k = sequence.n_frames();
    let all: Vec<Vector3<f64>> = (0..k)
        .flat_map(|f| sequence.positions(f).expect("tracked in R^3").to_vec())
        .collect();
    let v = sequence.mesh().n_vertices();
    let positions = points_array(&all)
        .into_shape_with_order((k, v, 3))
        .expect("K × V × 3");
    let grey: Vec<f64> = (0..k)
        .flat_map(|f| sequence.intensities(f).to_vec())
        .collect();
    let report = serde_json::to_string(&tracked.report).expect("reports serialize");
    Ok((
        positions.into_pyarray(py),
        faces_array(sequence.mesh().faces()).into_pyarray(py),
        Array2::from_shape_vec((k, v), grey)
            .expect("K × V")
            .into_pyarray(py),
        sequence.times().to_vec().into_pyarray(py),
        report,
    ))
}

// ---------------------------------------------------------------------------------------------
// Microscopy: surfaces through points, volumes onto surfaces.

/// A moving surface fitted through point clouds (`meshflow surface`): `frames[k]` (N_k, 3).
/// Returns a dict: `positions` (K, V, 3), `faces` (F, 3), `reference`, `frames` (per-frame
/// fit), `mean_point_spacing`, `lambda`.
#[pyfunction]
#[pyo3(signature = (frames, shape, whole_sphere, vertices, edge_length, smoothing, margin))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
fn fit_surface<'py>(
    py: Python<'py>,
    frames: Vec<PyReadonlyArray2<'py, f64>>,
    shape: &str,
    whole_sphere: bool,
    vertices: Option<usize>,
    edge_length: Option<f64>,
    smoothing: f64,
    margin: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let shape = match (shape, whole_sphere) {
        ("sphere-like", whole) => Shape::SphereLike { whole },
        ("graph", false) => Shape::Graph,
        ("graph", true) => {
            return Err(value_error(
                "whole_sphere applies to shape=\"sphere-like\" only, not \"graph\"",
            ))
        }
        (other, _) => {
            return Err(value_error(format!(
                "shape: '{other}': expected sphere-like or graph"
            )))
        }
    };
    let resolution = match (vertices, edge_length) {
        (Some(_), Some(_)) => {
            return Err(value_error(
                "give one of vertices and edge_length, not both",
            ))
        }
        (Some(n), None) => Resolution::Vertices(n),
        (None, Some(length)) => Resolution::EdgeLength(length),
        (None, None) => FitOptions::default().resolution,
    };
    let options = FitOptions {
        shape,
        resolution,
        smoothing,
        margin,
    };
    let frames: Vec<Vec<Vector3<f64>>> = frames.iter().map(read_points).collect();
    let fitted = py
        .detach(|| surface::fit_surface(&frames, &options))
        .map_err(|e| to_py_err(e.into()))?;
    let k = fitted.positions.len();
    let v = fitted.positions.first().map_or(0, Vec::len);
    let all: Vec<Vector3<f64>> = fitted.positions.concat();
    let positions = points_array(&all)
        .into_shape_with_order((k, v, 3))
        .expect("K × V × 3");
    let out = PyDict::new(py);
    out.set_item("positions", positions.into_pyarray(py))?;
    out.set_item("faces", faces_array(&fitted.faces).into_pyarray(py))?;
    out.set_item("reference", reference_dict(py, &fitted.reference)?)?;
    let fits = fitted
        .frames
        .iter()
        .map(|fit| -> PyResult<_> {
            let dict = PyDict::new(py);
            dict.set_item("points", fit.points)?;
            dict.set_item("dropped", fit.dropped)?;
            dict.set_item("rms_residual", fit.rms_residual)?;
            dict.set_item("max_residual", fit.max_residual)?;
            Ok(dict)
        })
        .collect::<PyResult<Vec<_>>>()?;
    out.set_item("frames", fits)?;
    out.set_item("mean_point_spacing", fitted.mean_point_spacing)?;
    out.set_item("lambda", fitted.lambda)?;
    Ok(out)
}

/// `{"kind": "sphere", "centre", "radius", "cap_degrees" (None: whole), "axis"}` or
/// `{"kind": "plane", "min", "max"}` (the rectangle of `z = 0` in `x` and `y`); points as
/// tuples.
fn reference_dict<'py>(py: Python<'py>, reference: &Reference) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    match *reference {
        Reference::Sphere {
            centre,
            radius,
            cap_degrees,
            axis,
        } => {
            dict.set_item("kind", "sphere")?;
            dict.set_item("centre", (centre[0], centre[1], centre[2]))?;
            dict.set_item("radius", radius)?;
            dict.set_item("cap_degrees", cap_degrees)?;
            dict.set_item("axis", (axis[0], axis[1], axis[2]))?;
        }
        Reference::Plane { min, max } => {
            dict.set_item("kind", "plane")?;
            dict.set_item("min", (min[0], min[1]))?;
            dict.set_item("max", (max[0], max[1]))?;
        }
    }
    Ok(dict)
}

/// One volume's shape `[n_z, n_y, n_x]` and its values in C order.
fn read_volume(array: &PyReadonlyArray3<f32>) -> ([usize; 3], Vec<f32>) {
    let array = array.as_array();
    let shape = [array.shape()[0], array.shape()[1], array.shape()[2]];
    let values = match array.as_slice() {
        Some(values) => values.to_vec(),
        None => array.iter().copied().collect(),
    };
    (shape, values)
}

/// A recording carried onto a moving surface (`meshflow sample`): `volumes[k]` (Z, Y, X)
/// read along the vertex normals of frame `k` of (`positions`, `faces`). Returns a dict:
/// `values` (K, V), `outside` (per frame), `shell` (inside, outside, layers), `smoothing`.
#[pyfunction]
#[pyo3(signature = (volumes, positions, faces, voxel_size, origin, smoothing, shell, layers, reduce))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
fn sample_volume<'py>(
    py: Python<'py>,
    volumes: Vec<PyReadonlyArray3<'py, f32>>,
    positions: PyReadonlyArray3<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    voxel_size: (f64, f64, f64),
    origin: (f64, f64, f64),
    smoothing: Option<f64>,
    shell: Option<(f64, f64)>,
    layers: usize,
    reduce: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let reduce = parse::<Reduce>(reduce, "reduce")?;
    let faces = read_faces(&faces)?;
    let positions = read_positions(&positions);
    let n_vertices = positions.first().map_or(0, Vec::len);
    let grids: Vec<([usize; 3], Vec<f32>)> = volumes.iter().map(read_volume).collect();
    let voxel_size = Vector3::new(voxel_size.0, voxel_size.1, voxel_size.2);
    let origin = Vector3::new(origin.0, origin.1, origin.2);
    let sampled = py.detach(|| -> PyResult<SampledSequence> {
        let volumes = grids
            .into_iter()
            .enumerate()
            .map(|(k, (shape, values))| {
                Volume::new(shape, values, voxel_size, origin)
                    .map_err(|e| value_error(format!("volumes[{k}]: {e}")))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let mesh = Mesh::new(n_vertices, faces).map_err(|e| to_py_err(e.into()))?;
        // No shell given: the library's default reach (± two of the largest voxel sides),
        // with `layers` layers.
        let shell = shell
            .map(|(inside, outside)| Shell {
                inside,
                outside,
                layers,
            })
            .or_else(|| {
                let first = volumes.first()?;
                let reach = SampleOptions::default().shell_for(first);
                Some(Shell { layers, ..reach })
            });
        let options = SampleOptions {
            smoothing,
            shell,
            reduce,
        };
        volume::sample_sequence(&volumes, &mesh, &positions, &options)
            .map_err(|e| to_py_err(e.into()))
    })?;
    let k = sampled.values.len();
    let values =
        Array2::from_shape_vec((k, n_vertices), sampled.values.concat()).expect("K × V values");
    let out = PyDict::new(py);
    out.set_item("values", values.into_pyarray(py))?;
    out.set_item("outside", sampled.outside)?;
    let shell = sampled.shell;
    out.set_item("shell", (shell.inside, shell.outside, shell.layers))?;
    out.set_item("smoothing", sampled.smoothing)?;
    Ok(out)
}

#[pymodule]
fn _meshflow(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Flow>()?;
    m.add_function(wrap_pyfunction!(compute_flow, m)?)?;
    m.add_function(wrap_pyfunction!(operators, m)?)?;
    m.add_function(wrap_pyfunction!(load_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(load_mesh_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(python_words, m)?)?;
    m.add_function(wrap_pyfunction!(limits, m)?)?;
    m.add_function(wrap_pyfunction!(track, m)?)?;
    m.add_function(wrap_pyfunction!(match_tracks, m)?)?;
    m.add_function(wrap_pyfunction!(fit_surface, m)?)?;
    m.add_function(wrap_pyfunction!(sample_volume, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
