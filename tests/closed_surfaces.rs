//! Closed surfaces from stacks as the field has them (issue 68): a layer with dim cells, a
//! layer of nuclei with dark gaps, voxels three times longer in z, a cavity cut open, an object
//! with a handle; and a turning patchy shell through `surface`, `sample` and `solve`, scored
//! against its material velocity.

mod common;

use common::{meshflow_error, meshflow_ok};
use meshflow::surface::{find_surface, FoundSurface, IsosurfaceOptions};
use meshflow::volume::Volume;
use nalgebra::{Rotation3, Vector3};
use std::path::Path;

const N: usize = 64;

/// The centre of the `N³` grid.
fn centre() -> Vector3<f64> {
    Vector3::repeat((N - 1) as f64 / 2.0)
}

/// The ellipsoidal radius of `d` (from the centre), semi-axes (23, 20, 17).
fn radius(d: &Vector3<f64>) -> f64 {
    ((d.x / 23.0).powi(2) + (d.y / 20.0).powi(2) + (d.z / 17.0).powi(2)).sqrt()
}

/// A volume of `shape` (z, y, x) and `voxel` size whose value at `x` (physical, with the grid's
/// centre at the physical centre of an `N³` unit grid) is `value`, with the deterministic
/// noise of [`common::noisy_volume`] of standard deviation `noise`.
fn sampled(
    shape: [usize; 3],
    voxel: Vector3<f64>,
    value: impl Fn(Vector3<f64>) -> f64,
    noise: f64,
) -> Volume {
    let [nz, ny, nx] = shape;
    let mut values = Vec::with_capacity(nz * ny * nx);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = Vector3::new(i as f64, j as f64, k as f64).component_mul(&voxel);
                let hash = ((i * 73_856_093) ^ (j * 19_349_663) ^ (k * 83_492_791)) % 1000;
                let uniform = hash as f64 / 1000.0 - 0.5;
                values.push((value(p) + noise * 12f64.sqrt() * uniform) as f32);
            }
        }
    }
    Volume::new(shape, values, voxel, Vector3::zeros()).unwrap()
}

/// A cell label of the layer at `d` (from the centre): cells are the cubes of side 8 of a
/// grid.
fn cell(d: &Vector3<f64>) -> u64 {
    let c = d.map(|x| (x / 8.0).floor() as i64 + 100);
    (c.x as u64 * 73_856_093) ^ (c.y as u64 * 19_349_663) ^ (c.z as u64 * 83_492_791)
}

/// A layer between ellipsoidal radii 0.75 and 1 (value 100 on 10) whose cells are dim (30)
/// one time in three, turned by `angle` about z.
fn patchy(d: Vector3<f64>, angle: f64) -> f64 {
    let material = Rotation3::from_axis_angle(&Vector3::z_axis(), -angle) * d;
    match radius(&material) {
        r if (0.75..1.0).contains(&r) && cell(&material).is_multiple_of(3) => 30.0,
        r if (0.75..1.0).contains(&r) => 100.0,
        _ => 10.0,
    }
}

/// Nuclei of radius 3.4 at 60 points spread evenly (a Fibonacci lattice) over the ellipsoid
/// of radius 0.87: a layer of nuclei with dark gaps of about two voxels between them.
fn nuclei(d: Vector3<f64>) -> f64 {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let bright = (0..60).any(|i| {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / 60.0;
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f64;
        let at = 0.87 * Vector3::new(23.0 * r * t.cos(), 20.0 * r * t.sin(), 17.0 * z);
        (d - at).norm() < 3.4
    });
    if bright {
        100.0
    } else {
        10.0
    }
}

/// The genus of a found surface, checked to be a closed manifold.
fn genus(found: &FoundSurface) -> i64 {
    let mesh = meshflow::mesh::Mesh::new(found.vertices, found.faces.clone()).unwrap();
    assert!(mesh.is_closed());
    (2 - mesh.euler_characteristic()) / 2
}

/// The share of the found vertices whose ellipsoidal radius lies in `range`.
fn share_within(found: &FoundSurface, range: std::ops::Range<f64>) -> f64 {
    let c = centre();
    let within = (found.positions.iter())
        .filter(|p| range.contains(&radius(&(*p - c))))
        .count();
    within as f64 / found.vertices as f64
}

#[test]
fn a_layer_with_dim_cells_gives_a_sphere_in_its_middle() {
    let volume = sampled(
        [N; 3],
        Vector3::repeat(1.0),
        |p| patchy(p - centre(), 0.0),
        3.0,
    );
    let found = find_surface(&volume, &IsosurfaceOptions::default()).unwrap();
    assert_eq!((genus(&found), found.genus), (0, 0));
    assert!(found.filled_voxels > 8_000, "the cavity is filled");
    let share = share_within(&found, 0.75..1.0);
    assert!(share > 0.95, "{share} of the vertices in the layer");
    assert!(found.layer_vertices > found.vertices / 2);
}

#[test]
fn a_layer_of_nuclei_is_closed_over_its_gaps() {
    let volume = sampled([N; 3], Vector3::repeat(1.0), |p| nuclei(p - centre()), 3.0);
    let found = find_surface(&volume, &IsosurfaceOptions::default()).unwrap();
    assert_eq!((genus(&found), found.genus), (0, 0));
    assert!(
        found.closing_radius > 0.0,
        "closed: {:?}",
        found.closings_tried
    );
    // The nuclei's centres lie at radius 0.87, their layer spans about 0.72–1.02.
    let share = share_within(&found, 0.7..1.02);
    assert!(
        share > 0.95,
        "{share} of the vertices in the layer of nuclei"
    );
    // Every radius tried before the one kept left handles, or an open, thin object.
    let kept = found.closings_tried.last().unwrap();
    assert_eq!((kept.radius, kept.genus), (found.closing_radius, 0));
}

#[test]
fn voxels_three_times_longer_in_z_give_the_same_sphere() {
    // The same 64³ box in voxels of 2/3 × 2/3 × 2.
    let voxel = Vector3::new(2.0 / 3.0, 2.0 / 3.0, 2.0);
    let shape = [N / 2, 3 * N / 2, 3 * N / 2];
    let volume = sampled(shape, voxel, |p| patchy(p - centre(), 0.0), 3.0);
    let found = find_surface(&volume, &IsosurfaceOptions::default()).unwrap();
    assert_eq!(genus(&found), 0);
    let share = share_within(&found, 0.7..1.05);
    assert!(
        share > 0.9,
        "{share} of the vertices in the patchy layer: {:?}, σ {}, layer {}",
        found.closings_tried,
        found.smoothing,
        found.layer_vertices
    );
}

#[test]
fn a_cavity_cut_open_is_filled_slice_by_slice() {
    // A shell 3 voxels thick whose cavity opens through the top (z above 11 from the centre)
    // by a hole wider than any closing: its slices ring the cavity.
    let cup = |p: Vector3<f64>| {
        let d = p - centre();
        match (radius(&d), d.z) {
            (r, z) if (0.8..1.0).contains(&r) && z < 11.0 => 100.0,
            _ => 10.0,
        }
    };
    let volume = sampled([N; 3], Vector3::repeat(1.0), cup, 3.0);
    let found = find_surface(&volume, &IsosurfaceOptions::default()).unwrap();
    assert_eq!(genus(&found), 0);
    assert!(found.slices_filled, "{:?}", found.closings_tried);
    assert!(found.filled_voxels > 10_000, "the open cavity is filled");
}

#[test]
fn a_ring_keeps_its_handle_when_asked_and_is_filled_otherwise() {
    // A torus: tube radius 6 around a circle of radius 17 in the z = 0 plane.
    let ring = |p: Vector3<f64>| {
        let d = p - centre();
        let around = (d.x.hypot(d.y) - 17.0).hypot(d.z);
        if around < 6.0 {
            100.0
        } else {
            10.0
        }
    };
    let volume = sampled([N; 3], Vector3::repeat(1.0), ring, 3.0);
    let handle = IsosurfaceOptions {
        genus: 1,
        ..IsosurfaceOptions::default()
    };
    let torus = find_surface(&volume, &handle).unwrap();
    assert_eq!(
        (genus(&torus), torus.genus, torus.closing_radius),
        (1, 1, 0.0)
    );
    let disc = find_surface(&volume, &IsosurfaceOptions::default()).unwrap();
    assert_eq!(genus(&disc), 0);
    assert!(disc.filled_voxels > 0 && disc.vertices != torus.vertices);
}

/// A patchy shell turning 0.06 rad a frame about z (1.4 voxels a frame at its equator): the
/// three commands with default options give one genus-0 mesh whose material velocity
/// (`velocity.npy`) is the turn's, tangentially, within a relative error of 0.25 and a median
/// speed ratio of 0.8–1.2.
#[test]
fn a_turning_patchy_shell_goes_through_surface_sample_and_solve() {
    let omega = 0.06;
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let frames = 4;
    let values: Vec<f64> = (0..frames)
        .flat_map(|k| {
            let volume = sampled(
                [N; 3],
                Vector3::repeat(1.0),
                |p| patchy(p - centre(), omega * k as f64),
                3.0,
            );
            volume
                .values()
                .iter()
                .map(|&x| f64::from(x))
                .collect::<Vec<_>>()
        })
        .collect();
    let stack = dir.join("stack.npy");
    let n = N as u64;
    meshflow::format::write_npy(&stack, &[frames as u64, n, n, n], &values).unwrap();
    let (surface, flow) = (dir.join("surface"), dir.join("flow"));
    let path = |p: &Path| p.to_str().unwrap().to_owned();
    let (stack, surface, flow) = (path(&stack), path(&surface), path(&flow));
    let stdout = meshflow_ok(&["surface", &stack, "--shape", "closed", "--out", &surface]).stdout;
    let stdout = String::from_utf8_lossy(&stdout).into_owned();
    assert!(stdout.contains("genus 0"), "{stdout}");
    meshflow_ok(&["sample", &stack, &surface]);
    meshflow_ok(&["solve", &surface, "--out", &flow]);

    let report = std::fs::read_to_string(Path::new(&surface).join("surface.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(report["genus"], 0);
    // A lone crease is a warning; a tangle would have been an error.
    for fold in report["folds"].as_array().unwrap() {
        assert!(fold["folded_edges"].as_u64().unwrap() <= 2, "{fold}");
    }
    let positions = meshflow::format::read_npy(&Path::new(&surface).join("positions.npy")).unwrap();
    let (_, faces) =
        meshflow::format::read_npy_indices(&Path::new(&surface).join("faces.npy")).unwrap();
    let velocity = meshflow::format::read_npy(&Path::new(&flow).join("velocity.npy")).unwrap();
    let vertices = positions.shape[1] as usize;
    let at = |data: &[f64], frame: usize, v: usize| {
        let o = (frame * vertices + v) * 3;
        Vector3::new(data[o], data[o + 1], data[o + 2])
    };
    let faces: Vec<[usize; 3]> = (faces.chunks(3))
        .map(|f| [f[0] as usize, f[1] as usize, f[2] as usize])
        .collect();
    let (mut error, mut truth, mut ratios) = (0.0, 0.0, Vec::new());
    for slab in 0..frames - 1 {
        let x: Vec<Vector3<f64>> = (0..vertices)
            .map(|v| 0.5 * (at(&positions.data, slab, v) + at(&positions.data, slab + 1, v)))
            .collect();
        let mut normals = vec![Vector3::zeros(); vertices];
        for f in &faces {
            let n = (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]]));
            f.iter().for_each(|&v| normals[v] += n);
        }
        for (v, n) in normals.iter().enumerate() {
            let n = n.normalize();
            let tangential = |u: Vector3<f64>| u - n * n.dot(&u);
            let true_velocity = tangential(omega * Vector3::z().cross(&(x[v] - centre())));
            let found = tangential(at(&velocity.data, slab, v));
            error += (found - true_velocity).norm();
            truth += true_velocity.norm();
            if true_velocity.norm() > 0.25 {
                ratios.push(found.norm() / true_velocity.norm());
            }
        }
    }
    let relative = error / truth;
    let ratio = meshflow::statistics::median(ratios);
    assert!(relative <= 0.25, "relative tangential error {relative}");
    assert!((0.8..1.2).contains(&ratio), "median speed ratio {ratio}");

    meshflow_error(
        &[
            "surface", &stack, "--out", &surface, "--force", "--align", "rigid",
        ],
        "--align applies to --shape closed",
    );
}
