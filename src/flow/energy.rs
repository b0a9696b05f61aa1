//! The energy at a given flow, term by term, evaluated face by face: the data and smoothness
//! terms from their element matrices, the speed and temporal terms as the forms those matrices
//! stand for, taken in the face frames ([`crate::fem::element::vector_form`],
//! [`TimeLink::face_energy`]). Independent of the assembled global system, which it therefore
//! checks.

use super::slab::{Slab, TimeLink};
use super::{FlowParams, Weights};
use crate::fem::element;
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
    weighting: (&FlowParams, &Weights),
    u: &[f64],
    counted: usize,
) -> EnergyTerms {
    energy_terms_visiting(mesh, slab, weighting, u, counted, &|_, _| ()).0
}

/// [`energy_terms`], and `visit(s, slab)` for each counted slab in the same pass.
///
/// The slabs are walked in runs of neighbours, a run per task, each slab's successor (which
/// its time link needs) becoming the next slab: where `slab` rebuilds them (a long sequence
/// does not keep its slabs, [`super::problem::KEEP_SLABS_BYTES`]), each is built about once
/// for the energy and whatever `visit` computes, instead of once for itself, once as a
/// successor and once more for the visit.
pub fn energy_terms_visiting<'a, T: Send>(
    mesh: &Mesh,
    slab: &(dyn Fn(usize) -> Cow<'a, Slab> + Sync),
    (params, weights): (&FlowParams, &Weights),
    u: &[f64],
    counted: usize,
    visit: &(dyn Fn(usize, &Slab) -> T + Sync),
) -> (EnergyTerms, Vec<T>) {
    let n = 2 * mesh.n_vertices();
    let n_slabs = u.len() / n;
    let corner_values = |s: usize, face: &[u32; 3]| {
        Vector6::from_fn(|k, _| u[s * n + 2 * face[k / 2] as usize + k % 2])
    };
    let terms_of = |s: usize, this: &Slab, next: Option<&Slab>| {
        let mut terms = spatial_terms(mesh, this, params, weights, |face| corner_values(s, face));
        if let Some(next) = next {
            let link = TimeLink::new(this, next, weights);
            terms.temporal = (0..mesh.n_faces())
                .map(|f| {
                    let face = &mesh.faces()[f];
                    let x = (&corner_values(s, face), &corner_values(s + 1, face));
                    link.face_energy((this, next), f, params.time_coupling, x)
                })
                .sum::<f64>();
        }
        terms
    };
    let run = counted.div_ceil(4 * rayon::current_num_threads()).max(1);
    let runs: Vec<Vec<(EnergyTerms, T)>> = (0..counted.div_ceil(run))
        .into_par_iter()
        .map(|r| {
            let slabs = r * run..((r + 1) * run).min(counted);
            let mut this = slab(slabs.start);
            let mut out = Vec::with_capacity(slabs.len());
            for s in slabs.clone() {
                let next = (s + 1 < n_slabs && (weights.is_coupled() || s + 1 < slabs.end))
                    .then(|| slab(s + 1));
                let linked = next.as_deref().filter(|_| weights.is_coupled());
                out.push((terms_of(s, &this, linked), visit(s, &this)));
                if let Some(next) = next {
                    this = next;
                }
            }
            out
        })
        .collect();
    let (per_slab, visited): (Vec<EnergyTerms>, Vec<T>) = runs.into_iter().flatten().unzip();
    let total = per_slab
        .iter()
        .fold(EnergyTerms::default(), |acc, t| EnergyTerms {
            data: acc.data + t.data,
            speed: acc.speed + t.speed,
            spatial: acc.spatial + t.spatial,
            temporal: acc.temporal + t.temporal,
        });
    (total, visited)
}

/// Data, speed and spatial terms of one slab, with `x(face)` the corner values (the speed
/// term's vector mass as its form, [`element::vector_form`]; none where `β = 0`).
fn spatial_terms(
    mesh: &Mesh,
    slab: &Slab,
    params: &FlowParams,
    weights: &Weights,
    x: impl Fn(&[u32; 3]) -> Vector6<f64>,
) -> EnergyTerms {
    let mut terms = EnergyTerms::default();
    for (f, face) in mesh.faces().iter().enumerate() {
        let x = x(face);
        let e = slab.face_elements(face, f, &params.regularizer);
        terms.data += slab.dt * e.data.value(&x);
        if weights.beta != 0.0 {
            let rotations = &slab.connection.face_rotations(f);
            terms.speed +=
                slab.dt * weights.beta * element::vector_form(&e.mass, rotations, &x, &x);
        }
        terms.spatial += slab.dt * weights.gamma * x.dot(&(e.stiffness * x));
    }
    terms
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::{FlowParams, FlowProblem};
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// One pass visits every slab once, in order, and builds each about once: coupled, at most
    /// one more build per run of neighbours (slab by slab took `2·counted − 1`), uncoupled
    /// exactly `counted`; the total is the assembled quadratic `uᵀAu − 2bᵀu + c` (the forms of
    /// the speed and temporal terms against the element matrices the system is assembled from).
    #[test]
    fn one_pass_builds_each_slab_about_once() {
        for (alpha, beta) in [(0.3, 0.2), (f64::INFINITY, 0.0)] {
            let sequence = crate::synth::paper_torus(8, 6, 14).unwrap();
            let params = FlowParams::paper(alpha, beta, 1.0);
            let problem = FlowProblem::new(&sequence, &params).unwrap();
            let slabs = problem.slabs();
            let builds = AtomicUsize::new(0);
            let slab = |s: usize| {
                builds.fetch_add(1, Ordering::Relaxed);
                Cow::Borrowed(&slabs[s])
            };
            let system = problem.system();
            let u: Vec<f64> = (0..system.dimension())
                .map(|i| (0.1 * i as f64).sin())
                .collect();
            let counted = system.n_slabs();
            let (terms, visited) = energy_terms_visiting(
                sequence.mesh(),
                &slab,
                (&params, problem.weights()),
                &u,
                counted,
                &|s, _| s,
            );
            assert_eq!(visited, (0..counted).collect::<Vec<_>>(), "α = {alpha}");
            let runs = counted.div_ceil(counted.div_ceil(4 * rayon::current_num_threads()));
            let built = builds.load(Ordering::Relaxed);
            match alpha.is_finite() {
                true => assert!(built < counted + runs, "α = {alpha}: {built} builds"),
                false => assert_eq!(built, counted, "α = ∞"),
            }
            let assembled = system.energy(&u);
            let error = (terms.total() - assembled).abs() / assembled.abs();
            assert!(error < 1e-12, "α = {alpha}: {error:e}");
        }
    }
}
