//! Push-forward of vertex tangent vectors to R^3 (`docs/discretization.md` §8).
//!
//! Face `T = (a, b, c)` maps its layout onto its embedding by the affine map with linear part
//! `F_T = E3 · E2⁻¹` (3×2), `E3 = [x_b − x_a, x_c − x_a]` in R^3 and `E2` the same edge vectors
//! in the layout. A vertex vector `u_i` becomes the corner-angle-weighted mean
//!
//! ```text
//! U_i = Σ_T θ_{T,i} F_T R_{T,i} u_i / Σ_T θ_{T,i}
//! ```
//!
//! which is linear in `u_i`: `U_i = P_i u_i` with the 3×2 *frame matrix* `P_i` whose columns are
//! the images of the frame's basis vectors. When the embedding is not the one the intrinsic
//! geometry was computed from (a slab's mean lengths against frame `s`), `F_T` is not an
//! isometry and `P_i` absorbs the stretch.

use super::Connection;
use crate::geometry::{check_positions, GeometryError, IntrinsicGeometry};
use crate::mesh::Mesh;
use nalgebra::{Matrix3x2, SMatrix, Vector2, Vector3};

/// `P_i` for every vertex: columns are the R^3 images of the vertex frame's basis vectors.
pub fn vertex_frames_in_r3(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    positions: &[Vector3<f64>],
) -> Result<Vec<Matrix3x2<f64>>, GeometryError> {
    check_positions(mesh, positions)?;
    let face_edges: Vec<Matrix3x2<f64>> = mesh
        .faces()
        .iter()
        .map(|face| {
            let [a, b, c] = face.map(|v| positions[v as usize]);
            Matrix3x2::from_columns(&[b - a, c - a])
        })
        .collect();
    Ok(vertex_frames_for_face_maps(
        mesh,
        geometry,
        connection,
        &face_edges,
    ))
}

/// `P_i` for any piecewise-linear map of the faces into R^D, given by the images
/// `face_edges[f] = [x_b − x_a, x_c − x_a]` (D×2) of each face's first two edges: an embedding
/// (D = 3, [`vertex_frames_in_r3`]) or a chart into the parameter plane (D = 2), which need not
/// be continuous across faces (a periodic parameter domain). `face_edges.len()` must equal the
/// number of faces.
pub fn vertex_frames_for_face_maps<const D: usize>(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    face_edges: &[SMatrix<f64, D, 2>],
) -> Vec<SMatrix<f64, D, 2>> {
    assert_eq!(face_edges.len(), mesh.n_faces(), "one edge matrix per face");
    let mut frames = vec![SMatrix::<f64, D, 2>::zeros(); mesh.n_vertices()];
    for (f, (face, edges)) in mesh.faces().iter().zip(face_edges).enumerate() {
        let triangle = geometry.triangle(f);
        // The layout edge matrix is upper triangular with positive diagonal: always invertible.
        let layout_inverse = triangle
            .layout_edge_matrix()
            .try_inverse()
            .expect("layout of a validated triangle is invertible");
        let face_map = edges * layout_inverse;
        for (local, &v) in face.iter().enumerate() {
            let weight = triangle.angles[local];
            frames[v as usize] += weight * face_map * connection.vertex_to_face(f, local);
        }
    }
    for (frame, sum) in frames.iter_mut().zip(geometry.vertex_angle_sums()) {
        *frame /= *sum;
    }
    frames
}

/// `U_i = P_i u_i` for every vertex, with `P_i` from [`vertex_frames_in_r3`].
pub fn push_forward(frames: &[Matrix3x2<f64>], vectors: &[Vector2<f64>]) -> Vec<Vector3<f64>> {
    frames.iter().zip(vectors).map(|(p, u)| p * u).collect()
}
