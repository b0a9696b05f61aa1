//! Transport of tangent vectors from one slab to the next by the spin of the deformation.
//!
//! Per face `T`, `J_T = E2^{s+1} (E2^s)⁻¹` is the linear map taking `T`'s layout in slab `s` to
//! its layout in slab `s + 1`. Its polar decomposition `J = Q S` (Q a rotation, S symmetric
//! positive definite) splits the deformation into spin and stretch; the covariant time
//! derivative of the metric `diag(α², g(t))` transports by the spin only, so `Q_T` is the
//! discrete transport (`docs/discretization.md` §7). For a 2×2 matrix the rotation angle of
//! the polar factor is `atan2(J10 − J01, J00 + J11)`.

use crate::geometry::IntrinsicGeometry;

/// Rotation angle of `Q_T` for every face, from the layouts of `from` to those of `to`
/// (two geometries of the same mesh).
pub fn polar_rotation_angles(from: &IntrinsicGeometry, to: &IntrinsicGeometry) -> Vec<f64> {
    from.triangles()
        .iter()
        .zip(to.triangles())
        .map(|(a, b)| {
            let inverse = a
                .layout_edge_matrix()
                .try_inverse()
                .expect("layout of a validated triangle is invertible");
            let j = b.layout_edge_matrix() * inverse;
            (j[(1, 0)] - j[(0, 1)]).atan2(j[(0, 0)] + j[(1, 1)])
        })
        .collect()
}
