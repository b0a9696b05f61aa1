//! How the vertices of the input files map onto the vertices of the mesh.
//!
//! Loading renumbers vertices: welding merges file vertices ([`crate::mesh`]'s welding), vertices that
//! no face uses are dropped, and `--repair` splits vertices into manifold pieces
//! ([`crate::mesh::repair`]). A [`VertexMap`] records both directions:
//!
//! - the **mesh vertex of each file vertex**, or none when it was dropped. A file vertex whose
//!   faces end up at several mesh vertices (split by repair) maps to the one at its first face;
//! - the **representative file vertex of each mesh vertex**: the lowest file vertex mapped to
//!   it, or, for a piece that repair split off and no file vertex maps to, the file vertex at
//!   its first corner.
//!
//! Values move between the numberings as follows: a mesh vertex takes the position of its
//! representative and the mean of the per-vertex values (grey values) of the file vertices
//! mapped to it (copies along a seam may differ slightly; a split-off piece takes its
//! representative's); a file vertex takes the value of its mesh vertex, copies repeating it,
//! and a dropped one a filler (NaN in the outputs, −1 in `vertex_map.npy`).

use nalgebra::Vector3;

/// "No mesh vertex" in [`VertexMap`]'s table.
const DROPPED: u32 = u32::MAX;

/// File vertices ↔ mesh vertices (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct VertexMap {
    /// Per file vertex: its mesh vertex, or [`DROPPED`].
    mesh_vertices: Vec<u32>,
    /// Per mesh vertex: its representative file vertex.
    representatives: Vec<u32>,
}

impl VertexMap {
    /// Every file vertex is the mesh vertex with its number.
    pub fn identity(n: usize) -> Self {
        let all: Vec<u32> = (0..n as u32).collect();
        Self {
            mesh_vertices: all.clone(),
            representatives: all,
        }
    }

    /// The map that sends file vertex `i` to `mesh_vertices[i]` (`None`: dropped), each mesh
    /// vertex represented by its lowest file vertex. `None` when some mesh vertex below the
    /// largest one named has no file vertex.
    pub fn from_mesh_vertices(mesh_vertices: &[Option<u32>]) -> Option<Self> {
        let n_mesh = mesh_vertices.iter().flatten().max().map_or(0, |&m| m + 1);
        let mesh_vertices: Vec<u32> = mesh_vertices.iter().map(|m| m.unwrap_or(DROPPED)).collect();
        let no_corners = vec![DROPPED; n_mesh as usize];
        Self::with_fallback(mesh_vertices, &no_corners)
    }

    /// The map from each file vertex's mesh vertex; a mesh vertex that no file vertex maps to
    /// is represented by `first_corner_file[m]` (`None` if that is [`DROPPED`] too).
    pub(crate) fn with_fallback(
        mesh_vertices: Vec<u32>,
        first_corner_file: &[u32],
    ) -> Option<Self> {
        let mut representatives = first_corner_file.to_vec();
        let mut taken = vec![false; representatives.len()];
        for (i, &m) in mesh_vertices.iter().enumerate() {
            if m != DROPPED && !std::mem::replace(taken.get_mut(m as usize)?, true) {
                representatives[m as usize] = i as u32;
            }
        }
        representatives
            .iter()
            .all(|&r| r != DROPPED)
            .then_some(Self {
                mesh_vertices,
                representatives,
            })
    }

    pub fn n_file_vertices(&self) -> usize {
        self.mesh_vertices.len()
    }

    pub fn n_mesh_vertices(&self) -> usize {
        self.representatives.len()
    }

    /// The mesh vertex of file vertex `i`, `None` if it was dropped.
    pub fn mesh_vertex(&self, i: usize) -> Option<usize> {
        let m = self.mesh_vertices[i];
        (m != DROPPED).then_some(m as usize)
    }

    /// The representative file vertex of mesh vertex `m`.
    pub fn representative(&self, m: usize) -> usize {
        self.representatives[m] as usize
    }

    /// Mesh triangles `faces` over file vertices: each mesh vertex as its representative. What
    /// per-face arrays written beside per-file-vertex arrays are laid over.
    pub fn file_faces(&self, faces: &[[u32; 3]]) -> Vec<[u32; 3]> {
        faces
            .iter()
            .map(|face| face.map(|m| self.representatives[m as usize]))
            .collect()
    }

    /// Whether file vertex `i` is mesh vertex `i` for every `i`.
    pub fn is_identity(&self) -> bool {
        self.mesh_vertices.len() == self.representatives.len()
            && self
                .mesh_vertices
                .iter()
                .enumerate()
                .all(|(i, &m)| m == i as u32)
    }

    /// File vertices that were dropped.
    pub fn n_dropped(&self) -> usize {
        self.mesh_vertices.iter().filter(|&&m| m == DROPPED).count()
    }

    /// File vertices that share their mesh vertex with a lower file vertex (welded copies).
    pub fn n_welded(&self) -> usize {
        let mut seen = vec![false; self.n_mesh_vertices()];
        self.mesh_vertices
            .iter()
            .filter(|&&m| m != DROPPED && std::mem::replace(&mut seen[m as usize], true))
            .count()
    }

    /// `vertex_map.npy`: the mesh vertex of each file vertex, −1 when dropped.
    pub fn to_npy(&self) -> Vec<i64> {
        self.mesh_vertices
            .iter()
            .map(|&m| if m == DROPPED { -1 } else { i64::from(m) })
            .collect()
    }

    /// Mesh positions: each mesh vertex at its representative's position.
    pub fn positions(&self, file_positions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        self.representatives
            .iter()
            .map(|&r| file_positions[r as usize])
            .collect()
    }

    /// Mesh values from file values: the mean over the file vertices mapped to each mesh
    /// vertex, the representative's value for a piece no file vertex maps to.
    pub fn mean_values(&self, file_values: &[f64]) -> Vec<f64> {
        let mut sum = vec![0.0; self.n_mesh_vertices()];
        let mut count = vec![0u32; self.n_mesh_vertices()];
        for (&m, &value) in self.mesh_vertices.iter().zip(file_values) {
            if m != DROPPED {
                sum[m as usize] += value;
                count[m as usize] += 1;
            }
        }
        (0..self.n_mesh_vertices())
            .map(|m| match count[m] {
                0 => file_values[self.representatives[m] as usize],
                c => sum[m] / f64::from(c),
            })
            .collect()
    }

    /// File rows from mesh values: each file vertex gets its mesh vertex's value, a dropped
    /// one `dropped`.
    pub fn file_rows<T: Copy>(&self, mesh_values: &[T], dropped: T) -> Vec<T> {
        self.mesh_vertices
            .iter()
            .map(|&m| match m {
                DROPPED => dropped,
                m => mesh_values[m as usize],
            })
            .collect()
    }
}
