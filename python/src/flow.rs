//! The flow: `compute_flow`'s keywords as the library's [`FlowOptions`], progress and Ctrl-C
//! during a solve ([`PythonObserver`]), and the [`Flow`] class with its arrays, scores,
//! pictures and outputs.

use crate::convert::{
    faces_array, file_intrinsic, file_scalars, file_vectors, frame_rows, frames_array,
    optional_parse, parse, points_array, read_faces, read_images, read_points, read_positions,
};
use crate::load::MeshArgs;
use crate::{to_py_err, value_error};
use meshflow::flow::{
    FlowError, FlowOptions, FlowParams, FlowProblem, FlowResult, SolveEvent, SolveObserver,
};
use meshflow::load::{sequence_from_arrays, LoadOptions, LoadedSequence};
use meshflow::render::{
    result_views, write_chosen_slab_pictures, FigureOptions, SlabSelection, UpAxis, UpChoice, View,
};
use meshflow::run::{
    write_flow_outputs, write_run_input, OutputFormat, Overwrite, SolveRecord, StagedDir,
};
use meshflow::{accuracy, Error};
use nalgebra::Vector3;
use numpy::ndarray::{Array1, Array2, Array3, Array4};
use numpy::{
    IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyReadonlyArrayDyn,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Mutex;

/// Calls the Python `progress` callback with each [`SolveEvent`] as a dict, and checks for
/// signals (Ctrl-C); the first exception either raises stops the solve and is kept for
/// re-raising.
pub(crate) struct PythonObserver {
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

pub(crate) fn event_dict<'py>(py: Python<'py>, event: SolveEvent) -> PyResult<Bound<'py, PyDict>> {
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
        SolveEvent::LargeMotion {
            linearization_error,
            threshold,
        } => {
            dict.set_item("kind", "large_motion")?;
            dict.set_item("linearization_error", linearization_error)?;
            dict.set_item("threshold", threshold)?;
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
pub(crate) struct ParamArgs {
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
    robust_data: Option<String>,
    median_filter: bool,
    local_integration: Option<f64>,
    channel_weights: Option<Vec<f64>>,
    boundary: String,
    time_coupling: String,
    solver: String,
    tolerance: f64,
    levels: Option<usize>,
    warps: Option<usize>,
    /// `None`: checked (the default); `True`: always warp; `False`: never.
    large_motion: Option<bool>,
}

impl ParamArgs {
    /// The keywords as the library's [`FlowOptions`] (words parsed as the CLI parses them),
    /// checked and made into parameters by [`FlowOptions::params`].
    fn params(&self) -> PyResult<FlowParams> {
        let options = FlowOptions {
            alpha: self.alpha,
            time_scale: self.time_scale,
            beta: self.beta,
            speed_penalty: self.speed_penalty,
            gamma: self.gamma,
            spread: self.spread,
            regularizer: parse(&self.regularizer, "regularizer")?,
            dirichlet_mix: self.dirichlet_mix,
            anisotropic: optional_parse(self.anisotropic.as_deref(), "anisotropic")?,
            anisotropic_sigma: self.anisotropic_sigma,
            anisotropic_in_time: self.anisotropic_in_time,
            robust_smoothness: optional_parse(
                self.robust_smoothness.as_deref(),
                "robust_smoothness",
            )?,
            flow_driven: parse(&self.flow_driven, "flow_driven")?,
            robust_data: optional_parse(self.robust_data.as_deref(), "robust_data")?,
            median_filter: self.median_filter,
            local_integration: self.local_integration,
            detect_large_motion: self.large_motion != Some(false),
            channel_weights: self.channel_weights.clone(),
            boundary: parse(&self.boundary, "boundary")?,
            time_coupling: parse(&self.time_coupling, "time_coupling")?,
            solver: parse(&self.solver, "solver")?,
            tolerance: self.tolerance,
            levels: self.levels,
            warps: self.warps,
            large_motion: self.large_motion == Some(true),
        };
        options.params().map_err(|e| to_py_err(e.into()))
    }
}

/// A computed flow: arrays in the input's vertex numbering, and what `write` needs.
#[pyclass(module = "meshflow._meshflow", frozen)]
pub(crate) struct Flow {
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

    /// Per slab, the scale `ε` of the robust data term as used (`"auto"` resolved); empty
    /// without it.
    #[getter]
    fn robust_data_scales(&self) -> Vec<f64> {
        self.result.robust_data_scales.clone()
    }

    /// The check of the linear model against the images warped by its flow, as
    /// `{"linearization_error", "threshold", "warped"}`; `None` where it did not run
    /// (`large_motion` True or False, or warping asked for).
    #[getter]
    fn large_motion<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(check) = &self.result.motion_check else {
            return Ok(None);
        };
        let dict = PyDict::new(py);
        dict.set_item("linearization_error", check.linearization_error)?;
        dict.set_item("threshold", check.threshold)?;
        dict.set_item("warped", check.warped)?;
        Ok(Some(dict))
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
    /// staged and renamed into place whole; with `recording` (the recording the image was
    /// sampled from: `path`, `shape` (z, y, x), `voxel_size`, `origin` (x, y, z), `channel`,
    /// `resolution_level`) named in its manifest, as `meshflow sample` names it.
    #[pyo3(signature = (out, formats, force, recording=None))]
    fn write(
        &self,
        py: Python<'_>,
        out: PathBuf,
        formats: Vec<String>,
        force: bool,
        recording: Option<RecordingArgs>,
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
            staged.record_solve(SolveRecord::new(None, load, &out));
            if let Some(recording) = recording {
                staged.record_recording(recording.record(&out));
            }
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
pub(crate) type TrajectoryArrays<'py> = (
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<i64>>,
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, numpy::PyArray1<bool>>,
);

impl Flow {
    /// The view of the pictures: the default angles and the input's up axis.
    fn view(&self) -> View {
        UpChoice::of_sequence(&self.loaded).view()
    }
}

/// Builds the sequence, solves, and returns the [`Flow`]; the GIL is released throughout.
#[pyfunction]
#[pyo3(signature = (positions, faces, intensity, times, params, mesh, progress))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per array
pub(crate) fn compute_flow(
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

/// The recording a flow's image was sampled from, as `Flow.write` takes it.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub(crate) struct RecordingArgs {
    path: PathBuf,
    shape: [usize; 3],
    voxel_size: [f64; 3],
    origin: [f64; 3],
    channel: Option<usize>,
    resolution_level: usize,
}

impl RecordingArgs {
    /// The manifest's record for the output `out`.
    fn record(self, out: &std::path::Path) -> meshflow::run::RecordingRecord {
        meshflow::run::RecordingRecord {
            path: meshflow::run::RecordingRecord::path_from(out, &self.path),
            shape: self.shape,
            voxel_size: self.voxel_size,
            origin: self.origin,
            channel: self.channel,
            resolution_level: self.resolution_level,
        }
    }
}
