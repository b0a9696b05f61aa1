//! Reading a known flow ("ground truth") to measure a computed one against.
//!
//! The file is a `.npy` of shape `(S, V_file, 3)`, float64 or float32: `truth[s, i]` is the R^3
//! flow of slab `s` at vertex `i` of frame `s`, with `S = K − 1` slabs and `V_file` the vertex
//! count **of the input files** (before welding, as the user wrote them). It becomes `[s][w]`
//! over the welded vertices `w` through the [`Welding`]: the vector of the first file vertex of
//! each welded group. The other file vertices of a group (copies at a texture seam) must carry
//! the same flow, to within `1e-9` of the slab's largest true speed; anything else means the
//! file's numbering is not the input's. Every vector must be finite. Errors name the file, and
//! the slab and file vertices at fault.

use super::{read_npy_float, IoError, Welding};
use nalgebra::Vector3;
use std::path::Path;

/// How far apart (relative to the slab's largest true speed) two copies of a welded vertex may
/// be.
const DUPLICATE_TOLERANCE: f64 = 1e-9;

/// Reads the true flow of an `n_slabs`-slab sequence from `path` (see the module docs) and maps
/// it onto the welded vertices: `truth[s][w]`.
pub fn read_ground_truth(
    path: &Path,
    welding: &Welding,
    n_slabs: usize,
) -> Result<Vec<Vec<Vector3<f64>>>, IoError> {
    let array = read_npy_float(path)?;
    let n_file_vertices = welding.vertex_map.len();
    if array.shape != [n_slabs as u64, n_file_vertices as u64, 3] {
        return Err(IoError::format(
            path,
            format!(
                "ground truth has shape {:?}, expected ({n_slabs}, {n_file_vertices}, 3) = (slabs, vertices in the input files, 3)",
                array.shape
            ),
        ));
    }
    let row = 3 * n_file_vertices;
    (0..n_slabs)
        .map(|s| {
            let vectors: Vec<Vector3<f64>> = array.data[s * row..(s + 1) * row]
                .chunks_exact(3)
                .map(Vector3::from_column_slice)
                .collect();
            welded_slab(s, &vectors, welding).map_err(|message| IoError::format(path, message))
        })
        .collect()
}

/// The vectors of slab `s` (file numbering) on the welded vertices, checked.
fn welded_slab(
    s: usize,
    vectors: &[Vector3<f64>],
    welding: &Welding,
) -> Result<Vec<Vector3<f64>>, String> {
    if let Some(i) = vectors
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(format!(
            "slab {s}, vertex {i}: true flow {} is not finite",
            show(&vectors[i])
        ));
    }
    let largest = vectors.iter().map(|v| v.norm()).fold(0.0, f64::max);
    for (i, &w) in welding.vertex_map.iter().enumerate() {
        let first = welding.representatives[w as usize] as usize;
        if (vectors[i] - vectors[first]).norm() > DUPLICATE_TOLERANCE * largest {
            return Err(format!(
                "slab {s}: file vertices {first} and {i} are welded into one vertex (same position in every frame) but their true flows differ, {} vs {}",
                show(&vectors[first]),
                show(&vectors[i])
            ));
        }
    }
    Ok(welding
        .representatives
        .iter()
        .map(|&r| vectors[r as usize])
        .collect())
}

fn show(v: &Vector3<f64>) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}
