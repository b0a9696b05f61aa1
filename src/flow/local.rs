//! The combined local-global data term (Bruhn, Weickert & Schnörr, "Lucas/Kanade meets
//! Horn/Schunck", IJCV 61(3), 2005) on the surface: the flow at a vertex must explain the
//! brightness change of its neighbourhood, not only its own, so sparse bright cells on a dark
//! background inform their dark surroundings, and noise in one vertex's rate is averaged out.
//!
//! With `w = (u, 1)` the data term's density is `wᵀ J w`, `J` the motion tensor
//!
//! ```text
//! J = Σ_c w_c [ g_c g_cᵀ   g_c τ_c ]        (g_c = ∇I_c, τ_c = ∂_t I_c, linearized
//!             [ τ_c g_cᵀ   τ_c²    ]         around the warp's flow when warping)
//! ```
//!
//! and CLG replaces `J` by its Gaussian average `K_ρ * J`. On the surface `J` is a field of
//! tensors (its `g gᵀ` block turns with the frame, its `g τ` column like a vector), so it is
//! averaged in the connection's frames.
//!
//! **Discretization.** Per vertex `a`, the density `j_a = Σ_{T ∋ a} (A_T/3) J_{T,a} / m_a`
//! (`m_a = Σ_{T ∋ a} A_T/3`, the lumped mass; `J_{T,a}` with face `T`'s gradient `R_aᵀ G_T` in
//! the vertex frame and the vertex's rate), then [`averaging_steps`]`(ρ)` steps of
//!
//! ```text
//! J_T = ⅓ Σ_{a ∈ T} R_a J_a R_aᵀ     (vertices → face frame)
//! J_a = Σ_{T ∋ a} (A_T/3) R_aᵀ J_T R_a / m_a    (faces → vertex frame)
//! ```
//!
//! (`R_a`: vertex frame to face frame, [`crate::connection::Connection::face_rotations`];
//! `R J Rᵀ` on the `g gᵀ` block, `R j` on the `g τ` column, the `τ²` entry as is). Each step
//! is an average (weights positive, summing to 1), so it never amplifies, and moves a unit
//! mass over the star: on a regular mesh of edge `h` the spread grows by `E|x|² = ⅔ h²` per
//! step, and `k = 3ρ²/h̄²` steps (`h̄` the slab's mean edge length) give a Gaussian of standard
//! deviation `ρ` per direction (`E|x|² = 2ρ²`). Explicit steps rather than the implicit heat
//! steps of [`super::pyramid`]: those act on scalars, and a tensor field's heat equation would
//! need a connection Laplacian for each of the tensor's spins; `k` stays in the tens for the
//! few edge lengths CLG is used at.
//!
//! The data term is then lumped, `Σ_a m_a w_aᵀ J̃_a w_a`, and given to the solver as each
//! face's [`DataElement`] with only diagonal blocks (corner `a`: `A_T/3 · J̃_a`), so the robust
//! data term, energies, windows and ranks take it as they take the paper's. `ρ = 0` is the
//! lumped Horn–Schunck term (the paper's term has the consistent mass).

use super::params::check;
use super::slab::Slab;
use super::FlowError;
use crate::fem::element::{face_gradient, DataElement};
use crate::fem::vertex_areas;
use crate::mesh::Mesh;
use nalgebra::{Matrix2, Vector2};
use rayon::prelude::*;

/// The most averaging steps (`ρ` of about 18 mean edge lengths); a wider `ρ` is refused when
/// the slab is built (a Gaussian that wide is better had by a coarser mesh).
pub const MAX_STEPS: usize = 1000;

/// A vertex's motion tensor density (module docs) in its own frame: `space` the `g gᵀ` block,
/// `mixed` the `g τ` column, `time` the `τ²` entry.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionTensor {
    pub space: Matrix2<f64>,
    pub mixed: Vector2<f64>,
    pub time: f64,
}

impl MotionTensor {
    fn scaled(&self, w: f64) -> Self {
        Self {
            space: self.space * w,
            mixed: self.mixed * w,
            time: self.time * w,
        }
    }

    fn add(&mut self, other: &Self) {
        self.space += other.space;
        self.mixed += other.mixed;
        self.time += other.time;
    }

    /// The tensor in the frame `R` maps to: `R J Rᵀ`, `R j`, `τ²`.
    fn rotated(&self, r: &Matrix2<f64>) -> Self {
        Self {
            space: r * self.space * r.transpose(),
            mixed: r * self.mixed,
            time: self.time,
        }
    }
}

/// The number of averaging steps for a Gaussian of standard deviation `rho` on a mesh of mean
/// edge length `mean_edge` (module docs): `round(3ρ²/h̄²)`.
pub fn averaging_steps(rho: f64, mean_edge: f64) -> usize {
    (3.0 * rho * rho / (mean_edge * mean_edge)).round() as usize
}

/// The slab's per-vertex motion tensors (every channel with its weight, each rate linearized
/// around the slab's linearization), averaged to standard deviation `rho` (module docs); an
/// error if that takes more than [`MAX_STEPS`].
pub fn local_motion_tensors(
    mesh: &Mesh,
    slab: &Slab,
    rho: f64,
) -> Result<Vec<MotionTensor>, FlowError> {
    let steps = averaging_steps(rho, slab.geometry.mean_edge_length());
    check(
        "local_integration",
        rho,
        steps <= MAX_STEPS,
        "at most about 18 mean edge lengths of the surface (a wider average: a coarser mesh)",
    )?;
    let masses = vertex_areas(mesh, &slab.geometry);
    let mut tensors = vertex_tensors(mesh, slab, &masses);
    for _ in 0..steps {
        tensors = averaged(mesh, slab, &masses, &tensors);
    }
    Ok(tensors)
}

/// The face's lumped data element of the averaged tensors `tensors` (module docs): corner
/// `a`'s diagonal block `A_T/3 · J̃_a`.
pub fn lumped_data_element(face: &[u32; 3], area: f64, tensors: &[MotionTensor]) -> DataElement {
    let mut element = DataElement::zero();
    for (a, &v) in face.iter().enumerate() {
        let j = tensors[v as usize].scaled(area / 3.0);
        element
            .quadratic
            .fixed_view_mut::<2, 2>(2 * a, 2 * a)
            .copy_from(&j.space);
        element
            .linear
            .fixed_rows_mut::<2>(2 * a)
            .copy_from(&j.mixed);
        element.constant += j.time;
    }
    element
}

/// `j_a` of the module docs: each face's corner tensors, area-weighted over the star.
fn vertex_tensors(mesh: &Mesh, slab: &Slab, masses: &[f64]) -> Vec<MotionTensor> {
    let mut tensors = vec![MotionTensor::default(); mesh.n_vertices()];
    for (f, face) in mesh.faces().iter().enumerate() {
        let triangle = slab.geometry.triangle(f);
        let rotations = slab.connection.face_rotations(f);
        for channel in &slab.channels {
            let gradient = face_gradient(triangle, face.map(|v| channel.mid[v as usize]));
            let rates = slab.linearized_rates(channel, face, f, &rotations);
            for ((&v, rotation), rate) in face.iter().zip(&rotations).zip(rates) {
                let g = rotation.transpose() * gradient;
                let corner = MotionTensor {
                    space: g * g.transpose(),
                    mixed: g * rate,
                    time: rate * rate,
                };
                tensors[v as usize].add(&corner.scaled(channel.weight * triangle.area / 3.0));
            }
        }
    }
    for (tensor, &m) in tensors.iter_mut().zip(masses) {
        *tensor = tensor.scaled(1.0 / m);
    }
    tensors
}

/// One averaging step, vertices → faces → vertices (module docs).
fn averaged(
    mesh: &Mesh,
    slab: &Slab,
    masses: &[f64],
    tensors: &[MotionTensor],
) -> Vec<MotionTensor> {
    let faces: Vec<MotionTensor> = (mesh.faces().par_iter().enumerate())
        .map(|(f, face)| {
            let rotations = slab.connection.face_rotations(f);
            let mut sum = MotionTensor::default();
            for (a, &v) in face.iter().enumerate() {
                sum.add(&tensors[v as usize].rotated(&rotations[a]));
            }
            sum.scaled(1.0 / 3.0)
        })
        .collect();
    let mut out = vec![MotionTensor::default(); mesh.n_vertices()];
    for (f, face) in mesh.faces().iter().enumerate() {
        let rotations = slab.connection.face_rotations(f);
        let weight = slab.geometry.triangle(f).area / 3.0;
        for (a, &v) in face.iter().enumerate() {
            let back = faces[f].rotated(&rotations[a].transpose());
            out[v as usize].add(&back.scaled(weight / masses[v as usize]));
        }
    }
    out
}
