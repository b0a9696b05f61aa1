use meshflow::accuracy::compare_result;
use meshflow::flow::{compute_flow, FlowParams};
use meshflow::synth::deforming_sphere;
fn main() {
    for strain in [0.0, 0.5] {
        for (name, params) in [
            ("paper γ=1e-3", FlowParams::paper(1.0, 0.0, 1e-3)),
            ("default", FlowParams::default()),
        ] {
            let v: Vec<String> = (2..=4)
                .map(|level| {
                    let truth = deforming_sphere(level, 3, 0.1, 0.5, strain).unwrap();
                    let flow = compute_flow(&truth.sequence, &params).unwrap();
                    let e = compare_result(&truth.sequence, &flow, &truth.flow).unwrap();
                    format!(
                        "AE {:.3} DE {:.3} REPE {:.4} ratio {:.3}",
                        e.mean_angular_degrees,
                        e.mean_direction_degrees,
                        e.relative_endpoint,
                        e.median_speed_ratio
                    )
                })
                .collect();
            println!("strain {strain} {name}: {v:?}");
        }
    }
}
