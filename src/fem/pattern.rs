//! The sparsity pattern of vertex-coupled operators, built once per mesh and filled per geometry.
//!
//! With block size `B` (1 for scalar fields, 2 for tangent fields) the matrix is `BV × BV`; the
//! block `(i, j)` is stored when `i = j` or `i`, `j` share an edge. The pattern is column-major
//! (CSC) with sorted row indices, the layout faer's sparse Cholesky takes, and every face knows
//! where its 3×3 blocks land, so assembling new values (another slab, another parameter) is a
//! scatter with no search and no allocation but the value array.

use super::{SparseMatrix, SparseMatrixRef};
use crate::mesh::{Mesh, VertexNeighbours};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use nalgebra::SMatrix;

#[derive(Clone, Debug)]
pub struct VertexPattern {
    block: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// `slots[f][a][b]`: the position of corner `a`'s vertex among the neighbours of corner `b`'s.
    slots: Vec<[[u32; 3]; 3]>,
    faces: Vec<[u32; 3]>,
}

impl VertexPattern {
    /// The pattern of `mesh` for `block`×`block` vertex blocks (`block` is 1 or 2).
    pub fn new(mesh: &Mesh, block: usize) -> Self {
        assert!(block == 1 || block == 2, "vertex blocks are 1×1 or 2×2");
        let VertexNeighbours {
            offsets,
            indices: neighbours,
        } = VertexNeighbours::closed(mesh);
        let n = mesh.n_vertices();
        let mut col_ptr = Vec::with_capacity(block * n + 1);
        let mut row_idx = Vec::with_capacity(block * block * neighbours.len());
        col_ptr.push(0);
        for j in 0..n {
            for _ in 0..block {
                for &i in &neighbours[offsets[j]..offsets[j + 1]] {
                    row_idx.extend((0..block).map(|r| block * i as usize + r));
                }
                col_ptr.push(row_idx.len());
            }
        }
        let slot = |i: u32, j: u32| {
            let list = &neighbours[offsets[j as usize]..offsets[j as usize + 1]];
            list.binary_search(&i)
                .expect("face vertices are neighbours") as u32
        };
        let slots = mesh
            .faces()
            .iter()
            .map(|face| std::array::from_fn(|a| std::array::from_fn(|b| slot(face[a], face[b]))))
            .collect();
        let symbolic =
            SymbolicSparseColMat::new_checked(block * n, block * n, col_ptr, None, row_idx);
        Self {
            block,
            symbolic,
            slots,
            faces: mesh.faces().to_vec(),
        }
    }

    /// Rows (= columns) of the assembled matrix: `block · V`.
    pub fn dimension(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Stored entries, both triangles.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    pub fn symbolic(&self) -> &SymbolicSparseColMat<usize> {
        &self.symbolic
    }

    /// Adds the `3B×3B` element matrix of `face` (DOF `B·a + r` for corner `a`, component `r`)
    /// into `values`, which is laid out like this pattern.
    pub fn add_element<const N: usize>(
        &self,
        face: usize,
        element: &SMatrix<f64, N, N>,
        values: &mut [f64],
    ) {
        let b = self.block;
        debug_assert_eq!(N, 3 * b);
        let col_ptr = self.symbolic.col_ptr();
        for (corner_a, slots_a) in self.slots[face].iter().enumerate() {
            for (corner_b, &slot) in slots_a.iter().enumerate() {
                for c in 0..b {
                    let column = b * self.faces[face][corner_b] as usize + c;
                    let start = col_ptr[column] + b * slot as usize;
                    for r in 0..b {
                        values[start + r] += element[(b * corner_a + r, b * corner_b + c)];
                    }
                }
            }
        }
    }

    /// Sums the element matrices of all faces into a matrix with this pattern.
    pub fn assemble<const N: usize>(
        &self,
        n_faces: usize,
        element: impl Fn(usize) -> SMatrix<f64, N, N>,
    ) -> SparseMatrix {
        self.matrix(self.assemble_values(n_faces, element))
    }

    /// Zero values in this pattern's order, written rather than `vec![0.0; n]`, to scatter
    /// elements into: calloc's fresh pages are the shared zero page until the scatter's first
    /// write, which then faults a second time and flushes every core's TLB (a tenth of the
    /// assembly's time on 200 frames of 96,900 faces).
    pub fn zero_values(&self) -> Vec<f64> {
        let mut values = Vec::with_capacity(self.nnz());
        values.resize(self.nnz(), 0.0);
        values
    }

    /// The values (in this pattern's order) of the sum of the element matrices of all faces.
    pub fn assemble_values<const N: usize>(
        &self,
        n_faces: usize,
        element: impl Fn(usize) -> SMatrix<f64, N, N>,
    ) -> Vec<f64> {
        let mut values = self.zero_values();
        for face in 0..n_faces {
            self.add_element(face, &element(face), &mut values);
        }
        values
    }

    /// A view of `values` (laid out like this pattern) as a matrix.
    pub fn view<'a>(&'a self, values: &'a [f64]) -> SparseMatrixRef<'a> {
        SparseMatrixRef::new(self.symbolic.as_ref(), values)
    }

    /// The matrix with this pattern and the given values.
    pub fn matrix(&self, values: Vec<f64>) -> SparseMatrix {
        SparseColMat::new(self.symbolic.clone(), values)
    }
}
