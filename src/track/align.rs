//! Aligning a frame to the previous one: iterative closest points (Besl & McKay 1992) with
//! the point-to-plane distance (Chen & Medioni 1992).
//!
//! A recording whose sample drifts between time points (a stage that moves, an organ that
//! turns) puts a rigid motion between its frames that normal motion cannot follow: the step
//! bound is exceeded or the mesh shears. Each frame `k ≥ 1` is moved onto frame `k − 1` (as
//! aligned, so motions compose back to frame 0) by the transform `x ↦ s R x + t` minimizing
//!
//! ```text
//! Σ_i |s R p_i + t − c(s R p_i + t)|²,   c = the closest point of frame k − 1's surface,
//! ```
//!
//! over up to [`SAMPLES`] of its vertices, with `s = 1` for a rigid motion. Each iteration
//! pairs the points with their closest points (pairs farther than [`TRIM`] times the median
//! distance are left out: parts of the surface not seen in both frames) and takes one
//! Gauss–Newton step of the distances to the tangent planes there (`linearized_step`).
//!
//! Alignment removes the rigid (or similarity) part of the whole sample's motion, which is then
//! in neither the mesh's motion nor the flow; the transforms are reported so that a user can
//! put it back.

use crate::spatial::FrameSurface;
use nalgebra::{Matrix3, Matrix4, Vector3};
use rayon::prelude::*;

/// Which motion is taken out between frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Alignment {
    /// None: frames are taken as they are (a misalignment is still detected and reported).
    #[default]
    None,
    /// Rotation and translation.
    Rigid,
    /// Rotation, translation and uniform scale (also removes uniform growth).
    Similarity,
}

parse_by_name!(
    Alignment,
    "none" => Alignment::None,
    "rigid" => Alignment::Rigid,
    "similarity" => Alignment::Similarity
);

/// The motion found between a frame and the previous one, and how close they are.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct AlignmentReport {
    /// Which fit this is: the one applied, or (`--align none`) a rigid fit only measured.
    pub applied: bool,
    pub rotation_degrees: f64,
    pub translation: [f64; 3],
    pub scale: f64,
    /// Median distance of the frame's vertices to the previous frame's surface, before and
    /// after the motion.
    pub median_distance_before: f64,
    pub median_distance_after: f64,
    /// `x ↦ M (x, 1)`: row-major 4×4 matrix taking the frame as read to the aligned frame.
    pub matrix: [[f64; 4]; 4],
}

/// At most this many vertices of a frame enter the fit (evenly spread by index).
pub const SAMPLES: usize = 4000;

/// Pairs farther apart than this many median distances are left out of a fit.
pub const TRIM: f64 = 2.5;

const MAX_ITERATIONS: usize = 50;

/// Iterations stop when a step moves the points by less than this fraction of their extent.
const SETTLED: f64 = 1e-9;

/// A similarity transform `x ↦ s R x + t`.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    pub rotation: Matrix3<f64>,
    pub scale: f64,
    pub translation: Vector3<f64>,
}

impl Motion {
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            scale: 1.0,
            translation: Vector3::zeros(),
        }
    }

    pub fn apply(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.scale * self.rotation * x + self.translation
    }

    /// `x` such that `self.apply(x) = y`.
    pub fn invert(&self, y: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.transpose() * (y - self.translation) / self.scale
    }

    /// `self ∘ first`.
    fn after(&self, first: &Motion) -> Motion {
        Motion {
            rotation: self.rotation * first.rotation,
            scale: self.scale * first.scale,
            translation: self.apply(&first.translation),
        }
    }

    fn matrix(&self) -> [[f64; 4]; 4] {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.scale * self.rotation));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
    }

    fn rotation_degrees(&self) -> f64 {
        let cosine = ((self.rotation.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        cosine.acos().to_degrees()
    }
}

/// The motion of `points` onto `target` of the kind `alignment` asks for (`None`: a rigid fit,
/// measured but reported as not applied) and its report.
pub fn fit(
    points: &[Vector3<f64>],
    target: &FrameSurface,
    alignment: Alignment,
) -> (Motion, AlignmentReport) {
    // Only measured: fewer points tell a drift apart as well.
    let samples = match alignment {
        Alignment::None => SAMPLES / 4,
        _ => SAMPLES,
    };
    let stride = points.len().div_ceil(samples).max(1);
    let sample: Vec<Vector3<f64>> = points.iter().step_by(stride).copied().collect();
    let with_scale = alignment == Alignment::Similarity;
    let before = median_distance(&sample, target, &Motion::identity());
    let extent = sample
        .iter()
        .map(|p| (p - sample[0]).norm())
        .fold(0.0, f64::max);
    let mut motion = Motion::identity();
    for _ in 0..MAX_ITERATIONS {
        let moved: Vec<Vector3<f64>> = sample.iter().map(|p| motion.apply(p)).collect();
        let pairs = closest_pairs(&moved, target);
        let Some(step) = linearized_step(&pairs, with_scale) else {
            break;
        };
        motion = step.after(&motion);
        let negligible = step.rotation_degrees() < 1e-6
            && (step.scale - 1.0).abs() < 1e-9
            && step.translation.norm() <= SETTLED * (extent + before);
        if negligible {
            break;
        }
    }
    let report = AlignmentReport {
        applied: alignment != Alignment::None,
        rotation_degrees: motion.rotation_degrees(),
        translation: motion.translation.into(),
        scale: motion.scale,
        median_distance_before: before,
        median_distance_after: median_distance(&sample, target, &motion),
        matrix: motion.matrix(),
    };
    (motion, report)
}

/// Whether the fit of `report` explains a drift away: the frame was more than a quarter of
/// the median edge `spacing` from the previous one, and the motion at least halves that.
pub fn explains_drift(report: &AlignmentReport, spacing: f64) -> bool {
    let (before, after) = (report.median_distance_before, report.median_distance_after);
    before > 0.25 * spacing && after < 0.5 * before
}

/// A point, its closest point on the target and the target's unit normal there.
type Pair = (Vector3<f64>, Vector3<f64>, Vector3<f64>);

/// Each point with its closest point on `target`, the farthest (beyond [`TRIM`] medians) left
/// out.
fn closest_pairs(points: &[Vector3<f64>], target: &FrameSurface) -> Vec<Pair> {
    let pairs: Vec<Pair> = points
        .par_iter()
        .map(|p| {
            let (q, n) = target.closest_point_and_normal(p);
            (*p, q.position, n)
        })
        .collect();
    let distances: Vec<f64> = pairs.iter().map(|(p, q, _)| (p - q).norm()).collect();
    let limit = TRIM * median(distances.clone());
    pairs
        .into_iter()
        .zip(distances)
        .filter(|(_, d)| *d <= limit)
        .map(|(pair, _)| pair)
        .collect()
}

/// One Gauss–Newton step of the point-to-plane distance (Chen & Medioni 1992), which converges
/// in a few iterations where point-to-point pairs would slide along a smooth surface for
/// hundreds: with `x ↦ x + δs x + ω × x + t` (small `ω`, `δs`), minimize
/// `Σ (n · (p + δs p + ω × p + t − q))²`, a 6×6 (7×7 with scale) least-squares problem; the
/// rotation is then the exact one of angle `|ω|` about `ω`. `None` if it is singular.
fn linearized_step(pairs: &[Pair], with_scale: bool) -> Option<Motion> {
    if pairs.len() < 7 {
        return None;
    }
    let dimension = if with_scale { 7 } else { 6 };
    let mut normal = nalgebra::DMatrix::<f64>::zeros(dimension, dimension);
    let mut rhs = nalgebra::DVector::<f64>::zeros(dimension);
    for (p, q, n) in pairs {
        let c = p.cross(n);
        let mut row = vec![c.x, c.y, c.z, n.x, n.y, n.z];
        if with_scale {
            row.push(p.dot(n));
        }
        let row = nalgebra::DVector::from_vec(row);
        normal += &row * row.transpose();
        rhs += &row * n.dot(&(q - p));
    }
    // A little damping: directions the surface does not pin (a sphere's rotations, a
    // cylinder's slide) stay put instead of taking round-off for a motion.
    let damping = 1e-9 * normal.trace() / dimension as f64;
    normal += nalgebra::DMatrix::<f64>::identity(dimension, dimension) * damping;
    let x = normal.cholesky()?.solve(&rhs);
    let omega = Vector3::new(x[0], x[1], x[2]);
    let rotation = nalgebra::Rotation3::new(omega).into_inner();
    Some(Motion {
        rotation,
        scale: if with_scale { 1.0 + x[6] } else { 1.0 },
        translation: Vector3::new(x[3], x[4], x[5]),
    })
}

fn median_distance(points: &[Vector3<f64>], target: &FrameSurface, motion: &Motion) -> f64 {
    median(
        points
            .par_iter()
            .map(|p| {
                let x = motion.apply(p);
                (target.closest_point(&x).position - x).norm()
            })
            .collect(),
    )
}

pub(super) use crate::statistics::median;
