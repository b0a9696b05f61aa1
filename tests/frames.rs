//! Vertex tangent frames in R^3 (docs/discretization.md §8): orthonormal on every mesh, equal to
//! geometry-central's `computeVertexTangentBasis` rule computed independently, exact on flat
//! meshes, and a push-forward that does not depend on the reference edge (§5).

mod common;

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::flow::{compute_flow, FlowParams, MeshSequence};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::mesh::Mesh;
use meshflow::shapes::{grid, icosphere, torus, Surface};
use meshflow::synth::rotating_sphere;
use nalgebra::{Matrix2, Matrix3x2, Rotation3, Unit, Vector2, Vector3};
use std::f64::consts::TAU;

fn frames_of(surface: &Surface) -> (Mesh, Vec<Matrix3x2<f64>>) {
    let mesh = surface.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &surface.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &surface.positions).unwrap();
    (mesh, frames)
}

/// A closed spike: apex high above a ring of 7 vertices, a bottom vertex just below it. The
/// apex has an angle defect of about 5.3 rad, the ring vertices are sharp folds.
fn spike() -> Surface {
    let n = 7;
    let mut positions = vec![Vector3::new(0.0, 0.0, 6.0), Vector3::new(0.1, 0.0, -0.3)];
    positions.extend((0..n).map(|k| {
        let a = TAU * k as f64 / n as f64;
        Vector3::new(a.cos(), 0.8 * a.sin(), 0.05 * (3.0 * a).sin())
    }));
    let ring = |k: usize| (2 + k % n) as u32;
    let faces = (0..n)
        .flat_map(|k| [[0, ring(k), ring(k + 1)], [1, ring(k + 1), ring(k)]])
        .collect();
    Surface { positions, faces }
}

/// A curved patch with boundary: a saddle over a jittered grid.
fn saddle() -> Surface {
    let mut surface = common::jittered_grid(7, 6, 1.4, 1.2, 0.05);
    for p in &mut surface.positions {
        p.z = 0.6 * (p.x - 0.7) * (p.y - 0.6) + 0.2 * (p.x * 2.0).sin();
    }
    surface
}

/// Curved (sphere, torus), sharp (spike) and with boundary (saddle).
fn test_surfaces() -> [(&'static str, Surface); 4] {
    [
        ("sphere", icosphere(2)),
        ("torus", torus(2.0, 0.6, 16, 9)),
        ("spike", spike()),
        ("saddle", saddle()),
    ]
}

fn assert_orthonormal(frames: &[Matrix3x2<f64>], what: &str) {
    for (i, p) in frames.iter().enumerate() {
        let defect = (p.transpose() * p - Matrix2::identity()).amax();
        assert!(defect < 1e-14, "{what}, vertex {i}: PᵀP − I = {defect:e}");
    }
}

#[test]
fn frames_are_orthonormal_on_curved_sharp_and_boundary_meshes() {
    for (what, surface) in test_surfaces() {
        let (_, frames) = frames_of(&surface);
        assert_orthonormal(&frames, what);
    }
}

#[test]
fn vectors_keep_their_length_at_sharp_vertices() {
    // The earlier corner-mean push-forward shrank vectors where the faces around a vertex point
    // in very different directions (to 0.31 of their length at a scan's sharp vertices).
    let surface = spike();
    let (mesh, frames) = frames_of(&surface);
    let geometry = IntrinsicGeometry::from_positions(&mesh, &surface.positions).unwrap();
    assert!(geometry.angle_defects(&mesh)[0] > 5.0, "a sharp apex");
    for u in [Vector2::new(1.0, 0.0), Vector2::new(0.3, -0.8)] {
        for p in &frames {
            assert!(((p * u).norm() - u.norm()).abs() < 1e-14);
        }
    }
}

/// geometry-central's rule written out independently: corner angles by `acos` of positions,
/// polar angles accumulated along the fan with the scale 2π/Θ (1 on the boundary), rotations by
/// nalgebra's axis-angle.
fn reference_frames(mesh: &Mesh, x: &[Vector3<f64>]) -> Vec<Matrix3x2<f64>> {
    let corner_angle = |f: usize, c: usize| {
        let face = mesh.faces()[f];
        let at = x[face[c] as usize];
        let a = (x[face[(c + 1) % 3] as usize] - at).normalize();
        let b = (x[face[(c + 2) % 3] as usize] - at).normalize();
        a.dot(&b).clamp(-1.0, 1.0).acos()
    };
    (0..mesh.n_vertices())
        .map(|i| {
            let fan = mesh.vertex_fan(i);
            let angles: Vec<f64> = fan
                .iter()
                .map(|c| corner_angle(c.face as usize, c.local as usize))
                .collect();
            let normal = fan
                .iter()
                .zip(&angles)
                .map(|(c, &angle)| {
                    let [a, b, d] = mesh.faces()[c.face as usize].map(|v| x[v as usize]);
                    angle * (b - a).cross(&(d - a)).normalize()
                })
                .sum::<Vector3<f64>>()
                .normalize();
            let total: f64 = angles.iter().sum();
            let scale = if mesh.is_boundary_vertex(i) {
                1.0
            } else {
                TAU / total
            };
            let mut heads: Vec<u32> = fan
                .iter()
                .map(|c| mesh.faces()[c.face as usize][(c.local as usize + 1) % 3])
                .collect();
            if mesh.is_boundary_vertex(i) {
                let last = fan[fan.len() - 1];
                heads.push(mesh.faces()[last.face as usize][(last.local as usize + 2) % 3]);
            }
            let mut swept = 0.0;
            let mut sum = Vector3::zeros();
            for (k, &j) in heads.iter().enumerate() {
                let edge = x[j as usize] - x[i];
                let tangent = edge - normal * normal.dot(&edge);
                let turn = Rotation3::from_axis_angle(&Unit::new_unchecked(normal), -scale * swept);
                sum += turn * tangent;
                swept += angles.get(k).copied().unwrap_or(0.0);
            }
            let e1 = sum.normalize();
            Matrix3x2::from_columns(&[e1, normal.cross(&e1)])
        })
        .collect()
}

#[test]
fn frames_follow_geometry_centrals_vertex_tangent_basis() {
    for (what, surface) in test_surfaces() {
        let (mesh, frames) = frames_of(&surface);
        let expected = reference_frames(&mesh, &surface.positions);
        for (i, (p, q)) in frames.iter().zip(&expected).enumerate() {
            let difference = (p - q).amax();
            assert!(difference < 1e-12, "{what}, vertex {i}: {difference:e}");
        }
    }
}

#[test]
fn on_a_flat_mesh_every_edge_sits_at_its_polar_angle() {
    let surface = common::jittered_grid(6, 5, 1.2, 1.0, 0.06);
    let mesh = surface.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &surface.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &surface.positions).unwrap();
    let mut n_edges = 0;
    for (i, p) in frames.iter().enumerate() {
        for (j, angle) in connection.outgoing_edges(&mesh, &geometry, i) {
            let edge = (surface.positions[j as usize] - surface.positions[i]).normalize();
            let components = p.transpose() * edge;
            let polar = Vector2::new(angle.cos(), angle.sin());
            assert!((components - polar).norm() < 1e-13, "edge {i}→{j}");
            n_edges += 1;
        }
    }
    // Every halfedge once, plus the closing edge of each boundary vertex's fan.
    assert_eq!(n_edges, 2 * mesh.n_edges());
}

#[test]
fn interior_fans_start_in_the_lowest_numbered_face() {
    let mut surface = torus(2.0, 0.6, 9, 7);
    surface.faces.reverse();
    surface.faces.rotate_left(17);
    let mesh = surface.mesh().unwrap();
    for i in 0..mesh.n_vertices() {
        let lowest = (0..mesh.n_faces())
            .find(|&f| mesh.faces()[f].contains(&(i as u32)))
            .unwrap();
        assert_eq!(mesh.vertex_fan(i)[0].face as usize, lowest, "vertex {i}");
    }
    // On a surface with boundary, boundary fans still start at the boundary edge.
    let patch = grid(4, 3, 1.0, 1.0).mesh().unwrap();
    for i in (0..patch.n_vertices()).filter(|&i| patch.is_boundary_vertex(i)) {
        assert!(patch.is_boundary_halfedge(patch.vertex_fan(i)[0].first_halfedge()));
    }
}

#[test]
fn the_r3_flow_does_not_depend_on_the_reference_edges() {
    // Listing the faces in another order moves every interior vertex's reference edge: the
    // intrinsic components turn, the vectors in R^3 stay.
    let truth = rotating_sphere(2, 3, 0.1, 0.5).unwrap();
    let original = &truth.sequence;
    let mut faces = original.mesh().faces().to_vec();
    faces.reverse();
    let n_frames = original.n_frames();
    let reordered = MeshSequence::new(
        Mesh::new(original.mesh().n_vertices(), faces).unwrap(),
        (0..n_frames)
            .map(|k| original.positions(k).unwrap().to_vec())
            .collect(),
        (0..n_frames)
            .map(|k| original.intensities(k).to_vec())
            .collect(),
        Some(original.times().to_vec()),
    )
    .unwrap();
    let params = FlowParams::paper(1.0, 0.0, 1e-3);
    let (a, b) = (
        compute_flow(original, &params).unwrap(),
        compute_flow(&reordered, &params).unwrap(),
    );
    let largest = a.vectors.as_ref().unwrap()[0]
        .iter()
        .map(|u| u.norm())
        .fold(0.0, f64::max);
    assert!(largest > 0.01, "a non-trivial flow");
    let mut largest_intrinsic_change: f64 = 0.0;
    for s in 0..original.n_slabs() {
        let (ua, ub) = (
            &a.vectors.as_ref().unwrap()[s],
            &b.vectors.as_ref().unwrap()[s],
        );
        for (i, (x, y)) in ua.iter().zip(ub).enumerate() {
            assert!((x - y).norm() < 1e-9 * largest, "slab {s}, vertex {i}");
        }
        for (x, y) in a.intrinsic[s].iter().zip(&b.intrinsic[s]) {
            largest_intrinsic_change = largest_intrinsic_change.max((x - y).norm());
        }
    }
    assert!(
        largest_intrinsic_change > 0.1 * largest,
        "the reference edges did move: {largest_intrinsic_change}"
    );
}
