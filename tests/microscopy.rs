//! From a recording to a scored flow, on a synthetic confocal recording whose truth is known:
//! Gaussian "cells" on a sphere turning about its axis, imaged in anisotropic voxels. The
//! library's pipeline (surface through the cells → volumes sampled onto it → flow → scores
//! at the cells) finds the turning, the CLI's `surface`, `sample`, `match` and `solve
//! --ground-truth-tracks` give the same numbers, and bad input stops each command with one
//! line and no output.

mod common;

use common::{meshflow, meshflow_ok, write_npy};
use meshflow::accuracy::{score_result, Tracks};
use meshflow::flow::{compute_flow, FlowParams, MeshSequence};
use meshflow::mesh::Mesh;
use meshflow::surface::{fit_surface, FitOptions, Resolution};
use meshflow::volume::{sample_sequence, SampleOptions, Volume};
use nalgebra::{Rotation3, Vector3};
use std::path::Path;

const VOXEL: [f64; 3] = [1.0, 1.0, 2.0];
/// `(z, y, x)` voxels: 60 × 80 × 80 µm.
const SHAPE: [usize; 3] = [31, 81, 81];
const CENTRE: Vector3<f64> = Vector3::new(40.0, 40.0, 20.0);
const RADIUS: f64 = 30.0;
/// Radians per frame about the z-axis through the centre: up to 1.4 µm per frame.
const OMEGA: f64 = 0.05;
const FRAMES: usize = 3;
const CELLS: usize = 60;
/// The cells' Gaussian radius (µm).
const CELL_SIGMA: f64 = 2.5;

/// The cells' centres at frame `k`: a Fibonacci lattice over the cap within 70° of +z, turned
/// by `k ω` (row `n` is the same cell in every frame).
fn cells(k: usize) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), OMEGA * k as f64);
    let lowest = 70f64.to_radians().cos();
    (0..CELLS)
        .map(|n| {
            let z = 1.0 - (1.0 - lowest) * (n as f64 + 0.5) / CELLS as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * n as f64;
            CENTRE + turn * Vector3::new(r * phi.cos(), r * phi.sin(), z) * RADIUS
        })
        .collect()
}

/// The library's pipeline on the recording: the surface fitted through the cells of `frames`,
/// every frame's volume sampled onto it with the defaults (frames at times 0, 1, 2, …); with
/// the vertices outside the volumes per frame and the smoothing used.
fn library_pipeline(frames: &[Vec<Vector3<f64>>]) -> (MeshSequence, Vec<usize>, f64) {
    let fitted = fit_surface(frames, &fit_options()).unwrap();
    let volumes: Vec<Volume> = (0..FRAMES)
        .map(|k| {
            let values = recording(k).into_iter().map(|v| v as f32).collect();
            Volume::new(SHAPE, values, VOXEL.into(), Vector3::zeros()).unwrap()
        })
        .collect();
    let mesh = Mesh::new(fitted.positions[0].len(), fitted.faces.clone()).unwrap();
    let options = SampleOptions::default();
    let sampled = sample_sequence(&volumes, &mesh, &fitted.positions, &options).unwrap();
    let sequence = MeshSequence::new(mesh, fitted.positions, sampled.values, None).unwrap();
    (sequence, sampled.outside, sampled.smoothing)
}

/// Frame `k`'s volume: the cells as Gaussians, in voxels of [`VOXEL`].
fn recording(k: usize) -> Vec<f64> {
    let centres = cells(k);
    let mut values = Vec::with_capacity(SHAPE.iter().product());
    for z in 0..SHAPE[0] {
        for y in 0..SHAPE[1] {
            for x in 0..SHAPE[2] {
                let p =
                    Vector3::new(x as f64, y as f64, z as f64).component_mul(&Vector3::from(VOXEL));
                let value: f64 = (centres.iter())
                    .map(|c: &Vector3<f64>| {
                        (-(p - c).norm_squared() / (2.0 * CELL_SIGMA * CELL_SIGMA)).exp()
                    })
                    .sum();
                values.push(value);
            }
        }
    }
    values
}

fn tracks() -> Tracks {
    Tracks::new((0..FRAMES).map(cells).collect()).unwrap()
}

fn fit_options() -> FitOptions {
    FitOptions {
        resolution: Resolution::Vertices(4000),
        ..FitOptions::default()
    }
}

#[test]
fn the_pipeline_finds_the_turning_of_cells_on_a_sphere() {
    let frames: Vec<Vec<Vector3<f64>>> = (0..FRAMES).map(cells).collect();
    let (sequence, outside, smoothing) = library_pipeline(&frames);
    assert_eq!(outside, vec![0; FRAMES]);
    assert_eq!(smoothing, 2.0);
    let flow = compute_flow(&sequence, &FlowParams::default()).unwrap();
    let scores = score_result(&sequence, &flow, &tracks()).unwrap();
    let s = &scores.overall;
    assert_eq!(s.points, CELLS * (FRAMES - 1));
    // The cells lie on the surface up to the chords of its facets (measured 0.006 µm).
    assert!(s.median_distance < 0.02, "{s:?}");
    // Measured: EPE 0.085 of the zero flow's, 1.8°, speed ratio 0.93.
    assert!(s.endpoint_ratio() < 0.15, "{s:?}");
    assert!(s.median_direction_degrees < 4.0, "{s:?}");
    assert!((0.85..1.05).contains(&s.median_speed_ratio), "{s:?}");
}

fn write_points(path: &Path, frames: &[Vec<Vector3<f64>>]) {
    let values: Vec<f64> = frames
        .iter()
        .flatten()
        .flat_map(|p| p.iter().copied())
        .collect();
    let n = frames[0].len() as u64;
    match frames.len() {
        1 => write_npy(path, &[n, 3], &values),
        k => write_npy(path, &[k as u64, n, 3], &values),
    }
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn the_cli_pipeline_gives_the_library_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let (points, volumes) = (dir.path().join("cells.npy"), dir.path().join("volumes.npy"));
    let (surface, run) = (dir.path().join("surface"), dir.path().join("run"));
    let frames: Vec<Vec<Vector3<f64>>> = (0..FRAMES).map(cells).collect();
    write_points(&points, &frames);
    let recorded: Vec<f64> = (0..FRAMES).flat_map(recording).collect();
    let mut shape = vec![FRAMES as u64];
    shape.extend(SHAPE.map(|n| n as u64));
    write_npy(&volumes, &shape, &recorded);

    meshflow_ok(&[
        "surface",
        path(&points),
        "--out",
        path(&surface),
        "--vertices",
        "4000",
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(surface.join("surface.json")).unwrap())
            .unwrap();
    assert!((report["reference"]["Sphere"]["radius"].as_f64().unwrap() - RADIUS).abs() < 1e-9);
    let sampled = meshflow_ok(&[
        "sample",
        path(&volumes),
        path(&surface),
        "--voxel-size",
        "1,1,2",
    ]);
    let said = String::from_utf8_lossy(&sampled.stdout);
    assert!(said.contains("σ = 2"), "{said}");
    assert!(surface.join("intensity.npy").exists());
    meshflow_ok(&[
        "solve",
        path(&surface),
        "--out",
        path(&run),
        "--format",
        "npy",
        "--ground-truth-tracks",
        path(&points),
    ]);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    let cli = &summary["ground_truth_tracks"];

    // The library on the same input.
    let (sequence, _, _) = library_pipeline(&frames);
    let flow = compute_flow(&sequence, &FlowParams::default()).unwrap();
    let library = score_result(&sequence, &flow, &tracks()).unwrap().overall;
    assert_eq!(cli["points"].as_u64(), Some(library.points as u64));
    for (key, value) in [
        ("mean_endpoint", library.mean_endpoint),
        ("median_direction_degrees", library.median_direction_degrees),
        ("median_speed_ratio", library.median_speed_ratio),
    ] {
        let got = cli[key].as_f64().unwrap();
        assert!(
            (got - value).abs() < 1e-9 * value.abs().max(1.0),
            "{key}: {got} vs {value}"
        );
    }
}

#[test]
fn match_recovers_the_cells_from_shuffled_frames() {
    let dir = tempfile::tempdir().unwrap();
    let frames_dir = dir.path().join("cells");
    std::fs::create_dir(&frames_dir).unwrap();
    for k in 0..FRAMES {
        let mut shuffled = cells(k);
        shuffled.rotate_left(7 * k);
        write_points(&frames_dir.join(format!("frame_{k}.npy")), &[shuffled]);
    }
    let out = dir.path().join("tracks.npy");
    meshflow_ok(&["match", path(&frames_dir), "--out", path(&out)]);
    let matched = meshflow::surface::read_points(&out).unwrap();
    let truth: Vec<Vec<Vector3<f64>>> = (0..FRAMES).map(cells).collect();
    assert_eq!(matched, truth);
}

/// Runs a failing command: non-zero exit, one line naming `names`, and `absent` not written.
fn fails(args: &[&str], names: &[&str], absent: &Path) {
    let run = meshflow(args);
    assert!(!run.status.success(), "{args:?} succeeded");
    let stderr = String::from_utf8_lossy(&run.stderr);
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("meshflow: error"))
        .collect();
    assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
    for name in names {
        assert!(
            lines[0].contains(name),
            "{args:?}: {:?} does not name {name}",
            lines[0]
        );
    }
    assert!(!absent.exists(), "{args:?} wrote {}", absent.display());
}

#[test]
fn bad_input_stops_each_command_with_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("cells.npy");
    write_points(&points, &(0..2).map(cells).collect::<Vec<_>>());
    let surface = dir.path().join("surface");
    meshflow_ok(&[
        "surface",
        path(&points),
        "--out",
        path(&surface),
        "--vertices",
        "500",
    ]);
    let intensity = surface.join("intensity.npy");

    let flat = dir.path().join("flat.npy");
    let on_a_plane: Vec<Vector3<f64>> = cells(0)
        .iter()
        .map(|p| Vector3::new(p.x, p.y, 0.0))
        .collect();
    write_points(&flat, &[on_a_plane]);
    let nowhere = dir.path().join("nowhere");
    fails(
        &["surface", path(&flat), "--out", path(&nowhere)],
        &["flat.npy", "plane"],
        &nowhere,
    );
    fails(
        &[
            "surface",
            path(&points),
            "--out",
            path(&nowhere),
            "--smoothing",
            "-1",
        ],
        &["smoothing"],
        &nowhere,
    );

    let one_frame = dir.path().join("one.npy");
    write_npy(&one_frame, &[4, 5, 6], &[1.0; 120]);
    fails(
        &[
            "sample",
            path(&one_frame),
            path(&surface),
            "--voxel-size",
            "1,1,2",
        ],
        &["one.npy", "1 volume frames for 2 surface frames"],
        &intensity,
    );
    let two_frames = dir.path().join("two.npy");
    write_npy(&two_frames, &[2, 4, 5, 6], &[1.0; 240]);
    fails(
        &[
            "sample",
            path(&two_frames),
            path(&surface),
            "--voxel-size",
            "1,0,2",
        ],
        &["two.npy", "voxel size"],
        &intensity,
    );
    fails(
        &[
            "sample",
            path(&two_frames),
            path(&surface),
            "--voxel-size",
            "1,2",
        ],
        &["--voxel-size"],
        &intensity,
    );
    let flat_volume = dir.path().join("flat_volume.npy");
    write_npy(&flat_volume, &[4, 5], &[1.0; 20]);
    fails(
        &["sample", path(&flat_volume), path(&surface)],
        &["flat_volume.npy"],
        &intensity,
    );
    fails(
        &[
            "sample",
            path(&two_frames),
            path(&surface),
            "--reduce",
            "layer:9",
        ],
        &["layer 9"],
        &intensity,
    );

    let tracks = dir.path().join("tracks.npy");
    fails(
        &[
            "match",
            path(&points),
            "--out",
            path(&tracks),
            "--max-distance",
            "0",
        ],
        &["positive"],
        &tracks,
    );
}
