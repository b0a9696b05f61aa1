//! Sparse Cholesky factors through faer's low-level API, so that many factorizations can run
//! in parallel under rayon, each single-threaded (`Par::Seq`), sharing one symbolic analysis.
//!
//! The fill-reducing ordering is METIS's nested dissection (`METIS_NodeND`) of the vertex
//! graph, each vertex's two DOFs kept together: on surface meshes it leaves about a quarter
//! less fill than faer's approximate minimum degree, which is memory and time in every
//! factorization and every triangular solve. AMD remains the fallback should METIS refuse.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

/// A borrowed sparse matrix, CSC with `usize` indices (meshflow's `fem::SparseMatrixRef`).
pub(crate) type SparseMatrixRef<'a> = SparseColMatRef<'a, usize, f64>;
use faer::{Conj, MatMut, Par, Side};
use std::sync::Arc;

/// The symbolic analysis (ordering, elimination tree, fill) of a symmetric sparsity pattern
/// whose DOFs come in vertex blocks `b i .. b i + b` (`b = dofs_per_vertex`: 2 for tangent
/// fields, 1 for scalars).
pub fn analyze(
    pattern: SymbolicSparseColMatRef<'_, usize>,
    dofs_per_vertex: usize,
) -> Arc<SymbolicCholesky<usize>> {
    let Some(forward) = nested_dissection(pattern, dofs_per_vertex) else {
        return symbolic_with(pattern, SymmetricOrdering::Amd);
    };
    let mut inverse = vec![0; forward.len()];
    forward
        .iter()
        .enumerate()
        .for_each(|(new, &old)| inverse[old] = new);
    let perm = PermRef::new_checked(&forward, &inverse, forward.len());
    symbolic_with(pattern, SymmetricOrdering::Custom(perm))
}

/// faer's approximate minimum degree order of a symmetric pattern (either triangle or both):
/// `new_row[old]`. Cheaper to compute than nested dissection, for patterns factorized only a
/// few times.
pub fn amd_order(pattern: SymbolicSparseColMatRef<'_, usize>) -> Vec<usize> {
    let symbolic = symbolic_with(pattern, SymmetricOrdering::Amd);
    match symbolic.perm() {
        Some(perm) => perm.arrays().1.to_vec(),
        None => (0..pattern.ncols()).collect(),
    }
}

/// The symbolic analysis of a pattern already in elimination order, given by its upper
/// triangle (faer reads that one when there is no ordering to apply). Matrices factorized with
/// it are passed as their lower triangle, which faer's supernodal factorization reads in place
/// (its simplicial one transposes a copy).
pub fn analyze_in_order(
    pattern: SymbolicSparseColMatRef<'_, usize>,
) -> Arc<SymbolicCholesky<usize>> {
    symbolic_with(pattern, SymmetricOrdering::Identity)
}

fn symbolic_with(
    pattern: SymbolicSparseColMatRef<'_, usize>,
    ordering: SymmetricOrdering<'_, usize>,
) -> Arc<SymbolicCholesky<usize>> {
    let symbolic = factorize_symbolic_cholesky(pattern, Side::Lower, ordering, Default::default())
        .expect("symbolic Cholesky needs only memory");
    Arc::new(symbolic)
}

/// Held around every METIS call (see [`nested_dissection`]).
static METIS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// METIS's nested-dissection order of the DOFs (`forward[new] = old`), by vertex blocks of
/// `b` DOFs; `None` for a dimension that is not a multiple of `b`, a graph too large for
/// METIS's 32-bit indices, or a METIS error.
fn nested_dissection(pattern: SymbolicSparseColMatRef<'_, usize>, b: usize) -> Option<Vec<usize>> {
    let n = pattern.ncols();
    if b == 0 || n % b != 0 || pattern.compute_nnz() > i32::MAX as usize {
        return None;
    }
    let n_vertices = n / b;
    let mut xadj = vec![0i32];
    let mut adjncy = Vec::new();
    for vertex in 0..n_vertices {
        let mut neighbours: Vec<i32> = pattern
            .row_idx_of_col(b * vertex)
            .map(|r| (r / b) as i32)
            .filter(|&v| v != vertex as i32)
            .collect();
        neighbours.sort_unstable();
        neighbours.dedup();
        adjncy.extend(neighbours);
        xadj.push(adjncy.len() as i32);
    }
    let mut nvtxs = n_vertices as i32;
    let (mut perm, mut iperm) = (vec![0i32; n_vertices], vec![0i32; n_vertices]);
    // METIS keeps its random generator's state in globals (GKlib's Mersenne twister): calls
    // from two threads race on it and return orderings that differ from run to run.
    let _one_at_a_time = METIS.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: xadj/adjncy form a valid CSR graph of nvtxs vertices (sorted, no duplicates, no
    // self loops, symmetric because the pattern is); perm and iperm hold nvtxs entries; null
    // vertex weights and options mean METIS's defaults.
    let status = unsafe {
        metis_sys::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    (status == metis_sys::rstatus_et_METIS_OK).then(|| {
        perm.iter()
            .flat_map(|&v| (0..b).map(move |d| b * v as usize + d))
            .collect()
    })
}

/// A floating-point type the factors can be stored in; the system stays in `f64`.
pub trait Precision: faer::traits::ComplexField + Copy {
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn is_subnormal(self) -> bool;
}

impl Precision for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn is_subnormal(self) -> bool {
        f64::is_subnormal(self)
    }
}

impl Precision for f32 {
    fn from_f64(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
    fn is_subnormal(self) -> bool {
        f32::is_subnormal(self)
    }
}

/// `L Lᵀ = A` for one symmetric positive definite matrix with the analysed pattern, stored in
/// precision `T` (`f32` halves the memory and the memory traffic of a preconditioner's solves).
#[derive(Clone)]
pub struct CholeskyFactor<T = f64> {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<T>,
}

impl<T: Precision> CholeskyFactor<T> {
    /// Factors `matrix` (rounded to `T`); `Err` carries faer's reason when it is not
    /// numerically positive definite.
    pub fn new(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
        par: Par,
    ) -> Result<Self, String> {
        Self::new_in(symbolic, matrix, par, Vec::new())
    }

    /// [`Self::new`], writing `L` into `values` (whatever it holds; its pages already mapped
    /// where it held a factor before, [`super::factor::SpareValues`]).
    pub fn new_in(
        symbolic: &Arc<SymbolicCholesky<usize>>,
        matrix: SparseMatrixRef<'_>,
        par: Par,
        mut values: Vec<T>,
    ) -> Result<Self, String> {
        let (pattern, entries) = matrix.parts();
        let rounded: Vec<T> = entries.iter().map(|&v| T::from_f64(v)).collect();
        let (len, zero) = (symbolic.len_val(), T::from_f64(0.0));
        values.clear();
        match values.capacity() {
            // Zero pages from the system, mapped where faer writes first (no second pass).
            0 => values = vec![zero; len],
            // A packed factor's buffer is shorter than faer's layout (its diagonal blocks'
            // upper triangles left out): grown in place where it can be (a large buffer is
            // remapped, not copied), so only the extra pages are new.
            _ => {
                values.reserve_exact(len);
                values.resize(len, zero);
            }
        }
        let scratch = symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default());
        symbolic
            .factorize_numeric_llt::<T>(
                &mut values,
                SparseColMatRef::new(pattern, &rounded),
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut MemBuffer::new(scratch)),
                Default::default(),
            )
            .map_err(|e| format!("{e:?}"))?;
        Ok(Self {
            symbolic: symbolic.clone(),
            values,
        })
    }

    /// Overwrites `x` with `A⁻¹ x` (computed in precision `T`): one column.
    pub fn solve_in_place(&self, x: &mut [f64], par: Par) {
        self.solve_columns_in_place(x, par)
    }

    /// Overwrites the columns of `x` (column-major, `A`'s order each) with `A⁻¹ x`, in one
    /// blocked triangular solve.
    pub fn solve_columns_in_place(&self, x: &mut [f64], par: Par) {
        let n = self.symbolic.nrows();
        let columns = x.len().checked_div(n).unwrap_or(0);
        let mut scratch = MemBuffer::new(self.symbolic.solve_in_place_scratch::<T>(columns, par));
        let mut rhs: Vec<T> = x.iter().map(|&v| T::from_f64(v)).collect();
        LltRef::<'_, usize, T>::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut rhs, n, columns),
            par,
            MemStack::new(&mut scratch),
        );
        x.iter_mut().zip(&rhs).for_each(|(x, r)| *x = r.to_f64());
    }

    /// The symbolic analysis and the values of `L`, the factor given up.
    pub fn into_parts(self) -> (Arc<SymbolicCholesky<usize>>, Vec<T>) {
        (self.symbolic, self.values)
    }

    /// A factor with the given values of `L` (tests that compare solves).
    #[cfg(test)]
    pub(crate) fn from_parts(symbolic: Arc<SymbolicCholesky<usize>>, values: Vec<T>) -> Self {
        Self { symbolic, values }
    }

    /// The symbolic analysis this factor was computed with.
    pub fn symbolic(&self) -> &Arc<SymbolicCholesky<usize>> {
        &self.symbolic
    }

    /// The values of `L` in faer's layout for [`Self::symbolic`].
    pub fn values(&self) -> &[T] {
        &self.values
    }

    /// Stored entries of `L`, and how many of them are subnormal numbers (none once the
    /// factorization ran with them flushed, [`crate::subnormals`]).
    pub fn entries(&self) -> FactorEntries {
        FactorEntries {
            stored: self.values.len(),
            subnormal: self.values.iter().filter(|v| v.is_subnormal()).count(),
        }
    }
}

/// Entries of Cholesky factors: stored, and subnormal among them (a subnormal operand costs a
/// microcode assist on some processors, [`crate::subnormals`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FactorEntries {
    pub stored: usize,
    pub subnormal: usize,
}

impl std::ops::Add for FactorEntries {
    type Output = Self;
    fn add(self, other: Self) -> Self {
        Self {
            stored: self.stored + other.stored,
            subnormal: self.subnormal + other.subnormal,
        }
    }
}

impl std::iter::Sum for FactorEntries {
    fn sum<I: Iterator<Item = Self>>(entries: I) -> Self {
        entries.fold(Self::default(), |a, b| a + b)
    }
}
