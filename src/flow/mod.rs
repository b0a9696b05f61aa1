//! Optical flow on a moving mesh: the space-time energy, its assembly and its minimizer.
//!
//! For frames `k = 0..K−1` and slabs `s = [t_s, t_{s+1}]`, the flow has one tangent field
//! `u_s` per slab and minimizes (`docs/discretization.md` §3–§7)
//!
//! ```text
//! E(u) = Σ_s Δt_s [ ∫ (τ + dI_mid(u_s))² + β|u_s|² + γ|∇u_s|² ]
//!      + Σ_s (γ / α² h_s) ∫ |u_{s+1} − Q u_s|²            (h_s = (Δt_s + Δt_{s+1})/2)
//! ```
//!
//! with the P1 tangent-field elements of [`crate::fem`] on the slab's mean geometry, and `Q` the
//! per-face polar rotation between slab layouts. The minimizer solves `A u = −f` with `A`
//! symmetric positive (semi-)definite and block-tridiagonal in time.
//!
//! ```
//! use meshflow::flow::{compute_flow, FlowParams, MeshSequence};
//! use meshflow::shapes::icosphere;
//!
//! let sphere = icosphere(2);
//! let mesh = sphere.mesh()?;
//! // A texture turning about the z-axis by 0.05 rad per frame on a still sphere.
//! let texture = |t: f64| -> Vec<f64> {
//!     sphere.positions.iter().map(|p| {
//!         let (s, c) = (0.05 * t).sin_cos();
//!         (3.0 * (c * p.x + s * p.y)).sin() + p.z
//!     }).collect()
//! };
//! let frames = vec![sphere.positions.clone(); 3];
//! let sequence = MeshSequence::new(mesh, frames, (0..3).map(|k| texture(k as f64)).collect(), None)?;
//! let flow = compute_flow(&sequence, &FlowParams::default())?;
//! assert_eq!(flow.intrinsic.len(), 2); // one field per slab
//! assert!(flow.relative_residual < 1e-8);
//! # Ok::<(), meshflow::Error>(())
//! ```
//!
//! This file is the module's front door: declarations and re-exports only. The data flows
//! through the submodules as follows: [`MeshSequence`] and [`Images`] (`sequence`) →
//! [`FlowParams`] (`options`, `params`, `scales`, `anisotropy`, `regularizer`) → one [`Slab`] per time
//! step and the time links (`slab`) → the [`SpaceTimeSystem`] (`system`, checked by
//! `uniqueness`) → its solvers (`solve`) → [`FlowProblem`] and [`compute_flow`] (`problem`),
//! with the outer loops of warping (`warp`, `pyramid`) and robust reweighting (`robust`,
//! `outer`), time windows over ranks (`window`), and what a flow carries (`advect`).

pub mod advect;
pub mod anisotropy;
mod energy;
mod error;
pub mod local;
pub mod median;
pub mod motion;
mod options;
mod outer;
mod params;
mod problem;
pub mod pyramid;
pub mod regularizer;
pub mod robust;
mod scales;
mod sequence;
mod slab;
pub(crate) mod solve;
mod system;
mod uniqueness;
pub mod warp;
pub mod window;

pub use advect::{advect, closest_seeds, slab_velocity, tissue_velocity, vertex_seeds};
pub use advect::{Trajectories, SUBSTEPS};
pub use anisotropy::Anisotropy;
pub use energy::EnergyTerms;
pub use error::FlowError;
pub use motion::{MotionCheck, LARGE_MOTION_ERROR};
pub use options::FlowOptions;
pub use params::{Boundary, FlowParams, Scale, SolverChoice, TimeCoupling, Weight, Weights};
pub use params::{Warping, DEFAULT_SPREAD, DEFAULT_TIME_SCALE};
pub use problem::{compute_flow, FlowProblem, FlowResult, SolveStep, Timings, KEEP_SLABS_BYTES};
pub use pyramid::{heat_times, scale_pyramid, smoothed_over_length, COARSEST_HEAT_TIME};
pub use regularizer::Regularizer;
pub use robust::FlowDriven;
pub use scales::{DataScales, ScaleSums};
pub(crate) use sequence::check_finite_intensities;
pub use sequence::{Images, MeshSequence};
pub use slab::{Slab, SlabChannel};
pub use solve::distributed;
pub use solve::{SolveEvent, SolveObserver, SolverMethod, WarmStart};
pub use system::{LinkMatrix, SpaceTimeSystem, SystemWindow};
pub use warp::warped_slab;
