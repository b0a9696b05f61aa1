//! The strain regularizer `|Sym ∇u|²` against exact values: affine fields on a flat mesh to
//! round-off, Killing and gradient fields of the sphere under refinement, and what it changes
//! in a solve.

use meshflow::accuracy::compare_result;
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::flow::{compute_flow, FlowError, FlowParams, MeshSequence, Regularizer, Warping};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::shapes::{grid, icosphere, Surface};
use meshflow::synth::rotating_sphere;
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
            let e = regularizer.element(geometry.triangle(f), connection.face_rotations(f));
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
