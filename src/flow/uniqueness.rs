//! Does the energy have a unique minimizer? Only a question when `β = 0`.
//!
//! The analysis below is the covariant regularizer's. It holds for the strain regularizer
//! too as far as it goes: a parallel field is a Killing field (`∇u = 0` makes `Sym ∇u = 0`),
//! so every kernel found here is one of the strain energy as well; rotations the image leaves
//! free (a pattern symmetric about an axis) are a kernel of the pure strain energy only, which
//! this check does not look for (the factorization or the solver then reports the singular
//! system, and `β > 0` removes it). The anisotropic tensors ([`super::anisotropy`]) change
//! no kernel: `D` is positive definite, so `tr(∇u D ∇uᵀ) = |∇u D^½|²` vanishes exactly where
//! `|∇u|²` does (and likewise for `Sym ∇u`).
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
#[cfg(doc)]
use super::solve::distributed::OneProcess;
use super::solve::distributed::{all_gather, TimeRanks};
use super::{Boundary, FlowError, FlowParams, Weights};
use crate::connection::{rotation, wrap_angle};
use crate::mesh::Mesh;
use nalgebra::Matrix2;
use std::ops::Range;

/// Angles agreeing to this many radians are equal: far above round-off, far below any
/// holonomy a real mesh produces.
const ANGLE_TOLERANCE: f64 = 1e-8;
/// `det N ≤ this · (tr N)²` means `N` has a null direction.
const SINGULAR_RATIO: f64 = 1e-10;

/// The slabs a check sees: the whole sequence's, or over ranks one window's frames' slabs, of
/// which `own` (local indices; slab `l` is the sequence's `l + offset`) are this rank's and the
/// one after them, if any, lends its angles to their last link.
pub struct CheckedSlabs<'a> {
    pub slabs: &'a [Slab],
    /// `links[l]` joins `slabs[l]` and `slabs[l + 1]` (none without time coupling).
    pub links: &'a [TimeLink],
    pub own: Range<usize>,
    pub offset: usize,
}

/// `Ok` when the minimizer is unique; [`FlowError::Singular`] otherwise. Over ranks every rank
/// calls it with its window ([`CheckedSlabs`]) and gets the same answer: each checks its own
/// slabs and links, and the parts that couple all slabs (the first singular slab, whether
/// every slab and link carries the parallel field, the rotation accumulated along the links,
/// the data matrix `N`) are summed over `ranks` ([`OneProcess`] in one process).
pub fn check_unique_minimizer(
    mesh: &Mesh,
    checked: &CheckedSlabs,
    params: &FlowParams,
    weights: &Weights,
    ranks: &dyn TimeRanks,
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
        // The own slabs' angles and the next slab's (its link needs them).
        let seen = checked.own.start..(checked.own.end + 1).min(checked.slabs.len());
        let angles: Vec<Option<Vec<f64>>> = (checked.slabs[seen.clone()].iter())
            .map(|slab| parallel_face_angles(mesh, slab, component[0]))
            .collect();
        let theta = |l: usize| angles[l - seen.start].as_ref();
        if !weights.is_coupled() {
            let singular_slab = checked.own.clone().find(|&l| {
                theta(l).is_some_and(|theta| {
                    is_singular(&data_matrix(mesh, &checked.slabs[l], theta, &component))
                })
            });
            let first = first_over_ranks(ranks, singular_slab.map(|l| l + checked.offset));
            if let Some(s) = first {
                return Err(singular(format!("slab {s} carries a covariantly constant field along which the image has no gradient")));
            }
            continue;
        }
        let total = steady_data_matrix(mesh, checked, &theta, &component, ranks);
        if total.is_some_and(|total| is_singular(&total)) {
            return Err(singular(format!(
                "vertex {} lies on a part of the surface that carries a covariantly constant field, steady in time, along which the image has no gradient",
                component[0]
            )));
        }
    }
    Ok(())
}

/// The first rank's `value` that is not `None` (ranks hold slabs in order, so for a slab, the
/// smallest); collective.
fn first_over_ranks(ranks: &dyn TimeRanks, value: Option<usize>) -> Option<usize> {
    let mine = [value.map_or(0.0, |v| v as f64 + 1.0)];
    (all_gather(ranks, &mine).iter())
        .find(|v| v[0] > 0.0)
        .map(|v| v[0] as usize - 1)
}

/// `N` for a field that is parallel in every slab, or `None` when the time links do not carry
/// one slab's parallel field onto the next by a single rotation; collective. Each rank adds
/// its slabs' terms, rotated by the angle accumulated along all links before them (the sum of
/// the earlier ranks' link angles).
fn steady_data_matrix<'a>(
    mesh: &Mesh,
    checked: &CheckedSlabs,
    theta: &dyn Fn(usize) -> Option<&'a Vec<f64>>,
    component: &[usize],
    ranks: &dyn TimeRanks,
) -> Option<Matrix2<f64>> {
    let faces = component_faces(mesh, component);
    // The angle by which each own link carries the field on, `None` where it does not.
    let link_angle = |l: usize| -> Option<f64> {
        let link = checked.links.get(l)?;
        let (before, after) = (theta(l)?, theta(l + 1)?);
        let kappa = |f: usize| link.polar_angle(f) + before[f] - after[f];
        let first = kappa(faces[0]);
        (faces.iter())
            .all(|&f| wrap_angle(kappa(f) - first).abs() <= ANGLE_TOLERANCE)
            .then_some(first)
    };
    let own_links = checked.own.start..checked.own.end.min(checked.links.len());
    let kappas: Option<Vec<f64>> = own_links.clone().map(link_angle).collect();
    let parallel = checked.own.clone().all(|l| theta(l).is_some());
    // Per rank: whether its slabs and links carry the field (1) or break it (0), and the
    // angle its links turn it by.
    let mine = match (&kappas, parallel) {
        (Some(kappas), true) => [1.0, kappas.iter().sum()],
        _ => [0.0, 0.0],
    };
    let all = all_gather(ranks, &mine);
    if all.iter().any(|rank| rank[0] == 0.0) {
        return None;
    }
    let kappas = kappas.expect("checked above");
    let mut phi: f64 = all[..ranks.rank()].iter().map(|rank| rank[1]).sum();
    let mut total = Matrix2::zeros();
    for (k, l) in checked.own.clone().enumerate() {
        let rotate = rotation(phi);
        let slab = &checked.slabs[l];
        let theta = theta(l).expect("checked above");
        total += rotate.transpose() * data_matrix(mesh, slab, theta, component) * rotate * slab.dt;
        phi += kappas.get(k).copied().unwrap_or(0.0);
    }
    let mut entries = [total[(0, 0)], total[(0, 1)], total[(1, 0)], total[(1, 1)]];
    ranks.sum(&mut entries);
    Some(Matrix2::new(entries[0], entries[1], entries[2], entries[3]))
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
