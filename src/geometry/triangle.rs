//! One intrinsic triangle: angles, area, cotangents and its 2D layout from three edge lengths.

use nalgebra::{Matrix2, Vector2};
use std::f64::consts::PI;

/// A triangle `(a, b, c)` known by its edge lengths `[l_ab, l_bc, l_ca]`.
///
/// Corner quantities are indexed by corner: `[a, b, c]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// `[l_ab, l_bc, l_ca]`: the length of the edge leaving each corner.
    pub lengths: [f64; 3],
    /// Interior angles `[θ_a, θ_b, θ_c]`.
    pub angles: [f64; 3],
    /// `[cot θ_a, cot θ_b, cot θ_c]`.
    pub cotans: [f64; 3],
    pub area: f64,
}

impl Triangle {
    /// The triangle with the given lengths, or `Err(area)` when it is degenerate: a length is not
    /// positive and finite, the triangle inequality fails, or `area ≤ ε · l_max²`.
    pub fn from_lengths(lengths: [f64; 3]) -> Result<Self, f64> {
        let area = Self::checked_area(lengths)?;
        let sq = lengths.map(|l| l * l);
        // Corner c sits between its own edge (c) and the previous corner's edge (c + 2); the
        // edge opposite it is (c + 1).
        let cotans: [f64; 3] =
            std::array::from_fn(|c| (sq[c] + sq[(c + 2) % 3] - sq[(c + 1) % 3]) / (4.0 * area));
        let angles = cotans.map(|cot| (1.0f64).atan2(cot));
        Ok(Self {
            lengths,
            angles,
            cotans,
            area,
        })
    }

    /// The area of the triangle with the given lengths, or `Err(area)` when it is degenerate
    /// (as [`Self::from_lengths`]): the check without the angles, for validating frames.
    pub fn checked_area(lengths: [f64; 3]) -> Result<f64, f64> {
        if !lengths.iter().all(|l| l.is_finite() && *l > 0.0) {
            return Err(0.0);
        }
        let area = kahan_heron_area(lengths);
        let l_max = lengths.iter().cloned().fold(0.0, f64::max);
        match area > f64::EPSILON * l_max * l_max {
            true => Ok(area),
            false => Err(area),
        }
    }

    /// Corner positions of the layout: `p_a = (0, 0)`, `p_b = (l_ab, 0)`, `p_c` above the x-axis,
    /// `p_c = (l_ca cos θ_a, l_ca sin θ_a) = (h cot θ_a, h)` with the height `h = 2A / l_ab`
    /// (no trigonometric call: layouts are made per face and use, in every assembly).
    pub fn layout(&self) -> [Vector2<f64>; 3] {
        let l_ab = self.lengths[0];
        let height = 2.0 * self.area / l_ab;
        [
            Vector2::zeros(),
            Vector2::new(l_ab, 0.0),
            Vector2::new(height * self.cotans[0], height),
        ]
    }

    /// Edge vectors `[p_b − p_a, p_c − p_a]` of the layout as the columns of a 2×2 matrix.
    pub fn layout_edge_matrix(&self) -> Matrix2<f64> {
        let [_, p_b, p_c] = self.layout();
        Matrix2::from_columns(&[p_b, p_c])
    }

    /// Face-frame polar angle of each corner's first edge: `[0, π − θ_b, π + θ_a]`.
    pub fn first_edge_angles(&self) -> [f64; 3] {
        [0.0, PI - self.angles[1], PI + self.angles[0]]
    }

    /// Face-frame gradients of the three P1 hat functions: `∇φ_a = J (p_c − p_b) / 2A` with `J`
    /// the rotation by +90°, i.e. the inward normal of the opposite edge over the height.
    pub fn hat_gradients(&self) -> [Vector2<f64>; 3] {
        let p = self.layout();
        std::array::from_fn(|c| {
            let e = p[(c + 2) % 3] - p[(c + 1) % 3];
            Vector2::new(-e.y, e.x) / (2.0 * self.area)
        })
    }
}

/// Heron's formula in Kahan's ordering, accurate for needle-shaped triangles ("Miscalculating
/// Area and Angles of a Needle-like Triangle", 2014). NaN or ≤ 0 when the lengths violate the
/// triangle inequality.
fn kahan_heron_area(lengths: [f64; 3]) -> f64 {
    let mut l = lengths;
    l.sort_by(|x, y| y.total_cmp(x));
    let [a, b, c] = l;
    let product = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
    if product > 0.0 {
        0.25 * product.sqrt()
    } else {
        0.0
    }
}
