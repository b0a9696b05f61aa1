//! The tissue's rate of deformation: the mesh's own motion plus the flow.
//!
//! The material moves with the mesh and, relative to it, with the flow `u`. In the layout of
//! face `T` in the slab's (mean) geometry, whose metric is the identity, the metric of frame
//! `k` is the symmetric `G_k` with `E_eᵀ G_k E_e = ℓ_e(t_k)²` for the three edge vectors `E_e`
//! of the layout and the frame's edge lengths `ℓ_e`. The rate of deformation is
//!
//! ```text
//! D_T = ½ (G_{s+1} − G_s) / Δt_s  +  Sym ∇U_T,
//! ```
//!
//! the metric's rate `½ g⁻¹ ġ` (with `g = I` to first order in `Δt`) plus the symmetric part of
//! the flow's covariant gradient ([`super::derivatives`]). From it, per face:
//!
//! - the **areal growth rate** `tr D = d/dt log(area)` of a material patch (1/time): `2ṙ/r` on a
//!   sphere of radius `r(t)` carrying its texture;
//! - the **shear rate** `|dev D| = |λ₁ − λ₂| / √2`, the norm of the traceless part;
//! - the **principal rates** `λ₁ ≥ λ₂` and their directions (eigenvectors of `D`).
//!
//! A rigid motion of the surface carrying its texture (a Killing field) has `D = 0`. Edge
//! lengths and intrinsic flows do not see rigid motions of the whole sequence, so neither
//! does `D`.

use crate::geometry::Triangle;
use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};

/// The rate of deformation of one face and what is read from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrainRate {
    /// `D` in the face's layout frame (symmetric).
    pub tensor: Matrix2<f64>,
    /// `tr D`.
    pub areal: f64,
    /// `|dev D|`.
    pub shear: f64,
    /// `λ₁ ≥ λ₂`.
    pub principal: [f64; 2],
    /// Unit eigenvectors of `λ₁`, `λ₂` in the layout frame.
    pub directions: [Vector2<f64>; 2],
}

impl StrainRate {
    pub fn new(tensor: Matrix2<f64>) -> Self {
        let eigen = SymmetricEigen::new(tensor);
        let (first, second) = match eigen.eigenvalues[0] >= eigen.eigenvalues[1] {
            true => (0, 1),
            false => (1, 0),
        };
        let deviator = tensor - Matrix2::identity() * (0.5 * tensor.trace());
        StrainRate {
            tensor,
            areal: tensor.trace(),
            shear: deviator.norm(),
            principal: [eigen.eigenvalues[first], eigen.eigenvalues[second]],
            directions: [
                eigen.eigenvectors.column(first).into_owned(),
                eigen.eigenvectors.column(second).into_owned(),
            ],
        }
    }
}

/// The metric `G` in the layout of `triangle` whose edges have lengths `lengths` (`[ℓ_ab,
/// ℓ_bc, ℓ_ca]`, as [`Triangle::lengths`]): `E_eᵀ G E_e = ℓ_e²`.
pub fn layout_metric(triangle: &Triangle, lengths: [f64; 3]) -> Matrix2<f64> {
    let p = triangle.layout();
    let edges: [Vector2<f64>; 3] = std::array::from_fn(|e| p[(e + 1) % 3] - p[e]);
    let rows = Matrix3::from_fn(|e, k| {
        let (x, y) = (edges[e].x, edges[e].y);
        [x * x, 2.0 * x * y, y * y][k]
    });
    let squares = Vector3::from(lengths.map(|l| l * l));
    // Three edges of a non-degenerate triangle (the geometry refuses others) determine the
    // metric; should rounding make the system singular, the layout's own metric stands in.
    let g = rows
        .lu()
        .solve(&squares)
        .unwrap_or_else(|| Vector3::new(1.0, 0.0, 1.0));
    Matrix2::new(g[0], g[1], g[1], g[2])
}

/// `D_T` of a face: the metric's rate between the frames' edge lengths `before` and `after`
/// over `dt`, plus `Sym ∇U` of the flow's face gradient `gradient`
/// ([`super::derivatives::field_gradient`]).
pub fn face_strain_rate(
    triangle: &Triangle,
    before: [f64; 3],
    after: [f64; 3],
    dt: f64,
    gradient: &Matrix2<f64>,
) -> StrainRate {
    let metric_rate =
        (layout_metric(triangle, after) - layout_metric(triangle, before)) / (2.0 * dt);
    let symmetric = (gradient + gradient.transpose()) * 0.5;
    StrainRate::new(metric_rate + symmetric)
}
