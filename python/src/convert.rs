//! Arrays in, arrays out: NumPy arrays copied into the library's types (positions, faces,
//! images) and results copied back in the input files' vertex numbering; keyword words parsed as
//! the CLI parses them.

use crate::value_error;
use meshflow::format::VertexValues;
use meshflow::load::VertexMap;
use nalgebra::{Matrix3x2, Vector2, Vector3};
use numpy::ndarray::{Array2, Array3};
use numpy::{PyReadonlyArray2, PyReadonlyArray3, PyReadonlyArrayDyn};
use pyo3::prelude::*;

pub(crate) fn read_positions(array: &PyReadonlyArray3<f64>) -> Vec<Vec<Vector3<f64>>> {
    array
        .as_array()
        .outer_iter()
        .map(read_points_view)
        .collect()
}

pub(crate) fn read_points(array: &PyReadonlyArray2<f64>) -> Vec<Vector3<f64>> {
    read_points_view(array.as_array())
}

pub(crate) fn read_points_view(frame: numpy::ndarray::ArrayView2<f64>) -> Vec<Vector3<f64>> {
    frame
        .outer_iter()
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .collect()
}

/// Each frame's image from a (K, V) grey or (K, V, C) channel array.
pub(crate) fn read_images(array: &PyReadonlyArrayDyn<f64>) -> PyResult<Vec<VertexValues>> {
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
pub(crate) fn read_faces(array: &PyReadonlyArray2<i64>) -> PyResult<Vec<[u32; 3]>> {
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
pub(crate) fn file_vectors(map: &VertexMap, rows: &[Vec<Vector3<f64>>]) -> Array3<f64> {
    let v = map.n_file_vertices();
    let values = rows
        .iter()
        .flat_map(|slab| map.file_rows(slab, Vector3::repeat(f64::NAN)))
        .flat_map(|u| [u.x, u.y, u.z])
        .collect();
    Array3::from_shape_vec((rows.len(), v, 3), values).expect("S × V × 3 values")
}

pub(crate) fn file_intrinsic(map: &VertexMap, rows: &[Vec<Vector2<f64>>]) -> Array3<f64> {
    let v = map.n_file_vertices();
    let values = rows
        .iter()
        .flat_map(|slab| map.file_rows(slab, Vector2::repeat(f64::NAN)))
        .flat_map(|u| [u.x, u.y])
        .collect();
    Array3::from_shape_vec((rows.len(), v, 2), values).expect("S × V × 2 values")
}

pub(crate) fn file_scalars(map: &VertexMap, rows: &[Vec<f64>]) -> Array2<f64> {
    let v = map.n_file_vertices();
    let values = rows
        .iter()
        .flat_map(|slab| map.file_rows(slab, f64::NAN))
        .collect();
    Array2::from_shape_vec((rows.len(), v), values).expect("S × V values")
}

/// Frames `P_i = [e1, e2]` as rows: `frames[i][k]` is basis vector `k` of vertex `i` in R^3
/// (as `frames.npy`).
pub(crate) fn frame_rows(frames: &[Matrix3x2<f64>]) -> Vec<[f64; 6]> {
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
pub(crate) fn frames_array(rows: &[Vec<Vector3<f64>>]) -> Array3<f64> {
    let n = rows.first().map_or(0, Vec::len);
    let values = rows
        .iter()
        .flatten()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    Array3::from_shape_vec((rows.len(), n, 3), values).expect("K × N × 3 values")
}

pub(crate) fn points_array(points: &[Vector3<f64>]) -> Array2<f64> {
    let values = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((points.len(), 3), values).expect("N × 3 values")
}

pub(crate) fn faces_array(faces: &[[u32; 3]]) -> Array2<i64> {
    let values = faces.iter().flatten().map(|&i| i as i64).collect();
    Array2::from_shape_vec((faces.len(), 3), values).expect("F × 3 indices")
}

/// `text`, if given, parsed; errors name the keyword `name`.
pub(crate) fn optional_parse<T: std::str::FromStr>(
    text: Option<&str>,
    name: &str,
) -> PyResult<Option<T>>
where
    T::Err: std::fmt::Display,
{
    text.map(|text| parse(text, name)).transpose()
}

pub(crate) fn parse<T: std::str::FromStr>(text: &str, name: &str) -> PyResult<T>
where
    T::Err: std::fmt::Display,
{
    text.parse()
        .map_err(|e| value_error(format!("{name}: {e}")))
}
