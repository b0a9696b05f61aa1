//! Regenerates the small meshes shipped in `meshes/` (OBJ meshes, the rotating-sphere sequence
//! as OBJ frames with its true flow `ground_truth.npy`, and as a glTF animation):
//! `cargo run --release --example sample_meshes`.

use meshflow::format::gltf::{write_glb_animation, AnimationFrame};
use meshflow::format::{write_npy, write_obj};
use meshflow::shapes::{grid, icosphere, torus};
use meshflow::synth::rotating_sphere;
use std::path::Path;

fn main() -> Result<(), meshflow::Error> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    let samples = [
        ("icosphere.obj", icosphere(3)),
        ("torus.obj", torus(2.0, 0.8, 32, 16)),
        ("patch.obj", grid(12, 8, 1.5, 1.0)),
    ];
    for (name, surface) in samples {
        write_obj(&dir.join(name), &surface.positions, &surface.faces, None)?;
        println!(
            "{name}: {} vertices, {} faces",
            surface.positions.len(),
            surface.faces.len()
        );
    }
    // A texture turning by 0.05 rad per frame about the z-axis of the unit sphere (642 vertices),
    // grey values as vertex colours r = g = b.
    let truth = rotating_sphere(3, 6, 1.0, 0.05)?;
    let sequence_dir = dir.join("rotating_sphere");
    std::fs::create_dir_all(&sequence_dir).map_err(|e| meshflow::format::IoError::File {
        path: sequence_dir.clone(),
        source: e,
    })?;
    let sequence = &truth.sequence;
    for k in 0..sequence.n_frames() {
        let grey: Vec<[f64; 3]> = sequence.intensities(k).iter().map(|&g| [g; 3]).collect();
        let positions = sequence.positions(k).expect("embedded");
        write_obj(
            &sequence_dir.join(format!("frame_{k}.obj")),
            positions,
            sequence.mesh().faces(),
            Some(&grey),
        )?;
    }
    // The true flow ω ẑ × x of every slab, (slabs, vertices, 3) float64, for `--ground-truth`.
    let flow: Vec<f64> = truth
        .flow
        .iter()
        .flatten()
        .flat_map(|u| [u.x, u.y, u.z])
        .collect();
    let shape = [
        truth.flow.len() as u64,
        sequence.mesh().n_vertices() as u64,
        3,
    ];
    write_npy(&sequence_dir.join("ground_truth.npy"), &shape, &flow)?;
    println!(
        "rotating_sphere/: {} frames, ground_truth.npy {shape:?}",
        sequence.n_frames()
    );

    // The same sequence as one glTF morph animation (float32), grey values as COLOR_0.
    let colors: Vec<Vec<[f64; 3]>> = (0..sequence.n_frames())
        .map(|k| sequence.intensities(k).iter().map(|&g| [g; 3]).collect())
        .collect();
    let frames: Vec<AnimationFrame> = (0..sequence.n_frames())
        .map(|k| AnimationFrame {
            time: sequence.times()[k],
            positions: sequence.positions(k).expect("embedded"),
            colors: &colors[k],
        })
        .collect();
    write_glb_animation(
        &dir.join("rotating_sphere.glb"),
        sequence.mesh().faces(),
        &frames,
    )?;
    println!("rotating_sphere.glb: {} keyframes", frames.len());
    Ok(())
}
