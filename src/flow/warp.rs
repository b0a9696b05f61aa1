//! Coarse-to-fine warping for motions larger than the image's features (Brox et al. 2004;
//! Sun, Roth & Black 2010), on the moving surface.
//!
//! The paper's data term `(∂_t I + dI(u))²` is linear in `u` only while the image moves by
//! much less than its feature size per frame. Warping re-linearizes it around the current
//! flow `ū`: for each slab `s` and vertex `i`, with `exp` the straightest geodesic of the slab's
//! geometry ([`crate::geometry::trace`]),
//!
//! ```text
//! I⁻_i = I_s(exp_i(−Δt_s ū_i / 2))      I⁺_i = I_{s+1}(exp_i(+Δt_s ū_i / 2))
//! ∂_t I + dI(u) ≈ (I⁺ − I⁻)/Δt_s + ∇((I⁺ + I⁻)/2) · (u − ū)
//! ```
//!
//! **Symmetric, not forward.** Both frames are warped halfway because the model's `u` is the
//! velocity at the middle of the slab, where its data term takes the image gradient (the mean
//! of the two frames): a forward warp (frame `s + 1` at `exp(Δt ū)`, frame `s` unwarped)
//! estimates the velocity at the slab's start instead, which differs from the middle one by
//! the flow's own change along the path, and the prototype measured 0.4–8° of error from that
//! alone, with an exact warp.
//!
//! **Smoothness on the total flow.** Every solve minimizes the full energy in the total `u`
//! (only the data term is linearized), so spatial and temporal smoothness, the boundary
//! conditions and the time coupling act on the flow itself, not on increments. So each solve
//! starts from the last one's flow (a warm start, [`super::FlowProblem::solve_from`]): within
//! a level the next warp's system differs from the last one's by the re-linearization alone.
//!
//! **Levels.** The images are smoothed by heat diffusion ([`super::pyramid`]), coarsest first;
//! `γ` doubles per level coarser (a blurred image has weaker gradients, and the coarse flow
//! should be smooth). All slabs are warped and solved together at every step.

use super::median::star_median;
use super::outer::{OuterStart, RunClock, SlabSolver};
use super::problem::FlowResult;
use super::pyramid::scale_pyramid;
use super::slab::{Slab, SlabChannel};
use super::solve::FactorReuse;
use super::{FlowError, FlowParams, Images, MeshSequence, SolveEvent};
use super::{SolveObserver, Weight};
use crate::geometry::{trace, SurfacePoint};
use nalgebra::Vector2;
use rayon::prelude::*;

/// Solves coarse to fine with the warping of `start.params`, its weights fixed at the original
/// images' `start.weights`; the result is the last, finest solve's (of `solver`'s own slabs),
/// with the original data scales. Over ranks, each rank warps its own slabs.
pub(super) fn coarse_to_fine(
    solver: &dyn SlabSolver,
    start: &OuterStart,
    observer: &dyn SolveObserver,
) -> Result<FlowResult, FlowError> {
    let mut clock = RunClock::start(start.assembly_seconds);
    let frames = solver.frames();
    let warping = start.params.warping;
    let warping_median = start.params.median_filter;
    let pyramid = scale_pyramid(frames, warping.levels)?;
    let channel_weights = start.params.channel_weights_for(frames.n_channels())?;
    let own = solver.own();
    // The flow of the frames' slabs: the own ones' from the last solve, zero beyond them (those
    // only lend their geometry to the window's time links).
    let mut flow = vec![vec![Vector2::zeros(); frames.mesh().n_vertices()]; frames.n_slabs()];
    let mut result = None;
    let mut solves = 0;
    for level in (0..warping.levels).rev() {
        let params = FlowParams {
            gamma: Weight::Value(start.weights.gamma * 2f64.powi(level as i32)),
            warping: super::Warping::NONE,
            ..start.fixed_params()
        };
        for warp in 0..warping.warps {
            solves += 1;
            observer.notify(SolveEvent::Warp {
                level,
                warp,
                solve: solves,
                solves: warping.solves(),
            })?;
            clock.begin_step();
            // The zero flow of the first warp has nothing to filter.
            let median = warping_median && solves > 1;
            let slabs = warped_slabs(frames, &pyramid[level], &flow, &channel_weights, median)?;
            // The last solve's flow is a first guess (the energy is the total flow's).
            // A level's next warp differs by the re-linearized data term alone: it
            // preconditions with this warp's factors.
            let reuse = FactorReuse {
                take: warp > 0,
                keep: warp + 1 < warping.warps,
            };
            let solved = solver.solve(&params, slabs, result.as_ref(), reuse, observer)?;
            clock.end_step(format!("level {level}, warp {}", warp + 1), &solved);
            flow[own.clone()].clone_from_slice(&solved.intrinsic);
            result = Some(solved);
        }
    }
    let mut result = result.expect("warping solves at least once");
    result.scales = start.scales;
    let last = warped_slabs(frames, &pyramid[0], &flow, &channel_weights, false)?;
    result.warped_residual = Some(last[own].iter().map(warped_residual).collect());
    result.timings = clock.finish();
    Ok(result)
}

/// `I⁺ − I⁻` per vertex for one channel; with several, the weighted root mean square over
/// channels, `√(Σ_c w_c (I⁺_c − I⁻_c)² / Σ_c w_c)`.
fn warped_residual(slab: &Slab) -> Vec<f64> {
    if let [channel] = slab.channels.as_slice() {
        return channel.rate.iter().map(|r| r * slab.dt).collect();
    }
    let total: f64 = slab.channels.iter().map(|c| c.weight).sum();
    (0..slab.channels[0].rate.len())
        .map(|i| {
            let sum: f64 = (slab.channels.iter())
                .map(|c| c.weight * (c.rate[i] * slab.dt).powi(2))
                .sum();
            (sum / total).sqrt()
        })
        .collect()
}

/// Every slab with its two images warped halfway by `flow` and linearized around it; with
/// `median`, around `flow`'s weighted median over each vertex's star instead
/// ([`super::median`]).
fn warped_slabs(
    sequence: &MeshSequence,
    images: &Images,
    flow: &[Vec<Vector2<f64>>],
    channel_weights: &[f64],
    median: bool,
) -> Result<Vec<Slab>, FlowError> {
    (0..sequence.n_slabs())
        .into_par_iter()
        .map(|s| {
            let frames = (images.frame(s), images.frame(s + 1));
            warped_slab_around(sequence, s, frames, channel_weights, |slab| match median {
                true => star_median(sequence.mesh(), &slab.geometry, &slab.connection, &flow[s]),
                false => flow[s].clone(),
            })
        })
        .collect()
}

/// Slab `s` with `I⁻`, `I⁺` of the module docs (every channel of the two frames' images
/// `before`, `after`, channel `c` weighted by `channel_weights[c]`) and the linearization
/// point `u`.
pub fn warped_slab(
    sequence: &MeshSequence,
    s: usize,
    frames: (&[Vec<f64>], &[Vec<f64>]),
    u: &[Vector2<f64>],
    channel_weights: &[f64],
) -> Result<Slab, FlowError> {
    warped_slab_around(sequence, s, frames, channel_weights, |_| u.to_vec())
}

/// [`warped_slab`] linearized around `point(slab)`, a flow that may depend on the slab's own
/// geometry and connection (built first: they also serve the traces).
fn warped_slab_around(
    sequence: &MeshSequence,
    s: usize,
    frames: (&[Vec<f64>], &[Vec<f64>]),
    channel_weights: &[f64],
    point: impl FnOnce(&Slab) -> Vec<Vector2<f64>>,
) -> Result<Slab, FlowError> {
    let mut slab = Slab::with_channels(sequence, s, Vec::new(), None)?;
    let u = point(&slab);
    slab.channels = warped_channels(sequence.mesh(), &slab, frames, &u, channel_weights);
    slab.linearization = Some(u);
    Ok(slab)
}

/// The channels between `I⁻` and `I⁺` (module docs): the images `before` and `after` read
/// halfway back and forth along `u` on `slab`'s geometry, channel `c` weighted by
/// `channel_weights[c]` (`slab`'s own channels are not read).
pub(super) fn warped_channels(
    mesh: &crate::mesh::Mesh,
    slab: &Slab,
    (before, after): (&[Vec<f64>], &[Vec<f64>]),
    u: &[Vector2<f64>],
    channel_weights: &[f64],
) -> Vec<SlabChannel> {
    let (geometry, connection, dt) = (&slab.geometry, &slab.connection, slab.dt);
    // Each vertex's two traces serve every channel.
    let (minus, plus): (Vec<SurfacePoint>, Vec<SurfacePoint>) = (0..mesh.n_vertices())
        .map(|i| {
            let half = 0.5 * dt * u[i];
            let point = |step: Vector2<f64>| {
                let (start, step) = connection.vertex_trace_start(mesh, geometry, i, step);
                trace(mesh, geometry, start, step).point
            };
            (point(-half), point(half))
        })
        .unzip();
    let sample = |points: &[SurfacePoint], image: &[f64]| -> Vec<f64> {
        points.iter().map(|p| p.interpolate(mesh, image)).collect()
    };
    (before.iter().zip(after).zip(channel_weights))
        .map(|((b, a), &w)| SlabChannel::between(&sample(&minus, b), &sample(&plus, a), dt, w))
        .collect()
}
