//! One frame's surface as a spatial query structure: rays along vertex normals, closest
//! points, and grey values sampled where they land.
//!
//! parry3d-f64's `TriMesh` (a BVH over the triangles) answers both queries; it speaks glam, so
//! points are converted at this boundary and nowhere else. The tracker
//! ([`crate::track`]), the trajectories ([`crate::flow::advect()`]), the scores at tracked points
//! ([`crate::accuracy`]) and the surface fit ([`crate::surface`]) all locate points on frames,
//! so this sits below them.

use crate::geometry::SurfacePoint;
use nalgebra::Vector3;
use parry3d_f64::math::Vector;
use parry3d_f64::query::{PointQueryWithLocation, Ray, RayCast};
use parry3d_f64::shape::TriMesh;
use std::collections::HashSet;

/// A frame's triangles that the spatial query structure refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("frame {frame}: {detail}")]
pub struct SpatialError {
    pub frame: usize,
    pub detail: String,
}

/// A frame's triangles with a grey value per vertex.
pub struct FrameSurface {
    positions: Vec<Vector3<f64>>,
    faces: Vec<[u32; 3]>,
    intensity: Vec<f64>,
    bvh: TriMesh,
    /// Edges `(min, max)` with one triangle only, and their vertices.
    boundary: HashSet<(u32, u32)>,
    boundary_vertices: HashSet<u32>,
}

/// A point on a frame's surface: where it is and the grey value there (the mesh-independent
/// counterpart of [`SurfacePoint`], which names a face and barycentric coordinates).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceSample {
    pub position: Vector3<f64>,
    pub intensity: f64,
}

impl FrameSurface {
    /// `frame` is the frame's number, for errors.
    pub fn new(
        frame: usize,
        positions: &[Vector3<f64>],
        faces: &[[u32; 3]],
        intensity: &[f64],
    ) -> Result<Self, SpatialError> {
        let vertices = positions.iter().map(to_glam).collect();
        let bvh = TriMesh::new(vertices, faces.to_vec()).map_err(|e| SpatialError {
            frame,
            detail: e.to_string(),
        })?;
        let mut edges: Vec<(u32, u32)> = (faces.iter())
            .flat_map(|f| (0..3).map(move |c| (f[c].min(f[(c + 1) % 3]), f[c].max(f[(c + 1) % 3]))))
            .collect();
        edges.sort_unstable();
        let boundary: HashSet<(u32, u32)> = (edges.chunk_by(|a, b| a == b))
            .filter(|run| run.len() == 1)
            .map(|run| run[0])
            .collect();
        let boundary_vertices = boundary.iter().flat_map(|&(a, b)| [a, b]).collect();
        Ok(Self {
            positions: positions.to_vec(),
            faces: faces.to_vec(),
            intensity: intensity.to_vec(),
            bvh,
            boundary,
            boundary_vertices,
        })
    }

    /// The nearer of the first hits of the rays from `origin` along `+direction` and
    /// `−direction` (a unit vector), within `max_distance`.
    pub fn nearest_hit_along(
        &self,
        origin: &Vector3<f64>,
        direction: &Vector3<f64>,
        max_distance: f64,
    ) -> Option<SurfaceSample> {
        [1.0, -1.0]
            .into_iter()
            .filter_map(|sign| {
                let ray = Ray::new(to_glam(origin), to_glam(&(sign * direction)));
                let hit = self
                    .bvh
                    .cast_local_ray_and_get_normal(&ray, max_distance, false)?;
                Some((hit.time_of_impact, sign, hit.subshape))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(t, sign, face)| self.sample(face as usize, origin + sign * t * direction))
    }

    /// The closest point of the surface to `point`.
    pub fn closest_point(&self, point: &Vector3<f64>) -> SurfaceSample {
        let (face, position) = self.project(point);
        self.sample(face, position)
    }

    /// The closest point of the surface to `point` as a face and barycentric coordinates.
    pub fn locate(&self, point: &Vector3<f64>) -> SurfacePoint {
        self.locate_with_distance(point).0
    }

    /// [`Self::locate`] and the distance from `point` to that closest point, from one query.
    pub fn locate_with_distance(&self, point: &Vector3<f64>) -> (SurfacePoint, f64) {
        let (face, position) = self.project(point);
        let located = SurfacePoint {
            face,
            barycentric: self.barycentric_on(face, &position),
        };
        (located, (position - point).norm())
    }

    /// The closest point of the surface to `point` and the unit normal of the triangle it lies
    /// on (oriented as that triangle's corners are).
    pub fn closest_point_and_normal(&self, point: &Vector3<f64>) -> (SurfaceSample, Vector3<f64>) {
        let (face, position) = self.project(point);
        let [a, b, c] = self.faces[face].map(|v| self.positions[v as usize]);
        let normal = (b - a).cross(&(c - a));
        let unit = normal.try_normalize(0.0).unwrap_or_else(Vector3::z);
        (self.sample(face, position), unit)
    }

    /// Whether the closest point of the surface to `point` lies on its boundary.
    pub fn closest_point_is_on_boundary(&self, point: &Vector3<f64>) -> bool {
        let (face, position) = self.project(point);
        let weights = self.barycentric_on(face, &position);
        let corners = self.faces[face];
        let on_edge = (0..3).any(|c| {
            let (a, b) = (corners[(c + 1) % 3], corners[(c + 2) % 3]);
            weights[c] <= 1e-9 && self.boundary.contains(&(a.min(b), a.max(b)))
        });
        // At a corner, the face found need not be the one along the boundary.
        let at_boundary_vertex = (0..3)
            .any(|c| weights[c] >= 1.0 - 1e-9 && self.boundary_vertices.contains(&corners[c]));
        on_edge || at_boundary_vertex
    }

    /// The face and position of the closest point of the surface to `point`.
    fn project(&self, point: &Vector3<f64>) -> (usize, Vector3<f64>) {
        let (projection, (face, _)) = self
            .bvh
            .project_local_point_and_get_location(to_glam(point), false);
        let p = projection.point;
        (face as usize, Vector3::new(p.x, p.y, p.z))
    }

    fn barycentric_on(&self, face: usize, position: &Vector3<f64>) -> [f64; 3] {
        barycentric(
            self.faces[face].map(|v| self.positions[v as usize]),
            position,
        )
    }

    /// The grey value at `position` on face `face`: barycentric interpolation of its corners.
    fn sample(&self, face: usize, position: Vector3<f64>) -> SurfaceSample {
        let weights = self.barycentric_on(face, &position);
        let intensity = self.faces[face]
            .iter()
            .zip(weights)
            .map(|(&v, w)| w * self.intensity[v as usize])
            .sum();
        SurfaceSample {
            position,
            intensity,
        }
    }
}

/// Barycentric coordinates of the projection of `p` onto the plane of triangle `x`, clamped to
/// the triangle (a point found on a triangle lies in it up to round-off); the centroid for a
/// degenerate triangle.
pub fn barycentric(x: [Vector3<f64>; 3], p: &Vector3<f64>) -> [f64; 3] {
    let (e1, e2, d) = (x[1] - x[0], x[2] - x[0], p - x[0]);
    let (a, b, c) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
    let determinant = a * c - b * b;
    if determinant <= f64::EPSILON * a * c {
        return [1.0 / 3.0; 3];
    }
    let (d1, d2) = (d.dot(&e1), d.dot(&e2));
    let v = ((c * d1 - b * d2) / determinant).clamp(0.0, 1.0);
    let w = ((a * d2 - b * d1) / determinant).clamp(0.0, 1.0);
    let total = (1.0 - v - w).max(0.0) + v + w;
    [(1.0 - v - w).max(0.0) / total, v / total, w / total]
}

fn to_glam(p: &Vector3<f64>) -> Vector {
    Vector::new(p.x, p.y, p.z)
}
