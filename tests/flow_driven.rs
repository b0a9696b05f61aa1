//! Flow-driven anisotropic robust smoothness (`--flow-driven anisotropic`,
//! `meshflow::flow::robust`): the gradient structure it penalizes, its limits, and the CLI.

mod common;

use common::{meshflow_error, shipped, solve_and_summary};
use meshflow::flow::robust::{gradient_structure, matrix_function};
use meshflow::flow::{
    compute_flow, Anisotropy, FlowDriven, FlowParams, FlowProblem, MeshSequence, Regularizer, Scale,
};
use meshflow::synth::rotating_sphere;
use nalgebra::{Matrix2, Vector2, Vector6};

fn sphere() -> MeshSequence {
    rotating_sphere(2, 3, 1.0, 0.1).unwrap().sequence
}

/// A smooth, non-trivial field in every vertex frame.
fn some_field(n: usize) -> Vec<Vector2<f64>> {
    (0..n)
        .map(|i| {
            let t = i as f64;
            Vector2::new((0.7 * t).sin(), (1.3 * t).cos() * 0.5)
        })
        .collect()
}

/// `J_T` of the covariant regularizer is `∇uᵀ∇u` with `∇u = Σ_a (R_a u_a) ∇φ_aᵀ` built here
/// independently, and for every regularizer `tr(D J)` is the element's density under `D`.
#[test]
fn the_gradient_structure_is_the_gradient_gram_matrix() {
    let sequence = sphere();
    let problem = FlowProblem::new(&sequence, &FlowParams::default()).unwrap();
    let slabs = problem.slabs();
    let slab = &slabs[0];
    let u = some_field(sequence.mesh().n_vertices());
    let tensor = Matrix2::new(1.3, 0.4, 0.4, 0.6);
    let strain = Regularizer::Strain { dirichlet: 0.0 };
    let mixed = Regularizer::Strain { dirichlet: 0.3 };
    for (f, face) in sequence.mesh().faces().iter().enumerate().take(40) {
        let triangle = slab.geometry.triangle(f);
        let rotations = &slab.connection.face_rotations(f);
        let g = triangle.hat_gradients();
        let gradient: Matrix2<f64> = (0..3)
            .map(|a| rotations[a] * u[face[a] as usize] * g[a].transpose())
            .sum();
        let covariant = gradient_structure(&Regularizer::Covariant, slab, f, face, &u);
        let expected = gradient.transpose() * gradient;
        assert!(
            (covariant - expected).norm() < 1e-12 * (1.0 + expected.norm()),
            "face {f}: {covariant} against {expected}"
        );
        let x = Vector6::from_fn(|k, _| u[face[k / 2] as usize][k % 2]);
        for regularizer in [Regularizer::Covariant, strain, mixed] {
            let j = gradient_structure(&regularizer, slab, f, face, &u);
            let e = regularizer.element(triangle, rotations, None, Some(&tensor));
            let density = x.dot(&(e * x)) / triangle.area;
            let traced = (tensor * j).trace();
            assert!(
                (density - traced).abs() < 1e-12 * (1.0 + density.abs()),
                "{regularizer:?}, face {f}: {density} against {traced}"
            );
            // Positive semi-definite.
            assert!(j.determinant() > -1e-12 * j.norm_squared() && j.trace() >= 0.0);
        }
    }
}

/// `Ψ'(A)` keeps `A`'s eigenvectors and maps its eigenvalues.
#[test]
fn the_matrix_function_maps_eigenvalues() {
    let rotation = nalgebra::Rotation2::new(0.4).into_inner();
    let a = rotation * Matrix2::new(4.0, 0.0, 0.0, 0.25) * rotation.transpose();
    let root = matrix_function(&a, f64::sqrt);
    assert!((root * root - a).norm() < 1e-14);
    let weights = matrix_function(&a, |mu| 1.0 / (1.0 + mu));
    let expected = rotation * Matrix2::new(0.2, 0.0, 0.0, 0.8) * rotation.transpose();
    assert!((weights - expected).norm() < 1e-14, "{weights}");
}

fn flow(sequence: &MeshSequence, params: &FlowParams) -> Vec<Vec<Vector2<f64>>> {
    compute_flow(sequence, params).unwrap().intrinsic
}

fn relative_difference(a: &[Vec<Vector2<f64>>], b: &[Vec<Vector2<f64>>]) -> f64 {
    let pairs = a.iter().flatten().zip(b.iter().flatten());
    let difference: f64 = pairs.map(|(x, y)| (x - y).norm_squared()).sum::<f64>();
    let size: f64 = b.iter().flatten().map(|y| y.norm_squared()).sum::<f64>();
    (difference / size).sqrt()
}

/// `ε → ∞`: `Ψ' = Id`, so the lagged tensor is the image-driven one (or `Id`) and the flow is
/// the quadratic model's, for both regularizers; a moderate `ε` changes it.
#[test]
fn a_huge_epsilon_gives_the_quadratic_flow() {
    let sequence = sphere();
    for regularizer in [
        Regularizer::Covariant,
        Regularizer::Strain { dirichlet: 0.0 },
    ] {
        for anisotropy in [None, Some(Anisotropy::new(0.3))] {
            let quadratic = FlowParams {
                regularizer,
                anisotropy,
                ..FlowParams::default()
            };
            let robust = |epsilon| FlowParams {
                robust_smoothness: Some(Scale::Value(epsilon)),
                flow_driven: FlowDriven::Anisotropic,
                ..quadratic.clone()
            };
            let reference = flow(&sequence, &quadratic);
            let limit = relative_difference(&flow(&sequence, &robust(1e7)), &reference);
            assert!(limit < 1e-7, "{regularizer:?} {anisotropy:?}: {limit:e}");
            let moderate = relative_difference(&flow(&sequence, &robust(0.01)), &reference);
            assert!(
                moderate > 1e-3,
                "{regularizer:?} {anisotropy:?}: {moderate:e}"
            );
        }
    }
}

/// Majorize–minimize: the robust energy of the reweighted flow is below the robust energy of
/// the first (quadratic) solve, which a single reweighting caps: with the scale so small that
/// it reweights several times, the result's energy must fall below the quadratic flow's.
#[test]
fn reweighting_lowers_the_robust_energy_and_stops() {
    let sequence = sphere();
    let params = FlowParams {
        robust_smoothness: Some(Scale::Value(0.02)),
        flow_driven: FlowDriven::Anisotropic,
        ..FlowParams::default()
    };
    let result = compute_flow(&sequence, &params).unwrap();
    assert!(
        (2..meshflow::flow::robust::MAX_REWEIGHTINGS).contains(&result.reweightings),
        "{} reweightings",
        result.reweightings
    );
    // The energy at the first solve is the first step's; each step's energy is below the last
    // (checked through the steps' labels, one per solve).
    assert_eq!(result.timings.steps.len(), result.reweightings + 1);
    assert!(result.energy < result.energy_at_zero);
}

#[test]
fn the_cli_solves_flow_driven_anisotropic_and_refuses_it_without_a_scale() {
    let out = tempfile::tempdir().unwrap();
    let input = shipped("rotating_sphere");
    let robust = [
        "--robust-smoothness",
        "0.05",
        "--flow-driven",
        "anisotropic",
    ];
    let (stdout, summary) = solve_and_summary(&input, out.path(), &robust);
    assert!(stdout.contains("flow-driven anisotropic"), "{stdout}");
    assert_eq!(summary["params"]["flow_driven"], "anisotropic", "{summary}");
    assert!(summary["reweightings"].as_u64().unwrap() >= 1, "{summary}");
    // `auto`: ε from the first solve, printed and recorded per slab.
    let (stdout, summary) = solve_and_summary(&input, out.path(), &["--robust-smoothness", "auto"]);
    assert!(
        stdout.contains("ε = ") && stdout.contains("(auto)"),
        "{stdout}"
    );
    assert_eq!(summary["params"]["robust_smoothness"], "auto", "{summary}");
    let scales = summary["robust_scales"].as_array().unwrap();
    assert_eq!(scales.len(), 5, "{summary}");
    assert!(
        scales.iter().all(|e| e.as_f64().unwrap() > 0.0),
        "{summary}"
    );
    let elsewhere = tempfile::tempdir().unwrap();
    let other = elsewhere.path().to_str().unwrap();
    let without = [
        "solve",
        &input,
        "--out",
        other,
        "--flow-driven",
        "anisotropic",
    ];
    meshflow_error(&without, "give its scale with --robust-smoothness");
    let embedded = [
        &without[..],
        &["--robust-smoothness", "0.1", "--regularizer", "embedded"][..],
    ]
    .concat();
    meshflow_error(&embedded, "not the embedded regularizer");
    let typo = [&without[..], &["--robust-smoothness", "0.1"][..]]
        .concat()
        .iter()
        .map(|a| if *a == "anisotropic" { "sideways" } else { a })
        .collect::<Vec<_>>();
    let run = common::meshflow(&typo);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("'sideways' is not one of: isotropic, anisotropic"),
        "{stderr}"
    );
}
