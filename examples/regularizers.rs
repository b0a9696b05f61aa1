//! The model options side by side (issue 15's comparison), each with coarse-to-fine warping
//! (`--large-motion`) and the best γ of {1e-4, 1e-3, 1e-2}:
//!
//! 1. **regularizers**: the paper's covariant `|∇u|²` against the strain `|Sym ∇u|²` (with and
//!    without a small speed penalty) and the embedded `|∇^{R³}u|²` of Kirisits, Lang &
//!    Scherzer, on a texture turning rigidly and on one shearing (the equator turning, the
//!    poles still);
//! 2. **cells**: a cell crawling past still ones on a flat background
//!    ([`moving_cell_sphere`]), quadratic against robust (Charbonnier) smoothness: the mean
//!    angular error over the sphere (zero flow off the moving cell) and the drag, the mean speed
//!    at the still cells relative to the moving one's; and the image-driven anisotropic
//!    regularizer (`--anisotropic 0.5`), which smooths less across the cells' rims;
//! 3. **colour**: an isoluminant texture ([`isoluminant`]: the hue turns, the luma is constant)
//!    read as luma, as the mean of its channels, and as RGB.
//!
//! `cargo run --release --example regularizers [-- LEVEL FRAMES [SECTION]]` (default: the
//! 2562-vertex icosphere, 6 frames, every section; SECTION is 1, 2 or 3).

use meshflow::accuracy::compare_result;
use meshflow::flow::{
    compute_flow, Anisotropy, FlowParams, MeshSequence, Regularizer, Scale, Warping, Weight,
};
use meshflow::format::VertexValues;
use meshflow::load::{select_channels, Channels};
use meshflow::synth::{isoluminant, moving_cell_sphere, rotating_sphere};
use meshflow::synth::{rotating_sphere_in_channels, shearing_sphere, GroundTruth, STILL_CELLS};
use nalgebra::Vector3;

const GAMMAS: [f64; 3] = [1e-4, 1e-3, 1e-2];
/// One section of the comparison, on the icosphere of a level with a number of frames.
type Section = fn(u32, usize) -> Result<(), meshflow::Error>;
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
    let section = args.get(2).copied();
    println!("level-{level} icosphere, {frames} frames, --large-motion, best γ of {GAMMAS:?}");
    let sections: [Section; 3] = [regularizers, cells, colour];
    for (k, run) in sections.iter().enumerate() {
        if section.is_none_or(|s| s == k + 1) {
            run(level, frames)?;
        }
    }
    Ok(())
}

/// Section 1: mean angular error per regularizer.
fn regularizers(level: u32, frames: usize) -> Result<(), meshflow::Error> {
    let models = [
        ("covariant", Regularizer::Covariant, 0.0),
        ("strain", STRAIN, 0.0),
        ("strain, β 1e-4", STRAIN, 1e-4),
        ("embedded (KLS)", Regularizer::Embedded, 0.0),
    ];
    println!("\n1. regularizers: mean angular error");
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
                let params = FlowParams {
                    regularizer,
                    beta: Weight::Value(beta),
                    ..large_motion()
                };
                let (error, gamma) =
                    best_of_gammas(&params, |p| angular_error(&scene, &scene.sequence, p))?;
                print!(" {error:>13.2}° (γ {gamma:.0e})");
            }
            println!();
        }
    }
    Ok(())
}

/// Section 2: quadratic against robust smoothness on a cell crawling past still ones.
fn cells(level: u32, frames: usize) -> Result<(), meshflow::Error> {
    // (name, regularizer, robust, anisotropic λ)
    let models = [
        ("covariant", Regularizer::Covariant, false, None),
        ("covariant, robust", Regularizer::Covariant, true, None),
        (
            "covariant, anisotropic 0.5",
            Regularizer::Covariant,
            false,
            Some(0.5),
        ),
        (
            "cov., robust, anisotropic 0.5",
            Regularizer::Covariant,
            true,
            Some(0.5),
        ),
        ("strain", STRAIN, false, None),
        ("strain, robust", STRAIN, true, None),
        ("strain, anisotropic 0.5", STRAIN, false, Some(0.5)),
    ];
    println!("\n2. cells: mean angular error over the sphere, drag of the still cells");
    print!("{:>10}", "rad/frame");
    models.iter().for_each(|(name, ..)| print!(" {name:>30}"));
    println!();
    for rotation in [0.05, 0.3] {
        let scene = moving_cell_sphere(level, frames, 1.0, rotation)?;
        print!("{rotation:>10}");
        for (_, regularizer, robust, lambda) in models {
            let params = FlowParams {
                regularizer,
                anisotropy: lambda.map(Anisotropy::new),
                // ε well below the jump of |∇u| at the cell's rim (about ω / radius).
                robust_smoothness: robust.then_some(Scale::Value(0.2 * rotation)),
                beta: Weight::Value(1e-4),
                ..large_motion()
            };
            let (error, gamma, drag) = best_of_gammas_with(&params, |p| {
                let result = compute_flow(&scene.sequence, p)?;
                let error = compare_result(&scene.sequence, &result, &scene.flow)?;
                let drag = still_cell_drag(&scene, &result.vectors.expect("embedded"));
                Ok((error.mean_angular_degrees, drag / rotation))
            })?;
            print!(
                " {error:>6.2}°, drag {:>5.1}% (γ {gamma:.0e})",
                100.0 * drag
            );
        }
        println!();
    }
    Ok(())
}

/// Mean speed within one radius of the still cells' centres, over slabs.
fn still_cell_drag(scene: &GroundTruth, vectors: &[Vec<Vector3<f64>>]) -> f64 {
    let positions = scene.sequence.positions(0).expect("embedded");
    let near: Vec<usize> = (0..positions.len())
        .filter(|&i| {
            let centres = STILL_CELLS.map(Vector3::from);
            let radius = meshflow::synth::CELL_RADIUS;
            centres.iter().any(|c| (positions[i] - c).norm() < radius)
        })
        .collect();
    let total: f64 = (vectors.iter())
        .flat_map(|slab| near.iter().map(|&i| slab[i].norm()))
        .sum();
    total / (near.len() * vectors.len()) as f64
}

/// Section 3: an isoluminant texture as luma, as the channels' mean, as RGB.
fn colour(level: u32, frames: usize) -> Result<(), meshflow::Error> {
    let readings = [
        ("luma", Channels::Luma),
        ("grey (mean)", Channels::Grey),
        ("rgb", Channels::Rgb),
    ];
    println!("\n3. colour: an isoluminant texture turning, mean angular error");
    print!("{:>10}", "rad/frame");
    readings.iter().for_each(|(name, _)| print!(" {name:>22}"));
    println!();
    for rotation in [0.05, 0.6] {
        let scene = rotating_sphere_in_channels(isoluminant, level, frames, 1.0, rotation)?;
        print!("{rotation:>10}");
        for (_, reading) in readings {
            let sequence = reread(&scene.sequence, reading)?;
            match best_of_gammas(&large_motion(), |p| angular_error(&scene, &sequence, p)) {
                Ok((error, gamma)) => print!(" {error:>13.2}° (γ {gamma:.0e})"),
                Err(e) => print!(" {:>22}", short(&e)),
            }
        }
        println!();
    }
    Ok(())
}

/// `sequence` with its channels read as `--channels reading` reads them.
fn reread(sequence: &MeshSequence, reading: Channels) -> Result<MeshSequence, meshflow::Error> {
    let frames = 0..sequence.n_frames();
    let positions = (frames.clone())
        .map(|k| sequence.positions(k).expect("embedded").to_vec())
        .collect();
    let values = frames
        .map(|k| VertexValues::Channels(sequence.channels(k).to_vec()))
        .collect();
    let images = select_channels(values, reading).expect("three channels in every frame");
    let times = Some(sequence.times().to_vec());
    Ok(MeshSequence::with_images(
        sequence.mesh().clone(),
        positions,
        images,
        times,
    )?)
}

/// The first words of an error, for a table cell.
fn short(error: &meshflow::Error) -> String {
    let text = error.to_string();
    match text.contains("do not vary") {
        true => "no image gradient".to_string(),
        false => text.chars().take(22).collect(),
    }
}

fn large_motion() -> FlowParams {
    FlowParams {
        warping: Warping::LARGE_MOTION,
        ..FlowParams::default()
    }
}

fn angular_error(
    scene: &GroundTruth,
    sequence: &MeshSequence,
    params: &FlowParams,
) -> Result<f64, meshflow::Error> {
    let result = compute_flow(sequence, params)?;
    Ok(compare_result(sequence, &result, &scene.flow)?.mean_angular_degrees)
}

/// The least `error` over [`GAMMAS`] (`params` with each γ as a value) and its γ.
fn best_of_gammas(
    params: &FlowParams,
    mut error: impl FnMut(&FlowParams) -> Result<f64, meshflow::Error>,
) -> Result<(f64, f64), meshflow::Error> {
    best_of_gammas_with(params, |p| Ok((error(p)?, ()))).map(|(e, gamma, ())| (e, gamma))
}

/// [`best_of_gammas`] for an `error` that also measures something else: that of the best γ.
fn best_of_gammas_with<T>(
    params: &FlowParams,
    mut error: impl FnMut(&FlowParams) -> Result<(f64, T), meshflow::Error>,
) -> Result<(f64, f64, T), meshflow::Error> {
    let mut best = None;
    for gamma in GAMMAS {
        let params = FlowParams {
            gamma: Weight::Value(gamma),
            ..params.clone()
        };
        let (e, other) = error(&params)?;
        if best.as_ref().is_none_or(|(b, _, _)| e < *b) {
            best = Some((e, gamma, other));
        }
    }
    Ok(best.expect("GAMMAS is not empty"))
}
