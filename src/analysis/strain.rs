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
use nalgebra::{Matrix2, Vector2};

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
    /// Reads `D` (symmetric): `λ₁,₂ = m ± r` with `m = tr D / 2`, `r = √(((D₁₁ − D₂₂)/2)² + D₁₂²)`,
    /// so `|dev D| = √2 r`; the eigenvector of `λ₁` is the larger of `(D₁₂, λ₁ − D₁₁)` and
    /// `(λ₁ − D₂₂, D₁₂)` (both are eigenvectors; the larger is the accurate one), `e₁` when
    /// `r = 0`. Closed forms, as this runs for every face of every slab.
    pub fn new(tensor: Matrix2<f64>) -> Self {
        let (a, b, d) = (tensor[(0, 0)], tensor[(0, 1)], tensor[(1, 1)]);
        let mean = 0.5 * (a + d);
        let radius = (0.5 * (a - d)).hypot(b);
        let first = mean + radius;
        let candidates = [Vector2::new(b, first - a), Vector2::new(first - d, b)];
        let larger = match candidates[0].norm_squared() >= candidates[1].norm_squared() {
            true => candidates[0],
            false => candidates[1],
        };
        let direction = larger.try_normalize(0.0).unwrap_or_else(Vector2::x);
        StrainRate {
            tensor,
            areal: a + d,
            shear: std::f64::consts::SQRT_2 * radius,
            principal: [first, mean - radius],
            directions: [direction, Vector2::new(-direction.y, direction.x)],
        }
    }
}

/// The metric `G` in the layout of `triangle` whose edges have lengths `lengths` (`[ℓ_ab,
/// ℓ_bc, ℓ_ca]`, as [`Triangle::lengths`]): `E_eᵀ G E_e = ℓ_e²`.
pub fn layout_metric(triangle: &Triangle, lengths: [f64; 3]) -> Matrix2<f64> {
    // With the layout's edge vectors E = [p_b − p_a, p_c − p_a], Eᵀ G E is the Gram matrix of
    // those edges in the metric: diagonal ℓ_ab², ℓ_ca², off-diagonal (ℓ_ab² + ℓ_ca² − ℓ_bc²)/2
    // (law of cosines).
    let [ab, bc, ca] = lengths.map(|l| l * l);
    let gram = Matrix2::new(ab, 0.5 * (ab + ca - bc), 0.5 * (ab + ca - bc), ca);
    // A non-degenerate layout (the geometry refuses others) has independent edges.
    let inverse = (triangle.layout_edge_matrix().try_inverse()).unwrap_or_else(Matrix2::identity);
    inverse.transpose() * gram * inverse
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
