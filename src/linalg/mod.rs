//! Sparse linear algebra that several parts of meshflow share, low in the house: the sparse
//! Cholesky factors (`cholesky`: METIS ordering, one symbolic analysis shared by many numeric
//! factorizations, single or double precision, faer's symbolic/numeric split) serve the flow
//! solver, the presmoothing of the images, the tracker's relaxation, the Hodge decomposition
//! and the surface fit alike. `factor` holds the factors the flow's slab sweeps solve with, in
//! double, single or bfloat16 precision; `packed` stores the single and bfloat16 ones and
//! solves with them by meshflow's own kernels, and `bfloat` is the bfloat16 entry and its
//! rounding. It depends on faer and METIS only.

pub(crate) mod bfloat;
pub(crate) mod cholesky;
pub(crate) mod factor;
pub(crate) mod packed;
