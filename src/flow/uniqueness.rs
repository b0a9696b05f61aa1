//! Does the energy have a unique minimizer? Only a question when `β = 0`.
//!
//! The analysis below is the covariant regularizer's. It holds for the strain regularizer
//! too as far as it goes: a parallel field is a Killing field (`∇u = 0` makes `Sym ∇u = 0`),
//! so every kernel found here is one of the strain energy as well; rotations the image leaves
//! free (a pattern symmetric about an axis) are a kernel of the pure strain energy only, which
//! this check does not look for (the factorization or the solver then reports the singular
//! system, and `β > 0` removes it).
//!
//! Every term of `E` is a non-negative quadratic, so `A u = 0` iff every term vanishes at `u`:
//! `K_s u_s = 0` makes `u_s` covariantly constant on each slab (on every face the three
//! transported corner vectors coincide, since the cotan stiffness of a triangle only
//! annihilates constants); the data term then needs `G_T · U_T = 0` on every face; the time
//! term (when `α < ∞`) needs `U^{s+1}_T = Q_T U^s_T` on every face. On one connected component,
//! with face angles `θ_T` of a parallel field (`U_T = Rot(θ_T) c`), this reduces to 2×2
//! algebra: the component carries a kernel iff the parallel fields exist, match in time by
//! one rotation per link, and `N = Σ_s Δt_s Rot(Φ_s)ᵀ (Σ_T A_T h_T h_Tᵀ) Rot(Φ_s)` with
//! `h_T = Rot(−θ_T) G_T` is singular. Dirichlet boundaries pin such fields to zero.

use super::slab::{Slab, TimeLink};
use super::{Boundary, FlowError, FlowParams, Weights};
use crate::connection::{rotation, wrap_angle};
use crate::mesh::Mesh;
use nalgebra::Matrix2;

/// Angles agreeing to this many radians are equal: far above round-off, far below any
/// holonomy a real mesh produces.
const ANGLE_TOLERANCE: f64 = 1e-8;
/// `det N ≤ this · (tr N)²` means `N` has a null direction.
const SINGULAR_RATIO: f64 = 1e-10;

/// `Ok` when the minimizer is unique; [`FlowError::Singular`] otherwise.
pub fn check_unique_minimizer(
    mesh: &Mesh,
    slabs: &[Slab],
    links: &[TimeLink],
    params: &FlowParams,
    weights: &Weights,
) -> Result<(), FlowError> {
    if weights.beta > 0.0 {
        return Ok(());
    }
    for component in mesh.connected_components() {
        let pinned = params.boundary == Boundary::Dirichlet
            && component.iter().any(|&v| mesh.is_boundary_vertex(v));
        if pinned {
            continue;
        }
        let angles: Vec<Option<Vec<f64>>> = slabs
            .iter()
            .map(|slab| parallel_face_angles(mesh, slab, component[0]))
            .collect();
        if !weights.is_coupled() {
            for (s, face_angles) in angles.iter().enumerate() {
                if let Some(theta) = face_angles {
                    if is_singular(&data_matrix(mesh, &slabs[s], theta, &component)) {
                        return Err(singular(format!("slab {s} carries a covariantly constant field along which the image has no gradient")));
                    }
                }
            }
            continue;
        }
        let Some(theta) = angles.into_iter().collect::<Option<Vec<_>>>() else {
            continue;
        };
        let Some(total) = steady_data_matrix(mesh, slabs, links, &theta, &component) else {
            continue;
        };
        if is_singular(&total) {
            return Err(singular(format!(
                "vertex {} lies on a part of the surface that carries a covariantly constant field, steady in time, along which the image has no gradient",
                component[0]
            )));
        }
    }
    Ok(())
}

/// `N` for a field that is parallel in every slab, or `None` when the time links do not carry
/// one slab's parallel field onto the next by a single rotation.
fn steady_data_matrix(
    mesh: &Mesh,
    slabs: &[Slab],
    links: &[TimeLink],
    theta: &[Vec<f64>],
    component: &[usize],
) -> Option<Matrix2<f64>> {
    let faces = component_faces(mesh, component);
    let mut total = Matrix2::zeros();
    let mut phi = 0.0;
    for (s, slab) in slabs.iter().enumerate() {
        let rotate = rotation(phi);
        total +=
            rotate.transpose() * data_matrix(mesh, slab, &theta[s], component) * rotate * slab.dt;
        if let Some(link) = links.get(s) {
            let kappa = |f: usize| link.polar_angles[f] + theta[s][f] - theta[s + 1][f];
            let first = kappa(faces[0]);
            if faces
                .iter()
                .any(|&f| wrap_angle(kappa(f) - first).abs() > ANGLE_TOLERANCE)
            {
                return None;
            }
            phi += first;
        }
    }
    Some(total)
}

fn singular(reason: String) -> FlowError {
    FlowError::Singular { reason }
}

fn is_singular(n: &Matrix2<f64>) -> bool {
    n.determinant() <= SINGULAR_RATIO * n.trace() * n.trace()
}

/// `Σ_T A_T Rot(−θ_T) (Σ_c w_c G_c G_cᵀ) Rot(θ_T)` over the faces of a component: for one
/// channel `Σ_T A_T h_T h_Tᵀ`, `h_T = Rot(−θ_T) G_T`.
fn data_matrix(mesh: &Mesh, slab: &Slab, theta: &[f64], component: &[usize]) -> Matrix2<f64> {
    component_faces(mesh, component)
        .into_iter()
        .map(|f| {
            let face = mesh.faces()[f];
            let triangle = slab.geometry.triangle(f);
            let turn = rotation(-theta[f]);
            turn * slab.structure_tensor(&face, f) * turn.transpose() * triangle.area
        })
        .sum()
}

/// Face angles `θ_T` (indexed by face; faces outside the component are 0) of a covariantly
/// constant field on the component of `start`, or `None` when the holonomy is not trivial.
fn parallel_face_angles(mesh: &Mesh, slab: &Slab, start: usize) -> Option<Vec<f64>> {
    let mut vertex_angle = vec![f64::NAN; mesh.n_vertices()];
    let mut face_angle = vec![f64::NAN; mesh.n_faces()];
    vertex_angle[start] = 0.0;
    let mut queue = vec![start];
    while let Some(v) = queue.pop() {
        for corner in mesh.vertex_fan(v) {
            let f = corner.face as usize;
            let theta_t = vertex_angle[v]
                + slab
                    .connection
                    .corner_rotation_angle(f, corner.local as usize);
            if !face_angle[f].is_nan() {
                if wrap_angle(face_angle[f] - theta_t).abs() > ANGLE_TOLERANCE {
                    return None;
                }
                continue;
            }
            face_angle[f] = theta_t;
            for (local, &w) in mesh.faces()[f].iter().enumerate() {
                let theta_w = theta_t - slab.connection.corner_rotation_angle(f, local);
                let w = w as usize;
                if vertex_angle[w].is_nan() {
                    vertex_angle[w] = theta_w;
                    queue.push(w);
                } else if wrap_angle(vertex_angle[w] - theta_w).abs() > ANGLE_TOLERANCE {
                    return None;
                }
            }
        }
    }
    Some(
        face_angle
            .into_iter()
            .map(|a| if a.is_nan() { 0.0 } else { a })
            .collect(),
    )
}

/// Vertex sets of the connected components (through shared faces).
fn component_faces(mesh: &Mesh, component: &[usize]) -> Vec<usize> {
    let mut faces: Vec<usize> = component
        .iter()
        .flat_map(|&v| mesh.vertex_fan(v).iter().map(|c| c.face as usize))
        .collect();
    faces.sort_unstable();
    faces.dedup();
    faces
}
