//! Straightest geodesics (`geometry::trace`): exact on flat meshes, great circles on a sphere
//! to discretization order, intrinsic (rigid motions and isometric bending change nothing).

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::geometry::{trace, IntrinsicGeometry, SurfacePoint};
use meshflow::mesh::Mesh;
use meshflow::shapes::{grid, icosphere, Surface};
use nalgebra::{Rotation3, Vector2, Vector3};

/// The R³ tangent `v` at a point of `face` in the face's layout frame (x along its first edge).
fn in_face_frame(surface: &Surface, face: usize, v: &Vector3<f64>) -> Vector2<f64> {
    let [a, b, c] = surface.faces[face].map(|i| surface.positions[i as usize]);
    let e1 = (b - a).normalize();
    let e2 = (b - a).cross(&(c - a)).cross(&e1).normalize();
    Vector2::new(v.dot(&e1), v.dot(&e2))
}

fn centroid(face: usize) -> SurfacePoint {
    SurfacePoint {
        face,
        barycentric: [1.0 / 3.0; 3],
    }
}

#[test]
fn on_a_flat_mesh_a_trace_is_the_straight_line_across_many_triangles() {
    let plane = grid(12, 10, 1.2, 1.0);
    let mesh = plane.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &plane.positions).unwrap();
    for (face, angle, length) in [(0, 0.3, 0.9), (5, 1.2, 0.7), (30, 0.05, 0.8)] {
        let start = centroid(face);
        let direction = Vector3::new(f64::cos(angle), f64::sin(angle), 0.0);
        let step = length * in_face_frame(&plane, face, &direction);
        let end = trace(&mesh, &geometry, start, step);
        let expected = start.position(&mesh, &plane.positions) + length * direction;
        let reached = end.point.position(&mesh, &plane.positions);
        assert!(!end.reached_boundary && (end.length - length).abs() < 1e-15);
        assert!(
            (reached - expected).norm() < 1e-12,
            "{reached:?} vs {expected:?}"
        );
    }
}

#[test]
fn a_trace_stops_at_the_boundary() {
    let plane = grid(4, 4, 1.0, 1.0);
    let mesh = plane.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &plane.positions).unwrap();
    let start = centroid(0);
    let step = 5.0 * in_face_frame(&plane, 0, &Vector3::x());
    let end = trace(&mesh, &geometry, start, step);
    let reached = end.point.position(&mesh, &plane.positions);
    let x0 = start.position(&mesh, &plane.positions);
    assert!(end.reached_boundary);
    assert!((reached.x - 1.0).abs() < 1e-12 && (reached.y - x0.y).abs() < 1e-12);
    assert!((end.length - (1.0 - x0.x)).abs() < 1e-12);
}

/// Along a great circle of the unit icosphere a length `L` is an angle `L`: the error decays
/// like `h²` (by more than 2.5× per refinement).
#[test]
fn on_a_sphere_a_trace_follows_a_great_circle() {
    let length = 2.0;
    let error = |level: u32| {
        let sphere = icosphere(level);
        let mesh = sphere.mesh().unwrap();
        let geometry = IntrinsicGeometry::from_positions(&mesh, &sphere.positions).unwrap();
        let start = centroid(7);
        let x0 = start.position(&mesh, &sphere.positions).normalize();
        let axis = x0.cross(&Vector3::z()).normalize();
        let direction = axis.cross(&x0);
        let step = length * in_face_frame(&sphere, 7, &direction);
        let end = trace(&mesh, &geometry, start, step);
        let reached = end.point.position(&mesh, &sphere.positions).normalize();
        let expected =
            Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), length) * x0;
        reached.angle(&expected)
    };
    let (coarse, fine) = (error(4), error(5));
    println!("angle errors {coarse:.2e}, {fine:.2e}");
    assert!(fine < 5e-3, "{fine}");
    assert!(fine < coarse / 2.5, "{coarse} → {fine}");
}

#[test]
fn traces_are_intrinsic() {
    let plane = grid(8, 8, 1.0, 1.0);
    let mesh = plane.mesh().unwrap();
    let turn = Rotation3::from_euler_angles(0.7, -0.4, 1.9);
    let moved: Vec<_> = plane
        .positions
        .iter()
        .map(|x| turn * x + Vector3::new(3.0, -1.0, 2.0))
        .collect();
    // A fold along the line x = 0.5 (a line of edges) by 70°: every length kept.
    let fold = Rotation3::from_axis_angle(&Vector3::y_axis(), 70f64.to_radians());
    let folded: Vec<_> = plane
        .positions
        .iter()
        .map(|x| match x.x > 0.5 {
            true => Vector3::new(0.5, 0.0, 0.0) + fold * (x - Vector3::new(0.5, 0.0, 0.0)),
            false => *x,
        })
        .collect();
    let traced = |positions: &[Vector3<f64>]| {
        let geometry = IntrinsicGeometry::from_positions(&mesh, positions).unwrap();
        trace(&mesh, &geometry, centroid(3), Vector2::new(0.6, 0.35))
    };
    let reference = traced(&plane.positions);
    for other in [traced(&moved), traced(&folded)] {
        assert_eq!(other.point.face, reference.point.face);
        for k in 0..3 {
            assert!((other.point.barycentric[k] - reference.point.barycentric[k]).abs() < 1e-12);
        }
    }
}

/// The 6×6 grid on the unit square with what a trace from a vertex needs.
struct FramedGrid {
    plane: Surface,
    mesh: Mesh,
    geometry: IntrinsicGeometry,
    connection: Connection,
    /// `P_i`, each vertex frame in R³.
    frames: Vec<nalgebra::Matrix3x2<f64>>,
}

impl FramedGrid {
    fn new() -> Self {
        let plane = grid(6, 6, 1.0, 1.0);
        let mesh: Mesh = plane.mesh().unwrap();
        let geometry = IntrinsicGeometry::from_positions(&mesh, &plane.positions).unwrap();
        let connection = Connection::new(&mesh, &geometry);
        let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &plane.positions).unwrap();
        Self {
            plane,
            mesh,
            geometry,
            connection,
            frames,
        }
    }

    /// Where the trace of the vertex-frame vector `u` from `vertex` ends, in R³.
    fn trace_end(&self, vertex: usize, u: Vector2<f64>) -> Vector3<f64> {
        let (mesh, geometry) = (&self.mesh, &self.geometry);
        let (start, step) = self
            .connection
            .vertex_trace_start(mesh, geometry, vertex, u);
        let end = trace(mesh, geometry, start, step);
        end.point.position(mesh, &self.plane.positions)
    }
}

/// From a vertex, a vertex-frame vector `u` goes where its R³ image `P_i u` (geometry-central's
/// frames) points, on a flat mesh exactly.
#[test]
fn a_trace_from_a_vertex_follows_its_frame_vector() {
    let plane = FramedGrid::new();
    let vertex = 3 * 7 + 3; // interior
    for angle in [0.1, 1.7, 3.0, 4.4, 6.0] {
        let u = 0.3 * Vector2::new(f64::cos(angle), f64::sin(angle));
        let expected = plane.plane.positions[vertex] + plane.frames[vertex] * u;
        let reached = plane.trace_end(vertex, u);
        assert!(
            (reached - expected).norm() < 1e-12,
            "angle {angle}: {reached:?} vs {expected:?}"
        );
    }
}

/// A trace from a boundary vertex along a boundary edge — what a flow tangent to the boundary
/// asks of warping, and what a direction pointing out of the surface is projected onto — runs
/// along the boundary through the next vertices, whichever way round-off tilts its direction:
/// directions within 1e-13 rad of the edge, inside or outside, land where the exact one does.
/// (A tilt of 1e-16 out of the surface used to end the trace at its start, or stall it at the
/// next boundary vertex: warping then jumped by the whole step under round-off.)
#[test]
fn a_trace_along_the_boundary_does_not_depend_on_round_off() {
    let plane = FramedGrid::new();
    // Crosses the next boundary vertex (cells are 1/6 wide).
    let length = 0.3;
    // Bottom edge (y = 0), then the left edge (x = 0), each from a vertex on it.
    for (vertex, along) in [(3, Vector3::x()), (3 * 7, Vector3::y())] {
        let tangent = plane.frames[vertex].transpose() * along;
        let psi = tangent.y.atan2(tangent.x);
        for sign in [1.0, -1.0] {
            for tilt in [0.0, 1e-16, -1e-16, 1e-13, -1e-13] {
                let angle = psi + tilt;
                let u = sign * length * Vector2::new(angle.cos(), angle.sin());
                let expected = plane.plane.positions[vertex] + sign * length * along;
                let reached = plane.trace_end(vertex, u);
                assert!(
                    (reached - expected).norm() < 1e-12,
                    "vertex {vertex}, sign {sign}, tilt {tilt:e}: {reached:?} vs {expected:?}"
                );
            }
        }
    }
}
