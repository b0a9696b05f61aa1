//! Accuracy of a computed flow against a known one: angular and endpoint errors per vertex, and
//! their area-weighted means per slab and over the whole sequence.
//!
//! Both flows are R^3 vectors per slab and vertex, `u[s][i]` on frame `s` (as
//! [`FlowResult::vectors`]). Per vertex:
//!
//! ```text
//! AE(u, v)  = ∠((u, 1), (v, 1)) = acos((u·v + 1) / √((|u|² + 1)(|v|² + 1)))   (reported in degrees)
//! EPE(u, v) = |u − v|
//! ```
//!
//! the angle between the space-time directions `(u, 1)` and `(v, 1)` (Barron, Fleet &
//! Beauchemin 1994, the measure Bauer, Grasmair & Kirisits report), and the endpoint error.
//!
//! Means approximate integrals, so that a fine patch of mesh does not count more than a coarse
//! one of the same area. Slab `s` weighs vertex `i` by its lumped area `a_i^s = Σ_{T∋i} A_T / 3`
//! in the slab geometry (edge lengths the mean of frames `s` and `s + 1`,
//! `docs/discretization.md` §3), and the sequence weighs slab `s` by its space-time measure,
//! duration `Δt_s = t_{s+1} − t_s` times area `A_s`:
//!
//! ```text
//! mean_s = Σ_i a_i^s e_i^s / A_s,              A_s = Σ_i a_i^s
//! mean   = Σ_s Δt_s A_s mean_s / Σ_s Δt_s A_s  ≈ ∫∫ e dA dt / ∫∫ dA dt
//! ```
//!
//! (for a surface of constant area, `mean` is the `Δt`-weighted mean of the slab means).
//!
//! ```
//! use meshflow::accuracy::compare_result;
//! use meshflow::flow::{compute_flow, FlowParams};
//! use meshflow::synth::rotating_sphere;
//!
//! // A texture turning at 0.5 rad per unit time on a 162-vertex sphere; true flow ω ẑ × x.
//! let truth = rotating_sphere(2, 3, 0.1, 0.5)?;
//! let params = FlowParams { gamma: 1e-3, ..FlowParams::default() };
//! let flow = compute_flow(&truth.sequence, &params)?;
//! let errors = compare_result(&truth.sequence, &flow, &truth.flow)?;
//! assert!(errors.mean_angular_degrees < 11.0); // 10.4°: coarse; finer meshes do better
//! assert_eq!(errors.angular_degrees.len(), 2); // [slab][vertex]
//! # Ok::<(), meshflow::Error>(())
//! ```
//!
//! [`FlowResult::vectors`]: crate::flow::FlowResult::vectors

use crate::fem::vertex_areas;
use crate::flow::{FlowError, FlowResult, MeshSequence};
use nalgebra::{Vector3, Vector4};

/// Why two flows could not be compared. Variants name the slab and vertex at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AccuracyError {
    #[error("the sequence is intrinsic (edge lengths, no positions): its flow has no R^3 vectors to compare with a ground truth")]
    Intrinsic,
    #[error("the {which} flow has {got} slabs, the sequence has {expected}")]
    SlabCount {
        which: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("slab {slab}: the {which} flow has {got} vectors, the mesh has {expected} vertices")]
    VertexCount {
        which: &'static str,
        slab: usize,
        expected: usize,
        got: usize,
    },
    #[error("slab {slab}, vertex {vertex}: the {which} flow ({}, {}, {}) is not finite", value[0], value[1], value[2])]
    NonFinite {
        which: &'static str,
        slab: usize,
        vertex: usize,
        value: [f64; 3],
    },
    #[error(transparent)]
    Flow(#[from] FlowError),
}

/// The errors of one slab: area-weighted means and maxima over its vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabErrors {
    /// `Δt_s`.
    pub duration: f64,
    /// `A_s`: the area of the slab geometry.
    pub area: f64,
    pub mean_angular_degrees: f64,
    pub mean_endpoint: f64,
    pub max_angular_degrees: f64,
    pub max_endpoint: f64,
}

/// A computed flow measured against the true one (see the module docs for the formulas).
#[derive(Clone, Debug, PartialEq)]
pub struct FlowErrors {
    /// `angular_degrees[s][i]`: AE at vertex `i` of slab `s`, in degrees.
    pub angular_degrees: Vec<Vec<f64>>,
    /// `endpoint[s][i]`: EPE at vertex `i` of slab `s`.
    pub endpoint: Vec<Vec<f64>>,
    pub slabs: Vec<SlabErrors>,
    /// Space-time mean of the AE (degrees): slabs weighted by `Δt_s A_s`.
    pub mean_angular_degrees: f64,
    /// Space-time mean of the EPE.
    pub mean_endpoint: f64,
    pub max_angular_degrees: f64,
    pub max_endpoint: f64,
}

/// Angular error (radians) between R^3 flow vectors `u` and `v`: the angle between `(u, 1)` and
/// `(v, 1)` in R^4, `acos((u·v + 1) / √((|u|²+1)(|v|²+1)))`.
///
/// Evaluated as Kahan's `2 atan2(|a|b| − b|a||, |a|b| + b|a||)` for `a = (u, 1)`, `b = (v, 1)`:
/// accurate for small angles (where `acos` loses half the digits), exactly `0` when `u = v`
/// and exactly symmetric in `u`, `v`.
pub fn angular_error(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    let a = Vector4::new(u.x, u.y, u.z, 1.0);
    let b = Vector4::new(v.x, v.y, v.z, 1.0);
    let (a_scaled, b_scaled) = (a * b.norm(), b * a.norm());
    2.0 * (a_scaled - b_scaled)
        .norm()
        .atan2((a_scaled + b_scaled).norm())
}

/// Endpoint error `|u − v|`.
pub fn endpoint_error(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    (u - v).norm()
}

/// Compares the `computed` flow of `sequence` with the `truth`, both `[s][i]` in R^3 on frame
/// `s`: per-vertex AE and EPE, and their area-weighted means per slab and over the sequence.
///
/// Errors: an intrinsic sequence; a slab or vertex count that does not match the sequence; a
/// vector that is not finite (naming the flow, slab and vertex).
pub fn compare_flows(
    sequence: &MeshSequence,
    computed: &[Vec<Vector3<f64>>],
    truth: &[Vec<Vector3<f64>>],
) -> Result<FlowErrors, AccuracyError> {
    check_embedded(sequence)?;
    check_flow(sequence, "computed", computed)?;
    check_flow(sequence, "true", truth)?;
    let angular_degrees = per_vertex(computed, truth, |u, v| angular_error(u, v).to_degrees());
    let endpoint = per_vertex(computed, truth, endpoint_error);
    let slabs = (0..sequence.n_slabs())
        .map(|s| slab_errors(sequence, s, &angular_degrees[s], &endpoint[s]))
        .collect::<Result<Vec<_>, _>>()?;
    let weights: Vec<f64> = slabs.iter().map(|e| e.duration * e.area).collect();
    let space_time_mean = |mean: fn(&SlabErrors) -> f64| {
        weighted_mean(&slabs.iter().map(mean).collect::<Vec<_>>(), &weights)
    };
    Ok(FlowErrors {
        mean_angular_degrees: space_time_mean(|e| e.mean_angular_degrees),
        mean_endpoint: space_time_mean(|e| e.mean_endpoint),
        max_angular_degrees: maximum(slabs.iter().map(|e| e.max_angular_degrees)),
        max_endpoint: maximum(slabs.iter().map(|e| e.max_endpoint)),
        angular_degrees,
        endpoint,
        slabs,
    })
}

/// `error(u[s][i], v[s][i])` for every slab and vertex.
fn per_vertex(
    u: &[Vec<Vector3<f64>>],
    v: &[Vec<Vector3<f64>>],
    error: impl Fn(&Vector3<f64>, &Vector3<f64>) -> f64,
) -> Vec<Vec<f64>> {
    u.iter()
        .zip(v)
        .map(|(us, vs)| us.iter().zip(vs).map(|(a, b)| error(a, b)).collect())
        .collect()
}

/// Means weighted by the lumped vertex areas of slab `s`'s geometry, and maxima.
fn slab_errors(
    sequence: &MeshSequence,
    s: usize,
    angular_degrees: &[f64],
    endpoint: &[f64],
) -> Result<SlabErrors, AccuracyError> {
    let areas = vertex_areas(sequence.mesh(), &sequence.slab_geometry(s)?);
    Ok(SlabErrors {
        duration: sequence.slab_duration(s),
        area: areas.iter().sum(),
        mean_angular_degrees: weighted_mean(angular_degrees, &areas),
        mean_endpoint: weighted_mean(endpoint, &areas),
        max_angular_degrees: maximum(angular_degrees.iter().copied()),
        max_endpoint: maximum(endpoint.iter().copied()),
    })
}

/// [`compare_flows`] for a computed [`FlowResult`]; an intrinsic one has no R^3 vectors.
pub fn compare_result(
    sequence: &MeshSequence,
    result: &FlowResult,
    truth: &[Vec<Vector3<f64>>],
) -> Result<FlowErrors, AccuracyError> {
    let computed = result.vectors.as_deref().ok_or(AccuracyError::Intrinsic)?;
    compare_flows(sequence, computed, truth)
}

/// Only an embedded sequence (with positions) has R^3 flows to compare.
pub fn check_embedded(sequence: &MeshSequence) -> Result<(), AccuracyError> {
    match sequence.positions(0) {
        Some(_) => Ok(()),
        None => Err(AccuracyError::Intrinsic),
    }
}

/// One finite vector per vertex and slab.
fn check_flow(
    sequence: &MeshSequence,
    which: &'static str,
    flow: &[Vec<Vector3<f64>>],
) -> Result<(), AccuracyError> {
    if flow.len() != sequence.n_slabs() {
        return Err(AccuracyError::SlabCount {
            which,
            expected: sequence.n_slabs(),
            got: flow.len(),
        });
    }
    let n_vertices = sequence.mesh().n_vertices();
    for (slab, vectors) in flow.iter().enumerate() {
        if vectors.len() != n_vertices {
            return Err(AccuracyError::VertexCount {
                which,
                slab,
                expected: n_vertices,
                got: vectors.len(),
            });
        }
        if let Some(vertex) = vectors
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(AccuracyError::NonFinite {
                which,
                slab,
                vertex,
                value: vectors[vertex].into(),
            });
        }
    }
    Ok(())
}

/// `Σ w_i e_i / Σ w_i`.
fn weighted_mean(values: &[f64], weights: &[f64]) -> f64 {
    values.iter().zip(weights).map(|(v, w)| v * w).sum::<f64>() / weights.iter().sum::<f64>()
}

fn maximum(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(0.0, f64::max)
}
