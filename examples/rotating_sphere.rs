//! Ground truth: a texture turning on the unit sphere, flow against `ω ẑ × x` for a few mesh
//! levels and smoothness weights. `cargo run --release --example rotating_sphere`
use meshflow::fem::vertex_areas;
use meshflow::flow::{compute_flow, FlowParams};
use meshflow::synth::{angular_error, endpoint_error, rotating_sphere, weighted_mean};

fn main() -> Result<(), meshflow::Error> {
    println!(
        "{:>5} {:>7} {:>8} {:>10} {:>10} {:>8}",
        "level", "verts", "gamma", "mean AE°", "mean EPE", "seconds"
    );
    for gamma in [1e-2, 1e-3] {
        for level in 2..=5 {
            let truth = rotating_sphere(level, 3, 0.1, 0.5)?;
            let params = FlowParams {
                gamma,
                ..FlowParams::default()
            };
            let flow = compute_flow(&truth.sequence, &params)?;
            let computed = &flow.vectors.as_ref().expect("embedded")[0];
            let mesh = truth.sequence.mesh();
            let geometry = &flow_geometry(&truth.sequence);
            let areas = vertex_areas(mesh, geometry);
            let ae: Vec<f64> = computed
                .iter()
                .zip(&truth.flow[0])
                .map(|(u, v)| angular_error(u, v).to_degrees())
                .collect();
            let epe: Vec<f64> = computed
                .iter()
                .zip(&truth.flow[0])
                .map(|(u, v)| endpoint_error(u, v))
                .collect();
            println!(
                "{level:>5} {:>7} {gamma:>8.0e} {:>10.4} {:>10.2e} {:>8.2}",
                mesh.n_vertices(),
                weighted_mean(&ae, &areas),
                weighted_mean(&epe, &areas),
                flow.timings.total
            );
        }
    }
    Ok(())
}

fn flow_geometry(sequence: &meshflow::flow::MeshSequence) -> meshflow::geometry::IntrinsicGeometry {
    meshflow::geometry::IntrinsicGeometry::new(sequence.mesh(), sequence.edge_lengths(0).to_vec())
        .expect("valid")
}
