//! Straightest geodesics: following a tangent direction across triangles for a given length,
//! from edge lengths alone (the discrete exponential map of Polthier & Schmies, "Straightest
//! geodesics on polyhedral surfaces", 1998).
//!
//! Inside a face the path is a straight segment of the face's layout
//! ([`Triangle::layout`](super::Triangle::layout)); where it meets an edge, the neighbouring
//! face is unfolded across that edge (a rigid motion of the plane, so the angle between the path
//! and the edge is kept) and the path goes on. Barycentric coordinates move linearly along a
//! segment, `b(t) = b + t (∇φ · d)`, so the exit edge is the first coordinate to reach 0.
//!
//! A point is a face and barycentric coordinates: with fixed connectivity that is a point of
//! every frame of a sequence, which is how a flow reads the next frame's image where it leads.
//! Through a vertex the path leaves by one of the edges it reaches at once (a tie: no angle is
//! split), which is straightest up to the vertex's angle defect.

use super::IntrinsicGeometry;
use crate::mesh::Mesh;
use nalgebra::{Vector2, Vector3};

/// A point of the surface: a face and its barycentric coordinates (corners `a, b, c`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub face: usize,
    pub barycentric: [f64; 3],
}

impl SurfacePoint {
    /// Vertex `local` (0, 1, 2) of `face`.
    pub fn corner(face: usize, local: usize) -> Self {
        let mut barycentric = [0.0; 3];
        barycentric[local] = 1.0;
        Self { face, barycentric }
    }

    /// Its position in a frame: `Σ b_k x_k` over the face's vertices.
    pub fn position(&self, mesh: &Mesh, positions: &[Vector3<f64>]) -> Vector3<f64> {
        let face = mesh.faces()[self.face];
        (0..3)
            .map(|k| self.barycentric[k] * positions[face[k] as usize])
            .sum()
    }

    /// `Σ b_k v_k` of per-vertex values, e.g. grey values.
    pub fn interpolate(&self, mesh: &Mesh, values: &[f64]) -> f64 {
        let face = mesh.faces()[self.face];
        (0..3)
            .map(|k| self.barycentric[k] * values[face[k] as usize])
            .sum()
    }
}

/// Where a trace ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceEnd {
    pub point: SurfacePoint,
    /// The unit direction of travel at the end, in the end face's layout frame.
    pub direction: Vector2<f64>,
    /// Length travelled: the requested one, or less where the path reached the boundary.
    pub length: f64,
    pub reached_boundary: bool,
}

/// How far (the sine of the angle) a direction must point out through an edge for a path to
/// leave through it; closer to parallel, it runs along the edge. Round-off tilts a direction
/// meant to run along an edge by ~1e-16 either way — a flow tangent to the boundary, a
/// direction projected onto a boundary edge ([`crate::connection::Connection::vertex_trace_start`])
/// — and a path that left through a boundary edge at once, or stalled at the next vertex,
/// would jump by its whole length with that round-off (warping on open surfaces did:
/// `tests/trace.rs`). A path within 1e-12 of parallel strays from the edge by at most 1e-12
/// of its length.
const PARALLEL: f64 = 1e-12;

/// Follows `step` (a vector in `start.face`'s layout frame; its length is the distance to go)
/// from `start` along the straightest geodesic.
pub fn trace(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    start: SurfacePoint,
    step: Vector2<f64>,
) -> TraceEnd {
    let total = step.norm();
    let mut end = TraceEnd {
        point: start,
        direction: step.try_normalize(0.0).unwrap_or_else(Vector2::x),
        length: 0.0,
        reached_boundary: false,
    };
    // Each face is crossed at most a few times by one straight path; the bound only guards
    // against a cycle of zero-length crossings in floating point.
    let mut entry_edge = None;
    for _ in 0..4 * mesh.n_faces() + 8 {
        let remaining = total - end.length;
        let gradients = geometry.triangle(end.point.face).hat_gradients();
        let rates = gradients.map(|g| g.dot(&end.direction));
        let b = end.point.barycentric;
        // Corner k's coordinate reaches 0 on the edge opposite k, halfedge (k + 1) % 3.
        let exit = (0..3)
            .filter(|&k| rates[k] < -PARALLEL * gradients[k].norm())
            .filter(|&k| Some((k + 1) % 3) != entry_edge)
            .map(|k| (k, (-b[k] / rates[k]).max(0.0)))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        let advance = |t: f64| std::array::from_fn(|k| (b[k] + t * rates[k]).max(0.0));
        match exit {
            Some((k, t)) if t < remaining => {
                let mut at_edge: [f64; 3] = advance(t);
                at_edge[k] = 0.0;
                end.length += t;
                let edge = (k + 1) % 3;
                match cross(mesh, geometry, end.point.face, edge, at_edge, end.direction) {
                    Some((point, direction, entered)) => {
                        end.point = point;
                        end.direction = direction;
                        entry_edge = Some(entered);
                    }
                    None => {
                        end.point.barycentric = normalized(at_edge);
                        end.reached_boundary = true;
                        return end;
                    }
                }
            }
            _ => {
                end.point.barycentric = normalized(advance(remaining));
                end.length = total;
                return end;
            }
        }
    }
    end
}

/// The same point and direction in the face across local edge `edge` of `face` (`None` on the
/// boundary), with the local edge index by which the path entered it.
fn cross(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    face: usize,
    edge: usize,
    barycentric: [f64; 3],
    direction: Vector2<f64>,
) -> Option<(SurfacePoint, Vector2<f64>, usize)> {
    let twin = mesh.twin(3 * face + edge)?;
    let (next, next_edge) = (twin / 3, twin % 3);
    // Halfedge u→v in `face` is v→u in `next`: the position along the edge carries over.
    let (u, v) = (edge, (edge + 1) % 3);
    let along = barycentric[v] / (barycentric[u] + barycentric[v]);
    let mut next_barycentric = [0.0; 3];
    next_barycentric[next_edge] = along;
    next_barycentric[(next_edge + 1) % 3] = 1.0 - along;
    // Unfolding is a rigid motion: the angle from the directed edge u→v to the path is kept.
    let here = geometry.triangle(face).layout();
    let there = geometry.triangle(next).layout();
    let edge_here = here[v] - here[u];
    let edge_there = there[next_edge] - there[(next_edge + 1) % 3];
    let (e, e_there) = (edge_here.normalize(), edge_there.normalize());
    let (cos, sin) = (e.dot(&direction), e.perp(&direction));
    let turned = cos * e_there + sin * Vector2::new(-e_there.y, e_there.x);
    let point = SurfacePoint {
        face: next,
        barycentric: next_barycentric,
    };
    Some((point, turned, next_edge))
}

fn normalized(b: [f64; 3]) -> [f64; 3] {
    let sum: f64 = b.iter().sum();
    b.map(|x| x / sum)
}
