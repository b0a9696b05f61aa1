//! Large motions: a texture turning on the sphere by 0.05 to 1 rad per frame, rigidly and
//! shearing (the equator turning by that much, the poles still), the paper's single linear
//! solve against coarse-to-fine symmetric warping (`--large-motion`), each with the best γ of
//! {1e-4, 3e-4, 1e-3} and the default temporal smoothing (time scale 1 frame). Mean angular
//! error against the true flow `ω ẑ × x`, and the cost of warping relative to one solve.
//!
//! `cargo run --release --example large_motion [-- LEVEL FRAMES]` (default: icosphere level 4,
//! 2562 vertices, 6 frames).

use meshflow::accuracy::compare_result;
use meshflow::flow::{compute_flow, FlowParams, Warping};
use meshflow::synth::{rotating_sphere, shearing_sphere, GroundTruth};
use std::time::Instant;

const GAMMAS: [f64; 3] = [1e-4, 3e-4, 1e-3];

fn main() -> Result<(), meshflow::Error> {
    let args: Vec<u32> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("a number"))
        .collect();
    let (level, frames) = (
        args.first().copied().unwrap_or(4),
        args.get(1).copied().unwrap_or(6),
    );
    for (name, scene) in [
        ("turning", rotating_sphere as fn(u32, usize, f64, f64) -> _),
        ("shearing", shearing_sphere),
    ] {
        println!("texture {name} on the level-{level} icosphere, {frames} frames, mean angular error (best γ)");
        println!(
            "{:>10} {:>22} {:>22} {:>10}",
            "rad/frame", "single solve", "--large-motion", "cost"
        );
        for rotation in [0.05, 0.3, 0.6, 1.0] {
            let scene: GroundTruth = scene(level, frames as usize, 1.0, rotation)?;
            let single = best_of_gammas(&scene, Warping::NONE)?;
            let warped = best_of_gammas(&scene, Warping::LARGE_MOTION)?;
            println!(
                "{rotation:>10} {:>12.2}° (γ {:.0e}) {:>12.2}° (γ {:.0e}) {:>9.1}×",
                single.0,
                single.1,
                warped.0,
                warped.1,
                warped.2 / single.2
            );
        }
    }
    Ok(())
}

/// The least mean angular error over [`GAMMAS`], with its γ and seconds.
fn best_of_gammas(
    scene: &GroundTruth,
    warping: Warping,
) -> Result<(f64, f64, f64), meshflow::Error> {
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for gamma in GAMMAS {
        let params = FlowParams {
            warping,
            gamma: meshflow::flow::Weight::Value(gamma),
            ..FlowParams::default()
        };
        let start = Instant::now();
        let result = compute_flow(&scene.sequence, &params)?;
        let seconds = start.elapsed().as_secs_f64();
        let error = compare_result(&scene.sequence, &result, &scene.flow)?.mean_angular_degrees;
        if error < best.0 {
            best = (error, gamma, seconds);
        }
    }
    Ok(best)
}
