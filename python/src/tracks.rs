//! Tracking: point clouds chained into tracks, and frames with their own meshes made one
//! sequence (`meshflow track`).

use crate::convert::{faces_array, points_array, read_faces, read_points};
use crate::to_py_err;
use meshflow::{accuracy, shapes, track as tracking};
use nalgebra::Vector3;
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// One frame for `track`: its own positions (V_k, 3), faces (F_k, 3) and grey values (V_k,).
pub(crate) type TrackFrameArgs<'py> = (
    PyReadonlyArray2<'py, f64>,
    PyReadonlyArray2<'py, i64>,
    Option<PyReadonlyArray1<'py, f64>>,
);

/// positions (K, V, 3), faces (F, 3), grey values (K, V), times (K,), the report as JSON.
pub(crate) type TrackedArrays<'py> = (
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
pub(crate) fn match_tracks<'py>(
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
pub(crate) fn track<'py>(
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
        // As `meshflow track`: the alignment's motion is taken out.
        keep_coordinates: false,
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
