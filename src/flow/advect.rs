//! Trajectories: points carried through the slabs by a computed flow (the paper's Appendix A
//! remark on reparametrizing the surface by the flow), and the material's velocity in R³, the
//! mesh's own motion plus the flow ([`tissue_velocity`]; `velocity.npy`).
//!
//! A point is a face and barycentric coordinates, so it is a point of every frame. In slab `s`
//! the flow at a point of face `T` is the P1 interpolation of the vertex vectors carried into
//! `T`'s frame (`docs/discretization.md` §4–5),
//!
//! ```text
//! u_T(p) = Σ_k b_k R_{T,k} u_{s,k}
//! ```
//!
//! and the point moves along the straightest geodesic of the slab's geometry
//! ([`crate::geometry::trace`]) in `SUBSTEPS` explicit steps of `Δt_s / SUBSTEPS`, each with the
//! flow where it stands (a single step would follow the tangent geodesic, which leaves a curved
//! path such as a circle of latitude at second order in the step).

use super::{FlowError, MeshSequence};
use crate::connection::Connection;
use crate::geometry::{trace, IntrinsicGeometry, SurfacePoint};
use crate::spatial::FrameSurface;
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;

/// Explicit substeps per slab.
pub const SUBSTEPS: usize = 4;

/// Where each seed is at every frame: `points[k][n]` on frame `k` (`k = 0..K`).
#[derive(Clone, Debug)]
pub struct Trajectories {
    pub points: Vec<Vec<SurfacePoint>>,
    /// Seeds whose path reached the boundary (they stay there).
    pub reached_boundary: Vec<bool>,
}

impl Trajectories {
    /// `positions[k][n]`: the points in R³ on their frames (`None` for an intrinsic sequence).
    pub fn positions(&self, sequence: &MeshSequence) -> Option<Vec<Vec<Vector3<f64>>>> {
        (0..self.points.len())
            .map(|k| {
                let x = sequence.positions(k)?;
                Some(
                    self.points[k]
                        .iter()
                        .map(|p| p.position(sequence.mesh(), x))
                        .collect(),
                )
            })
            .collect()
    }
}

impl Trajectories {
    /// `I_k` at the points of frame `k`: for vertex seeds, the image of the sequence
    /// reparametrized by the flow, which a perfect flow makes static.
    pub fn intensities(&self, sequence: &MeshSequence) -> Vec<Vec<f64>> {
        self.points
            .iter()
            .enumerate()
            .map(|(k, points)| {
                let image = sequence.intensities(k);
                points
                    .iter()
                    .map(|p| p.interpolate(sequence.mesh(), image))
                    .collect()
            })
            .collect()
    }
}

/// Every vertex of the mesh as a seed (its first corner).
pub fn vertex_seeds(sequence: &MeshSequence) -> Vec<SurfacePoint> {
    let mesh = sequence.mesh();
    (0..mesh.n_vertices())
        .map(|i| {
            let corner = mesh.vertex_fan(i)[0];
            SurfacePoint::corner(corner.face as usize, corner.local as usize)
        })
        .collect()
}

/// Seeds at the closest points of frame 0's surface to `points` (in R³; e.g. cells to follow).
/// Fails for an intrinsic sequence (no surface to find them on) and for non-finite points,
/// naming the point.
pub fn closest_seeds(
    sequence: &MeshSequence,
    points: &[Vector3<f64>],
) -> Result<Vec<SurfacePoint>, crate::Error> {
    let positions = sequence.positions(0).ok_or(FlowError::Intrinsic)?;
    if let Some(i) = points.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(FlowError::NonFinitePoint { point: i }.into());
    }
    let faces = sequence.mesh().faces();
    let surface = FrameSurface::new(0, positions, faces, sequence.intensities(0))?;
    Ok(points.iter().map(|p| surface.locate(p)).collect())
}

/// Carries `seeds` (points of frame 0) through all slabs along `flow` (`flow[s][i]`: the
/// vertex-frame vectors of slab `s`, as [`super::FlowResult::intrinsic`]).
pub fn advect(
    sequence: &MeshSequence,
    flow: &[Vec<Vector2<f64>>],
    seeds: &[SurfacePoint],
) -> Result<Trajectories, FlowError> {
    let mesh = sequence.mesh();
    if flow.len() != sequence.n_slabs() {
        return Err(FlowError::CountMismatch {
            what: "flow slabs",
            expected: sequence.n_slabs(),
            got: flow.len(),
        });
    }
    let mut points = vec![seeds.to_vec()];
    let mut reached_boundary = vec![false; seeds.len()];
    for (s, u) in flow.iter().enumerate() {
        if u.len() != mesh.n_vertices() {
            return Err(FlowError::CountMismatch {
                what: "flow vectors per slab",
                expected: mesh.n_vertices(),
                got: u.len(),
            });
        }
        let geometry = sequence.slab_geometry(s)?;
        let connection = Connection::new(mesh, &geometry);
        let slab = SlabFlow {
            mesh,
            geometry: &geometry,
            connection: &connection,
            u,
            dt: sequence.slab_duration(s) / SUBSTEPS as f64,
        };
        let moved: Vec<(SurfacePoint, bool)> = points[s]
            .par_iter()
            .map(|&p| (0..SUBSTEPS).fold((p, false), |(p, hit), _| slab.step(p, hit)))
            .collect();
        reached_boundary
            .iter_mut()
            .zip(&moved)
            .for_each(|(r, (_, hit))| *r |= hit);
        points.push(moved.into_iter().map(|(p, _)| p).collect());
    }
    Ok(Trajectories {
        points,
        reached_boundary,
    })
}

/// One slab's flow on its geometry, and the substep length.
struct SlabFlow<'a> {
    mesh: &'a crate::mesh::Mesh,
    geometry: &'a IntrinsicGeometry,
    connection: &'a Connection,
    u: &'a [Vector2<f64>],
    dt: f64,
}

impl SlabFlow<'_> {
    /// `u_T(p)` in the face frame of `p`'s face.
    fn velocity(&self, p: &SurfacePoint) -> Vector2<f64> {
        let face = self.mesh.faces()[p.face];
        let rotations = self.connection.face_rotations(p.face);
        (0..3)
            .map(|k| p.barycentric[k] * (rotations[k] * self.u[face[k] as usize]))
            .sum()
    }

    /// One substep (a point on the boundary stays there).
    fn step(&self, p: SurfacePoint, reached_boundary: bool) -> (SurfacePoint, bool) {
        if reached_boundary {
            return (p, true);
        }
        let end = trace(self.mesh, self.geometry, p, self.dt * self.velocity(&p));
        (end.point, end.reached_boundary)
    }
}

/// The material's velocity in R³ per slab and vertex: the mesh's own motion
/// `(x_{s+1} − x_s) / (t_{s+1} − t_s)` plus the flow `u`, which the model measures relative
/// to the mesh (a mesh moved only along its normals has a normal motion, and the sum is then
/// normal velocity plus flow; a tracked or animated mesh that also slides brings its sliding).
pub fn tissue_velocity(
    sequence: &MeshSequence,
    flow: &[Vec<Vector3<f64>>],
) -> Vec<Vec<Vector3<f64>>> {
    (flow.iter().enumerate())
        .map(|(s, u)| slab_velocity(sequence, s, u))
        .collect()
}

/// [`tissue_velocity`] of slab `s` with the flow `u`.
pub fn slab_velocity(sequence: &MeshSequence, s: usize, u: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    match (sequence.positions(s), sequence.positions(s + 1)) {
        (Some(x0), Some(x1)) => {
            let dt = sequence.slab_duration(s);
            (x0.iter().zip(x1).zip(u))
                .map(|((a, b), u)| (b - a) / dt + u)
                .collect()
        }
        _ => u.to_vec(),
    }
}
