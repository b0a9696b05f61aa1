//! Intrinsic geometry: closed-form triangles, Gauss–Bonnet, and the degenerate-input errors.

mod common;

use meshflow::geometry::{edge_lengths, GeometryError, IntrinsicGeometry, Triangle};
use meshflow::mesh::Mesh;
use meshflow::shapes::{grid, icosphere, torus};
use nalgebra::{Vector2, Vector3};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_3, FRAC_PI_4, PI};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-14 * (1.0 + b.abs())
}

#[test]
fn right_isosceles_triangle() {
    // a = (0,0), b = (1,0), c = (0,1): l_ab = 1, l_bc = √2, l_ca = 1.
    let t = Triangle::from_lengths([1.0, 2f64.sqrt(), 1.0]).unwrap();
    assert!(close(t.area, 0.5));
    for (angle, exact) in t.angles.iter().zip([FRAC_PI_2, FRAC_PI_4, FRAC_PI_4]) {
        assert!(close(*angle, exact), "{:?}", t.angles);
    }
    assert!(t.cotans[0].abs() < 1e-15 && close(t.cotans[1], 1.0) && close(t.cotans[2], 1.0));
    let [a, b, c] = t.layout();
    assert_eq!((a, b), (Vector2::zeros(), Vector2::new(1.0, 0.0)));
    assert!((c - Vector2::new(0.0, 1.0)).norm() < 1e-15);
    let g = t.hat_gradients();
    for (grad, exact) in g.iter().zip([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]) {
        assert!((grad - Vector2::from(exact)).norm() < 1e-14, "{g:?}");
    }
    let first = t.first_edge_angles();
    assert!(close(first[1], 3.0 * FRAC_PI_4) && close(first[2], 3.0 * FRAC_PI_2));
}

#[test]
fn equilateral_triangle() {
    let t = Triangle::from_lengths([2.0; 3]).unwrap();
    assert!(close(t.area, 3f64.sqrt()));
    assert!(t.angles.iter().all(|&a| close(a, FRAC_PI_3)));
    assert!(t.cotans.iter().all(|&c| close(c, 1.0 / 3f64.sqrt())));
    // Gradients of the hat functions sum to zero and have length 1/height.
    let g = t.hat_gradients();
    assert!((g[0] + g[1] + g[2]).norm() < 1e-15);
    assert!(g.iter().all(|v| close(v.norm(), 1.0 / 3f64.sqrt())));
}

#[test]
fn needle_triangle_keeps_its_area() {
    // Sides 1, 1, c: area c/4 · √(4 − c²), where plain Heron loses every digit for tiny c.
    let c: f64 = 1e-9;
    let t = Triangle::from_lengths([1.0, 1.0, c]).unwrap();
    let exact = c / 4.0 * (4.0 - c * c).sqrt();
    assert!(
        (t.area - exact).abs() < 1e-14 * exact,
        "area {} vs {exact}",
        t.area
    );
}

#[test]
fn gauss_bonnet_holds_for_closed_meshes() {
    for (surface, chi) in [(icosphere(2), 2.0), (torus(3.0, 1.0, 16, 9), 0.0)] {
        let mesh = surface.mesh().unwrap();
        let geometry = IntrinsicGeometry::from_positions(&mesh, &surface.positions).unwrap();
        let total: f64 = geometry.angle_defects(&mesh).iter().sum();
        assert!(
            (total - 2.0 * PI * chi).abs() < 1e-10,
            "total curvature {total}"
        );
    }
    let patch = grid(3, 3, 1.0, 1.0);
    let mesh = patch.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &patch.positions).unwrap();
    // A flat square: no interior curvature, turning π/2 at each of the 4 corners.
    let total: f64 = geometry.angle_defects(&mesh).iter().sum();
    assert!((total - 2.0 * PI).abs() < 1e-12);
    assert!((geometry.total_area() - 1.0).abs() < 1e-14);
}

#[test]
fn intrinsic_input_equals_embedded_input() {
    let sphere = icosphere(1);
    let mesh = sphere.mesh().unwrap();
    let embedded = IntrinsicGeometry::from_positions(&mesh, &sphere.positions).unwrap();
    let lengths = edge_lengths(&mesh, &sphere.positions).unwrap();
    let intrinsic = IntrinsicGeometry::new(&mesh, lengths).unwrap();
    assert_eq!(embedded.triangles(), intrinsic.triangles());
}

fn square() -> (Mesh, Vec<Vector3<f64>>) {
    let s = grid(1, 1, 1.0, 1.0);
    (s.mesh().unwrap(), s.positions)
}

#[test]
fn rejects_collinear_face_and_names_it() {
    let (mesh, mut positions) = square();
    // Faces [0, 1, 3] and [0, 3, 2]; move vertex 2 onto the diagonal 0–3.
    positions[2] = Vector3::new(0.5, 0.5, 0.0);
    let err = IntrinsicGeometry::from_positions(&mesh, &positions).unwrap_err();
    assert!(
        matches!(
            err,
            GeometryError::DegenerateFace {
                face: 1,
                vertices: [0, 3, 2],
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("face 1"));
}

#[test]
fn rejects_lengths_breaking_the_triangle_inequality() {
    let (mesh, positions) = square();
    let mut lengths = edge_lengths(&mesh, &positions).unwrap();
    let diagonal = mesh.edges().iter().position(|&e| e == [0, 3]).unwrap();
    lengths[diagonal] = 2.5; // longer than the two unit sides together
    let err = IntrinsicGeometry::new(&mesh, lengths.clone()).unwrap_err();
    assert!(
        matches!(err, GeometryError::DegenerateFace { face: 0, .. }),
        "{err:?}"
    );
    // The check without angles (a sequence's frames) finds the same error.
    assert_eq!(
        IntrinsicGeometry::check(&mesh, &lengths)
            .unwrap_err()
            .to_string(),
        err.to_string()
    );
    lengths[diagonal] = 2f64.sqrt();
    assert!(IntrinsicGeometry::check(&mesh, &lengths).is_ok());
}

#[test]
fn rejects_zero_and_nan_lengths_and_positions() {
    let (mesh, mut positions) = square();
    let mut lengths = edge_lengths(&mesh, &positions).unwrap();
    lengths[2] = 0.0;
    let err = IntrinsicGeometry::new(&mesh, lengths.clone()).unwrap_err();
    assert!(
        matches!(err, GeometryError::InvalidEdgeLength { edge: 2, .. }),
        "{err:?}"
    );
    lengths[2] = f64::NAN;
    assert!(matches!(
        IntrinsicGeometry::new(&mesh, lengths).unwrap_err(),
        GeometryError::InvalidEdgeLength { edge: 2, .. }
    ));
    positions[1].y = f64::INFINITY;
    let err = IntrinsicGeometry::from_positions(&mesh, &positions).unwrap_err();
    assert!(
        matches!(err, GeometryError::NonFinitePosition { vertex: 1, .. }),
        "{err:?}"
    );
    // Coincident vertices: a zero-length edge.
    positions[1] = positions[0];
    assert!(matches!(
        IntrinsicGeometry::from_positions(&mesh, &positions).unwrap_err(),
        GeometryError::InvalidEdgeLength { .. }
    ));
}

#[test]
fn rejects_wrong_counts() {
    let (mesh, positions) = square();
    let err = IntrinsicGeometry::from_positions(&mesh, &positions[..3]).unwrap_err();
    assert_eq!(
        err,
        GeometryError::CountMismatch {
            what: "vertex positions",
            expected: 4,
            got: 3
        }
    );
    let err = IntrinsicGeometry::new(&mesh, vec![1.0; 4]).unwrap_err();
    assert_eq!(
        err,
        GeometryError::CountMismatch {
            what: "edge lengths",
            expected: 5,
            got: 4
        }
    );
}
