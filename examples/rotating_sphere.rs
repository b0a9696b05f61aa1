//! Ground truth under refinement: a texture turning on the unit sphere (true flow `ω ẑ × x`),
//! and on a sphere stretching into an ellipsoid (true flow `D(t)(ω ẑ × p)`, see
//! `synth::deforming_sphere`), at icosphere levels 2 to 5 (162 to 10,242 vertices), with the
//! default weights and with the paper's fixed γ = 1e-3. Prints the scores of
//! `meshflow::accuracy`: angular error on displacements in mean edge lengths, direction error,
//! relative endpoint error (these two converge under refinement), median speed ratio, and the
//! zero flow's angular error for comparison.
//!
//! For the finest level with the default weights it writes into
//! `out/rotating_sphere/{rotating,deforming}/`: `sphere_SSSS.vtu` + `sphere.pvd` (computed and
//! true flow, errors, the image) and the pictures `grey_`, `flow_`, `arrows_`,
//! `angular_error_SSSS.png`.
//!
//! `cargo run --release --example rotating_sphere`
use meshflow::accuracy::{compare_result, FlowErrors};
use meshflow::flow::{compute_flow, FlowParams, FlowResult};
use meshflow::format::vtk::NamedArray;
use meshflow::format::IoError;
use meshflow::render::{sequence_views, write_slab_pictures, FigureOptions};
use meshflow::run::write_slab_vtus;
use meshflow::synth::{deforming_sphere, GroundTruth};
use std::path::Path;

/// Frames, time step, angular velocity (rad per unit time).
const FRAMES: usize = 3;
const DT: f64 = 0.1;
const OMEGA: f64 = 0.5;
const LEVELS: std::ops::RangeInclusive<u32> = 2..=5;

fn main() -> Result<(), meshflow::Error> {
    println!(
        "{:>10} {:>5} {:>7} {:>12} {:>8} {:>8} {:>8} {:>6} {:>8} {:>8}",
        "sequence",
        "level",
        "verts",
        "weights",
        "AE°",
        "DE°",
        "rel.EPE",
        "ratio",
        "zero AE°",
        "seconds"
    );
    for (name, strain) in [("rotating", 0.0), ("deforming", 0.5)] {
        for (label, params) in [
            ("default", FlowParams::default()),
            ("γ = 1e-3", FlowParams::paper(1.0, 0.0, 1e-3)),
        ] {
            for level in LEVELS {
                let truth = deforming_sphere(level, FRAMES, DT, OMEGA, strain)?;
                let flow = compute_flow(&truth.sequence, &params)?;
                let errors = compare_result(&truth.sequence, &flow, &truth.flow)?;
                let zero = FlowErrors::zero_flow(&truth.sequence, &truth.flow)?;
                println!(
                    "{name:>10} {level:>5} {:>7} {label:>12} {:>8.3} {:>8.3} {:>7.1}% {:>6.3} {:>8.3} {:>8.2}",
                    truth.sequence.mesh().n_vertices(),
                    errors.mean_angular_degrees,
                    errors.mean_direction_degrees,
                    100.0 * errors.relative_endpoint,
                    errors.median_speed_ratio,
                    zero.mean_angular_degrees,
                    flow.timings.total
                );
                if level == *LEVELS.end() && label == "default" {
                    let out = Path::new("out/rotating_sphere").join(name);
                    write_outputs(&out, &truth, &flow, &errors)?;
                }
            }
        }
    }
    println!("pictures and VTU of the finest level, default weights, in out/rotating_sphere/");
    Ok(())
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
            NamedArray::scalars("direction_error", &errors.direction_degrees[s]),
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
