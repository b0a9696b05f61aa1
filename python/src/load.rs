//! Files and arrays in: sequences as `meshflow solve` reads them, surfaces without an image,
//! and one mesh's operators (`meshflow operators`).

use crate::convert::{faces_array, frame_rows, frames_array, parse, read_faces, read_points};
use crate::to_py_err;
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::flow::MeshSequence;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::load::{
    load_geometry, load_sequence as load_files, mesh_from_arrays, LoadOptions, LoadedSequence,
};
use meshflow::{fem, Error};
use nalgebra::Vector3;
use numpy::ndarray::{Array1, Array3};
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// How meshes are built from faces (the CLI's `--no-weld`, `--weld-tolerance`, `--repair`)
/// and which image channels are used (`--channels`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub(crate) struct MeshArgs {
    weld: bool,
    weld_tolerance: f64,
    repair: bool,
    channels: String,
}

impl MeshArgs {
    pub(crate) fn options(&self) -> PyResult<LoadOptions> {
        Ok(LoadOptions {
            weld: self.weld,
            weld_tolerance: self.weld_tolerance,
            repair: self.repair,
            channels: parse(&self.channels, "channels")?,
            ..LoadOptions::default()
        })
    }
}

/// `(data, indices, indptr, shape)` of a CSC matrix, for `scipy.sparse.csc_matrix`.
pub(crate) type Csc<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    (usize, usize),
);

pub(crate) fn csc<'py>(py: Python<'py>, matrix: &fem::SparseMatrix) -> Csc<'py> {
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
pub(crate) fn operators<'py>(
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
pub(crate) type SequenceArrays<'py> = (
    Bound<'py, numpy::PyArray3<f64>>,
    Bound<'py, numpy::PyArray2<i64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<i64>>,
    Vec<String>,
    String,
);

pub(crate) fn sequence_arrays<'py>(
    py: Python<'py>,
    loaded: &LoadedSequence,
) -> SequenceArrays<'py> {
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
pub(crate) fn image_array<'py>(
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
pub(crate) fn load_sequence<'py>(
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
pub(crate) type GeometryArrays<'py> = (
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
pub(crate) fn load_mesh_sequence<'py>(
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
