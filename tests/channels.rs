//! Colour and multi-channel images: the data term sums over channels; and the combined
//! local-global data term, which averages the channels' motion tensors over the surface.

mod common;

use meshflow::accuracy::compare_result;
use meshflow::fem::vertex_areas;
use meshflow::flow::{
    compute_flow, FlowError, FlowParams, FlowProblem, FlowResult, Images, MeshSequence, Warping,
};
use meshflow::flow::{local::averaging_steps, Weight};
use meshflow::io::{grey_value, load_sequence, write_npy, Channels, LoadOptions};
use meshflow::shapes::grid;
use meshflow::synth::{isoluminant, rotating_sphere, rotating_sphere_in_channels, GroundTruth};
use nalgebra::Vector3;

/// `sequence` with its image replaced by `channels(k)` per frame.
fn with_channels(
    sequence: &MeshSequence,
    channels: impl Fn(usize) -> Vec<Vec<f64>>,
) -> MeshSequence {
    let frames = 0..sequence.n_frames();
    let positions = frames
        .clone()
        .map(|k| sequence.positions(k).unwrap().to_vec())
        .collect();
    let images = Images::from_channels(frames.map(channels).collect());
    let times = Some(sequence.times().to_vec());
    MeshSequence::with_images(sequence.mesh().clone(), positions, images, times).unwrap()
}

fn max_difference(a: &FlowResult, b: &FlowResult) -> f64 {
    let scale = a
        .intrinsic
        .iter()
        .flatten()
        .map(|u| u.norm())
        .fold(0.0, f64::max);
    let difference = (a.intrinsic.iter().flatten())
        .zip(b.intrinsic.iter().flatten())
        .map(|(u, v)| (u - v).norm())
        .fold(0.0, f64::max);
    difference / scale
}

/// Three copies of a grey image: data term and gradient scale three times the grey ones', so
/// with relative weights the flow is the grey flow, with warping too.
#[test]
fn three_equal_channels_are_the_grey_image_three_times() {
    let scene = rotating_sphere(3, 4, 1.0, 0.1).unwrap();
    let grey = &scene.sequence;
    let colour = with_channels(grey, |k| vec![grey.intensities(k).to_vec(); 3]);
    assert_eq!(colour.n_channels(), 3);

    let params = FlowParams::default();
    let (one, three) = (
        FlowProblem::new(grey, &params).unwrap(),
        FlowProblem::new(&colour, &params).unwrap(),
    );
    let ratio = three.scales().gradient / one.scales().gradient;
    assert!(
        (ratio - 3f64.sqrt()).abs() < 1e-12,
        "gradient scale ratio {ratio}"
    );
    let u: Vec<f64> = (scene.intrinsic_flow().unwrap().iter().flatten())
        .flat_map(|v| [v.x + 0.01, v.y - 0.02])
        .collect();
    let (e1, e3) = (one.energy_terms(&u), three.energy_terms(&u));
    assert!(
        (e3.data - 3.0 * e1.data).abs() < 1e-12 * e1.data,
        "{} vs {}",
        e3.data,
        e1.data
    );
    assert!((e3.spatial - 3.0 * e1.spatial).abs() < 1e-12 * e1.spatial);

    for params in [
        FlowParams::default(),
        FlowParams {
            warping: Warping::LARGE_MOTION,
            ..FlowParams::default()
        },
    ] {
        let (a, b) = (
            compute_flow(grey, &params).unwrap(),
            compute_flow(&colour, &params).unwrap(),
        );
        let difference = max_difference(&a, &b);
        assert!(difference < 1e-9, "{:?}: {difference:e}", params.warping);
    }
}

/// A channel of weight 0 does not count; one weighted channel gives the grey flow whatever its
/// weight (relative weights follow the data term).
#[test]
fn channel_weights_choose_what_counts() {
    let scene = rotating_sphere(3, 3, 1.0, 0.1).unwrap();
    let grey = &scene.sequence;
    let noise = |k: usize, c: usize| -> Vec<f64> {
        (0..grey.mesh().n_vertices())
            .map(|i| ((i * 7919 + k * 104_729 + c * 13) % 1000) as f64 / 1000.0)
            .collect()
    };
    let mixed = with_channels(grey, |k| {
        vec![noise(k, 0), grey.intensities(k).to_vec(), noise(k, 2)]
    });
    let reference = compute_flow(grey, &FlowParams::default()).unwrap();
    for weight in [1.0, 4.0] {
        let params = FlowParams {
            channel_weights: Some(vec![0.0, weight, 0.0]),
            ..FlowParams::default()
        };
        let result = compute_flow(&mixed, &params).unwrap();
        assert!(max_difference(&reference, &result) < 1e-9);
    }
    let unweighted = compute_flow(&mixed, &FlowParams::default()).unwrap();
    assert!(
        max_difference(&reference, &unweighted) > 0.1,
        "the noise channels count"
    );

    let wrong_count = FlowParams {
        channel_weights: Some(vec![1.0, 1.0]),
        ..FlowParams::default()
    };
    assert!(matches!(
        compute_flow(&mixed, &wrong_count).unwrap_err(),
        FlowError::CountMismatch {
            expected: 3,
            got: 2,
            ..
        }
    ));
    for bad in [
        vec![1.0, -1.0, 0.0],
        vec![0.0, 0.0, 0.0],
        vec![f64::NAN, 1.0, 1.0],
    ] {
        let params = FlowParams {
            channel_weights: Some(bad.clone()),
            ..FlowParams::default()
        };
        let error = compute_flow(&mixed, &params).unwrap_err();
        assert!(
            error.to_string().contains("channel_weights"),
            "{bad:?}: {error}"
        );
    }
}

/// A texture whose hue turns while its luma is constant: grey (luma) sees no image at all, the
/// three colour channels see the rotation.
#[test]
fn colour_sees_an_isoluminant_texture_that_grey_cannot() {
    let scene: GroundTruth = rotating_sphere_in_channels(isoluminant, 3, 4, 1.0, 0.05).unwrap();
    let colour = &scene.sequence;
    assert_eq!(colour.n_channels(), 3);
    let luma = |k: usize| -> Vec<f64> {
        let c = colour.channels(k);
        (0..c[0].len())
            .map(|i| grey_value([c[0][i], c[1][i], c[2][i]]))
            .collect()
    };
    assert!((0..colour.n_frames()).all(|k| luma(k).iter().all(|l| (l - 0.5).abs() < 1e-12)));
    let grey = with_channels(colour, |k| vec![luma(k)]);
    assert_eq!(
        compute_flow(&grey, &FlowParams::default()).unwrap_err(),
        FlowError::NoImageGradient
    );
    let result = compute_flow(colour, &FlowParams::default()).unwrap();
    let error = compare_result(colour, &result, &scene.flow).unwrap();
    println!("isoluminant, colour: {:.2}°", error.mean_angular_degrees);
    assert!(
        error.mean_angular_degrees < 3.0,
        "{}",
        error.mean_angular_degrees
    );
}

/// A non-finite value names its frame, vertex and channel; frames must agree on channels.
#[test]
fn bad_channels_are_named() {
    let scene = rotating_sphere(2, 3, 1.0, 0.1).unwrap();
    let grey = &scene.sequence;
    let frames = 0..grey.n_frames();
    let positions: Vec<Vec<Vector3<f64>>> = frames
        .clone()
        .map(|k| grey.positions(k).unwrap().to_vec())
        .collect();
    let mut channels: Vec<Vec<Vec<f64>>> = frames
        .map(|k| vec![grey.intensities(k).to_vec(); 2])
        .collect();
    channels[2][1][5] = f64::INFINITY;
    let build = |channels: Vec<Vec<Vec<f64>>>| {
        let mesh = grey.mesh().clone();
        MeshSequence::with_images(
            mesh,
            positions.clone(),
            Images::from_channels(channels),
            None,
        )
    };
    let error = build(channels.clone()).unwrap_err().to_string();
    assert_eq!(
        error,
        "frame 2: intensity at vertex 5, channel 1 is inf, not a finite number"
    );
    channels[2][1][5] = 0.0;
    channels[1].pop();
    let error = build(channels).unwrap_err().to_string();
    assert_eq!(error, "frame 1 has 1 image channels, frame 0 has 2");
}

/// `--intensity` with a channel axis, and what `--channels` makes of it and of colours.
#[test]
fn channel_arrays_and_the_channels_option() {
    let dir = tempfile::tempdir().unwrap();
    let sample = shipped_frames(dir.path());
    let loaded = load_sequence(&sample, &LoadOptions::default()).unwrap();
    let (k, v) = (
        loaded.sequence.n_frames(),
        loaded.vertex_map.n_file_vertices(),
    );
    // Shipped frames are grey (r = g = b): one channel under `auto`.
    assert_eq!(loaded.sequence.n_channels(), 1);

    let values: Vec<f64> = (0..k * v * 5).map(|i| (i % 17) as f64 / 17.0).collect();
    let five = dir.path().join("five.npy");
    write_npy(&five, &[k as u64, v as u64, 5], &values).unwrap();
    let load = |file: &std::path::Path, channels: Channels| {
        let options = LoadOptions {
            intensity: Some(file.to_path_buf()),
            channels,
            ..LoadOptions::default()
        };
        load_sequence(&sample, &options)
    };
    let all = load(&five, Channels::Auto).unwrap().sequence;
    assert_eq!(all.n_channels(), 5);
    assert!(
        loaded.vertex_map.is_identity(),
        "each value below is one file vertex's"
    );
    let file_vertex = |i: usize| loaded.vertex_map.representative(i);
    let i = 3;
    for c in 0..5 {
        let expected = values[(2 * v + file_vertex(i)) * 5 + c];
        assert_eq!(all.channels(2)[c][i], expected);
    }
    let mean = load(&five, Channels::Grey).unwrap().sequence;
    assert_eq!(mean.n_channels(), 1);
    let expected: f64 = (0..5).map(|c| all.channels(2)[c][i]).sum::<f64>() / 5.0;
    assert!((mean.intensities(2)[i] - expected).abs() < 1e-15);
    for refused in [Channels::Rgb, Channels::Luma] {
        let error = error_of(load(&five, refused));
        assert!(
            error.contains("five.npy") && error.contains("needs 3 colour channels"),
            "{error}"
        );
    }

    let three = dir.path().join("three.npy");
    let rgb: Vec<f64> = (0..k * v * 3).map(|i| (i % 11) as f64 / 11.0).collect();
    write_npy(&three, &[k as u64, v as u64, 3], &rgb).unwrap();
    let luma = load(&three, Channels::Luma).unwrap().sequence;
    let at = |c: usize| rgb[(2 * v + file_vertex(i)) * 3 + c];
    let expected = grey_value([at(0), at(1), at(2)]);
    assert!((luma.intensities(2)[i] - expected).abs() < 1e-15);

    // Grey values only: rgb is refused, naming the file.
    let grey = dir.path().join("grey.npy");
    write_npy(&grey, &[k as u64, v as u64], &rgb[..k * v]).unwrap();
    let error = error_of(load(&grey, Channels::Rgb));
    assert!(
        error.contains("--channels rgb needs colours") && error.contains("grey.npy"),
        "{error}"
    );
    // Colours that are all grey: `rgb` makes three equal channels of them.
    let rgb_of_grey = load_sequence(
        &sample,
        &LoadOptions {
            channels: Channels::Rgb,
            ..LoadOptions::default()
        },
    )
    .unwrap()
    .sequence;
    assert_eq!(rgb_of_grey.n_channels(), 3);
    assert_eq!(rgb_of_grey.channels(1)[2], loaded.sequence.intensities(1));
}

/// The error's message (without printing a large `Ok` value when there is none).
fn error_of<T>(result: Result<T, meshflow::Error>) -> String {
    match result {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

/// A copy of the shipped sphere's frames in `dir`.
fn shipped_frames(dir: &std::path::Path) -> std::path::PathBuf {
    let target = dir.join("frames");
    std::fs::create_dir_all(&target).unwrap();
    let source = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rotating_sphere");
    for entry in std::fs::read_dir(source).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, target.join(path.file_name().unwrap())).unwrap();
    }
    target
}

/// Arrays from a caller whose channels differ in length are refused, naming the frame.
#[test]
fn ragged_channel_arrays_are_refused() {
    use meshflow::io::{sequence_from_arrays, VertexValues};
    let scene = rotating_sphere(1, 2, 1.0, 0.1).unwrap();
    let sequence = &scene.sequence;
    let positions: Vec<Vec<Vector3<f64>>> = (0..2)
        .map(|k| sequence.positions(k).unwrap().to_vec())
        .collect();
    let grey = |k: usize| sequence.intensities(k).to_vec();
    let mut short = grey(1);
    short.pop();
    let images = vec![
        VertexValues::Channels(vec![grey(0), grey(0)]),
        VertexValues::Channels(vec![grey(1), short]),
    ];
    let faces = sequence.mesh().faces().to_vec();
    let result = sequence_from_arrays(faces, positions, images, None, &LoadOptions::default());
    let v = sequence.mesh().n_vertices();
    let error = error_of(result);
    assert!(
        error.contains(&format!(
            "frame 1 has {} grey values for {v} vertices",
            v - 1
        )),
        "{error}"
    );
}

/// Two linear channels translating by `v` on a flat jittered patch: every vertex's motion
/// tensor says `v` exactly (`J_ut = −J_uu v`, two independent gradients), so the combined
/// local-global term keeps the exact flow at every `ρ` only if the averaging turns the
/// tensors between the (different) vertex frames correctly.
#[test]
fn local_integration_keeps_an_exact_translation_on_a_jittered_patch() {
    let surface = common::jittered_grid(12, 10, 1.2, 1.0, 0.03);
    let v = Vector3::new(0.03, -0.02, 0.0);
    let (a, b) = (Vector3::new(1.0, 0.3, 0.0), Vector3::new(-0.4, 1.0, 0.0));
    let image = |k: usize| {
        let moved = |p: &Vector3<f64>| p - v * k as f64;
        vec![
            surface.positions.iter().map(|p| a.dot(&moved(p))).collect(),
            surface
                .positions
                .iter()
                .map(|p| 2.0 + b.dot(&moved(p)))
                .collect(),
        ]
    };
    let images = Images::from_channels((0..2).map(image).collect());
    let positions = vec![surface.positions.clone(); 2];
    let mesh = surface.mesh().unwrap();
    let sequence = MeshSequence::with_images(mesh, positions, images, None).unwrap();
    for rho in [0.0, 0.1, 0.25] {
        let params = FlowParams {
            local_integration: Some(rho),
            ..FlowParams::default()
        };
        let result = compute_flow(&sequence, &params).unwrap();
        let vectors = result.vectors.as_ref().unwrap();
        let error = vectors[0]
            .iter()
            .map(|u| (u - v).norm())
            .fold(0.0, f64::max);
        assert!(error < 1e-10, "ρ = {rho}: max error {error:e}");
    }
}

/// The averaging moves a vertex's rate to a Gaussian of the stated width and loses none of it:
/// one vertex flashes on a still, flat, uniform patch (its motion tensor is `(0, 0, τ²)` there
/// and zero elsewhere); after `3ρ²/h̄²` steps the lumped total `Σ m_a J_tt,a` is unchanged and
/// the second moment about the vertex is `2ρ²` (exact on an equilateral mesh; this grid of
/// right triangles spreads 3 % faster per step, module `flow::local`).
#[test]
fn local_integration_spreads_a_flash_to_its_gaussian_width() {
    let surface = grid(40, 40, 40.0, 40.0);
    let centre = surface
        .positions
        .iter()
        .position(|p| (p - Vector3::new(20.0, 20.0, 0.0)).norm() < 1e-9)
        .unwrap();
    let image = |k: usize| {
        let mut values = vec![1.0; surface.positions.len()];
        values[centre] += k as f64;
        values
    };
    let positions = vec![surface.positions.clone(); 2];
    let sequence = MeshSequence::new(
        surface.mesh().unwrap(),
        positions,
        (0..2).map(image).collect(),
        None,
    )
    .unwrap();
    let rho = 3.0;
    let params = FlowParams {
        local_integration: Some(rho),
        beta: Weight::Value(1.0),
        ..FlowParams::default()
    };
    let problem = FlowProblem::new(&sequence, &params).unwrap();
    let slab = &problem.slabs()[0];
    let tensors = slab.local_motion.as_ref().unwrap();
    let masses = vertex_areas(sequence.mesh(), &slab.geometry);
    let total: f64 = tensors.iter().zip(&masses).map(|(j, m)| m * j.time).sum();
    assert!(
        (total - masses[centre]).abs() < 1e-12,
        "{total} vs {}",
        masses[centre]
    );
    let moment: f64 = (tensors.iter().zip(&masses).zip(&surface.positions))
        .map(|((j, m), p)| m * j.time * (p - surface.positions[centre]).norm_squared())
        .sum::<f64>()
        / total;
    let h = slab.geometry.mean_edge_length();
    assert_eq!(averaging_steps(rho, h), 21);
    let relative = moment / (2.0 * rho * rho) - 1.0;
    assert!(
        (0.0..0.05).contains(&relative),
        "second moment {moment} against 2ρ² = {}",
        2.0 * rho * rho
    );
}
