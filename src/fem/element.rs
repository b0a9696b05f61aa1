//! Element matrices of one triangle: P1 scalar stiffness and mass, and their vector versions.
//!
//! Scalar matrices are 3×3, indexed by local corner `(a, b, c)`. Vector matrices are 6×6 with
//! DOFs `2a, 2a + 1` the components of the tangent vector at corner `a` in *its vertex frame*;
//! a scalar bilinear form `Σ_ab m_ab (R_a u_a)·(R_b u_b)` of face-frame vectors becomes the block
//! `(a, b) = m_ab R_aᵀ R_b = m_ab · Rot(r_b − r_a)`.

use crate::geometry::Triangle;
use nalgebra::{Matrix2, Matrix3, Matrix6, Vector2, Vector6};

/// P1 cotan stiffness `S_ab = −½ cot θ_opposite(ab)` for `a ≠ b`, `S_aa = −Σ_{b≠a} S_ab`.
///
/// `uᵀ S u = ∫_T |∇u|²` for the P1 interpolant; positive semi-definite, rows sum to zero.
pub fn cotan_stiffness(triangle: &Triangle) -> Matrix3<f64> {
    let mut s = Matrix3::zeros();
    for c in 0..3 {
        // The edge opposite corner c joins corners c + 1 and c + 2.
        let (i, j) = ((c + 1) % 3, (c + 2) % 3);
        let w = 0.5 * triangle.cotans[c];
        s[(i, j)] -= w;
        s[(j, i)] -= w;
        s[(i, i)] += w;
        s[(j, j)] += w;
    }
    s
}

/// Anisotropic P1 stiffness `K^D_ab = A ∇φ_aᵀ D ∇φ_b` for a symmetric 2×2 tensor `D` in the
/// face frame: `uᵀ K^D u = ∫_T ∇uᵀ D ∇u` for the P1 interpolant. `D = Id` is
/// [`cotan_stiffness`] (`A ∇φ_a·∇φ_b = −½ cot θ_opposite`); rows sum to zero for every `D`.
pub fn anisotropic_stiffness(triangle: &Triangle, tensor: &Matrix2<f64>) -> Matrix3<f64> {
    let g = triangle.hat_gradients();
    Matrix3::from_fn(|a, b| triangle.area * g[a].dot(&(tensor * g[b])))
}

/// Consistent P1 mass `A/12 · [[2,1,1],[1,2,1],[1,1,2]]`: `uᵀ m v = ∫_T u v` exactly.
pub fn consistent_mass(triangle: &Triangle) -> Matrix3<f64> {
    (Matrix3::repeat(1.0) + Matrix3::identity()) * (triangle.area / 12.0)
}

/// Lumped (barycentric) mass `A/3 · I`: the row sums of the consistent mass.
pub fn lumped_mass(triangle: &Triangle) -> Matrix3<f64> {
    Matrix3::identity() * (triangle.area / 3.0)
}

/// The 6×6 vector version of the scalar element matrix `m`, with block `(a, b) = m_ab R_aᵀ R_b`
/// for the vertex→face rotations `rotations = [R_a, R_b, R_c]`.
pub fn vector_element(m: &Matrix3<f64>, rotations: &[Matrix2<f64>; 3]) -> Matrix6<f64> {
    rotated_element(m, rotations, rotations, &Matrix2::identity())
}

/// `xᵀ V y` for `V = vector_element(m, rotations)` without forming it: `Σ_ab m_ab (R_a x_a)·(R_b
/// y_b)`, the corners' vectors taken to the face frame once (the energy's pass over the faces).
pub fn vector_form(
    m: &Matrix3<f64>,
    rotations: &[Matrix2<f64>; 3],
    x: &Vector6<f64>,
    y: &Vector6<f64>,
) -> f64 {
    let in_face = |v: &Vector6<f64>| {
        std::array::from_fn::<_, 3, _>(|a| rotations[a] * v.fixed_rows::<2>(2 * a))
    };
    scalar_form(m, &in_face(x), &in_face(y))
}

/// `Σ_ab m_ab v_a·w_b` for face-frame vectors `v`, `w` at the three corners.
pub fn scalar_form(m: &Matrix3<f64>, v: &[Vector2<f64>; 3], w: &[Vector2<f64>; 3]) -> f64 {
    (0..3)
        .flat_map(|a| (0..3).map(move |b| (a, b)))
        .map(|(a, b)| m[(a, b)] * v[a].dot(&w[b]))
        .sum()
}

/// Block `(a, b) = m_ab R_aᵀ Q R'_b`: the form `Σ_ab m_ab (R_a v_a)·(Q R'_b w_b)` between
/// vectors `v` transported by `row_rotations` and `w` transported by `col_rotations` and then
/// rotated by `q`.
pub fn rotated_element(
    m: &Matrix3<f64>,
    row_rotations: &[Matrix2<f64>; 3],
    col_rotations: &[Matrix2<f64>; 3],
    q: &Matrix2<f64>,
) -> Matrix6<f64> {
    let cols = col_rotations.map(|c| q * c);
    from_blocks(|a, b| row_rotations[a].transpose() * cols[b] * m[(a, b)])
}

/// The 6×6 matrix with 2×2 block `(a, b) = block(a, b)` for corners `a, b ∈ {0, 1, 2}`.
pub fn from_blocks(block: impl Fn(usize, usize) -> Matrix2<f64>) -> Matrix6<f64> {
    let mut out = Matrix6::zeros();
    for a in 0..3 {
        for b in 0..3 {
            out.fixed_view_mut::<2, 2>(2 * a, 2 * b)
                .copy_from(&block(a, b));
        }
    }
    out
}

/// The brightness-constancy (data) term `∫_T (τ + G·u)²` of one face as the quadratic
/// `uᵀ Q u + 2 lᵀ u + c` in the corners' vertex-frame DOFs.
#[derive(Clone, Debug, PartialEq)]
pub struct DataElement {
    pub quadratic: Matrix6<f64>,
    pub linear: Vector6<f64>,
    pub constant: f64,
}

impl DataElement {
    /// The element of no data (the sum over no channels).
    pub fn zero() -> Self {
        Self {
            quadratic: Matrix6::zeros(),
            linear: Vector6::zeros(),
            constant: 0.0,
        }
    }

    /// `self += w · other`: the elements of several image channels add up, each with its weight.
    pub fn add_scaled(&mut self, other: &DataElement, w: f64) {
        self.quadratic += other.quadratic * w;
        self.linear += other.linear * w;
        self.constant += other.constant * w;
    }

    /// `self + w · other`.
    pub fn plus_scaled(mut self, other: &DataElement, w: f64) -> Self {
        self.add_scaled(other, w);
        self
    }

    /// The form at the corner values `x`: `xᵀ Q x + 2 lᵀ x + c`, the face's integral of the
    /// squared residual.
    pub fn value(&self, x: &Vector6<f64>) -> f64 {
        x.dot(&(self.quadratic * x)) + 2.0 * self.linear.dot(x) + self.constant
    }
}

/// The data element for P1 intensity `intensity` (face gradient `G`) and P1 temporal rate
/// `rate` (τ) on `triangle`: with `g_a = R_aᵀ G`, block `(a, b) = m_ab g_a g_bᵀ`,
/// `l_a = Σ_b m_ab τ_b g_a`, `c = τᵀ m τ` (`m` the consistent mass). This is the exact integral
/// of `(Σ_a φ_a (τ_a + G·R_a u_a))²` (`docs/discretization.md` §6).
pub fn data_element(
    triangle: &Triangle,
    rotations: &[Matrix2<f64>; 3],
    intensity: [f64; 3],
    rate: [f64; 3],
) -> DataElement {
    let gradient = face_gradient(triangle, intensity);
    let m = consistent_mass(triangle);
    let g = rotations.map(|r| r.transpose() * gradient);
    let mut quadratic = Matrix6::zeros();
    let mut linear = Vector6::zeros();
    for a in 0..3 {
        for b in 0..3 {
            quadratic
                .fixed_view_mut::<2, 2>(2 * a, 2 * b)
                .copy_from(&(g[a] * g[b].transpose() * m[(a, b)]));
            linear
                .fixed_rows_mut::<2>(2 * a)
                .axpy(m[(a, b)] * rate[b], &g[a], 1.0);
        }
    }
    let tau = nalgebra::Vector3::from(rate);
    DataElement {
        quadratic,
        linear,
        constant: tau.dot(&(m * tau)),
    }
}

/// Face-frame gradient `G = Σ_a f_a ∇φ_a` of the P1 function with corner values `values`.
pub fn face_gradient(triangle: &Triangle, values: [f64; 3]) -> Vector2<f64> {
    let grads = triangle.hat_gradients();
    grads[0] * values[0] + grads[1] * values[1] + grads[2] * values[2]
}

/// Strain (symmetric-gradient) element `∫_T |Sym ∇u|²` in the corners' vertex-frame DOFs.
///
/// On the face, `∇u = Σ_a v_a g_aᵀ` with `v_a = R_a u_a` (face frame) and `g_a = ∇φ_a`, so
/// `|Sym ∇u|² = ½ |∇u|² + ½ tr(∇u ∇u) = ½ Σ_ab [(v_a·v_b)(g_a·g_b) + (v_a·g_b)(v_b·g_a)]`:
/// block `(a, b) = A/2 · R_aᵀ [(g_a·g_b) I + g_b g_aᵀ] R_b`. Positive semi-definite; zero on
/// infinitesimal rigid motions of the face (`v_a = ω J x_a + c`), the discrete Killing fields.
/// It is [`anisotropic_strain_element`] with `D = Id`, to the last bit.
pub fn strain_element(triangle: &Triangle, rotations: &[Matrix2<f64>; 3]) -> Matrix6<f64> {
    anisotropic_strain_element(triangle, rotations, &Matrix2::identity())
}

/// Anisotropic strain element `∫_T tr(Sym∇u D Sym∇uᵀ)` for a symmetric tensor `D` in the face
/// frame. With `S_a = ½ (v_a g_aᵀ + g_a v_aᵀ)` the four products of `tr(S_a D S_b)` give
/// block `(a, b) = A/4 · R_aᵀ [(g_aᵀ D g_b) I + g_b g_aᵀ D + (g_a·g_b) D + D g_b g_aᵀ] R_b`;
/// `D = Id` gives [`strain_element`]. Positive semi-definite for `D` positive semi-definite
/// (`tr(S D S) = |S D^½|²`), zero on the face's Killing fields for every `D`.
pub fn anisotropic_strain_element(
    triangle: &Triangle,
    rotations: &[Matrix2<f64>; 3],
    tensor: &Matrix2<f64>,
) -> Matrix6<f64> {
    let g = triangle.hat_gradients();
    let d = tensor;
    from_blocks(|a, b| {
        let outer = g[b] * g[a].transpose();
        // Summed in this order, `D = Id` doubles `(g_a·g_b) I + g_b g_aᵀ` exactly.
        let face = (Matrix2::identity() * g[a].dot(&(d * g[b])) + outer * d)
            + (d * g[a].dot(&g[b]) + d * outer);
        rotations[a].transpose() * face * rotations[b] * (0.25 * triangle.area)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The form equals the product with the element it stands for.
    #[test]
    fn vector_form_is_the_vector_elements_product() {
        let triangle = Triangle::from_lengths([1.0, 1.3, 0.8]).unwrap();
        let rotations =
            [0.3, -1.2, 2.5].map(|a: f64| Matrix2::new(a.cos(), -a.sin(), a.sin(), a.cos()));
        let (x, y) = (
            Vector6::from_fn(|i, _| (0.7 * i as f64).sin()),
            Vector6::from_fn(|i, _| (1.1 * i as f64 + 0.2).cos()),
        );
        for m in [consistent_mass(&triangle), cotan_stiffness(&triangle)] {
            let matrix = x.dot(&(vector_element(&m, &rotations) * y));
            let form = vector_form(&m, &rotations, &x, &y);
            assert!(
                (form - matrix).abs() < 1e-14 * matrix.abs().max(1.0),
                "{form} against {matrix}"
            );
        }
    }
}
