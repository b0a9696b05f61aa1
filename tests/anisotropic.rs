//! The image-driven anisotropic regularizer `tr(∇u D ∇uᵀ)` (`flow::anisotropy`): its element
//! against exact values on one face, its limit `λ → ∞` (the paper's system), its invariances,
//! and the CLI's `--anisotropic`.

mod common;

use common::{meshflow_error, relative_value_difference, rigid_motion, shipped, solve_and_summary};
use meshflow::fem::element::{
    anisotropic_stiffness, anisotropic_strain_element, cotan_stiffness, strain_element,
};
use meshflow::flow::anisotropy::tensor;
use meshflow::flow::{Anisotropy, FlowParams, FlowProblem, MeshSequence, Regularizer, Scale, Slab};
use meshflow::geometry::Triangle;
use meshflow::synth::rotating_sphere;
use nalgebra::{Matrix2, Vector2, Vector6};

#[test]
fn the_identity_tensor_gives_the_cotan_stiffness() {
    for lengths in [
        [1.0, 1.0, 1.0],
        [3.0, 4.0, 5.0],
        [1.0, 0.3, 0.8],
        [2.0, 1.99, 0.02],
    ] {
        let triangle = Triangle::from_lengths(lengths).unwrap();
        let cotan = cotan_stiffness(&triangle);
        let isotropic = anisotropic_stiffness(&triangle, &Matrix2::identity());
        let difference = (isotropic - cotan).amax() / cotan.amax();
        assert!(difference < 1e-13, "{lengths:?}: {difference:e}");
    }
}

#[test]
fn the_tensor_has_trace_two_and_the_edge_eigenvalues() {
    let g = Vector2::new(0.6, -0.8) * 3.0; // |g| = 3
    let d = tensor(&(g * g.transpose()), 1.5);
    let (g2, l2) = (9.0, 2.25);
    let across = 2.0 * l2 / (g2 + 2.0 * l2);
    let along = 2.0 * (g2 + l2) / (g2 + 2.0 * l2);
    let (n, t) = (g.normalize(), Vector2::new(0.8, 0.6));
    assert!((d.trace() - 2.0).abs() < 1e-15);
    assert!((d - d.transpose()).amax() == 0.0);
    assert!((d * n - across * n).norm() < 1e-15, "{d}");
    assert!((d * t - along * t).norm() < 1e-15, "{d}");
    // No structure: the identity.
    assert_eq!(tensor(&Matrix2::zeros(), 1.5), Matrix2::identity());
}

/// `u_Tᵀ E u_T` for the affine face-frame field `u(x) = a (n·x)` on `triangle`, with the DOFs in
/// the face frame (identity rotations).
fn affine_energy(triangle: &Triangle, tensor: Option<&Matrix2<f64>>, n: Vector2<f64>) -> f64 {
    let a = Vector2::new(0.7, -1.3);
    let rotations = [Matrix2::identity(); 3];
    let e = Regularizer::Covariant.element(triangle, &rotations, None, tensor);
    let p = triangle.layout();
    let x = Vector6::from_fn(|k, _| (a * n.dot(&p[k / 2]))[k % 2]);
    x.dot(&(e * x))
}

/// A straight image edge on one flat face: the image is linear, `I = g·x`, its structure the
/// face's [`Slab::structure_tensor`]. A field varying across the edge costs
/// `2λ²/(|g|² + 2λ²)` times its isotropic energy, one varying along it
/// `2(|g|² + λ²)/(|g|² + 2λ²)` times.
#[test]
fn across_an_edge_costs_less_along_it_more() {
    let triangle = Triangle::from_lengths([1.3, 0.9, 1.1]).unwrap();
    let p = triangle.layout();
    let g = Vector2::new(2.0, 1.0);
    let intensity: [f64; 3] = std::array::from_fn(|a| 0.4 + g.dot(&p[a]));
    let structure = {
        let grad = meshflow::fem::element::face_gradient(&triangle, intensity);
        grad * grad.transpose()
    };
    assert!((structure - g * g.transpose()).amax() < 1e-13);
    for lambda in [0.1, 1.0, 4.0] {
        let d = tensor(&structure, lambda);
        let (g2, l2) = (g.norm_squared(), lambda * lambda);
        let cases = [
            (g.normalize(), 2.0 * l2 / (g2 + 2.0 * l2)),
            (
                Vector2::new(-g.y, g.x).normalize(),
                2.0 * (g2 + l2) / (g2 + 2.0 * l2),
            ),
        ];
        for (n, factor) in cases {
            let isotropic = affine_energy(&triangle, None, n);
            let anisotropic = affine_energy(&triangle, Some(&d), n);
            let ratio = anisotropic / isotropic;
            assert!(
                (ratio - factor).abs() < 1e-12,
                "λ {lambda}: {ratio} ≠ {factor}"
            );
        }
    }
}

/// The strain element of the affine face-frame field `v(x) = B x + c` (identity rotations) is
/// `A tr(S D S)`, `S = Sym B`, zero on rotations; `D = Id` gives the isotropic strain element
/// bit for bit.
#[test]
fn the_anisotropic_strain_element_is_exact_on_affine_fields() {
    let triangle = Triangle::from_lengths([1.3, 0.9, 1.1]).unwrap();
    let rotations = [Matrix2::identity(); 3];
    let p = triangle.layout();
    let d = tensor(
        &(Vector2::new(1.0, -2.0) * Vector2::new(1.0, -2.0).transpose()),
        0.7,
    );
    let element = anisotropic_strain_element(&triangle, &rotations, &d);
    let energy = |b: Matrix2<f64>| {
        let c = Vector2::new(0.3, -0.2);
        let x = Vector6::from_fn(|k, _| (b * p[k / 2] + c)[k % 2]);
        x.dot(&(element * x))
    };
    let b = Matrix2::new(0.3, -1.1, 0.4, 0.7);
    let s: Matrix2<f64> = 0.5 * (b + b.transpose());
    let exact = triangle.area * (s * d * s).trace();
    assert!(
        (energy(b) - exact).abs() < 1e-13 * exact,
        "{} {exact}",
        energy(b)
    );
    assert!(energy(Matrix2::new(0.0, -1.0, 1.0, 0.0)).abs() < 1e-14);
    let twisted: [Matrix2<f64>; 3] =
        std::array::from_fn(|a| nalgebra::Rotation2::new(0.4 + a as f64).into_inner());
    // The isotropic strain element's formula, A/2 R_aᵀ [(g_a·g_b) I + g_b g_aᵀ] R_b, to the bit.
    let g = triangle.hat_gradients();
    let isotropic = strain_element(&triangle, &twisted);
    for (a, b) in (0..3).flat_map(|a| (0..3).map(move |b| (a, b))) {
        let face = Matrix2::identity() * g[a].dot(&g[b]) + g[b] * g[a].transpose();
        let block = twisted[a].transpose() * face * twisted[b] * (0.5 * triangle.area);
        assert_eq!(isotropic.fixed_view::<2, 2>(2 * a, 2 * b), block);
    }
}

/// The rotating-texture sphere, 3 frames.
fn sphere() -> MeshSequence {
    rotating_sphere(2, 3, 1.0, 0.1).unwrap().sequence
}

fn anisotropic(lambda: f64) -> FlowParams {
    FlowParams {
        anisotropy: Some(Anisotropy::new(lambda)),
        ..FlowParams::default()
    }
}

fn matrix(sequence: &MeshSequence, params: &FlowParams) -> meshflow::fem::SparseMatrix {
    FlowProblem::new(sequence, params)
        .unwrap()
        .system()
        .to_sparse()
}

fn tensors(sequence: &MeshSequence, params: &FlowParams) -> Vec<Vec<Matrix2<f64>>> {
    let problem = FlowProblem::new(sequence, params).unwrap();
    let slabs = problem.slabs();
    slabs
        .iter()
        .map(|s: &Slab| s.diffusion_tensors.clone().expect("anisotropic"))
        .collect()
}

#[test]
fn a_huge_lambda_gives_the_quadratic_system() {
    let sequence = sphere();
    let strain = Regularizer::Strain { dirichlet: 0.0 };
    let mixed = Regularizer::Strain { dirichlet: 0.4 };
    for regularizer in [Regularizer::Covariant, strain, mixed] {
        let with = |anisotropy: Option<f64>| FlowParams {
            regularizer,
            anisotropy: anisotropy.map(Anisotropy::new),
            beta: meshflow::flow::Weight::Relative(0.01),
            ..FlowParams::default()
        };
        let quadratic = matrix(&sequence, &with(None));
        // |∇I| is of order 1 on the unit sphere.
        let limit = matrix(&sequence, &with(Some(1e12)));
        let difference = relative_value_difference(&quadratic, &limit);
        assert!(difference < 1e-12, "{regularizer:?}: {difference:e}");
        // So with the weight in time too (`D_tt → 1`).
        let in_time = |lambda| FlowParams {
            anisotropy: Some(Anisotropy {
                in_time: true,
                ..Anisotropy::new(lambda)
            }),
            ..with(None)
        };
        let limit = matrix(&sequence, &in_time(1e12));
        let difference = relative_value_difference(&quadratic, &limit);
        assert!(
            difference < 1e-12,
            "{regularizer:?} in time: {difference:e}"
        );
        // and a moderate λ changes it, in time too.
        let moderate = matrix(&sequence, &with(Some(0.3)));
        assert!(relative_value_difference(&quadratic, &moderate) > 1e-3);
        let moderate_in_time = matrix(&sequence, &in_time(0.3));
        assert!(relative_value_difference(&moderate, &moderate_in_time) > 1e-4);
    }
}

/// The same sequence with every frame moved rigidly and its grey values times `scale`.
fn moved(sequence: &MeshSequence, scale: f64) -> MeshSequence {
    let frames = 0..sequence.n_frames();
    MeshSequence::new(
        sequence.mesh().clone(),
        frames
            .clone()
            .map(|k| rigid_motion(sequence.positions(k).unwrap()))
            .collect(),
        frames
            .map(|k| sequence.intensities(k).iter().map(|v| v * scale).collect())
            .collect(),
        Some(sequence.times().to_vec()),
    )
    .unwrap()
}

fn max_difference(a: &[Vec<Matrix2<f64>>], b: &[Vec<Matrix2<f64>>]) -> f64 {
    (a.iter().flatten().zip(b.iter().flatten()))
        .map(|(x, y)| (x - y).amax())
        .fold(0.0, f64::max)
}

#[test]
fn the_system_is_invariant_under_rigid_motion() {
    let sequence = sphere();
    let params = anisotropic(0.3);
    let difference = relative_value_difference(
        &matrix(&sequence, &params),
        &matrix(&moved(&sequence, 1.0), &params),
    );
    assert!(difference < 1e-12, "{difference:e}");
}

#[test]
fn scaling_grey_values_and_lambda_together_keeps_the_tensors() {
    let sequence = sphere();
    let original = tensors(&sequence, &anisotropic(0.3));
    let scaled = tensors(&moved(&sequence, 40.0), &anisotropic(12.0));
    let difference = max_difference(&original, &scaled);
    assert!(difference < 1e-12, "{difference:e}");
    // The tensors are not all the identity, and a different λ changes them.
    let identity = vec![vec![Matrix2::identity(); original[0].len()]; original.len()];
    assert!(max_difference(&original, &identity) > 0.1);
    let other = tensors(&moved(&sequence, 40.0), &anisotropic(3.0));
    assert!(max_difference(&original, &other) > 0.1);
}

#[test]
fn the_embedded_regularizer_and_bad_lambdas_are_refused() {
    let sequence = sphere();
    let params = FlowParams {
        regularizer: Regularizer::Embedded,
        ..anisotropic(1.0)
    };
    let error = FlowProblem::new(&sequence, &params).err().unwrap();
    assert!(error.to_string().contains("not the embedded"), "{error}");
    for lambda in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let error = FlowProblem::new(&sequence, &anisotropic(lambda))
            .err()
            .unwrap();
        assert!(error.to_string().contains("anisotropy lambda"), "{error}");
    }
}

#[test]
fn the_cli_solves_with_anisotropic_and_records_lambda() {
    let out = tempfile::tempdir().unwrap();
    let input = shipped("rotating_sphere");
    let (_, summary) = solve_and_summary(&input, out.path(), &["--anisotropic", "0.1"]);
    assert_eq!(summary["params"]["anisotropy"]["lambda"], 0.1, "{summary}");
    assert_eq!(
        summary["anisotropic_contrasts"],
        serde_json::json!(vec![0.1; 5])
    );
    let auto = ["--anisotropic", "auto", "--anisotropic-sigma", "0"];
    let (stdout, summary) = solve_and_summary(&input, out.path(), &auto);
    assert!(
        stdout.contains("λ = ") && stdout.contains("(auto)"),
        "{stdout}"
    );
    assert_eq!(
        summary["params"]["anisotropy"]["lambda"], "auto",
        "{summary}"
    );
    assert_eq!(summary["params"]["anisotropy"]["sigma"], 0.0, "{summary}");
    // 1.5 times the contrast-weighted median of the unsmoothed texture: of order 1 on the
    // unit sphere.
    let lambda = summary["anisotropic_contrasts"][0].as_f64().unwrap();
    assert!((0.05..5.0).contains(&lambda), "{summary}");
    let strain = ["--regularizer", "strain", "--anisotropic", "0.3"];
    let (_, summary) = solve_and_summary(&input, out.path(), &strain);
    assert_eq!(summary["params"]["anisotropy"]["in_time"], false);
    let in_time = ["--anisotropic", "0.3", "--anisotropic-in-time"];
    let (stdout, summary) = solve_and_summary(&input, out.path(), &in_time);
    assert!(stdout.contains("in time too"), "{stdout}");
    assert_eq!(summary["params"]["anisotropy"]["in_time"], true);
}

#[test]
fn the_cli_refuses_a_bad_lambda_and_the_embedded_regularizer() {
    let out = tempfile::tempdir().unwrap();
    let input = shipped("rotating_sphere");
    let out_dir = out.path().to_str().unwrap();
    for lambda in ["0", "-2", "NaN"] {
        let args = ["solve", &input, "--out", out_dir, "--anisotropic", lambda];
        meshflow_error(&args, "anisotropy lambda");
    }
    let args = ["solve", &input, "--out", out_dir, "--anisotropic", "sharp"];
    let done = common::meshflow(&args);
    assert_eq!(done.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(
        stderr.contains("'sharp' is neither auto nor a number"),
        "{stderr}"
    );
    let args = [
        "solve",
        &input,
        "--out",
        out_dir,
        "--anisotropic",
        "1",
        "--regularizer",
        "embedded",
    ];
    meshflow_error(&args, "not the embedded regularizer");
}

/// Robust smoothness reads the tensors: with a huge `ε` the Charbonnier penalty is the
/// quadratic one, so the robust spatial energy is the anisotropic solve's (the isotropic
/// density would give another).
#[test]
fn robust_smoothness_weighs_the_anisotropic_density() {
    let sequence = sphere();
    let solve = |params: &FlowParams| {
        let problem = FlowProblem::new(&sequence, params).unwrap();
        problem.solve(&|_| {}).unwrap().energy_terms.spatial
    };
    let quadratic = solve(&anisotropic(0.3));
    let robust = solve(&FlowParams {
        robust_smoothness: Some(Scale::Value(1e6)),
        ..anisotropic(0.3)
    });
    let isotropic = solve(&FlowParams::default());
    assert!(
        (robust - quadratic).abs() < 1e-6 * quadratic,
        "{robust} {quadratic}"
    );
    assert!((isotropic - quadratic).abs() > 1e-2 * quadratic);
}

/// A moving linear image `I = g·x − t` on a flat grid (a still one leaves its isophote
/// direction free), tensors without presmoothing (`σ = 0`), `β > 0`.
fn grid_tensors(
    channels: Vec<(f64, Vector2<f64>)>,
    lambda: Scale,
) -> (MeshSequence, Vec<Matrix2<f64>>) {
    let surface = meshflow::shapes::grid(4, 3, 2.0, 1.0);
    let frames = 2;
    let images = (0..frames)
        .map(|k| {
            (channels.iter())
                .map(|(_, g)| {
                    let at = |p: &nalgebra::Vector3<f64>| g.dot(&p.xy()) - 0.1 * k as f64;
                    surface.positions.iter().map(at).collect()
                })
                .collect()
        })
        .collect();
    let sequence = MeshSequence::with_images(
        surface.mesh().unwrap(),
        vec![surface.positions.clone(); frames],
        meshflow::flow::Images::from_channels(images),
        None,
    )
    .unwrap();
    let params = FlowParams {
        anisotropy: Some(Anisotropy {
            lambda,
            sigma: Some(0.0),
            in_time: false,
        }),
        channel_weights: Some(channels.iter().map(|(w, _)| *w).collect()),
        ..FlowParams::paper(1.0, 0.1, 1.0)
    };
    let tensors = tensors(&sequence, &params).remove(0);
    (sequence, tensors)
}

/// Every face of a slab with a linear image (one channel of weight `w`): the face-frame
/// gradient `G` is an eigenvector of `D` with `2λ²/(w|g|² + 2λ²)`, `tr D = 2`.
#[test]
fn the_slab_tensors_of_a_linear_image_have_its_edge_eigenvalues() {
    let (g, w, lambda) = (Vector2::new(1.5, -0.5), 2.0, 0.8);
    let (sequence, tensors) = grid_tensors(vec![(w, g)], Scale::Value(lambda));
    let geometry = sequence.slab_geometry(0).unwrap();
    let across = 2.0 * lambda * lambda / (w * g.norm_squared() + 2.0 * lambda * lambda);
    for (f, (face, d)) in sequence.mesh().faces().iter().zip(&tensors).enumerate() {
        let values = face.map(|v| g.dot(&sequence.positions(0).unwrap()[v as usize].xy()));
        let gradient = meshflow::fem::element::face_gradient(geometry.triangle(f), values);
        assert!((gradient.norm() - g.norm()).abs() < 1e-12);
        assert!(
            (d * gradient - across * gradient).norm() < 1e-12 * g.norm(),
            "{d}"
        );
        assert!((d.trace() - 2.0).abs() < 1e-14);
    }
}

/// `auto` takes 1.5 times the contrast-weighted median: a linear image has one contrast
/// `m = √w |g|` everywhere, so `λ = 1.5m` and `D` has the eigenvalues `9/11` across the edge
/// (`2λ²/(m² + 2λ²)`) and `13/11` along it (trace 2, determinant 117/121); grey values scaled
/// by 40 leave `D` as it is.
#[test]
fn auto_takes_the_weighted_median_contrast_and_ignores_grey_scaling() {
    let (g, w) = (Vector2::new(1.5, -0.5), 2.0);
    let (_, tensors) = grid_tensors(vec![(w, g)], Scale::Auto);
    let (_, scaled) = grid_tensors(vec![(w, 40.0 * g)], Scale::Auto);
    for (d, s) in tensors.iter().zip(&scaled) {
        assert!((d.trace() - 2.0).abs() < 1e-12, "{d}");
        assert!((d.determinant() - 117.0 / 121.0).abs() < 1e-12, "{d}");
        assert!((d - s).amax() < 1e-12, "{d} {s}");
    }
}

/// The data scale under the tensor: a linear image of contrast `c = √w |g|` has `S = c`
/// isotropically and `S² = 2λ²c² / (c² + 2λ²)` (the gradient energy the tensor smooths across)
/// with the tensor, whatever the presmoothing; `λ → ∞` gives `c` back.
#[test]
fn the_data_scale_counts_the_gradient_energy_the_tensor_smooths_across() {
    let (g, w, lambda) = (Vector2::new(1.5, -0.5), 2.0, 0.8);
    let c2 = w * g.norm_squared();
    let (sequence, _) = grid_tensors(vec![(w, g)], Scale::Value(lambda));
    let scale = |anisotropy: Option<f64>| {
        let params = FlowParams {
            anisotropy: anisotropy.map(Anisotropy::new),
            channel_weights: Some(vec![w]),
            // The linear image leaves its isophote direction free.
            beta: meshflow::flow::Weight::Relative(0.1),
            ..FlowParams::default()
        };
        FlowProblem::new(&sequence, &params)
            .unwrap()
            .scales()
            .gradient
    };
    let expected = (2.0 * lambda * lambda * c2 / (c2 + 2.0 * lambda * lambda)).sqrt();
    assert!(
        (scale(Some(lambda)) - expected).abs() < 1e-12,
        "{}",
        scale(Some(lambda))
    );
    assert!((scale(None) - c2.sqrt()).abs() < 1e-12);
    assert!((scale(Some(1e9)) - c2.sqrt()).abs() < 1e-9);
}

/// Two channels with crossing edges of the same weighted contrast (`w |g|²`) sum to an
/// isotropic structure: `D = Id` on every face.
#[test]
fn crossing_edges_of_two_channels_give_the_identity() {
    let channels = vec![(1.0, Vector2::new(2.0, 0.0)), (4.0, Vector2::new(0.0, 1.0))];
    let (_, tensors) = grid_tensors(channels, Scale::Value(0.5));
    for d in tensors {
        assert!((d - Matrix2::identity()).amax() < 1e-12, "{d}");
    }
}

/// The discrete anisotropic energy of a smooth field converges to the continuous one on the
/// unit sphere at second order: the image `I = z` (`g = ∇z`, `|g|² = 1 − z²`, P1 face
/// gradients, no presmoothing) and the gradient field `u = ∇(z²) = 2z(ẑ − z x)`, whose
/// covariant derivative `Hess(z²) = 2 g gᵀ − 2z² Id` has the eigenvalues `2 − 4z²` along `g`
/// and `−2z²` across it, so `tr(∇u D ∇uᵀ) = ((2 − 4z²)² 2λ² + 4z⁴ 2(1 − z² + λ²)) / (1 − z² + 2λ²)`,
/// integrated over the sphere as `2π ∫ dz`.
#[test]
fn the_anisotropic_energy_converges_at_second_order_on_the_sphere() {
    use meshflow::connection::{vertex_frames_in_r3, Connection};
    use meshflow::fem::element::face_gradient;
    use meshflow::geometry::IntrinsicGeometry;
    use meshflow::shapes::icosphere;
    use nalgebra::Vector3;
    let lambda: f64 = 0.4;
    let l2 = lambda * lambda;
    let density = |z: f64| {
        let across = (2.0 - 4.0 * z * z).powi(2) * 2.0 * l2;
        let along = 4.0 * z.powi(4) * 2.0 * (1.0 - z * z + l2);
        (across + along) / (1.0 - z * z + 2.0 * l2)
    };
    // Composite Simpson on [−1, 1]; the integrand is a smooth rational function of z.
    let n = 20_000;
    let h = 2.0 / n as f64;
    let simpson: f64 = (0..=n)
        .map(|k| {
            let weight = match k {
                0 => 1.0,
                k if k == n => 1.0,
                k if k % 2 == 1 => 4.0,
                _ => 2.0,
            };
            weight * density(-1.0 + k as f64 * h)
        })
        .sum::<f64>()
        * h
        / 3.0;
    let exact = 2.0 * std::f64::consts::PI * simpson;
    let field = |x: &Vector3<f64>| (Vector3::z() - x.z * x) * (2.0 * x.z);
    let mut errors = Vec::new();
    for level in 2..=5 {
        let sphere = icosphere(level);
        let mesh = sphere.mesh().unwrap();
        let geometry = IntrinsicGeometry::from_positions(&mesh, &sphere.positions).unwrap();
        let connection = Connection::new(&mesh, &geometry);
        let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &sphere.positions).unwrap();
        let u: Vec<_> = (sphere.positions.iter().zip(&frames))
            .map(|(x, p)| p.transpose() * field(x))
            .collect();
        let energy: f64 = (mesh.faces().iter().enumerate())
            .map(|(f, face)| {
                let triangle = geometry.triangle(f);
                let g = face_gradient(triangle, face.map(|v| sphere.positions[v as usize].z));
                let d = tensor(&(g * g.transpose()), lambda);
                let corner = face.map(|v| &frames[v as usize]);
                let e = Regularizer::Covariant.element(
                    triangle,
                    &connection.face_rotations(f),
                    Some(corner),
                    Some(&d),
                );
                let x = Vector6::from_fn(|k, _| u[face[k / 2] as usize][k % 2]);
                x.dot(&(e * x))
            })
            .sum();
        println!("level {level}: {energy:.6} against {exact:.6}");
        errors.push((energy - exact).abs());
    }
    for pair in errors.windows(2) {
        let order = (pair[0] / pair[1]).log2();
        assert!(order > 1.8, "{errors:?}");
    }
    assert!(errors[3] < 2e-3 * exact, "{errors:?} of {exact}");
}

/// A linear space-time image `I = g·x − b t` (one channel of weight `w`, no presmoothing) on a
/// still grid: every face of every slab has the structure `tr J = w|g|²`, rate `w b²`, and the
/// link of two slabs the space-time tensor's time entry
/// `3(w|g|² + λ²) / (2(w|g|² + w b²/α²) + 3λ²)`; the grey values and `λ` scaled alike leave it.
#[test]
fn the_time_entry_of_a_linear_space_time_image() {
    let (g, b, w, lambda, alpha) = (Vector2::new(1.5, -0.5), 0.7, 2.0, 0.8, 0.5);
    let entries = |scale: f64| {
        let surface = meshflow::shapes::grid(4, 3, 2.0, 1.0);
        let image = |k: usize| -> Vec<f64> {
            let at = |p: &nalgebra::Vector3<f64>| scale * (g.dot(&p.xy()) - b * k as f64);
            surface.positions.iter().map(at).collect()
        };
        let sequence = MeshSequence::with_images(
            surface.mesh().unwrap(),
            vec![surface.positions.clone(); 3],
            meshflow::flow::Images::from_channels((0..3).map(|k| vec![image(k)]).collect()),
            None,
        )
        .unwrap();
        let params = FlowParams {
            anisotropy: Some(Anisotropy {
                lambda: Scale::Value(scale * lambda),
                sigma: Some(0.0),
                in_time: true,
            }),
            channel_weights: Some(vec![w]),
            ..FlowParams::paper(alpha, 0.1, 1.0)
        };
        let problem = FlowProblem::new(&sequence, &params).unwrap();
        let slabs = problem.slabs();
        for structure in slabs.iter().flat_map(|s| s.space_time.clone().unwrap()) {
            let (contrast, rate) = (w * g.norm_squared(), w * b * b);
            let s2 = scale * scale;
            assert!((structure.contrast - s2 * contrast).abs() < 1e-12 * s2 * contrast);
            assert!((structure.rate - s2 * rate).abs() < 1e-12 * s2 * rate);
        }
        meshflow::flow::anisotropy::time_entries(&slabs[0], &slabs[1], alpha).unwrap()
    };
    let (c, l2) = (w * g.norm_squared(), lambda * lambda);
    let expected = 3.0 * (c + l2) / (2.0 * (c + w * b * b / (alpha * alpha)) + 3.0 * l2);
    assert!(expected < 0.9, "the case weakens the coupling: {expected}");
    for scale in [1.0, 40.0] {
        for entry in entries(scale) {
            assert!(
                (entry - expected).abs() < 1e-12,
                "{scale}: {entry} ≠ {expected}"
            );
        }
    }
}
