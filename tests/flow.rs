//! The space-time flow: exact cases, minimality, invariance, solvers, errors (convergence to a
//! known flow: `tests/accuracy.rs`).

mod common;
use common::{assert_same_intrinsic_flow, flat_u};

use meshflow::flow::{
    compute_flow, Boundary, FlowError, FlowParams, FlowProblem, MeshSequence, SolverChoice,
    SolverMethod, TimeCoupling, Weight,
};
use meshflow::geometry::GeometryError;
use meshflow::shapes::{grid, icosphere, Surface};
use meshflow::synth::{rotating_sphere, texture};
use nalgebra::{Rotation3, Vector3};

/// Positions per frame, and grey values per frame.
type Frames = Vec<Vec<Vector3<f64>>>;
type Intensities = Vec<Vec<f64>>;

/// A flat grid (interior moved off the lattice by up to `jitter`) that stretches in x and
/// shears over `n_frames` frames, with a moving texture.
fn deforming_patch(n_frames: usize, jitter: f64) -> (Surface, Frames, Intensities) {
    let surface = common::jittered_grid(8, 6, 1.2, 1.0, jitter);
    let frames: Vec<Vec<Vector3<f64>>> = (0..n_frames)
        .map(|k| {
            let t = k as f64;
            surface
                .positions
                .iter()
                .map(|p| Vector3::new(p.x * (1.0 + 0.05 * t) + 0.03 * t * p.y, p.y, 0.0))
                .collect()
        })
        .collect();
    let intensities = (0..n_frames)
        .map(|k| {
            surface
                .positions
                .iter()
                .map(|p| {
                    texture(&Vector3::new(
                        p.x - 0.05 * k as f64,
                        p.y + 0.02 * k as f64,
                        0.3,
                    ))
                })
                .collect()
        })
        .collect();
    (surface, frames, intensities)
}

#[test]
fn static_image_gives_zero_flow_exactly() {
    let (surface, frames, intensities) = deforming_patch(4, 0.04);
    let still = vec![intensities[0].clone(); 4];
    let sequence = MeshSequence::new(surface.mesh().unwrap(), frames, still, None).unwrap();
    let flow = compute_flow(&sequence, &FlowParams::default()).unwrap();
    assert!(flat_u(&flow).iter().all(|&v| v == 0.0));
    assert_eq!((flow.energy, flow.energy_at_zero), (0.0, 0.0));
    assert_eq!((flow.iterations, flow.relative_residual), (0, 0.0));
}

#[test]
fn solution_minimizes_the_energy() {
    let (surface, frames, intensities) = deforming_patch(4, 0.04);
    let sequence = MeshSequence::new(surface.mesh().unwrap(), frames, intensities, None).unwrap();
    for coupling in [TimeCoupling::Lumped, TimeCoupling::Consistent] {
        let params = FlowParams {
            time_coupling: coupling,
            ..FlowParams::paper(0.5, 0.0, 0.1)
        };
        let problem = FlowProblem::new(&sequence, &params).unwrap();
        let flow = problem.solve(&|_| {}).unwrap();
        let u = flat_u(&flow);
        // The face-by-face energy agrees with the assembled quadratic uᵀAu − 2bᵀu + c.
        let assembled = problem.system().energy(&u);
        assert!(
            (assembled - flow.energy).abs() < 1e-10 * flow.energy_at_zero,
            "{assembled} vs {}",
            flow.energy
        );
        assert!(
            flow.energy < 0.5 * flow.energy_at_zero,
            "{} vs E(0) = {}",
            flow.energy,
            flow.energy_at_zero
        );
        assert!(
            flow.energy_terms.temporal > 0.0
                && flow.energy_terms.spatial > 0.0
                && flow.energy_terms.speed == 0.0
        );
        let scale = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for seed in 0..5 {
            let perturbed: Vec<f64> = u
                .iter()
                .zip(common::noise(u.len(), seed))
                .map(|(v, n)| v + 1e-3 * scale * n)
                .collect();
            let e = problem.energy_terms(&perturbed).total();
            assert!(
                e > flow.energy,
                "perturbation {seed} lowers the energy: {e} < {}",
                flow.energy
            );
        }
    }
}

/// The intrinsic flows of two sequences agree to round-off.

#[test]
fn rigid_motions_of_each_frame_change_nothing_intrinsic() {
    let truth = rotating_sphere(2, 4, 0.1, 0.5).unwrap();
    let sequence = &truth.sequence;
    let motions: Vec<Rotation3<f64>> = (0..4)
        .map(|k| Rotation3::from_euler_angles(0.3 * k as f64, -0.7, 1.1 * k as f64))
        .collect();
    let moved_frames: Vec<Vec<Vector3<f64>>> = (0..4)
        .map(|k| {
            sequence
                .positions(k)
                .unwrap()
                .iter()
                .map(|p| motions[k] * p + Vector3::new(k as f64, 2.0, -3.0))
                .collect()
        })
        .collect();
    let moved = MeshSequence::new(
        sequence.mesh().clone(),
        moved_frames,
        (0..4).map(|k| sequence.intensities(k).to_vec()).collect(),
        Some(sequence.times().to_vec()),
    )
    .unwrap();
    let params = FlowParams::paper(1.0, 0.0, 0.01);
    let (a, b) = (
        compute_flow(sequence, &params).unwrap(),
        compute_flow(&moved, &params).unwrap(),
    );
    assert_same_intrinsic_flow(&a, &b);
    // The R^3 flow of slab s turns with frame s.
    for (s, (va, vb)) in a
        .vectors
        .unwrap()
        .iter()
        .zip(b.vectors.unwrap().iter())
        .enumerate()
    {
        for (x, y) in va.iter().zip(vb) {
            assert!((motions[s] * x - y).norm() < 1e-9 * (1.0 + x.norm()));
        }
    }
}

#[test]
fn isometric_folding_of_a_deforming_surface_changes_nothing_intrinsic() {
    let (surface, frames, intensities) = deforming_patch(3, 0.0);
    // Fold every frame along the grid line of vertex column 4 (a line of edges: the affine
    // stretch and shear keep columns straight), by an angle that changes over time.
    let folded: Vec<Vec<Vector3<f64>>> = frames
        .iter()
        .enumerate()
        .map(|(k, positions)| {
            let column = |i: usize| i % 9;
            let hinge_a = positions[4];
            let hinge_b = positions[4 + 9 * 6];
            let axis = nalgebra::Unit::new_normalize(hinge_b - hinge_a);
            let fold = Rotation3::from_axis_angle(&axis, 0.4 + 0.5 * k as f64);
            positions
                .iter()
                .enumerate()
                .map(|(i, &p)| {
                    if column(i) > 4 {
                        hinge_a + fold * (p - hinge_a)
                    } else {
                        p
                    }
                })
                .collect()
        })
        .collect();
    assert!(folded[2].iter().any(|p| p.z.abs() > 0.1));
    let mesh = surface.mesh().unwrap();
    let params = FlowParams::default();
    let flat = compute_flow(
        &MeshSequence::new(mesh.clone(), frames, intensities.clone(), None).unwrap(),
        &params,
    )
    .unwrap();
    let bent = compute_flow(
        &MeshSequence::new(mesh, folded, intensities, None).unwrap(),
        &params,
    )
    .unwrap();
    assert_same_intrinsic_flow(&flat, &bent);
}

#[test]
fn iterative_and_direct_solvers_agree() {
    // Unit time steps: α = 1 balances the temporal and spatial smoothness per frame.
    let truth = rotating_sphere(3, 5, 1.0, 0.05).unwrap();
    let solve = |solver, alpha| {
        let params = FlowParams {
            solver,
            tolerance: 1e-11,
            ..FlowParams::paper(alpha, 0.0, 0.1)
        };
        compute_flow(&truth.sequence, &params).unwrap()
    };
    for alpha in [1.0, 0.1] {
        let direct = solve(SolverChoice::Direct, alpha);
        assert_eq!(direct.method, SolverMethod::Direct);
        assert!(
            direct.relative_residual < 1e-10,
            "direct residual {:e}",
            direct.relative_residual
        );
        for solver in [SolverChoice::PcgSlabGaussSeidel, SolverChoice::PcgJacobi] {
            let iterative = solve(solver, alpha);
            assert!(iterative.relative_residual <= 1e-11);
            assert_same_intrinsic_flow(&direct, &iterative);
        }
    }
    let sgs = solve(SolverChoice::PcgSlabGaussSeidel, 1.0);
    let jacobi = solve(SolverChoice::PcgJacobi, 1.0);
    println!(
        "iterations to 1e-11: slab Gauss-Seidel {}, Jacobi {}",
        sgs.iterations, jacobi.iterations
    );
    assert!(
        sgs.iterations * 5 < jacobi.iterations,
        "{} vs {}",
        sgs.iterations,
        jacobi.iterations
    );
    // Frame by frame: one factorization per slab equals the direct solve of the decoupled system.
    let slabwise = solve(SolverChoice::Auto, f64::INFINITY);
    assert_eq!(slabwise.method, SolverMethod::SlabwiseDirect);
    assert_same_intrinsic_flow(&slabwise, &solve(SolverChoice::Direct, f64::INFINITY));
}

/// A flat patch whose image varies along x only: `u = ŷ` costs nothing.
fn stripes(n_frames: usize) -> MeshSequence {
    common::still_sequence(&grid(6, 5, 1.0, 1.0), n_frames, |p, k| {
        (4.0 * p.x - 0.2 * k as f64).sin()
    })
}

#[test]
fn undetermined_flow_is_an_error_that_suggests_a_speed_penalty() {
    for alpha in [1.0, f64::INFINITY] {
        let err = compute_flow(
            &stripes(3),
            &FlowParams {
                alpha: Weight::Value(alpha),
                ..FlowParams::default()
            },
        )
        .unwrap_err();
        assert!(matches!(err, FlowError::Singular { .. }), "{err:?}");
        // The README's unit-free option first, then β in the data's units.
        let message = err.to_string();
        assert!(message.contains("--speed-penalty 0.01"), "{message}");
        assert!(message.contains("(--beta)"), "{message}");
    }
    // Remedies: a speed penalty, or Dirichlet boundary values.
    assert!(compute_flow(
        &stripes(3),
        &FlowParams {
            beta: Weight::Value(1e-3),
            ..FlowParams::default()
        }
    )
    .is_ok());
    assert!(compute_flow(
        &stripes(3),
        &FlowParams {
            boundary: Boundary::Dirichlet,
            ..FlowParams::default()
        }
    )
    .is_ok());
    // A curved surface has no parallel field: β = 0 is fine.
    assert!(compute_flow(
        &rotating_sphere(1, 3, 1.0, 0.3).unwrap().sequence,
        &FlowParams::default()
    )
    .is_ok());
}

#[test]
fn invalid_parameters_are_named() {
    let sequence = stripes(2);
    type Spoil = fn(&mut FlowParams);
    // Values carry the paper's names, relative scales the command line's.
    let cases: [(Spoil, &str); 14] = [
        (|p| p.alpha = Weight::Value(0.0), "alpha"),
        // Coupling in time so strong that the system is numerically singular (it failed in
        // the Cholesky factorization, NonPositivePivot, before it was refused by name).
        (|p| p.alpha = Weight::Value(1e-300), "alpha"),
        (|p| p.alpha = Weight::Value(1e-100), "alpha"),
        (|p| p.alpha = Weight::Relative(1e300), "time-scale"),
        (|p| p.alpha = Weight::Value(f64::NAN), "alpha"),
        (|p| p.alpha = Weight::Relative(-1.0), "time-scale"),
        (|p| p.alpha = Weight::Relative(f64::INFINITY), "time-scale"),
        (|p| p.beta = Weight::Value(-1.0), "beta"),
        (|p| p.beta = Weight::Relative(f64::NAN), "speed-penalty"),
        (|p| p.gamma = Weight::Value(0.0), "gamma"),
        (|p| p.gamma = Weight::Value(f64::INFINITY), "gamma"),
        (|p| p.gamma = Weight::Relative(0.0), "spread"),
        (|p| p.gamma = Weight::Relative(-0.5), "spread"),
        (|p| p.tolerance = 0.0, "tolerance"),
    ];
    for (spoil, name) in cases {
        let mut params = FlowParams::default();
        spoil(&mut params);
        match compute_flow(&sequence, &params).unwrap_err() {
            FlowError::InvalidParameter { name: n, .. } => assert_eq!(n, name),
            other => panic!("{name}: {other:?}"),
        }
    }
}

#[test]
fn invalid_sequences_name_frame_and_element() {
    let sphere = icosphere(1);
    let mesh = sphere.mesh().unwrap();
    let v = sphere.positions.len();
    let make = |frames: Vec<Vec<Vector3<f64>>>, intensities: Vec<Vec<f64>>, times| {
        MeshSequence::new(mesh.clone(), frames, intensities, times)
    };
    let still = |k: usize| vec![sphere.positions.clone(); k];
    let grey = |k: usize| vec![vec![0.5; v]; k];

    assert_eq!(
        make(still(1), grey(1), None).unwrap_err(),
        FlowError::TooFewFrames(1)
    );
    assert!(matches!(
        make(still(3), grey(2), None).unwrap_err(),
        FlowError::CountMismatch {
            what: "intensity frames",
            ..
        }
    ));
    let mut short = grey(3);
    short[2].pop();
    assert!(matches!(
        make(still(3), short, None).unwrap_err(),
        FlowError::Frame { frame: 2, .. }
    ));
    let mut nan = grey(3);
    nan[1][7] = f64::NAN;
    assert!(matches!(
        make(still(3), nan, None).unwrap_err(),
        FlowError::NonFiniteIntensity {
            frame: 1,
            vertex: 7,
            ..
        }
    ));
    let err = make(still(3), grey(3), Some(vec![0.0, 1.0, 1.0])).unwrap_err();
    assert!(
        matches!(err, FlowError::NonIncreasingTimes { frame: 2, .. }),
        "{err:?}"
    );
    assert!(matches!(
        make(still(2), grey(2), Some(vec![0.0])).unwrap_err(),
        FlowError::CountMismatch {
            what: "frame times",
            ..
        }
    ));
    let mut collapsed = still(3);
    let face = mesh.faces()[5];
    collapsed[1][face[0] as usize] = collapsed[1][face[1] as usize];
    let err = make(collapsed, grey(3), None).unwrap_err();
    assert!(
        matches!(
            err,
            FlowError::Frame {
                frame: 1,
                source: GeometryError::InvalidEdgeLength { .. }
            }
        ),
        "{err:?}"
    );
    let mut infinite = still(2);
    infinite[1][3].x = f64::INFINITY;
    let err = make(infinite, grey(2), None).unwrap_err();
    assert!(
        matches!(
            err,
            FlowError::Frame {
                frame: 1,
                source: GeometryError::NonFinitePosition { vertex: 3, .. }
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().starts_with("frame 1: vertex 3"), "{err}");
}

/// The sequence with grey values times `grey` and times times `time`.
fn rescaled(sequence: &MeshSequence, grey: f64, time: f64) -> MeshSequence {
    let k = sequence.n_frames();
    MeshSequence::new(
        sequence.mesh().clone(),
        (0..k)
            .map(|i| sequence.positions(i).unwrap().to_vec())
            .collect(),
        (0..k)
            .map(|i| sequence.intensities(i).iter().map(|v| grey * v).collect())
            .collect(),
        Some(sequence.times().iter().map(|t| time * t).collect()),
    )
    .unwrap()
}

#[test]
fn default_weights_do_not_depend_on_units() {
    // Grey values in [0, 255] instead of [0, 1], frames at 30 per second instead of one per
    // unit time: the default (relative) weights give the same flow per frame; the paper's
    // fixed weights do not.
    let truth = rotating_sphere(2, 4, 1.0, 0.05).unwrap();
    let base = &truth.sequence;
    for params in [FlowParams::default(), FlowParams::paper(1.0, 0.0, 0.1)] {
        let reference = compute_flow(base, &params).unwrap();
        let scale = flat_u(&reference)
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let mut largest_change: f64 = 0.0;
        for (grey, time) in [(255.0, 1.0), (1.0, 1.0 / 30.0), (255.0, 1.0 / 30.0)] {
            let flow = compute_flow(&rescaled(base, grey, time), &params).unwrap();
            // Velocities per unit time: per frame, they are `time` times smaller.
            for (a, b) in flat_u(&flow).iter().zip(flat_u(&reference)) {
                largest_change = largest_change.max((a * time - b).abs());
            }
            let expected = reference.weights.gamma * grey * grey;
            if params == FlowParams::default() {
                assert!((flow.weights.gamma / expected - 1.0).abs() < 1e-12);
            }
        }
        match params == FlowParams::default() {
            true => assert!(largest_change < 1e-9 * scale, "{largest_change:e}"),
            false => assert!(largest_change > 0.1 * scale, "{largest_change:e}"),
        }
    }
}

#[test]
fn relative_weights_need_an_image_gradient() {
    let sphere = icosphere(1);
    let flat_image = vec![vec![0.5; sphere.positions.len()]; 2];
    let sequence = MeshSequence::new(
        sphere.mesh().unwrap(),
        vec![sphere.positions.clone(); 2],
        flat_image,
        None,
    )
    .unwrap();
    let err = compute_flow(&sequence, &FlowParams::default()).unwrap_err();
    assert_eq!(err, FlowError::NoImageGradient);
    assert!(err.to_string().contains("do not vary"), "{err}");
    // The paper's fixed weights need no scale: the flow is zero.
    let flow = compute_flow(&sequence, &FlowParams::paper(1.0, 0.0, 0.1)).unwrap();
    assert!(flat_u(&flow).iter().all(|&x| x == 0.0));
}
