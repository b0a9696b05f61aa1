//! Connectivity of an oriented triangle mesh: faces, halfedges, edges, boundary and corner fans.
//!
//! Nothing here knows about positions or lengths. A [`Mesh`] is validated on construction: it is
//! an oriented 2-manifold (possibly with boundary) with every vertex used by some face.
//! [`orient`] makes the faces of a manifold agree in orientation and [`repair`] turns any face
//! list into an oriented manifold by splitting vertices; welding (module `weld`) joins the
//! vertices that a file split along seams, where that keeps the mesh manifold.
//!
//! # Conventions (used by every other module)
//!
//! - Face `f = [a, b, c]` is counter-clockwise; its local corners are `0, 1, 2` at `a, b, c`.
//! - Halfedge `h = 3 f + c` runs from `faces[f][c]` to `faces[f][(c + 1) % 3]`: the edges of
//!   face `[a, b, c]` are `a→b`, `b→c`, `c→a`.
//! - A [`Corner`] of face `[i, j, k]` at vertex `i` has *first edge* `i→j` (halfedge `3f + c`) and
//!   *second edge* `i→k` (the opposite direction of halfedge `3f + (c + 2) % 3`).
//! - Around a vertex the corners are ordered counter-clockwise: the corner after `(i, j, k)` is the
//!   face containing halfedge `i→k`. A boundary vertex's fan runs from the corner whose first edge
//!   is a boundary edge to the corner whose second edge is one; an interior vertex's fan starts
//!   at its corner in the lowest-numbered face.
//! - Undirected edge `e` joins `edges[e][0] < edges[e][1]`.

mod cohomology;
mod neighbours;
mod repair;
mod validate;
mod weld;

pub use cohomology::{halfedge_sign, TreeCotree};
pub use neighbours::VertexNeighbours;
pub(crate) use repair::UnionFind;
pub use repair::{orient, repair, RepairReport, Repaired};
pub use validate::{check_index_range, ConnectivityError};
pub use weld::SumOverReaders;
pub(crate) use weld::{weld, Weld};

/// A corner of a face: the face and the local index (0, 1, 2) of the vertex in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Corner {
    pub face: u32,
    pub local: u8,
}

impl Corner {
    /// The halfedge leaving this corner's vertex inside its face (the corner's first edge).
    pub fn first_halfedge(self) -> usize {
        3 * self.face as usize + self.local as usize
    }

    /// The halfedge entering this corner's vertex inside its face (reverse of the second edge).
    pub fn incoming_halfedge(self) -> usize {
        3 * self.face as usize + (self.local as usize + 2) % 3
    }
}

/// Sentinel for "no twin": the halfedge lies on the boundary.
pub const NO_HALFEDGE: u32 = u32::MAX;

/// Validated connectivity of an oriented manifold triangle mesh.
#[derive(Clone, Debug)]
pub struct Mesh {
    n_vertices: usize,
    faces: Vec<[u32; 3]>,
    /// `twins[h]`: the opposite halfedge, or [`NO_HALFEDGE`] on the boundary.
    twins: Vec<u32>,
    /// `halfedge_edges[h]`: the undirected edge of halfedge `h`.
    halfedge_edges: Vec<u32>,
    edges: Vec<[u32; 2]>,
    /// Corners of vertex `i` in counter-clockwise order: `fan_corners[fan_offsets[i]..fan_offsets[i + 1]]`.
    fan_offsets: Vec<usize>,
    fan_corners: Vec<Corner>,
    boundary_vertices: Vec<bool>,
}

impl Mesh {
    /// Validates `faces` over `n_vertices` vertices and builds the connectivity tables.
    ///
    /// Errors name the offending element: out-of-range or repeated indices, non-manifold edges
    /// (three or more faces), inconsistently oriented neighbours, non-manifold vertices (two or
    /// more fans) and isolated vertices.
    pub fn new(n_vertices: usize, faces: Vec<[u32; 3]>) -> Result<Self, ConnectivityError> {
        validate::build(n_vertices, faces)
    }

    pub fn n_vertices(&self) -> usize {
        self.n_vertices
    }

    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    pub fn n_edges(&self) -> usize {
        self.edges.len()
    }

    pub fn n_halfedges(&self) -> usize {
        3 * self.faces.len()
    }

    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// Undirected edges, each as `[i, j]` with `i < j`.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// Tail and head vertex of halfedge `h`.
    pub fn halfedge_vertices(&self, h: usize) -> [u32; 2] {
        let face = &self.faces[h / 3];
        [face[h % 3], face[(h + 1) % 3]]
    }

    /// The opposite halfedge, `None` on the boundary.
    pub fn twin(&self, h: usize) -> Option<usize> {
        let t = self.twins[h];
        (t != NO_HALFEDGE).then_some(t as usize)
    }

    /// The undirected edge that halfedge `h` runs along.
    pub fn halfedge_edge(&self, h: usize) -> usize {
        self.halfedge_edges[h] as usize
    }

    /// Corners around vertex `i`, counter-clockwise (see the module conventions).
    pub fn vertex_fan(&self, i: usize) -> &[Corner] {
        &self.fan_corners[self.fan_offsets[i]..self.fan_offsets[i + 1]]
    }

    pub fn is_boundary_vertex(&self, i: usize) -> bool {
        self.boundary_vertices[i]
    }

    pub fn is_boundary_halfedge(&self, h: usize) -> bool {
        self.twins[h] == NO_HALFEDGE
    }

    /// Whether the mesh has no boundary edge.
    pub fn is_closed(&self) -> bool {
        !self.boundary_vertices.iter().any(|&b| b)
    }

    /// The vertices of each connected component (vertices joined by faces), each component
    /// in breadth-first order from its lowest vertex, components in order of that vertex.
    pub fn connected_components(&self) -> Vec<Vec<usize>> {
        let mut seen = vec![false; self.n_vertices];
        let mut result = Vec::new();
        for root in 0..self.n_vertices {
            if std::mem::replace(&mut seen[root], true) {
                continue;
            }
            let mut component = vec![root];
            let mut k = 0;
            while k < component.len() {
                for corner in self.vertex_fan(component[k]) {
                    for &w in &self.faces[corner.face as usize] {
                        if !std::mem::replace(&mut seen[w as usize], true) {
                            component.push(w as usize);
                        }
                    }
                }
                k += 1;
            }
            result.push(component);
        }
        result
    }

    /// Euler characteristic V - E + F.
    pub fn euler_characteristic(&self) -> i64 {
        self.n_vertices as i64 - self.n_edges() as i64 + self.n_faces() as i64
    }
}
