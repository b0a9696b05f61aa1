//! Ground truth: a texture turning on the unit sphere (true flow `ω ẑ × x`), and on a sphere
//! stretching into an ellipsoid (true flow `D(t)(ω ẑ × p)`, see `synth::deforming_sphere`).
//! Space-time, area-weighted mean angular and endpoint errors (`accuracy::compare_flows`) for a
//! few mesh levels and smoothness weights; the mean angular error falls under refinement.
//!
//! For the finest level at γ = 1e-3 it writes into `out/rotating_sphere/{rotating,deforming}/`:
//! `sphere_SSSS.vtu` + `sphere.pvd` (computed and true flow, both errors, the image) and the
//! pictures `grey_`, `flow_`, `arrows_`, `angular_error_SSSS.png`.
//!
//! `cargo run --release --example rotating_sphere`
use meshflow::accuracy::{compare_result, FlowErrors};
use meshflow::flow::{compute_flow, FlowParams, FlowResult};
use meshflow::io::vtk::NamedArray;
use meshflow::io::{write_slab_vtus, IoError};
use meshflow::render::{sequence_views, write_slab_pictures, FigureOptions};
use meshflow::synth::{deforming_sphere, GroundTruth};
use std::path::Path;

/// Frames, time step, angular velocity (rad per unit time).
const FRAMES: usize = 3;
const DT: f64 = 0.1;
const OMEGA: f64 = 0.5;
const LEVELS: std::ops::RangeInclusive<u32> = 2..=5;
const GAMMAS: [f64; 2] = [1e-2, 1e-3];

fn main() -> Result<(), meshflow::Error> {
    println!(
        "{:>10} {:>5} {:>7} {:>8} {:>10} {:>10} {:>8}",
        "sequence", "level", "verts", "gamma", "mean AE°", "mean EPE", "seconds"
    );
    for (name, strain) in [("rotating", 0.0), ("deforming", 0.5)] {
        for gamma in GAMMAS {
            for level in LEVELS {
                let truth = deforming_sphere(level, FRAMES, DT, OMEGA, strain)?;
                let (flow, errors) = solve(&truth, gamma)?;
                print_row(name, level, gamma, &truth, &flow, &errors);
                if level == *LEVELS.end() && gamma == GAMMAS[1] {
                    let out = Path::new("out/rotating_sphere").join(name);
                    write_outputs(&out, &truth, &flow, &errors)?;
                }
            }
        }
    }
    println!("pictures and VTU of the finest level at γ = 1e-3 in out/rotating_sphere/");
    Ok(())
}

fn solve(truth: &GroundTruth, gamma: f64) -> Result<(FlowResult, FlowErrors), meshflow::Error> {
    let params = FlowParams {
        gamma,
        ..FlowParams::default()
    };
    let flow = compute_flow(&truth.sequence, &params)?;
    let errors = compare_result(&truth.sequence, &flow, &truth.flow)?;
    Ok((flow, errors))
}

fn print_row(
    name: &str,
    level: u32,
    gamma: f64,
    truth: &GroundTruth,
    flow: &FlowResult,
    errors: &FlowErrors,
) {
    println!(
        "{name:>10} {level:>5} {:>7} {gamma:>8.0e} {:>10.4} {:>10.2e} {:>8.2}",
        truth.sequence.mesh().n_vertices(),
        errors.mean_angular_degrees,
        errors.mean_endpoint,
        flow.timings.total
    );
}

/// VTU per slab (computed and true flow, errors, image) and the pictures of every slab.
fn write_outputs(
    out: &Path,
    truth: &GroundTruth,
    flow: &FlowResult,
    errors: &FlowErrors,
) -> Result<(), meshflow::Error> {
    std::fs::create_dir_all(out).map_err(|e| IoError::file(out, e))?;
    let sequence = &truth.sequence;
    let vectors = flow.vectors.as_ref().expect("the spheres are embedded");
    write_slab_vtus(out, "sphere", sequence, |s| {
        vec![
            NamedArray::vectors("flow", &vectors[s]),
            NamedArray::vectors("true_flow", &truth.flow[s]),
            NamedArray::scalars("angular_error", &errors.angular_degrees[s]),
            NamedArray::scalars("endpoint_error", &errors.endpoint[s]),
            NamedArray::scalars("intensity", sequence.intensities(s)),
        ]
    })?;
    let views = sequence_views(
        sequence,
        vectors,
        Some(&errors.angular_degrees),
        0..sequence.n_slabs(),
    )?;
    write_slab_pictures(
        out,
        sequence.mesh().faces(),
        &views,
        &FigureOptions::default(),
        &|| {},
    )?;
    Ok(())
}
