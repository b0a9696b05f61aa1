//! Trajectories (`flow::advect`): points carried by a flow through the slabs.

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::flow::{advect, compute_flow, vertex_seeds, FlowParams};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::synth::rotating_sphere;
use nalgebra::{Rotation3, Vector2, Vector3};

const FRAMES: usize = 11;
const DT: f64 = 0.1;
const OMEGA: f64 = 0.5;

/// Carried by the true flow `ω ẑ × x` (as vertex-frame vectors) for 10 frames, every vertex of
/// the 2562-vertex sphere ends within 1 % of the radius of where the rotation takes it.
#[test]
fn the_true_rotation_carries_vertices_along_their_circles() {
    let scene = rotating_sphere(4, FRAMES, DT, OMEGA).unwrap();
    let sequence = &scene.sequence;
    let mesh = sequence.mesh();
    let x = sequence.positions(0).unwrap();
    let geometry = IntrinsicGeometry::from_positions(mesh, x).unwrap();
    let connection = Connection::new(mesh, &geometry);
    let frames = vertex_frames_in_r3(mesh, &geometry, &connection, x).unwrap();
    let intrinsic: Vec<Vec<Vector2<f64>>> = scene
        .flow
        .iter()
        .map(|u| {
            u.iter()
                .zip(&frames)
                .map(|(u, p)| p.transpose() * u)
                .collect()
        })
        .collect();
    let trajectories = advect(sequence, &intrinsic, &vertex_seeds(sequence)).unwrap();
    let positions = trajectories.positions(sequence).unwrap();
    let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), OMEGA * DT * (FRAMES - 1) as f64);
    let worst = x
        .iter()
        .zip(&positions[FRAMES - 1])
        .map(|(x0, end)| (end - turn * x0).norm())
        .fold(0.0, f64::max);
    println!("worst distance from the rotated vertex: {worst:.2e}");
    assert!(worst < 0.01, "{worst}");
    assert_eq!(positions.len(), FRAMES);
    assert!(!trajectories.reached_boundary.iter().any(|&b| b));
}

/// Carried by the *computed* flow (the paper's single linear solve, γ = 3e-4, α = 0.1: the best
/// of γ ∈ {1e-4, 3e-4, 1e-3, 1e-2} × α ∈ {1, 0.1}), vertices stay near their circles of
/// latitude: 1.3 % of the radius on average, 3 % at worst, and turn by 0.45 of the true 0.5 rad
/// (the linear model underestimates speeds; issue 13's warping is meant to bring the worst
/// case under 1 %).
#[test]
fn computed_flow_trajectories_stay_on_the_true_circles() {
    let scene = rotating_sphere(4, FRAMES, DT, OMEGA).unwrap();
    let sequence = &scene.sequence;
    let result = compute_flow(sequence, &FlowParams::paper(0.1, 0.0, 3e-4)).unwrap();
    let trajectories = advect(sequence, &result.intrinsic, &vertex_seeds(sequence)).unwrap();
    let positions = trajectories.positions(sequence).unwrap();
    let x = sequence.positions(0).unwrap();
    let (mut off_circle, mut turned, mut mean_off) = (0.0f64, Vec::new(), 0.0);
    for (x0, end) in x.iter().zip(&positions[FRAMES - 1]) {
        let (r0, r1) = (x0.xy().norm(), end.xy().norm());
        off_circle = off_circle.max((r1 - r0).abs()).max((end.z - x0.z).abs());
        mean_off += ((r1 - r0).powi(2) + (end.z - x0.z).powi(2)).sqrt() / x.len() as f64;
        if r0 > 0.5 {
            turned.push((end.y.atan2(end.x) - x0.y.atan2(x0.x)).rem_euclid(std::f64::consts::TAU));
        }
    }
    let mean_turn = turned.iter().sum::<f64>() / turned.len() as f64;
    println!(
        "off the circles {off_circle:.2e} mean {mean_off:.2e}, mean turn {mean_turn:.3} (true 0.5)"
    );
    assert!(
        mean_off < 0.015 && off_circle < 0.035,
        "{mean_off}, {off_circle}"
    );
    assert!((mean_turn - 0.5).abs() < 0.06, "{mean_turn}");
}
