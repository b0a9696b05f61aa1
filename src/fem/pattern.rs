//! The sparsity pattern of vertex-coupled operators, built once per mesh and filled per geometry.
//!
//! With block size `B` (1 for scalar fields, 2 for tangent fields) the matrix is `BV × BV`; the
//! block `(i, j)` is stored when `i = j` or `i`, `j` share an edge (a lower pattern keeps only
//! the blocks with `i ≥ j`, for symmetric operators: [`VertexPattern::lower`]). The pattern is
//! column-major (CSC) with sorted row indices, the layout faer's sparse Cholesky takes, and every
//! face knows where its 3×3 blocks land, so assembling new values (another slab, another
//! parameter) is a scatter with no search and no allocation but the value array.

use super::{SparseMatrix, SparseMatrixRef};
use crate::mesh::{Mesh, VertexNeighbours};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use nalgebra::SMatrix;

#[derive(Clone, Debug)]
pub struct VertexPattern {
    block: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// `slots[f][a][b]`: the position of corner `a`'s vertex among the neighbours of corner `b`'s
    /// ([`NOT_STORED`] for a block the pattern leaves out).
    slots: Vec<[[u32; 3]; 3]>,
    faces: Vec<[u32; 3]>,
    /// For a [lower](Self::lower) pattern, each column's first row in the full pattern's column
    /// (the lower part of a sorted column is its tail); empty for a full pattern.
    full_offsets: Vec<usize>,
}

/// The slot of a block a lower pattern does not store.
const NOT_STORED: u32 = u32::MAX;

impl VertexPattern {
    /// The pattern of `mesh` for `block`×`block` vertex blocks (`block` is 1 or 2).
    pub fn new(mesh: &Mesh, block: usize) -> Self {
        Self::with_blocks(mesh, block, false)
    }

    /// The vertex blocks `(i, j)` with `i ≥ j` only: the lower half of a symmetric operator's
    /// blocks, the diagonal blocks whole (so that the scalar lower triangle faer's Cholesky
    /// reads is all there, with one entry above the diagonal per vertex for `block = 2`).
    /// On a closed triangle mesh a vertex keeps 4 blocks (its own and, on average, half of its 6
    /// neighbours') instead of 7: a space-time system's diagonal blocks take 57 % of the memory
    /// and of a product's reads.
    pub fn lower(mesh: &Mesh, block: usize) -> Self {
        Self::with_blocks(mesh, block, true)
    }

    fn with_blocks(mesh: &Mesh, block: usize, lower: bool) -> Self {
        assert!(block == 1 || block == 2, "vertex blocks are 1×1 or 2×2");
        let VertexNeighbours {
            offsets,
            indices: neighbours,
        } = VertexNeighbours::closed(mesh);
        let n = mesh.n_vertices();
        // Neighbour lists are sorted: the blocks `i ≥ j` of column `j` are a tail.
        let first_kept = |j: usize| match lower {
            true => neighbours[offsets[j]..offsets[j + 1]].partition_point(|&i| (i as usize) < j),
            false => 0,
        };
        let mut col_ptr = Vec::with_capacity(block * n + 1);
        let mut row_idx = Vec::new();
        let mut full_offsets = Vec::new();
        col_ptr.push(0);
        for j in 0..n {
            let skipped = first_kept(j);
            for _ in 0..block {
                for &i in &neighbours[offsets[j] + skipped..offsets[j + 1]] {
                    row_idx.extend((0..block).map(|r| block * i as usize + r));
                }
                col_ptr.push(row_idx.len());
                if lower {
                    full_offsets.push(block * skipped);
                }
            }
        }
        let slot = |i: u32, j: u32| {
            if lower && i < j {
                return NOT_STORED;
            }
            let list = &neighbours[offsets[j as usize]..offsets[j as usize + 1]];
            let at = list
                .binary_search(&i)
                .expect("face vertices are neighbours");
            (at - first_kept(j as usize)) as u32
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
            full_offsets,
        }
    }

    /// Whether this is a [lower](Self::lower) pattern.
    pub fn is_lower(&self) -> bool {
        !self.full_offsets.is_empty()
    }

    /// The values of a lower pattern taken from `full`'s, laid out like `full` (the full pattern
    /// of the same mesh and block size): the blocks `i ≥ j` of a matrix.
    pub fn lower_part_of(&self, full: &VertexPattern, values: &[f64]) -> Vec<f64> {
        debug_assert!(self.is_lower() && !full.is_lower());
        let (own, whole) = (self.symbolic.col_ptr(), full.symbolic.col_ptr());
        (0..self.dimension())
            .flat_map(|c| {
                let start = whole[c] + self.full_offsets[c];
                &values[start..start + own[c + 1] - own[c]]
            })
            .copied()
            .collect()
    }

    /// Rows (= columns) of the assembled matrix: `block · V`.
    pub fn dimension(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Stored entries (both triangles; a [lower](Self::lower) pattern's blocks `i ≥ j`).
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
                if slot == NOT_STORED {
                    continue;
                }
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
