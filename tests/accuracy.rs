//! Error measures against a known flow, and the synthetic sequences that have one: AE, EPE,
//! direction error, relative EPE and speed ratio by hand, exact zeros and symmetry, area and
//! duration weighting, the zero flow's scores, typed errors; the flow converges to the truth
//! under refinement; the deforming sphere's true flow satisfies brightness constancy.

use meshflow::accuracy::{angular_error, compare_flows, compare_result, endpoint_error};
use meshflow::accuracy::{direction_error_degrees, AccuracyError, FlowErrors};
use meshflow::flow::{compute_flow, FlowParams, MeshSequence, Weight};
use meshflow::mesh::Mesh;
use meshflow::synth::{deforming_sphere, rotating_sphere, texture, GroundTruth};
use nalgebra::{Rotation3, Vector3};

type Flow = Vec<Vec<Vector3<f64>>>;

#[test]
fn hand_computed_pairs() {
    let (x, y, zero) = (Vector3::x(), Vector3::y(), Vector3::zeros());
    // (1,0,0,1)·(0,1,0,1) = 1, both of length √2: cos = 1/2.
    assert!((angular_error(&x, &y).to_degrees() - 60.0).abs() < 1e-12);
    assert!((endpoint_error(&x, &y) - 2f64.sqrt()).abs() < 1e-15);
    // (1,0,0,1)·(0,0,0,1) = 1, lengths √2 and 1: cos = 1/√2.
    assert!((angular_error(&x, &zero).to_degrees() - 45.0).abs() < 1e-12);
    assert_eq!(endpoint_error(&x, &zero), 1.0);
    // Opposite vectors (0, 0, ±a): each (0, 0, ±a, 1) is atan(1/a) off the z-axis.
    let far = Vector3::new(0.0, 0.0, 1e4);
    let expected = 180.0 - 2.0 * 1e-4f64.atan().to_degrees();
    assert!((angular_error(&far, &-far).to_degrees() - expected).abs() < 1e-10);
    // A tiny difference is resolved (acos of a cosine rounded to 1 would give 0 or 1.5e-8).
    let tiny = Vector3::new(1e-9, 0.0, 0.0);
    assert!((angular_error(&tiny, &zero) / 1e-9 - 1.0).abs() < 1e-9);
    // Directions: the angle between the vectors themselves; a zero vector has none (90°).
    assert!((direction_error_degrees(&x, &y) - 90.0).abs() < 1e-12);
    assert!((direction_error_degrees(&(3.0 * x), &(x + y)) - 45.0).abs() < 1e-12);
    assert_eq!(direction_error_degrees(&(2.0 * x), &x), 0.0);
    assert_eq!(direction_error_degrees(&zero, &x), 90.0);
}

#[test]
fn angular_error_is_the_acos_formula() {
    let vectors: Vec<Vector3<f64>> = (0..40)
        .map(|k| {
            let t = k as f64;
            Vector3::new(
                (1.3 * t).sin(),
                (0.7 * t).cos() * 2.0,
                (0.31 * t).sin() - 0.2,
            )
        })
        .collect();
    for u in &vectors {
        for v in &vectors {
            let cosine =
                (u.dot(v) + 1.0) / ((u.norm_squared() + 1.0) * (v.norm_squared() + 1.0)).sqrt();
            let angle = angular_error(u, v);
            // acos is ill-conditioned near 0; compare where it is not.
            if angle > 1e-3 {
                assert!((angle - cosine.acos()).abs() < 1e-12, "{u} {v}");
            }
        }
    }
}

fn solved(truth: &GroundTruth, gamma: f64) -> Flow {
    compute_flow(&truth.sequence, &FlowParams::paper(1.0, 0.0, gamma))
        .unwrap()
        .vectors
        .unwrap()
}

fn all_values(errors: &FlowErrors) -> Vec<f64> {
    let mut values: Vec<f64> = errors.angular_degrees.concat();
    values.extend(errors.endpoint.concat());
    values.extend(errors.direction_degrees.concat());
    values.extend(errors.slabs.iter().flat_map(|s| {
        [
            s.mean_angular_degrees,
            s.mean_endpoint,
            s.max_angular_degrees,
            s.max_endpoint,
        ]
    }));
    values.extend([
        errors.mean_angular_degrees,
        errors.mean_endpoint,
        errors.mean_direction_degrees,
        errors.relative_endpoint,
        errors.max_angular_degrees,
        errors.max_endpoint,
    ]);
    values
}

#[test]
fn a_flow_against_itself_has_exactly_zero_error_and_errors_are_symmetric() {
    let truth = deforming_sphere(2, 4, 0.1, 0.5, 0.5).unwrap();
    let computed = solved(&truth, 1e-2);
    for flow in [&computed, &truth.flow] {
        let errors = compare_flows(&truth.sequence, flow, flow).unwrap();
        // Zero, or NaN for the direction where the truth does not move (near the poles).
        assert!(all_values(&errors).iter().all(|&e| e == 0.0 || e.is_nan()));
        assert_eq!(errors.median_speed_ratio, 1.0);
    }
    let forward = compare_flows(&truth.sequence, &computed, &truth.flow).unwrap();
    let backward = compare_flows(&truth.sequence, &truth.flow, &computed).unwrap();
    // AE, EPE and their maxima are symmetric; direction, relative EPE and ratio are not.
    let symmetric = |e: &FlowErrors| {
        let mut values = e.angular_degrees.concat();
        values.extend(e.endpoint.concat());
        values.extend([
            e.mean_angular_degrees,
            e.mean_endpoint,
            e.max_angular_degrees,
        ]);
        values
    };
    assert_eq!(symmetric(&forward), symmetric(&backward));
    assert!(
        forward.mean_angular_degrees > 1.0,
        "{}",
        forward.mean_angular_degrees
    );
    assert_eq!(forward.slabs.len(), 3);
    assert_eq!(forward.angular_degrees.len(), 3);
    assert!(forward.angular_degrees.iter().all(|s| s.len() == 162));
}

/// A unit square of two triangles (0,1,2), (0,2,3): lumped areas 1/3 at the diagonal's ends 0
/// and 2, 1/6 at 1 and 3. Frames at t = 0, 1, 3; the third frame is twice as large, so slab 1
/// (mean lengths) is a square of side 1.5.
fn square_sequence() -> MeshSequence {
    let unit = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(1.0, 1.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
    ];
    let double = unit.iter().map(|p| 2.0 * p).collect();
    let mesh = Mesh::new(4, vec![[0, 1, 2], [0, 2, 3]]).unwrap();
    MeshSequence::new(
        mesh,
        vec![unit.clone(), unit, double],
        vec![vec![0.1, 0.2, 0.3, 0.4]; 3],
        Some(vec![0.0, 1.0, 3.0]),
    )
    .unwrap()
}

#[test]
fn means_are_weighted_by_vertex_area_and_slab_duration() {
    let sequence = square_sequence();
    let truth: Flow = vec![vec![Vector3::zeros(); 4]; 2];
    let mut computed = truth.clone();
    computed[0][1] = Vector3::new(1.0, 0.0, 0.0); // area 1/6 of 1
    computed[1][0] = Vector3::new(0.0, 2.0, 0.0); // area 0.75 of 2.25
    let errors = compare_flows(&sequence, &computed, &truth).unwrap();

    let close = |a: f64, b: f64| (a - b).abs() < 1e-12 * b.abs().max(1.0);
    let slabs = &errors.slabs;
    assert!(close(slabs[0].area, 1.0) && close(slabs[1].area, 2.25));
    assert_eq!((slabs[0].duration, slabs[1].duration), (1.0, 2.0));
    assert!(close(slabs[0].mean_endpoint, 1.0 / 6.0));
    assert!(close(slabs[1].mean_endpoint, 2.0 / 3.0));
    // Space-time: (Δt_0 Σ a e + Δt_1 Σ a e) / (Δt_0 A_0 + Δt_1 A_1) = (1/6 + 2·1.5) / 5.5.
    assert!(
        close(errors.mean_endpoint, 19.0 / 33.0),
        "{}",
        errors.mean_endpoint
    );
    // The plain mean over vertices would be 3/8, the plain mean of slab means 5/12.
    assert!(!close(errors.mean_endpoint, 3.0 / 8.0) && !close(errors.mean_endpoint, 5.0 / 12.0));
    // AE on displacements in mean edge lengths: ℓ_0 = (4 + √2)/5 for the unit square and its
    // diagonal, ℓ_1 = 1.5 ℓ_0; |u| Δt / ℓ is 1/ℓ_0 in slab 0 and 2·2/ℓ_1 in slab 1.
    let l0 = (4.0 + 2f64.sqrt()) / 5.0;
    assert!(close(slabs[0].edge_length, l0) && close(slabs[1].edge_length, 1.5 * l0));
    let (ae0, ae1) = (
        (1.0 / l0).atan().to_degrees(),
        (4.0 / (1.5 * l0)).atan().to_degrees(),
    );
    assert!(close(slabs[0].mean_angular_degrees, ae0 / 6.0));
    assert!(close(slabs[1].mean_angular_degrees, ae1 / 3.0));
    assert!(close(
        errors.mean_angular_degrees,
        (ae0 / 6.0 + 2.0 * 0.75 * ae1) / 5.5
    ));
    assert!(close(errors.max_angular_degrees, ae1) && close(errors.max_endpoint, 2.0));
    assert!(close(slabs[0].max_angular_degrees, ae0) && slabs[0].max_endpoint == 1.0);
    assert_eq!(errors.endpoint[0], vec![0.0, 1.0, 0.0, 0.0]);
    assert_eq!(errors.endpoint[1], vec![2.0, 0.0, 0.0, 0.0]);
    // The truth is zero: it moves nowhere, and nothing is relative to it.
    assert!(errors.direction_degrees.concat().iter().all(|e| e.is_nan()));
    assert!(errors.mean_direction_degrees.is_nan() && errors.relative_endpoint.is_nan());
    assert_eq!(errors.moving_fraction, 0.0);
}

#[test]
fn direction_relative_endpoint_and_speed_ratio_by_hand() {
    // Square sequence (weights Δt a: slab 0 [1/3, 1/6, 1/3, 1/6], slab 1 [1.5, 0.75, 1.5,
    // 0.75]); the truth moves along x at unit speed, except vertex 3 in slab 0, at 0.05: below
    // 10 % of the slab's largest speed, so not moving.
    let sequence = square_sequence();
    let x = Vector3::x();
    let mut truth: Flow = vec![vec![x; 4]; 2];
    truth[0][3] = 0.05 * x;
    let computed: Flow = vec![
        vec![x, x, Vector3::new(0.0, 2.0, 0.0), Vector3::zeros()],
        vec![1.5 * x; 4],
    ];
    let errors = compare_flows(&sequence, &computed, &truth).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12 * b.abs().max(1.0);
    assert_eq!(errors.direction_degrees[0][..3], [0.0, 0.0, 90.0]);
    assert!(errors.direction_degrees[0][3].is_nan());
    assert_eq!(errors.direction_degrees[1], vec![0.0; 4]);
    // Moving weight 1/3 + 1/6 + 1/3 + 4.5 of 5.5; only vertex 2 of slab 0 errs, by 90°.
    let moving = 5.0 / 6.0 + 4.5;
    assert!(close(errors.moving_fraction, moving / 5.5));
    assert!(close(errors.mean_direction_degrees, (90.0 / 3.0) / moving));
    // ∫∫|u − v| / ∫∫|v|: √5 at vertex 2 and 0.05 at vertex 3 of slab 0, 0.5 everywhere in slab 1.
    let numerator = 5f64.sqrt() / 3.0 + 0.05 / 6.0 + 0.5 * 4.5;
    let denominator = 5.0 / 6.0 + 0.05 / 6.0 + 4.5;
    assert!(close(errors.relative_endpoint, numerator / denominator));
    // Ratios 1 (weight 1/2), 2 (1/3), 1.5 (4.5): the weighted median is 1.5.
    assert_eq!(errors.median_speed_ratio, 1.5);
    assert!(close(
        errors.slabs[0].mean_direction_degrees,
        30.0 / (5.0 / 6.0)
    ));

    let zero = FlowErrors::zero_flow(&sequence, &truth).unwrap();
    assert!(close(zero.mean_direction_degrees, 90.0));
    assert!(close(zero.relative_endpoint, 1.0));
    assert_eq!(zero.median_speed_ratio, 0.0);
    assert!(zero.mean_angular_degrees > errors.mean_angular_degrees);
}

#[test]
fn mismatched_or_non_finite_flows_and_intrinsic_sequences_are_typed_errors() {
    let sequence = square_sequence();
    let good: Flow = vec![vec![Vector3::zeros(); 4]; 2];
    let compare = |computed: &Flow, truth: &Flow| compare_flows(&sequence, computed, truth);

    assert_eq!(
        compare(&good, &good[..1].to_vec()),
        Err(AccuracyError::SlabCount {
            which: "true",
            expected: 2,
            got: 1
        })
    );
    let mut short = good.clone();
    short[1].pop();
    assert_eq!(
        compare(&short, &good),
        Err(AccuracyError::VertexCount {
            which: "computed",
            slab: 1,
            expected: 4,
            got: 3
        })
    );
    let mut nan = good.clone();
    nan[1][2].y = f64::NAN;
    let error = compare(&good, &nan).unwrap_err();
    assert!(matches!(
        error,
        AccuracyError::NonFinite {
            which: "true",
            slab: 1,
            vertex: 2,
            ..
        }
    ));
    assert!(error.to_string().contains("slab 1, vertex 2"), "{error}");

    let intrinsic = MeshSequence::from_edge_lengths(
        sequence.mesh().clone(),
        (0..3).map(|k| sequence.edge_lengths(k).to_vec()).collect(),
        (0..3).map(|k| sequence.intensities(k).to_vec()).collect(),
        None,
    )
    .unwrap();
    assert_eq!(
        compare_flows(&intrinsic, &good, &good),
        Err(AccuracyError::Intrinsic)
    );
    let flow = compute_flow(
        &intrinsic,
        &FlowParams {
            beta: Weight::Value(1e-3),
            ..FlowParams::default()
        },
    )
    .unwrap();
    assert_eq!(
        compare_result(&intrinsic, &flow, &good),
        Err(AccuracyError::Intrinsic)
    );
}

/// Relative EPE and mean direction error at icosphere levels 2, 3, 4, γ = 1e-3, three
/// frames 0.1 apart, ω = 0.5. (The AE, on displacements in mean edge lengths, is not a
/// convergence measure: refining shrinks the edge lengths, so the same velocity error weighs
/// more.)
fn errors_under_refinement(strain: f64) -> Vec<(f64, f64)> {
    (2..=4)
        .map(|level| {
            let truth = deforming_sphere(level, 3, 0.1, 0.5, strain).unwrap();
            let params = FlowParams::paper(1.0, 0.0, 1e-3);
            let flow = compute_flow(&truth.sequence, &params).unwrap();
            let errors = compare_result(&truth.sequence, &flow, &truth.flow).unwrap();
            (errors.relative_endpoint, errors.mean_direction_degrees)
        })
        .collect()
}

fn assert_converges(errors: &[(f64, f64)], finest_relative_endpoint: f64) {
    for pair in errors.windows(2) {
        let ((e0, d0), (e1, d1)) = (pair[0], pair[1]);
        assert!(e0 > 1.5 * e1 && d0 > 1.5 * d1, "{errors:?}");
    }
    assert!(errors[2].0 < finest_relative_endpoint, "{errors:?}");
}

#[test]
fn rotating_sphere_error_falls_under_refinement() {
    let errors = errors_under_refinement(0.0);
    println!("rotating sphere, (relative EPE, direction error°), levels 2-4: {errors:.4?}");
    // Measured: (0.507, 14.2°), (0.299, 7.0°), (0.192, 4.2°).
    assert_converges(&errors, 0.2);
}

#[test]
fn deforming_sphere_error_falls_under_refinement() {
    let errors = errors_under_refinement(0.5);
    println!("deforming sphere, (relative EPE, direction error°), levels 2-4: {errors:.4?}");
    // Measured: (0.504, 14.1°), (0.299, 7.2°), (0.194, 4.4°).
    assert_converges(&errors, 0.2);
}

/// `D(t)⁻¹ x` for `D(t) = diag(1 + εt, 1, 1/(1 + εt))`, written out here independently of synth.
fn undeform(strain: f64, t: f64, x: &Vector3<f64>) -> Vector3<f64> {
    let e = 1.0 + strain * t;
    Vector3::new(x.x / e, x.y, x.z * e)
}

/// The deforming sphere's image at time `t` and point `x` of the surface, from its definition:
/// `texture(R_z(−ωt) D(t)⁻¹ x)`.
fn image(omega: f64, strain: f64, t: f64, x: &Vector3<f64>) -> f64 {
    let back = Rotation3::from_axis_angle(&Vector3::z_axis(), -omega * t);
    texture(&(back * undeform(strain, t, x)))
}

/// Largest `|∂_t I + dI(u)|` over the vertices of the deforming sphere's frame at `t = 0.5`
/// (level 2, ω = ε = 0.5, frames `dt` apart) for the flow `flow(truth, s, i)`: `∂_t I` is the
/// forward difference of the sequence's grey values, `dI(u)` a central difference (step `h`)
/// of the image along `u`.
fn brightness_residual(dt: f64, flow: impl Fn(&GroundTruth, usize, usize) -> Vector3<f64>) -> f64 {
    let (omega, strain, h) = (0.5, 0.5, 1e-5);
    let s = (0.5 / dt).round() as usize;
    let truth = deforming_sphere(2, s + 2, dt, omega, strain).unwrap();
    let sequence = &truth.sequence;
    let t = sequence.times()[s];
    assert!((t - 0.5).abs() < 1e-12);
    let positions = sequence.positions(s).unwrap();
    (0..positions.len())
        .map(|i| {
            let (x, u) = (positions[i], flow(&truth, s, i));
            let derivative = (image(omega, strain, t, &(x + h * u))
                - image(omega, strain, t, &(x - h * u)))
                / (2.0 * h);
            let rate = (sequence.intensities(s + 1)[i] - sequence.intensities(s)[i]) / dt;
            (rate + derivative).abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn deforming_sphere_truth_satisfies_brightness_constancy() {
    let true_flow = |truth: &GroundTruth, s: usize, i: usize| truth.flow[s][i];
    let (coarse, fine) = (
        brightness_residual(0.02, true_flow),
        brightness_residual(0.01, true_flow),
    );
    println!("brightness residual: dt 0.02 -> {coarse:.3e}, dt 0.01 -> {fine:.3e}");
    // O(dt): halving the step halves the residual. Measured: 3.30e-3, 1.65e-3.
    assert!(coarse < 0.2 * 0.02 && fine < 0.2 * 0.01, "{coarse} {fine}");
    assert!((coarse / fine - 2.0).abs() < 0.1, "{coarse} {fine}");

    // Control: the rotation field at the deformed positions (not the push-forward of the rest
    // sphere's) is wrong by O(1), however small the step.
    let naive = |truth: &GroundTruth, s: usize, i: usize| {
        Vector3::new(0.0, 0.0, 0.5).cross(&truth.sequence.positions(s).unwrap()[i])
    };
    let wrong = brightness_residual(0.01, naive);
    println!("brightness residual of the naive field: {wrong:.3e}"); // measured 5.4e-2
    assert!(wrong > 20.0 * fine, "{wrong} vs {fine}");
}

#[test]
fn deforming_sphere_flow_is_tangent_and_rotating_sphere_is_its_rigid_case() {
    let (omega, strain, dt) = (0.5, 0.5, 0.25);
    let truth = deforming_sphere(2, 3, dt, omega, strain).unwrap();
    for (s, flow) in truth.flow.iter().enumerate() {
        let t = s as f64 * dt;
        for (x, u) in truth.sequence.positions(s).unwrap().iter().zip(flow) {
            // The ellipsoid |D⁻¹x| = 1 has normal D⁻²x at x; u is tangent to it.
            let normal = undeform(strain, t, &undeform(strain, t, x));
            assert!(u.dot(&normal).abs() < 1e-14, "{u} {normal}");
            assert!((undeform(strain, t, x).norm() - 1.0).abs() < 1e-12);
        }
    }
    // The frames really deform: frame 2's x extent is (1 + 2 ε dt) times frame 0's.
    let extent = |k: usize| {
        truth
            .sequence
            .positions(k)
            .unwrap()
            .iter()
            .map(|p| p.x)
            .fold(0.0, f64::max)
    };
    assert!((extent(2) / extent(0) - (1.0 + strain * 2.0 * dt)).abs() < 1e-12);

    // Without strain: a still sphere, the same flow ω ẑ × x in every slab.
    let rigid = rotating_sphere(2, 3, dt, omega).unwrap();
    for k in 0..3 {
        assert_eq!(
            rigid.sequence.positions(k).unwrap(),
            rigid.sequence.positions(0).unwrap()
        );
    }
    assert_eq!(rigid.flow[0], rigid.flow[1]);
    for (x, u) in rigid
        .sequence
        .positions(0)
        .unwrap()
        .iter()
        .zip(&rigid.flow[1])
    {
        assert_eq!(*u, Vector3::new(0.0, 0.0, omega).cross(x));
    }
}
