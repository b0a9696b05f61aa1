//! Synthetic sequences, most with a known flow (measure computed flows against it with
//! [`crate::accuracy`]).

use crate::flow::{FlowError, Images, MeshSequence};
use crate::shapes::{icosphere, uv_sphere, Surface};
use crate::track::TrackFrame;
use nalgebra::{Rotation3, Vector2, Vector3};

/// A sequence and the flow that generated it: `flow[s][i]` in R^3 on frame `s`.
pub struct GroundTruth {
    pub sequence: MeshSequence,
    pub flow: Vec<Vec<Vector3<f64>>>,
}

impl GroundTruth {
    /// The true flow in the vertex frames of each slab (`docs/discretization.md` §7), as
    /// [`crate::flow::FlowResult::intrinsic`]: `P_iᵀ u_i` with `P_i` the orthonormal frame of
    /// vertex `i` on frame `s` (the tangential part; synthetic flows are tangent already).
    pub fn intrinsic_flow(&self) -> Result<Vec<Vec<Vector2<f64>>>, FlowError> {
        (0..self.sequence.n_slabs())
            .map(|s| {
                let frames = self
                    .sequence
                    .slab_frames(s)?
                    .expect("synthetic frames are embedded");
                Ok(frames
                    .iter()
                    .zip(&self.flow[s])
                    .map(|(p, u)| p.transpose() * u)
                    .collect())
            })
            .collect()
    }
}

/// A smooth grey-value pattern on R^3 with features in every direction (range about [0, 1]).
pub fn texture(p: &Vector3<f64>) -> f64 {
    0.5 + 0.2 * (3.0 * p.x + 1.0).sin() * (2.0 * p.y).cos()
        + 0.15 * (4.0 * p.z - p.x).sin()
        + 0.1 * (2.5 * p.y + 3.0 * p.z).cos()
}

/// Sparse features on a dark background (range about [0.1, 0.9]): twelve round bright blobs
/// (Gaussians of radius 0.12) spread evenly over the unit sphere (a Fibonacci lattice), like
/// cells on an embryo's surface. Most of the sphere carries no gradient.
pub fn blobs(p: &Vector3<f64>) -> f64 {
    const N: usize = 12;
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let blob = |j: usize| {
        let z = 1.0 - 2.0 * (j as f64 + 0.5) / N as f64;
        let (sin, cos) = (golden_angle * j as f64).sin_cos();
        let r = (1.0 - z * z).sqrt();
        Vector3::new(r * cos, r * sin, z)
    };
    0.1 + (0..N)
        .map(|j| 0.8 * (-(p - blob(j)).norm_squared() / (2.0 * 0.12f64.powi(2))).exp())
        .sum::<f64>()
}

/// The unit icosphere of the given level at rest, with [`texture`] turning about the z-axis at
/// `omega` radians per unit time; frames at `0, dt, 2 dt, …`. The true flow is `u = ω ẑ × x`.
///
/// This is [`deforming_sphere`] with `strain = 0`.
pub fn rotating_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<GroundTruth, FlowError> {
    deforming_sphere(level, n_frames, dt, omega, 0.0)
}

/// [`rotating_sphere`] with another image on the sphere, e.g. [`blobs`].
pub fn rotating_sphere_with(
    image: impl Fn(&Vector3<f64>) -> f64,
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<GroundTruth, FlowError> {
    textured_deforming_sphere(image, level, n_frames, dt, omega, 0.0)
}

/// A sphere that stretches into an ellipsoid while a texture turns on it; frames at
/// `t_k = k dt`.
///
/// Vertex `i` is the material point `p_i` of the unit icosphere, at `x_i(t) = D(t) p_i` with
///
/// ```text
/// D(t) = diag(1 + εt, 1, 1 / (1 + εt))        (ε = strain)
/// ```
///
/// (volume-preserving, not rigid and not isometric for `ε ≠ 0`). The image is [`texture`] on
/// the rest sphere turned by `ωt` about the z-axis: `I(t, p) = texture(R_z(−ωt) p)`. A texture
/// point sits at `p(t) = R_z(ωt) q`, moving on the rest sphere with velocity `ω ẑ × p`; on the
/// surface it moves with the push-forward by the linear map `D(t)`, so the true flow on frame
/// `s` is
///
/// ```text
/// u_s(x_i) = D(t_s) (ω ẑ × p_i)
/// ```
///
/// (tangent to the ellipsoid `D(t_s) S²`), and brightness constancy `∂_t I + dI(u) = 0` holds.
pub fn deforming_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
    strain: f64,
) -> Result<GroundTruth, FlowError> {
    textured_deforming_sphere(texture, level, n_frames, dt, omega, strain)
}

fn textured_deforming_sphere(
    image: impl Fn(&Vector3<f64>) -> f64,
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
    strain: f64,
) -> Result<GroundTruth, FlowError> {
    textured_sphere(|p| vec![image(p)], level, n_frames, dt, |_| omega, strain)
}

/// [`rotating_sphere`] with an image of several channels: `image(p)[c]` is channel `c`, e.g.
/// [`isoluminant`].
pub fn rotating_sphere_in_channels(
    image: impl Fn(&Vector3<f64>) -> Vec<f64>,
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<GroundTruth, FlowError> {
    textured_sphere(image, level, n_frames, dt, |_| omega, 0.0)
}

/// An isoluminant colour pattern (R, G, B in about `[0.2, 0.8]`): the hue varies with two
/// smooth patterns while the Rec. 709 luma `0.2126 R + 0.7152 G + 0.0722 B` is `0.5`
/// everywhere, so a grey (luma) image of it is blank and only colour shows the motion.
pub fn isoluminant(p: &Vector3<f64>) -> Vec<f64> {
    let luma = Vector3::new(0.2126, 0.7152, 0.0722);
    // Two orthonormal colour directions of zero luma.
    let first = Vector3::new(1.0, 0.0, 0.0).cross(&luma).normalize();
    let second = luma.cross(&first).normalize();
    let hue = (
        (3.0 * p.x + 1.0).sin() * (2.0 * p.y).cos() + 0.5 * (2.5 * p.y + 3.0 * p.z).cos(),
        (4.0 * p.z - p.x).sin() + 0.5 * (2.0 * p.x + 3.0 * p.y).sin(),
    );
    let colour = Vector3::repeat(0.5) + 0.15 * (hue.0 * first + hue.1 * second);
    colour.iter().copied().collect()
}

/// The icosphere stretched by `D(t)` ([`deforming_sphere`]) with `image` turning about the
/// z-axis at `rate(p)` radians per unit time at rest point `p`: `I(t, p) =
/// image(R_z(−rate(p) t) p)`, true flow `D(t_s) (rate(p) ẑ × p)`. A rate constant on circles of
/// latitude keeps every texture point on its circle.
fn textured_sphere(
    image: impl Fn(&Vector3<f64>) -> Vec<f64>,
    level: u32,
    n_frames: usize,
    dt: f64,
    rate: impl Fn(&Vector3<f64>) -> f64,
    strain: f64,
) -> Result<GroundTruth, FlowError> {
    let sphere = icosphere(level);
    let mesh = sphere.mesh().expect("icospheres are valid meshes");
    let times: Vec<f64> = (0..n_frames).map(|k| k as f64 * dt).collect();
    let turned_back =
        |t: f64, p: &Vector3<f64>| Rotation3::from_axis_angle(&Vector3::z_axis(), -rate(p) * t) * p;
    let images = times
        .iter()
        .map(|&t| {
            let values: Vec<Vec<f64>> = sphere
                .positions
                .iter()
                .map(|p| image(&turned_back(t, p)))
                .collect();
            (0..values[0].len())
                .map(|c| values.iter().map(|v| v[c]).collect())
                .collect()
        })
        .collect();
    let deform = |t: f64, v: &Vector3<f64>| stretch(strain * t, v);
    let frames = times
        .iter()
        .map(|&t| sphere.positions.iter().map(|p| deform(t, p)).collect())
        .collect();
    let flow = times[..n_frames.saturating_sub(1)]
        .iter()
        .map(|&t| {
            sphere
                .positions
                .iter()
                .map(|p| deform(t, &(rate(p) * Vector3::z().cross(p))))
                .collect()
        })
        .collect();
    let images = Images::from_channels(images);
    let sequence = MeshSequence::with_images(mesh, frames, images, Some(times))?;
    Ok(GroundTruth { sequence, flow })
}

/// `diag(1 + e, 1, 1 / (1 + e)) v`: exactly `v` for `e = 0`.
fn stretch(e: f64, v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new((1.0 + e) * v.x, v.y, v.z / (1.0 + e))
}

/// Grey-value scale of [`paper_torus`]'s image.
const GREY_SCALE: f64 = 20.0;

/// The moving surface of Bauer, Grasmair & Kirisits' Experiment I on an `n1 × n2` periodic
/// parameter grid, frames `t = 0, 1, …, n_frames − 1` (`T = n_frames − 1`): a ring torus whose
/// major circle stretches into an ellipse while its tube grows ripples,
/// `f(t, x1, x2) = ((R + t/T + r cos x2) cos x1, (R + r cos x2) sin x1, r sin x2)`, `R = 2`,
/// `r = 1 + t/(5T) sin 8x1`. The image (in place of the paper's taxi video) is
/// `20 ·` [`moving_blobs`]: a textured background with bright blobs moving in different
/// directions in the parameter domain. The weights of the energy are relative to the grey
/// values' scale; the factor 20 balances data and smoothness at the paper's `α = γ = 1` (with
/// values in `[0, 1]` the smoothness smears each car's motion over the whole torus, with 8-bit
/// values the flow breaks up into normal flow around the cars' edges).
pub fn paper_torus(n1: usize, n2: usize, n_frames: usize) -> Result<MeshSequence, FlowError> {
    paper_torus_frames(n1, n2, n_frames, 0..n_frames)
}

/// The frames `frames` of [`paper_torus`]`(n1, n2, n_frames)` alone, at their own times `k`:
/// what one rank of a solve over time windows holds ([`crate::flow::window`]).
pub fn paper_torus_frames(
    n1: usize,
    n2: usize,
    n_frames: usize,
    frames: std::ops::Range<usize>,
) -> Result<MeshSequence, FlowError> {
    use std::f64::consts::TAU;
    let surface = crate::shapes::torus(2.0, 1.0, n1, n2);
    let mesh = surface.mesh().expect("a periodic grid is a valid torus");
    let t_end = (n_frames - 1).max(1) as f64;
    let parameters: Vec<(f64, f64)> = (0..n1)
        .flat_map(|i| {
            (0..n2).map(move |j| (TAU * i as f64 / n1 as f64, TAU * j as f64 / n2 as f64))
        })
        .collect();
    let positions = (frames.clone())
        .map(|k| {
            let t = k as f64 / t_end;
            parameters
                .iter()
                .map(|&(x1, x2)| {
                    let r = 1.0 + t / 5.0 * (8.0 * x1).sin();
                    Vector3::new(
                        (2.0 + t + r * x2.cos()) * x1.cos(),
                        (2.0 + r * x2.cos()) * x1.sin(),
                        r * x2.sin(),
                    )
                })
                .collect()
        })
        .collect();
    let intensities = (frames.clone())
        .map(|k| {
            parameters
                .iter()
                .map(|&(x1, x2)| GREY_SCALE * moving_blobs(x1, x2, k as f64))
                .collect()
        })
        .collect();
    let times = frames.map(|k| k as f64).collect();
    MeshSequence::new(mesh, positions, intensities, Some(times))
}

/// Background texture plus four Gaussian blobs ("cars") moving through the periodic parameter
/// domain `[0, 2π)²` with constant velocities (radians per frame).
pub fn moving_blobs(x1: f64, x2: f64, t: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let periodic = |d: f64| (d + PI).rem_euclid(TAU) - PI;
    let cars = [
        (1.0, 2.0, 0.03, 0.0),
        (3.0, 4.5, -0.02, 0.015),
        (4.5, 1.0, 0.0, -0.03),
        (5.5, 3.5, 0.025, 0.025),
    ];
    let background =
        0.35 + 0.08 * (7.0 * x1).sin() * (5.0 * x2).cos() + 0.05 * (3.0 * x1 + 11.0 * x2).sin();
    background
        + cars
            .iter()
            .map(|&(c1, c2, v1, v2)| {
                let (d1, d2) = (periodic(x1 - c1 - v1 * t), periodic(x2 - c2 - v2 * t));
                0.5 * (-(d1 * d1 + d2 * d2) / (2.0 * 0.15f64.powi(2))).exp()
            })
            .sum::<f64>()
}

/// A surface in the spirit of Bauer, Grasmair & Kirisits' Experiment II: the graph
/// `x3 = h(t, x1, x2)` over the unit square, `(n + 1)²` vertices on the grid of
/// [`shapes::grid`](crate::shapes::grid), frames `t = 0, 1, …, n_frames − 1`, with
/// `h(t, x) = (0.5 + 0.25 t/T) exp(−|x − c|² / 0.05) + 0.04 sin(2π(x1 + x2) − 0.6 t)`,
/// `c = (0.5, 0.5)`, `T = n_frames − 1`: a dome that rises while a small wave runs across it.
/// The image is [`moving_cells`].
pub fn graph_surface(n: usize, n_frames: usize) -> Result<MeshSequence, FlowError> {
    let plane = crate::shapes::grid(n, n, 1.0, 1.0);
    let mesh = plane.mesh().expect("a grid is a valid disc");
    let t_end = (n_frames - 1).max(1) as f64;
    let frames = (0..n_frames)
        .map(|k| {
            let t = k as f64;
            plane
                .positions
                .iter()
                .map(|p| Vector3::new(p.x, p.y, graph_height(t / t_end, t, p.x, p.y)))
                .collect()
        })
        .collect();
    let intensities = (0..n_frames)
        .map(|k| {
            plane
                .positions
                .iter()
                .map(|p| moving_cells(p.x, p.y, k as f64))
                .collect()
        })
        .collect();
    MeshSequence::new(mesh, frames, intensities, None)
}

/// `h` of [`graph_surface`] at relative time `s = t/T` and frame time `t`.
fn graph_height(s: f64, t: f64, x1: f64, x2: f64) -> f64 {
    use std::f64::consts::TAU;
    let r2 = (x1 - 0.5).powi(2) + (x2 - 0.5).powi(2);
    (0.5 + 0.25 * s) * (-r2 / 0.05).exp() + 0.04 * (TAU * (x1 + x2) - 0.6 * t).sin()
}

/// Bright round cells (Gaussians of radius 0.035) crawling in straight lines over a dim,
/// faintly textured background on the unit square; velocities in parameter units per frame,
/// most of them outwards from the centre, one across it.
pub fn moving_cells(x1: f64, x2: f64, t: f64) -> f64 {
    let cells = [
        (0.50, 0.50, 0.012, 0.004),
        (0.30, 0.35, -0.008, -0.006),
        (0.70, 0.30, 0.007, -0.008),
        (0.65, 0.70, 0.006, 0.009),
        (0.30, 0.68, -0.009, 0.005),
        (0.20, 0.20, 0.010, 0.000),
        (0.82, 0.50, 0.000, 0.010),
        (0.45, 0.85, -0.010, -0.002),
    ];
    let background = 0.15 + 0.04 * (23.0 * x1).sin() * (19.0 * x2).cos();
    background
        + cells
            .iter()
            .map(|&(c1, c2, v1, v2)| {
                let (d1, d2) = (x1 - c1 - v1 * t, x2 - c2 - v2 * t);
                0.8 * (-(d1 * d1 + d2 * d2) / (2.0 * 0.035f64.powi(2))).exp()
            })
            .sum::<f64>()
}

/// Frames of one scene without correspondence, and the same scene with it.
pub struct RemeshedScene {
    /// Each frame with its own triangulation: an icosphere, a latitude–longitude sphere and a
    /// rotated, once more subdivided icosphere, in turn.
    pub frames: Vec<TrackFrame>,
    pub times: Vec<f64>,
    /// The scene on the icosphere of the first frame, vertex `i` moving radially.
    pub fixed: GroundTruth,
    /// Angular velocity of the texture about the z-axis: the true flow at `x` is `ω ẑ × x`.
    pub omega: f64,
}

/// A pulsating sphere, radius `r(t) = 1 + 0.1 sin 4t`, with [`texture`] turning about the
/// z-axis at `omega`; frames at `t_k = k dt`, meshed as [`RemeshedScene::frames`] says, the
/// icosphere at `level`. Normal motion of a sphere is radial, so tracked points keep their
/// direction and the flow relative to them is the texture's, `u = ω ẑ × x`.
pub fn remeshed_pulsating_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<RemeshedScene, FlowError> {
    let radius = |t: f64| 1.0 + 0.1 * (4.0 * t).sin();
    let grey = |t: f64, x: &Vector3<f64>| {
        texture(&(Rotation3::from_axis_angle(&Vector3::z_axis(), -omega * t) * x.normalize()))
    };
    let icosphere_vertices = 10 * 4usize.pow(level) + 2;
    let bands = ((icosphere_vertices as f64 / 2.0).sqrt()).round() as usize;
    let turned = Rotation3::from_euler_angles(0.4, 0.3, 0.2);
    let mut rotated_finer = icosphere(level + 1);
    rotated_finer
        .positions
        .iter_mut()
        .for_each(|p| *p = turned * *p);
    let meshes = [icosphere(level), uv_sphere(bands, 2 * bands), rotated_finer];
    let times: Vec<f64> = (0..n_frames).map(|k| k as f64 * dt).collect();
    let frame = |t: f64, surface: &Surface| {
        let positions: Vec<_> = surface.positions.iter().map(|p| radius(t) * p).collect();
        TrackFrame {
            intensity: positions.iter().map(|x| grey(t, x)).collect(),
            positions,
            faces: surface.faces.clone(),
        }
    };
    let frames = times
        .iter()
        .enumerate()
        .map(|(k, &t)| frame(t, &meshes[k % meshes.len()]))
        .collect();
    let fixed_frames: Vec<TrackFrame> = times.iter().map(|&t| frame(t, &meshes[0])).collect();
    let flow = fixed_frames[..n_frames.saturating_sub(1)]
        .iter()
        .map(|f| turning_flow(omega, &f.positions))
        .collect();
    let mesh = meshes[0].mesh().expect("icospheres are valid meshes");
    let (positions, intensities) = fixed_frames
        .into_iter()
        .map(|f| (f.positions, f.intensity))
        .unzip();
    let sequence = MeshSequence::new(mesh, positions, intensities, Some(times.clone()))?;
    Ok(RemeshedScene {
        frames,
        times,
        fixed: GroundTruth { sequence, flow },
        omega,
    })
}

/// `ω ẑ × x` at every point: a rotation about the z-axis.
pub fn turning_flow(omega: f64, positions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let axis = Vector3::new(0.0, 0.0, omega);
    positions.iter().map(|x| axis.cross(x)).collect()
}

/// A motion boundary that is also an image edge: on the unit icosphere at rest, the cap
/// `z > z_edge` turns about the z-axis at `omega` radians per unit time and the rest of the
/// sphere stands still; the image is [`texture`] on both, the cap brighter by `0.3` (a step at
/// the boundary circle). Frames at `t_k = k dt`; the true flow is `ω ẑ × x` on the cap and
/// zero elsewhere, and brightness constancy holds exactly in each region (turning about z
/// keeps a point's height, so its region).
pub fn turning_cap_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
    z_edge: f64,
) -> Result<GroundTruth, FlowError> {
    let on_cap = move |p: &Vector3<f64>| p.z > z_edge;
    textured_sphere(
        |p| vec![texture(p) + if on_cap(p) { 0.3 } else { 0.0 }],
        level,
        n_frames,
        dt,
        |p| if on_cap(p) { omega } else { 0.0 },
        0.0,
    )
}

/// The unit icosphere at rest with [`texture`] shearing about the z-axis: the circle of
/// latitude at height `z` turns at `ω (1 − z²)` (fastest at the equator, still at the poles),
/// frames at `t_k = k dt`. Not a rigid motion of the image: the true flow `ω (1 − z²) ẑ × x`
/// has a strain a rotation lacks.
pub fn shearing_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<GroundTruth, FlowError> {
    textured_sphere(
        |p| vec![texture(p)],
        level,
        n_frames,
        dt,
        |p| omega * (1.0 - p.z * p.z),
        0.0,
    )
}

/// Radius (Gaussian σ) of the cells of [`moving_cell_sphere`].
pub const CELL_RADIUS: f64 = 0.15;

/// Centres of the still cells of [`moving_cell_sphere`] on the unit sphere.
pub const STILL_CELLS: [[f64; 3]; 3] = [[0.0, 0.6, 0.8], [0.0, -0.6, 0.8], [-0.8, 0.0, 0.6]];

/// A flow with discontinuities: on the unit icosphere at rest, one bright round cell (a
/// Gaussian of radius [`CELL_RADIUS`]) crawls along the equator from `(1, 0, 0)` at `omega`
/// radians per unit time past three still ones ([`STILL_CELLS`]) on a dark, flat background;
/// frames at `t_k = k dt`. The true flow is the moving cell's velocity `ω ẑ × x` within two
/// radii of its centre at `t_s` and zero elsewhere (brightness constancy holds up to the
/// cells' overlap, which is below `1e-6` for `ω t ≤ 1`).
pub fn moving_cell_sphere(
    level: u32,
    n_frames: usize,
    dt: f64,
    omega: f64,
) -> Result<GroundTruth, FlowError> {
    let sphere = icosphere(level);
    let mesh = sphere.mesh().expect("icospheres are valid meshes");
    let cell = |p: &Vector3<f64>, c: &Vector3<f64>| {
        (-(p - c).norm_squared() / (2.0 * CELL_RADIUS * CELL_RADIUS)).exp()
    };
    let centre = |t: f64| Vector3::new((omega * t).cos(), (omega * t).sin(), 0.0);
    let still: Vec<Vector3<f64>> = STILL_CELLS.iter().map(|c| Vector3::from(*c)).collect();
    let times: Vec<f64> = (0..n_frames).map(|k| k as f64 * dt).collect();
    let grey = times
        .iter()
        .map(|&t| {
            let moving = centre(t);
            (sphere.positions.iter())
                .map(|p| {
                    0.1 + 0.8 * cell(p, &moving)
                        + still.iter().map(|c| 0.8 * cell(p, c)).sum::<f64>()
                })
                .collect()
        })
        .collect();
    let flow = times[..n_frames.saturating_sub(1)]
        .iter()
        .map(|&t| {
            let moving = centre(t);
            (sphere.positions.iter())
                .map(|p| match (p - moving).norm() < 2.0 * CELL_RADIUS {
                    true => omega * Vector3::z().cross(p),
                    false => Vector3::zeros(),
                })
                .collect()
        })
        .collect();
    let frames = vec![sphere.positions.clone(); n_frames];
    let sequence = MeshSequence::new(mesh, frames, grey, Some(times))?;
    Ok(GroundTruth { sequence, flow })
}
