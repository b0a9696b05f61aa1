//! The discrete Levi-Civita connection: vertex tangent frames and parallel transport.
//!
//! A tangent vector at vertex `i` is a 2-vector in the vertex's own frame. The frame is defined
//! in *scaled polar coordinates* (Knöppel et al. 2013; Sharp, Soliman & Crane 2019, §5.1): the
//! corners around `i` are laid side by side counter-clockwise, starting at a reference outgoing
//! edge, and their angles are scaled by `s_i = 2π / Θ_i` so that they fill a whole turn
//! (`s_i = 1` at boundary vertices, which keeps boundary corners undistorted). The outgoing edge
//! `i→j` then has the vertex-frame polar angle
//!
//! ```text
//! ϑ_i(i→j) = s_i · (sum of the corner angles from the reference edge to i→j)
//! ```
//!
//! The reference edge is the first edge of the first corner of [`Mesh::vertex_fan`]: at a
//! boundary vertex the boundary edge the fan starts from, at an interior vertex the first edge
//! of its corner in the lowest-numbered face. It is fixed because the intrinsic components
//! (`flow_intrinsic.npy`) and the frames (`frames.npy`) depend on it; nothing else does.
//!
//! # Vertex → face transport
//!
//! For the corner of face `T` at vertex `i`, with face-frame angle `φ` of its first edge
//! ([`Triangle::first_edge_angles`](crate::geometry::Triangle::first_edge_angles)) and vertex-frame angle `ϑ` of the same edge, the rotation
//! `R_{T,i}` by
//!
//! ```text
//! r_{T,i} = φ − ϑ + θ_i (1 − s_i) / 2
//! ```
//!
//! maps vertex-frame vectors into `T`'s face frame, aligning the corner's bisector in both. This
//! is the transport the finite elements use (`docs/discretization.md` §5).
//!
//! # Vertex → vertex transport
//!
//! Across halfedge `i→j` a vector at polar angle `ψ` in `i`'s frame becomes the vector at polar
//! angle `ψ + ρ_{ij}` in `j`'s frame, `ρ_{ij} = ϑ_j(j→i) + π − ϑ_i(i→j)` (the connection of the
//! Vector Heat Method). It is exact on flat regions and is what a discrete parallel transport
//! along a path of edges uses; the finite elements do not need it.

mod push_forward;
mod time_transport;

pub use push_forward::{push_forward, vertex_frames_in_r3, vertex_normals};
pub use time_transport::polar_rotations;

use crate::geometry::{IntrinsicGeometry, SurfacePoint};
use crate::mesh::{Corner, Mesh};
use nalgebra::{Matrix2, Vector2};
use std::f64::consts::PI;

/// Vertex frames and transports of one intrinsic geometry.
#[derive(Clone, Debug)]
pub struct Connection {
    vertex_scales: Vec<f64>,
    /// Vertex-frame polar angle of each halfedge at its tail vertex.
    halfedge_angles: Vec<f64>,
    /// `R_{T,i}` as `(cos r_{T,i}, sin r_{T,i})`: the element assembly's hot path needs no
    /// trigonometry, and the two numbers are half of the matrix (48 bytes per face and slab
    /// less: 88 MB at paper size). The angles are not kept besides,
    /// [`Self::corner_rotation_angle`] reads them off the pairs.
    corner_rotations: Vec<[[f64; 2]; 3]>,
}

impl Connection {
    pub fn new(mesh: &Mesh, geometry: &IntrinsicGeometry) -> Self {
        let mut vertex_scales = vec![1.0; mesh.n_vertices()];
        let mut halfedge_angles = vec![0.0; mesh.n_halfedges()];
        let mut corner_rotations = vec![[[1.0, 0.0]; 3]; mesh.n_faces()];
        for (i, scale) in vertex_scales.iter_mut().enumerate() {
            if !mesh.is_boundary_vertex(i) {
                *scale = 2.0 * PI / geometry.vertex_angle_sums()[i];
            }
            let mut swept = 0.0;
            for corner in mesh.vertex_fan(i) {
                let (f, c) = (corner.face as usize, corner.local as usize);
                let triangle = geometry.triangle(f);
                let theta = triangle.angles[c];
                let vartheta = *scale * swept;
                halfedge_angles[corner.first_halfedge()] = vartheta;
                let (sin, cos) = (triangle.first_edge_angles()[c] - vartheta
                    + theta * (1.0 - *scale) / 2.0)
                    .sin_cos();
                corner_rotations[f][c] = [cos, sin];
                swept += theta;
            }
        }
        Self {
            vertex_scales,
            halfedge_angles,
            corner_rotations,
        }
    }

    /// `s_i`: the factor that scales corner angles at vertex `i` to polar angles.
    pub fn vertex_scales(&self) -> &[f64] {
        &self.vertex_scales
    }

    /// `ϑ_i(h)`: the polar angle of halfedge `h` in the frame of its tail vertex.
    pub fn halfedge_angle(&self, h: usize) -> f64 {
        self.halfedge_angles[h]
    }

    /// Every outgoing edge `i→j` of vertex `i` as `(j, ϑ_i(i→j))`, counter-clockwise from the
    /// reference edge: the first edge of each corner of the fan and, at a boundary vertex, the
    /// second edge of the last corner (polar angle `ϑ + s_i θ` of that corner).
    pub fn outgoing_edges<'a>(
        &'a self,
        mesh: &'a Mesh,
        geometry: &'a IntrinsicGeometry,
        i: usize,
    ) -> impl Iterator<Item = (u32, f64)> + 'a {
        let fan = mesh.vertex_fan(i);
        let first_edges = fan.iter().map(|corner| {
            let h = corner.first_halfedge();
            (mesh.halfedge_vertices(h)[1], self.halfedge_angles[h])
        });
        let closing_edge = mesh.is_boundary_vertex(i).then(|| {
            let last = fan[fan.len() - 1];
            let theta = geometry.triangle(last.face as usize).angles[last.local as usize];
            let head = mesh.halfedge_vertices(last.incoming_halfedge())[0];
            let angle = self.halfedge_angles[last.first_halfedge()] + self.vertex_scales[i] * theta;
            (head, angle)
        });
        first_edges.chain(closing_edge)
    }

    /// `r_{T,i}` for face `face` and local corner `local`, in `(−π, π]`.
    pub fn corner_rotation_angle(&self, face: usize, local: usize) -> f64 {
        let [cos, sin] = self.corner_rotations[face][local];
        sin.atan2(cos)
    }

    /// `R_{T,i}`: maps a vertex-frame vector at corner `local` of `face` into the face frame.
    pub fn vertex_to_face(&self, face: usize, local: usize) -> Matrix2<f64> {
        rotation_matrix(self.corner_rotations[face][local])
    }

    /// `[R_{T,a}, R_{T,b}, R_{T,c}]` for face `T = face`.
    pub fn face_rotations(&self, face: usize) -> [Matrix2<f64>; 3] {
        self.corner_rotations[face].map(rotation_matrix)
    }

    /// `ρ_{ij}` for halfedge `h = i→j`: the rotation angle that carries a vector at `i` to `j`.
    ///
    /// `ϑ_j(j→i)` is the second-edge angle of `j`'s corner in `h`'s face, which exists on the
    /// boundary too.
    pub fn transport_angle(&self, mesh: &Mesh, geometry: &IntrinsicGeometry, h: usize) -> f64 {
        let (f, c) = (h / 3, h % 3);
        let head_corner = 3 * f + (c + 1) % 3;
        let [_, j] = mesh.halfedge_vertices(h);
        let theta_j = geometry.triangle(f).angles[(c + 1) % 3];
        let vartheta_ji =
            self.halfedge_angles[head_corner] + self.vertex_scales[j as usize] * theta_j;
        wrap_angle(vartheta_ji + PI - self.halfedge_angles[h])
    }

    /// Transports the tangent vector `u` at the tail of halfedge `h` to its head.
    pub fn transport(
        &self,
        mesh: &Mesh,
        geometry: &IntrinsicGeometry,
        h: usize,
        u: Vector2<f64>,
    ) -> Vector2<f64> {
        rotation(self.transport_angle(mesh, geometry, h)) * u
    }
}

impl Connection {
    /// The start of a trace from vertex `i` along the vertex-frame vector `u`
    /// ([`crate::geometry::trace`]): the vertex as a point of the corner whose scaled sector
    /// `[ϑ, ϑ + s_i θ)` holds `u`'s polar angle `ψ`, and `u` in that face's frame, at the face
    /// angle `φ + (ψ − ϑ) / s_i` (the sector unscaled). At a boundary vertex a direction
    /// outside the fan by the angle `δ` is projected onto the nearer of its two boundary edges,
    /// length `|u| max(cos δ, 0)`: a trace may slide along the boundary, never leave it, and
    /// the start is continuous in `u` where the boundary is straight or convex (the step
    /// vanishes midway between the edges instead of jumping from one to the other, which made
    /// warping at the boundary flip with round-off).
    pub fn vertex_trace_start(
        &self,
        mesh: &Mesh,
        geometry: &IntrinsicGeometry,
        i: usize,
        u: Vector2<f64>,
    ) -> (SurfacePoint, Vector2<f64>) {
        let scale = self.vertex_scales[i];
        let psi = u.y.atan2(u.x).rem_euclid(2.0 * PI);
        let fan = mesh.vertex_fan(i);
        let sector = |c: &Corner| {
            let start = self.halfedge_angles[c.first_halfedge()];
            let width = scale * geometry.triangle(c.face as usize).angles[c.local as usize];
            (start, width)
        };
        // Offset of ψ into each sector, clamped to it, and how far ψ lies outside (0 inside);
        // the corner ψ lies least outside of wins.
        let (corner, offset, outside) = fan
            .iter()
            .map(|c| {
                let (start, width) = sector(c);
                let offset = (psi - start).rem_euclid(2.0 * PI);
                let (before, after) = (2.0 * PI - offset, offset - width);
                match offset <= width {
                    true => (*c, offset, 0.0),
                    false if before < after => (*c, 0.0, before),
                    false => (*c, width, after),
                }
            })
            .min_by(|a, b| a.2.total_cmp(&b.2))
            .expect("every vertex has a corner");
        let (face, local) = (corner.face as usize, corner.local as usize);
        let angle = geometry.triangle(face).first_edge_angles()[local] + offset / scale;
        let length = u.norm() * outside.cos().max(0.0);
        let step = length * Vector2::new(angle.cos(), angle.sin());
        (SurfacePoint::corner(face, local), step)
    }
}

/// The counter-clockwise rotation by `angle`.
pub fn rotation(angle: f64) -> Matrix2<f64> {
    let (s, c) = angle.sin_cos();
    rotation_matrix([c, s])
}

/// The rotation with cosine and sine `[c, s]`.
fn rotation_matrix([c, s]: [f64; 2]) -> Matrix2<f64> {
    Matrix2::new(c, -s, s, c)
}

/// `angle` reduced to `(−π, π]`.
pub fn wrap_angle(angle: f64) -> f64 {
    let wrapped = angle.rem_euclid(2.0 * PI);
    if wrapped > PI {
        wrapped - 2.0 * PI
    } else {
        wrapped
    }
}
