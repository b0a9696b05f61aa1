//! Each vertex's neighbours along the mesh's edges, packed in compressed rows (CSR): the
//! one-rings that umbrella smoothing and sparsity patterns walk.

use super::Mesh;

/// `of(i)`: the vertices `j` with an edge `ij`, plus `i` itself where built closed; in
/// compressed rows (`offsets[i]..offsets[i + 1]` of `indices`).
#[derive(Clone, Debug)]
pub struct VertexNeighbours {
    pub offsets: Vec<usize>,
    pub indices: Vec<u32>,
}

impl VertexNeighbours {
    /// The open one-rings `{j : ij is an edge}`, in edge order.
    pub fn open(mesh: &Mesh) -> Self {
        Self::build(mesh, false)
    }

    /// The closed one-rings `{i} ∪ {j : ij is an edge}`, sorted.
    pub fn closed(mesh: &Mesh) -> Self {
        let mut rings = Self::build(mesh, true);
        for i in 0..mesh.n_vertices() {
            rings.indices[rings.offsets[i]..rings.offsets[i + 1]].sort_unstable();
        }
        rings
    }

    fn build(mesh: &Mesh, closed: bool) -> Self {
        let n = mesh.n_vertices();
        let mut offsets = vec![usize::from(closed); n + 1];
        offsets[0] = 0;
        for &[i, j] in mesh.edges() {
            offsets[i as usize + 1] += 1;
            offsets[j as usize + 1] += 1;
        }
        for k in 0..n {
            offsets[k + 1] += offsets[k];
        }
        let mut filled = offsets.clone();
        let mut indices = vec![0u32; offsets[n]];
        let mut push = |at: usize, v: u32| {
            indices[filled[at]] = v;
            filled[at] += 1;
        };
        if closed {
            (0..n).for_each(|k| push(k, k as u32));
        }
        for &[i, j] in mesh.edges() {
            push(i as usize, j);
            push(j as usize, i);
        }
        Self { offsets, indices }
    }

    /// The neighbours of vertex `i`.
    pub fn of(&self, i: usize) -> &[u32] {
        &self.indices[self.offsets[i]..self.offsets[i + 1]]
    }
}
