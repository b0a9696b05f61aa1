//! The space-time linear system `A u = b` (`b = −f`) of all slabs, block-tridiagonal in time.
//!
//! Unknowns are slab-major: `u = [u_0, …, u_{S−1}]`, each `u_s` the `2V` vertex-frame DOFs of
//! slab `s`. Diagonal block `s` is `Δt_s (D_s + β M_s + γ K_s)` plus the diagonal parts of the
//! time links to slabs `s ± 1`; the block below the diagonal, `X_s` at `(s + 1, s)`, is the
//! cross part of link `s`. The diagonal blocks are symmetric and share one lower
//! [`VertexPattern`]: each keeps its 2×2 vertex blocks `(i, j)` with `i ≥ j` only, which on a
//! closed mesh is 4 of every 7 (the 200-frame torus of `bench_paper_torus` peaked at 7.24 GB
//! instead of 8.16 GB). A lumped link is a 2×2 block per vertex, a consistent one uses the full
//! vertex pattern (it is not symmetric). With Dirichlet boundary conditions boundary DOFs get
//! identity rows and a zero right-hand side.
//!
//! The energy is `E(u) = uᵀAu − 2bᵀu + c`.

use super::slab::{Slab, TimeLink};
use super::solve::factors_slabs;
use super::{Boundary, FlowParams, TimeCoupling, Weights};
use crate::fem::{SparseMatrix, SparseMatrixRef, VertexPattern};
use crate::linalg::cholesky::analyze;
use crate::mesh::Mesh;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use nalgebra::Matrix2;
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// The coupling block `X_s` between slab `s` and `s + 1`.
#[derive(Clone, Debug, PartialEq)]
pub enum LinkMatrix {
    /// One 2×2 block per vertex.
    Lumped(Vec<Matrix2<f64>>),
    /// A `2V × 2V` matrix on the vertex pattern (not symmetric), with its diagonal parts.
    Consistent(ConsistentLink),
}

/// A consistent link on the vertex pattern: its cross block `X` and the parts `B`, `A` it adds
/// to the diagonal blocks of the slabs before and after. Together they are the link's energy,
/// `[u_a; u_b]ᵀ [B Xᵀ; X A] [u_a; u_b] = c ‖u_b − P u_a‖²_M ≥ 0`; multigrid in time halves it
/// on coarse levels ([`LinkMatrix::halve`]), which `X` alone does not allow (`B` and `A` are
/// mass matrices rotated by each slab's connection).
#[derive(Clone, Debug, PartialEq)]
pub struct ConsistentLink {
    /// `X` (rows: the slab after, columns: the slab before).
    pub cross: Vec<f64>,
    /// `B`, on the slab before.
    pub before: Vec<f64>,
    /// `A`, on the slab after.
    pub after: Vec<f64>,
}

impl ConsistentLink {
    fn parts_mut(&mut self) -> [&mut Vec<f64>; 3] {
        [&mut self.cross, &mut self.before, &mut self.after]
    }
}

#[derive(Clone, Debug)]
pub struct SpaceTimeSystem {
    /// The vertex pattern of the consistent links, shared by every system on the same mesh
    /// (coarse levels, windows) instead of copied (with its lower part, about 28 MB on the
    /// paper's 48,450-vertex torus).
    pattern: Arc<VertexPattern>,
    /// Its blocks `i ≥ j` ([`VertexPattern::lower`]): the diagonal blocks are symmetric.
    lower: Arc<VertexPattern>,
    /// Values of the diagonal blocks on `lower`.
    blocks: Vec<Vec<f64>>,
    links: Vec<LinkMatrix>,
    rhs: Vec<f64>,
    /// Each slab's part of the energy constant `c` (empty for a coarse level).
    slab_constants: Vec<f64>,
    /// The symbolic analysis of the slab blocks' pattern ([`Self::slab_symbolic`]), shared by
    /// every system on the same pattern (windows, coarse levels).
    slab_analysis: OnceLock<Arc<SymbolicCholesky<usize>>>,
}

impl LinkMatrix {
    /// `ys += X x` (a consistent link's values lie on the slabs' `pattern`).
    pub fn mul(&self, pattern: &VertexPattern, x: &[f64], ys: &mut [f64]) {
        match self {
            LinkMatrix::Lumped(blocks) => add_block_diagonal_mul(blocks, false, x, ys),
            LinkMatrix::Consistent(m) => {
                for_each_column(pattern.view(&m.cross), |j, rows, values| {
                    for (&i, &v) in rows.iter().zip(values) {
                        ys[i] += v * x[j];
                    }
                })
            }
        }
    }

    /// `ys += Xᵀ x`.
    pub fn transpose_mul(&self, pattern: &VertexPattern, x: &[f64], ys: &mut [f64]) {
        match self {
            LinkMatrix::Lumped(blocks) => add_block_diagonal_mul(blocks, true, x, ys),
            LinkMatrix::Consistent(m) => {
                for_each_column(pattern.view(&m.cross), |j, rows, values| {
                    ys[j] += rows
                        .iter()
                        .zip(values)
                        .map(|(&i, &v)| v * x[i])
                        .sum::<f64>();
                })
            }
        }
    }
}

/// A run of slabs of a [`SpaceTimeSystem`] and its links to the slabs beyond
/// ([`SpaceTimeSystem::window`]).
#[derive(Clone, Debug)]
pub struct SystemWindow {
    pub system: SpaceTimeSystem,
    /// The window's slabs in the whole sequence (`system`'s slab 0 is `slabs.start`).
    pub slabs: std::ops::Range<usize>,
    /// The whole sequence's number of slabs.
    pub n_slabs_in_all: usize,
    /// `X_{a−1}`, from the slab before the window into its first; `None` at the start.
    pub link_before: Option<LinkMatrix>,
    /// `X_{b−1}`, from the window's last slab into the one after; `None` at the end.
    pub link_after: Option<LinkMatrix>,
}

impl SpaceTimeSystem {
    /// Assembles the system of `slabs` (with `links[s]` between slab `s` and `s + 1`; no links
    /// for frame-by-frame flow) with the weights `weights`. Slabs are assembled in parallel.
    /// `analysis` is where the slab blocks' symbolic analysis of systems on `mesh` is kept
    /// (the sequence's, [`Self::slab_symbolic`]): taken from it when there, made beside the
    /// assembly and kept there when the solve will factor the slabs.
    pub fn assemble(
        mesh: &Mesh,
        slabs: &[Slab],
        links: &[TimeLink],
        params: &FlowParams,
        weights: &Weights,
        analysis: &OnceLock<Arc<SymbolicCholesky<usize>>>,
    ) -> Self {
        let coupling = params.time_coupling;
        let pattern = Arc::new(VertexPattern::new(mesh, 2));
        let lower = Arc::new(VertexPattern::lower(mesh, 2));
        let n_slabs = slabs.len();
        let assembly = || {
            let diagonal: Vec<(Vec<f64>, Vec<f64>, f64)> = (0..n_slabs)
                .into_par_iter()
                .map(|s| {
                    let coupled = !links.is_empty();
                    let link_before = (coupled && s > 0).then(|| (&links[s - 1], &slabs[s - 1]));
                    let link_after =
                        (coupled && s + 1 < n_slabs).then(|| (&links[s], &slabs[s + 1]));
                    let links = (link_before, link_after);
                    assemble_slab(mesh, &lower, &slabs[s], links, params, weights)
                })
                .collect();
            let links: Vec<LinkMatrix> = (0..links.len())
                .into_par_iter()
                .map(|s| {
                    assemble_link(
                        mesh,
                        &pattern,
                        &links[s],
                        &slabs[s],
                        &slabs[s + 1],
                        coupling,
                    )
                })
                .collect();
            (diagonal, links)
        };
        // The ordering (METIS, on one thread) needs only the pattern: where the solve will
        // factor the slabs, it runs beside the assembly instead of after it, alone on one core.
        let dimension = n_slabs * pattern.dimension();
        let factors = factors_slabs(params, dimension, !links.is_empty());
        let (analysis, (diagonal, links)) = match (analysis.get(), factors) {
            (Some(made), _) => (OnceLock::from(made.clone()), assembly()),
            (None, true) => {
                let (made, assembled) =
                    rayon::join(|| analyze(pattern.symbolic().as_ref(), 2), assembly);
                (
                    OnceLock::from(analysis.get_or_init(|| made).clone()),
                    assembled,
                )
            }
            (None, false) => (OnceLock::new(), assembly()),
        };
        let slab_constants = diagonal.iter().map(|d| d.2).collect();
        let (blocks, rhs): (Vec<_>, Vec<_>) = diagonal.into_iter().map(|(a, b, _)| (a, b)).unzip();
        let mut system = Self {
            pattern,
            lower,
            blocks,
            links,
            rhs: rhs.concat(),
            slab_constants,
            slab_analysis: analysis,
        };
        if params.boundary == Boundary::Dirichlet {
            let fixed: Vec<bool> = (0..mesh.n_vertices())
                .flat_map(|i| [mesh.is_boundary_vertex(i); 2])
                .collect();
            system.fix_dofs(&fixed);
        }
        system
    }

    pub fn n_slabs(&self) -> usize {
        self.blocks.len()
    }

    /// `2V`: unknowns per slab.
    pub fn slab_dimension(&self) -> usize {
        self.pattern.dimension()
    }

    /// `S · 2V`.
    pub fn dimension(&self) -> usize {
        self.n_slabs() * self.slab_dimension()
    }

    /// The full vertex pattern: the consistent links' (products with [`LinkMatrix::mul`]), and
    /// the one to order the slab factors by (a fill-reducing ordering needs both triangles).
    pub fn pattern(&self) -> &VertexPattern {
        &self.pattern
    }

    /// The symbolic Cholesky analysis of the slab blocks (METIS's nested dissection of
    /// [`Self::pattern`]'s vertices, two DOFs each), which every slab factor of the system and
    /// of its coarse levels and windows uses; made once, beside the assembly.
    pub fn slab_symbolic(&self) -> &Arc<SymbolicCholesky<usize>> {
        self.slab_analysis
            .get_or_init(|| analyze(self.pattern.symbolic().as_ref(), 2))
    }

    /// The pattern of the diagonal blocks: [`Self::pattern`]'s blocks `i ≥ j`.
    pub fn block_pattern(&self) -> &VertexPattern {
        &self.lower
    }

    /// Diagonal block `s`, by its vertex blocks `i ≥ j` ([`Self::block_pattern`]): its lower
    /// triangle, which is what a Cholesky factorization reads, and one entry above the diagonal
    /// per vertex.
    pub fn block(&self, s: usize) -> SparseMatrixRef<'_> {
        self.lower.view(&self.blocks[s])
    }

    /// The values of the mean of the diagonal blocks `slabs` (on [`Self::block_pattern`]).
    pub fn mean_block(&self, slabs: std::ops::Range<usize>) -> Vec<f64> {
        let weight = 1.0 / slabs.len() as f64;
        let mut mean = vec![0.0; self.lower.nnz()];
        for s in slabs {
            mean.iter_mut()
                .zip(&self.blocks[s])
                .for_each(|(m, v)| *m += weight * v);
        }
        mean
    }

    /// `X_s`, the block at `(s + 1, s)`.
    pub fn link(&self, s: usize) -> &LinkMatrix {
        &self.links[s]
    }

    pub fn has_links(&self) -> bool {
        !self.links.is_empty()
    }

    /// `b = −f`.
    pub fn rhs(&self) -> &[f64] {
        &self.rhs
    }

    /// `c = E(0)`.
    pub fn constant(&self) -> f64 {
        self.slab_constants.iter().sum()
    }

    /// Slabs `slabs` with the links that join them to the slabs outside: what one rank of a
    /// solve distributed over time windows holds. The window's system has its blocks (each with
    /// the diagonal parts of both its links), the links between them, their right-hand side
    /// and their part of the constant.
    pub fn window(&self, slabs: std::ops::Range<usize>) -> SystemWindow {
        self.clone().into_window(slabs)
    }

    /// [`Self::window`], moving the window's blocks and links out instead of copying them.
    pub fn into_window(mut self, slabs: std::ops::Range<usize>) -> SystemWindow {
        let n = self.slab_dimension();
        let (a, b, n_slabs) = (slabs.start, slabs.end, self.n_slabs());
        let link = |links: &[LinkMatrix], s: Option<usize>| s.and_then(|s| links.get(s)).cloned();
        let link_before = link(&self.links, a.checked_sub(1));
        let link_after = link(&self.links, (b < n_slabs).then(|| b - 1));
        let inner_links = match self.has_links() {
            true => self.links.drain(a..b - 1).collect(),
            false => Vec::new(),
        };
        SystemWindow {
            system: SpaceTimeSystem {
                pattern: self.pattern,
                lower: self.lower,
                blocks: self.blocks.drain(slabs.clone()).collect(),
                links: inner_links,
                rhs: self.rhs[a * n..b * n].to_vec(),
                slab_constants: self.slab_constants[slabs.clone()].to_vec(),
                slab_analysis: self.slab_analysis,
            },
            slabs,
            n_slabs_in_all: n_slabs,
            link_before,
            link_after,
        }
    }

    /// `y = A x`, parallel over slabs.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.apply_rows(x, y, |_| true);
    }

    /// `y_s = (A x)_s` for the slabs `s` that `rows` accepts, `y_s = 0` for the others.
    pub fn apply_rows(&self, x: &[f64], y: &mut [f64], rows: impl Fn(usize) -> bool + Sync) {
        let n = self.slab_dimension();
        y.par_chunks_mut(n).enumerate().for_each(|(s, ys)| {
            if !rows(s) {
                ys.fill(0.0);
                return;
            }
            symmetric_mul(self.block(s), &x[s * n..(s + 1) * n], ys);
            if s > 0 && self.has_links() {
                self.link_mul(s - 1, &x[(s - 1) * n..s * n], ys);
            }
            if s < self.links.len() {
                self.link_transpose_mul(s, &x[(s + 1) * n..(s + 2) * n], ys);
            }
        });
    }

    /// `ys += X_s x`.
    pub fn link_mul(&self, s: usize, x: &[f64], ys: &mut [f64]) {
        self.links[s].mul(&self.pattern, x, ys);
    }

    /// `ys += X_sᵀ x`.
    pub fn link_transpose_mul(&self, s: usize, x: &[f64], ys: &mut [f64]) {
        self.links[s].transpose_mul(&self.pattern, x, ys);
    }

    /// `E(u) = uᵀAu − 2bᵀu + c`.
    pub fn energy(&self, u: &[f64]) -> f64 {
        let mut au = vec![0.0; u.len()];
        self.apply(u, &mut au);
        dot(u, &au) - 2.0 * dot(&self.rhs, u) + self.constant()
    }

    /// The diagonal of `A`.
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.n_slabs())
            .flat_map(|s| {
                let mut d = vec![0.0; self.slab_dimension()];
                for_each_column(self.block(s), |j, rows, values| {
                    d[j] = rows
                        .iter()
                        .zip(values)
                        .filter(|(&i, _)| i == j)
                        .map(|(_, &v)| v)
                        .sum();
                });
                d
            })
            .collect()
    }

    /// The whole of `A` as one sparse matrix (for the direct solver).
    pub fn to_sparse(&self) -> SparseMatrix {
        let n = self.slab_dimension();
        let mut triplets = Vec::new();
        for (s, block) in self.blocks.iter().enumerate() {
            for (i, j, slots) in vertex_blocks(&self.lower) {
                for (k, &p) in slots.iter().enumerate() {
                    let (r, c) = (2 * i + k / 2, 2 * j + k % 2);
                    let at = |r, c| faer::sparse::Triplet::new(s * n + r, s * n + c, block[p]);
                    triplets.push(at(r, c));
                    if i != j {
                        triplets.push(at(c, r));
                    }
                }
            }
        }
        let mut push = |m: SparseMatrixRef<'_>, row0: usize, col0: usize, transpose: bool| {
            for_each_column(m, |j, rows, values| {
                for (&i, &v) in rows.iter().zip(values) {
                    let (r, c) = if transpose { (j, i) } else { (i, j) };
                    triplets.push(faer::sparse::Triplet::new(row0 + r, col0 + c, v));
                }
            })
        };
        for (s, link) in self.links.iter().enumerate() {
            let lumped;
            let m = match link {
                LinkMatrix::Consistent(link) => self.pattern.view(&link.cross),
                LinkMatrix::Lumped(blocks) => {
                    lumped = block_diagonal(blocks);
                    lumped.as_ref()
                }
            };
            push(m, (s + 1) * n, s * n, false);
            push(m, s * n, (s + 1) * n, true);
        }
        SparseMatrix::try_new_from_triplets(self.dimension(), self.dimension(), &triplets)
            .expect("space-time triplets are in range")
    }

    /// Identity rows and columns and zero right-hand side for the DOFs marked in `fixed`
    /// (`2V` flags, the same in every slab).
    fn fix_dofs(&mut self, fixed: &[bool]) {
        let n = self.slab_dimension();
        for block in &mut self.blocks {
            mask(&self.lower, block, fixed, true);
        }
        for link in &mut self.links {
            match link {
                LinkMatrix::Consistent(link) => {
                    for values in link.parts_mut() {
                        mask(&self.pattern, values, fixed, false);
                    }
                }
                LinkMatrix::Lumped(blocks) => {
                    for (i, b) in blocks.iter_mut().enumerate() {
                        if fixed[2 * i] {
                            *b = Matrix2::zeros();
                        }
                    }
                }
            }
        }
        for (k, b) in self.rhs.iter_mut().enumerate() {
            if fixed[k % n] {
                *b = 0.0;
            }
        }
    }
}

/// A slab's link to its neighbour in time and that neighbour, if there is one.
type Neighbour<'a> = Option<(&'a TimeLink, &'a Slab)>;

/// Assembles diagonal block, right-hand side and energy constant of one slab.
fn assemble_slab(
    mesh: &Mesh,
    pattern: &VertexPattern,
    slab: &Slab,
    (link_before, link_after): (Neighbour, Neighbour),
    params: &FlowParams,
    weights: &Weights,
) -> (Vec<f64>, Vec<f64>, f64) {
    let coupling = params.time_coupling;
    let mut values = pattern.zero_values();
    let mut rhs = vec![0.0; pattern.dimension()];
    let mut constant = 0.0;
    for (f, face) in mesh.faces().iter().enumerate() {
        let e = slab.face_elements(face, f, &params.regularizer);
        // The speed term and the links' parts are scalar forms under this slab's transports:
        // summed, then transported once.
        let mut scalar = e.mass * (weights.beta * slab.dt);
        if let Some((link, previous)) = link_before {
            scalar += link.scalar_element(previous, slab, f, coupling);
        }
        if let Some((link, next)) = link_after {
            scalar += link.scalar_element(slab, next, f, coupling);
        }
        let a = (e.data.quadratic + e.stiffness * weights.gamma) * slab.dt
            + slab.vector_form_element(f, &scalar);
        pattern.add_element(f, &a, &mut values);
        for (corner, &v) in face.iter().enumerate() {
            for r in 0..2 {
                rhs[2 * v as usize + r] -= slab.dt * e.data.linear[2 * corner + r];
            }
        }
        constant += slab.dt * e.data.constant;
    }
    (values, rhs, constant)
}

fn assemble_link(
    mesh: &Mesh,
    pattern: &VertexPattern,
    link: &TimeLink,
    before: &Slab,
    after: &Slab,
    coupling: TimeCoupling,
) -> LinkMatrix {
    let cross = |f| link.cross_element(before, after, f, coupling);
    match coupling {
        TimeCoupling::Lumped => {
            let mut blocks = vec![Matrix2::zeros(); mesh.n_vertices()];
            for (f, face) in mesh.faces().iter().enumerate() {
                let x = link.lumped_cross_blocks(before, after, f);
                for (corner, &v) in face.iter().enumerate() {
                    blocks[v as usize] += x[corner];
                }
            }
            LinkMatrix::Lumped(blocks)
        }
        TimeCoupling::Consistent => {
            let part = |slab| {
                let element = |f| link.diagonal_element(before, after, slab, f, coupling);
                pattern.assemble_values(mesh.n_faces(), element)
            };
            LinkMatrix::Consistent(ConsistentLink {
                cross: pattern.assemble_values(mesh.n_faces(), cross),
                before: part(before),
                after: part(after),
            })
        }
    }
}

/// `ys += B x` (or `Bᵀ x`) for the block-diagonal `B` with 2×2 `blocks`.
fn add_block_diagonal_mul(blocks: &[Matrix2<f64>], transpose: bool, x: &[f64], ys: &mut [f64]) {
    for (i, b) in blocks.iter().enumerate() {
        let xi = nalgebra::Vector2::new(x[2 * i], x[2 * i + 1]);
        let v = if transpose {
            b.transpose() * xi
        } else {
            b * xi
        };
        ys[2 * i] += v.x;
        ys[2 * i + 1] += v.y;
    }
}

/// `y = A x` for symmetric `A` given by its 2×2 vertex blocks `B = A_ij`, `i ≥ j` (on a lower
/// [`VertexPattern`], where columns `2j` and `2j + 1` list the same rows in pairs): each adds
/// `B x_j` to `y_i` and, off the diagonal, `Bᵀ x_i` to `y_j`. Block by block, so that each pair
/// of rows reads one row index.
fn symmetric_mul(a: SparseMatrixRef<'_>, x: &[f64], y: &mut [f64]) {
    let (symbolic, values) = a.parts();
    let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
    y.fill(0.0);
    for j in 0..col_ptr.len() / 2 {
        let (first, second) = (col_ptr[2 * j], col_ptr[2 * j + 1]);
        let (left, right) = (&values[first..second], &values[second..2 * second - first]);
        let xj = [x[2 * j], x[2 * j + 1]];
        let mut mirrored = [0.0; 2];
        for ((rows, b0), b1) in (row_idx[first..second].chunks_exact(2))
            .zip(left.chunks_exact(2))
            .zip(right.chunks_exact(2))
        {
            let i = rows[0];
            y[i] += b0[0] * xj[0] + b1[0] * xj[1];
            y[i + 1] += b0[1] * xj[0] + b1[1] * xj[1];
            if i != 2 * j {
                mirrored[0] += b0[0] * x[i] + b0[1] * x[i + 1];
                mirrored[1] += b1[0] * x[i] + b1[1] * x[i + 1];
            }
        }
        y[2 * j] += mirrored[0];
        y[2 * j + 1] += mirrored[1];
    }
}

/// Calls `f(j, row indices, values)` for every column `j`.
pub(crate) fn for_each_column(a: SparseMatrixRef<'_>, mut f: impl FnMut(usize, &[usize], &[f64])) {
    let (symbolic, values) = a.parts();
    let col_ptr = symbolic.col_ptr();
    for j in 0..a.ncols() {
        let range = col_ptr[j]..col_ptr[j + 1];
        f(j, &symbolic.row_idx()[range.clone()], &values[range]);
    }
}

/// Zeroes the entries (values on `pattern`) in fixed rows or columns; with `unit_diagonal`,
/// puts 1 on their diagonal.
fn mask(pattern: &VertexPattern, values: &mut [f64], fixed: &[bool], unit_diagonal: bool) {
    let (col_ptr, row_idx) = (pattern.symbolic().col_ptr(), pattern.symbolic().row_idx());
    for j in 0..col_ptr.len() - 1 {
        for k in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[k];
            if fixed[i] || fixed[j] {
                values[k] = if unit_diagonal && i == j { 1.0 } else { 0.0 };
            }
        }
    }
}

fn block_diagonal(blocks: &[Matrix2<f64>]) -> SparseMatrix {
    let triplets: Vec<_> = blocks
        .iter()
        .enumerate()
        .flat_map(|(i, b)| {
            (0..4).map(move |k| {
                faer::sparse::Triplet::new(2 * i + k % 2, 2 * i + k / 2, b[(k % 2, k / 2)])
            })
        })
        .collect();
    let n = 2 * blocks.len();
    SparseMatrix::try_new_from_triplets(n, n, &triplets)
        .expect("block-diagonal triplets are in range")
}

/// Deterministic parallel dot product (fixed chunking, so results do not depend on scheduling).
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.par_chunks(8192)
        .zip(y.par_chunks(8192))
        .map(|(a, b)| a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>())
        .collect::<Vec<f64>>()
        .iter()
        .sum()
}

/// Semi-coarsening in time: the Galerkin product `Pᵀ A P` for the prolongation that merges
/// slabs `2k` and `2k + 1` into coarse slab `k`, `u_{2k} = ũ_k`, `u_{2k+1} = T_k ũ_k`, with
/// `T_k` a 2×2 rotation per vertex (an odd last slab stays alone, `u_{2k} = ũ_k`).
///
/// ```text
/// D̃_k = D_{2k} + T_kᵀ D_{2k+1} T_k + T_kᵀ X_{2k} + X_{2k}ᵀ T_k       X̃_k = X_{2k+1} T_k
/// ```
///
/// Both keep the vertex pattern (and a lumped link stays lumped), so a coarse system is again a
/// [`SpaceTimeSystem`]; it has no right-hand side and no energy constant (a consistent link's
/// parts follow: `B̃_k = T_kᵀ B_{2k+1} T_k`, `Ã_k = A_{2k+1}`). The links are then halved with
/// their share of the diagonal blocks ([`LinkMatrix::halve`]): the coarse system is `Pᵀ A P`
/// less half its time coupling.
impl SpaceTimeSystem {
    /// `T_k` for every pair: per vertex, the rotation that minimizes the link energy of
    /// `X_{2k}` for fields transported as `u_{2k+1} = T u_{2k}`, the polar factor of `−X_ii`
    /// (the identity where the link vanishes, e.g. at Dirichlet vertices).
    pub(crate) fn pair_transports(&self) -> Vec<Vec<Matrix2<f64>>> {
        (0..self.n_slabs() / 2)
            .into_par_iter()
            .map(|k| {
                let diagonal = self.link_diagonal_blocks(2 * k);
                diagonal.iter().map(|x| polar_rotation(&-x)).collect()
            })
            .collect()
    }

    /// The diagonal 2×2 blocks `(X_s)_ii`.
    fn link_diagonal_blocks(&self, s: usize) -> Vec<Matrix2<f64>> {
        match &self.links[s] {
            LinkMatrix::Lumped(blocks) => blocks.clone(),
            LinkMatrix::Consistent(link) => {
                let mut diagonal = vec![Matrix2::zeros(); self.pattern.dimension() / 2];
                for_each_vertex_block(&self.pattern, &link.cross, |i, j, block| {
                    if i == j {
                        diagonal[i] = block;
                    }
                });
                diagonal
            }
        }
    }

    /// `Pᵀ A P` for the pair transports `transports` (from [`Self::pair_transports`]).
    pub(crate) fn merge_slab_pairs(&self, transports: &[Vec<Matrix2<f64>>]) -> SpaceTimeSystem {
        let n_coarse = self.n_slabs().div_ceil(2);
        let blocks = (0..n_coarse)
            .into_par_iter()
            .map(|k| match transports.get(k) {
                Some(t) => self.merged_block(k, t),
                None => self.blocks[2 * k].clone(),
            })
            .collect();
        let links = (0..n_coarse - 1)
            .into_par_iter()
            .map(|k| self.right_multiplied_link(2 * k + 1, &transports[k]))
            .collect();
        let mut coarse = SpaceTimeSystem {
            pattern: self.pattern.clone(),
            lower: self.lower.clone(),
            blocks,
            links,
            rhs: Vec::new(),
            slab_constants: Vec::new(),
            slab_analysis: self.slab_analysis.clone(),
        };
        coarse.halve_time_coupling();
        coarse
    }

    /// Halves the coupling energy of every link ([`LinkMatrix::halve`]): the coarse level's
    /// time step is twice the fine one's, and its weight `γ / (α² h)` half. Parallel over the
    /// blocks: block `s` takes the share after link `s − 1` and the share before link `s`.
    fn halve_time_coupling(&mut self) {
        self.links.par_iter_mut().for_each(LinkMatrix::halve);
        let (links, patterns) = (&self.links, (&*self.lower, &*self.pattern));
        self.blocks
            .par_iter_mut()
            .enumerate()
            .for_each(|(s, block)| {
                if let Some(link) = s.checked_sub(1).and_then(|k| links.get(k)) {
                    subtract_share(patterns, block, &link.share(Side::After));
                }
                if let Some(link) = links.get(s) {
                    subtract_share(patterns, block, &link.share(Side::Before));
                }
            });
    }

    /// `D_s −= share`.
    fn subtract_share(&mut self, s: usize, share: &DiagonalShare) {
        subtract_share((&self.lower, &self.pattern), &mut self.blocks[s], share);
    }

    /// `D_{2k} + Tᵀ D_{2k+1} T + Tᵀ X_{2k} + X_{2k}ᵀ T`.
    fn merged_block(&self, k: usize, t: &[Matrix2<f64>]) -> Vec<f64> {
        let mut merged = map_vertex_blocks(&self.lower, &self.blocks[2 * k + 1], |i, j, d| {
            t[i].transpose() * d * t[j]
        });
        merged
            .iter_mut()
            .zip(&self.blocks[2 * k])
            .for_each(|(m, d)| *m += d);
        match &self.links[2 * k] {
            LinkMatrix::Lumped(x) => update_vertex_diagonal(&self.lower, &mut merged, |i, m| {
                let coupling = t[i].transpose() * x[i];
                m + coupling + coupling.transpose()
            }),
            LinkMatrix::Consistent(link) => {
                let tx =
                    map_vertex_blocks(&self.pattern, &link.cross, |i, _, x| t[i].transpose() * x);
                let txt = transposed_values(&self.pattern, &tx);
                let sum: Vec<f64> = tx.iter().zip(&txt).map(|(a, b)| a + b).collect();
                (merged.iter_mut())
                    .zip(self.lower.lower_part_of(&self.pattern, &sum))
                    .for_each(|(m, v)| *m += v);
            }
        }
        merged
    }

    /// `X_s T` for a block-diagonal `T`.
    fn right_multiplied_link(&self, s: usize, t: &[Matrix2<f64>]) -> LinkMatrix {
        self.links[s].right_multiplied(&self.pattern, t)
    }
}

/// What a link adds to one of the diagonal blocks it joins: one 2×2 block per vertex, or values
/// on the vertex pattern (a consistent link's own part, borrowed).
enum DiagonalShare<'a> {
    Vertex(Vec<Matrix2<f64>>),
    Pattern(&'a [f64]),
}

/// Which of the two diagonal blocks a link joins: the slab's before it or after it.
#[derive(Clone, Copy)]
enum Side {
    Before,
    After,
}

/// `D −= share` for a diagonal block's values `block` on `lower`, the blocks `i ≥ j` of `full`
/// (on which a consistent link's parts lie).
fn subtract_share(
    (lower, full): (&VertexPattern, &VertexPattern),
    block: &mut [f64],
    share: &DiagonalShare,
) {
    match share {
        DiagonalShare::Vertex(blocks) => update_vertex_diagonal(lower, block, |i, d| d - blocks[i]),
        DiagonalShare::Pattern(values) => (block.iter_mut())
            .zip(lower.lower_part_of(full, values))
            .for_each(|(d, v)| *d -= v),
    }
}

impl LinkMatrix {
    /// Halves the link's coupling energy: `X ← X / 2`; the caller then subtracts the halved
    /// link's shares of the diagonal blocks ([`Self::share`]) from the blocks of the slabs
    /// before and after the link.
    ///
    /// Why: the Galerkin product `Pᵀ A P` of the piecewise-constant prolongation keeps the
    /// fine coupling weight `c` between coarse slabs, while a coarse slab spans twice the time
    /// step and rediscretization gives `c / 2`: the coarse level is twice too stiff in time,
    /// and a V-cycle compounds that error level by level (iterations grew with the number of
    /// frames: 17, 25, 42, 58 at 20, 40, 100, 200 frames, 64×48 torus, `α = 0.01`). The
    /// energy taken off, `[u_a; u_b]ᵀ [S_a Xᵀ; X S_b] [u_a; u_b]`, is positive semidefinite and
    /// no more than half the link's, so the coarse operator stays positive definite.
    fn halve(&mut self) {
        match self {
            LinkMatrix::Lumped(blocks) => blocks.iter_mut().for_each(|x| *x *= 0.5),
            LinkMatrix::Consistent(link) => {
                for part in link.parts_mut() {
                    part.iter_mut().for_each(|v| *v *= 0.5);
                }
            }
        }
    }

    /// The link's share of the diagonal block on `side`, for [`Self::halve`]: a consistent
    /// link's own part (`B` before, `A` after); for a lumped one, `|X|` before and `|Xᵀ|` after
    /// per vertex (`|X| = (XᵀX)^½`), since a lumped link does not keep its parts.
    /// `E(u_a, u_b) = u_aᵀ|X|u_a + u_bᵀ|Xᵀ|u_b + 2 u_bᵀ X u_a` is positive semidefinite (with
    /// the polar decomposition `X = U |X|`, `E = ‖|X|^½ (u_a + Uᵀ u_b)‖²`), and the lumped
    /// link's true part `c m_i I` dominates `|X|` (`X_ii` is `−c m_i` times a mean of
    /// rotations).
    fn share(&self, side: Side) -> DiagonalShare<'_> {
        match (self, side) {
            (LinkMatrix::Lumped(blocks), side) => {
                let square = |x: &Matrix2<f64>| match side {
                    Side::Before => x.transpose() * x,
                    Side::After => x * x.transpose(),
                };
                DiagonalShare::Vertex(blocks.iter().map(|x| spd_sqrt(&square(x))).collect())
            }
            (LinkMatrix::Consistent(link), Side::Before) => DiagonalShare::Pattern(&link.before),
            (LinkMatrix::Consistent(link), Side::After) => DiagonalShare::Pattern(&link.after),
        }
    }

    /// The link between `u_a = T ũ_a` and `u_b`, for a block-diagonal `T` (one 2×2 block per
    /// vertex): `X T`, and a consistent link's part before becomes `Tᵀ B T`.
    fn right_multiplied(&self, pattern: &VertexPattern, t: &[Matrix2<f64>]) -> LinkMatrix {
        match self {
            LinkMatrix::Lumped(x) => {
                LinkMatrix::Lumped(x.iter().zip(t).map(|(x, t)| x * t).collect())
            }
            LinkMatrix::Consistent(link) => LinkMatrix::Consistent(ConsistentLink {
                cross: map_vertex_blocks(pattern, &link.cross, |_, j, x| x * t[j]),
                before: map_vertex_blocks(pattern, &link.before, |i, j, b| {
                    t[i].transpose() * b * t[j]
                }),
                after: link.after.clone(),
            }),
        }
    }

    /// The link as numbers to send to another rank: `[0, blocks…]` (lumped, 4 per vertex,
    /// column-major) or `[1, X…, B…, A…]` (consistent).
    pub fn to_message(&self) -> Vec<f64> {
        match self {
            LinkMatrix::Lumped(blocks) => std::iter::once(0.0)
                .chain(blocks.iter().flat_map(|b| b.iter().copied()))
                .collect(),
            LinkMatrix::Consistent(link) => {
                [&[1.0][..], &link.cross, &link.before, &link.after].concat()
            }
        }
    }

    /// The link of a [`Self::to_message`] (`None` for an empty message: no link).
    pub fn from_message(message: &[f64]) -> Option<LinkMatrix> {
        let (kind, values) = message.split_first()?;
        Some(match *kind == 0.0 {
            true => LinkMatrix::Lumped(
                values
                    .chunks_exact(4)
                    .map(Matrix2::from_column_slice)
                    .collect(),
            ),
            false => {
                let mut parts = values.chunks_exact(values.len() / 3).map(<[f64]>::to_vec);
                let mut next = || parts.next().unwrap_or_default();
                LinkMatrix::Consistent(ConsistentLink {
                    cross: next(),
                    before: next(),
                    after: next(),
                })
            }
        })
    }
}

/// Slab pairs across ranks: the distributed multigrid in time pairs slabs `(2k, 2k + 1)` of the
/// whole sequence, and coarse slab `k` belongs to the rank that owns slab `2k`. A window
/// `[a, b)` that starts at an odd slab lends slab `a` (its block and the link after it,
/// [`Self::first_slab_message`]) to the rank before, and one that ends at an odd `b` borrows
/// slab `b` from the rank after; its pairs `[a', b')` (`a'` even) are then its own, and
/// [`Self::merge_slab_pairs`] forms their `Pᵀ A P` as [`SpaceTimeSystem::merge_slab_pairs`]
/// does for the whole system.
impl SystemWindow {
    /// The first slab's block values and the link after it ([`LinkMatrix::to_message`]; none
    /// at the sequence's end).
    pub(crate) fn first_slab_message(&self) -> Vec<f64> {
        let link = match self.system.n_slabs() {
            1 => self.link_after.as_ref(),
            _ => self.system.links.first(),
        };
        let link = link.map(LinkMatrix::to_message).unwrap_or_default();
        [&self.system.blocks[0][..], &link].concat()
    }

    /// Sets the coarse link from the rank before (computed and halved there by
    /// [`Self::merge_slab_pairs`]) and takes its share of the halved coupling off the first
    /// block, as [`SpaceTimeSystem::merge_slab_pairs`] does inside a whole system.
    pub(crate) fn set_coarse_link_before(&mut self, link: Option<LinkMatrix>) {
        if let Some(link) = &link {
            self.system.subtract_share(0, &link.share(Side::After));
        }
        self.link_before = link;
    }

    /// Whether the window lends its first slab to the rank before (it starts at an odd slab).
    pub(crate) fn lends_first(&self) -> bool {
        self.slabs.start % 2 == 1
    }

    /// Whether the window borrows the first slab of the rank after (it ends at an odd slab
    /// that is not the sequence's end).
    pub(crate) fn borrows_next(&self) -> bool {
        self.slabs.end % 2 == 1 && self.slabs.end < self.n_slabs_in_all
    }

    /// The coarse window of the pairs `[a', b')` (its `link_before` is the coarse link the rank
    /// before computes: `None` here) and their transports `T_k`; `borrowed` is the rank
    /// after's [`Self::first_slab_message`] when [`Self::borrows_next`].
    pub(crate) fn merge_slab_pairs(
        &self,
        borrowed: Option<&[f64]>,
    ) -> (SystemWindow, Vec<Vec<Matrix2<f64>>>) {
        let lent = usize::from(self.lends_first());
        let own = &self.system;
        let mut blocks = own.blocks.get(lent..).unwrap_or_default().to_vec();
        let mut links = own.links.get(lent..).unwrap_or_default().to_vec();
        let mut link_after = self.link_after.clone();
        if let Some(message) = borrowed {
            let (block, link) = message.split_at(own.lower.nnz());
            blocks.push(block.to_vec());
            links.extend(link_after.take());
            link_after = LinkMatrix::from_message(link);
        }
        let start = self.slabs.start + lent;
        let paired = SpaceTimeSystem {
            pattern: own.pattern.clone(),
            lower: own.lower.clone(),
            blocks,
            links,
            rhs: Vec::new(),
            slab_constants: Vec::new(),
            slab_analysis: own.slab_analysis.clone(),
        };
        let transports = paired.pair_transports();
        let mut system = match paired.n_slabs() {
            0 => paired.clone(),
            _ => paired.merge_slab_pairs(&transports),
        };
        let link_after = match (link_after, transports.last()) {
            (Some(link), Some(t)) => {
                let mut link = link.right_multiplied(&own.pattern, t);
                link.halve();
                system.subtract_share(system.n_slabs() - 1, &link.share(Side::Before));
                Some(link)
            }
            _ => None,
        };
        let coarse = SystemWindow {
            system,
            slabs: start / 2..(start + paired.n_slabs()).div_ceil(2),
            n_slabs_in_all: self.n_slabs_in_all.div_ceil(2),
            link_before: None,
            link_after,
        };
        (coarse, transports)
    }
}

/// The square root of a symmetric positive semidefinite 2×2 matrix: `(S + √det S I) / √(tr S +
/// 2 √det S)` (Cayley–Hamilton), zero for `S = 0`.
fn spd_sqrt(s: &Matrix2<f64>) -> Matrix2<f64> {
    let root_det = s.determinant().max(0.0).sqrt();
    match (s.trace() + 2.0 * root_det).sqrt() {
        t if t > 0.0 => (s + Matrix2::identity() * root_det) / t,
        _ => Matrix2::zeros(),
    }
}

/// The rotation `R` of the polar decomposition `M = R S` of a 2×2 matrix (the identity for 0).
fn polar_rotation(m: &Matrix2<f64>) -> Matrix2<f64> {
    let angle = (m[(1, 0)] - m[(0, 1)]).atan2(m[(0, 0)] + m[(1, 1)]);
    let (s, c) = angle.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// Every stored 2×2 vertex block `(i, j)` of the pattern with the positions of its entries
/// `(0,0), (0,1), (1,0), (1,1)` (block size 2: columns `2j`, `2j + 1` list the same rows, in
/// pairs `2i`, `2i + 1`).
fn vertex_blocks(pattern: &VertexPattern) -> impl Iterator<Item = (usize, usize, [usize; 4])> + '_ {
    let (col_ptr, row_idx) = (pattern.symbolic().col_ptr(), pattern.symbolic().row_idx());
    (0..col_ptr.len() / 2).flat_map(move |j| {
        let (first, second) = (col_ptr[2 * j], col_ptr[2 * j + 1]);
        (first..second).step_by(2).map(move |p| {
            let q = second + (p - first);
            (row_idx[p] / 2, j, [p, q, p + 1, q + 1])
        })
    })
}

fn read_block(values: &[f64], [a, b, c, d]: [usize; 4]) -> Matrix2<f64> {
    Matrix2::new(values[a], values[b], values[c], values[d])
}

fn write_block(values: &mut [f64], [a, b, c, d]: [usize; 4], m: &Matrix2<f64>) {
    [values[a], values[b], values[c], values[d]] = [m[(0, 0)], m[(0, 1)], m[(1, 0)], m[(1, 1)]];
}

/// Calls `f(i, j, M_ij)` for every stored vertex block of `values` on `pattern`.
fn for_each_vertex_block(
    pattern: &VertexPattern,
    values: &[f64],
    mut f: impl FnMut(usize, usize, Matrix2<f64>),
) {
    vertex_blocks(pattern).for_each(|(i, j, slots)| f(i, j, read_block(values, slots)));
}

/// Replaces every diagonal vertex block `M_ii` of `values` by `f(i, M_ii)`, in place (a coarse
/// level's blocks are each updated a few times; new buffers would be fresh pages each time).
fn update_vertex_diagonal(
    pattern: &VertexPattern,
    values: &mut [f64],
    f: impl Fn(usize, Matrix2<f64>) -> Matrix2<f64>,
) {
    for (i, j, slots) in vertex_blocks(pattern) {
        if i == j {
            let m = f(i, read_block(values, slots));
            write_block(values, slots, &m);
        }
    }
}

/// The values of the matrix whose block `(i, j)` is `f(i, j, M_ij)`.
fn map_vertex_blocks(
    pattern: &VertexPattern,
    values: &[f64],
    f: impl Fn(usize, usize, Matrix2<f64>) -> Matrix2<f64>,
) -> Vec<f64> {
    let mut out = vec![0.0; values.len()];
    for (i, j, slots) in vertex_blocks(pattern) {
        write_block(&mut out, slots, &f(i, j, read_block(values, slots)));
    }
    out
}

/// The values of `Mᵀ` on the same (symmetric) pattern.
fn transposed_values(pattern: &VertexPattern, values: &[f64]) -> Vec<f64> {
    let (col_ptr, row_idx) = (pattern.symbolic().col_ptr(), pattern.symbolic().row_idx());
    let mut out = vec![0.0; values.len()];
    for j in 0..col_ptr.len() - 1 {
        for p in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[p];
            let column = &row_idx[col_ptr[i]..col_ptr[i + 1]];
            let q = col_ptr[i] + column.binary_search(&j).expect("the pattern is symmetric");
            out[q] = values[p];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::{slab, FlowProblem};

    /// The diagonal blocks kept by their vertex blocks `i ≥ j` are the full assembly's lower
    /// blocks exactly, the full assembly is symmetric (so the mirror loses nothing), and the
    /// product from the kept blocks is the full matrix's: for both time couplings.
    #[test]
    fn lower_blocks_are_the_symmetric_full_assembly_halved() {
        let sequence = crate::synth::paper_torus(12, 9, 4).unwrap();
        let mesh = sequence.mesh();
        let full = VertexPattern::new(mesh, 2);
        for coupling in [TimeCoupling::Lumped, TimeCoupling::Consistent] {
            let params = FlowParams {
                time_coupling: coupling,
                ..FlowParams::paper(0.5, 0.0, 1.0)
            };
            let problem = FlowProblem::new(&sequence, &params).unwrap();
            let (system, slabs, weights) = (problem.system(), problem.slabs(), problem.weights());
            assert_eq!(
                7 * system.lower.nnz(),
                4 * full.nnz(),
                "a torus: 4 of 7 blocks"
            );
            let links = slab::time_links(&slabs, weights);
            for s in 0..system.n_slabs() {
                let before = s.checked_sub(1).map(|p| (&links[p], &slabs[p]));
                let after = links.get(s).map(|link| (link, &slabs[s + 1]));
                let (values, _, _) =
                    assemble_slab(mesh, &full, &slabs[s], (before, after), &params, weights);
                let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let transposed = transposed_values(&full, &values);
                let asymmetry =
                    (values.iter().zip(&transposed)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                assert!(
                    asymmetry <= 1e-14 * largest,
                    "{coupling:?} slab {s}: {asymmetry:e}"
                );
                assert_eq!(system.lower.lower_part_of(&full, &values), system.blocks[s]);
                let x: Vec<f64> = (0..full.dimension())
                    .map(|k| (0.7 * k as f64).sin())
                    .collect();
                let mut whole = vec![0.0; x.len()];
                for_each_column(full.view(&values), |j, rows, column| {
                    rows.iter()
                        .zip(column)
                        .for_each(|(&i, &v)| whole[i] += v * x[j]);
                });
                let mut halved = vec![1.0; x.len()];
                symmetric_mul(system.block(s), &x, &mut halved);
                let error =
                    (whole.iter().zip(&halved)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                assert!(error <= 1e-13 * largest, "{coupling:?} slab {s}: {error:e}");
            }
        }
    }
}
