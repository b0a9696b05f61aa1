//! MatrixMarket (coordinate, real, general) through sprs.

use super::{write_atomically, IoError};
use crate::fem::SparseMatrix;
use faer::sparse::{SparseColMat, Triplet};
use std::path::Path;

/// Writes a sparse matrix as MatrixMarket `coordinate real general` (1-based indices, every
/// stored entry), readable by `scipy.io.mmread` and MATLAB's `mmread`.
pub fn write_matrix_market(path: &Path, matrix: &SparseMatrix) -> Result<(), IoError> {
    let (symbolic, values) = matrix.parts();
    let csc = sprs::CsMat::new_csc(
        (matrix.nrows(), matrix.ncols()),
        symbolic.col_ptr().to_vec(),
        symbolic.row_idx().to_vec(),
        values.to_vec(),
    );
    write_atomically(path, |w| sprs::io::write_matrix_market_to_bufwrite(w, &csc))
}

/// Reads a real MatrixMarket matrix (general or symmetric) into a sparse matrix.
pub fn read_matrix_market(path: &Path) -> Result<SparseMatrix, IoError> {
    let triplets: sprs::TriMat<f64> =
        sprs::io::read_matrix_market(path).map_err(|e| IoError::format(path, e.to_string()))?;
    let entries: Vec<_> = triplets
        .triplet_iter()
        .map(|(&v, (r, c))| Triplet::new(r, c, v))
        .collect();
    SparseColMat::try_new_from_triplets(triplets.rows(), triplets.cols(), &entries)
        .map_err(|e| IoError::format(path, format!("{e:?}")))
}
