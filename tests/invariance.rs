//! Everything is intrinsic: rigid motions and edge-length-preserving folds change no operator.

mod common;

use common::{relative_value_difference, rigid_motion};
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem::{self, MassKind, SparseMatrix};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::mesh::Mesh;
use meshflow::shapes::{grid, icosphere, torus};
use nalgebra::{Rotation3, Vector3};

fn operators(mesh: &Mesh, positions: &[Vector3<f64>]) -> Vec<SparseMatrix> {
    let geometry = IntrinsicGeometry::from_positions(mesh, positions).unwrap();
    let connection = Connection::new(mesh, &geometry);
    vec![
        fem::cotan_laplacian(mesh, &geometry),
        fem::scalar_mass(mesh, &geometry, MassKind::Consistent),
        fem::connection_laplacian(mesh, &geometry, &connection),
        fem::vector_mass(mesh, &geometry, &connection, MassKind::Consistent),
        fem::vector_mass(mesh, &geometry, &connection, MassKind::Lumped),
        fem::face_gradient_operator(mesh, &geometry),
    ]
}

fn assert_same_operators(mesh: &Mesh, a: &[Vector3<f64>], b: &[Vector3<f64>]) {
    for (x, y) in operators(mesh, a).iter().zip(&operators(mesh, b)) {
        let difference = relative_value_difference(x, y);
        assert!(difference < 1e-12, "operator changed by {difference:e}");
    }
}

#[test]
fn rigid_motion_changes_no_operator() {
    for surface in [icosphere(2), torus(2.0, 0.7, 14, 9), grid(5, 4, 1.0, 0.8)] {
        let mesh = surface.mesh().unwrap();
        assert_same_operators(&mesh, &surface.positions, &rigid_motion(&surface.positions));
    }
}

#[test]
fn rigid_motion_rotates_the_frames() {
    let surface = icosphere(2);
    let mesh = surface.mesh().unwrap();
    let frames_of = |positions: &[Vector3<f64>]| {
        let geometry = IntrinsicGeometry::from_positions(&mesh, positions).unwrap();
        let connection = Connection::new(&mesh, &geometry);
        vertex_frames_in_r3(&mesh, &geometry, &connection, positions).unwrap()
    };
    let moved = rigid_motion(&surface.positions);
    let rotation = common::rigid_rotation();
    for (before, after) in frames_of(&surface.positions).iter().zip(frames_of(&moved)) {
        assert!((rotation * before - after).amax() < 1e-13);
    }
}

#[test]
fn folding_along_a_line_of_edges_changes_no_operator() {
    // Grid lines x = 0.2 k are lines of edges; fold the part x > 0.6 up by 100° about x = 0.6.
    let surface = grid(6, 4, 1.2, 0.8);
    let mesh = surface.mesh().unwrap();
    let hinge = Vector3::new(0.6, 0.0, 0.0);
    let fold = Rotation3::from_axis_angle(&Vector3::y_axis(), -100f64.to_radians());
    let folded: Vec<Vector3<f64>> = surface
        .positions
        .iter()
        .map(|&p| {
            if p.x > 0.6 + 1e-9 {
                hinge + fold * (p - hinge)
            } else {
                p
            }
        })
        .collect();
    assert!(
        folded.iter().any(|p| p.z > 0.5),
        "the fold leaves the plane"
    );
    assert_same_operators(&mesh, &surface.positions, &folded);
}
