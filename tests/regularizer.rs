//! The strain regularizer `|Sym ∇u|²` against exact values: affine fields on a flat mesh to
//! round-off, Killing and gradient fields of the sphere under refinement, and what it changes
//! in a solve.

use meshflow::accuracy::compare_result;
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::flow::{
    compute_flow, FlowError, FlowParams, MeshSequence, Regularizer, Scale, SolverChoice, Warping,
};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::shapes::{grid, icosphere, Surface};
use meshflow::synth::{moving_cell_sphere, rotating_sphere, STILL_CELLS};
use nalgebra::{Matrix2, Vector3, Vector6};
use std::f64::consts::PI;

const STRAIN: Regularizer = Regularizer::Strain { dirichlet: 0.0 };

/// `Σ_T u_Tᵀ E_T u_T` for the R^3 field `field` sampled at the vertices (tangential part in the
/// vertex frames), with `E_T` the regularizer's element.
fn energy(
    surface: &Surface,
    regularizer: Regularizer,
    field: impl Fn(&Vector3<f64>) -> Vector3<f64>,
) -> f64 {
    let mesh = surface.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &surface.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &surface.positions).unwrap();
    let u: Vec<_> = surface
        .positions
        .iter()
        .zip(&frames)
        .map(|(x, p)| p.transpose() * field(x))
        .collect();
    mesh.faces()
        .iter()
        .enumerate()
        .map(|(f, face)| {
            let corner = face.map(|v| &frames[v as usize]);
            let e = regularizer.element(
                geometry.triangle(f),
                &connection.face_rotations(f),
                Some(corner),
                None,
            );
            let x = Vector6::from_fn(|k, _| u[face[k / 2] as usize][k % 2]);
            x.dot(&(e * x))
        })
        .sum()
}

#[test]
fn affine_fields_on_a_flat_mesh_have_their_exact_strain() {
    let plane = grid(7, 5, 2.0, 1.0);
    let a = Matrix2::new(0.3, -1.1, 0.4, 0.7);
    let field = |x: &Vector3<f64>| {
        let v = a * x.xy() + nalgebra::Vector2::new(0.2, -0.5);
        Vector3::new(v.x, v.y, 0.0)
    };
    let sym = 0.5 * (a + a.transpose());
    let area = 2.0;
    let strain = energy(&plane, STRAIN, field);
    assert!(
        (strain - area * sym.norm_squared()).abs() < 1e-12,
        "{strain}"
    );
    let covariant = energy(&plane, Regularizer::Covariant, field);
    assert!(
        (covariant - area * a.norm_squared()).abs() < 1e-12,
        "{covariant}"
    );
    // A rotation about any point strains nothing.
    let rotation = |x: &Vector3<f64>| Vector3::new(-(x.y - 0.3), x.x - 1.2, 0.0);
    assert!(energy(&plane, STRAIN, rotation).abs() < 1e-12);
    assert!((energy(&plane, Regularizer::Covariant, rotation) - 2.0 * area).abs() < 1e-12);
}

/// Errors of the strain energy of the sphere's rotation `ẑ × x` (exact: 0) and of the gradient
/// field `∇z = ẑ − z x` (exact: `∫|Hess z|² = ∫ 2z² = 8π/3`, Hess z = −z g), levels 2..=5.
#[test]
fn strain_of_sphere_fields_converges_at_second_order() {
    let killing = |x: &Vector3<f64>| Vector3::z().cross(x);
    let gradient = |x: &Vector3<f64>| Vector3::z() - x.z * x;
    let mut errors = Vec::new();
    for level in 2..=5 {
        let sphere = icosphere(level);
        let rotation = energy(&sphere, STRAIN, killing);
        let conformal = (energy(&sphere, STRAIN, gradient) - 8.0 * PI / 3.0).abs();
        // The covariant term of the rotation stays at ∫K|u|² = ∫|u|² = 8π/3 (Bochner).
        let covariant = energy(&sphere, Regularizer::Covariant, killing);
        println!("level {level}: Killing {rotation:.3e}, ∇z {conformal:.3e}, covariant rotation {covariant:.4}");
        assert!((covariant - 8.0 * PI / 3.0).abs() < 0.05 * 8.0 * PI / 3.0);
        errors.push((rotation, conformal));
    }
    for pair in errors.windows(2) {
        let order = |a: f64, b: f64| (a / b).log2();
        assert!(order(pair[0].0, pair[1].0) > 1.8, "{errors:?}");
        assert!(order(pair[0].1, pair[1].1) > 1.8, "{errors:?}");
    }
    // Weitzenböck: ∫|Sym∇u|² = ½∫|∇u|² + ½∫(div u)² − ½∫K|u|², with div ∇z = −2z on the unit
    // sphere: ½·8π/3 + ½·16π/3 − ½·8π/3 = 8π/3, what the discrete strain converges to above.
}

#[test]
fn strain_lets_a_turning_texture_turn() {
    let scene = rotating_sphere(3, 3, 1.0, 0.05).unwrap();
    let error = |regularizer| {
        let params = FlowParams {
            regularizer,
            warping: Warping::LARGE_MOTION,
            ..FlowParams::paper(1.0, 0.0, 1e-3)
        };
        let result = compute_flow(&scene.sequence, &params).unwrap();
        compare_result(&scene.sequence, &result, &scene.flow).unwrap()
    };
    let (covariant, strain) = (error(Regularizer::Covariant), error(STRAIN));
    println!(
        "angular error {:.2}° covariant, {:.2}° strain; speed ratio {:.3} / {:.3}",
        covariant.mean_angular_degrees,
        strain.mean_angular_degrees,
        covariant.median_speed_ratio,
        strain.median_speed_ratio
    );
    assert!(strain.mean_angular_degrees < 0.3 * covariant.mean_angular_degrees);
    assert!(strain.mean_angular_degrees < 0.5);
    assert!(
        (strain.median_speed_ratio - 1.0).abs() < 0.5 * (covariant.median_speed_ratio - 1.0).abs()
    );
}

/// Stripes moving across a flat patch leave the translation along them free: parallel, so a
/// kernel of the strain energy too; refused with the hint, solved with `β > 0`.
#[test]
fn strain_with_a_free_translation_is_refused() {
    let plane = grid(6, 6, 1.0, 1.0);
    let frames = vec![plane.positions.clone(); 3];
    let grey = (0..3)
        .map(|k| {
            plane
                .positions
                .iter()
                .map(|p| (3.0 * p.x - 0.1 * k as f64).sin())
                .collect()
        })
        .collect();
    let sequence = MeshSequence::new(plane.mesh().unwrap(), frames, grey, None).unwrap();
    let params = |beta| FlowParams {
        regularizer: STRAIN,
        ..FlowParams::paper(1.0, beta, 1e-3)
    };
    let error = compute_flow(&sequence, &params(0.0)).unwrap_err();
    assert!(matches!(error, FlowError::Singular { .. }), "{error}");
    assert!(compute_flow(&sequence, &params(1e-3)).is_ok());
    let mixed = Regularizer::with_mix(STRAIN, Some(-1.0)).unwrap();
    let invalid = FlowParams {
        regularizer: mixed,
        ..FlowParams::paper(1.0, 1e-3, 1e-3)
    };
    let message = compute_flow(&sequence, &invalid).unwrap_err().to_string();
    assert!(message.contains("dirichlet"), "{message}");
    assert!(Regularizer::with_mix(Regularizer::Covariant, Some(0.5)).is_err());
}

/// Charbonnier smoothness with ε → ∞ is the quadratic model.
#[test]
fn robust_smoothness_with_a_huge_scale_is_the_quadratic_model() {
    let scene = rotating_sphere(3, 3, 1.0, 0.05).unwrap();
    let params = |robust_smoothness| FlowParams {
        robust_smoothness,
        ..FlowParams::paper(1.0, 0.0, 1e-3)
    };
    let quadratic = compute_flow(&scene.sequence, &params(None)).unwrap();
    let robust = compute_flow(&scene.sequence, &params(Some(Scale::Value(1e8)))).unwrap();
    let difference: f64 = quadratic
        .intrinsic
        .concat()
        .iter()
        .zip(robust.intrinsic.concat())
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    let size = quadratic
        .intrinsic
        .concat()
        .iter()
        .map(|u| u.norm())
        .fold(0.0, f64::max);
    assert!(difference < 1e-9 * size, "{difference} vs {size}");
    assert_eq!(robust.reweightings, 1);
    assert!((robust.energy - quadratic.energy).abs() < 1e-9 * quadratic.energy);
    assert_eq!(quadratic.reweightings, 0);
}

/// A bright cell moving over a still background of cells: the quadratic smoothness drags the
/// still cells along; the robust one keeps the motion where it is.
#[test]
fn robust_smoothness_keeps_a_moving_cell_from_dragging_its_neighbours() {
    let scene = moving_cell_sphere(4, 3, 1.0, 0.08).unwrap();
    let sequence = scene.sequence;
    let sphere = icosphere(4);
    let still = STILL_CELLS.map(Vector3::from);
    // Mean speed at the still cells' centres (where their image gradient is weak) and around them.
    let near_still: Vec<usize> = (0..sphere.positions.len())
        .filter(|&i| still.iter().any(|c| (sphere.positions[i] - c).norm() < 0.3))
        .collect();
    let drift = |robust_smoothness| {
        let params = FlowParams {
            robust_smoothness,
            ..FlowParams::paper(1.0, 1e-4, 1e-3)
        };
        let result = compute_flow(&sequence, &params).unwrap();
        let vectors = result.vectors.unwrap();
        let mean = near_still
            .iter()
            .map(|&i| vectors[0][i].norm())
            .sum::<f64>()
            / near_still.len() as f64;
        let peak = vectors[0].iter().map(|v| v.norm()).fold(0.0, f64::max);
        (mean, peak, result.reweightings)
    };
    let (quadratic, quadratic_peak, _) = drift(None);
    let (robust, robust_peak, reweightings) = drift(Some(Scale::Value(0.01)));
    println!("drift at the still cells: {quadratic:.3e} quadratic, {robust:.3e} robust ({reweightings} reweightings); peaks {quadratic_peak:.3e} / {robust_peak:.3e}");
    assert!(robust < 0.2 * quadratic);
    assert!(robust_peak > 0.8 * quadratic_peak);
    assert!((2..crate_max()).contains(&reweightings));
    // `auto` finds a scale of the flow's own gradient that more than halves the drag (0.41×;
    // ε = 0.01, far below the typical |∇u|, 0.12×).
    let (auto, auto_peak, reweightings) = drift(Some(Scale::Auto));
    println!("auto: drift {auto:.3e}, peak {auto_peak:.3e} ({reweightings} reweightings)");
    assert!(auto < 0.5 * quadratic);
    assert!(auto_peak > 0.8 * quadratic_peak);
}

fn crate_max() -> usize {
    meshflow::flow::robust::MAX_REWEIGHTINGS
}

/// Kirisits–Lang–Scherzer's embedded term equals the covariant one on a flat mesh to round-off
/// (whatever the field), and adds `∫|II(u,·)|² = ∫|u|²` on the unit sphere: the rotation's
/// `8π/3 + 8π/3`.
#[test]
fn embedded_regularizer_is_covariant_when_flat_and_adds_the_second_fundamental_form() {
    let plane = grid(7, 5, 2.0, 1.0);
    let field = |x: &Vector3<f64>| Vector3::new((3.0 * x.y).sin(), x.x * x.x - x.y, 0.0);
    let (flat_embedded, flat_covariant) = (
        energy(&plane, Regularizer::Embedded, field),
        energy(&plane, Regularizer::Covariant, field),
    );
    assert!((flat_embedded - flat_covariant).abs() < 1e-12 * flat_covariant);
    let killing = |x: &Vector3<f64>| Vector3::z().cross(x);
    let errors: Vec<f64> = (2..=5)
        .map(|level| {
            (energy(&icosphere(level), Regularizer::Embedded, killing) - 16.0 * PI / 3.0).abs()
        })
        .collect();
    println!("embedded energy of the rotation, error per level: {errors:?}");
    assert!(errors[3] < 0.01 * 16.0 * PI / 3.0, "{errors:?}");
    assert!(errors.windows(2).all(|e| e[1] < 0.5 * e[0]), "{errors:?}");
    // Edge lengths alone do not say how the surface bends.
    let sphere = icosphere(2);
    let mesh = sphere.mesh().unwrap();
    let lengths = meshflow::geometry::edge_lengths(&mesh, &sphere.positions).unwrap();
    let grey: Vec<f64> = sphere.positions.iter().map(|p| p.x).collect();
    let intrinsic =
        MeshSequence::from_edge_lengths(mesh, vec![lengths; 2], vec![grey.clone(), grey], None)
            .unwrap();
    let params = FlowParams {
        regularizer: Regularizer::Embedded,
        ..FlowParams::paper(1.0, 0.0, 1e-3)
    };
    let error = compute_flow(&intrinsic, &params).unwrap_err();
    assert_eq!(error, FlowError::NeedsEmbedding);
}

/// The Charbonnier data term with ε → ∞ is the paper's quadratic one (one reweighted solve
/// that changes nothing); with a small ε it shrugs off frames that break brightness
/// constancy: a texture turning on the sphere whose middle frame has a bright flash on part of
/// it (grey values +2 over a cap), which drags the quadratic flow off the rotation there.
#[test]
fn the_robust_data_term_is_quadratic_for_a_huge_scale_and_resists_a_flash() {
    let scene = rotating_sphere(4, 3, 1.0, 0.05).unwrap();
    let params = |robust_data| FlowParams {
        robust_data,
        ..FlowParams::paper(1.0, 0.0, 1e-3)
    };
    let quadratic = compute_flow(&scene.sequence, &params(None)).unwrap();
    let huge = compute_flow(&scene.sequence, &params(Some(Scale::Value(1e8)))).unwrap();
    let difference = (quadratic.intrinsic.concat().iter())
        .zip(huge.intrinsic.concat())
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(difference < 1e-9, "{difference}");
    assert_eq!(huge.reweightings, 1);
    assert!((huge.energy - quadratic.energy).abs() < 1e-9 * quadratic.energy);
    assert_eq!(huge.robust_data_scales, vec![1e8; 2]);

    let sphere = icosphere(4);
    let mut frames: Vec<Vec<f64>> = (0..3)
        .map(|k| scene.sequence.intensities(k).to_vec())
        .collect();
    for (i, x) in sphere.positions.iter().enumerate() {
        if x.z > 0.7 {
            frames[1][i] += 2.0;
        }
    }
    let positions = vec![sphere.positions.clone(); 3];
    let flashed = MeshSequence::new(sphere.mesh().unwrap(), positions, frames, None).unwrap();
    let error = |robust_data| {
        let result = compute_flow(&flashed, &params(robust_data)).unwrap();
        let scores = compare_result(&flashed, &result, &scene.flow).unwrap();
        (
            scores.mean_angular_degrees,
            result.reweightings,
            result.robust_data_scales,
        )
    };
    let (plain, _, _) = error(None);
    let (robust, reweightings, _) = error(Some(Scale::Value(0.01)));
    let (auto, _, scales) = error(Some(Scale::Auto));
    println!("flash: mean angular error {plain:.2}° quadratic, {robust:.2}° robust ({reweightings} reweightings), {auto:.2}° auto (ε {scales:?})");
    assert!(robust < 0.7 * plain, "{robust} vs {plain}");
    assert!(auto < plain, "{auto} vs {plain}");
    assert!((2..crate_max()).contains(&reweightings));
}

/// With an iterative solver the reweightings stop early until the energy settles
/// (`flow::robust`, "Inexact steps"), then one solves at the run's tolerance: the same
/// minimizer as the direct solver's exact reweightings, to the stopping rule's accuracy.
#[test]
fn inexact_reweightings_reach_the_exact_reweightings_minimizer() {
    let scene = rotating_sphere(3, 4, 1.0, 0.05).unwrap();
    let params = |solver| FlowParams {
        robust_data: Some(Scale::Auto),
        robust_smoothness: Some(Scale::Auto),
        solver,
        tolerance: 1e-10,
        ..FlowParams::paper(1.0, 0.0, 1e-3)
    };
    let exact = compute_flow(&scene.sequence, &params(SolverChoice::Direct)).unwrap();
    let inexact = compute_flow(&scene.sequence, &params(SolverChoice::PcgSlabGaussSeidel)).unwrap();
    let (a, b) = (exact.intrinsic.concat(), inexact.intrinsic.concat());
    let size = a.iter().map(|u| u.norm()).fold(0.0, f64::max);
    let difference = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    println!(
        "direct: {} reweightings, energy {:e}; PCG: {} reweightings, energy {:e}; flows differ by {:.1e} of the largest",
        exact.reweightings, exact.energy, inexact.reweightings, inexact.energy, difference / size
    );
    assert!(
        inexact.relative_residual < 1e-10,
        "{}",
        inexact.relative_residual
    );
    assert!((inexact.energy - exact.energy).abs() < 1e-4 * exact.energy);
    assert!(difference < 1e-2 * size, "{difference:e} of {size:e}");
    assert!(inexact.reweightings >= 2 && inexact.reweightings < crate_max());
}
