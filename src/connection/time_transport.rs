//! Transport of tangent vectors from one slab to the next by the spin of the deformation.
//!
//! Per face `T`, `J_T = E2^{s+1} (E2^s)⁻¹` is the linear map taking `T`'s layout in slab `s` to
//! its layout in slab `s + 1`. Its polar decomposition `J = Q S` (Q a rotation, S symmetric
//! positive definite) splits the deformation into spin and stretch; the covariant time
//! derivative of the metric `diag(α², g(t))` transports by the spin only, so `Q_T` is the
//! discrete transport (`docs/discretization.md` §7). For a 2×2 matrix the rotation angle of
//! the polar factor is `atan2(J10 − J01, J00 + J11)`: `Q = [[c, −s], [s, c]]` with
//! `(c, s) = (J00 + J11, J10 − J01) / |(J00 + J11, J10 − J01)|`.

use crate::geometry::IntrinsicGeometry;
use nalgebra::Vector2;

/// `(cos q_T, sin q_T)` of the rotation `Q_T` for every face, from the layouts of `from` to
/// those of `to` (two geometries of the same mesh): the normalized `(J00 + J11, J10 − J01)`,
/// no angle taken on the way (the time links are built in every assembly and energy pass).
pub fn polar_rotations(from: &IntrinsicGeometry, to: &IntrinsicGeometry) -> Vec<Vector2<f64>> {
    from.triangles()
        .iter()
        .zip(to.triangles())
        .map(|(a, b)| {
            let inverse = a
                .layout_edge_matrix()
                .try_inverse()
                .expect("layout of a validated triangle is invertible");
            let j = b.layout_edge_matrix() * inverse;
            let (c, s) = (j[(0, 0)] + j[(1, 1)], j[(1, 0)] - j[(0, 1)]);
            Vector2::new(c, s) / c.hypot(s)
        })
        .collect()
}
