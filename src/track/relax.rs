//! Tangential relaxation of a tracked mesh on its frame's surface: as-rigid-as-possible (ARAP)
//! against the previous frame, every vertex kept on the surface.
//!
//! Normal motion moves each vertex along its own normal; nothing keeps neighbours apart, so
//! where a step is large against the surface's radius of curvature, or where the surface
//! slides, the mesh shears, and over many frames it folds. After the normal step, the tracked
//! positions `y` on frame `k + 1`'s surface `S` minimize the distortion against the previous
//! frame's positions `x` (Liu et al. 2008, "A Local/Global Approach to Mesh Parameterization",
//! per triangle; Sorkine & Alexa 2007):
//!
//! ```text
//! E(y) = Σ_f A_f ‖J_f(y) − σ R_f‖²_F,   y_i ∈ S,
//! J_f = [y_b − y_a, y_c − y_a] D_f⁻¹   (3×2: the linear map of face f from frame k to k + 1),
//! ```
//!
//! with `D_f` the previous triangle's edge vectors in its own 2-D layout and `A_f` its area.
//! The targets are rotations scaled by the change of the whole surface's area under the normal
//! step, `σ = (area(y⁰) / area(x))^½`: a surface that grows or shrinks uniformly (a pulsating
//! sphere) costs nothing and is left to normal motion; plain ARAP would pull such a mesh
//! tangentially, like a membrane under tension, a little more with every step.
//! Local step: `R_f` is the rotation nearest to `J_f` in the face's plane (oriented like the
//! previous triangle), `R_f = [t₁ t₂] rot(θ)`, `tan θ = (J₂₁ − J₁₂)/(J₁₁ + J₂₂)` for `J = [t₁ t₂]ᵀ J_f`
//! — orientation-preserving, so a folded triangle is pulled back, not fitted as a
//! reflection. Global step: each vertex moves in its tangent plane, `y_i = p_i + T_i a_i`
//! (`T_i`: an orthonormal 3×2 basis at `p_i`), and the 2V unknowns `a` solve
//!
//! ```text
//! (Tᵀ (K ⊗ I₃) T + μ M) a = Tᵀ (b − (K ⊗ I₃) p),   K = Σ_f A_f G_f G_fᵀ,  b_a = Σ_f σ A_f R_f G_fᵀ e_a,
//! ```
//!
//! `G_f = [−1 −1; 1 0; 0 1] D_f⁻¹` (`K` is the cotangent stiffness matrix of the previous
//! frame), `M` the lumped vertex areas and `μ = 10⁻³ / area`: a proximal term that fixes the
//! in-plane translations of a flat patch and is too weak to resist any deformation. Then every
//! vertex goes back onto `S` by its closest point, and the two steps repeat. The system's
//! pattern is the mesh's, so one symbolic factorization serves every step of every frame.
//!
//! What it means for the flow: the relaxed mesh moves tangentially as well as normally. The
//! model's flow `u` is the material's velocity relative to the mesh's own motion, so the
//! tissue's velocity is the mesh velocity plus `u` (`solve` writes it as `velocity.npy`).

use super::SurfaceSample;
use crate::fem::VertexPattern;
use crate::geometry::{mean_edge_length_at, surface_area};
use crate::linalg::cholesky::{analyze, CholeskyFactor};
use crate::mesh::Mesh;
use crate::spatial::FrameSurface;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::Par;
use nalgebra::{Matrix2, Matrix3, Matrix3x2, SMatrix, Vector2, Vector3};
use rayon::prelude::*;
use std::sync::Arc;

/// Weight of the proximal term, relative to the stiffness over the whole surface.
const PROXIMAL_WEIGHT: f64 = 1e-3;

/// Relaxation stops when no vertex moves farther than this fraction of the mean edge length.
const CONVERGED_STEP: f64 = 1e-3;

/// Rounds of the asked number of steps go on, up to this many, while triangles remain flipped
/// against the previous frame.
const ROUNDS_FOR_FOLDS: usize = 5;

/// Steps between new tangent planes (and a new factorization).
const STEPS_PER_FACTOR: usize = 4;

/// The factorization plan for one connectivity.
pub(super) struct Relaxer {
    pattern: VertexPattern,
    symbolic: Arc<SymbolicCholesky<usize>>,
    iterations: usize,
}

/// The relaxed mesh: where each vertex is on the surface, and the vertices that the last step
/// would have moved over the surface's edge (they were held on its boundary instead).
pub(super) struct Relaxed {
    pub samples: Vec<SurfaceSample>,
    pub clamped: Vec<usize>,
}

/// One vertex's move in a step.
struct Move {
    sample: SurfaceSample,
    length: f64,
    clamped: bool,
}

/// One previous triangle: area and the map from corner positions to the face's Jacobian.
struct RestFace {
    area: f64,
    /// `G_f`: `J_f = Y_f G_f` for `Y_f = [y_a y_b y_c]`.
    gradient: Matrix3x2<f64>,
    normal: Vector3<f64>,
}

impl RestFace {
    /// `A_f G_f G_fᵀ`: the face's P1 stiffness matrix.
    fn stiffness(&self) -> Matrix3<f64> {
        self.area * self.gradient * self.gradient.transpose()
    }
}

impl Relaxer {
    pub(super) fn new(mesh: &Mesh, iterations: usize) -> Self {
        let pattern = VertexPattern::new(mesh, 2);
        let symbolic = analyze(pattern.symbolic().as_ref(), 2);
        Self {
            pattern,
            symbolic,
            iterations,
        }
    }

    /// `start` (on `surface`) relaxed against `rest`, each vertex on `surface`; what the
    /// surface holds at each final position. `Err` names the reason the system was singular.
    pub(super) fn relax(
        &self,
        mesh: &Mesh,
        rest: &[Vector3<f64>],
        start: Vec<SurfaceSample>,
        surface: &FrameSurface,
    ) -> Result<Relaxed, String> {
        let faces = rest_faces(mesh, rest);
        let total_area: f64 = faces.iter().map(|f| f.area).sum();
        let mean_edge = mean_edge_length_at(mesh, rest);
        // From the normal step, once: recomputed from the iterates, a surface with a free
        // boundary would shrink a little more with every step.
        let start_positions: Vec<Vector3<f64>> = start.iter().map(|s| s.position).collect();
        let growth = (surface_area(mesh.faces(), &start_positions) / total_area).sqrt();
        let mut samples = start;
        let mut clamped = Vec::new();
        // Rounds of steps; a further round only while triangles remain flipped. The tangent
        // planes serve [`STEPS_PER_FACTOR`] steps, so the matrix is factored once for them;
        // the projection onto the surface takes up the planes' slow turning meanwhile.
        for _ in 0..ROUNDS_FOR_FOLDS {
            let mut planes = None;
            for step in 0..self.iterations {
                if step % STEPS_PER_FACTOR == 0 {
                    let bases: Vec<Matrix3x2<f64>> = (samples.par_iter())
                        .map(|s| tangent_basis(&surface.closest_point_and_normal(&s.position).1))
                        .collect();
                    let factor = self.factor(mesh, &faces, total_area, &bases)?;
                    planes = Some((bases, factor));
                }
                let (bases, factor) = planes.as_ref().expect("set at step 0");
                let (next, largest_step) =
                    iterate(mesh, &faces, growth, bases, factor, &samples, surface);
                clamped = (next.iter().enumerate())
                    .filter(|(_, m)| m.clamped)
                    .map(|(i, _)| i)
                    .collect();
                samples = next.into_iter().map(|m| m.sample).collect();
                if largest_step <= CONVERGED_STEP * mean_edge {
                    break;
                }
            }
            if !any_flipped(mesh, &faces, &samples) {
                break;
            }
        }
        Ok(Relaxed { samples, clamped })
    }

    /// `Tᵀ (K ⊗ I₃) T + μ M`, factored.
    fn factor(
        &self,
        mesh: &Mesh,
        faces: &[RestFace],
        total_area: f64,
        bases: &[Matrix3x2<f64>],
    ) -> Result<CholeskyFactor, String> {
        let proximal = PROXIMAL_WEIGHT / total_area;
        let mut values = self.pattern.zero_values();
        for (f, face) in mesh.faces().iter().enumerate() {
            let rest = &faces[f];
            let stiffness = rest.stiffness();
            let mut element = SMatrix::<f64, 6, 6>::zeros();
            for a in 0..3 {
                let ta = bases[face[a] as usize];
                for b in 0..3 {
                    let block: Matrix2<f64> =
                        stiffness[(a, b)] * ta.transpose() * bases[face[b] as usize];
                    element
                        .fixed_view_mut::<2, 2>(2 * a, 2 * b)
                        .copy_from(&block);
                }
                let lumped = proximal * rest.area / 3.0;
                element[(2 * a, 2 * a)] += lumped;
                element[(2 * a + 1, 2 * a + 1)] += lumped;
            }
            self.pattern.add_element(f, &element, &mut values);
        }
        CholeskyFactor::<f64>::new(&self.symbolic, self.pattern.view(&values), Par::Seq)
    }
}

/// One local and one global step, then the projection onto the surface; the largest
/// tangential move.
fn iterate(
    mesh: &Mesh,
    faces: &[RestFace],
    growth: f64,
    bases: &[Matrix3x2<f64>],
    factor: &CholeskyFactor,
    samples: &[SurfaceSample],
    surface: &FrameSurface,
) -> (Vec<Move>, f64) {
    let p: Vec<Vector3<f64>> = samples.iter().map(|s| s.position).collect();
    let rotations: Vec<Matrix3x2<f64>> = (mesh.faces().par_iter().zip(faces))
        .map(|(face, rest)| {
            let y = face.map(|v| p[v as usize]);
            let jacobian = Matrix3::from_columns(&y) * rest.gradient;
            nearest_rotation_in_plane(&jacobian, &target_plane(&y, &rest.normal))
        })
        .collect();
    let mut rhs = vec![0.0; 2 * p.len()];
    for (f, face) in mesh.faces().iter().enumerate() {
        let rest = &faces[f];
        let stiffness = rest.stiffness();
        let targets = (rest.area * growth) * rotations[f] * rest.gradient.transpose();
        for a in 0..3 {
            let mut force = targets.column(a).into_owned();
            for b in 0..3 {
                force -= stiffness[(a, b)] * p[face[b] as usize];
            }
            let reduced = bases[face[a] as usize].transpose() * force;
            rhs[2 * face[a] as usize] += reduced.x;
            rhs[2 * face[a] as usize + 1] += reduced.y;
        }
    }
    factor.solve_in_place(&mut rhs, Par::Seq);
    let clamp_tolerance = 1e-6 * mean_edge_length_at(mesh, &p);
    let moved: Vec<Move> = (p.par_iter().zip(bases).enumerate())
        .map(|(i, (x, basis))| {
            let step = basis * Vector2::new(rhs[2 * i], rhs[2 * i + 1]);
            let wanted = x + step;
            let sample = surface.closest_point(&wanted);
            let clamped = (sample.position - wanted).norm() > clamp_tolerance + 1e-3 * step.norm()
                && surface.closest_point_is_on_boundary(&wanted);
            Move {
                sample,
                length: step.norm(),
                clamped,
            }
        })
        .collect();
    let largest = moved.iter().map(|m| m.length).fold(0.0, f64::max);
    (moved, largest)
}

/// Whether a triangle's normal turned by more than 90° from the previous frame's.
fn any_flipped(mesh: &Mesh, faces: &[RestFace], samples: &[SurfaceSample]) -> bool {
    mesh.faces().iter().zip(faces).any(|(face, rest)| {
        let [a, b, c] = face.map(|v| samples[v as usize].position);
        rest.area > 0.0 && (b - a).cross(&(c - a)).dot(&rest.normal) <= 0.0
    })
}

fn rest_faces(mesh: &Mesh, rest: &[Vector3<f64>]) -> Vec<RestFace> {
    mesh.faces()
        .iter()
        .map(|face| {
            let [a, b, c] = face.map(|v| rest[v as usize]);
            let (e1, e2) = (b - a, c - a);
            let cross = e1.cross(&e2);
            let area = 0.5 * cross.norm();
            let (Some(x), Some(normal)) = (e1.try_normalize(0.0), cross.try_normalize(0.0)) else {
                return RestFace {
                    area: 0.0,
                    gradient: Matrix3x2::zeros(),
                    normal: Vector3::z(),
                };
            };
            let y = normal.cross(&x);
            let layout = Matrix2::new(e1.dot(&x), e2.dot(&x), 0.0, e2.dot(&y));
            let corners = Matrix3x2::new(-1.0, -1.0, 1.0, 0.0, 0.0, 1.0);
            let gradient = corners * layout.try_inverse().unwrap_or_else(Matrix2::zeros);
            RestFace {
                area,
                gradient,
                normal,
            }
        })
        .collect()
}

/// The unit normal of the plane a face is rotated into: the face's own plane, oriented like
/// the previous triangle (so a face that flipped is rotated back), or the previous triangle's
/// plane if the face collapsed.
fn target_plane(y: &[Vector3<f64>; 3], rest_normal: &Vector3<f64>) -> Vector3<f64> {
    match (y[1] - y[0]).cross(&(y[2] - y[0])).try_normalize(1e-300) {
        Some(n) if n.dot(rest_normal) < 0.0 => -n,
        Some(n) => n,
        None => *rest_normal,
    }
}

/// An orthonormal basis `[t₁ t₂]` of the plane normal to the unit vector `n`.
fn tangent_basis(n: &Vector3<f64>) -> Matrix3x2<f64> {
    let helper = match n.x.abs() < 0.9 {
        true => Vector3::x(),
        false => Vector3::y(),
    };
    let t1 = n.cross(&helper).normalize();
    let t2 = n.cross(&t1);
    Matrix3x2::from_columns(&[t1, t2])
}

/// The orientation-preserving isometry onto the plane normal to `n` nearest to `jacobian` in
/// the Frobenius norm (see the module docs).
fn nearest_rotation_in_plane(jacobian: &Matrix3x2<f64>, n: &Vector3<f64>) -> Matrix3x2<f64> {
    let basis = tangent_basis(n);
    let j = basis.transpose() * jacobian;
    let angle = (j[(1, 0)] - j[(0, 1)]).atan2(j[(0, 0)] + j[(1, 1)]);
    basis * crate::connection::rotation(angle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_rotation_of_a_rotation_is_itself_and_of_a_reflection_is_a_rotation() {
        let n = Vector3::new(0.3, -0.2, 0.9).normalize();
        let basis = tangent_basis(&n);
        let rotation = basis * crate::connection::rotation(0.7);
        let scaled = 2.5 * rotation;
        assert!((nearest_rotation_in_plane(&scaled, &n) - rotation).norm() < 1e-14);
        let reflection = basis * Matrix2::new(1.0, 0.0, 0.0, -1.0);
        let r = basis.transpose() * nearest_rotation_in_plane(&reflection, &n);
        assert!((r.determinant() - 1.0).abs() < 1e-14);
    }
}
