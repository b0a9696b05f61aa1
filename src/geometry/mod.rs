//! Intrinsic geometry: everything a triangle mesh's metric determines, computed from edge lengths.
//!
//! Positions enter only through [`edge_lengths`]; an *intrinsic* mesh (a flat torus, say) is
//! described by its edge lengths alone and goes through [`IntrinsicGeometry::new`] directly.
//!
//! # Conventions
//!
//! For face `[a, b, c]` with lengths `l_ab, l_bc, l_ca` ([`Triangle::lengths`], in halfedge
//! order):
//! - the *layout* puts `p_a = (0, 0)`, `p_b = (l_ab, 0)` and `p_c` in the upper half-plane;
//!   it defines the face frame in which face vectors (gradients, transported tangent vectors)
//!   are expressed;
//! - `θ_a, θ_b, θ_c` are the interior corner angles, `A` the area;
//! - `cot θ_a = (l_ab² + l_ca² − l_bc²) / 4A` (law of cosines with `sin θ_a = 2A / (l_ab l_ca)`).
//!
//! Areas use Kahan's cancellation-free Heron formula, and a face whose area is not positive
//! relative to its size (`A ≤ ε · l_max²`) is reported as degenerate instead of producing
//! infinite cotangents.

pub mod folds;
mod trace;
mod triangle;

pub use trace::{trace, SurfacePoint, TraceEnd};
pub use triangle::Triangle;

use crate::mesh::Mesh;
use nalgebra::Vector3;

/// Why lengths or positions do not describe a valid intrinsic triangle mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    #[error("expected {expected} {what}, got {got}")]
    CountMismatch {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("vertex {vertex} has a non-finite position {position:?}")]
    NonFinitePosition { vertex: usize, position: [f64; 3] },
    #[error("edge {edge} (vertices {vertices:?}) has length {length}, which is not a positive finite number")]
    InvalidEdgeLength {
        edge: usize,
        vertices: [u32; 2],
        length: f64,
    },
    #[error("face {face} (vertices {vertices:?}) is degenerate: edge lengths {lengths:?} give area {area:e}")]
    DegenerateFace {
        face: usize,
        vertices: [u32; 3],
        lengths: [f64; 3],
        area: f64,
    },
}

/// The corners `(low, high)` of the axis-aligned box around `positions` (`(+max, −max)` when
/// there are none).
pub fn bounding_box(positions: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    let low = positions
        .iter()
        .fold(Vector3::repeat(f64::MAX), |a, p| a.inf(p));
    let high = positions
        .iter()
        .fold(Vector3::repeat(f64::MIN), |a, p| a.sup(p));
    (low, high)
}

/// The length of the diagonal of [`bounding_box`]: the size of `positions`, in their units.
pub fn bounding_diameter(positions: &[Vector3<f64>]) -> f64 {
    let (low, high) = bounding_box(positions);
    (high - low).norm()
}

/// The mean length of `mesh`'s edges at `positions` (0 without edges), where no
/// [`Geometry`] is built.
pub fn mean_edge_length_at(mesh: &Mesh, positions: &[Vector3<f64>]) -> f64 {
    let total: f64 = (mesh.edges().iter())
        .map(|&[i, j]| (positions[i as usize] - positions[j as usize]).norm())
        .sum();
    total / mesh.n_edges().max(1) as f64
}

/// The total area `Σ ½ |(b − a) × (c − a)|` of the triangles `faces` at `positions`.
pub fn surface_area(faces: &[[u32; 3]], positions: &[Vector3<f64>]) -> f64 {
    (faces.iter())
        .map(|f| {
            let [a, b, c] = f.map(|v| positions[v as usize]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .sum()
}

/// Length of every undirected edge (indexed like [`Mesh::edges`]) of an embedding in R^3.
pub fn edge_lengths(mesh: &Mesh, positions: &[Vector3<f64>]) -> Result<Vec<f64>, GeometryError> {
    check_positions(mesh, positions)?;
    Ok(mesh
        .edges()
        .iter()
        .map(|&[i, j]| (positions[j as usize] - positions[i as usize]).norm())
        .collect())
}

/// Checks that there is one finite position per vertex.
pub fn check_positions(mesh: &Mesh, positions: &[Vector3<f64>]) -> Result<(), GeometryError> {
    if positions.len() != mesh.n_vertices() {
        return Err(GeometryError::CountMismatch {
            what: "vertex positions",
            expected: mesh.n_vertices(),
            got: positions.len(),
        });
    }
    check_finite_positions(positions)
}

/// Checks that every position is finite (before any mesh exists, e.g. straight from a file).
pub fn check_finite_positions(positions: &[Vector3<f64>]) -> Result<(), GeometryError> {
    match positions
        .iter()
        .position(|p| !p.iter().all(|x| x.is_finite()))
    {
        Some(vertex) => Err(GeometryError::NonFinitePosition {
            vertex,
            position: positions[vertex].into(),
        }),
        None => Ok(()),
    }
}

/// The intrinsic geometry of a mesh: one [`Triangle`] per face and the vertex angle sums.
#[derive(Clone, Debug)]
pub struct IntrinsicGeometry {
    edge_lengths: Vec<f64>,
    triangles: Vec<Triangle>,
    vertex_angle_sums: Vec<f64>,
}

impl IntrinsicGeometry {
    /// Geometry from one length per undirected edge (indexed like [`Mesh::edges`]).
    pub fn new(mesh: &Mesh, edge_lengths: Vec<f64>) -> Result<Self, GeometryError> {
        check_edge_lengths(mesh, &edge_lengths)?;
        // Pushed into a vector of its size: collected through a `Result` (no size hint), it grew
        // by doubling and kept the surplus (31,072 triangles' worth on the paper-size torus).
        let mut triangles = Vec::with_capacity(mesh.n_faces());
        for f in 0..mesh.n_faces() {
            triangles.push(face_triangle(mesh, &edge_lengths, f)?);
        }
        let mut vertex_angle_sums = vec![0.0; mesh.n_vertices()];
        for (face, triangle) in mesh.faces().iter().zip(&triangles) {
            for c in 0..3 {
                vertex_angle_sums[face[c] as usize] += triangle.angles[c];
            }
        }
        Ok(Self {
            edge_lengths,
            triangles,
            vertex_angle_sums,
        })
    }

    /// Whether [`Self::new`] would accept `edge_lengths`, and its error if not, without
    /// computing the angles (a sequence checks every frame this way; its slabs' geometries
    /// are made from mean lengths).
    pub fn check(mesh: &Mesh, edge_lengths: &[f64]) -> Result<(), GeometryError> {
        check_edge_lengths(mesh, edge_lengths)?;
        (0..mesh.n_faces()).try_for_each(|f| {
            checked_face(mesh, edge_lengths, f, Triangle::checked_area).map(|_| ())
        })
    }

    /// Geometry induced by an embedding in R^3.
    pub fn from_positions(mesh: &Mesh, positions: &[Vector3<f64>]) -> Result<Self, GeometryError> {
        Self::new(mesh, edge_lengths(mesh, positions)?)
    }

    /// Length of every undirected edge, indexed like [`Mesh::edges`].
    pub fn edge_lengths(&self) -> &[f64] {
        &self.edge_lengths
    }

    /// One triangle per face, in face order.
    pub fn triangles(&self) -> &[Triangle] {
        &self.triangles
    }

    pub fn triangle(&self, face: usize) -> &Triangle {
        &self.triangles[face]
    }

    /// Θ_i: the sum of the corner angles at vertex i (2π at a flat interior vertex).
    pub fn vertex_angle_sums(&self) -> &[f64] {
        &self.vertex_angle_sums
    }

    /// Angle defect 2π − Θ_i (interior) or π − Θ_i (boundary): the discrete Gaussian/geodesic
    /// curvature; over a closed mesh it sums to 2π χ (Gauss–Bonnet).
    pub fn angle_defects(&self, mesh: &Mesh) -> Vec<f64> {
        use std::f64::consts::PI;
        (0..mesh.n_vertices())
            .map(|i| {
                let full = if mesh.is_boundary_vertex(i) {
                    PI
                } else {
                    2.0 * PI
                };
                full - self.vertex_angle_sums[i]
            })
            .collect()
    }

    /// The mean of the edge lengths: the mesh's "pixel", the unit of displacements in
    /// [`crate::accuracy`] and of the spread in [`crate::flow::FlowParams`].
    pub fn mean_edge_length(&self) -> f64 {
        self.edge_lengths.iter().sum::<f64>() / self.edge_lengths.len() as f64
    }

    pub fn total_area(&self) -> f64 {
        self.triangles.iter().map(|t| t.area).sum()
    }
}

fn check_edge_lengths(mesh: &Mesh, lengths: &[f64]) -> Result<(), GeometryError> {
    if lengths.len() != mesh.n_edges() {
        return Err(GeometryError::CountMismatch {
            what: "edge lengths",
            expected: mesh.n_edges(),
            got: lengths.len(),
        });
    }
    match lengths.iter().position(|&l| !(l.is_finite() && l > 0.0)) {
        Some(edge) => Err(GeometryError::InvalidEdgeLength {
            edge,
            vertices: mesh.edges()[edge],
            length: lengths[edge],
        }),
        None => Ok(()),
    }
}

fn face_triangle(
    mesh: &Mesh,
    edge_lengths: &[f64],
    face: usize,
) -> Result<Triangle, GeometryError> {
    checked_face(mesh, edge_lengths, face, Triangle::from_lengths)
}

/// `make` of face `face`'s lengths, its error (the degenerate face's area) named by the face.
fn checked_face<T>(
    mesh: &Mesh,
    edge_lengths: &[f64],
    face: usize,
    make: impl Fn([f64; 3]) -> Result<T, f64>,
) -> Result<T, GeometryError> {
    let lengths: [f64; 3] = std::array::from_fn(|c| edge_lengths[mesh.halfedge_edge(3 * face + c)]);
    make(lengths).map_err(|area| GeometryError::DegenerateFace {
        face,
        vertices: mesh.faces()[face],
        lengths,
        area,
    })
}
