//! Coarse-to-fine warping: the scale pyramid, the warp, and what they buy on large motions.

use meshflow::accuracy::compare_result;
use meshflow::flow::LARGE_MOTION_ERROR;
use meshflow::flow::{compute_flow, heat_times, scale_pyramid, warped_slab, FlowParams};
use meshflow::flow::{FlowResult, MeshSequence, SolverChoice, SolverMethod, Warping};
use meshflow::shapes::icosphere;
use meshflow::synth::rotating_sphere;
use nalgebra::Vector2;

/// A zero flow warps nothing: the warped slab's images are the frames' own.
#[test]
fn a_zero_flow_warps_nothing() {
    let scene = rotating_sphere(3, 3, 1.0, 0.2).unwrap();
    let sequence = &scene.sequence;
    let zero = vec![Vector2::zeros(); sequence.mesh().n_vertices()];
    for s in 0..2 {
        let frames = (sequence.channels(s), sequence.channels(s + 1));
        let slab = warped_slab(sequence, s, frames, &zero, &[1.0]).unwrap();
        let (before, after) = (sequence.intensities(s), sequence.intensities(s + 1));
        let channel = &slab.channels[0];
        for i in 0..zero.len() {
            assert!((channel.mid[i] - 0.5 * (before[i] + after[i])).abs() < 1e-15);
            assert!((channel.rate[i] - (after[i] - before[i])).abs() < 1e-15);
        }
    }
}

/// Heat smoothing of the spherical harmonic `z² − 1/3` (eigenvalue 6 of the Laplacian on the
/// unit sphere): `n` implicit steps of `τ` scale it by `(1 + 6τ)^−n`, up to the mesh's O(h²).
#[test]
fn pyramid_smoothing_decays_sphere_harmonics_as_the_heat_equation() {
    let sphere = icosphere(4);
    let mesh = sphere.mesh().unwrap();
    let harmonic: Vec<f64> = sphere
        .positions
        .iter()
        .map(|x| x.z * x.z - 1.0 / 3.0)
        .collect();
    let sequence = MeshSequence::new(
        mesh,
        vec![sphere.positions.clone(); 2],
        vec![harmonic.clone(); 2],
        None,
    )
    .unwrap();
    let levels = 4;
    let pyramid = scale_pyramid(&sequence, levels).unwrap();
    let area = meshflow::geometry::IntrinsicGeometry::new(
        sequence.mesh(),
        sequence.edge_lengths(0).to_vec(),
    )
    .unwrap()
    .total_area();
    let times = heat_times(levels, area);
    let step = times[1];
    for (level, t) in times.iter().enumerate() {
        let steps = (t / step).round() as i32;
        let expected = (1.0 + 6.0 * step).powi(-steps);
        let smoothed = &pyramid[level].frame(0)[0];
        let ratio = smoothed
            .iter()
            .zip(&harmonic)
            .map(|(s, h)| s * h)
            .sum::<f64>()
            / harmonic.iter().map(|h| h * h).sum::<f64>();
        assert!(
            (ratio / expected - 1.0).abs() < 0.01,
            "level {level}: decay {ratio}, heat equation {expected}"
        );
    }
}

/// A texture turning by 1 rad per frame defeats the linear model (over 30° of error);
/// `--large-motion` brings it to the small-motion accuracy (2562 vertices, 3 frames).
#[test]
fn large_motion_warping_recovers_a_fast_rotation() {
    let scene = rotating_sphere(4, 3, 1.0, 1.0).unwrap();
    let error = |warping: Warping| {
        let params = FlowParams {
            warping,
            ..FlowParams::paper(1.0, 0.0, 1e-4)
        };
        let result = compute_flow(&scene.sequence, &params).unwrap();
        compare_result(&scene.sequence, &result, &scene.flow)
            .unwrap()
            .mean_angular_degrees
    };
    let (linear, warped) = (error(Warping::NONE), error(Warping::LARGE_MOTION));
    // What warping leaves between the two frames read along the flow is a fraction of the
    // change at rest.
    let params = FlowParams {
        warping: Warping::LARGE_MOTION,
        ..FlowParams::paper(1.0, 0.0, 1e-4)
    };
    let residual = compute_flow(&scene.sequence, &params)
        .unwrap()
        .warped_residual
        .unwrap();
    let sequence = &scene.sequence;
    let mean_abs =
        |values: Vec<f64>| values.iter().map(|x| x.abs()).sum::<f64>() / values.len() as f64;
    let left = mean_abs(residual.concat());
    let at_rest = mean_abs(
        (0..2)
            .flat_map(|s| {
                let (a, b) = (sequence.intensities(s), sequence.intensities(s + 1));
                a.iter().zip(b).map(|(x, y)| y - x).collect::<Vec<_>>()
            })
            .collect(),
    );
    println!("warped residual {left:.2e}, at rest {at_rest:.2e}");
    assert!(left < 0.1 * at_rest, "{left} vs {at_rest}");
    println!("linear {linear:.2}°, warped {warped:.2}°");
    assert!(linear > 30.0, "{linear}");
    assert!(warped < 2.5, "{warped}");
}

/// Warping gives the same numbers every run: the frames' heat steps share one METIS ordering,
/// and METIS (whose random generator lives in globals) is never called from two threads at
/// once. Before, concurrent orderings differed from run to run in the last bits.
#[test]
fn warping_is_deterministic() {
    let scene = rotating_sphere(3, 6, 1.0, 0.3).unwrap();
    let params = FlowParams {
        warping: Warping {
            levels: 3,
            warps: 1,
        },
        ..FlowParams::paper(1.0, 0.0, 1e-4)
    };
    let first = compute_flow(&scene.sequence, &params).unwrap();
    for _ in 0..3 {
        let again = compute_flow(&scene.sequence, &params).unwrap();
        assert_eq!(again.intrinsic, first.intrinsic);
    }
    let pyramid = |_| scale_pyramid(&scene.sequence, 4).unwrap();
    let pyramids: Vec<_> = (0..4).map(pyramid).collect();
    assert!(pyramids.iter().all(|p| *p == pyramids[0]));
}

/// A run of several solves reports the whole run: `total` is the wall time of assembly plus
/// all warps (within 10 %), and each warp's share is listed with its iterations.
#[test]
fn warping_reports_the_time_of_every_warp() {
    let scene = rotating_sphere(4, 4, 1.0, 0.5).unwrap();
    let params = FlowParams {
        warping: Warping::LARGE_MOTION,
        ..FlowParams::paper(1.0, 0.0, 1e-4)
    };
    let start = std::time::Instant::now();
    let result = compute_flow(&scene.sequence, &params).unwrap();
    let wall = start.elapsed().as_secs_f64();
    let timings = &result.timings;
    println!(
        "wall {wall:.3} s, total {:.3} s, steps {:?}",
        timings.total, timings.steps
    );
    assert!(
        (timings.total - wall).abs() <= 0.1 * wall,
        "{} vs {wall}",
        timings.total
    );
    assert_eq!(timings.steps.len(), Warping::LARGE_MOTION.solves());
    let shares: f64 = timings.steps.iter().map(|s| s.seconds).sum();
    assert!(shares <= timings.total && shares >= 0.8 * (timings.total - timings.assembly));
    let iterations: usize = timings.steps.iter().map(|s| s.iterations).sum();
    assert_eq!(result.iterations_in_all(), iterations);
    assert!(iterations >= timings.steps.len());
    assert_eq!(timings.steps.last().unwrap().label, "level 0, warp 2");
}

/// Each level's second warp is preconditioned with its first warp's factors (the systems
/// differ by the re-linearized data term alone), in slab Gauss–Seidel and in multigrid in time:
/// the whole warped run gives the flow of the same run solved directly.
#[test]
fn a_levels_next_warp_solves_with_the_factors_of_the_last() {
    let scene = rotating_sphere(3, 5, 1.0, 0.5).unwrap();
    let run = |solver, direct_limit| {
        let params = FlowParams {
            solver,
            direct_limit,
            tolerance: 1e-11,
            warping: Warping {
                levels: 2,
                warps: 2,
            },
            ..FlowParams::paper(1.0, 0.0, 0.1)
        };
        compute_flow(&scene.sequence, &params).unwrap()
    };
    let direct = run(SolverChoice::Auto, usize::MAX);
    assert_eq!(direct.method, SolverMethod::Direct);
    for solver in [
        SolverChoice::PcgSlabGaussSeidel,
        SolverChoice::PcgTimeMultigrid,
    ] {
        let kept = run(solver, 0);
        let reason = &kept.solver_reason;
        println!("{solver:?}: {:?}", kept.timings.steps);
        assert!(
            reason.contains("previous warp, kept"),
            "{solver:?}: {reason}"
        );
        let flat = |r: &FlowResult| -> Vec<f64> {
            r.intrinsic
                .iter()
                .flatten()
                .flat_map(|v| [v.x, v.y])
                .collect()
        };
        let (got, want) = (flat(&kept), flat(&direct));
        let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let difference = (got.iter().zip(&want)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            difference <= 1e-7 * scale,
            "{solver:?}: {difference:e} of {scale:e}"
        );
    }
}

/// The check of the linear model (`flow::motion`): its error `η` is the second difference of
/// the warped rate, which is exactly 0 while every trace stays in the face it starts in (the
/// P1 image is linear there) and grows with the motion once traces cross edges (level 4: edges
/// of 0.08 rad); a turn of a feature's size per frame passes the threshold, and the default
/// solve then warps by itself, exactly as `--large-motion` does.
#[test]
fn the_linear_model_checks_itself_and_warps_when_the_motion_is_large() {
    let eta = |omega: f64| {
        let scene = rotating_sphere(4, 2, 1.0, omega).unwrap();
        let params = FlowParams {
            detect_large_motion: true,
            ..FlowParams::default()
        };
        let result = compute_flow(&scene.sequence, &params).unwrap();
        let check = result.motion_check.unwrap();
        (check.linearization_error, check.warped)
    };
    let etas: Vec<(f64, bool)> = [0.0, 0.02, 0.15, 0.3].into_iter().map(eta).collect();
    println!("η at 0, 0.02, 0.15, 0.3 rad per frame: {etas:?}");
    assert!(etas[0].0 < 1e-12 && etas[1].0 < 1e-12, "{etas:?}");
    assert!(etas[2].0 > 1e-3 && etas[3].0 > 2.0 * etas[2].0, "{etas:?}");
    assert!(etas
        .iter()
        .all(|&(eta, warped)| !warped && eta < LARGE_MOTION_ERROR));

    let scene = rotating_sphere(4, 2, 1.0, 0.6).unwrap();
    let auto = compute_flow(&scene.sequence, &FlowParams::default()).unwrap();
    let check = auto.motion_check.unwrap();
    println!("0.6 rad per frame: {check:?}");
    assert!(check.warped && check.linearization_error > check.threshold);
    let forced = FlowParams {
        warping: Warping::LARGE_MOTION,
        ..FlowParams::default()
    };
    let warped = compute_flow(&scene.sequence, &forced).unwrap();
    assert!(warped.motion_check.is_none());
    assert_eq!(auto.intrinsic, warped.intrinsic);
    // The check's linear solve leads the run's steps.
    assert_eq!(auto.timings.steps.len(), warped.timings.steps.len() + 1);
    assert_eq!(auto.timings.steps[0].label, "linear solve, checked");
    // Off, the paper's single linear solve stays.
    let linear = FlowParams {
        detect_large_motion: false,
        ..FlowParams::default()
    };
    let single = compute_flow(&scene.sequence, &linear).unwrap();
    assert!(single.motion_check.is_none() && single.timings.steps.is_empty());
    let error = |r: &FlowResult| {
        compare_result(&scene.sequence, r, &scene.flow)
            .unwrap()
            .mean_angular_degrees
    };
    println!(
        "mean angular error: {:.2}° linear, {:.2}° warped by itself",
        error(&single),
        error(&auto)
    );
    assert!(error(&auto) < 0.5 * error(&single));
}

/// Median filtering between warps (`flow::median`): a field linear over a flat regular star
/// is kept at interior vertices, an outlier at one vertex becomes its neighbours' value, and
/// with warping the filtered run stays as accurate as the unfiltered one.
#[test]
fn the_star_median_keeps_smooth_fields_and_removes_an_outlier() {
    use meshflow::connection::Connection;
    use meshflow::flow::median::star_median;
    use meshflow::geometry::IntrinsicGeometry;
    let plane = meshflow::shapes::grid(6, 6, 1.0, 1.0);
    let mesh = plane.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &plane.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    let frames =
        meshflow::connection::vertex_frames_in_r3(&mesh, &geometry, &connection, &plane.positions)
            .unwrap();
    let field =
        |x: &nalgebra::Vector3<f64>| nalgebra::Vector3::new(0.3 + x.x, 0.5 * x.y - 0.2, 0.0);
    let u: Vec<Vector2<f64>> = (plane.positions.iter().zip(&frames))
        .map(|(x, p)| p.transpose() * field(x))
        .collect();
    let filtered = star_median(&mesh, &geometry, &connection, &u);
    let interior: Vec<usize> = (0..u.len())
        .filter(|&i| !mesh.is_boundary_vertex(i))
        .collect();
    for &i in &interior {
        assert!((filtered[i] - u[i]).norm() < 1e-12, "vertex {i}");
    }
    let outlier = interior[interior.len() / 2];
    let mut spoiled = u.clone();
    spoiled[outlier] += Vector2::new(5.0, -4.0);
    let filtered = star_median(&mesh, &geometry, &connection, &spoiled);
    let size = u[outlier].norm();
    assert!(
        (filtered[outlier] - u[outlier]).norm() < 0.3 * size,
        "{:?} vs {:?}",
        filtered[outlier],
        u[outlier]
    );

    let scene = rotating_sphere(4, 2, 1.0, 0.6).unwrap();
    let run = |median_filter| {
        let params = FlowParams {
            warping: Warping::LARGE_MOTION,
            median_filter,
            ..FlowParams::default()
        };
        let result = compute_flow(&scene.sequence, &params).unwrap();
        compare_result(&scene.sequence, &result, &scene.flow)
            .unwrap()
            .mean_angular_degrees
    };
    let (plain, filtered) = (run(false), run(true));
    println!("0.6 rad per frame, warped: {plain:.3}° plain, {filtered:.3}° median-filtered");
    assert!(filtered != plain && filtered < 1.2 * plain);
}
