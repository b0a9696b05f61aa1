//! The energy at a given flow, term by term, evaluated face by face from the element matrices
//! (independently of the assembled global system, which it therefore checks).

use super::slab::{Slab, TimeLink};
use super::{FlowParams, Weights};
use crate::mesh::Mesh;
use nalgebra::Vector6;
use rayon::prelude::*;
use std::borrow::Cow;

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

/// The energy terms at `u` (slab-major, `2V` per slab) of slabs `0..counted` and their links to
/// the next slab where `u` has it, with `slab(s)` giving slab `s` (kept or rebuilt; the time
/// links are rebuilt from neighbouring slabs). `counted` is all of `u`'s slabs for a whole
/// sequence; a rank's window passes its own and appends the next rank's first slab to `u`.
pub fn energy_terms<'a>(
    mesh: &Mesh,
    slab: &(dyn Fn(usize) -> Cow<'a, Slab> + Sync),
    (params, weights): (&FlowParams, &Weights),
    u: &[f64],
    counted: usize,
) -> EnergyTerms {
    let n = 2 * mesh.n_vertices();
    let n_slabs = u.len() / n;
    let corner_values = |s: usize, face: &[u32; 3]| {
        Vector6::from_fn(|k, _| u[s * n + 2 * face[k / 2] as usize + k % 2])
    };
    let per_slab: Vec<EnergyTerms> = (0..counted)
        .into_par_iter()
        .map(|s| {
            let this = slab(s);
            let mut terms =
                spatial_terms(mesh, &this, params, weights, |face| corner_values(s, face));
            if weights.is_coupled() && s + 1 < n_slabs {
                let next = slab(s + 1);
                let link = TimeLink::new(&this, &next, weights);
                terms.temporal = mesh
                    .faces()
                    .iter()
                    .enumerate()
                    .map(|(f, face)| {
                        let e = link.face_elements(&this, &next, f, params.time_coupling);
                        let (x0, x1) = (corner_values(s, face), corner_values(s + 1, face));
                        x0.dot(&(e.before * x0))
                            + x1.dot(&(e.after * x1))
                            + 2.0 * x1.dot(&(e.cross * x0))
                    })
                    .sum::<f64>();
            }
            terms
        })
        .collect();
    per_slab
        .iter()
        .fold(EnergyTerms::default(), |acc, t| EnergyTerms {
            data: acc.data + t.data,
            speed: acc.speed + t.speed,
            spatial: acc.spatial + t.spatial,
            temporal: acc.temporal + t.temporal,
        })
}

/// Data, speed and spatial terms of one slab, with `x(face)` the corner values.
fn spatial_terms(
    mesh: &Mesh,
    slab: &Slab,
    params: &FlowParams,
    weights: &Weights,
    x: impl Fn(&[u32; 3]) -> Vector6<f64>,
) -> EnergyTerms {
    let mut terms = EnergyTerms::default();
    for (f, face) in mesh.faces().iter().enumerate() {
        let e = slab.face_elements(face, f, &params.regularizer);
        let x = x(face);
        terms.data += slab.dt
            * (x.dot(&(e.data.quadratic * x)) + 2.0 * e.data.linear.dot(&x) + e.data.constant);
        terms.speed += slab.dt * weights.beta * x.dot(&(e.mass * x));
        terms.spatial += slab.dt * weights.gamma * x.dot(&(e.stiffness * x));
    }
    terms
}
