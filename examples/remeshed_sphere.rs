//! Surfaces without correspondence: a pulsating sphere with a turning texture, every frame
//! meshed differently (icosphere, latitude–longitude sphere, rotated finer icosphere), tracked
//! (`meshflow::track`: normal steps and relaxation) and solved, against the same scene on one fixed mesh.
//! Prints the mean angular error against the true flow `ω ẑ × x` for both, the tracking
//! report, and the time to track a surface of more than 100k triangles through 20 frames by
//! normal motion alone and with the relaxation.
//!
//! Draws the first three level-3 frames as given and as tracked, each vertex a random grey so
//! that the triangulations show (`out/remeshed_sphere/meshes.png`, the guide's figure), and writes the level-4 frames as OBJ files with grey vertex colours into
//! `out/remeshed_sphere/frames/`, to try the command line on:
//! `meshflow track out/remeshed_sphere/frames --out out/remeshed_sphere/tracked` then
//! `meshflow solve out/remeshed_sphere/tracked --out out/remeshed_sphere/flow`.
//!
//! `cargo run --release --example remeshed_sphere`

use meshflow::accuracy::compare_result;
use meshflow::flow::{compute_flow, FlowParams};
use meshflow::format::write_obj;
use meshflow::render::{mosaic_picture, write_png, Camera, Surface, View};
use meshflow::shapes::uv_sphere;
use meshflow::synth::{remeshed_pulsating_sphere, turning_flow, RemeshedScene};
use meshflow::track::{track, Relaxation, TrackOptions};
use std::path::Path;
use std::time::Instant;

const FRAMES: usize = 5;
const DT: f64 = 0.1;
const OMEGA: f64 = 0.5;

fn main() -> Result<(), meshflow::Error> {
    println!("pulsating sphere, texture turning at ω = {OMEGA}, {FRAMES} frames, Δt = {DT}, default weights");
    println!(
        "{:>5} {:>8} {:>14} {:>14} {:>9} {:>10} {:>12}",
        "level", "vertices", "fixed AE°", "tracked AE°", "misses", "max step", "edge change"
    );
    for level in [3, 4, 5] {
        let scene = remeshed_pulsating_sphere(level, FRAMES, DT, OMEGA)?;
        let (fixed, tracked, report) = errors(&scene)?;
        println!(
            "{level:>5} {:>8} {fixed:>14.3} {tracked:>14.3} {:>9} {:>10.2e} {:>11.1}%",
            scene.fixed.sequence.mesh().n_vertices(),
            report.frames.iter().map(|f| f.misses).sum::<usize>(),
            report.frames.iter().map(|f| f.max_step).fold(0.0, f64::max),
            100.0
                * report
                    .frames
                    .iter()
                    .map(|f| f.worst_edge_change)
                    .fold(0.0, f64::max),
        );
        match level {
            3 => draw_meshes(&scene, Path::new("out/remeshed_sphere"))?,
            4 => write_frames(&scene, Path::new("out/remeshed_sphere/frames"))?,
            _ => {}
        }
    }
    time_large_tracking()
}

/// Mean angular errors of the fixed-connectivity and the tracked flow, and the track report.
fn errors(
    scene: &RemeshedScene,
) -> Result<(f64, f64, meshflow::track::TrackReport), meshflow::Error> {
    let params = FlowParams::default();
    let fixed = compute_flow(&scene.fixed.sequence, &params)?;
    let fixed = compare_result(&scene.fixed.sequence, &fixed, &scene.fixed.flow)?;
    let tracked = track(
        &scene.frames,
        Some(scene.times.clone()),
        &TrackOptions::default(),
    )?;
    let sequence = &tracked.sequence;
    let truth: Vec<_> = (0..sequence.n_slabs())
        .map(|s| turning_flow(scene.omega, sequence.positions(s).expect("embedded")))
        .collect();
    let result = compute_flow(sequence, &params)?;
    let errors = compare_result(sequence, &result, &truth)?;
    Ok((
        fixed.mean_angular_degrees,
        errors.mean_angular_degrees,
        tracked.report,
    ))
}

fn write_frames(scene: &RemeshedScene, dir: &Path) -> Result<(), meshflow::Error> {
    std::fs::create_dir_all(dir).map_err(|e| meshflow::format::IoError::file(dir, e))?;
    for (k, frame) in scene.frames.iter().enumerate() {
        let grey: Vec<[f64; 3]> = frame.intensity.iter().map(|&g| [g; 3]).collect();
        let path = dir.join(format!("frame_{k:02}.obj"));
        write_obj(&path, &frame.positions, &frame.faces, Some(&grey))?;
    }
    let times: Vec<String> = scene.times.iter().map(f64::to_string).collect();
    std::fs::write(dir.join("times.txt"), times.join("\n") + "\n")
        .map_err(|e| meshflow::format::IoError::file(dir, e))?;
    Ok(())
}

/// Frames 0–2 as given and as tracked, every vertex a pseudo-random grey.
fn draw_meshes(scene: &RemeshedScene, dir: &Path) -> Result<(), meshflow::Error> {
    std::fs::create_dir_all(dir).map_err(|e| meshflow::format::IoError::file(dir, e))?;
    let tracked = track(
        &scene.frames,
        Some(scene.times.clone()),
        &TrackOptions::default(),
    )?;
    let faces = tracked.sequence.mesh().faces();
    let mut sheet = image::RgbImage::new(3 * 480, 2 * 480);
    for k in 0..3 {
        let given = &scene.frames[k];
        let moved = tracked.sequence.positions(k).expect("embedded");
        let camera = Camera::framing(&given.positions, View::new(-60.0, 30.0), 480, 480);
        for (row, (name, positions, faces)) in [
            ("input", &given.positions[..], &given.faces[..]),
            ("tracked", moved, faces),
        ]
        .into_iter()
        .enumerate()
        {
            let label = format!("{name} {k}: {} faces", faces.len());
            let picture = mosaic_picture(&camera, Surface { positions, faces }, label)?;
            image::imageops::replace(&mut sheet, &picture, 480 * k as i64, 480 * row as i64);
        }
    }
    write_png(&dir.join("meshes.png"), &sheet)?;
    Ok(())
}

/// A 105,340-triangle reference tracked through 20 frames of 82k–328k triangles, by normal
/// motion alone and with the default relaxation.
fn time_large_tracking() -> Result<(), meshflow::Error> {
    let scene = remeshed_pulsating_sphere(6, 20, DT, OMEGA)?;
    let reference = uv_sphere(230, 230);
    for relaxation in [Relaxation::None, Relaxation::default()] {
        let options = TrackOptions {
            reference: Some(reference.clone()),
            relaxation,
            ..Default::default()
        };
        let start = Instant::now();
        let tracked = track(&scene.frames, Some(scene.times.clone()), &options)?;
        let seconds = start.elapsed().as_secs_f64();
        let relaxed = (tracked.report.frames.iter())
            .map(|f| f.mean_relaxation)
            .fold(0.0, f64::max);
        println!(
            "tracking {} triangles through {} frames ({relaxation:?}): {seconds:.2} s on {} \
             threads; largest mean relaxation per frame {relaxed:.2e}",
            reference.faces.len(),
            tracked.sequence.n_frames(),
            rayon::current_num_threads()
        );
    }
    Ok(())
}
