//! Reading a known flow ("ground truth") to measure a computed one against.
//!
//! The file is a `.npy` of shape `(S, V_file, 3)`, float64 or float32: `truth[s, i]` is the R^3
//! flow of slab `s` at vertex `i` of frame `s`, with `S = K − 1` slabs and `V_file` the vertex
//! count **of the input files** (before welding, as the user wrote them). It becomes `[s][m]`
//! over the mesh vertices `m` through the [`VertexMap`]: the vector of each mesh vertex's
//! representative file vertex. The other file vertices mapped to it (copies at a texture seam)
//! must carry the same flow, to within `1e-9` of the slab's largest true speed; anything else
//! means the file's numbering is not the input's. Every vector of a file vertex that was not
//! dropped must be finite (dropped ones are ignored). Errors name the file, and the slab and
//! file vertices at fault.

use super::VertexMap;
use crate::format::{read_npy_float, read_npy_float_rows, IoError};
use nalgebra::Vector3;
use std::path::Path;

/// How far apart (relative to the slab's largest true speed) two copies of a welded vertex may
/// be.
const DUPLICATE_TOLERANCE: f64 = 1e-9;

/// Reads the true flow of an `n_slabs`-slab sequence from `path` (see the module docs) and maps
/// it onto the mesh vertices: `truth[s][m]`.
pub fn read_ground_truth(
    path: &Path,
    vertex_map: &VertexMap,
    n_slabs: usize,
) -> Result<Vec<Vec<Vector3<f64>>>, IoError> {
    let n_file_vertices = vertex_map.n_file_vertices();
    // The header alone first: a file of the wrong shape is refused before its data is read.
    let (header, rows) = read_npy_float_rows(path, &|_| false)?;
    let shape: Vec<u64> = std::iter::once(rows)
        .chain(header.shape.iter().skip(1).copied())
        .collect();
    if shape != [n_slabs as u64, n_file_vertices as u64, 3] {
        return Err(IoError::format(
            path,
            format!(
                "ground truth has shape {shape:?}, expected ({n_slabs}, {n_file_vertices}, 3) = (slabs, vertices in the input files, 3)"
            ),
        ));
    }
    let array = read_npy_float(path)?;
    let row = 3 * n_file_vertices;
    (0..n_slabs)
        .map(|s| {
            let vectors: Vec<Vector3<f64>> = array.data[s * row..(s + 1) * row]
                .chunks_exact(3)
                .map(Vector3::from_column_slice)
                .collect();
            mesh_slab(s, &vectors, vertex_map).map_err(|message| IoError::format(path, message))
        })
        .collect()
}

/// The vectors of slab `s` (file numbering) on the mesh vertices, checked.
fn mesh_slab(
    s: usize,
    vectors: &[Vector3<f64>],
    vertex_map: &VertexMap,
) -> Result<Vec<Vector3<f64>>, String> {
    let kept = |i: &usize| vertex_map.mesh_vertex(*i).is_some();
    if let Some(i) = (0..vectors.len())
        .filter(kept)
        .find(|&i| !vectors[i].iter().all(|c| c.is_finite()))
    {
        return Err(format!(
            "slab {s}, vertex {i}: true flow {} is not finite",
            show(&vectors[i])
        ));
    }
    let largest = (0..vectors.len())
        .filter(kept)
        .map(|i| vectors[i].norm())
        .fold(0.0, f64::max);
    for i in 0..vectors.len() {
        let Some(m) = vertex_map.mesh_vertex(i) else {
            continue;
        };
        let first = vertex_map.representative(m);
        if (vectors[i] - vectors[first]).norm() > DUPLICATE_TOLERANCE * largest {
            return Err(format!(
                "slab {s}: file vertices {first} and {i} are welded into one vertex (same position in every frame) but their true flows differ, {} vs {}",
                show(&vectors[first]),
                show(&vectors[i])
            ));
        }
    }
    Ok((0..vertex_map.n_mesh_vertices())
        .map(|m| vectors[vertex_map.representative(m)])
        .collect())
}

fn show(v: &Vector3<f64>) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}
