//! Charts: pulling flows back to parameter coordinates, and the chart's flat metric (the
//! "naive" model of Bauer, Grasmair & Kirisits' comparison).

use meshflow::chart::{Chart, ChartError};
use meshflow::flow::{FlowParams, FlowProblem, MeshSequence};
use meshflow::shapes::{grid, torus};
use nalgebra::{Rotation3, Vector2, Vector3};
use std::f64::consts::TAU;

/// A smooth periodic pattern on an `n1 × n2` grid translated by `shift` grid units.
fn periodic_pattern(n1: usize, n2: usize, shift: Vector2<f64>) -> Vec<f64> {
    (0..n1)
        .flat_map(|i| (0..n2).map(move |j| (i, j)))
        .map(|(i, j)| {
            let x = TAU * (i as f64 - shift.x) / n1 as f64;
            let y = TAU * (j as f64 - shift.y) / n2 as f64;
            (2.0 * x).sin() * (3.0 * y).cos() + 0.5 * (x + 2.0 * y).cos()
        })
        .collect()
}

/// Mean relative error of the naive (flat-torus) flow of a pattern translated by `velocity`
/// grid units per frame on an `n1 × n2` periodic grid, pulled back to grid units.
fn flat_torus_translation_error(n1: usize, n2: usize, velocity: Vector2<f64>) -> f64 {
    let mesh = torus(2.0, 1.0, n1, n2).mesh().unwrap();
    let chart = Chart::periodic_grid(n1, n2);
    let lengths = chart.flat_edge_lengths(&mesh).unwrap();
    let frames = 3;
    let sequence = MeshSequence::from_edge_lengths(
        mesh,
        vec![lengths; frames],
        (0..frames)
            .map(|k| periodic_pattern(n1, n2, velocity * k as f64))
            .collect(),
        None,
    )
    .unwrap();
    // γ large enough to fill in the aperture problem: a constant field costs no smoothness.
    let params = FlowParams::paper(1.0, 0.0, 1.0);
    let problem = FlowProblem::new(&sequence, &params).unwrap();
    let flow = problem.solve(&|_| {}).unwrap();
    let pulled = chart
        .pull_back(sequence.mesh(), &problem.slabs(), &flow.intrinsic)
        .unwrap();
    let errors: Vec<f64> = pulled
        .iter()
        .flatten()
        .map(|w| (w - velocity).norm() / velocity.norm())
        .collect();
    errors.iter().sum::<f64>() / errors.len() as f64
}

#[test]
fn flat_torus_recovers_a_translation_in_pixels_per_frame_to_second_order() {
    // The same pattern (periodic, so the same wavelengths in periods) on two grids; the velocity
    // scales with the grid so the motion is the same fraction of a period.
    let velocity = Vector2::new(0.3, -0.2);
    let coarse = flat_torus_translation_error(48, 40, velocity);
    let fine = flat_torus_translation_error(96, 80, 2.0 * velocity);
    // Measured: 5.7 % and 1.3 %, the O(h²) of the P1 image gradient.
    assert!(fine < 0.02, "fine-grid error {fine}");
    assert!(coarse / fine > 3.3, "order: {coarse} → {fine}");
}

#[test]
fn chart_of_a_flat_embedding_pulls_back_to_its_xy_components() {
    // A grid of unit squares in the plane: chart and embedding agree, so the pull-back equals
    // the R^3 push-forward's x and y components to round-off. The second frame folds the grid
    // by 70° along the line of edges x = 6: the slab geometry stays that of the flat grid.
    let (nx, ny) = (12, 9);
    let surface = grid(nx, ny, nx as f64, ny as f64);
    let mesh = surface.mesh().unwrap();
    let chart = Chart::grid(nx, ny);
    let hinge = Vector3::new(6.0, 0.0, 0.0);
    let fold = Rotation3::from_axis_angle(&Vector3::y_axis(), -70f64.to_radians());
    let moved: Vec<Vector3<f64>> = surface
        .positions
        .iter()
        .map(|&p| match p.x > 6.0 + 1e-9 {
            true => hinge + fold * (p - hinge),
            false => p,
        })
        .collect();
    assert!(moved.iter().any(|p| p.z > 3.0), "the fold leaves the plane");
    let intensity = |positions: &[Vector3<f64>], t: f64| -> Vec<f64> {
        positions
            .iter()
            .map(|p| ((p.x - 0.2 * t) * 0.7).sin() + ((p.y + 0.1 * t) * 0.5).cos())
            .collect()
    };
    let sequence = MeshSequence::new(
        mesh,
        vec![surface.positions.clone(), moved],
        vec![
            intensity(&surface.positions, 0.0),
            intensity(&surface.positions, 1.0),
        ],
        None,
    )
    .unwrap();
    let problem = FlowProblem::new(&sequence, &FlowParams::default()).unwrap();
    let flow = problem.solve(&|_| {}).unwrap();
    let vectors = &flow.vectors.as_ref().unwrap()[0];
    let pulled = &chart
        .pull_back(sequence.mesh(), &problem.slabs(), &flow.intrinsic)
        .unwrap()[0];
    let largest = vectors.iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(largest > 0.05, "a non-trivial flow: {largest}");
    for (w, v) in pulled.iter().zip(vectors) {
        assert!((w - v.xy()).norm() < 1e-12 * largest, "{w:?} vs {v:?}");
    }
}

#[test]
fn periodic_differences_take_the_nearest_image() {
    let chart = Chart::periodic_grid(10, 8);
    // Vertex (9, 7) to vertex (0, 0) is one step up and right across both seams.
    let (from, to) = (9 * 8 + 7, 0);
    assert_eq!(chart.difference(from, to), Vector2::new(1.0, 1.0));
    let mesh = torus(2.0, 1.0, 10, 8).mesh().unwrap();
    let lengths = chart.flat_edge_lengths(&mesh).unwrap();
    let diagonal = 2f64.sqrt();
    assert!(lengths
        .iter()
        .all(|&l| l == 1.0 || (l - diagonal).abs() < 1e-15));
    assert_eq!(
        lengths.iter().filter(|&&l| l == 1.0).count(),
        2 * 10 * 8,
        "two axis edges and one diagonal per grid cell"
    );
}

#[test]
fn bad_charts_are_typed_errors() {
    let mesh = torus(2.0, 1.0, 6, 5).mesh().unwrap();
    assert_eq!(
        Chart::periodic_grid(6, 4).face_edges(&mesh).unwrap_err(),
        ChartError::VertexCount {
            expected: 30,
            found: 24
        }
    );
    let mut coordinates = Chart::grid(2, 2).coordinates().to_vec();
    coordinates[4].y = f64::NAN;
    assert_eq!(
        Chart::new(coordinates, [None, None]).unwrap_err(),
        ChartError::NonFinite { vertex: 4 }
    );
    assert!(matches!(
        Chart::new(vec![Vector2::zeros()], [Some(0.0), None]),
        Err(ChartError::Period { axis: 0, .. })
    ));
}
