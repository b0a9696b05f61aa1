//! Large motions: a texture turning on the sphere by 0.05 to 1 rad per frame, rigidly and
//! shearing (the equator turning by that much, the poles still), the paper's single linear
//! solve against coarse-to-fine symmetric warping (`--large-motion`), each with the best γ of
//! {1e-4, 3e-4, 1e-3} and the default temporal smoothing (time scale 1 frame). Mean angular
//! error against the true flow `ω ẑ × x`, and the cost of warping relative to one solve.
//!
//! The last column is the default solve, which checks its linear flow against the warped
//! images and warps by itself when the motion is too large for it (`flow::motion`): its error,
//! the linearization error `η` it measured and whether it warped.
//!
//! The column "minimizer" separates the two sources of error: it warps from the *true* flow
//! (three warps on the original images, at the γ `--large-motion` chose), which converges to
//! the energy's own minimizer near the truth. Its error is the model's at that γ (the covariant
//! regularizer's bias, and the discretization), which no warping schedule can beat; the gap
//! between it and `--large-motion` is what the coarse-to-fine search leaves.
//!
//! `cargo run --release --example large_motion [-- LEVEL FRAMES [REGULARIZER]]` (default:
//! icosphere level 4, 2562 vertices, 6 frames, the covariant regularizer; `strain` for
//! `--regularizer strain`).

use meshflow::accuracy::compare_result;
use meshflow::flow::{
    compute_flow, warped_slab, FlowParams, FlowProblem, MotionCheck, Regularizer, Warping, Weight,
};
use meshflow::synth::{rotating_sphere, shearing_sphere, GroundTruth};
use std::time::Instant;

const GAMMAS: [f64; 3] = [1e-4, 3e-4, 1e-3];

fn main() -> Result<(), meshflow::Error> {
    let text: Vec<String> = std::env::args().skip(1).collect();
    let args: Vec<u32> = text
        .iter()
        .take(2)
        .map(|a| a.parse().expect("a number"))
        .collect();
    let regularizer: Regularizer = match text.get(2) {
        Some(name) => name.parse().expect("covariant or strain"),
        None => Regularizer::Covariant,
    };
    let (level, frames) = (
        args.first().copied().unwrap_or(4),
        args.get(1).copied().unwrap_or(6),
    );
    for (name, scene) in [
        ("turning", rotating_sphere as fn(u32, usize, f64, f64) -> _),
        ("shearing", shearing_sphere),
    ] {
        println!("texture {name} on the level-{level} icosphere, {frames} frames, {regularizer:?} regularizer, mean angular error (best γ)");
        println!(
            "{:>10} {:>22} {:>22} {:>10} {:>10} {:>24}",
            "rad/frame",
            "single solve",
            "--large-motion",
            "minimizer",
            "cost",
            "default (η, warped?)"
        );
        for rotation in [0.05, 0.1, 0.2, 0.3, 0.6, 1.0] {
            let scene: GroundTruth = scene(level, frames as usize, 1.0, rotation)?;
            let single = best_of_gammas(&scene, Warping::NONE, false, regularizer)?;
            let warped = best_of_gammas(&scene, Warping::LARGE_MOTION, false, regularizer)?;
            let default = best_of_gammas(&scene, Warping::NONE, true, regularizer)?;
            let floor = minimizer_error(&scene, warped.gamma, regularizer)?;
            let check = default.check.expect("the default checks its linearization");
            println!(
                "{rotation:>10} {:>12.2}° (γ {:.0e}) {:>12.2}° (γ {:.0e}) {floor:>9.2}° {:>9.1}× {:>9.2}° ({:.2}, {})",
                single.error,
                single.gamma,
                warped.error,
                warped.gamma,
                warped.seconds / single.seconds,
                default.error,
                check.linearization_error,
                if check.warped { "warped" } else { "linear" },
            );
        }
    }
    Ok(())
}

/// The best of the γs: its mean angular error, γ, seconds and check of the linear model.
struct Best {
    error: f64,
    gamma: f64,
    seconds: f64,
    check: Option<MotionCheck>,
}

/// The least mean angular error over [`GAMMAS`] with `warping` (and, with `detect`, the check
/// that switches warping on by itself).
fn best_of_gammas(
    scene: &GroundTruth,
    warping: Warping,
    detect: bool,
    regularizer: Regularizer,
) -> Result<Best, meshflow::Error> {
    let mut best = Best {
        error: f64::INFINITY,
        gamma: 0.0,
        seconds: 0.0,
        check: None,
    };
    for gamma in GAMMAS {
        let params = FlowParams {
            warping,
            regularizer,
            gamma: Weight::Value(gamma),
            detect_large_motion: detect,
            ..FlowParams::default()
        };
        let start = Instant::now();
        let result = compute_flow(&scene.sequence, &params)?;
        let seconds = start.elapsed().as_secs_f64();
        let error = compare_result(&scene.sequence, &result, &scene.flow)?.mean_angular_degrees;
        if error < best.error {
            best = Best {
                error,
                gamma,
                seconds,
                check: result.motion_check,
            };
        }
    }
    Ok(best)
}

/// The mean angular error of the energy's minimizer near the truth at `gamma`: three warps on
/// the original images, starting from the true flow.
fn minimizer_error(
    scene: &GroundTruth,
    gamma: f64,
    regularizer: Regularizer,
) -> Result<f64, meshflow::Error> {
    const WARPS: usize = 3;
    let sequence = &scene.sequence;
    let params = FlowParams {
        gamma: Weight::Value(gamma),
        regularizer,
        ..FlowParams::default()
    };
    let images = |s: usize| (sequence.channels(s), sequence.channels(s + 1));
    let mut flow = scene.intrinsic_flow()?;
    let mut error = f64::NAN;
    for _ in 0..WARPS {
        let slabs = (0..sequence.n_slabs())
            .map(|s| warped_slab(sequence, s, images(s), &flow[s], &[1.0]))
            .collect::<Result<Vec<_>, _>>()?;
        let result = FlowProblem::from_slabs(sequence, &params, slabs)?.solve(&|_| {})?;
        error = compare_result(sequence, &result, &scene.flow)?.mean_angular_degrees;
        flow = result.intrinsic;
    }
    Ok(error)
}
