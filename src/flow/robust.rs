//! Robust spatial smoothness: the Charbonnier penalty of the regularizer, for flows with
//! discontinuities (cells moving against a still background), by iteratively reweighted least
//! squares.
//!
//! With `r_T(u) = u_Tᵀ E_T u_T / A_T` the regularizer's density on face `T` (`|∇u|²` or
//! `|Sym ∇u|²`, [`super::regularizer`]) the spatial term becomes
//!
//! ```text
//! γ Σ_s Δt_s Σ_T A_T ψ(r_T),     ψ(r) = 2ε (√(r + ε²) − ε)
//! ```
//!
//! which is `r` for `r ≪ ε²` (ε → ∞: the quadratic model) and grows like `2ε√r` beyond, so a
//! jump in the flow costs in proportion to its size, not its square. `ψ` is concave in `r`, so
//! its tangent `ψ(r₀) + ψ'(r₀)(r − r₀)` lies above it: each step solves the quadratic model
//! with per-face weights `w_T = ψ'(r_T(u_k)) = ε / √(r_T(u_k) + ε²)` lagged from the previous
//! flow, and the robust energy never increases (majorize–minimize). It stops when the energy
//! changes by less than [`ENERGY_CHANGE`] relative, or after [`MAX_REWEIGHTINGS`].
//!
//! With coarse-to-fine warping, every warp reweights from its own linear solve (the prototype
//! found the per-level γ schedule necessary for stability at large motions).

use super::outer::{OuterStart, RunClock, SlabSolver};
use super::{FlowError, FlowParams, FlowResult, SolveObserver};
use crate::mesh::Mesh;
use nalgebra::{Vector2, Vector6};

/// The relative change of the robust energy below which reweighting stops.
pub const ENERGY_CHANGE: f64 = 1e-4;
/// Reweighted solves at most.
pub const MAX_REWEIGHTINGS: usize = 30;

/// Minimizes the energy of `start.params` on `slabs` (all of `solver`'s frames' slabs) with the
/// Charbonnier smoothness of scale `epsilon` (module docs); the result is the last reweighted
/// solve's, with `reweightings` set and the robust energy (`energy_terms.spatial` the
/// Charbonnier term). Over ranks, each rank reweights its own slabs.
pub(super) fn reweighted(
    solver: &dyn SlabSolver,
    start: &OuterStart,
    mut slabs: Vec<super::Slab>,
    epsilon: f64,
    observer: &dyn SolveObserver,
) -> Result<FlowResult, FlowError> {
    let mesh = solver.frames().mesh();
    let own = solver.own();
    let params = FlowParams {
        robust_smoothness: None,
        ..start.fixed_params()
    };
    let penalty = Charbonnier {
        epsilon,
        params: &params,
        gamma: start.weights.gamma,
    };
    // The densities below read the slabs' anisotropic tensors, which the solves would add.
    super::slab::complete_slabs(&mut slabs, solver.frames(), &params)?;
    let mut clock = RunClock::start(start.assembly_seconds);
    let mut result = solver.solve(&params, slabs.clone(), observer)?;
    clock.end_step("first solve".into(), &result);
    // `densities[s][T] = r_T` of the current flow on the own slabs: its energy, and the next
    // solve's weights.
    let mut densities = penalty.densities(mesh, &slabs[own.clone()], &result);
    let mut energy = penalty.robust_energy(solver, &slabs[own.clone()], &densities, &mut result);
    let mut reweightings = 0;
    while reweightings < MAX_REWEIGHTINGS {
        for (slab, r) in slabs[own.clone()].iter_mut().zip(&densities) {
            slab.smoothness_weights = Some(r.iter().map(|&r| penalty.weight(r)).collect());
        }
        clock.begin_step();
        result = solver.solve(&params, slabs.clone(), observer)?;
        reweightings += 1;
        clock.end_step(format!("reweighting {reweightings}"), &result);
        densities = penalty.densities(mesh, &slabs[own.clone()], &result);
        let next = penalty.robust_energy(solver, &slabs[own.clone()], &densities, &mut result);
        let change = (energy - next).abs() / next.abs().max(f64::MIN_POSITIVE);
        energy = next;
        if change <= ENERGY_CHANGE {
            break;
        }
    }
    result.reweightings = reweightings;
    result.timings = clock.finish();
    result.scales = start.scales;
    Ok(result)
}

/// `ψ(r) = 2ε(√(r + ε²) − ε)` with the regularizer and weight of `params`.
struct Charbonnier<'a> {
    epsilon: f64,
    params: &'a FlowParams,
    gamma: f64,
}

impl Charbonnier<'_> {
    /// In the form `2ε r / (√(r + ε²) + ε)`, free of cancellation for `r ≪ ε²`.
    fn psi(&self, r: f64) -> f64 {
        let e = self.epsilon;
        2.0 * e * r / ((r + e * e).sqrt() + e)
    }

    /// `ψ'(r)`.
    fn weight(&self, r: f64) -> f64 {
        self.epsilon / (r + self.epsilon * self.epsilon).sqrt()
    }

    /// `r_T(u) = u_Tᵀ E_T u_T / A_T` per slab and face of `result`'s flow.
    fn densities(&self, mesh: &Mesh, slabs: &[super::Slab], result: &FlowResult) -> Vec<Vec<f64>> {
        slabs
            .iter()
            .zip(&result.intrinsic)
            .map(|(slab, u)| self.slab_densities(mesh, slab, u))
            .collect()
    }

    /// `r_T(u)` per face of one slab (unweighted element).
    fn slab_densities(&self, mesh: &Mesh, slab: &super::Slab, u: &[Vector2<f64>]) -> Vec<f64> {
        mesh.faces()
            .iter()
            .enumerate()
            .map(|(f, face)| {
                let e = slab.regularizer_element(face, f, &self.params.regularizer);
                let x = Vector6::from_fn(|k, _| u[face[k / 2] as usize][k % 2]);
                x.dot(&(e * x)) / slab.geometry.triangle(f).area
            })
            .collect()
    }

    /// Puts the robust energy of `result` (its `densities` on the own `slabs`, summed over
    /// processes) into it and returns it: the data, speed and temporal terms (which the weights
    /// do not touch) stay, the spatial term becomes the Charbonnier one.
    fn robust_energy(
        &self,
        solver: &dyn SlabSolver,
        slabs: &[super::Slab],
        densities: &[Vec<f64>],
        result: &mut FlowResult,
    ) -> f64 {
        let spatial: f64 = slabs
            .iter()
            .zip(densities)
            .map(|(slab, densities)| {
                let areas = slab.geometry.triangles().iter().map(|t| t.area);
                slab.dt
                    * areas
                        .zip(densities)
                        .map(|(a, &r)| a * self.psi(r))
                        .sum::<f64>()
            })
            .sum();
        let mut spatial = [spatial];
        solver.sum(&mut spatial);
        result.energy_terms.spatial = self.gamma * spatial[0];
        result.energy = result.energy_terms.total();
        result.energy
    }
}
