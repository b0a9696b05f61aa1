//! The spatial regularizers side by side (issue 15's comparison, the parts built so far):
//! the paper's covariant `|∇u|²` against the strain `|Sym ∇u|²` (with and without a small
//! speed penalty) and the embedded `|∇^{R³}u|²` of Kirisits, Lang & Scherzer, on a texture turning rigidly and on one shearing (the equator turning, the
//! poles still), with coarse-to-fine warping (`--large-motion`).
//!
//! `cargo run --release --example regularizers [-- LEVEL FRAMES]` (default: the 2562-vertex
//! icosphere, 6 frames). Mean angular error against the true flow, best γ of {1e-4, 1e-3,
//! 1e-2}, default temporal smoothing.

use meshflow::accuracy::compare_result;
use meshflow::flow::{compute_flow, FlowParams, Regularizer, Warping, Weight};
use meshflow::synth::{rotating_sphere, shearing_sphere, GroundTruth};

const GAMMAS: [f64; 3] = [1e-4, 1e-3, 1e-2];
const STRAIN: Regularizer = Regularizer::Strain { dirichlet: 0.0 };

fn main() -> Result<(), meshflow::Error> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("a number"))
        .collect();
    let (level, frames) = (
        args.first().copied().unwrap_or(4) as u32,
        args.get(1).copied().unwrap_or(6),
    );
    let models = [
        ("covariant", Regularizer::Covariant, 0.0),
        ("strain", STRAIN, 0.0),
        ("strain, β 1e-4", STRAIN, 1e-4),
        ("embedded (KLS)", Regularizer::Embedded, 0.0),
    ];
    println!(
        "level-{level} icosphere, {frames} frames, --large-motion; mean angular error (best γ)"
    );
    print!("{:>10} {:>10}", "scene", "rad/frame");
    models.iter().for_each(|(name, _, _)| print!(" {name:>22}"));
    println!();
    for (scene_name, scene) in [
        ("turning", rotating_sphere as fn(u32, usize, f64, f64) -> _),
        ("shearing", shearing_sphere),
    ] {
        for rotation in [0.05, 0.6] {
            let scene: GroundTruth = scene(level, frames, 1.0, rotation)?;
            print!("{scene_name:>10} {rotation:>10}");
            for (_, regularizer, beta) in models {
                let (error, gamma) = best_of_gammas(&scene, regularizer, beta)?;
                print!(" {:>13.2}° (γ {gamma:.0e})", error);
            }
            println!();
        }
    }
    Ok(())
}

/// The least mean angular error over [`GAMMAS`] with `--large-motion`, and its γ.
fn best_of_gammas(
    scene: &GroundTruth,
    regularizer: Regularizer,
    beta: f64,
) -> Result<(f64, f64), meshflow::Error> {
    let mut best = (f64::INFINITY, 0.0);
    for gamma in GAMMAS {
        let params = FlowParams {
            regularizer,
            warping: Warping::LARGE_MOTION,
            beta: Weight::Value(beta),
            gamma: Weight::Value(gamma),
            ..FlowParams::default()
        };
        let result = compute_flow(&scene.sequence, &params)?;
        let error = compare_result(&scene.sequence, &result, &scene.flow)?.mean_angular_degrees;
        if error < best.0 {
            best = (error, gamma);
        }
    }
    Ok(best)
}
