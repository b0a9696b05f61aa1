//! The reference surface of a fit and its mesh: a sphere fitted to frame 0's points (whole or a
//! cap) or a rectangle of the plane `z = 0` (module docs of [`super`]).

use super::{FitOptions, HeightSample, Reference, Resolution, Shape, SurfaceError};
use crate::shapes::{grid, icosphere};
use crate::spatial::FrameSurface;
use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Subdivision levels of the icosphere tried (level 9: 2.6 million vertices on the sphere).
const MAX_LEVEL: u32 = 9;

/// The reference mesh: positions `X(v)`, normals `N(v)`, faces, and what it is.
pub(super) struct ReferenceMesh {
    pub positions: Vec<Vector3<f64>>,
    pub faces: Vec<[u32; 3]>,
    /// Grey values for the locator (unused).
    pub zeros: Vec<f64>,
    normals: Vec<Vector3<f64>>,
    kind: Kind,
}

enum Kind {
    Sphere {
        centre: Vector3<f64>,
        radius: f64,
        axis: Vector3<f64>,
        /// Half-angle (radians); `None`: whole.
        cap: Option<f64>,
    },
    Plane {
        min: [f64; 2],
        max: [f64; 2],
    },
}

impl ReferenceMesh {
    pub fn new(frames: &[Vec<Vector3<f64>>], options: &FitOptions) -> Result<Self, SurfaceError> {
        let n_points = frames.iter().map(Vec::len).sum::<usize>() as f64 / frames.len() as f64;
        match options.shape {
            Shape::SphereLike { whole } => {
                if frames[0].len() < 4 {
                    return Err(SurfaceError::TooFewPoints {
                        frame: 0,
                        points: frames[0].len(),
                        needed: 4,
                    });
                }
                let (centre, radius) = fit_sphere(&frames[0])?;
                Ok(Self::sphere(
                    frames, centre, radius, whole, n_points, options,
                ))
            }
            Shape::Graph => Self::plane(frames, n_points, options),
        }
    }

    fn sphere(
        frames: &[Vec<Vector3<f64>>],
        centre: Vector3<f64>,
        radius: f64,
        whole: bool,
        n_points: f64,
        options: &FitOptions,
    ) -> Self {
        let directions: Vec<Vector3<f64>> = (frames.iter().flatten())
            .filter_map(|p| (p - centre).try_normalize(0.0))
            .collect();
        let axis = directions
            .iter()
            .sum::<Vector3<f64>>()
            .try_normalize(0.0)
            .unwrap_or(Vector3::z());
        let widest = directions
            .iter()
            .map(|d| d.dot(&axis).clamp(-1.0, 1.0).acos())
            .fold(0.0, f64::max);
        let covered = 2.0 * PI * radius * radius * (1.0 - widest.cos());
        let spacing = (covered / n_points).sqrt();
        let angle = widest + options.margin * spacing / radius;
        let cap = (!whole && angle < PI).then_some(angle);
        let fraction = cap.map_or(1.0, |a| (1.0 - a.cos()) / 2.0);
        let level = icosphere_level(options.resolution, radius, fraction);
        let unit = icosphere(level);
        let inside = |d: &Vector3<f64>| cap.is_none_or(|a| d.dot(&axis) >= a.cos());
        let faces: Vec<[u32; 3]> = unit
            .faces
            .iter()
            .filter(|f| f.iter().all(|&v| inside(&unit.positions[v as usize])))
            .copied()
            .collect();
        let (directions, faces) = compact(&unit.positions, &faces);
        Self {
            positions: directions.iter().map(|d| centre + radius * d).collect(),
            zeros: vec![0.0; directions.len()],
            normals: directions,
            faces,
            kind: Kind::Sphere {
                centre,
                radius,
                axis,
                cap,
            },
        }
    }

    fn plane(
        frames: &[Vec<Vector3<f64>>],
        n_points: f64,
        options: &FitOptions,
    ) -> Result<Self, SurfaceError> {
        check_not_collinear(frames.iter().flatten())?;
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in frames.iter().flatten() {
            for axis in 0..2 {
                min[axis] = min[axis].min(p[axis]);
                max[axis] = max[axis].max(p[axis]);
            }
        }
        let spacing = ((max[0] - min[0]) * (max[1] - min[1]) / n_points).sqrt();
        for axis in 0..2 {
            min[axis] -= options.margin * spacing;
            max[axis] += options.margin * spacing;
        }
        let (width, height) = (max[0] - min[0], max[1] - min[1]);
        // A right-triangle grid of step s has mean edge (2 + √2)/3 · s.
        let step = match options.resolution {
            Resolution::EdgeLength(length) => length * 3.0 / (2.0 + 2f64.sqrt()),
            Resolution::Vertices(n) => (width * height / n as f64).sqrt(),
        };
        let cells = |extent: f64| ((extent / step).ceil() as usize).max(1);
        let rectangle = grid(cells(width), cells(height), width, height);
        let offset = Vector3::new(min[0], min[1], 0.0);
        Ok(Self {
            positions: rectangle.positions.iter().map(|p| p + offset).collect(),
            zeros: vec![0.0; rectangle.positions.len()],
            normals: vec![Vector3::z(); rectangle.positions.len()],
            faces: rectangle.faces,
            kind: Kind::Plane { min, max },
        })
    }

    /// Where each point sits on the reference, with its height and weight (`weights[n]`, 1
    /// without); points beyond the mesh's extent are left out.
    pub fn locate(
        &self,
        locator: &FrameSurface,
        points: &[Vector3<f64>],
        weights: Option<&[f64]>,
    ) -> Vec<HeightSample> {
        let weight = |n: usize| weights.map_or(1.0, |w| w[n]);
        points
            .par_iter()
            .enumerate()
            .filter_map(|(n, p)| {
                let (on_reference, height) = match self.kind {
                    Kind::Sphere {
                        centre,
                        radius,
                        axis,
                        cap,
                    } => {
                        let offset = p - centre;
                        let direction = offset.try_normalize(0.0)?;
                        if cap.is_some_and(|a| direction.dot(&axis) < a.cos()) {
                            return None;
                        }
                        (centre + radius * direction, offset.norm() - radius)
                    }
                    Kind::Plane { min, max } => {
                        let inside = (0..2).all(|a| p[a] >= min[a] && p[a] <= max[a]);
                        if !inside {
                            return None;
                        }
                        (Vector3::new(p.x, p.y, 0.0), p.z)
                    }
                };
                let at = locator.locate(&on_reference);
                Some(HeightSample {
                    corners: self.faces[at.face].map(|v| v as usize),
                    weights: at.barycentric,
                    height,
                    weight: weight(n),
                })
            })
            .collect()
    }

    /// `x(v) = X(v) + h(v) N(v)`.
    pub fn lift(&self, heights: &[f64]) -> Vec<Vector3<f64>> {
        (self.positions.iter().zip(&self.normals).zip(heights))
            .map(|((x, n), h)| x + *h * n)
            .collect()
    }

    pub fn describe(&self) -> Reference {
        match self.kind {
            Kind::Sphere {
                centre,
                radius,
                axis,
                cap,
            } => Reference::Sphere {
                centre: centre.into(),
                radius,
                cap_degrees: cap.map(f64::to_degrees),
                axis: axis.into(),
            },
            Kind::Plane { min, max } => Reference::Plane { min, max },
        }
    }
}

/// The sphere `|p − c|² = R²` nearest to the points in the algebraic sense: least squares of
/// `2 c·p + d = |p|²` (`R² = d + |c|²`), in coordinates centred and scaled for conditioning.
/// Points on a plane (or fewer than four) determine no sphere.
pub(super) fn fit_sphere(points: &[Vector3<f64>]) -> Result<(Vector3<f64>, f64), SurfaceError> {
    let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let scale = points
        .iter()
        .map(|p| (p - mean).norm())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let q: Vec<Vector3<f64>> = points.iter().map(|p| (p - mean) / scale).collect();
    let a = DMatrix::from_fn(q.len(), 4, |row, col| match col {
        3 => 1.0,
        _ => 2.0 * q[row][col],
    });
    let b = DVector::from_iterator(q.len(), q.iter().map(|p| p.norm_squared()));
    let svd = a.svd(true, true);
    let (largest, smallest) = (svd.singular_values.max(), svd.singular_values.min());
    if smallest <= 1e-9 * largest {
        return Err(SurfaceError::Coplanar);
    }
    let solution = svd.solve(&b, 0.0).map_err(|_| SurfaceError::Coplanar)?;
    let c = Vector3::new(solution[0], solution[1], solution[2]);
    let radius_squared = solution[3] + c.norm_squared();
    if radius_squared <= 0.0 {
        return Err(SurfaceError::Coplanar);
    }
    Ok((mean + scale * c, scale * radius_squared.sqrt()))
}

/// Refuses points whose `(x, y)` lie on one line (or one point).
fn check_not_collinear<'a>(
    points: impl Iterator<Item = &'a Vector3<f64>> + Clone,
) -> Result<(), SurfaceError> {
    let n = points.clone().count() as f64;
    let mean = points
        .clone()
        .map(|p| p.xy())
        .sum::<nalgebra::Vector2<f64>>()
        / n;
    let scatter = points
        .map(|p| {
            let d = p.xy() - mean;
            d * d.transpose()
        })
        .sum::<nalgebra::Matrix2<f64>>();
    let eigen = scatter.symmetric_eigenvalues();
    let (small, large) = (eigen.min(), eigen.max());
    match small > 1e-12 * large && large > 0.0 {
        true => Ok(()),
        false => Err(SurfaceError::Collinear),
    }
}

/// The icosphere level for the resolution on a sphere of `radius`, of which the mesh keeps
/// `fraction` (the cap's share of the area).
fn icosphere_level(resolution: Resolution, radius: f64, fraction: f64) -> u32 {
    match resolution {
        // Level l has about 1.2 R / 2^l mean edge (equilateral triangles of the sphere's area
        // 4πR² / (20·4^l)).
        Resolution::EdgeLength(length) => (0..=MAX_LEVEL)
            .find(|&l| 1.2 * radius / 2f64.powi(l as i32) <= length)
            .unwrap_or(MAX_LEVEL),
        Resolution::Vertices(n) => (0..=MAX_LEVEL)
            .min_by(|&a, &b| {
                let miss = |l: u32| {
                    let count = fraction * (10.0 * 4f64.powi(l as i32) + 2.0);
                    (count / n as f64).ln().abs()
                };
                miss(a).total_cmp(&miss(b))
            })
            .unwrap_or(MAX_LEVEL),
    }
}

/// The vertices that `faces` use, renumbered in order.
pub(super) fn compact(
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let mut index = vec![u32::MAX; positions.len()];
    let mut kept = Vec::new();
    let faces = faces
        .iter()
        .map(|face| {
            face.map(|v| {
                if index[v as usize] == u32::MAX {
                    index[v as usize] = kept.len() as u32;
                    kept.push(positions[v as usize]);
                }
                index[v as usize]
            })
        })
        .collect();
    (kept, faces)
}
