//! The energy at a given flow, term by term, evaluated face by face from the element matrices
//! (independently of the assembled global system, which it therefore checks).

use super::slab::{Slab, TimeLink};
use super::{FlowParams, Weights};
use crate::mesh::Mesh;
use nalgebra::Vector6;
use rayon::prelude::*;

/// The four terms of `E(u)`; [`EnergyTerms::total`] is the energy.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct EnergyTerms {
    /// `∫∫ (∂_t I + dI(u))²`
    pub data: f64,
    /// `β ∫∫ |u|²`
    pub speed: f64,
    /// `γ ∫∫ |∇u|²`
    pub spatial: f64,
    /// `(γ/α²) ∫∫ |∇_t u|²`
    pub temporal: f64,
}

impl EnergyTerms {
    pub fn total(&self) -> f64 {
        self.data + self.speed + self.spatial + self.temporal
    }
}

/// The energy terms at `u` (slab-major, `2V` per slab).
pub fn energy_terms(
    mesh: &Mesh,
    slabs: &[Slab],
    links: &[TimeLink],
    params: &FlowParams,
    weights: &Weights,
    u: &[f64],
) -> EnergyTerms {
    let n = 2 * mesh.n_vertices();
    let corner_values = |s: usize, face: &[u32; 3]| {
        Vector6::from_fn(|k, _| u[s * n + 2 * face[k / 2] as usize + k % 2])
    };
    let spatial: Vec<EnergyTerms> = slabs
        .par_iter()
        .enumerate()
        .map(|(s, slab)| {
            let mut terms = EnergyTerms::default();
            for (f, face) in mesh.faces().iter().enumerate() {
                let e = slab.face_elements(face, f);
                let x = corner_values(s, face);
                terms.data += slab.dt
                    * (x.dot(&(e.data.quadratic * x))
                        + 2.0 * e.data.linear.dot(&x)
                        + e.data.constant);
                terms.speed += slab.dt * weights.beta * x.dot(&(e.mass * x));
                terms.spatial += slab.dt * weights.gamma * x.dot(&(e.stiffness * x));
            }
            terms
        })
        .collect();
    let temporal: f64 = links
        .par_iter()
        .enumerate()
        .map(|(s, link)| {
            mesh.faces()
                .iter()
                .enumerate()
                .map(|(f, face)| {
                    let e = link.face_elements(&slabs[s], &slabs[s + 1], f, params.time_coupling);
                    let (x0, x1) = (corner_values(s, face), corner_values(s + 1, face));
                    x0.dot(&(e.before * x0))
                        + x1.dot(&(e.after * x1))
                        + 2.0 * x1.dot(&(e.cross * x0))
                })
                .sum::<f64>()
        })
        .sum();
    let mut total = spatial
        .iter()
        .fold(EnergyTerms::default(), |acc, t| EnergyTerms {
            data: acc.data + t.data,
            speed: acc.speed + t.speed,
            spatial: acc.spatial + t.spatial,
            temporal: 0.0,
        });
    total.temporal = temporal;
    total
}
