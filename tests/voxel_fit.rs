//! Sheets and caps fitted from volumes alone (`meshflow::surface::foreground_points` and
//! `fit_surface_weighted`, `meshflow surface VOLUMES --shape sphere-like|graph`): the surface
//! passes through the middle of the bright layer, pulled towards its brighter part, in spite
//! of noise.

mod common;

use common::{meshflow_error, meshflow_ok, write_npy, write_ome_zarr_f32};
use meshflow::surface::{
    fit_surface_weighted, foreground_points, FitOptions, IsosurfaceOptions, Resolution, Shape,
};
use meshflow::volume::Volume;
use nalgebra::Vector3;
use std::path::Path;

const N: usize = 40;
/// The centre of the cap's sphere: below the volume's middle, so that the cap fills its top.
const CENTRE: [f64; 3] = [19.5, 19.5, 6.0];

/// `N³` unit voxels of `value` with noise ([`common::noisy_volume`]).
fn volume(value: impl Fn(Vector3<f64>) -> f64, noise: f64) -> Volume {
    common::noisy_volume(N, value, noise)
}

fn distance_from_centre(p: &Vector3<f64>) -> f64 {
    (p - Vector3::from(CENTRE)).norm()
}

/// A spherical cap layer between radii 25 and 28 about [`CENTRE`] (above `z = 14`, inside the
/// volume), `inner` bright in its inner half and `outer` in its outer half, on a background of
/// 20.
fn cap_layer(inner: f64, outer: f64) -> Volume {
    volume(
        move |p| match distance_from_centre(&p) {
            r if p.z > 14.0 && (25.0..26.5).contains(&r) => inner,
            r if p.z > 14.0 && (26.5..28.0).contains(&r) => outer,
            _ => 20.0,
        },
        12.0,
    )
}

fn fit(volume: &Volume, shape: Shape) -> meshflow::surface::FittedSurface {
    let found = foreground_points(volume, &IsosurfaceOptions::default()).unwrap();
    assert_eq!(found.stride, 1);
    assert_eq!(found.points.len(), found.foreground_voxels);
    assert!(found.weights.iter().all(|&w| w > 0.0));
    let options = FitOptions {
        shape,
        resolution: Resolution::Vertices(2000),
        ..FitOptions::default()
    };
    let frames = vec![found.points.clone(), found.points];
    let weights = vec![found.weights.clone(), found.weights];
    fit_surface_weighted(&frames, &weights, 4.0, &options).unwrap()
}

/// The cap's mean distance from its sphere's centre, over the vertices above the layer's
/// bottom edge (the rim, where the spline meets the margin, is left out).
fn mean_radius(fitted: &meshflow::surface::FittedSurface) -> (f64, f64, f64) {
    let radii: Vec<f64> = (fitted.positions[0].iter())
        .filter(|p| p.z > 20.0)
        .map(distance_from_centre)
        .collect();
    let mean = radii.iter().sum::<f64>() / radii.len() as f64;
    let (low, high) = radii
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &r| (l.min(r), h.max(r)));
    (mean, low, high)
}

#[test]
fn a_cap_layer_is_fitted_through_its_middle() {
    let fitted = fit(&cap_layer(120.0, 120.0), Shape::SphereLike { whole: false });
    let (mean, low, high) = mean_radius(&fitted);
    assert!((mean - 26.5).abs() < 0.3, "mean radius {mean}");
    assert!(
        low > 25.0 && high < 28.0,
        "radii {low}–{high} leave the layer 25–28"
    );
}

/// Weighted by brightness: a layer bright in its outer half draws the surface outwards, one
/// bright inside inwards, each by about a quarter of the layer (the halves' middles are
/// ±0.75 from the layer's).
#[test]
fn the_brighter_part_of_the_layer_pulls_the_surface() {
    let cap = Shape::SphereLike { whole: false };
    let (outer, ..) = mean_radius(&fit(&cap_layer(60.0, 200.0), cap));
    let (inner, ..) = mean_radius(&fit(&cap_layer(200.0, 60.0), cap));
    assert!(
        outer - inner > 0.5,
        "outer-bright {outer}, inner-bright {inner}"
    );
    assert!(
        outer > 26.5 && inner < 26.5,
        "outer-bright {outer}, inner-bright {inner}"
    );
}

/// A tilted sheet `z = 12 + 0.3 x ± 1.5` seen from above: the graph through its middle.
#[test]
fn a_sheet_is_fitted_as_a_graph() {
    let sheet = volume(
        |p| match (p.z - 12.0 - 0.3 * p.x).abs() {
            d if d < 1.5 => 150.0,
            _ => 20.0,
        },
        12.0,
    );
    let fitted = fit(&sheet, Shape::Graph);
    let inner = fitted.positions[0]
        .iter()
        .filter(|p| (4.0..35.0).contains(&p.x));
    let offsets: Vec<f64> = inner.map(|p| p.z - 12.0 - 0.3 * p.x).collect();
    let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
    let worst = offsets.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    assert!(mean.abs() < 0.2, "mean offset {mean}");
    assert!(worst < 1.0, "largest offset {worst}");
}

/// The command: volumes (with a volume flag) are fitted through their bright voxels and
/// reported per frame; an image with nothing above the threshold is refused in one line.
#[test]
fn the_command_fits_volumes_and_reports_their_voxels() {
    let dir = tempfile::tempdir().unwrap();
    let cap = cap_layer(120.0, 120.0);
    let file = dir.path().join("volumes.npy");
    let frames = [cap.values(), cap.values()].concat();
    write_npy(&file, &[2, N as u64, N as u64, N as u64], &frames);
    let out = dir.path().join("surf");
    let name = |p: &Path| p.to_str().unwrap().to_string();
    let run = meshflow_ok(&[
        "surface",
        &name(&file),
        "--voxel-size",
        "1,1,1",
        "--vertices",
        "2000",
        "--out",
        &name(&out),
    ]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("bright voxels"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("surface.json")).unwrap()).unwrap();
    assert_eq!(report["volumes"]["smoothing_unit"], 8.0);
    let first = &report["volumes"]["frames"][0];
    assert!(first["threshold"].as_f64().unwrap() > 20.0, "{first}");
    assert!(
        first["foreground_voxels"].as_u64().unwrap() > 1000,
        "{first}"
    );
    // The same frames as an OME-Zarr image are volumes without any flag, and fit the same.
    let image = dir.path().join("volumes.zarr");
    write_ome_zarr_f32(&image, [N, N, N], &[cap.values(), cap.values()]);
    let from_zarr = dir.path().join("surf_zarr");
    let args = [
        "surface",
        &name(&image),
        "--vertices",
        "2000",
        "--out",
        &name(&from_zarr),
    ];
    meshflow_ok(&args);
    let positions = |d: &Path| std::fs::read(d.join("positions.npy")).unwrap();
    assert_eq!(positions(&from_zarr), positions(&out));
    let flat = dir.path().join("flat.npy");
    write_npy(&flat, &[2, 4, 4, 4], &[1.0f32; 128]);
    meshflow_error(
        &[
            "surface",
            &name(&flat),
            "--voxel-size",
            "1,1,1",
            "--out",
            &name(&dir.path().join("f")),
        ],
        "the image is constant",
    );
}
