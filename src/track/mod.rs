//! Surfaces without correspondence: a fixed-connectivity moving mesh built by normal motion
//! (Bauer, Grasmair & Kirisits 2015, Appendix A).
//!
//! Frames that each come with their own triangulation (a segmentation meshed per time point,
//! a 4D scan, a remeshing simulation) have no vertex-to-vertex correspondence. The paper
//! parametrizes such a moving surface by its normal motion: a point moves from one frame's
//! surface to the next along the surface normal, so the parametrization adds no tangential
//! motion of its own. Discretely, starting from a reference mesh on frame 0:
//!
//! ```text
//! x_i^{k+1} = x_i^k + t_i n_i^k,   t_i = the signed distance of the nearest hit of the line
//!                                       x_i^k + t n_i^k with frame k+1's surface, |t_i| ≤ max_step
//! ```
//!
//! with `n_i^k` the corner-angle-weighted vertex normal of the tracked mesh at frame `k` (the
//! normal of `connection::vertex_normals`, geometry-central's convention). The grey value of
//! vertex `i` at frame `k + 1` is frame `k + 1`'s own, interpolated barycentrically in the
//! triangle that was hit. A line that meets no triangle within `max_step` and within
//! [`FAR_HIT_RATIO`] times the distance to the closest point (a topology change, a thin
//! feature that moved sideways by more than its width, a step too large for the surface)
//! falls back to the closest point, and is counted.
//!
//! What it means for the flow: `solve` on the tracked sequence measures motion relative to
//! points that move normally, which is exactly the flow of the paper's model; the tangential
//! motion of the material is what the flow then shows. Limits: the tracked mesh's quality
//! drifts over many frames (tangential shrinking or stretching is not corrected; the report
//! shows the worst edge and area change), and a topology change cannot be followed.

mod surface;

use crate::connection::vertex_normals;
use crate::flow::{FlowError, MeshSequence};
use crate::mesh::{ConnectivityError, Mesh};
use crate::shapes::Surface;
use nalgebra::Vector3;
use rayon::prelude::*;
pub use surface::{barycentric, FrameSurface, SurfaceSample};

/// One frame as read, with its own vertices and triangles.
#[derive(Clone, Debug, Default)]
pub struct TrackFrame {
    pub positions: Vec<Vector3<f64>>,
    pub faces: Vec<[u32; 3]>,
    /// A grey value per vertex of this frame.
    pub intensity: Vec<f64>,
}

/// How far a vertex may move per frame, and what to do with vertices and triangles that
/// cannot be tracked.
#[derive(Clone, Debug, Default)]
pub struct TrackOptions {
    /// Largest normal step per frame, in the data's length unit; `None`: 10 % of the diagonal
    /// of frame 0's bounding box.
    pub max_step: Option<f64>,
    /// Keep going past a vertex farther than `max_step` from the next surface (it takes the
    /// closest point) and past flipped triangles, counting them, instead of failing.
    pub keep_going: bool,
    /// The mesh to track (positions on frame 0's surface, or near it: it is first moved onto
    /// frame 0 by the same normal step); `None`: frame 0's own mesh.
    pub reference: Option<Surface>,
}

/// What tracking did from the previous frame to this one.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameReport {
    pub frame: usize,
    /// Vertices whose normal line met no triangle within the step bound and
    /// [`FAR_HIT_RATIO`] times the distance to the closest point.
    pub misses: usize,
    /// Misses that took the closest point within the step bound.
    pub fallbacks: usize,
    /// Misses farther than the step bound (only with `keep_going`).
    pub beyond_max_step: usize,
    pub mean_step: f64,
    pub max_step: f64,
    /// `max |l/l_ref − 1|` over the edges, against the reference mesh.
    pub worst_edge_change: f64,
    /// `max |A/A_ref − 1|` over the triangles, against the reference mesh.
    pub worst_area_change: f64,
    /// Triangles whose normal turned by more than 90° in this step.
    pub flipped_triangles: usize,
}

/// The whole run: the step bound used and one report per frame (frame 0: the reference).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct TrackReport {
    pub max_step_bound: f64,
    pub frames: Vec<FrameReport>,
}

/// A tracked sequence with its report.
pub struct Tracked {
    pub sequence: MeshSequence,
    pub report: TrackReport,
}

/// Why frames could not be tracked. Each variant names the frame (and vertex or face).
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    #[error("no frames to track")]
    NoFrames,
    #[error("frame {frame} has no triangles")]
    NoTriangles { frame: usize },
    #[error("frame {frame}: vertex {vertex} has a non-finite coordinate")]
    NonFinite { frame: usize, vertex: usize },
    #[error("frame {frame}: grey value {vertex} is not finite")]
    NonFiniteIntensity { frame: usize, vertex: usize },
    #[error("frame {frame} has {values} grey values for {vertices} vertices")]
    IntensityCount {
        frame: usize,
        values: usize,
        vertices: usize,
    },
    #[error("frame {frame}: face {face} uses vertex {vertex}, but there are {vertices} vertices")]
    FaceIndex {
        frame: usize,
        face: usize,
        vertex: u32,
        vertices: usize,
    },
    #[error("frame {frame}: {detail}")]
    Surface { frame: usize, detail: String },
    #[error(
        "frame {frame}: vertex {vertex} is {distance:.3e} from the surface, beyond the step bound \
         {max_step:.3e} (a topology change or too large a motion; raise --max-step, or \
         --keep-going to take the closest point)"
    )]
    TooFar {
        frame: usize,
        vertex: usize,
        distance: f64,
        max_step: f64,
    },
    #[error(
        "frame {frame}: {count} triangles flipped, first triangle {face} (the tracked mesh \
         folds where the normal step exceeds the surface's radius of curvature: use frames \
         closer in time or a coarser --reference; --keep-going to continue anyway)"
    )]
    Flipped {
        frame: usize,
        face: usize,
        count: usize,
    },
    #[error(
        "frame {frame}: tracked triangle {face} collapsed to zero area (its vertices landed on \
         one line): the tracked mesh cannot carry a flow; use frames closer in time or a \
         coarser --reference"
    )]
    Collapsed { frame: usize, face: usize },
    #[error("the step bound must be a positive number, got {0}")]
    BadMaxStep(f64),
    #[error("the reference mesh: {0}")]
    Reference(#[from] ConnectivityError),
    #[error("tracked sequence: {0}")]
    Sequence(#[from] FlowError),
}

/// Tracks `frames` (at `times`, default `0, 1, 2, …`) by normal motion from the reference mesh
/// (see the module docs); returns the fixed-connectivity sequence and the report.
pub fn track(
    frames: &[TrackFrame],
    times: Option<Vec<f64>>,
    options: &TrackOptions,
) -> Result<Tracked, TrackError> {
    let first = frames.first().ok_or(TrackError::NoFrames)?;
    for (k, frame) in frames.iter().enumerate() {
        check_frame(k, frame)?;
    }
    let bound = match options.max_step {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => return Err(TrackError::BadMaxStep(s)),
        None => 0.1 * bounding_diagonal(&first.positions),
    };
    let (reference, faces) = match &options.reference {
        Some(surface) => (surface.positions.clone(), surface.faces.clone()),
        None => (first.positions.clone(), first.faces.clone()),
    };
    let mesh = Mesh::new(reference.len(), faces)?;
    let tracker = Tracker {
        mesh: &mesh,
        reference: &reference,
        bound,
        keep_going: options.keep_going,
    };
    let mut positions = Vec::with_capacity(frames.len());
    let mut intensities = Vec::with_capacity(frames.len());
    let mut reports = Vec::with_capacity(frames.len());
    let mut current = reference.clone();
    for (k, frame) in frames.iter().enumerate() {
        let step = tracker.step(k, &current, frame)?;
        current = step.positions;
        positions.push(current.clone());
        intensities.push(step.intensity);
        reports.push(step.report);
    }
    let sequence = MeshSequence::new(mesh, positions, intensities, times)?;
    Ok(Tracked {
        sequence,
        report: TrackReport {
            max_step_bound: bound,
            frames: reports,
        },
    })
}

/// How much farther than the closest point a hit along the normal may be: a surface tilted by
/// up to `acos(1/3)` ≈ 70° against the normal is still hit; a farther hit means the line
/// missed the nearby surface (a thin feature that moved sideways) and met another part.
pub const FAR_HIT_RATIO: f64 = 3.0;

/// Area, relative to the reference's, below which a tracked triangle counts as collapsed.
const COLLAPSED_AREA: f64 = 1e-9;

/// The reference connectivity and the rules of one step.
struct Tracker<'a> {
    mesh: &'a Mesh,
    reference: &'a [Vector3<f64>],
    bound: f64,
    keep_going: bool,
}

/// The tracked mesh on one frame: positions, grey values, and what happened.
struct Step {
    positions: Vec<Vector3<f64>>,
    intensity: Vec<f64>,
    report: FrameReport,
}

/// Where one vertex went.
enum Landing {
    Hit(SurfaceSample),
    Fallback(SurfaceSample),
    Beyond(SurfaceSample),
}

impl Tracker<'_> {
    /// Moves `current` onto `frame`'s surface along the vertex normals.
    fn step(
        &self,
        k: usize,
        current: &[Vector3<f64>],
        frame: &TrackFrame,
    ) -> Result<Step, TrackError> {
        let surface = FrameSurface::new(k, &frame.positions, &frame.faces, &frame.intensity)?;
        let normals = vertex_normals(self.mesh, current);
        let landings: Vec<Landing> = current
            .par_iter()
            .zip(&normals)
            .map(|(x, n)| self.land(&surface, x, n))
            .collect();
        let mut report = FrameReport {
            frame: k,
            ..Default::default()
        };
        let mut next = Vec::with_capacity(current.len());
        let mut grey = Vec::with_capacity(current.len());
        for (i, landing) in landings.into_iter().enumerate() {
            let point = match landing {
                Landing::Hit(p) => p,
                Landing::Fallback(p) => {
                    report.misses += 1;
                    report.fallbacks += 1;
                    p
                }
                Landing::Beyond(p) if self.keep_going => {
                    report.misses += 1;
                    report.beyond_max_step += 1;
                    p
                }
                Landing::Beyond(p) => {
                    return Err(TrackError::TooFar {
                        frame: k,
                        vertex: i,
                        distance: (p.position - current[i]).norm(),
                        max_step: self.bound,
                    })
                }
            };
            let step = (point.position - current[i]).norm();
            report.mean_step += step / current.len() as f64;
            report.max_step = report.max_step.max(step);
            next.push(point.position);
            grey.push(point.intensity);
        }
        self.measure_quality(k, current, &next, &mut report)?;
        Ok(Step {
            positions: next,
            intensity: grey,
            report,
        })
    }

    /// The nearest hit along the normal line within the bound, unless it is more than
    /// [`FAR_HIT_RATIO`] times as far as the closest point (the line then passed the nearby
    /// surface by and met another sheet); else the closest point.
    fn land(&self, surface: &FrameSurface, x: &Vector3<f64>, n: &Vector3<f64>) -> Landing {
        let closest = surface.closest_point(x);
        let distance = (closest.position - x).norm();
        // A point already on the surface has no normal motion, whatever the ray sees.
        if distance <= 1e-12 * self.bound {
            return Landing::Hit(closest);
        }
        let limit = self.bound.min(FAR_HIT_RATIO * distance);
        match surface.nearest_hit_along(x, n, limit) {
            Some(hit) => Landing::Hit(hit),
            None if distance <= self.bound => Landing::Fallback(closest),
            None => Landing::Beyond(closest),
        }
    }

    /// Edge and area changes against the reference, and triangles flipped in this step.
    fn measure_quality(
        &self,
        k: usize,
        before: &[Vector3<f64>],
        after: &[Vector3<f64>],
        report: &mut FrameReport,
    ) -> Result<(), TrackError> {
        let normal = |x: &[Vector3<f64>], f: &[u32; 3]| {
            let [a, b, c] = f.map(|v| x[v as usize]);
            (b - a).cross(&(c - a))
        };
        let mut flipped = Vec::new();
        for (f, face) in self.mesh.faces().iter().enumerate() {
            let (reference, now) = (normal(self.reference, face), normal(after, face));
            if now.norm() <= COLLAPSED_AREA * reference.norm() {
                return Err(TrackError::Collapsed { frame: k, face: f });
            }
            let change = (now.norm() / reference.norm() - 1.0).abs();
            report.worst_area_change = report.worst_area_change.max(change);
            if normal(before, face).dot(&now) <= 0.0 {
                flipped.push(f);
            }
            for c in 0..3 {
                let (i, j) = (face[c] as usize, face[(c + 1) % 3] as usize);
                let length = (after[i] - after[j]).norm();
                let change = (length / (self.reference[i] - self.reference[j]).norm() - 1.0).abs();
                report.worst_edge_change = report.worst_edge_change.max(change);
            }
        }
        report.flipped_triangles = flipped.len();
        match flipped.first() {
            Some(&face) if !self.keep_going => Err(TrackError::Flipped {
                frame: k,
                face,
                count: flipped.len(),
            }),
            _ => Ok(()),
        }
    }
}

/// Non-empty, finite, faces in range, one grey value per vertex.
fn check_frame(k: usize, frame: &TrackFrame) -> Result<(), TrackError> {
    if frame.faces.is_empty() {
        return Err(TrackError::NoTriangles { frame: k });
    }
    if let Some(vertex) = frame
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(TrackError::NonFinite { frame: k, vertex });
    }
    if frame.intensity.len() != frame.positions.len() {
        return Err(TrackError::IntensityCount {
            frame: k,
            values: frame.intensity.len(),
            vertices: frame.positions.len(),
        });
    }
    if let Some(vertex) = frame.intensity.iter().position(|v| !v.is_finite()) {
        return Err(TrackError::NonFiniteIntensity { frame: k, vertex });
    }
    let vertices = frame.positions.len();
    for (face, f) in frame.faces.iter().enumerate() {
        if let Some(&vertex) = f.iter().find(|&&v| v as usize >= vertices) {
            return Err(TrackError::FaceIndex {
                frame: k,
                face,
                vertex,
                vertices,
            });
        }
    }
    Ok(())
}

fn bounding_diagonal(points: &[Vector3<f64>]) -> f64 {
    let lower = points
        .iter()
        .fold(Vector3::repeat(f64::INFINITY), |m, p| m.inf(p));
    let upper = points
        .iter()
        .fold(Vector3::repeat(f64::NEG_INFINITY), |m, p| m.sup(p));
    (upper - lower).norm()
}
