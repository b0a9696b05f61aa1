//! Anisotropic and robust smoothness (`--anisotropic`, `--robust-smoothness`, `--flow-driven`;
//! [`meshflow::flow::anisotropy`], [`meshflow::flow::robust`]) against the quadratic defaults,
//! on the scenes of issue 37:
//!
//! 1. **boundary**: a cap of the sphere turns while the rest stands still, and the cap is
//!    brighter ([`turning_cap_sphere`]): the motion boundary is an image edge. Endpoint error
//!    within 4 mean edge lengths of the boundary, relative to the cap's speed there, and the
//!    relative endpoint error over the whole sphere; at the cap's edge `z = 0.3` (default) and
//!    at the equator (`-- LEVEL FRAMES 0`);
//! 2. **stop**: the same cap at the cap's edge turns for the first half of the frames, then
//!    stands still: a motion boundary in time. Endpoint error on the cap in the two slabs
//!    around the stop, relative to the cap's mean speed;
//! 3. **smooth**: a rich texture turning rigidly ([`rotating_sphere`]): relative endpoint error;
//! 4. **sample**: the shipped `meshes/rotating_sphere` against its `ground_truth.npy`: median
//!    speed ratio and mean angular error.
//!
//! The models: Weickert & Schnörr's taxonomy as meshflow has it (homogeneous = the defaults,
//! image-driven anisotropic, flow-driven isotropic and anisotropic, image- and flow-driven; the
//! image-driven ones also with the space-time tensor's weight in time), each with its `auto`
//! scales, and the robust data term (`--robust-data auto`) alone, with robust smoothness, and
//! with both and warping, and the combined local-global data term (`--local-integration`,
//! two mean edge lengths) alone and with the robust data term; then (with `SWEEP=1`) `λ` and
//! `ε` swept. It draws the boundary
//! scene's flow under the defaults and under `--anisotropic auto --robust-smoothness auto`
//! (arrows on the image, and the endpoint error over the cap's speed) into
//! `out/motion_boundaries/`.
//!
//! `cargo run --release --example motion_boundaries [-- LEVEL FRAMES Z_EDGE]` (default: the
//! 2562-vertex icosphere, 6 frames, 0.3).

use meshflow::accuracy::compare_result;
use meshflow::flow::{
    compute_flow, Anisotropy, FlowDriven, FlowParams, FlowResult, Images, MeshSequence, Scale,
};
use meshflow::render::{arrow_picture, scalar_picture, write_png};
use meshflow::render::{Camera, PictureStyle, Surface, View};
use meshflow::synth::{rotating_sphere, turning_cap_sphere, GroundTruth};
use nalgebra::Vector3;
use std::path::Path;

/// How fast the cap turns (radians per frame).
const OMEGA: f64 = 0.05;
const MULTIPLES: [f64; 4] = [0.5, 1.0, 2.0, 4.0];
/// Robust scales `ε` (1/time) of the sweep.
const EPSILONS: [f64; 3] = [0.01, 0.03, 0.1];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let number = |k: usize, default: f64| -> Result<f64, String> {
        args.get(k).map_or(Ok(default), |a| {
            a.parse().map_err(|_| format!("'{a}' is not a number"))
        })
    };
    let (level, frames, z_edge) = (
        number(0, 4.0)? as u32,
        number(1, 6.0)? as usize,
        number(2, 0.3)?,
    );
    let boundary = turning_cap_sphere(level, frames, 1.0, OMEGA, z_edge)?;
    let smooth = rotating_sphere(level, frames, 1.0, OMEGA)?;
    let stop = Stop::new(level, frames)?;
    let sample = shipped_sample()?;
    println!(
        "level-{level} icosphere, {frames} frames, ω = {OMEGA} rad/frame, cap edge z = {z_edge}"
    );
    println!(
        "{:<34} {:>15} {:>14} {:>11} {:>12} {:>14} {:>11} {:>8}",
        "model",
        "boundary: near",
        "boundary: all",
        "stop: cap",
        "smooth: all",
        "sample: speed",
        "sample: AE",
        "solves"
    );
    let band = Band::new(&boundary, z_edge);
    for (name, params) in models(&boundary.sequence) {
        let result = compute_flow(&boundary.sequence, &params)?;
        let (near, all) = band.errors(&boundary, &result)?;
        let stop_error = stop.error(&params)?;
        let smooth_error = compare_flow(&smooth, &params)?.relative_endpoint;
        let on_sample = compare_flow(&sample, &params)?;
        println!(
            "{name:<34} {:>14.1}% {:>13.1}% {:>10.1}% {:>11.1}% {:>14.3} {:>10.2}° {:>8}",
            100.0 * near,
            100.0 * all,
            100.0 * stop_error,
            100.0 * smooth_error,
            on_sample.median_speed_ratio,
            on_sample.mean_angular_degrees,
            1 + result.reweightings,
        );
    }
    draw(&boundary, &band, Path::new("out/motion_boundaries"))?;
    Ok(())
}

/// The taxonomy with `auto` scales, then the sweeps (with `SWEEP` set).
fn models(sequence: &MeshSequence) -> Vec<(String, FlowParams)> {
    let with = |anisotropy: Option<Scale>, robust: Option<Scale>, driven| FlowParams {
        anisotropy: anisotropy.map(Anisotropy::with),
        robust_smoothness: robust,
        flow_driven: driven,
        ..FlowParams::default()
    };
    let in_time = |anisotropy: Scale, robust: Option<Scale>| FlowParams {
        anisotropy: Some(Anisotropy {
            in_time: true,
            ..Anisotropy::with(anisotropy)
        }),
        robust_smoothness: robust,
        ..FlowParams::default()
    };
    let (auto, iso, aniso) = (
        Some(Scale::Auto),
        FlowDriven::Isotropic,
        FlowDriven::Anisotropic,
    );
    let mut models = vec![
        ("defaults (homogeneous)".to_string(), FlowParams::default()),
        (
            "image-driven: --anisotropic auto".into(),
            with(auto, None, iso),
        ),
        (
            "flow-driven iso.: --robust auto".into(),
            with(None, auto, iso),
        ),
        (
            "flow-driven aniso.: + --flow-d. a.".into(),
            with(None, auto, aniso),
        ),
        (
            "image+flow iso.: --aniso. + --robust".into(),
            with(auto, auto, iso),
        ),
        ("image+flow aniso.".into(), with(auto, auto, aniso)),
        (
            "image-driven, in time too".into(),
            in_time(Scale::Auto, None),
        ),
        (
            "image+flow iso., in time too".into(),
            in_time(Scale::Auto, auto),
        ),
        (
            "robust 0.01 (the issue's)".into(),
            with(None, Some(Scale::Value(0.01)), iso),
        ),
        (
            "robust data: --robust-data auto".into(),
            FlowParams {
                robust_data: auto,
                ..FlowParams::default()
            },
        ),
        (
            "robust data + robust smoothness".into(),
            FlowParams {
                robust_data: auto,
                ..with(None, auto, iso)
            },
        ),
        (
            "robust data + robust, --large-motion".into(),
            FlowParams {
                robust_data: auto,
                warping: meshflow::flow::Warping::LARGE_MOTION,
                ..with(None, auto, iso)
            },
        ),
    ];
    // The combined local-global data term over two mean edge lengths.
    let rho = 2.0
        * meshflow::geometry::mean_edge_length_at(
            sequence.mesh(),
            sequence.positions(0).expect("embedded"),
        );
    models.push((
        "CLG: --local-integration 2h̄".into(),
        FlowParams {
            local_integration: Some(rho),
            ..FlowParams::default()
        },
    ));
    models.push((
        "CLG + robust data".into(),
        FlowParams {
            local_integration: Some(rho),
            robust_data: auto,
            ..FlowParams::default()
        },
    ));
    if std::env::var_os("SWEEP").is_none() {
        return models;
    }
    let scale = median_edge_gradient(sequence);
    for m in MULTIPLES {
        let lambda = Some(Scale::Value(m * scale));
        models.push((format!("λ = {m} × {scale:.3}"), with(lambda, None, iso)));
    }
    for epsilon in EPSILONS {
        let epsilon = Some(Scale::Value(epsilon));
        models.push((
            format!("auto + robust {epsilon:?}"),
            with(auto, epsilon, iso),
        ));
        models.push((
            format!("auto + flow-aniso. {epsilon:?}"),
            with(auto, epsilon, aniso),
        ));
    }
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

/// The cap of [`turning_cap_sphere`] (edge at `z = 0.3`) turning for the first half of the
/// frames, then standing still.
struct Stop {
    scene: GroundTruth,
    /// The first slab in which the cap stands still.
    stop: usize,
    cap: Vec<usize>,
    speed: f64,
}

impl Stop {
    fn new(level: u32, frames: usize) -> Result<Self, meshflow::Error> {
        let moving = turning_cap_sphere(level, frames, 1.0, OMEGA, 0.3)?;
        let stop = frames / 2;
        let sequence = &moving.sequence;
        let images = (0..frames).map(|k| sequence.channels(k.min(stop)).to_vec());
        let positions = (0..frames).map(|k| sequence.positions(k).expect("embedded").to_vec());
        let stopped = MeshSequence::with_images(
            sequence.mesh().clone(),
            positions.collect(),
            Images::from_channels(images.collect()),
            Some(sequence.times().to_vec()),
        )?;
        let still = vec![Vector3::zeros(); sequence.mesh().n_vertices()];
        let flow = (0..frames - 1)
            .map(|s| match s < stop {
                true => moving.flow[s].clone(),
                false => still.clone(),
            })
            .collect();
        let on_cap = sequence.positions(0).expect("embedded").iter();
        let cap: Vec<usize> = (on_cap.enumerate())
            .filter_map(|(i, p)| (p.z > 0.3).then_some(i))
            .collect();
        let speed = cap.iter().map(|&i| moving.flow[0][i].norm()).sum::<f64>() / cap.len() as f64;
        Ok(Self {
            scene: GroundTruth {
                sequence: stopped,
                flow,
            },
            stop,
            cap,
            speed,
        })
    }

    /// The mean endpoint error on the cap in slabs `stop − 1` and `stop`, over the cap's mean
    /// speed.
    fn error(&self, params: &FlowParams) -> Result<f64, meshflow::Error> {
        let result = compute_flow(&self.scene.sequence, params)?;
        let errors = compare_result(&self.scene.sequence, &result, &self.scene.flow)?;
        let around = &errors.endpoint[self.stop - 1..=self.stop];
        let total: f64 = (around.iter())
            .flat_map(|slab| self.cap.iter().map(|&i| slab[i]))
            .sum();
        Ok(total / (2 * self.cap.len()) as f64 / self.speed)
    }
}

/// The vertices within 4 mean edge lengths of the cap's edge, and the cap's speed there.
struct Band {
    near: Vec<usize>,
    z_edge: f64,
    speed: f64,
}

impl Band {
    fn new(scene: &GroundTruth, z_edge: f64) -> Self {
        let positions = scene.sequence.positions(0).expect("embedded");
        let band = 4.0 * mean_edge_length(&scene.sequence);
        let near = (0..positions.len())
            .filter(|&i| (positions[i].z.asin() - z_edge.asin()).abs() <= band)
            .collect();
        Self {
            near,
            z_edge,
            speed: OMEGA * (1.0 - z_edge * z_edge).sqrt(),
        }
    }

    /// The mean endpoint error in the band relative to the speed, and the relative endpoint
    /// error over the sphere.
    fn errors(
        &self,
        scene: &GroundTruth,
        result: &FlowResult,
    ) -> Result<(f64, f64), meshflow::Error> {
        let errors = compare_result(&scene.sequence, result, &scene.flow)?;
        let total: f64 = (errors.endpoint.iter())
            .flat_map(|slab| self.near.iter().map(|&i| slab[i]))
            .sum();
        let mean = total / (self.near.len() * errors.endpoint.len()) as f64;
        Ok((mean / self.speed, errors.relative_endpoint))
    }
}

/// Arrows of slab 0's flow on the image, and its endpoint error over the cap's speed, under the
/// defaults and under the recommendation, seen from above the cap's edge.
fn draw(scene: &GroundTruth, band: &Band, out: &Path) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out)?;
    let sequence = &scene.sequence;
    let positions = sequence.positions(0).expect("embedded");
    let surface = Surface {
        positions,
        faces: sequence.mesh().faces(),
    };
    let camera = Camera::framing(
        positions,
        View::new(-60.0, 20.0 + band.z_edge.asin().to_degrees()),
        640,
        560,
    );
    let recommended = FlowParams {
        anisotropy: Some(Anisotropy::with(Scale::Auto)),
        robust_smoothness: Some(Scale::Auto),
        ..FlowParams::default()
    };
    for (name, params) in [
        ("defaults", FlowParams::default()),
        ("anisotropic", recommended),
    ] {
        let result = compute_flow(sequence, &params)?;
        let vectors = &result.vectors.as_ref().expect("embedded")[0];
        let errors = compare_result(sequence, &result, &scene.flow)?;
        let relative: Vec<f64> = errors.endpoint[0].iter().map(|e| e / band.speed).collect();
        let style = |label: String| PictureStyle {
            label: Some(label),
            arrow_spacing: 18.0,
            ..PictureStyle::default()
        };
        let arrows = arrow_picture(
            &camera,
            surface,
            sequence.intensities(0),
            (0.0, 1.1),
            vectors,
            band.speed,
            &style(format!("{name}: flow")),
        )?;
        write_png(&out.join(format!("{name}_arrows.png")), &arrows)?;
        let error = scalar_picture(
            &camera,
            surface,
            &relative,
            (0.0, 1.0),
            &style(format!("{name}: endpoint error / speed")),
        )?;
        write_png(&out.join(format!("{name}_error.png")), &error)?;
    }
    println!(
        "pictures: {}/{{defaults,anisotropic}}_{{arrows,error}}.png",
        out.display()
    );
    Ok(())
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
    let loaded = meshflow::load::load_sequence(&dir, &meshflow::load::LoadOptions::default())?;
    let slabs = loaded.sequence.n_slabs();
    let file = dir.join("ground_truth.npy");
    let flow: Vec<Vec<Vector3<f64>>> =
        meshflow::load::read_ground_truth(&file, &loaded.vertex_map, slabs)?;
    Ok(GroundTruth {
        sequence: loaded.sequence,
        flow,
    })
}
