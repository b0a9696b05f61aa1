//! P1 finite elements for scalar functions and tangent vector fields on a triangle mesh.
//!
//! A scalar P1 function is one value per vertex; a P1 tangent field is one 2-vector per vertex
//! in the vertex frames of [`Connection`], DOFs `2i, 2i + 1` for vertex `i`. On a face `T` the
//! field is interpolated after transporting the corner vectors into `T`'s face frame:
//! `u|_T = Σ_a φ_a R_{T,a} u_a`. With this interpolation:
//!
//! | operator | shape | sign / meaning |
//! |---|---|---|
//! | [`cotan_laplacian`] `L` | V×V | positive semi-definite; `uᵀLu = ∫|∇u|²`; `L·1 = 0` |
//! | [`scalar_mass`] `m` | V×V | positive definite; `1ᵀm1 = area` |
//! | [`connection_laplacian`] `K` | 2V×2V | positive semi-definite; `uᵀKu = Σ_T ∫_T |∇u|_T|²`, the discrete Bochner Laplacian `∇*∇` |
//! | [`vector_mass`] `M` | 2V×2V | positive definite; `uᵀMu = ∫|u|²` |
//! | [`face_gradient_operator`] `G` | 2F×V | rows `2f, 2f+1`: the face-frame gradient on face `f` |
//!
//! Note the sign: `L` and `K` are the *positive* (geometer's) Laplacians, so the generalized
//! eigenvalues of `(K, M)` on the unit sphere approach `l(l+1) − 1` (1, 5, 11, …).
//!
//! Element matrices ([`element`]) are kept apart from assembly ([`VertexPattern`]), so the flow
//! solver combines them per slab on one pattern. Their sparse Cholesky factors are
//! `crate::linalg`'s.

pub mod element;
mod pattern;

pub use pattern::VertexPattern;

use crate::connection::Connection;
use crate::geometry::IntrinsicGeometry;
use crate::mesh::Mesh;
use faer::sparse::{SparseColMat, Triplet};
use nalgebra::Matrix6;

/// Compressed sparse column matrix (faer) with sorted row indices; both triangles stored.
pub type SparseMatrix = SparseColMat<usize, f64>;

/// A borrowed [`SparseMatrix`], e.g. values on a shared [`VertexPattern`].
pub type SparseMatrixRef<'a> = faer::sparse::SparseColMatRef<'a, usize, f64>;

/// Which P1 mass matrix to build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MassKind {
    /// The exact `∫ u v` of P1 functions.
    #[default]
    Consistent,
    /// Its row sums on the diagonal: `A_i = Σ_{T∋i} A_T / 3` (barycentric vertex areas).
    Lumped,
}

/// Scalar cotan Laplacian `L = Σ_T S^T` (V×V, positive semi-definite).
pub fn cotan_laplacian(mesh: &Mesh, geometry: &IntrinsicGeometry) -> SparseMatrix {
    VertexPattern::new(mesh, 1).assemble(mesh.n_faces(), |f| {
        element::cotan_stiffness(geometry.triangle(f))
    })
}

/// Scalar P1 mass (V×V).
pub fn scalar_mass(mesh: &Mesh, geometry: &IntrinsicGeometry, kind: MassKind) -> SparseMatrix {
    match kind {
        MassKind::Consistent => VertexPattern::new(mesh, 1).assemble(mesh.n_faces(), |f| {
            element::consistent_mass(geometry.triangle(f))
        }),
        MassKind::Lumped => diagonal_matrix(vertex_areas(mesh, geometry)),
    }
}

/// Connection Laplacian `K` (2V×2V, positive semi-definite): block `(a, b)` of face `T` is
/// `S^T_ab R_{T,a}ᵀ R_{T,b}` (`docs/discretization.md` §6).
pub fn connection_laplacian(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
) -> SparseMatrix {
    assemble_vector(mesh, |f| {
        element::vector_element(
            &element::cotan_stiffness(geometry.triangle(f)),
            &connection.face_rotations(f),
        )
    })
}

/// Vector P1 mass `M` (2V×2V): block `(a, b)` is `m_ab R_{T,a}ᵀ R_{T,b}`; lumped, it is the
/// scalar lumped mass on both components.
pub fn vector_mass(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    kind: MassKind,
) -> SparseMatrix {
    match kind {
        MassKind::Consistent => assemble_vector(mesh, |f| {
            element::vector_element(
                &element::consistent_mass(geometry.triangle(f)),
                &connection.face_rotations(f),
            )
        }),
        MassKind::Lumped => diagonal_matrix(
            vertex_areas(mesh, geometry)
                .into_iter()
                .flat_map(|a| [a, a])
                .collect(),
        ),
    }
}

/// Face-frame gradient of P1 functions (2F×V): `(G f)[2t..2t+2] = Σ_a f_a ∇φ_a` on face `t`.
pub fn face_gradient_operator(mesh: &Mesh, geometry: &IntrinsicGeometry) -> SparseMatrix {
    let triplets: Vec<_> = mesh
        .faces()
        .iter()
        .zip(geometry.triangles())
        .enumerate()
        .flat_map(|(f, (face, triangle))| {
            let grads = triangle.hat_gradients();
            (0..3).flat_map(move |a| {
                (0..2).map(move |r| Triplet::new(2 * f + r, face[a] as usize, grads[a][r]))
            })
        })
        .collect();
    SparseColMat::try_new_from_triplets(2 * mesh.n_faces(), mesh.n_vertices(), &triplets)
        .expect("gradient triplets are in range")
}

/// The operators `meshflow operators` exports, with their file stems: `cotan` (L),
/// `mass_scalar` (consistent m), `stiffness` (K) and `mass` (consistent M).
pub fn exported_operators(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
) -> [(&'static str, SparseMatrix); 4] {
    [
        ("cotan", cotan_laplacian(mesh, geometry)),
        (
            "mass_scalar",
            scalar_mass(mesh, geometry, MassKind::Consistent),
        ),
        (
            "stiffness",
            connection_laplacian(mesh, geometry, connection),
        ),
        (
            "mass",
            vector_mass(mesh, geometry, connection, MassKind::Consistent),
        ),
    ]
}

/// Barycentric vertex areas `A_i = Σ_{T∋i} A_T / 3` (the lumped mass diagonal).
pub fn vertex_areas(mesh: &Mesh, geometry: &IntrinsicGeometry) -> Vec<f64> {
    let mut areas = vec![0.0; mesh.n_vertices()];
    for (face, triangle) in mesh.faces().iter().zip(geometry.triangles()) {
        for &v in face {
            areas[v as usize] += triangle.area / 3.0;
        }
    }
    areas
}

/// A square diagonal matrix.
pub fn diagonal_matrix(diagonal: Vec<f64>) -> SparseMatrix {
    let n = diagonal.len();
    let symbolic = faer::sparse::SymbolicSparseColMat::new_checked(
        n,
        n,
        (0..=n).collect(),
        None,
        (0..n).collect(),
    );
    SparseColMat::new(symbolic, diagonal)
}

fn assemble_vector(mesh: &Mesh, element: impl Fn(usize) -> Matrix6<f64>) -> SparseMatrix {
    VertexPattern::new(mesh, 2).assemble(mesh.n_faces(), element)
}
