//! Charts: parameter coordinates on a mesh, for reading flows in a parameter domain.
//!
//! A chart gives every vertex parameter coordinates `φ_i ∈ R²` — the pixel grid an image sequence
//! was sampled on, the `(x1, x2)` of a graph surface, a torus' two angles — optionally periodic
//! with periods `(P_1, P_2)`. On face `T = (a, b, c)` it is the affine map with edge images
//!
//! ```text
//! Φ_T = [φ_b − φ_a, φ_c − φ_a]      (2×2; each difference taken to its nearest periodic image,
//!                                    |d_k| ≤ P_k / 2, so that a periodic grid closes up)
//! ```
//!
//! Two uses:
//!
//! * **Pull-back of a flow.** A vertex vector `u_i` (components in vertex `i`'s frame) becomes
//!   the parameter velocity `w_i = P^φ_i u_i`, with `P^φ_i` the corner-angle-weighted mean of
//!   `Φ_T E2_T⁻¹ R_{T,i}` over the faces at `i`: the mean of the chart's differentials, which
//!   *should* carry the chart's stretch (unlike the orthonormal frames of the R^3 output,
//!   `docs/discretization.md` §8). For an image grid, `w` is in pixels per unit time, directly
//!   comparable with classical optical flow.
//! * **The chart's own flat metric**, edge lengths `|φ_j − φ_i|`: the "naive" model that forgets
//!   the surface and computes flow in the parameter plane (the flat torus of Bauer, Grasmair &
//!   Kirisits' comparison, Figs. 3–6), via
//!   [`MeshSequence::from_edge_lengths`](crate::flow::MeshSequence::from_edge_lengths).

use crate::connection::Connection;
use crate::flow::Slab;
use crate::geometry::IntrinsicGeometry;
use crate::mesh::Mesh;
use nalgebra::{Matrix2, Vector2};
use thiserror::Error;

/// Errors in building or applying a chart.
#[derive(Debug, Error, PartialEq)]
pub enum ChartError {
    #[error("the chart has coordinates for {found} vertices, the mesh has {expected}")]
    VertexCount { expected: usize, found: usize },
    #[error("chart coordinates of vertex {vertex} are not finite")]
    NonFinite { vertex: usize },
    #[error("chart period {axis} is {period}; periods must be positive and finite")]
    Period { axis: usize, period: f64 },
    #[error("slab {slab} has {found} flow vectors, the mesh has {expected} vertices")]
    FlowLength {
        slab: usize,
        expected: usize,
        found: usize,
    },
}

/// Per-vertex parameter coordinates, with optional periods per axis.
#[derive(Clone, Debug)]
pub struct Chart {
    coordinates: Vec<Vector2<f64>>,
    periods: [Option<f64>; 2],
}

impl Chart {
    /// A chart with the given coordinates (one per vertex of the mesh it will be used with)
    /// and periods (`None`: not periodic along that axis).
    pub fn new(
        coordinates: Vec<Vector2<f64>>,
        periods: [Option<f64>; 2],
    ) -> Result<Self, ChartError> {
        if let Some(vertex) = coordinates
            .iter()
            .position(|c| !(c.x.is_finite() && c.y.is_finite()))
        {
            return Err(ChartError::NonFinite { vertex });
        }
        for (axis, period) in periods.iter().enumerate() {
            if let Some(&period) = period.as_ref().filter(|p| !(p.is_finite() && **p > 0.0)) {
                return Err(ChartError::Period { axis, period });
            }
        }
        Ok(Self {
            coordinates,
            periods,
        })
    }

    /// The `n1 × n2` periodic grid of [`shapes::torus`](crate::shapes::torus) and
    /// [`synth::paper_torus`](crate::synth::paper_torus): vertex `i n2 + j` at `(i, j)`, periods
    /// `(n1, n2)` — grid units, i.e. pixels of an `n1 × n2` image.
    pub fn periodic_grid(n1: usize, n2: usize) -> Self {
        let coordinates = (0..n1)
            .flat_map(|i| (0..n2).map(move |j| Vector2::new(i as f64, j as f64)))
            .collect();
        Self::new(coordinates, [Some(n1 as f64), Some(n2 as f64)])
            .expect("grid coordinates and sizes are finite")
    }

    /// The `(nx + 1) × (ny + 1)` vertex grid of [`shapes::grid`](crate::shapes::grid): vertex
    /// `j (nx + 1) + i` at `(i, j)`, grid units, not periodic.
    pub fn grid(nx: usize, ny: usize) -> Self {
        let coordinates = (0..=ny)
            .flat_map(|j| (0..=nx).map(move |i| Vector2::new(i as f64, j as f64)))
            .collect();
        Self::new(coordinates, [None, None]).expect("grid coordinates are finite")
    }

    pub fn coordinates(&self) -> &[Vector2<f64>] {
        &self.coordinates
    }

    /// `φ_to − φ_from`, reduced to the nearest periodic image along periodic axes.
    pub fn difference(&self, from: usize, to: usize) -> Vector2<f64> {
        let d = self.coordinates[to] - self.coordinates[from];
        Vector2::from_fn(|k, _| match self.periods[k] {
            Some(period) => d[k] - period * (d[k] / period).round(),
            None => d[k],
        })
    }

    /// `Φ_T` for every face of `mesh`.
    pub fn face_edges(&self, mesh: &Mesh) -> Result<Vec<Matrix2<f64>>, ChartError> {
        self.check_vertex_count(mesh)?;
        Ok(mesh
            .faces()
            .iter()
            .map(|&[a, b, c]| {
                let (a, b, c) = (a as usize, b as usize, c as usize);
                Matrix2::from_columns(&[self.difference(a, b), self.difference(a, c)])
            })
            .collect())
    }

    /// The chart's flat metric: `|φ_j − φ_i|` for every edge of `mesh` (indexed like
    /// [`Mesh::edges`]).
    pub fn flat_edge_lengths(&self, mesh: &Mesh) -> Result<Vec<f64>, ChartError> {
        self.check_vertex_count(mesh)?;
        Ok(mesh
            .edges()
            .iter()
            .map(|&[i, j]| self.difference(i as usize, j as usize).norm())
            .collect())
    }

    /// The parameter velocities `w_i = P^φ_i u_i` of one field per slab, `flow[s][i]` in the
    /// vertex frames of `slabs[s]` (as in [`FlowResult::intrinsic`](crate::flow::FlowResult)).
    pub fn pull_back(
        &self,
        mesh: &Mesh,
        slabs: &[Slab],
        flow: &[Vec<Vector2<f64>>],
    ) -> Result<Vec<Vec<Vector2<f64>>>, ChartError> {
        let face_edges = self.face_edges(mesh)?;
        slabs
            .iter()
            .zip(flow)
            .enumerate()
            .map(|(s, (slab, u))| {
                if u.len() != mesh.n_vertices() {
                    return Err(ChartError::FlowLength {
                        slab: s,
                        expected: mesh.n_vertices(),
                        found: u.len(),
                    });
                }
                let frames = chart_frames(mesh, &slab.geometry, &slab.connection, &face_edges);
                Ok(frames.iter().zip(u).map(|(p, u)| p * u).collect())
            })
            .collect()
    }

    fn check_vertex_count(&self, mesh: &Mesh) -> Result<(), ChartError> {
        if self.coordinates.len() == mesh.n_vertices() {
            Ok(())
        } else {
            Err(ChartError::VertexCount {
                expected: mesh.n_vertices(),
                found: self.coordinates.len(),
            })
        }
    }
}

/// `P^φ_i` for every vertex: the corner-angle-weighted mean of `Φ_T E2_T⁻¹ R_{T,i}` over the
/// faces at `i` (see the module docs), for the chart's face edge images `face_edges[f] = Φ_T`.
fn chart_frames(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    face_edges: &[Matrix2<f64>],
) -> Vec<Matrix2<f64>> {
    let mut frames = vec![Matrix2::zeros(); mesh.n_vertices()];
    for (f, (face, edges)) in mesh.faces().iter().zip(face_edges).enumerate() {
        let triangle = geometry.triangle(f);
        // The layout edge matrix is upper triangular with positive diagonal: always invertible.
        let layout_inverse = triangle
            .layout_edge_matrix()
            .try_inverse()
            .expect("layout of a validated triangle is invertible");
        let face_map = edges * layout_inverse;
        for (local, &v) in face.iter().enumerate() {
            let weight = triangle.angles[local];
            frames[v as usize] += weight * face_map * connection.vertex_to_face(f, local);
        }
    }
    for (frame, sum) in frames.iter_mut().zip(geometry.vertex_angle_sums()) {
        *frame /= *sum;
    }
    frames
}
