//! Why the default weights are what they are, and how close they come to the best.
//!
//! Textures turning on the unit sphere (true flow `ω ẑ × x`, 0.05 rad per frame, 6 frames):
//! the shipped sample (a dense texture at 642 vertices), the same with grey values × 255, with
//! frames at 30 per second, and both; sparse blobs (`synth::blobs`) at 642 vertices; both
//! textures at 2562 vertices. For each: the scores of the default weights (spread 0.5 edge
//! lengths, time scale 1 frame), the best spread on a fine scan (equivalently the best γ, the
//! temporal weight held at the default's), the paper's fixed weights (γ = 0.1, α = 1, the
//! earlier defaults) and the zero flow. Scores are those of `meshflow::accuracy`: AE on
//! displacements in mean edge lengths, direction error, relative endpoint error, speed ratio.
//!
//! `cargo run --release --example default_parameters`

use meshflow::accuracy::{compare_result, FlowErrors};
use meshflow::flow::{compute_flow, FlowParams, MeshSequence, Weight};
use meshflow::synth::{blobs, rotating_sphere_with, texture, GroundTruth};
use nalgebra::Vector3;

const SPREADS: [f64; 12] = [
    0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.6, 0.7, 0.85, 1.0, 1.4,
];

fn main() -> Result<(), meshflow::Error> {
    println!(
        "{:<28} {:>5} | {:^29} | {:^19} | {:>7} | {:^14} | {:>6}",
        "scene",
        "V",
        "default: AE°  DE°  rel.EPE ratio",
        "best spread λ AE°",
        "default",
        "paper γ=0.1 α=1",
        "zero"
    );
    println!(
        "{:<28} {:>5} | {:>29} | {:>19} | {:>7} | {:>14} | {:>6}",
        "", "", "", "", "/ best", "AE° rel.EPE", "AE°"
    );
    let dense = |level| rotating_sphere_with(texture, level, 6, 1.0, 0.05);
    let sparse = |level| rotating_sphere_with(blobs, level, 6, 1.0, 0.05);
    let sample = dense(3)?;
    row("shipped sample (dense)", &sample)?;
    row("  grey values × 255", &rescaled(&sample, 255.0, 1.0)?)?;
    row(
        "  30 frames per second",
        &rescaled(&sample, 1.0, 1.0 / 30.0)?,
    )?;
    row("  × 255 and 30 fps", &rescaled(&sample, 255.0, 1.0 / 30.0)?)?;
    row("sparse blobs", &sparse(3)?)?;
    row("dense, finer", &dense(4)?)?;
    row("sparse blobs, finer", &sparse(4)?)?;
    Ok(())
}

fn scores(truth: &GroundTruth, params: &FlowParams) -> Result<FlowErrors, meshflow::Error> {
    let flow = compute_flow(&truth.sequence, params)?;
    Ok(compare_result(&truth.sequence, &flow, &truth.flow)?)
}

fn row(name: &str, truth: &GroundTruth) -> Result<(), meshflow::Error> {
    let default = scores(truth, &FlowParams::default())?;
    let mut best = (f64::INFINITY, 0.0);
    for spread in SPREADS {
        let params = FlowParams {
            gamma: Weight::Relative(spread),
            ..FlowParams::default()
        };
        let errors = scores(truth, &params)?;
        if errors.mean_angular_degrees < best.0 {
            best = (errors.mean_angular_degrees, spread);
        }
    }
    let paper = scores(truth, &FlowParams::paper(1.0, 0.0, 0.1))?;
    let zero = FlowErrors::zero_flow(&truth.sequence, &truth.flow)?;
    println!(
        "{name:<28} {:>5} | {:>6.2} {:>5.2} {:>6.1}% {:>5.2} | {:>9.2} {:>7.2}  | {:>6.1}% | {:>6.2} {:>6.1}% | {:>6.2}",
        truth.sequence.mesh().n_vertices(),
        default.mean_angular_degrees,
        default.mean_direction_degrees,
        100.0 * default.relative_endpoint,
        default.median_speed_ratio,
        best.1,
        best.0,
        100.0 * (default.mean_angular_degrees / best.0 - 1.0),
        paper.mean_angular_degrees,
        100.0 * paper.relative_endpoint,
        zero.mean_angular_degrees,
    );
    Ok(())
}

/// The scene with grey values times `grey` and frame times times `time` (the true velocities
/// divide by `time`).
fn rescaled(truth: &GroundTruth, grey: f64, time: f64) -> Result<GroundTruth, meshflow::Error> {
    let sequence = &truth.sequence;
    let k = sequence.n_frames();
    let positions = (0..k)
        .map(|i| sequence.positions(i).expect("embedded").to_vec())
        .collect();
    let intensities = (0..k)
        .map(|i| sequence.intensities(i).iter().map(|v| grey * v).collect())
        .collect();
    let times = sequence.times().iter().map(|t| time * t).collect();
    Ok(GroundTruth {
        sequence: MeshSequence::new(sequence.mesh().clone(), positions, intensities, Some(times))?,
        flow: truth
            .flow
            .iter()
            .map(|slab| slab.iter().map(|v| v / time).collect::<Vec<Vector3<f64>>>())
            .collect(),
    })
}
