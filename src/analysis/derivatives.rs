//! Divergence and curl of a P1 tangent field, per face and in the weak vertex form.
//!
//! In face `T` the corner vectors are carried into the face frame, `v_a = R_{T,a} u_a`, and
//! interpolated linearly; with the hat gradients `g_a = ∇λ_a` the field's gradient is the
//! constant 2×2 matrix (the covariant derivative the element matrices use)
//!
//! ```text
//! ∇U_T = Σ_a v_a g_aᵀ,      (∇U)_ij = ∂_j U_i,
//! div_T = tr ∇U_T = Σ_a v_a · g_a,      curl_T = (∇U)_21 − (∇U)_12 = Σ_a g_a × v_a,
//! ```
//!
//! with `a × b = a_x b_y − a_y b_x` in the face's counter-clockwise frame, so that a field
//! turning counter-clockwise about the surface normal (`J x`, `J` the rotation by +90°) has
//! positive curl, and `curl(J∇f) = div(∇f) = Δf`.
//!
//! The weak vertex form integrates against the hat function of vertex `i` over its
//! barycentric area `A_i = Σ_{T∋i} A_T / 3` (by parts, exact for the piecewise linear field):
//!
//! ```text
//! A_i div_i  = −Σ_{T∋i} A_T g_i·Ū_T + Σ_{e∋i, e ⊂ ∂M} |e| n_e·(2v_i + v_j)/6
//! A_i curl_i = −Σ_{T∋i} A_T g_i×Ū_T + Σ_{e∋i, e ⊂ ∂M} |e| n_e×(2v_i + v_j)/6
//! ```
//!
//! with `Ū_T` the mean of the face's corner vectors and `n_e` the outward normal of a
//! boundary edge `e = (i, j)` (the second sums vanish on closed surfaces). Units: a flow in
//! length per time gives both in 1/time.

use crate::connection::Connection;
use crate::geometry::{IntrinsicGeometry, Triangle};
use crate::mesh::Mesh;
use nalgebra::{Matrix2, Vector2};

/// `a × b = a_x b_y − a_y b_x`.
pub fn cross(a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// The corner vectors of face `f` carried into its frame, `v_a = R_{T,a} u_a`.
pub fn face_vectors(
    mesh: &Mesh,
    connection: &Connection,
    f: usize,
    u: &[Vector2<f64>],
) -> [Vector2<f64>; 3] {
    let rotations = connection.face_rotations(f);
    let face = mesh.faces()[f];
    std::array::from_fn(|a| rotations[a] * u[face[a] as usize])
}

/// `∇U_T = Σ_a v_a g_aᵀ` of the linear field with face-frame corner vectors `v`.
pub fn field_gradient(triangle: &Triangle, v: &[Vector2<f64>; 3]) -> Matrix2<f64> {
    let g = triangle.hat_gradients();
    (0..3).map(|a| v[a] * g[a].transpose()).sum()
}

/// `(div, curl)` of a face gradient `∇U`.
pub fn divergence_and_curl(gradient: &Matrix2<f64>) -> (f64, f64) {
    (gradient.trace(), gradient[(1, 0)] - gradient[(0, 1)])
}

/// Per vertex, the weak divergence and curl of the field whose corner vectors, carried into
/// each face's frame, are `vectors[f]` ([`face_vectors`]); see the module documentation.
pub fn vertex_divergence_and_curl(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    vectors: &[[Vector2<f64>; 3]],
) -> (Vec<f64>, Vec<f64>) {
    let n = mesh.n_vertices();
    let (mut div, mut curl, mut area) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for ((f, face), v) in mesh.faces().iter().enumerate().zip(vectors) {
        let triangle = geometry.triangle(f);
        let mean = (v[0] + v[1] + v[2]) / 3.0;
        let g = triangle.hat_gradients();
        let layout = triangle.layout();
        for a in 0..3 {
            let i = face[a] as usize;
            area[i] += triangle.area / 3.0;
            div[i] -= triangle.area * g[a].dot(&mean);
            curl[i] -= triangle.area * cross(&g[a], &mean);
            // Boundary edge a→b of this face: its flux, shared by its two ends.
            if mesh.is_boundary_halfedge(3 * f + a) {
                let b = (a + 1) % 3;
                let edge = layout[b] - layout[a];
                let outward = Vector2::new(edge.y, -edge.x); // |outward| = |e|
                for (here, there) in [(a, b), (b, a)] {
                    let flux = (2.0 * v[here] + v[there]) / 6.0;
                    div[face[here] as usize] += outward.dot(&flux);
                    curl[face[here] as usize] += cross(&outward, &flux);
                }
            }
        }
    }
    for i in 0..n {
        div[i] /= area[i];
        curl[i] /= area[i];
    }
    (div, curl)
}
