//! Scores at tracked points (`meshflow::accuracy::tracks`): the true flow of a turning texture
//! on a stretching sphere scores near zero at material points, the mesh's own motion is not
//! counted as flow, the zero flow scores exactly |r|; mutual-nearest-neighbour matching
//! recovers a shuffled, jittered point cloud; bad tracks are typed errors.

use meshflow::accuracy::{match_tracks, score_tracks, AccuracyError, Tracks};
use meshflow::synth::deforming_sphere;
use nalgebra::{Rotation3, Vector3};

const DT: f64 = 0.1;
const OMEGA: f64 = 0.5;
const STRAIN: f64 = 0.3;

/// `D(t) = diag(1 + εt, 1, 1/(1 + εt))`: the stretching of `synth::deforming_sphere`.
fn stretch(t: f64) -> Vector3<f64> {
    Vector3::new(1.0 + STRAIN * t, 1.0, 1.0 / (1.0 + STRAIN * t))
}

/// Points spread over the unit sphere (a Fibonacci lattice), away from the poles.
fn sphere_points(n: usize) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 0.9 - 1.8 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            Vector3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Material points of the texture turning at `omega` on the stretching sphere, per frame.
fn material_tracks(n_frames: usize, omega: f64) -> Tracks {
    let points = sphere_points(60);
    let frames = (0..n_frames)
        .map(|k| {
            let t = k as f64 * DT;
            let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), omega * t);
            points
                .iter()
                .map(|q| stretch(t).component_mul(&(turn * q)))
                .collect()
        })
        .collect();
    Tracks::new(frames).unwrap()
}

#[test]
fn true_flow_scores_near_zero_at_material_points() {
    let truth = deforming_sphere(4, 3, DT, OMEGA, STRAIN).unwrap();
    let tracks = material_tracks(3, OMEGA);
    let scores = score_tracks(&truth.sequence, &truth.flow, &tracks).unwrap();
    let s = scores.overall;
    assert_eq!(s.points, 120);
    // |r| ≈ ω Δt |x_⊥| ≈ 0.05 · 0.7; the true velocity misses the chord's second-order part and
    // P1 interpolation costs O(h²): a few per cent of the motion.
    assert!(
        s.zero_mean_endpoint > 0.025 && s.zero_mean_endpoint < 0.05,
        "{s:?}"
    );
    assert!(s.endpoint_ratio() < 0.04, "{s:?}");
    assert!(s.median_direction_degrees < 1.5, "{s:?}");
    assert!((s.median_speed_ratio - 1.0).abs() < 0.03, "{s:?}");
    assert!(s.median_distance < 2e-3, "points lie on the sphere: {s:?}");
}

#[test]
fn the_mesh_motion_is_not_flow() {
    // The texture does not turn: points move with the stretching mesh only.
    let truth = deforming_sphere(4, 3, DT, 0.0, STRAIN).unwrap();
    let tracks = material_tracks(3, 0.0);
    let zero = vec![vec![Vector3::zeros(); truth.sequence.mesh().n_vertices()]; 2];
    let scores = score_tracks(&truth.sequence, &zero, &tracks).unwrap();
    // The points move by up to ε Δt = 3 % of the radius, all of it the mesh's.
    let moved = (0..tracks.n_tracks())
        .map(|n| (tracks.position(1, n).unwrap() - tracks.position(0, n).unwrap()).norm())
        .fold(0.0, f64::max);
    assert!(moved > 0.02);
    assert!(
        scores.overall.mean_endpoint < 1e-3 * moved,
        "{:?}",
        scores.overall
    );
}

#[test]
fn zero_flow_scores_the_motion_itself() {
    let truth = deforming_sphere(3, 2, DT, OMEGA, 0.0).unwrap();
    let tracks = material_tracks(2, OMEGA);
    let zero = vec![vec![Vector3::zeros(); truth.sequence.mesh().n_vertices()]];
    let scores = score_tracks(&truth.sequence, &zero, &tracks).unwrap();
    for p in &scores.points {
        assert_eq!(p.endpoint, p.truth.norm());
        assert!(p.direction_degrees.is_nan() || p.direction_degrees == 90.0);
    }
    assert_eq!(scores.overall.endpoint_ratio(), 1.0);
    assert_eq!(scores.overall.median_speed_ratio, 0.0);
    assert_eq!(scores.slabs.len(), 1);
}

#[test]
fn untracked_points_are_left_out() {
    let truth = deforming_sphere(3, 3, DT, OMEGA, 0.0).unwrap();
    let full = material_tracks(3, OMEGA);
    let (shape, mut data) = full.to_array();
    // Point 0 untracked in frame 1: it takes part in neither slab.
    data[3 * full.n_tracks()..][..3].fill(f64::NAN);
    let tracks = Tracks::from_array(&shape, &data).unwrap();
    assert_eq!(tracks.pairs_per_slab(), vec![59, 59]);
    let scores = score_tracks(&truth.sequence, &truth.flow, &tracks).unwrap();
    assert_eq!(scores.slabs[0].points, 59);
    assert!(scores.points.iter().all(|p| p.track != 0));
}

/// Deterministic pseudo-random numbers in [0, 1).
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn mutual_nearest_neighbours_recover_a_shuffled_cloud() {
    let mut random = uniform(7);
    // A jittered grid of spacing 1: nearest neighbours at about 1.
    let first: Vec<Vector3<f64>> = (0..125)
        .map(|i| {
            let cell = Vector3::new((i % 5) as f64, ((i / 5) % 5) as f64, (i / 25) as f64);
            cell + 0.1 * Vector3::new(random(), random(), random())
        })
        .collect();
    // Frame 1: each point moved by at most 0.15, the order reversed, point 3 lost and a new
    // point far from all.
    let mut second: Vec<Vector3<f64>> = first
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != 3)
        .map(|(_, p)| p + 0.15 * Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5))
        .rev()
        .collect();
    second.push(Vector3::new(20.0, 20.0, 20.0));
    let tracks = match_tracks(&[first.clone(), second.clone()], None).unwrap();
    assert_eq!(tracks.n_tracks(), 126);
    assert_eq!(tracks.pairs_per_slab(), vec![124]);
    for (n, p) in first.iter().enumerate() {
        assert_eq!(tracks.position(0, n), Some(*p));
        let expected = match n {
            3 => None,
            n if n < 3 => Some(second[123 - n]),
            n => Some(second[124 - n]),
        };
        assert_eq!(tracks.position(1, n), expected, "point {n}");
    }
    assert_eq!(tracks.position(0, 125), None);
    assert_eq!(tracks.position(1, 125), Some(second[124]));
    // A bound below the motion matches nothing that moved more than it.
    let strict = match_tracks(&[first, second], Some(0.01)).unwrap();
    assert!(strict.pairs_per_slab()[0] < 5);
}

#[test]
fn bad_tracks_are_typed_errors() {
    let nan = f64::NAN;
    let error = Tracks::from_array(&[2, 1, 2], &[0.0; 4]).unwrap_err();
    assert!(matches!(error, AccuracyError::TracksShape(ref s) if s == &[2, 1, 2]));
    assert!(error.to_string().contains("(K, N, 3)"), "{error}");
    let error = Tracks::from_array(&[2, 1, 3], &[0.0, 0.0, 0.0, 1.0, nan, 1.0]).unwrap_err();
    assert!(
        matches!(error, AccuracyError::BadTrackPoint { frame: 1, point: 0 }),
        "{error}"
    );
    let error = Tracks::new(vec![vec![Vector3::zeros(); 2], vec![Vector3::zeros()]]).unwrap_err();
    assert!(
        error
            .to_string()
            .contains("frame 1 has 1 points, frame 0 has 2"),
        "{error}"
    );

    let truth = deforming_sphere(2, 3, DT, OMEGA, 0.0).unwrap();
    let two_frames = material_tracks(2, OMEGA);
    let error = score_tracks(&truth.sequence, &truth.flow, &two_frames).unwrap_err();
    assert!(
        error.to_string().contains("2 frames, the sequence has 3"),
        "{error}"
    );

    let points = vec![sphere_points(4), sphere_points(4)];
    let error = match_tracks(&points, Some(-1.0)).unwrap_err();
    assert!(matches!(error, AccuracyError::MatchDistance(d) if d == -1.0));
    let error = match_tracks(&[vec![Vector3::zeros()]], None).unwrap_err();
    assert!(matches!(error, AccuracyError::NoSpacing), "{error}");
    let error = match_tracks(&[vec![Vector3::new(inf(), 0.0, 0.0)]], None).unwrap_err();
    assert!(matches!(
        error,
        AccuracyError::BadTrackPoint { frame: 0, point: 0 }
    ));
}

fn inf() -> f64 {
    f64::INFINITY
}
