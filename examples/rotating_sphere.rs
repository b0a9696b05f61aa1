//! Ground truth: a texture turning on the unit sphere (true flow `ω ẑ × x`), and on a sphere
//! stretching into an ellipsoid (true flow `D(t)(ω ẑ × p)`, see `synth::deforming_sphere`).
//! Space-time, area-weighted mean angular and endpoint errors (`accuracy::compare_flows`) for a
//! few mesh levels and smoothness weights. `cargo run --release --example rotating_sphere`
use meshflow::accuracy::compare_result;
use meshflow::flow::{compute_flow, FlowParams};
use meshflow::synth::{deforming_sphere, GroundTruth};

/// Frames, time step, angular velocity (rad per unit time).
const FRAMES: usize = 3;
const DT: f64 = 0.1;
const OMEGA: f64 = 0.5;

fn main() -> Result<(), meshflow::Error> {
    println!(
        "{:>10} {:>5} {:>7} {:>8} {:>10} {:>10} {:>8}",
        "sequence", "level", "verts", "gamma", "mean AE°", "mean EPE", "seconds"
    );
    for (name, strain) in [("rotating", 0.0), ("deforming", 0.5)] {
        for gamma in [1e-2, 1e-3] {
            for level in 2..=5 {
                let truth = deforming_sphere(level, FRAMES, DT, OMEGA, strain)?;
                print_row(name, level, gamma, &truth)?;
            }
        }
    }
    Ok(())
}

fn print_row(
    name: &str,
    level: u32,
    gamma: f64,
    truth: &GroundTruth,
) -> Result<(), meshflow::Error> {
    let params = FlowParams {
        gamma,
        ..FlowParams::default()
    };
    let flow = compute_flow(&truth.sequence, &params)?;
    let errors = compare_result(&truth.sequence, &flow, &truth.flow)?;
    println!(
        "{name:>10} {level:>5} {:>7} {gamma:>8.0e} {:>10.4} {:>10.2e} {:>8.2}",
        truth.sequence.mesh().n_vertices(),
        errors.mean_angular_degrees,
        errors.mean_endpoint,
        flow.timings.total
    );
    Ok(())
}
