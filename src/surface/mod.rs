//! Moving surfaces fitted through point clouds: cell centres, landmarks or detected surface
//! points per frame become one mesh with fixed connectivity, whose vertices move with the fit.
//! From 3-D images, the points are the bright voxels, weighted by their brightness
//! ([`voxels`], [`fit_surface_weighted`]); or the closed surface of the object is found
//! ([`isosurface`]).
//!
//! # The model
//!
//! A **reference** surface `X(ξ)` with unit normal `N(ξ)` is chosen once for all frames, and
//! frame `k`'s surface is a height over it:
//!
//! ```text
//! x_k(ξ) = X(ξ) + h_k(ξ) N(ξ)
//! ```
//!
//! - [`Shape::SphereLike`]: `X` the sphere of centre `c` and radius `R` fitted to frame 0's
//!   points by algebraic least squares (`|p|² = 2 c·p + d`, `R² = d + |c|²`), `N` its outward
//!   normal; a point `p` sits at direction `ξ = (p − c)/|p − c|` with height `|p − c| − R`. The
//!   mesh is an icosphere of radius `R`, whole or cut to the cap of directions within the
//!   largest angle of any point from their mean direction, plus a margin.
//! - [`Shape::Graph`]: `X` the plane `z = 0` over the points' `(x, y)` bounding box plus a
//!   margin, `N = ẑ`; a point sits at `ξ = (x, y)` with height `z`. The paper's Experiment II
//!   form.
//!
//! **The height of each frame** is a smoothing spline (Wahba, *Spline Models for Observational
//! Data*, 1990) in P1 finite elements on the reference mesh:
//!
//! ```text
//! h_k = argmin_h  Σ_n (h(ξ_n) − h_n)²  +  λ hᵀ L M⁻¹ L h,     (BᵀB + λ L M⁻¹ L) h = Bᵀ h_data
//! ```
//!
//! with `B` (N × V) the barycentric interpolation at the points, `L` the cotan Laplacian and `M`
//! the lumped mass of the reference mesh (`[`crate::fem`]`): `hᵀ L M⁻¹ L h` is the discrete
//! thin-plate energy `∫ (Δh)² dA` (its natural boundary conditions flatten the surface
//! slightly at the rim, Stein et al. 2018, which the margin keeps away from the points). Its
//! null space is the constants, so one point already determines `h`; a fit is refused below
//! three points a frame, and the sphere below four points or for points on a plane (the
//! reference is then undetermined).
//!
//! **The smoothing weight is unit-free.** With `ρ = 1/d̄²` the density of the points (`d̄ =
//! √(A/N)` the mean point spacing over the reference's area `A`), `Σ_n ≈ ρ ∫ dA`, and the energy
//! reads `ρ [∫ (h − f)² + ℓ⁴ ∫ (Δh)²]` with `λ = ρ ℓ⁴`: variations of the height shorter than
//! `ℓ` are smoothed away. [`FitOptions::smoothing`] gives `ℓ = S d̄` in mean point spacings, so
//! `λ = S⁴ d̄²`, and scaling the points scales the surface and nothing else. One factorization
//! order (METIS) serves all frames; each frame's `B` differs, so each is factorized anew.

pub mod closed;
mod closing;
pub mod isosurface;
mod points;
mod reference;
pub mod voxels;

pub use closed::{closed_sequence, ClosedError, ClosedEvent, ClosedOptions, ClosedSequence};
pub use isosurface::{
    find_surface, find_surface_consuming, FoundSurface, IsosurfaceError, IsosurfaceOptions, Level,
};
pub use points::read_points;
pub use voxels::{foreground_points, ForegroundPoints};

use crate::fem::{cotan_laplacian, vertex_areas, SparseMatrix};
use crate::geometry::IntrinsicGeometry;
use crate::linalg::cholesky::{analyze, CholeskyFactor};
use crate::mesh::Mesh;
use crate::spatial::FrameSurface;
use faer::sparse::{SparseColMat, Triplet};
use faer::Par;
use nalgebra::Vector3;
use rayon::prelude::*;
use reference::ReferenceMesh;

/// The reference a height is measured from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A height over a sphere fitted to frame 0's points: the cap their directions cover (plus
    /// the margin), or the whole sphere.
    SphereLike { whole: bool },
    /// `z = h(x, y)` over the points' bounding box (plus the margin).
    Graph,
}

/// How fine the mesh is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    /// The mean edge length (physical units) at most this (the coarsest icosphere level or grid
    /// that reaches it).
    EdgeLength(f64),
    /// About this many vertices (the icosphere level whose count is nearest on a log scale;
    /// the grid spacing that gives it).
    Vertices(usize),
}

/// How to fit ([`fit_surface`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    pub shape: Shape,
    pub resolution: Resolution,
    /// `S`: the smoothing length in mean point spacings (module docs); 0 interpolates as
    /// closely as the mesh allows.
    pub smoothing: f64,
    /// How far the mesh reaches beyond the outermost point, in mean point spacings.
    pub margin: f64,
}

/// The default smoothing length: one mean point spacing, the finest detail that points so far
/// apart can describe.
pub const DEFAULT_SMOOTHING: f64 = 1.0;
/// The default margin: one mean point spacing beyond the outermost point.
pub const DEFAULT_MARGIN: f64 = 1.0;

impl Default for FitOptions {
    /// A sphere-like cap of about 16,000 vertices, smoothing and margin of one point spacing.
    fn default() -> Self {
        Self {
            shape: Shape::SphereLike { whole: false },
            resolution: Resolution::Vertices(16_000),
            smoothing: DEFAULT_SMOOTHING,
            margin: DEFAULT_MARGIN,
        }
    }
}

/// The reference of a fitted surface.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Reference {
    Sphere {
        centre: [f64; 3],
        radius: f64,
        /// The cap's half-angle in degrees about `axis`; `None` for the whole sphere.
        cap_degrees: Option<f64>,
        axis: [f64; 3],
    },
    /// The plane `z = 0` over `[min, max]` in `x` and `y`.
    Plane { min: [f64; 2], max: [f64; 2] },
}

/// How well one frame's points are fitted.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FrameFit {
    /// Points used.
    pub points: usize,
    /// Points outside the reference mesh (only with a cap or a plane that misses them).
    pub dropped: usize,
    /// `√(Σ (h(ξ_n) − h_n)² / N)`: how far the points are from the surface along its normal.
    pub rms_residual: f64,
    pub max_residual: f64,
}

/// A moving surface through the points: fixed faces, positions per frame.
#[derive(Clone, Debug)]
pub struct FittedSurface {
    /// Counter-clockwise seen from outside (normals away from the sphere's centre, or +z).
    pub faces: Vec<[u32; 3]>,
    /// `positions[k][v]`.
    pub positions: Vec<Vec<Vector3<f64>>>,
    pub reference: Reference,
    pub frames: Vec<FrameFit>,
    /// `d̄`, the unit of the smoothing and the margin.
    pub mean_point_spacing: f64,
    /// The smoothing weight `λ = S⁴ d̄²`.
    pub lambda: f64,
}

impl FittedSurface {
    /// The mean edge length of frame 0.
    pub fn mean_edge_length(&self) -> f64 {
        let x = &self.positions[0];
        let total: f64 = (self.faces.iter())
            .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
            .map(|(a, b)| (x[a as usize] - x[b as usize]).norm())
            .sum();
        total / (3 * self.faces.len()) as f64
    }
}

/// Why a surface could not be fitted. Variants name the frame and point.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    #[error("no frames of points")]
    NoFrames,
    #[error("frame {frame}, point {point} is not finite")]
    NonFinite { frame: usize, point: usize },
    #[error("frame {frame} has {points} points; a surface needs at least {needed}")]
    TooFewPoints {
        frame: usize,
        points: usize,
        needed: usize,
    },
    #[error(
        "frame 0's points lie on a plane: no sphere is determined by them (use --shape graph)"
    )]
    Coplanar,
    #[error("the points' (x, y) lie on a line: no height z = h(x, y) is determined (use --shape sphere-like, or rotate the data)")]
    Collinear,
    #[error("frame {frame}: {dropped} of {points} points are outside the reference surface, too few remain")]
    Outside {
        frame: usize,
        dropped: usize,
        points: usize,
    },
    #[error("{what} must be a positive number, got {value}")]
    BadSetting { what: &'static str, value: f64 },
    #[error("frame {frame}: the weights must be one positive number per point, for every frame")]
    Weights { frame: usize },
    #[error("the reference mesh: {0}")]
    Mesh(String),
    #[error("frame {frame}: the spline system could not be factorized ({detail}); are the coordinates badly scaled?")]
    Factorization { frame: usize, detail: String },
    #[error("frame {frame}, point {point}: coordinate {value:e} is too large (beyond ±{MAX_COORDINATE:e}) to fit in double precision: rescale the points (e.g. to micrometres)")]
    TooLarge {
        frame: usize,
        point: usize,
        value: f64,
    },
    #[error("frame {frame}: the points span only {extent:e}, too small to fit in double precision: rescale them (e.g. to micrometres)")]
    TooSmall { frame: usize, extent: f64 },
    #[error("{0}")]
    OverBudget(#[from] crate::limits::OverBudget),
}

/// The largest coordinate a fit takes: the spline's weight grows with the fourth power of the
/// point spacing and the sphere fit with the fourth power of the coordinates, so beyond about
/// 1e77 they overflow; 1e50 leaves room for the sums over many points.
pub const MAX_COORDINATE: f64 = 1e50;

/// The smallest extent of a frame's points a fit takes (the same powers underflow).
pub const MIN_EXTENT: f64 = 1e-50;

/// Fits a moving surface through `frames[k]` (module docs).
pub fn fit_surface(
    frames: &[Vec<Vector3<f64>>],
    options: &FitOptions,
) -> Result<FittedSurface, SurfaceError> {
    fit(frames, None, options)
}

/// Weighted points: `weights[k][n] > 0` for point `n` of frame `k`, and the length the
/// smoothing is measured in.
struct Weighting<'a> {
    weights: &'a [Vec<f64>],
    length: f64,
}

/// [`fit_surface`] with a weight per point, `weights[k][n] > 0` (the brightness of voxels,
/// [`foreground_points`]): the data term is `Σ_n w_n (h(ξ_n) − h_n)²` with each frame's weights
/// scaled to mean 1, and the smoothing length is `ℓ = S · length` in physical units, where
/// points as dense as voxels have no spacing to measure it in: `λ = (N/A) ℓ⁴`, `N/A` the
/// points' density (for `length` the mean point spacing this is [`fit_surface`]'s `λ`).
pub fn fit_surface_weighted(
    frames: &[Vec<Vector3<f64>>],
    weights: &[Vec<f64>],
    length: f64,
    options: &FitOptions,
) -> Result<FittedSurface, SurfaceError> {
    if !(length.is_finite() && length > 0.0) {
        let what = "the smoothing's length unit";
        return Err(SurfaceError::BadSetting {
            what,
            value: length,
        });
    }
    for (frame, (points, w)) in frames.iter().zip(weights).enumerate() {
        if w.len() != points.len() || w.iter().any(|&w| !(w.is_finite() && w > 0.0)) {
            return Err(SurfaceError::Weights { frame });
        }
    }
    if weights.len() != frames.len() {
        return Err(SurfaceError::Weights {
            frame: weights.len().min(frames.len()),
        });
    }
    let normalized: Vec<Vec<f64>> = (weights.iter())
        .map(|w| {
            let mean = w.iter().sum::<f64>() / w.len().max(1) as f64;
            w.iter().map(|x| x / mean).collect()
        })
        .collect();
    let weighting = Weighting {
        weights: &normalized,
        length,
    };
    fit(frames, Some(weighting), options)
}

fn fit(
    frames: &[Vec<Vector3<f64>>],
    weighting: Option<Weighting>,
    options: &FitOptions,
) -> Result<FittedSurface, SurfaceError> {
    check(frames, options)?;
    check_memory(frames)?;
    let reference = ReferenceMesh::new(frames, options)?;
    let mesh = Mesh::new(reference.positions.len(), reference.faces.clone())
        .map_err(|e| SurfaceError::Mesh(e.to_string()))?;
    let geometry = IntrinsicGeometry::from_positions(&mesh, &reference.positions)
        .map_err(|e| SurfaceError::Mesh(e.to_string()))?;
    let bilaplacian = bilaplacian(&mesh, &geometry);
    let n_points = frames.iter().map(Vec::len).sum::<usize>() as f64 / frames.len() as f64;
    let spacing = (geometry.total_area() / n_points).sqrt();
    let lambda = match &weighting {
        None => options.smoothing.powi(4) * spacing * spacing,
        Some(w) => (options.smoothing * w.length).powi(4) / (spacing * spacing),
    };
    let locator = FrameSurface::new(0, &reference.positions, &reference.faces, &reference.zeros)
        .map_err(|e| SurfaceError::Mesh(e.to_string()))?;
    let symbolic = analyze(bilaplacian.symbolic(), 1);
    let fits: Vec<(Vec<f64>, FrameFit)> = frames
        .par_iter()
        .enumerate()
        .map(|(k, points)| {
            let weights = weighting.as_ref().map(|w| w.weights[k].as_slice());
            let samples = reference.locate(&locator, points, weights);
            fit_heights(k, &samples, points.len(), &bilaplacian, lambda, &symbolic)
        })
        .collect::<Result<_, _>>()?;
    let positions = fits
        .iter()
        .map(|(heights, _)| reference.lift(heights))
        .collect();
    Ok(FittedSurface {
        faces: reference.faces.clone(),
        positions,
        reference: reference.describe(),
        frames: fits.into_iter().map(|(_, fit)| fit).collect(),
        mean_point_spacing: spacing,
        lambda,
    })
}

fn check(frames: &[Vec<Vector3<f64>>], options: &FitOptions) -> Result<(), SurfaceError> {
    if frames.is_empty() {
        return Err(SurfaceError::NoFrames);
    }
    for (frame, points) in frames.iter().enumerate() {
        check_scale(frame, points)?;
        if points.len() < 3 {
            return Err(SurfaceError::TooFewPoints {
                frame,
                points: points.len(),
                needed: 3,
            });
        }
    }
    let positive = |what, value: f64| match value.is_finite() && value > 0.0 {
        true => Ok(()),
        false => Err(SurfaceError::BadSetting { what, value }),
    };
    match options.resolution {
        Resolution::EdgeLength(length) => positive("the edge length", length)?,
        Resolution::Vertices(n) => positive("the vertex count", n as f64)?,
    }
    if options.smoothing != 0.0 {
        positive("the smoothing", options.smoothing)?;
    }
    if options.margin != 0.0 {
        positive("the margin", options.margin)?;
    }
    Ok(())
}

/// Every point finite and within [`MAX_COORDINATE`], and the points not all within
/// [`MIN_EXTENT`] of each other unless they coincide (what [`SurfaceError::Coplanar`] reports).
fn check_scale(frame: usize, points: &[Vector3<f64>]) -> Result<(), SurfaceError> {
    let mut low = Vector3::repeat(f64::INFINITY);
    let mut high = Vector3::repeat(f64::NEG_INFINITY);
    for (point, p) in points.iter().enumerate() {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(SurfaceError::NonFinite { frame, point });
        }
        if let Some(&value) = p.iter().find(|c| c.abs() > MAX_COORDINATE) {
            return Err(SurfaceError::TooLarge {
                frame,
                point,
                value,
            });
        }
        low = low.inf(p);
        high = high.sup(p);
    }
    let extent = (high - low).max();
    match extent > 0.0 && extent < MIN_EXTENT {
        true => Err(SurfaceError::TooSmall { frame, extent }),
        false => Ok(()),
    }
}

/// Bytes a point takes while its frame is fitted: its sample and the nine entries of `BᵀB`.
const BYTES_PER_POINT: u64 = (std::mem::size_of::<HeightSample>()
    + 9 * std::mem::size_of::<Triplet<usize, usize, f64>>()) as u64;

/// The frames' fitting memory (as many frames at once as rayon has threads) against the
/// memory limit, before any of it is allocated.
fn check_memory(frames: &[Vec<Vector3<f64>>]) -> Result<(), SurfaceError> {
    let at_once = rayon::current_num_threads().min(frames.len()).max(1);
    let largest = frames.iter().map(Vec::len).max().unwrap_or(0);
    let what = format!("fitting {at_once} frames of up to {largest} points at once");
    let points = (largest as u64).saturating_mul(at_once as u64);
    Ok(crate::limits::check_items(what, points, BYTES_PER_POINT)?)
}

/// `L M⁻¹ L` with the lumped mass (V × V, the 2-ring pattern), built column by column:
/// `(L M⁻¹ L)_ij = Σ_k L_ik L_kj / m_k`.
fn bilaplacian(mesh: &Mesh, geometry: &IntrinsicGeometry) -> SparseMatrix {
    let laplacian = cotan_laplacian(mesh, geometry);
    let areas = vertex_areas(mesh, geometry);
    let n = mesh.n_vertices();
    let mut triplets = Vec::new();
    for (k, area) in areas.iter().enumerate() {
        let column: Vec<(usize, f64)> = laplacian
            .row_idx_of_col(k)
            .zip(laplacian.val_of_col(k))
            .map(|(i, &v)| (i, v))
            .collect();
        for &(i, a) in &column {
            for &(j, b) in &column {
                triplets.push(Triplet::new(i, j, a * b / area));
            }
        }
    }
    SparseColMat::try_new_from_triplets(n, n, &triplets).expect("indices below n")
}

/// A point on the reference: its face's corners, barycentric weights, its height and the
/// weight of its term in the fit.
pub(crate) struct HeightSample {
    corners: [usize; 3],
    weights: [f64; 3],
    height: f64,
    weight: f64,
}

/// Solves frame `k`'s spline `(BᵀWB + λ L M⁻¹ L) h = BᵀW h_data` (`W` the points' weights).
fn fit_heights(
    frame: usize,
    samples: &[HeightSample],
    n_points: usize,
    bilaplacian: &SparseMatrix,
    lambda: f64,
    symbolic: &std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>,
) -> Result<(Vec<f64>, FrameFit), SurfaceError> {
    let dropped = n_points - samples.len();
    if samples.len() < 3 {
        return Err(SurfaceError::Outside {
            frame,
            dropped,
            points: n_points,
        });
    }
    let n = bilaplacian.nrows();
    // BᵀB on the bilaplacian's pattern (its corners share a face, so the pattern holds them),
    // with a tiny multiple of it so that λ = 0 stays definite away from the points.
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    let mut rhs = vec![0.0; n];
    for s in samples {
        for (a, wa) in s.corners.iter().zip(s.weights) {
            rhs[*a] += s.weight * wa * s.height;
            for (b, wb) in s.corners.iter().zip(s.weights) {
                triplets.push(Triplet::new(*a, *b, s.weight * wa * wb));
            }
        }
    }
    let scale = lambda.max(1e-12 * bilaplacian_scale(bilaplacian));
    for k in 0..n {
        for (i, &v) in bilaplacian.row_idx_of_col(k).zip(bilaplacian.val_of_col(k)) {
            triplets.push(Triplet::new(i, k, scale * v));
        }
    }
    let system = SparseColMat::try_new_from_triplets(n, n, &triplets).expect("indices below n");
    let factor = CholeskyFactor::<f64>::new(symbolic, system.as_ref(), Par::Seq)
        .map_err(|detail| SurfaceError::Factorization { frame, detail })?;
    factor.solve_in_place(&mut rhs, Par::Seq);
    let heights = rhs;
    let residuals: Vec<f64> = samples
        .iter()
        .map(|s| {
            let fitted: f64 = s
                .corners
                .iter()
                .zip(s.weights)
                .map(|(&v, w)| w * heights[v])
                .sum();
            fitted - s.height
        })
        .collect();
    let fit = FrameFit {
        points: samples.len(),
        dropped,
        rms_residual: (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64)
            .sqrt(),
        max_residual: residuals.iter().fold(0.0, |m, r| m.max(r.abs())),
    };
    Ok((heights, fit))
}

/// The inverse of the largest diagonal entry of `L M⁻¹ L` relative to 1: a scale that makes
/// the regularizing floor of a λ = 0 fit a fixed fraction of the data term.
fn bilaplacian_scale(bilaplacian: &SparseMatrix) -> f64 {
    let largest = (0..bilaplacian.ncols())
        .flat_map(|k| {
            bilaplacian
                .row_idx_of_col(k)
                .zip(bilaplacian.val_of_col(k))
                .filter(move |(i, _)| *i == k)
                .map(|(_, v)| v.abs())
        })
        .fold(0.0, f64::max);
    1.0 / largest.max(f64::MIN_POSITIVE)
}
