//! Surfaces found in volumes (`meshflow::surface::find_surface`, `meshflow surface --shape
//! closed`): closed manifolds in the middle of a bright layer, or on a solid object's boundary,
//! whatever the noise; the largest object only; one-line refusals of images with no object.

mod common;

use common::{meshflow_error, meshflow_ok};
use meshflow::surface::{find_surface, isosurface::otsu, IsosurfaceOptions, Level};
use meshflow::track::simplified_reference;
use meshflow::volume::Volume;
use nalgebra::Vector3;
use std::path::Path;

const N: usize = 40;

/// `N³` unit voxels of `value` with noise ([`common::noisy_volume`]).
fn volume(value: impl Fn(Vector3<f64>) -> f64, noise: f64) -> Volume {
    common::noisy_volume(N, value, noise)
}

/// The ellipsoidal radius of `p` about the volume's centre, semi-axes (13, 11, 9).
fn radius(p: &Vector3<f64>) -> f64 {
    let c = (N - 1) as f64 / 2.0;
    let d = p - Vector3::repeat(c);
    ((d.x / 13.0).powi(2) + (d.y / 11.0).powi(2) + (d.z / 9.0).powi(2)).sqrt()
}

/// `V − E + F` of a triangle list (a valid mesh's).
fn euler_characteristic(n_vertices: usize, faces: &[[u32; 3]]) -> i64 {
    let mesh = meshflow::mesh::Mesh::new(n_vertices, faces.to_vec()).expect("a manifold mesh");
    mesh.euler_characteristic()
}

/// A bright layer (120) between ellipsoidal radii `inner` and 1 on a background of 20, with
/// noise of standard deviation `noise`.
fn shell(inner: f64, noise: f64) -> Volume {
    let layer = move |p: Vector3<f64>| match radius(&p) {
        r if (inner..1.0).contains(&r) => 120.0,
        _ => 20.0,
    };
    volume(layer, noise)
}

#[test]
fn a_noisy_shell_gives_a_closed_surface_in_the_middle_of_its_layer() {
    let shell = shell(0.8, 15.0);
    let found = find_surface(&shell, &IsosurfaceOptions::default()).unwrap();
    assert_eq!(euler_characteristic(found.vertices, &found.faces), 2);
    assert!(
        (30.0..110.0).contains(&found.threshold),
        "{}",
        found.threshold
    );
    assert_eq!(found.component_share, 1.0);
    assert!(
        found.filled_voxels > found.component_voxels / 2,
        "the hollow inside is filled"
    );
    assert!(found.layer_vertices >= found.vertices * 99 / 100);
    let inside: Vec<f64> = found.positions.iter().map(radius).collect();
    let within = inside.iter().filter(|r| (0.8..1.0).contains(*r)).count();
    assert!(
        within >= inside.len() * 98 / 100,
        "{within} of {}",
        inside.len()
    );
    let mean = inside.iter().sum::<f64>() / inside.len() as f64;
    assert!((mean - 0.9).abs() < 0.03, "mean radius {mean}");
}

/// Faces of `positions` whose normal points towards the volume's centre: folds, where the
/// surface turned back on itself.
fn inward_faces(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> usize {
    let centre = Vector3::repeat((N - 1) as f64 / 2.0);
    (faces.iter())
        .filter(|f| {
            let [a, b, c] = f.map(|v| positions[v as usize]);
            (b - a).cross(&(c - a)).dot(&((a + b + c) / 3.0 - centre)) < 0.0
        })
        .count()
}

/// Moving each vertex to the layer's middle by its own depth folds the surface where
/// neighbours' depths differ; Taubin smoothing unfolds it: a noisy shell's surface faces
/// outward everywhere. Without it 3 of 5040 faces turn inward on the first shell here, and on
/// the large recording's first frame (`examples/large_recording`) 3078 of 679,444, where the
/// reference simplified from them pinched at every size near 8000 vertices.
#[test]
fn the_surface_in_a_noisy_layer_has_no_folds() {
    for (inner, noise) in [(0.8, 15.0), (0.85, 30.0), (0.7, 40.0)] {
        let found = find_surface(&shell(inner, noise), &IsosurfaceOptions::default()).unwrap();
        let inward = inward_faces(&found.positions, &found.faces);
        assert_eq!(
            inward,
            0,
            "layer {inner}–1, noise {noise}: {inward} of {} faces",
            found.faces.len()
        );
    }
}

/// A coarser reference made from a thin, noisy shell's surface is a closed manifold too, within
/// 10 % of the size asked. (The pinch that `simplified_reference` retries shows on
/// `examples/closed_shell 48 4` at 4000 of 4914 vertices, not on this scene.)
#[test]
fn a_thin_shell_simplifies_to_a_closed_manifold() {
    let shell = shell(0.88, 25.0);
    let found = find_surface(&shell, &IsosurfaceOptions::default()).unwrap();
    for percent in [95, 90, 85, 80, 70, 60, 40] {
        let asked = found.vertices * percent / 100;
        let reference = simplified_reference(&found.positions, &found.faces, asked);
        let n = reference.positions.len();
        let mesh = meshflow::mesh::Mesh::new(n, reference.faces.clone());
        assert!(mesh.is_ok(), "{percent} %: {:?}", mesh.err());
        assert_eq!(euler_characteristic(n, &reference.faces), 2, "{percent} %");
        assert!(
            n.abs_diff(asked) * 10 <= asked,
            "{percent} %: {n} vertices for {asked}"
        );
    }
}

#[test]
fn a_solid_object_keeps_its_boundary_and_small_objects_are_dropped() {
    let ball = volume(
        |p| {
            let blob = (p - Vector3::new(3.0, 3.0, 3.0)).norm() < 2.0;
            match radius(&p) < 1.0 || blob {
                true => 1.0,
                false => 0.0,
            }
        },
        0.0,
    );
    let options = IsosurfaceOptions {
        smoothing: Some(1.0),
        level: Level::Value(0.5),
        ..IsosurfaceOptions::default()
    };
    let found = find_surface(&ball, &options).unwrap();
    assert_eq!(euler_characteristic(found.vertices, &found.faces), 2);
    assert_eq!(found.layer_vertices, 0, "bright throughout: no layer");
    assert!(found.component_share < 1.0 && found.component_share > 0.95);
    let worst = (found.positions.iter())
        .map(|p| (radius(p) - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.05, "off the boundary by {worst} (radius units)");
    // Outward: the enclosed volume is positive and near the ellipsoid's.
    let enclosed: f64 = (found.faces.iter())
        .map(|f| {
            let [a, b, c] = f.map(|v| found.positions[v as usize]);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum();
    let ellipsoid = 4.0 / 3.0 * std::f64::consts::PI * 13.0 * 11.0 * 9.0;
    assert!(
        (enclosed / ellipsoid - 1.0).abs() < 0.05,
        "{enclosed} vs {ellipsoid}"
    );
}

#[test]
fn images_without_an_object_are_refused_in_one_line() {
    let flat = volume(|_| 3.0, 0.0);
    let error = find_surface(&flat, &IsosurfaceOptions::default()).unwrap_err();
    assert_eq!(
        error.to_string(),
        "the image is constant (3): there is no object to bound"
    );
    let ball = volume(|p| if radius(&p) < 1.0 { 1.0 } else { 0.0 }, 0.0);
    let above = IsosurfaceOptions {
        level: Level::Value(5.0),
        ..IsosurfaceOptions::default()
    };
    let error = find_surface(&ball, &above).unwrap_err().to_string();
    assert!(
        error.starts_with("no voxel is above the threshold 5"),
        "{error}"
    );
    assert!(error.contains("give --level below"), "{error}");
}

#[test]
fn otsu_separates_two_classes() {
    let values: Vec<f32> = (0..1000)
        .map(|i| if i % 4 == 0 { 200.0 } else { 10.0 })
        .collect();
    let t = otsu(&values, 10.0, 200.0);
    assert!(t > 10.0 && t < 200.0, "{t}");
    let noisy: Vec<f32> = (0..4000)
        .map(|i| match i % 2 {
            0 => 50.0 + (i % 7) as f32,
            _ => 150.0 + (i % 11) as f32,
        })
        .collect();
    let t = otsu(&noisy, 50.0, 160.0);
    assert!((56.0..150.0).contains(&t), "{t}");
}

#[test]
fn the_command_tracks_the_frames_surfaces_into_one_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let frames: Vec<Volume> = (0..3)
        .map(|k| {
            let shift = Vector3::new(0.7 * k as f64, 0.0, 0.0);
            volume(
                |p| {
                    if radius(&(p - shift)) < 1.0 {
                        100.0
                    } else {
                        0.0
                    }
                },
                10.0,
            )
        })
        .collect();
    let values: Vec<f64> = (frames.iter())
        .flat_map(|v| v.values().iter().map(|&x| f64::from(x)))
        .collect();
    let file = dir.path().join("stack.npy");
    meshflow::format::write_npy(&file, &[3, N as u64, N as u64, N as u64], &values).unwrap();
    let out = dir.path().join("surface");
    let (file, out) = (file.to_str().unwrap(), out.to_str().unwrap());
    let args = [
        "surface",
        file,
        "--shape",
        "closed",
        "--out",
        out,
        "--vertices",
        "600",
        "--voxel-size",
        "0.5,0.5,0.5",
    ];
    let stdout = String::from_utf8_lossy(&meshflow_ok(&args).stdout).into_owned();
    assert!(stdout.contains("frame   2: threshold"), "{stdout}");
    assert!(
        stdout.contains("solid: the surface is its boundary"),
        "{stdout}"
    );
    let positions = meshflow::format::read_npy(&Path::new(out).join("positions.npy")).unwrap();
    assert_eq!(positions.shape[0], 3);
    let n = positions.shape[1] as usize;
    assert!((400..900).contains(&n), "{n} vertices");
    // The object moves 0.7 voxels (0.35 units) a frame along x: so does the mesh's centroid.
    let centroid_x = |k: usize| {
        let frame = &positions.data[k * 3 * n..(k + 1) * 3 * n];
        frame.chunks(3).map(|p| p[0]).sum::<f64>() / n as f64
    };
    let step = centroid_x(2) - centroid_x(0);
    assert!((step - 0.7).abs() < 0.03, "centroid moved {step}");
    let report = std::fs::read_to_string(Path::new(out).join("surface.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(report["shape"], "closed");
    assert_eq!(report["frames"].as_array().unwrap().len(), 3);
    assert!(report["frames"][0]["threshold"].as_f64().unwrap() > 0.0);

    let two_times = [
        "surface", file, "--shape", "closed", "--out", out, "--times", "0,1", "--force",
    ];
    meshflow_error(&two_times, "--times gives 2 times for the 3 frames of");
    let spline = [
        "surface",
        file,
        "--shape",
        "closed",
        "--out",
        out,
        "--edge-length",
        "2",
    ];
    meshflow_error(&spline, "--edge-length applies to surfaces through points");
}

/// What still makes a surface but looks wrong is a warning naming why: an object cut by the
/// volume's border (it leaves the field of view), and one split in two (the largest part holds
/// half of the foreground). A whole object inside has none.
#[test]
fn an_object_at_the_border_or_split_is_warned_about() {
    let ball = |c: Vector3<f64>, r: f64| move |p: Vector3<f64>| (p - c).norm() < r;
    let inside = volume(
        |p| {
            if ball(Vector3::repeat(19.5), 10.0)(p) {
                120.0
            } else {
                20.0
            }
        },
        5.0,
    );
    let found = find_surface(&inside, &IsosurfaceOptions::default()).unwrap();
    assert_eq!(found.border_voxels, 0);
    assert!(found.warnings().is_empty(), "{:?}", found.warnings());
    let cut = volume(
        |p| {
            if ball(Vector3::new(3.0, 19.5, 19.5), 10.0)(p) {
                120.0
            } else {
                20.0
            }
        },
        5.0,
    );
    let found = find_surface(&cut, &IsosurfaceOptions::default()).unwrap();
    assert!(found.border_voxels > 100, "{}", found.border_voxels);
    let warnings = found.warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("touches the volume's border"),
        "{warnings:?}"
    );
    let two = volume(
        |p| {
            let apart = ball(Vector3::new(10.0, 19.5, 19.5), 6.0)(p)
                || ball(Vector3::new(29.0, 19.5, 19.5), 6.0)(p);
            if apart {
                120.0
            } else {
                20.0
            }
        },
        5.0,
    );
    let found = find_surface(&two, &IsosurfaceOptions::default()).unwrap();
    assert!(
        (found.component_share - 0.5).abs() < 0.05,
        "{}",
        found.component_share
    );
    let warnings = found.warnings();
    assert!(
        warnings.iter().any(|w| w.contains("holds only")),
        "{warnings:?}"
    );
}
