//! Whether the motion is too large for the paper's linear model: the check behind automatic
//! coarse-to-fine warping ([`FlowParams::detect_large_motion`](super::FlowParams)).
//!
//! The data term linearizes the images around the zero flow,
//! `I_{s+1}(x + Δt u/2) − I_s(x − Δt u/2) ≈ Δt (τ + ∇I·u)`, which holds while the image moves
//! by much less than the size of its features per frame. So once the linear model has a flow
//! `u`, the images themselves say whether it was right. Read halfway back and forth along
//! `λu` ([`super::warp`]), their rate `τ^w(λ) = (I⁺ − I⁻)/Δt` is `τ + λ ∇I·u + O(λ²)`: the
//! linear model keeps the first two terms. The second difference
//!
//! ```text
//! e = 2 (τ^w(1) − 2 τ^w(½) + τ^w(0)),     τ^w(0) = τ
//! ```
//!
//! is the part of `τ^w(1)` beyond them (exactly, for a quadratic `τ^w`). It is measured from
//! the warped images alone, so it leaves out what is linear in `u` on the mesh: the P1
//! image's gradient differs from face to face around a vertex, so a trace's rate and the
//! element's `G_T·R_a u_a` differ at first order even for the smallest motion (on the
//! textured spheres of `examples/large_motion` that floor is about 0.09 against the zero
//! flow's data term, whatever the motion). Per slab `s`, channel `c` (weight `w_c`) and face
//! `T` (consistent mass `m_T`, corner values):
//!
//! ```text
//! η² = Σ_s Δt_s Σ_c w_c Σ_T e_Tᵀ m_T e_T  /  Σ_s Δt_s Σ_c w_c Σ_T τ_Tᵀ m_T τ_T
//! ```
//!
//! the linearization's error against the zero flow's data term. It grows like the square of
//! the displacement over the features' size while that is small, and is of order one once the
//! first solve's flow carries the image by a good part of a feature: then the linear flow is
//! too slow (it underestimates the speed), which warping corrects. The check costs four traces
//! per vertex and slab and one pass over the faces, a few per cent of a solve.
//!
//! The threshold [`LARGE_MOTION_ERROR`] was measured on the scenes of `examples/large_motion`,
//! `examples/rotating_sphere`, the paper's torus, the zebrafish pairs and a real stack turned
//! about its axis (guide, "Large motions").

use super::outer::SlabSolver;
use super::slab::Slab;
use super::warp::warped_channels;
use super::{FlowError, FlowResult, SlabChannel};
use crate::fem::element::consistent_mass;
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;
use std::borrow::Cow;

/// `η` above which the motion counts as large and warping takes over.
pub const LARGE_MOTION_ERROR: f64 = 0.15;

/// What the check of the linear model found.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MotionCheck {
    /// `η` of the module docs.
    pub linearization_error: f64,
    /// [`LARGE_MOTION_ERROR`].
    pub threshold: f64,
    /// Whether the flow was solved again coarse to fine.
    pub warped: bool,
}

impl MotionCheck {
    /// Whether `η` calls for warping.
    pub fn is_large(&self) -> bool {
        self.linearization_error > self.threshold
    }
}

/// `η` of `result`'s flow (of `solver`'s own slabs, `slab(i)` the `i`-th of them with the
/// original images, unwarped), summed over processes.
pub(super) fn check_linearization<'a>(
    solver: &dyn SlabSolver,
    slab: &(dyn Fn(usize) -> Cow<'a, Slab> + Sync),
    result: &FlowResult,
    channel_weights: &[f64],
) -> Result<MotionCheck, FlowError> {
    let frames = solver.frames();
    let own = solver.own();
    let parts: Vec<[f64; 2]> = (0..own.len())
        .into_par_iter()
        .map(|i| {
            let s = own.start + i;
            let images = (frames.channels(s), frames.channels(s + 1));
            let slab = slab(i);
            let u = &result.intrinsic[i];
            let half: Vec<Vector2<f64>> = u.iter().map(|v| 0.5 * v).collect();
            let mesh = frames.mesh();
            let whole = warped_channels(mesh, &slab, images, u, channel_weights);
            let halfway = warped_channels(mesh, &slab, images, &half, channel_weights);
            slab_errors(mesh, &slab, &whole, &halfway)
        })
        .collect();
    let mut sums = parts
        .iter()
        .fold([0.0; 2], |a, p| [a[0] + p[0], a[1] + p[1]]);
    solver.sum(&mut sums);
    let linearization_error = match sums[1] > 0.0 {
        true => (sums[0] / sums[1]).sqrt(),
        false => 0.0,
    };
    Ok(MotionCheck {
        linearization_error,
        threshold: LARGE_MOTION_ERROR,
        warped: false,
    })
}

/// `[Δt Σ_c w_c Σ_T e_Tᵀ m_T e_T, Δt Σ_c w_c Σ_T τ_Tᵀ m_T τ_T]` of one slab (module docs),
/// with `whole` and `halfway` its channels read along `u` and `u/2`.
fn slab_errors(
    mesh: &crate::mesh::Mesh,
    slab: &Slab,
    whole: &[SlabChannel],
    halfway: &[SlabChannel],
) -> [f64; 2] {
    let mut sums = [0.0; 2];
    for (f, face) in mesh.faces().iter().enumerate() {
        let m = consistent_mass(slab.geometry.triangle(f));
        let channels = slab.channels.iter().zip(whole).zip(halfway);
        for ((channel, whole), halfway) in channels {
            let at = |values: &[f64]| Vector3::from(face.map(|v| values[v as usize]));
            let rate = at(&channel.rate);
            let error = (at(&whole.rate) - at(&halfway.rate) * 2.0 + rate) * 2.0;
            sums[0] += channel.weight * error.dot(&(m * error));
            sums[1] += channel.weight * rate.dot(&(m * rate));
        }
    }
    sums.map(|x| x * slab.dt)
}
