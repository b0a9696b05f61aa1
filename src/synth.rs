//! Synthetic sequences with known flow, and the error measures that compare flows.

use crate::flow::{FlowError, MeshSequence};
use crate::shapes::icosphere;
use nalgebra::{Rotation3, Vector3};

/// A sequence and the flow that generated it: `flow[s][i]` in R^3 on frame `s`.
pub struct GroundTruth {
    pub sequence: MeshSequence,
    pub flow: Vec<Vec<Vector3<f64>>>,
}

/// A smooth grey-value pattern on R^3 with features in every direction (range about [0, 1]).
pub fn texture(p: &Vector3<f64>) -> f64 {
    0.5 + 0.2 * (3.0 * p.x + 1.0).sin() * (2.0 * p.y).cos()
        + 0.15 * (4.0 * p.z - p.x).sin()
        + 0.1 * (2.5 * p.y + 3.0 * p.z).cos()
}

/// The unit icosphere of the given level at rest, with [`texture`] turning about the z-axis at
/// `omega` radians per unit time; frames at `0, dt, 2 dt, …`. The true flow is `ω ẑ × x`.
pub fn rotating_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<GroundTruth, FlowError> {
    let sphere = icosphere(level);
    let mesh = sphere.mesh().expect("icospheres are valid meshes");
    let times: Vec<f64> = (0..n_frames).map(|k| k as f64 * dt).collect();
    let intensities = times
        .iter()
        .map(|&t| {
            let back = Rotation3::from_axis_angle(&Vector3::z_axis(), -omega * t);
            sphere
                .positions
                .iter()
                .map(|p| texture(&(back * p)))
                .collect()
        })
        .collect();
    let axis = Vector3::new(0.0, 0.0, omega);
    let truth: Vec<Vector3<f64>> = sphere.positions.iter().map(|p| axis.cross(p)).collect();
    let sequence = MeshSequence::new(
        mesh,
        vec![sphere.positions; n_frames],
        intensities,
        Some(times),
    )?;
    Ok(GroundTruth {
        sequence,
        flow: vec![truth; n_frames - 1],
    })
}

/// Angular error between two R^3 flow vectors, with a 1 appended as a time component (Barron
/// et al. 1994; the measure of Bauer, Grasmair & Kirisits): `acos((u·v + 1) / √((|u|²+1)(|v|²+1)))`.
pub fn angular_error(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    let cosine = (u.dot(v) + 1.0) / ((u.norm_squared() + 1.0) * (v.norm_squared() + 1.0)).sqrt();
    cosine.clamp(-1.0, 1.0).acos()
}

/// Endpoint error `|u − v|`.
pub fn endpoint_error(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    (u - v).norm()
}

/// `Σ w_i e_i / Σ w_i`.
pub fn weighted_mean(values: &[f64], weights: &[f64]) -> f64 {
    values.iter().zip(weights).map(|(v, w)| v * w).sum::<f64>() / weights.iter().sum::<f64>()
}
