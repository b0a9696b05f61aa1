//! Orthonormal vertex tangent frames in R^3, and the push-forward of vertex vectors with them
//! (`docs/discretization.md` §8).
//!
//! The frames are geometry-central's `computeVertexTangentBasis` with our polar angles:
//!
//! ```text
//! n_i  = normalize( Σ_{T∋i} θ_{T,i} n_T )                       (corner angles and unit face
//!                                                               normals of the embedding)
//! e1_i = normalize( Σ_{i→j} Rot(n_i, −ϑ_i(i→j)) · Π_i (x_j − x_i) )
//! e2_i = n_i × e1_i
//! ```
//!
//! `Π_i = I − n_i n_iᵀ` projects onto the tangent plane and `Rot(n, ψ)` turns about `n` by `ψ`
//! (right-handed). The sum runs over every outgoing edge, at a boundary vertex including the
//! last edge of its fan, and `ϑ_i` is the edge's polar angle in the vertex frame
//! ([`Connection::halfedge_angle`], from the intrinsic geometry). Each edge rotated back by its
//! polar angle votes for the direction of polar angle 0; the votes agree exactly on a flat
//! mesh and to `O(h)` on a smooth one.
//!
//! A vertex vector `u_i = (x, y)` in the vertex frame is the R^3 vector `x e1_i + y e2_i`:
//! `U_i = P_i u_i` with the orthonormal 3×2 frame matrix `P_i = [e1_i, e2_i]`. Turning the
//! reference edge by `c` turns every vote, hence `e1_i`, by `c` and the intrinsic components
//! by `−c`, so `U_i` does not depend on the reference edge.
//!
//! This replaces the corner-angle-weighted mean of the face maps `F_T R_{T,i}`, which shrank
//! vectors at vertices with a large angle defect (to 0.31 of their length at a scan's sharp
//! vertices) and gave frames that were not orthonormal.
//!
//! Degenerate votes, possible only on meshes folded back onto themselves, fall back to a
//! deterministic choice so the frames stay orthonormal: a zero normal sum takes the normal of
//! the vertex's first face, a zero first-axis sum the projected reference edge, and a
//! reference edge along the normal any unit vector orthogonal to it.

use super::Connection;
use crate::geometry::{check_positions, GeometryError, IntrinsicGeometry};
use crate::mesh::Mesh;
use nalgebra::{Matrix3x2, Vector2, Vector3};

/// Below this fraction of its largest possible length, a sum of votes counts as zero.
const DEGENERATE_SUM: f64 = 1e-12;

/// `P_i = [e1_i, e2_i]` for every vertex (see the module docs): the orthonormal tangent frame
/// in R^3 of vertex `i`'s intrinsic frame, for the embedding `positions`.
///
/// `geometry` and `connection` supply the polar angles; they may come from other edge lengths
/// than `positions` (a slab's mean lengths, pushed forward on frame `s`).
pub fn vertex_frames_in_r3(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    positions: &[Vector3<f64>],
) -> Result<Vec<Matrix3x2<f64>>, GeometryError> {
    check_positions(mesh, positions)?;
    let normals = vertex_normals(mesh, positions);
    Ok((0..mesh.n_vertices())
        .map(|i| {
            let e1 = first_axis(mesh, geometry, connection, positions, i, &normals[i]);
            Matrix3x2::from_columns(&[e1, normals[i].cross(&e1)])
        })
        .collect())
}

/// `n_i`: the corner-angle-weighted mean of the unit normals of the faces at `i`, normalized.
pub fn vertex_normals(mesh: &Mesh, positions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let mut sums = vec![Vector3::zeros(); mesh.n_vertices()];
    let mut first_face_normal = vec![None; mesh.n_vertices()];
    for face in mesh.faces() {
        let x = face.map(|v| positions[v as usize]);
        let normal = (x[1] - x[0]).cross(&(x[2] - x[0])).normalize();
        for c in 0..3 {
            let (i, prev, next) = (face[c] as usize, x[(c + 2) % 3], x[(c + 1) % 3]);
            let (a, b) = (next - x[c], prev - x[c]);
            let angle = a.cross(&b).norm().atan2(a.dot(&b));
            sums[i] += angle * normal;
            first_face_normal[i].get_or_insert(normal);
        }
    }
    sums.iter()
        .zip(first_face_normal)
        .map(|(sum, fallback)| {
            let fallback = fallback.expect("a validated mesh uses every vertex");
            // Angle sums are at most a few 2π: DEGENERATE_SUM relative to 1 is safe.
            sum.try_normalize(DEGENERATE_SUM).unwrap_or(fallback)
        })
        .collect()
}

/// `e1_i`: the normalized sum of the outgoing edges' votes for polar angle 0.
fn first_axis(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    positions: &[Vector3<f64>],
    i: usize,
    normal: &Vector3<f64>,
) -> Vector3<f64> {
    let tangent = |j: u32| {
        let edge = positions[j as usize] - positions[i];
        edge - normal * normal.dot(&edge)
    };
    let mut sum = Vector3::zeros();
    let mut scale = 0.0;
    for (j, polar_angle) in connection.outgoing_edges(mesh, geometry, i) {
        let projected = tangent(j);
        let (sin, cos) = polar_angle.sin_cos();
        sum += cos * projected - sin * normal.cross(&projected);
        scale += projected.norm();
    }
    if let Some(axis) = sum.try_normalize(DEGENERATE_SUM * scale) {
        return axis;
    }
    let [_, reference] = mesh.halfedge_vertices(mesh.vertex_fan(i)[0].first_halfedge());
    tangent(reference)
        .try_normalize(DEGENERATE_SUM * (positions[reference as usize] - positions[i]).norm())
        .unwrap_or_else(|| any_orthogonal_unit(normal))
}

/// A unit vector orthogonal to the unit vector `n`: `n` crossed with the coordinate axis it is
/// least aligned with.
fn any_orthogonal_unit(n: &Vector3<f64>) -> Vector3<f64> {
    let axis = n.iamin();
    n.cross(&Vector3::ith(axis, 1.0)).normalize()
}

/// `U_i = P_i u_i` for every vertex, with `P_i` from [`vertex_frames_in_r3`].
pub fn push_forward(frames: &[Matrix3x2<f64>], vectors: &[Vector2<f64>]) -> Vec<Vector3<f64>> {
    frames.iter().zip(vectors).map(|(p, u)| p * u).collect()
}
