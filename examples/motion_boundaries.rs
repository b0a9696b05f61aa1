//! Image-driven anisotropic smoothness (`--anisotropic λ`, [`meshflow::flow::anisotropy`])
//! against the quadratic defaults and robust smoothness, on the scenes of issue 37:
//!
//! 1. **boundary**: a cap of the sphere turns while the rest stands still, and the cap is
//!    brighter ([`turning_cap_sphere`]): the motion boundary is an image edge. Endpoint error
//!    within 4 mean edge lengths of the boundary, relative to the cap's speed there, and the
//!    relative endpoint error over the whole sphere;
//! 2. **smooth**: a rich texture turning rigidly ([`rotating_sphere`]): relative endpoint error;
//! 3. **sample**: the shipped `meshes/rotating_sphere` against its `ground_truth.npy`: median
//!    speed ratio and mean angular error.
//!
//! λ is swept as multiples of the image's median edge gradient `|ΔI| / |Δx|` (frame 0).
//!
//! `cargo run --release --example motion_boundaries [-- LEVEL FRAMES]` (default: the
//! 2562-vertex icosphere, 6 frames).

use meshflow::accuracy::compare_result;
use meshflow::flow::{compute_flow, Anisotropy, Contrast, FlowDriven, FlowParams, MeshSequence};
use meshflow::synth::{rotating_sphere, turning_cap_sphere, GroundTruth};
use nalgebra::Vector3;

/// Where the cap's edge is, and how fast it turns (radians per frame).
const Z_EDGE: f64 = 0.3;
const OMEGA: f64 = 0.05;
const MULTIPLES: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];
/// Robust scales `ε` (1/time) of the flow-driven models.
const EPSILONS: [f64; 3] = [0.01, 0.03, 0.1];

fn main() -> Result<(), meshflow::Error> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("a number"))
        .collect();
    let level = args.first().copied().unwrap_or(4) as u32;
    let frames = args.get(1).copied().unwrap_or(6);
    let boundary = turning_cap_sphere(level, frames, 1.0, OMEGA, Z_EDGE)?;
    let smooth = rotating_sphere(level, frames, 1.0, OMEGA)?;
    let sample = shipped_sample()?;
    println!(
        "level-{level} icosphere, {frames} frames, ω = {OMEGA} rad/frame, cap edge z = {Z_EDGE}"
    );
    println!(
        "{:<26} {:>16} {:>16} {:>16} {:>14} {:>12}",
        "model", "boundary: near", "boundary: all", "smooth: all", "sample: speed", "sample: AE"
    );
    let models = models(&boundary.sequence);
    for (name, params) in &models {
        let (near, all) = boundary_errors(&boundary, params)?;
        let smooth_error = compare_flow(&smooth, params)?.relative_endpoint;
        let on_sample = compare_flow(&sample, params)?;
        println!(
            "{name:<26} {:>15.1}% {:>15.1}% {:>15.1}% {:>14.3} {:>11.2}°",
            100.0 * near,
            100.0 * all,
            100.0 * smooth_error,
            on_sample.median_speed_ratio,
            on_sample.mean_angular_degrees
        );
    }
    Ok(())
}

/// The defaults, robust smoothness, and the defaults with `--anisotropic λ` over the sweep.
fn models(sequence: &MeshSequence) -> Vec<(String, FlowParams)> {
    let scale = median_edge_gradient(sequence);
    let mut models = vec![
        ("defaults".to_string(), FlowParams::default()),
        (
            "robust 0.01".to_string(),
            FlowParams {
                robust_smoothness: Some(0.01),
                ..FlowParams::default()
            },
        ),
    ];
    models.push((
        "anisotropic auto".to_string(),
        FlowParams {
            anisotropy: Some(Anisotropy::with(Contrast::Auto)),
            ..FlowParams::default()
        },
    ));
    for epsilon in EPSILONS {
        let robust = |driven, anisotropy| FlowParams {
            robust_smoothness: Some(epsilon),
            flow_driven: driven,
            anisotropy,
            ..FlowParams::default()
        };
        let auto = Some(Anisotropy::with(Contrast::Auto));
        models.extend([
            (
                format!("flow-driven aniso. {epsilon}"),
                robust(FlowDriven::Anisotropic, None),
            ),
            (
                format!("auto + robust {epsilon}"),
                robust(FlowDriven::Isotropic, auto),
            ),
            (
                format!("auto + flow-aniso. {epsilon}"),
                robust(FlowDriven::Anisotropic, auto),
            ),
        ]);
    }
    if std::env::var_os("MOTION_BOUNDARIES_NO_SWEEP").is_some() {
        return models;
    }
    models.extend(MULTIPLES.iter().map(|&m| {
        let params = FlowParams {
            anisotropy: Some(Anisotropy::new(m * scale)),
            ..FlowParams::default()
        };
        (format!("anisotropic λ = {m} × {scale:.3}"), params)
    }));
    models
}

/// The median of `|I_i − I_j| / |x_i − x_j|` over the edges of frame 0.
fn median_edge_gradient(sequence: &MeshSequence) -> f64 {
    let positions = sequence.positions(0).expect("embedded");
    let image = sequence.intensities(0);
    let mut slopes: Vec<f64> = (sequence.mesh().faces().iter())
        .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
        .map(|(a, b)| {
            let (a, b) = (a as usize, b as usize);
            (image[a] - image[b]).abs() / (positions[a] - positions[b]).norm()
        })
        .collect();
    slopes.sort_by(f64::total_cmp);
    slopes[slopes.len() / 2]
}

fn compare_flow(
    scene: &GroundTruth,
    params: &FlowParams,
) -> Result<meshflow::accuracy::FlowErrors, meshflow::Error> {
    let result = compute_flow(&scene.sequence, params)?;
    Ok(compare_result(&scene.sequence, &result, &scene.flow)?)
}

/// The mean endpoint error within 4 mean edge lengths of the cap's edge relative to the cap's
/// speed there, and the relative endpoint error over the sphere.
fn boundary_errors(
    scene: &GroundTruth,
    params: &FlowParams,
) -> Result<(f64, f64), meshflow::Error> {
    let result = compute_flow(&scene.sequence, params)?;
    let errors = compare_result(&scene.sequence, &result, &scene.flow)?;
    let positions = scene.sequence.positions(0).expect("embedded");
    let band = 4.0 * mean_edge_length(&scene.sequence);
    let near: Vec<usize> = (0..positions.len())
        .filter(|&i| (positions[i].z.asin() - Z_EDGE.asin()).abs() <= band)
        .collect();
    let speed = OMEGA * (1.0 - Z_EDGE * Z_EDGE).sqrt();
    let total: f64 = (errors.endpoint.iter())
        .flat_map(|slab| near.iter().map(|&i| slab[i]))
        .sum();
    let mean = total / (near.len() * errors.endpoint.len()) as f64;
    Ok((mean / speed, errors.relative_endpoint))
}

fn mean_edge_length(sequence: &MeshSequence) -> f64 {
    let positions = sequence.positions(0).expect("embedded");
    let lengths: Vec<f64> = (sequence.mesh().faces().iter())
        .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
        .map(|(a, b)| (positions[a as usize] - positions[b as usize]).norm())
        .collect();
    lengths.iter().sum::<f64>() / lengths.len() as f64
}

/// `meshes/rotating_sphere` with its known flow.
fn shipped_sample() -> Result<GroundTruth, meshflow::Error> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rotating_sphere");
    let loaded = meshflow::io::load_sequence(&dir, &meshflow::io::LoadOptions::default())?;
    let slabs = loaded.sequence.n_slabs();
    let file = dir.join("ground_truth.npy");
    let flow: Vec<Vec<Vector3<f64>>> =
        meshflow::io::read_ground_truth(&file, &loaded.vertex_map, slabs)?;
    Ok(GroundTruth {
        sequence: loaded.sequence,
        flow,
    })
}
