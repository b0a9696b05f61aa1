//! Accuracy of a computed flow against a known one, in measures that cannot flatter.
//!
//! Both flows are R^3 velocities per slab and vertex, `u[s][i]` on frame `s` (as
//! [`FlowResult::vectors`]). The measures per vertex:
//!
//! ```text
//! AE    = ∠((d_u, 1), (d_v, 1)),   d = u Δt_s / ℓ_s        angular error (Barron, Fleet &
//!                                                          Beauchemin 1994), on displacements
//! EPE   = |u − v|                                           endpoint error (velocity units)
//! DE    = ∠(u, v) ∈ [0°, 180°]      where |v| ≥ 10 % of the slab's largest true speed
//! ratio = |u| / |v|                 where |v| ≥ 10 % of the slab's largest true speed
//! ```
//!
//! **Why displacements in edge lengths.** The angle between `(u, 1)` and `(v, 1)` weighs the
//! direction of the flow against the "1" of the time axis, so it depends on the units of `u`.
//! Image optical flow measures `u` in pixels per frame; a mesh's pixel is its mean edge length
//! `ℓ_s` (of the slab geometry, `docs/discretization.md` §7), and a frame is `Δt_s`. In surface
//! units per unit time the angle says little: a flow of 0.05 units per frame on a unit sphere
//! scores 2.3° for the zero flow. `d = u Δt_s / ℓ_s` is the displacement over the slab in mesh
//! pixels, whatever the units of lengths and times.
//!
//! **The direction error** `DE` is the angle between the vectors themselves, counted where the
//! truth moves (its speed is at least 10 % of the slab's largest true speed), so that it is
//! not diluted by still regions. A computed vector of length zero has no direction; it counts
//! as 90°, the mean error of a random direction. The zero flow therefore scores 90°.
//!
//! **Summaries.** Every mean approximates a space-time integral: vertex `i` of slab `s` weighs
//! `w = Δt_s a_i^s`, with `a_i^s = Σ_{T∋i} A_T / 3` its lumped area in the slab geometry.
//!
//! ```text
//! mean AE, mean EPE, mean DE   = Σ w e / Σ w                 (DE over the moving vertices)
//! relative EPE                 = Σ w |u − v| / Σ w |v|       (1 for the zero flow)
//! speed ratio                  = the w-weighted median of |u|/|v| over the moving vertices
//! ```
//!
//! [`FlowErrors::zero_flow`] scores the zero flow the same way: a computed flow is only worth
//! something where it beats it.
//!
//! ```
//! use meshflow::accuracy::{compare_result, FlowErrors};
//! use meshflow::flow::{compute_flow, FlowParams, Weight};
//! use meshflow::synth::rotating_sphere;
//!
//! // A texture turning at 0.5 rad per unit time on a 642-vertex sphere; true flow ω ẑ × x.
//! let truth = rotating_sphere(3, 3, 0.1, 0.5)?;
//! let flow = compute_flow(&truth.sequence, &FlowParams::default())?;
//! let errors = compare_result(&truth.sequence, &flow, &truth.flow)?;
//! let zero = FlowErrors::zero_flow(&truth.sequence, &truth.flow)?;
//! assert!(errors.relative_endpoint < 0.5 * zero.relative_endpoint);
//! assert!(errors.mean_angular_degrees < 0.5 * zero.mean_angular_degrees);
//! assert_eq!(errors.angular_degrees.len(), 2); // [slab][vertex]
//! # Ok::<(), meshflow::Error>(())
//! ```
//!
//! [`FlowResult::vectors`]: crate::flow::FlowResult::vectors

mod tracks;

pub use tracks::{
    default_match_distance, match_tracks, score_result, score_tracks, TrackPoint, TrackScores,
    TrackSummary, Tracks, TRACK_REACH,
};

use crate::fem::vertex_areas;
use crate::flow::{FlowError, FlowResult, MeshSequence};
use crate::statistics::weighted_median;
use nalgebra::{Vector3, Vector4};

/// Where the truth counts as moving, for the direction error and the speed ratio: true speed at
/// least this fraction of the slab's largest true speed.
pub const MOVING_FRACTION: f64 = 0.1;

/// The direction error of a computed vector of length zero (it has none): the mean angle
/// between a fixed and a random direction.
const NO_DIRECTION_DEGREES: f64 = 90.0;

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
    #[error("tracks: frame {frame} has {got} points, frame 0 has {expected} (a (K, N, 3) array has N points in every frame, NaN where untracked)")]
    TrackCount {
        frame: usize,
        expected: usize,
        got: usize,
    },
    #[error(
        "tracks: frame {frame}, point {point} is neither finite nor NaN in all three coordinates"
    )]
    BadTrackPoint { frame: usize, point: usize },
    #[error("tracks must have shape (K, N, 3), got {0:?}")]
    TracksShape(Vec<u64>),
    #[error("the tracks have {tracks} frames, the sequence has {frames}")]
    TrackFrames { tracks: usize, frames: usize },
    #[error("tracks: frame {frame}, point {point} lies {distance:.3e} from the surface's bounding box, over {}× its diameter {diameter:.3e}: not a point on it (wrong units or a corrupt file?)", TRACK_REACH)]
    TrackFarOff {
        frame: usize,
        point: usize,
        distance: f64,
        diameter: f64,
    },
    #[error("the matching distance must be a positive number, got {0}")]
    MatchDistance(f64),
    #[error(
        "cannot derive a matching distance: the first frame needs two distinct points (give one)"
    )]
    NoSpacing,
    #[error("the surface for scoring: {0}")]
    Surface(String),
    #[error(transparent)]
    Flow(#[from] FlowError),
}

/// The summaries of one slab (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabErrors {
    /// `Δt_s`.
    pub duration: f64,
    /// `A_s`: the area of the slab geometry.
    pub area: f64,
    /// `ℓ_s`: the mean edge length of the slab geometry, the unit of the displacements in AE.
    pub edge_length: f64,
    pub mean_angular_degrees: f64,
    pub mean_endpoint: f64,
    /// Mean DE over the moving vertices; NaN when the truth does not move in this slab.
    pub mean_direction_degrees: f64,
    /// `Σ a |u − v| / Σ a |v|`; NaN when the truth is zero in this slab.
    pub relative_endpoint: f64,
    pub max_angular_degrees: f64,
    pub max_endpoint: f64,
}

/// A computed flow measured against the true one (see the module docs for the formulas).
#[derive(Clone, Debug, PartialEq)]
pub struct FlowErrors {
    /// `angular_degrees[s][i]`: AE at vertex `i` of slab `s`, degrees, on displacements in
    /// mean edge lengths.
    pub angular_degrees: Vec<Vec<f64>>,
    /// `endpoint[s][i]`: EPE at vertex `i` of slab `s`, velocity units.
    pub endpoint: Vec<Vec<f64>>,
    /// `direction_degrees[s][i]`: DE in degrees; NaN where the truth is not moving.
    pub direction_degrees: Vec<Vec<f64>>,
    pub slabs: Vec<SlabErrors>,
    /// Space-time mean of the AE (degrees).
    pub mean_angular_degrees: f64,
    /// Space-time mean of the EPE (velocity units).
    pub mean_endpoint: f64,
    /// Space-time mean of the DE over the moving vertices (degrees); NaN if nothing moves.
    pub mean_direction_degrees: f64,
    /// `∫∫ |u − v| / ∫∫ |v|`; NaN if the true flow is zero everywhere.
    pub relative_endpoint: f64,
    /// Weighted median of `|u| / |v|` over the moving vertices; NaN if nothing moves.
    pub median_speed_ratio: f64,
    /// Fraction of the space-time measure where the truth moves (DE and ratio are taken there).
    pub moving_fraction: f64,
    pub max_angular_degrees: f64,
    pub max_endpoint: f64,
}

impl FlowErrors {
    /// The scores of the zero flow against `truth`: the baseline every computed flow must beat.
    pub fn zero_flow(
        sequence: &MeshSequence,
        truth: &[Vec<Vector3<f64>>],
    ) -> Result<Self, AccuracyError> {
        let zero: Vec<Vec<Vector3<f64>>> = truth
            .iter()
            .map(|slab| vec![Vector3::zeros(); slab.len()])
            .collect();
        compare_flows(sequence, &zero, truth)
    }
}

/// AE between displacements `a` and `b` (radians): the angle between `(a, 1)` and `(b, 1)` in
/// R^4, `acos((a·b + 1) / √((|a|²+1)(|b|²+1)))`.
///
/// Evaluated as Kahan's `2 atan2(|x|y| − y|x||, |x|y| + y|x||)` for `x = (a, 1)`, `y = (b, 1)`:
/// accurate for small angles (where `acos` loses half the digits), exactly `0` when `a = b`
/// and exactly symmetric in `a`, `b`.
pub fn angular_error(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let x = Vector4::new(a.x, a.y, a.z, 1.0);
    let y = Vector4::new(b.x, b.y, b.z, 1.0);
    angle_between(&x, &y)
}

/// The angle between two vectors (radians, in `[0, π]`), by Kahan's formula; 0 if either is 0.
fn angle_between<const D: usize>(
    x: &nalgebra::SVector<f64, D>,
    y: &nalgebra::SVector<f64, D>,
) -> f64 {
    let (x_scaled, y_scaled) = (x * y.norm(), y * x.norm());
    2.0 * (x_scaled - y_scaled)
        .norm()
        .atan2((x_scaled + y_scaled).norm())
}

/// DE between the directions of `u` and `v` (degrees); 90° when `u` is zero (see the module
/// docs).
pub fn direction_error_degrees(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    if *u == Vector3::zeros() {
        return NO_DIRECTION_DEGREES;
    }
    angle_between(u, v).to_degrees()
}

/// Endpoint error `|u − v|`.
pub fn endpoint_error(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    (u - v).norm()
}

/// Compares the `computed` flow of `sequence` with the `truth`, both `[s][i]` in R^3 on frame
/// `s`: per-vertex AE, EPE and DE, and the summaries of the module docs per slab and over the
/// sequence.
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
    let slabs: Vec<SlabComparison> = (0..sequence.n_slabs())
        .map(|s| SlabComparison::new(sequence, s, &computed[s], &truth[s]))
        .collect::<Result<_, _>>()?;
    let all = |value: fn(&SlabComparison) -> &[f64]| -> Vec<(f64, f64)> {
        slabs
            .iter()
            .flat_map(|c| c.space_time_weights().zip(value(c).iter().copied()))
            .collect()
    };
    let moving_weight: f64 = all(|c| &c.direction)
        .iter()
        .filter(|(_, e)| !e.is_nan())
        .map(|(w, _)| w)
        .sum();
    let total_weight: f64 = all(|c| &c.true_speed).iter().map(|(w, _)| w).sum();
    Ok(FlowErrors {
        mean_angular_degrees: weighted_mean(&all(|c| &c.angular)),
        mean_endpoint: weighted_mean(&all(|c| &c.endpoint)),
        mean_direction_degrees: weighted_mean(&all(|c| &c.direction)),
        relative_endpoint: relative(
            weighted_mean(&all(|c| &c.endpoint)),
            weighted_mean(&all(|c| &c.true_speed)),
        ),
        median_speed_ratio: weighted_median(all(|c| &c.speed_ratio)),
        moving_fraction: moving_weight / total_weight,
        max_angular_degrees: maximum(slabs.iter().flat_map(|c| &c.angular)),
        max_endpoint: maximum(slabs.iter().flat_map(|c| &c.endpoint)),
        slabs: slabs.iter().map(SlabComparison::summary).collect(),
        angular_degrees: slabs.iter().map(|c| c.angular.clone()).collect(),
        endpoint: slabs.iter().map(|c| c.endpoint.clone()).collect(),
        direction_degrees: slabs.into_iter().map(|c| c.direction).collect(),
    })
}

/// The per-vertex measures of one slab, with its weights.
struct SlabComparison {
    duration: f64,
    edge_length: f64,
    areas: Vec<f64>,
    angular: Vec<f64>,
    endpoint: Vec<f64>,
    /// NaN where the truth is not moving.
    direction: Vec<f64>,
    /// NaN where the truth is not moving.
    speed_ratio: Vec<f64>,
    true_speed: Vec<f64>,
}

impl SlabComparison {
    fn new(
        sequence: &MeshSequence,
        s: usize,
        computed: &[Vector3<f64>],
        truth: &[Vector3<f64>],
    ) -> Result<Self, AccuracyError> {
        let geometry = sequence.slab_geometry(s)?;
        let edge_length = geometry.mean_edge_length();
        let duration = sequence.slab_duration(s);
        let to_pixels = duration / edge_length;
        let true_speed: Vec<f64> = truth.iter().map(|v| v.norm()).collect();
        let threshold = MOVING_FRACTION * maximum(&true_speed);
        let moving = |i: usize| threshold > 0.0 && true_speed[i] >= threshold;
        let per_moving_vertex = |measure: &dyn Fn(usize) -> f64| -> Vec<f64> {
            (0..truth.len())
                .map(|i| if moving(i) { measure(i) } else { f64::NAN })
                .collect()
        };
        Ok(Self {
            duration,
            edge_length,
            areas: vertex_areas(sequence.mesh(), &geometry),
            angular: (0..truth.len())
                .map(|i| {
                    angular_error(&(computed[i] * to_pixels), &(truth[i] * to_pixels)).to_degrees()
                })
                .collect(),
            endpoint: (0..truth.len())
                .map(|i| endpoint_error(&computed[i], &truth[i]))
                .collect(),
            direction: per_moving_vertex(&|i| direction_error_degrees(&computed[i], &truth[i])),
            speed_ratio: per_moving_vertex(&|i| computed[i].norm() / true_speed[i]),
            true_speed,
        })
    }

    /// `Δt_s a_i^s` for every vertex.
    fn space_time_weights(&self) -> impl Iterator<Item = f64> + '_ {
        self.areas.iter().map(|a| self.duration * a)
    }

    fn summary(&self) -> SlabErrors {
        let by_area = |values: &[f64]| -> Vec<(f64, f64)> {
            self.areas
                .iter()
                .copied()
                .zip(values.iter().copied())
                .collect()
        };
        SlabErrors {
            duration: self.duration,
            area: self.areas.iter().sum(),
            edge_length: self.edge_length,
            mean_angular_degrees: weighted_mean(&by_area(&self.angular)),
            mean_endpoint: weighted_mean(&by_area(&self.endpoint)),
            mean_direction_degrees: weighted_mean(&by_area(&self.direction)),
            relative_endpoint: relative(
                weighted_mean(&by_area(&self.endpoint)),
                weighted_mean(&by_area(&self.true_speed)),
            ),
            max_angular_degrees: maximum(&self.angular),
            max_endpoint: maximum(&self.endpoint),
        }
    }
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

/// `Σ w e / Σ w` over the pairs `(w, e)` whose `e` is not NaN; NaN if there are none.
fn weighted_mean(pairs: &[(f64, f64)]) -> f64 {
    let (sum, weight) = pairs
        .iter()
        .filter(|(_, e)| !e.is_nan())
        .fold((0.0, 0.0), |(s, t), (w, e)| (s + w * e, t + w));
    if weight > 0.0 {
        sum / weight
    } else {
        f64::NAN
    }
}

/// `error / size`, NaN when `size` is zero (nothing to be relative to).
fn relative(error: f64, size: f64) -> f64 {
    if size > 0.0 {
        error / size
    } else {
        f64::NAN
    }
}

fn maximum<'a>(values: impl IntoIterator<Item = &'a f64>) -> f64 {
    values.into_iter().copied().fold(0.0, f64::max)
}
