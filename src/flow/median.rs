//! The weighted median of a tangent field over each vertex's star: the median filtering
//! between warps of Sun, Roth & Black (2010, "Secrets of optical flow estimation"), which
//! removes the outliers a warp's linearization leaves at motion boundaries and in noise, on the
//! surface.
//!
//! For vertex `i`, every corner `b` of every face `T` around it contributes the field's value
//! at its vertex carried into `i`'s frame by the face's transports (the ones the elements use,
//! [`crate::connection`]), `R_{T,i}ᵀ R_{T,b} u_b`, with the weight `A_T / 3` (its share of
//! the lumped mass). Each component of the filtered `ũ_i` is the weighted median of that
//! component over the star's contributions: `i` itself weighs its whole lumped area, each
//! neighbour the thirds of the faces it shares with `i`. A field that is linear over the star
//! in the transported frames is kept at interior vertices of a regular star (the median of a
//! symmetric set is its centre); an outlier at one vertex is replaced by its neighbours'.
//!
//! Componentwise, as in the plane: the median of each component in `i`'s frame depends on the
//! frame's orientation (a vector median would not), which the plane's methods accept too.

use crate::connection::Connection;
use crate::geometry::IntrinsicGeometry;
use crate::mesh::Mesh;
use crate::statistics::weighted_median;
use nalgebra::Vector2;
use rayon::prelude::*;

/// `ũ` of the module docs: `u` (one vector per vertex, vertex frames of `connection`) filtered
/// by its weighted median over each vertex's star on `geometry`.
pub fn star_median(
    mesh: &Mesh,
    geometry: &IntrinsicGeometry,
    connection: &Connection,
    u: &[Vector2<f64>],
) -> Vec<Vector2<f64>> {
    (0..mesh.n_vertices())
        .into_par_iter()
        .map(|i| {
            let mut x = Vec::new();
            let mut y = Vec::new();
            for corner in mesh.vertex_fan(i) {
                let f = corner.face as usize;
                let rotations = connection.face_rotations(f);
                let to_i = rotations[corner.local as usize].transpose();
                let weight = geometry.triangle(f).area / 3.0;
                for (b, &v) in mesh.faces()[f].iter().enumerate() {
                    let carried = to_i * (rotations[b] * u[v as usize]);
                    x.push((weight, carried.x));
                    y.push((weight, carried.y));
                }
            }
            match x.is_empty() {
                true => u[i],
                false => Vector2::new(weighted_median(x), weighted_median(y)),
            }
        })
        .collect()
}
