//! Surfaces through points (`meshflow::surface`): points on a sphere give that sphere exactly,
//! a height over a sphere or a plane converges at least at second order (measured: 2.8 to
//! 3.8) as points and mesh refine together, scaling the points scales the surface and nothing
//! else, the cap covers the points, the resolution is what was asked, points read from CSV and NPY alike, and bad
//! input is an error naming the frame and point.

mod common;

use meshflow::surface::{
    fit_surface, read_points, FitOptions, Reference, Resolution, Shape, SurfaceError,
};
use nalgebra::Vector3;
use std::f64::consts::PI;

const CENTRE: Vector3<f64> = Vector3::new(10.0, -5.0, 3.0);

/// `n` directions of a Fibonacci lattice within `cap` radians of `axis`.
fn cap_directions(n: usize, cap: f64, axis: Vector3<f64>) -> Vec<Vector3<f64>> {
    let golden = PI * (3.0 - 5f64.sqrt());
    let (e1, e2) = {
        let helper = if axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = axis.cross(&helper).normalize();
        (e1, axis.cross(&e1))
    };
    (0..n)
        .map(|i| {
            let z = 1.0 - (1.0 - cap.cos()) * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            axis * z + e1 * (r * phi.cos()) + e2 * (r * phi.sin())
        })
        .collect()
}

fn options(shape: Shape, resolution: Resolution) -> FitOptions {
    FitOptions {
        shape,
        resolution,
        ..FitOptions::default()
    }
}

const CAP: Shape = Shape::SphereLike { whole: false };

#[test]
fn points_on_spheres_give_those_spheres() {
    let axis = Vector3::new(0.2, -0.3, 1.0).normalize();
    let directions = cap_directions(300, 50f64.to_radians(), axis);
    let radii = [50.0, 52.0];
    let frames: Vec<Vec<Vector3<f64>>> = radii
        .iter()
        .map(|r| directions.iter().map(|d| CENTRE + d * *r).collect())
        .collect();
    let fitted = fit_surface(&frames, &options(CAP, Resolution::Vertices(3000))).unwrap();
    let Reference::Sphere {
        centre,
        radius,
        cap_degrees,
        axis: fitted_axis,
    } = fitted.reference
    else {
        panic!("{:?}", fitted.reference)
    };
    assert!((Vector3::from(centre) - CENTRE).norm() < 1e-8, "{centre:?}");
    assert!((radius - 50.0).abs() < 1e-8);
    // The cap is about the points' mean direction and reaches a margin beyond the widest.
    let mean = directions.iter().sum::<Vector3<f64>>().normalize();
    assert!((Vector3::from(fitted_axis) - mean).norm() < 1e-12);
    let cap = cap_degrees.expect("a cap");
    assert!(cap > 50.0 && cap < 60.0, "cap {cap}°");
    // Constant heights are the spline's null space: every vertex is on its frame's sphere.
    for (positions, r) in fitted.positions.iter().zip(radii) {
        for p in positions {
            assert!(((p - CENTRE).norm() - r).abs() < 1e-8 * r);
        }
    }
    for fit in &fitted.frames {
        assert_eq!((fit.points, fit.dropped), (300, 0));
        assert!(fit.max_residual < 1e-8, "{fit:?}");
    }
    // Faces are counter-clockwise seen from outside.
    let x = &fitted.positions[0];
    for f in &fitted.faces {
        let [a, b, c] = f.map(|v| x[v as usize]);
        assert!((b - a).cross(&(c - a)).dot(&(a - CENTRE)) > 0.0);
    }
}

/// The largest distance, along the normal of the exact surface, from the fitted vertices to
/// the exact surface `r = R (1 + ε Y(ξ))` with `Y = x z / R²`, points `n` over a 60° cap.
fn ellipsoidal_cap_error(n: usize) -> f64 {
    let radius = 50.0;
    let height = |d: &Vector3<f64>| radius * (1.0 + 0.05 * (3.0 * d.x * d.z));
    let directions = cap_directions(n, 60f64.to_radians(), Vector3::z());
    let points: Vec<Vector3<f64>> = directions.iter().map(|d| CENTRE + d * height(d)).collect();
    let spacing = radius * (2.0 * PI * (1.0 - 0.5) / n as f64).sqrt();
    let fitted = fit_surface(
        &[points],
        &FitOptions {
            resolution: Resolution::EdgeLength(spacing),
            ..options(CAP, Resolution::Vertices(0))
        },
    )
    .unwrap();
    // Within 50° of the axis: away from the rim, whose natural conditions flatten the fit.
    fitted.positions[0]
        .iter()
        .map(|p| p - CENTRE)
        .map(|q| (q, q.normalize()))
        .filter(|(_, d)| d.z > 50f64.to_radians().cos())
        .map(|(q, d)| (q.norm() - height(&d)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_height_over_a_sphere_converges_at_least_at_second_order() {
    // The reference sphere is fitted to the points, so heights are over another centre than
    // the exact surface's: the error is measured radially from the exact centre.
    let errors: Vec<f64> = [400, 1600, 6400]
        .iter()
        .map(|&n| ellipsoidal_cap_error(n))
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    assert!(errors[2] < 2e-3, "errors {errors:?}");
    println!("errors {errors:?}, orders {orders:?}");
    assert!(
        orders.iter().all(|&p| p > 1.7),
        "errors {errors:?}, orders {orders:?}"
    );
}

/// The largest error of a graph `z = f(x, y)` fitted through `m × m` jittered points of
/// `[0, 4]²`, at the vertices over `[0.5, 3.5]²`.
fn graph_error(m: usize) -> f64 {
    let f = |x: f64, y: f64| 0.3 * (0.8 * x).sin() * (0.6 * y).cos() + 0.1 * x;
    let step = 4.0 / (m - 1) as f64;
    let points: Vec<Vector3<f64>> = (0..m * m)
        .map(|n| {
            let (i, j) = (n % m, n / m);
            let jitter = 0.2 * step * ((n as f64 * 0.754_877).fract() - 0.5);
            let (x, y) = (i as f64 * step + jitter, j as f64 * step - jitter);
            Vector3::new(x, y, f(x, y))
        })
        .collect();
    let fitted = fit_surface(
        &[points],
        &options(Shape::Graph, Resolution::EdgeLength(step)),
    )
    .unwrap();
    fitted.positions[0]
        .iter()
        .filter(|p| (0.5..=3.5).contains(&p.x) && (0.5..=3.5).contains(&p.y))
        .map(|p| (p.z - f(p.x, p.y)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_graph_converges_at_least_at_second_order() {
    let errors: Vec<f64> = [17, 33, 65].iter().map(|&m| graph_error(m)).collect();
    let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    println!("errors {errors:?}, orders {orders:?}");
    assert!(
        orders.iter().all(|&p| p > 1.7),
        "errors {errors:?}, orders {orders:?}"
    );
}

#[test]
fn scaling_the_points_scales_the_surface_and_nothing_else() {
    let directions = cap_directions(200, 40f64.to_radians(), Vector3::y());
    let bumpy = |scale: f64| -> Vec<Vec<Vector3<f64>>> {
        vec![directions
            .iter()
            .map(|d| (CENTRE + d * (20.0 + (5.0 * d.x).sin())) * scale)
            .collect()]
    };
    let resolution = Resolution::Vertices(2000);
    let unit = fit_surface(&bumpy(1.0), &options(CAP, resolution)).unwrap();
    let scaled = fit_surface(&bumpy(1000.0), &options(CAP, resolution)).unwrap();
    assert_eq!(unit.faces, scaled.faces);
    for (a, b) in unit.positions[0].iter().zip(&scaled.positions[0]) {
        assert!((a * 1000.0 - b).norm() < 1e-9 * b.norm());
    }
    assert!((scaled.lambda / unit.lambda / 1e6 - 1.0).abs() < 1e-9);
    assert!((scaled.mean_point_spacing / unit.mean_point_spacing / 1e3 - 1.0).abs() < 1e-9);
    // More smoothing leaves the points farther from the surface.
    let smoother = fit_surface(
        &bumpy(1.0),
        &FitOptions {
            smoothing: 3.0,
            ..options(CAP, resolution)
        },
    )
    .unwrap();
    assert!(smoother.frames[0].rms_residual > 3.0 * unit.frames[0].rms_residual);
}

#[test]
fn the_resolution_is_what_was_asked() {
    let directions = cap_directions(500, PI, Vector3::z());
    let points: Vec<Vector3<f64>> = directions.iter().map(|d| CENTRE + d * 10.0).collect();
    for n in [1000, 10_000] {
        let whole = Shape::SphereLike { whole: true };
        let fitted = fit_surface(
            std::slice::from_ref(&points),
            &options(whole, Resolution::Vertices(n)),
        )
        .unwrap();
        let count = fitted.positions[0].len() as f64;
        assert!(
            count / n as f64 > 0.5 && count / (n as f64) < 2.0,
            "{count} for {n}"
        );
        let Reference::Sphere { cap_degrees, .. } = fitted.reference else {
            panic!()
        };
        assert_eq!(cap_degrees, None);
    }
    let fitted = fit_surface(&[points], &options(CAP, Resolution::EdgeLength(0.5))).unwrap();
    let edge = fitted.mean_edge_length();
    assert!(edge <= 0.5 && edge > 0.25, "mean edge {edge}");
}

#[test]
fn points_read_from_csv_and_npy_alike() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("frames");
    std::fs::create_dir(&csv).unwrap();
    std::fs::write(
        csv.join("t_2.csv"),
        "x,y,z\n1, 2, 3\n4 5 6 # a comment\n\n7;8;9\n",
    )
    .unwrap();
    std::fs::write(csv.join("t_10.csv"), "0,0,1\n").unwrap();
    let frames = read_points(&csv).unwrap();
    assert_eq!(
        frames,
        vec![
            vec![
                Vector3::new(1.0, 2.0, 3.0),
                Vector3::new(4.0, 5.0, 6.0),
                Vector3::new(7.0, 8.0, 9.0)
            ],
            vec![Vector3::new(0.0, 0.0, 1.0)],
        ]
    );
    std::fs::write(csv.join("t_11.csv"), "1,2\n").unwrap();
    let message = read_points(&csv).unwrap_err().to_string();
    assert!(
        message.contains("t_11.csv") && message.contains("line 1"),
        "{message}"
    );

    // (K, N, 3) tracks: untracked (NaN) rows are dropped per frame.
    let tracks = dir.path().join("tracks.npy");
    let values = [
        1.0,
        2.0,
        3.0,
        f64::NAN,
        f64::NAN,
        f64::NAN,
        4.0,
        5.0,
        6.0,
        7.0,
        8.0,
        9.0,
    ];
    common::write_npy(&tracks, &[2, 2, 3], &values);
    let frames = read_points(&tracks).unwrap();
    assert_eq!(frames[0], vec![Vector3::new(1.0, 2.0, 3.0)]);
    assert_eq!(frames[1].len(), 2);
}

#[test]
fn bad_points_are_errors_naming_frame_and_point() {
    let directions = cap_directions(50, 1.0, Vector3::z());
    let good: Vec<Vector3<f64>> = directions.iter().map(|d| d * 5.0).collect();
    let fit = |frames: &[Vec<Vector3<f64>>], options: &FitOptions| {
        fit_surface(frames, options).unwrap_err()
    };
    let default = FitOptions::default();
    let mut nan = good.clone();
    nan[7].y = f64::NAN;
    assert_eq!(
        fit(&[good.clone(), good.clone(), nan], &default),
        SurfaceError::NonFinite { frame: 2, point: 7 }
    );
    assert_eq!(
        fit(&[good.clone(), good[..2].to_vec()], &default),
        SurfaceError::TooFewPoints {
            frame: 1,
            points: 2,
            needed: 3
        }
    );
    assert_eq!(fit(&[], &default), SurfaceError::NoFrames);
    let flat: Vec<Vector3<f64>> = good.iter().map(|p| Vector3::new(p.x, p.y, 1.0)).collect();
    assert_eq!(fit(&[flat], &default), SurfaceError::Coplanar);
    let line: Vec<Vector3<f64>> = (0..10)
        .map(|i| Vector3::new(i as f64, 2.0 * i as f64, (i * i) as f64))
        .collect();
    assert_eq!(
        fit(&[line], &options(Shape::Graph, Resolution::Vertices(100))),
        SurfaceError::Collinear
    );
    let bad_smoothing = FitOptions {
        smoothing: -1.0,
        ..default
    };
    assert!(matches!(
        fit(std::slice::from_ref(&good), &bad_smoothing),
        SurfaceError::BadSetting { .. }
    ));
    let message = fit(&[good], &options(CAP, Resolution::EdgeLength(f64::NAN))).to_string();
    assert!(message.contains("edge length"), "{message}");
}
