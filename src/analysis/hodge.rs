//! Helmholtz–Hodge decomposition of a face-wise constant tangent field (Polthier & Preuss,
//! "Identifying vector field singularities using a discrete Hodge decomposition", 2003).
//!
//! A field `U` constant on each face (here the mean of the face's corner vectors) splits as
//!
//! ```text
//! U = ∇φ + J∇ψ + h,
//! ```
//!
//! - **exact part** `∇φ`, `φ` a conforming P1 function (vertex values): the L²-projection of
//!   `U` onto gradients, `S φ = b`, `S = Σ_T A_T g_a·g_b` the cotan stiffness, `b_i = Σ_{T∋i}
//!   A_T g_i·U_T`; natural (Neumann) boundary, `φ` fixed at one vertex per component;
//! - **co-exact part** `J∇ψ`, `ψ` a non-conforming Crouzeix–Raviart function (edge-midpoint
//!   values, basis `χ_e = 1 − 2λ_c` on the faces of edge `e` opposite corner `c`): the
//!   projection of `U` onto rotated gradients, `K ψ = c`, `K = Σ_T A_T ∇χ_e·∇χ_f` (4 × the
//!   cotan weights of the opposite corners), `c_e = −Σ_{T∋e} A_T ∇χ_e·J U_T`; `ψ = 0` on
//!   boundary edges (Dirichlet), fixed at one edge of each closed component;
//! - **harmonic part** `h = U − ∇φ − J∇ψ`, what neither potential can carry.
//!
//! **Why the parts are L²-orthogonal.** On each face `∇φ·J∇ψ = −J∇φ·∇ψ`, and `J∇φ` is
//! divergence-free and constant, so `∫_T ∇φ·J∇ψ = −Σ_{e⊂∂T} ∫_e ψ (J∇φ·n_e)`. `J∇φ·n_e` is the
//! derivative of `φ` along `e`, the same from both faces of an interior edge (`φ` is
//! continuous) with opposite normals, and `∫_e ψ` is `|e| ψ_e` from both sides (`ψ` is linear
//! on `e` with the shared midpoint value): interior edges cancel, boundary edges vanish with
//! `ψ_e = 0`. So gradients and rotated gradients are orthogonal, each projection is the
//! orthogonal projection onto its space, and `h` is orthogonal to both. The harmonic space then
//! has dimension `2F − (V − c) − (E − c) = 2g` on a closed surface with `c` components of total
//! genus `g` (`F/2 = E/3`): none on a sphere, two on a torus; with a boundary it holds the
//! fields that circulate around holes or flow between boundary components.
//!
//! **How it is computed.** `φ` is one solve with the cotan stiffness `S`. `ψ` needs no second
//! solve when H¹ is small: the closed fields (face-wise constant with continuous tangential
//! components across interior edges) are exactly the orthogonal complement of `J∇ψ`, and they
//! are the gradients plus the fields `w_k` of the closed edge 1-forms that span H¹
//! ([`crate::mesh::TreeCotree`]; `w_k` per face is the gradient of the form's local
//! primitive). So the harmonic fields are `b_k = w_k − ∇φ_k` (one more solve each with the
//! same factor), `h` is the projection of `r = U − ∇φ` onto their span (a `k × k` Gram
//! system), and `r − h = J∇ψ` exactly, whence `ψ` follows by integrating
//! `∇ψ = −J(r − h)` from edge midpoint to edge midpoint across the faces, starting where
//! `ψ = 0`. On the paper-size torus this halves the analysis's time: the Crouzeix–Raviart
//! system (145,350 edges) cost more to factorize than the vertex system (48,450 vertices).
//! When H¹ has [`GENERATOR_LIMIT`] generators or more (a scan with many holes) a solve per generator
//! costs more than that factorization, and `ψ` is solved for with `K` instead; both give the
//! same parts (tested to 1e-9).
//!
//! The matrices keep their sparsity pattern from slab to slab: the pattern, where each face's
//! entries go, the symbolic analysis and the closed forms are made once per mesh
//! ([`HodgeSolver::new`]); each slab geometry scatters its values and factorizes, slabs in
//! parallel. The ordering is faer's approximate minimum degree, not the solver's METIS nested
//! dissection: on the paper-size torus grid METIS's ordering cost 0.18 s more to compute and
//! its factorizations were slower (0.078 s against 0.069 s per slab).

use crate::fem::element::cotan_stiffness;
use crate::fem::SparseMatrix;
use crate::flow::FlowError;
use crate::geometry::IntrinsicGeometry;
use crate::linalg::cholesky::{amd_order, analyze_in_order, CholeskyFactor};
use crate::mesh::{halfedge_sign, Mesh, TreeCotree};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, Triplet};
use faer::Par;
use nalgebra::{DMatrix, DVector, Vector2};
use std::sync::Arc;

/// The rotation by +90° in a face's counter-clockwise frame.
pub fn rotate_quarter(v: &Vector2<f64>) -> Vector2<f64> {
    Vector2::new(-v.y, v.x)
}

/// The three parts of a face-wise field and their potentials.
#[derive(Clone, Debug, PartialEq)]
pub struct HodgeParts {
    /// `U_T`, face frames.
    pub field: Vec<Vector2<f64>>,
    /// `∇φ` per face.
    pub exact: Vec<Vector2<f64>>,
    /// `J∇ψ` per face.
    pub coexact: Vec<Vector2<f64>>,
    /// `h = U − ∇φ − J∇ψ` per face.
    pub harmonic: Vec<Vector2<f64>>,
    /// `φ` per vertex (0 at the first vertex of each component).
    pub potential: Vec<f64>,
    /// `ψ` per edge (Crouzeix–Raviart midpoint values; 0 on the boundary).
    pub stream: Vec<f64>,
}

impl HodgeParts {
    /// `ψ` per vertex: the mean of its edges' values (for display; `ψ` itself lives on edges).
    pub fn stream_at_vertices(&self, mesh: &Mesh) -> Vec<f64> {
        let mut sum = vec![0.0; mesh.n_vertices()];
        let mut count = vec![0usize; mesh.n_vertices()];
        for (edge, &value) in mesh.edges().iter().zip(&self.stream) {
            for &i in edge {
                sum[i as usize] += value;
                count[i as usize] += 1;
            }
        }
        sum.iter().zip(&count).map(|(s, &c)| s / c as f64).collect()
    }
}

/// Which unknowns of a potential are free: `index[k] = Some(row)`.
struct FreeUnknowns {
    index: Vec<Option<usize>>,
    n_free: usize,
}

impl FreeUnknowns {
    fn new(n: usize, fixed: impl Fn(usize) -> bool) -> Self {
        let mut n_free = 0;
        let index = (0..n)
            .map(|k| {
                (!fixed(k)).then(|| {
                    n_free += 1;
                    n_free - 1
                })
            })
            .collect();
        FreeUnknowns { index, n_free }
    }

    /// The same unknowns with row `i` moved to `new_row[i]`.
    fn renumbered(self, new_row: &[usize]) -> Self {
        let index = (self.index.iter()).map(|i| i.map(|i| new_row[i])).collect();
        FreeUnknowns { index, ..self }
    }
}

/// The pattern that joins each face's free unknowns, the entries `(i, j)` with `keep(i, j)`.
fn joined_pattern(
    unknowns: &[[usize; 3]],
    free: &FreeUnknowns,
    keep: fn(usize, usize) -> bool,
) -> SymbolicSparseColMat<usize> {
    let triplets: Vec<Triplet<usize, usize, f64>> = (unknowns.iter())
        .flat_map(|u| {
            let r = u.map(|k| free.index[k]);
            (0..9).filter_map(move |ab| {
                let (i, j) = (r[ab / 3]?, r[ab % 3]?);
                keep(i, j).then(|| Triplet::new(i, j, 1.0))
            })
        })
        .collect();
    let n = free.n_free;
    let matrix = SparseMatrix::try_new_from_triplets(n, n, &triplets)
        .expect("triplets within the free unknowns");
    matrix.symbolic().to_owned().expect("a pattern copies")
}

/// The unknowns of face `f` for each system: its corners (vertices) and its corners' opposite
/// edges.
fn corner_vertices(mesh: &Mesh, f: usize) -> [usize; 3] {
    mesh.faces()[f].map(|v| v as usize)
}

fn opposite_edges(mesh: &Mesh, f: usize) -> [usize; 3] {
    // The edge opposite corner c is halfedge c + 1 (it runs b→c for c = a).
    std::array::from_fn(|c| mesh.halfedge_edge(3 * f + (c + 1) % 3))
}

/// One potential's system: the unknowns of each face's corners, which are free, the matrix's
/// pattern over the free ones (with each face entry's place in it) and its symbolic
/// factorization, all fixed by the connectivity.
struct PotentialSystem {
    unknowns: Vec<[usize; 3]>,
    free: FreeUnknowns,
    /// Gradient of the basis function of corner `c` = `scale · g_c`.
    scale: f64,
    pattern: SymbolicSparseColMat<usize>,
    /// `slots[f][a][b]`: where the entry between face `f`'s unknowns `a` and `b` is stored.
    slots: Vec<[[Option<usize>; 3]; 3]>,
    symbolic: Option<Arc<SymbolicCholesky<usize>>>,
}

impl PotentialSystem {
    /// The system over `free`, its rows renumbered into faer's approximate minimum degree
    /// order and only its lower triangle stored: each factorization then reads the values in
    /// place instead of permuting a copy of the matrix. (faer's symbolic analysis in a given
    /// order reads the upper triangle, its supernodal factorization the lower.)
    fn new(unknowns: Vec<[usize; 3]>, free: FreeUnknowns, scale: f64) -> Self {
        let n = free.n_free;
        let order =
            (n > 0).then(|| amd_order(joined_pattern(&unknowns, &free, |_, _| true).as_ref()));
        let free = match &order {
            Some(order) => free.renumbered(order),
            None => free,
        };
        let lower = |i, j| i >= j;
        let pattern = joined_pattern(&unknowns, &free, lower);
        let rows = |unknowns: &[usize; 3]| unknowns.map(|k| free.index[k]);
        let slot = |i: usize, j: usize| {
            let column = pattern.col_ptr()[j]..pattern.col_ptr()[j + 1];
            let position = pattern.row_idx()[column.clone()].binary_search(&i);
            column.start + position.expect("every entry is in the pattern")
        };
        let slots = (unknowns.iter())
            .map(|u| {
                let r = rows(u);
                std::array::from_fn(|a| {
                    std::array::from_fn(|b| match (r[a]?, r[b]?) {
                        (i, j) if lower(i, j) => Some(slot(i, j)),
                        _ => None,
                    })
                })
            })
            .collect();
        let symbolic = order
            .map(|_| analyze_in_order(joined_pattern(&unknowns, &free, |i, j| i <= j).as_ref()));
        PotentialSystem {
            unknowns,
            free,
            scale,
            pattern,
            slots,
            symbolic,
        }
    }

    /// The matrix's values on `geometry`: `Σ_T A_T ∇χ_a·∇χ_b = scale² S^T_ab`.
    fn values(&self, geometry: &IntrinsicGeometry) -> Vec<f64> {
        let mut values = vec![0.0; self.pattern.row_idx().len()];
        for (f, slots) in self.slots.iter().enumerate() {
            let s = cotan_stiffness(geometry.triangle(f)) * (self.scale * self.scale);
            for (a, row) in slots.iter().enumerate() {
                for (b, slot) in row.iter().enumerate() {
                    if let Some(slot) = slot {
                        values[*slot] += s[(a, b)];
                    }
                }
            }
        }
        values
    }

    /// The factorization of the matrix on `geometry` (`None` when every unknown is fixed).
    fn factorize(&self, geometry: &IntrinsicGeometry) -> Result<Option<CholeskyFactor>, FlowError> {
        let Some(symbolic) = &self.symbolic else {
            return Ok(None);
        };
        let entries = self.values(geometry);
        let matrix = SparseColMatRef::new(self.pattern.as_ref(), &entries);
        let factor = CholeskyFactor::<f64>::new(symbolic, matrix, Par::Seq).map_err(|detail| {
            FlowError::Factorization {
                what: "a Hodge potential".into(),
                detail,
            }
        })?;
        Ok(Some(factor))
    }

    /// The potentials whose basis gradients best fit each of `targets` per face, in least
    /// squares: `Σ_T A_T |Σ_c x_c scale g_c − target_T|²` minimal, with the matrix's `factor`
    /// (one triangular solve for all targets).
    fn solve(
        &self,
        factor: Option<&CholeskyFactor>,
        shape: &SlabShape,
        targets: &[&[Vector2<f64>]],
    ) -> Vec<Vec<f64>> {
        let mut values = vec![vec![0.0; self.free.index.len()]; targets.len()];
        let Some(factor) = factor else {
            return values;
        };
        let n = self.free.n_free;
        let mut rhs = vec![0.0; n * targets.len()];
        for (f, unknowns) in self.unknowns.iter().enumerate() {
            let weight = shape.geometry.triangle(f).area * self.scale;
            for (c, g) in shape.hat[f].iter().enumerate() {
                if let Some(i) = self.free.index[unknowns[c]] {
                    for (column, target) in targets.iter().enumerate() {
                        rhs[column * n + i] += weight * g.dot(&target[f]);
                    }
                }
            }
        }
        factor.solve_columns_in_place(&mut rhs, Par::Seq);
        for (column, values) in values.iter_mut().enumerate() {
            for (k, index) in self.free.index.iter().enumerate() {
                if let Some(i) = index {
                    values[k] = rhs[column * n + i];
                }
            }
        }
        values
    }

    /// `Σ_c x_c scale g_c` per face.
    fn gradients(&self, shape: &SlabShape, x: &[f64]) -> Vec<Vector2<f64>> {
        (self.unknowns.iter().zip(&shape.hat))
            .map(|(unknowns, g)| (0..3).map(|c| g[c] * (self.scale * x[unknowns[c]])).sum())
            .collect()
    }
}

/// A slab geometry with each face's hat gradients computed once for all uses.
struct SlabShape<'a> {
    geometry: &'a IntrinsicGeometry,
    hat: Vec<[Vector2<f64>; 3]>,
}

impl<'a> SlabShape<'a> {
    fn new(geometry: &'a IntrinsicGeometry) -> Self {
        let hat = geometry
            .triangles()
            .iter()
            .map(|t| t.hat_gradients())
            .collect();
        SlabShape { geometry, hat }
    }
}

/// From this many H¹ generators on, the co-exact potential is solved for with the
/// Crouzeix–Raviart system rather than integrated (a solve per generator would cost more than
/// that factorization; see the module documentation).
pub const GENERATOR_LIMIT: usize = 25;

/// Decomposes face-wise fields on one mesh, reusing the symbolic factorizations across
/// geometries (slabs).
pub struct HodgeSolver {
    exact: PotentialSystem,
    coexact: CoexactMethod,
}

/// How `ψ` is found (see the module documentation).
enum CoexactMethod {
    /// `J∇ψ = U − ∇φ − h`, with `h` from the closed forms spanning H¹, integrated along `plan`.
    Integrated {
        closed_forms: Vec<Vec<f64>>,
        plan: StreamPlan,
    },
    /// The Crouzeix–Raviart system `K ψ = c`.
    Solved(PotentialSystem),
}

impl HodgeSolver {
    pub fn new(mesh: &Mesh) -> Self {
        Self::with_generator_limit(mesh, GENERATOR_LIMIT)
    }

    /// [`Self::new`] choosing the Crouzeix–Raviart solve when H¹ has `limit` generators or
    /// more (`0`: always).
    pub fn with_generator_limit(mesh: &Mesh, limit: usize) -> Self {
        let components = mesh.connected_components();
        let mut vertex_pins = vec![false; mesh.n_vertices()];
        for component in &components {
            vertex_pins[component[0]] = true;
        }
        let exact = PotentialSystem::new(
            (0..mesh.n_faces())
                .map(|f| corner_vertices(mesh, f))
                .collect(),
            FreeUnknowns::new(mesh.n_vertices(), |i| vertex_pins[i]),
            1.0,
        );
        let edge_fixed = stream_fixed_edges(mesh, &components);
        let tree_cotree = TreeCotree::new(mesh);
        let coexact = match tree_cotree.n_generators() < limit {
            true => CoexactMethod::Integrated {
                closed_forms: tree_cotree.closed_forms(mesh),
                plan: StreamPlan::new(mesh, &edge_fixed),
            },
            // ∇χ_e = −2 g_c for the corner c opposite e.
            false => CoexactMethod::Solved(PotentialSystem::new(
                (0..mesh.n_faces())
                    .map(|f| opposite_edges(mesh, f))
                    .collect(),
                FreeUnknowns::new(mesh.n_edges(), |e| edge_fixed[e]),
                -2.0,
            )),
        };
        HodgeSolver { exact, coexact }
    }

    /// The decomposition of `field` (one face-frame vector per face) on `geometry`.
    pub fn decompose(
        &self,
        mesh: &Mesh,
        geometry: &IntrinsicGeometry,
        field: Vec<Vector2<f64>>,
    ) -> Result<HodgeParts, FlowError> {
        let shape = SlabShape::new(geometry);
        let factor = self.exact.factorize(geometry)?;
        let (potential, exact, stream) = match &self.coexact {
            CoexactMethod::Integrated { closed_forms, plan } => {
                let closed_fields: Vec<Vec<Vector2<f64>>> = (closed_forms.iter())
                    .map(|form| closed_form_field(mesh, &shape, form))
                    .collect();
                let targets: Vec<&[Vector2<f64>]> = std::iter::once(&field)
                    .chain(&closed_fields)
                    .map(|t| t.as_slice())
                    .collect();
                let mut potentials = self.exact.solve(factor.as_ref(), &shape, &targets);
                let potential = potentials.remove(0);
                // b_k = w_k − ∇φ_k: harmonic, as closed fields orthogonal to all gradients.
                let harmonic_basis: Vec<Vec<Vector2<f64>>> = (closed_fields.iter())
                    .zip(&potentials)
                    .map(|(w, x)| difference(w, &self.exact.gradients(&shape, x)))
                    .collect();
                let exact = self.exact.gradients(&shape, &potential);
                let rest = difference(&field, &exact);
                let harmonic = project(geometry, &rest, &harmonic_basis)?;
                let gradient: Vec<Vector2<f64>> = (rest.iter().zip(&harmonic))
                    .map(|(r, h)| -rotate_quarter(&(r - h)))
                    .collect();
                (potential, exact, plan.integrate(mesh, &shape, &gradient))
            }
            CoexactMethod::Solved(system) => {
                let potential = self.exact.solve(factor.as_ref(), &shape, &[&field]);
                // J∇ψ ≈ U  ⇔  ∇ψ ≈ −J U.
                let turned: Vec<Vector2<f64>> = field.iter().map(|u| -rotate_quarter(u)).collect();
                let stream = system.solve(system.factorize(geometry)?.as_ref(), &shape, &[&turned]);
                let potential = potential.concat();
                let exact = self.exact.gradients(&shape, &potential);
                (potential, exact, stream.concat())
            }
        };
        let coexact: Vec<Vector2<f64>> = (stream_gradients(mesh, &shape, &stream).iter())
            .map(rotate_quarter)
            .collect();
        let harmonic = (0..field.len())
            .map(|f| field[f] - exact[f] - coexact[f])
            .collect();
        Ok(HodgeParts {
            field,
            exact,
            coexact,
            harmonic,
            potential,
            stream,
        })
    }
}

/// `a − b` face by face.
fn difference(a: &[Vector2<f64>], b: &[Vector2<f64>]) -> Vec<Vector2<f64>> {
    a.iter().zip(b).map(|(a, b)| a - b).collect()
}

/// `ψ = 0` on boundary edges; a closed component's first vertex's first edge pins it.
fn stream_fixed_edges(mesh: &Mesh, components: &[Vec<usize>]) -> Vec<bool> {
    let mut fixed = vec![false; mesh.n_edges()];
    for h in (0..mesh.n_halfedges()).filter(|&h| mesh.is_boundary_halfedge(h)) {
        fixed[mesh.halfedge_edge(h)] = true;
    }
    for component in components {
        if component.iter().all(|&i| !mesh.is_boundary_vertex(i)) {
            let corner = mesh.vertex_fan(component[0])[0];
            fixed[mesh.halfedge_edge(corner.first_halfedge())] = true;
        }
    }
    fixed
}

/// `∇ψ` per face of the Crouzeix–Raviart function with edge values `stream`
/// (`∇χ_e = −2 g_c`, `c` the corner opposite `e`).
fn stream_gradients(mesh: &Mesh, shape: &SlabShape, stream: &[f64]) -> Vec<Vector2<f64>> {
    (0..mesh.n_faces())
        .map(|f| {
            let g = shape.hat[f];
            let edges = opposite_edges(mesh, f);
            (0..3).map(|c| g[c] * (-2.0 * stream[edges[c]])).sum()
        })
        .collect()
}

/// The face-wise field of a closed 1-form: in each face the gradient of its local primitive
/// `x_a = 0, x_b = ω(a→b), x_c = ω(a→b) + ω(b→c)`.
fn closed_form_field(mesh: &Mesh, shape: &SlabShape, form: &[f64]) -> Vec<Vector2<f64>> {
    (0..mesh.n_faces())
        .map(|f| {
            let along = |h: usize| halfedge_sign(mesh, h) * form[mesh.halfedge_edge(h)];
            let x_b = along(3 * f);
            let x_c = x_b + along(3 * f + 1);
            let g = shape.hat[f];
            g[1] * x_b + g[2] * x_c
        })
        .collect()
}

/// The L²-orthogonal projection of `field` onto the span of `basis` (face-wise fields):
/// `Σ_k c_k b_k` with `G c = (⟨b_k, field⟩)`, `G_kl = ⟨b_k, b_l⟩`.
fn project(
    geometry: &IntrinsicGeometry,
    field: &[Vector2<f64>],
    basis: &[Vec<Vector2<f64>>],
) -> Result<Vec<Vector2<f64>>, FlowError> {
    let n = basis.len();
    let gram = DMatrix::from_fn(n, n, |k, l| inner_product(geometry, &basis[k], &basis[l]));
    let moments = DVector::from_fn(n, |k, _| inner_product(geometry, &basis[k], field));
    let coefficients = match gram.cholesky() {
        Some(cholesky) => cholesky.solve(&moments),
        None if n == 0 => moments,
        None => {
            return Err(FlowError::Factorization {
                what: "the harmonic fields' Gram matrix".into(),
                detail: "not positive definite".into(),
            })
        }
    };
    Ok((0..field.len())
        .map(|f| (0..n).map(|k| basis[k][f] * coefficients[k]).sum())
        .collect())
}

/// The order in which `ψ` is integrated: from the edges where it is fixed (0) across faces,
/// each step carrying it from one edge midpoint of a face to another.
struct StreamPlan {
    /// `(face, from, to)`: local halfedges of the face; `to`'s edge is set from `from`'s.
    steps: Vec<(usize, usize, usize)>,
}

impl StreamPlan {
    fn new(mesh: &Mesh, fixed: &[bool]) -> Self {
        let mut known = fixed.to_vec();
        let mut entered = vec![None; mesh.n_faces()];
        let mut queue = Vec::with_capacity(mesh.n_faces());
        let enter = |h: usize, entered: &mut Vec<Option<usize>>, queue: &mut Vec<usize>| {
            if entered[h / 3].is_none() {
                entered[h / 3] = Some(h % 3);
                queue.push(h / 3);
            }
        };
        for h in (0..mesh.n_halfedges()).filter(|&h| fixed[mesh.halfedge_edge(h)]) {
            enter(h, &mut entered, &mut queue);
        }
        let mut steps = Vec::with_capacity(mesh.n_edges());
        let mut next = 0;
        while let Some(&f) = queue.get(next) {
            next += 1;
            let from = entered[f].expect("queued faces were entered");
            for to in (0..3).filter(|&to| to != from) {
                let edge = mesh.halfedge_edge(3 * f + to);
                if !std::mem::replace(&mut known[edge], true) {
                    steps.push((f, from, to));
                }
                if let Some(t) = mesh.twin(3 * f + to) {
                    enter(t, &mut entered, &mut queue);
                }
            }
        }
        StreamPlan { steps }
    }

    /// `ψ` at the edge midpoints with face gradients `gradient`: `ψ(m_to) = ψ(m_from) +
    /// ∇ψ_T·(m_to − m_from)`, `m_k` the midpoint of local halfedge `k`.
    fn integrate(&self, mesh: &Mesh, shape: &SlabShape, gradient: &[Vector2<f64>]) -> Vec<f64> {
        let mut stream = vec![0.0; mesh.n_edges()];
        for &(f, from, to) in &self.steps {
            let p = shape.geometry.triangle(f).layout();
            let midpoint = |k: usize| (p[k] + p[(k + 1) % 3]) * 0.5;
            let step = gradient[f].dot(&(midpoint(to) - midpoint(from)));
            stream[mesh.halfedge_edge(3 * f + to)] =
                stream[mesh.halfedge_edge(3 * f + from)] + step;
        }
        stream
    }
}

/// `∫ a·b = Σ_T A_T a_T·b_T` of two face-wise fields.
pub fn inner_product(geometry: &IntrinsicGeometry, a: &[Vector2<f64>], b: &[Vector2<f64>]) -> f64 {
    (geometry.triangles().iter())
        .zip(a.iter().zip(b))
        .map(|(t, (a, b))| t.area * a.dot(b))
        .sum()
}
