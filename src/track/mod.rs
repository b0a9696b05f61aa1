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
//! Normal motion alone keeps no neighbours apart: where a step is large against the surface's
//! radius of curvature the mesh shears, and over many frames it folds. So after each normal step
//! the tracked mesh is relaxed on the new surface ([`Relaxation::Arap`], the default; see
//! `relax`): it moves tangentially to stay as rigid as possible against the previous frame. A
//! recording whose sample drifts is first aligned frame to frame ([`Alignment`], see `align`),
//! and a coarser reference can be made from frame 0 ([`simplified_reference`]).
//!
//! What it means for the flow: `solve` on the tracked sequence measures motion relative to
//! the tracked points. With [`Relaxation::None`] they move normally, which is exactly the
//! paper's model, and the flow is all of the material's tangential motion. With relaxation the
//! mesh also moves tangentially, and the material's velocity is the mesh's own velocity plus
//! the flow (`solve` writes that sum as `velocity.npy`). A topology change cannot be followed.
//!
//! Reports: every [`FrameReport`] compares frame `k` with frame `k − 1` (per frame, not
//! cumulative), except `worst_edge_change` and `worst_area_change`, which compare with the
//! reference (cumulative). Frame 0's report is the projection of the reference onto frame 0.

mod align;
mod reference;
mod relax;
mod trim;

use crate::connection::vertex_normals;
use crate::flow::{FlowError, MeshSequence};
use crate::geometry::folds::{folded_halfedges, smooth_out_widening};
use crate::geometry::SurfacePoint;
use crate::mesh::{ConnectivityError, Mesh, VertexNeighbours};
use crate::shapes::Surface;
pub use crate::spatial::{barycentric, FrameSurface, SurfaceSample};
pub use align::{Alignment, AlignmentReport, Motion};
use nalgebra::Vector3;
use rayon::prelude::*;
pub use reference::simplified_reference;
use relax::Relaxer;

/// One frame as read, with its own vertices and triangles.
#[derive(Clone, Debug, Default)]
pub struct TrackFrame {
    pub positions: Vec<Vector3<f64>>,
    pub faces: Vec<[u32; 3]>,
    /// A grey value per vertex of this frame.
    pub intensity: Vec<f64>,
}

/// How the tracked mesh is kept well shaped after each normal step (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Relaxation {
    /// Normal motion only: the paper's Appendix A.
    None,
    /// As rigid as possible against the previous frame, on the new surface, with at most
    /// `iterations` local/global steps per frame.
    Arap { iterations: usize },
}

impl Relaxation {
    /// The default number of ARAP steps per frame.
    pub const DEFAULT_ITERATIONS: usize = 20;
}

impl Default for Relaxation {
    fn default() -> Self {
        Relaxation::Arap {
            iterations: Self::DEFAULT_ITERATIONS,
        }
    }
}

/// How far a vertex may move per frame, how the mesh is kept in shape, and what to do with
/// vertices and triangles that cannot be tracked.
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
    /// Make the reference from frame 0 (or from `reference`) with about this many vertices
    /// ([`simplified_reference`]).
    pub reference_vertices: Option<usize>,
    /// Tangential relaxation after each normal step.
    pub relaxation: Relaxation,
    /// The motion taken out between frames before tracking.
    pub alignment: Alignment,
    /// Keep reference vertices beyond a frame's boundary (they take the closest point, on
    /// the boundary) instead of trimming the reference to what every frame covers (`trim`).
    pub keep_uncovered: bool,
    /// Leave each frame in its own coordinates: the alignment only starts each step from the
    /// previous mesh moved by the frame's motion, and the tracked mesh stays where the frames
    /// are (a mesh that then samples the recording needs that). Otherwise the motion is taken
    /// out, and the tracked frames are in frame 0's coordinates.
    pub keep_coordinates: bool,
}

/// What [`track_with_progress`] tells as it goes.
#[derive(Clone, Debug)]
pub enum TrackEvent<'a> {
    /// A frame is done.
    Frame(&'a FrameReport),
    /// `uncovered` reference vertices lie beyond frame `frame`'s boundary: the reference was
    /// trimmed to `remaining` vertices and tracking starts again from frame 0.
    Trimmed {
        frame: usize,
        uncovered: usize,
        remaining: usize,
    },
}

/// What tracking did from the previous frame to this one (frame 0: from the reference onto
/// frame 0). Per frame, except the two `worst_*_change` fields, which are against the
/// reference.
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
    /// Distance each vertex moved from the previous frame: mean and largest.
    pub mean_step: f64,
    pub max_step: f64,
    /// Tangential distance the relaxation moved vertices from where the normal step put them:
    /// mean and largest.
    pub mean_relaxation: f64,
    pub max_relaxation: f64,
    /// `|log(l / l_previous)|` over the edges: 99th percentile and largest.
    pub edge_log_ratio_p99: f64,
    pub edge_log_ratio_max: f64,
    /// `max |l/l_ref − 1|` over the edges, against the reference mesh.
    pub worst_edge_change: f64,
    /// `max |A/A_ref − 1|` over the triangles, against the reference mesh.
    pub worst_area_change: f64,
    /// Triangles whose normal turned by more than 90° in this step, and edges newly folded
    /// (their triangles facing opposite ways), before they were smoothed out on the surface
    /// ([`Tracker::repair_folds`]).
    pub repaired_folds: usize,
    /// Triangles whose normal turned by more than 90° in this step (after the repair).
    pub flipped_triangles: usize,
    /// The largest distance of a tracked vertex from the frame's surface (a check: the
    /// tracked vertices are put on it).
    pub max_off_surface: f64,
    /// The motion between this frame and the previous one (frames after the first).
    pub alignment: Option<AlignmentReport>,
}

/// The whole run: the step bound used and one report per frame (frame 0: the reference).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct TrackReport {
    pub max_step_bound: f64,
    pub relaxation: Option<Relaxation>,
    pub alignment: Alignment,
    /// Vertices of the reference: frame 0's, the one given, or made to the asked size.
    pub reference_vertices: usize,
    /// Reference vertices trimmed away because some frame does not cover them.
    pub trimmed_vertices: usize,
    pub frames: Vec<FrameReport>,
    /// Frames that look misaligned against the previous one, and other things to know.
    pub warnings: Vec<String>,
}

/// A tracked sequence with its report.
pub struct Tracked {
    pub sequence: MeshSequence,
    pub report: TrackReport,
    /// `landings[k][i]`: where tracked vertex `i` lies on frame `k`'s own triangulation (a
    /// face of the frame as given and barycentric coordinates), to carry any per-vertex data
    /// of the frames (colour channels, labels, signals) onto the tracked mesh.
    pub landings: Vec<Vec<SurfacePoint>>,
}

/// Where on the tracked mesh a fault is: a point in the frame's coordinates, and whether it is
/// at the mesh's boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Location {
    pub position: [f64; 3],
    pub at_boundary: bool,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [x, y, z] = self.position;
        let place = match self.at_boundary {
            true => "at the boundary",
            false => "inside",
        };
        write!(f, "at ({x:.4e}, {y:.4e}, {z:.4e}), {place}")
    }
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
        "frame {frame}: vertex {vertex} ({at}) is {distance:.3e} from the surface, beyond the \
         step bound {max_step:.3e} (a topology change, a drift or too large a motion; raise \
         --max-step, try --align rigid, or --keep-going to take the closest point)"
    )]
    TooFar {
        frame: usize,
        vertex: usize,
        distance: f64,
        max_step: f64,
        at: Location,
    },
    #[error(
        "frame {frame}: {count} triangles flipped, first triangle {face} ({at}; its smallest \
         angle was {smallest_angle:.1}°): the tracked mesh folds where the step is large \
         against the surface's curvature or a triangle is a sliver; use frames closer in time, \
         a clean coarser reference (--reference-vertices) or --align rigid; --keep-going to \
         continue anyway"
    )]
    Flipped {
        frame: usize,
        face: usize,
        count: usize,
        at: Location,
        /// Degrees, in the previous frame.
        smallest_angle: f64,
    },
    #[error(
        "frame {frame}: tracked triangle {face} ({at}) collapsed to zero area (its vertices \
         landed on one line): the tracked mesh cannot carry a flow; use frames closer in time \
         or a coarser reference (--reference-vertices)"
    )]
    Collapsed {
        frame: usize,
        face: usize,
        at: Location,
    },
    #[error(
        "frame {frame}: {} reference vertices lie beyond the frame's boundary (first: vertex \
         {})", vertices.len(), vertices[0]
    )]
    Uncovered { frame: usize, vertices: Vec<usize> },
    #[error("frame {frame} covers none of the reference: nothing is left to track")]
    NothingCovered { frame: usize },
    #[error("{source}; note: {warning}")]
    AfterWarning {
        warning: String,
        source: Box<TrackError>,
    },
    #[error("the step bound must be a positive number, got {0}")]
    BadMaxStep(f64),
    #[error("a reference of {0} vertices cannot be made: ask for at least 4")]
    BadReferenceVertices(usize),
    #[error(
        "--reference-vertices {asked} asks for more than the {has} vertices of the mesh it \
         simplifies (simplification only removes vertices); ask for at most {has}, or leave it \
         out to track the mesh as it is"
    )]
    ReferenceVerticesAboveMesh { asked: usize, has: usize },
    #[error("frame {frame}: the relaxation's system is singular ({detail})")]
    Relaxation { frame: usize, detail: String },
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
    track_with_progress(frames, times, options, &mut |_| {})
}

/// [`track`], telling `on_event` of each frame as soon as it is done (the frames done before
/// a failure are thus known to the caller) and of each trimming of the reference.
pub fn track_with_progress(
    frames: &[TrackFrame],
    times: Option<Vec<f64>>,
    options: &TrackOptions,
    on_event: &mut dyn FnMut(TrackEvent),
) -> Result<Tracked, TrackError> {
    let first = frames.first().ok_or(TrackError::NoFrames)?;
    for (k, frame) in frames.iter().enumerate() {
        check_frame(k, frame)?;
    }
    let bound = step_bound(options, first)?;
    let mut reference = reference_surface(first, options)?;
    let made = reference.positions.len();
    let mut notes = Vec::new();
    loop {
        let mut each = frames.iter().cloned().map(Ok);
        let counted: FrameSource = (&mut each, frames.len());
        match track_reference(counted, &reference, bound, options, on_event) {
            Err(TrackError::Uncovered { frame, vertices }) if !options.keep_uncovered => {
                let next = trim::trimmed(&reference, &vertices)
                    .ok_or(TrackError::NothingCovered { frame })?;
                let remaining = next.positions.len();
                on_event(TrackEvent::Trimmed {
                    frame,
                    uncovered: vertices.len(),
                    remaining,
                });
                notes.push(format!(
                    "frame {frame} does not cover {} reference vertices (beyond its boundary): \
                     the reference was trimmed to {remaining} vertices",
                    vertices.len()
                ));
                reference = next;
            }
            Err(e) => return Err(e),
            Ok(mut run) => {
                run.report.reference_vertices = made;
                run.report.trimmed_vertices = made - reference.positions.len();
                run.report.warnings.splice(0..0, notes);
                return run.tracked(reference, times);
            }
        }
    }
}

/// [`track_with_progress`] for frames that arrive one at a time (surfaces found in volumes as
/// they are read, say), each dropped once tracked: at most two frames are held, whatever the
/// recording's length. The reference is never trimmed (a trimmed one would need every frame
/// again), so vertices beyond a frame's boundary keep their closest point, as with
/// [`TrackOptions::keep_uncovered`]: for closed surfaces, which have no boundary.
pub fn track_as_they_come(
    first: TrackFrame,
    rest: &mut dyn Iterator<Item = TrackFrame>,
    times: Option<Vec<f64>>,
    options: &TrackOptions,
    on_event: &mut dyn FnMut(TrackEvent),
) -> Result<Tracked, TrackError> {
    check_frame(0, &first)?;
    let options = TrackOptions {
        keep_uncovered: true,
        ..options.clone()
    };
    let bound = step_bound(&options, &first)?;
    let reference = reference_surface(&first, &options)?;
    let made = reference.positions.len();
    let checked = std::iter::once(first).chain(rest).enumerate();
    let mut frames = checked.map(|(k, frame)| check_frame(k, &frame).map(|()| frame));
    let source: FrameSource = (&mut frames, 0);
    let mut run = track_reference(source, &reference, bound, &options, on_event)?;
    run.report.reference_vertices = made;
    run.tracked(reference, times)
}

/// `--max-step`, else a tenth of frame 0's bounding diagonal.
fn step_bound(options: &TrackOptions, first: &TrackFrame) -> Result<f64, TrackError> {
    match options.max_step {
        Some(s) if s.is_finite() && s > 0.0 => Ok(s),
        Some(s) => Err(TrackError::BadMaxStep(s)),
        None => Ok(0.1 * crate::geometry::bounding_diameter(&first.positions)),
    }
}

/// One tracking run of every frame from `reference`.
struct Run {
    positions: Vec<Vec<Vector3<f64>>>,
    intensities: Vec<Vec<f64>>,
    landings: Vec<Vec<SurfacePoint>>,
    report: TrackReport,
}

impl Run {
    /// The tracked sequence on `reference`'s connectivity, at `times`.
    fn tracked(self, reference: Surface, times: Option<Vec<f64>>) -> Result<Tracked, TrackError> {
        let mesh = Mesh::new(reference.positions.len(), reference.faces)?;
        let sequence = MeshSequence::new(mesh, self.positions, self.intensities, times)?;
        Ok(Tracked {
            sequence,
            report: self.report,
            landings: self.landings,
        })
    }
}

/// Frames one at a time, checked, with how many there are (0: not known).
type FrameSource<'a> = (
    &'a mut dyn Iterator<Item = Result<TrackFrame, TrackError>>,
    usize,
);

fn track_reference(
    (frames, count): FrameSource,
    reference: &Surface,
    bound: f64,
    options: &TrackOptions,
    on_event: &mut dyn FnMut(TrackEvent),
) -> Result<Run, TrackError> {
    let mesh = Mesh::new(reference.positions.len(), reference.faces.clone())?;
    let relaxer = match options.relaxation {
        Relaxation::Arap { iterations } if iterations > 0 => Some(Relaxer::new(&mesh, iterations)),
        _ => None,
    };
    let tracker = Tracker {
        mesh: &mesh,
        reference: &reference.positions,
        bound,
        keep_going: options.keep_going,
        keep_uncovered: options.keep_uncovered,
        relaxer,
        neighbours: VertexNeighbours::open(&mesh),
    };
    let mut run = Run {
        positions: Vec::with_capacity(count),
        intensities: Vec::with_capacity(count),
        landings: Vec::with_capacity(count),
        report: TrackReport {
            max_step_bound: bound,
            relaxation: tracker.relaxer.is_some().then_some(options.relaxation),
            alignment: options.alignment,
            ..Default::default()
        },
    };
    let mut current = reference.positions.clone();
    // Each frame's surface is built once: for its own step, then as the next frame's target.
    let mut previous: Option<FrameSurface> = None;
    for (k, frame) in frames.enumerate() {
        let frame = frame?;
        let warnings_before = run.report.warnings.len();
        let (frame, alignment, start) = match &previous {
            Some(before) => {
                let (frame, report, start) =
                    align_to(k, frame, before, options, &mut run.report.warnings);
                (frame, Some(report), start)
            }
            None => (frame, None, None),
        };
        // Frames kept in their own coordinates: the step starts from the previous mesh moved
        // by the frame's motion (frame k → k − 1, inverted).
        if let Some(motion) = start {
            current = current.iter().map(|x| motion.invert(x)).collect();
        }
        let surface = FrameSurface::new(k, &frame.positions, &frame.faces, &frame.intensity)?;
        let mut step = match tracker.step(k, &current, &surface) {
            Ok(step) => step,
            Err(e @ TrackError::Uncovered { .. }) => return Err(e),
            Err(e) => match run.report.warnings.get(warnings_before) {
                Some(warning) => {
                    return Err(TrackError::AfterWarning {
                        warning: warning.clone(),
                        source: Box::new(e),
                    })
                }
                None => return Err(e),
            },
        };
        step.report.alignment = alignment;
        on_event(TrackEvent::Frame(&step.report));
        current = step.positions;
        run.positions.push(current.clone());
        run.intensities.push(step.intensity);
        run.landings.push(step.landing);
        run.report.frames.push(step.report);
        previous = Some(surface);
    }
    Ok(run)
}

/// The mesh to track: the given reference or frame 0's, simplified if asked.
fn reference_surface(first: &TrackFrame, options: &TrackOptions) -> Result<Surface, TrackError> {
    let given = match &options.reference {
        Some(surface) => surface.clone(),
        None => Surface {
            positions: first.positions.clone(),
            faces: first.faces.clone(),
        },
    };
    match options.reference_vertices {
        Some(n) if n < 4 => Err(TrackError::BadReferenceVertices(n)),
        Some(asked) if asked > given.positions.len() => {
            Err(TrackError::ReferenceVerticesAboveMesh {
                asked,
                has: given.positions.len(),
            })
        }
        Some(n) => Ok(simplified_reference(&given.positions, &given.faces, n)),
        None => Ok(given),
    }
}

/// Frame `k` against `previous` as `alignment` asks: moved onto it (the motion taken out), or
/// with `keep_coordinates` left where it is, the motion returned to start the step from. A
/// rigid fit is still measured without alignment, and a frame it would bring much closer is
/// reported.
fn align_to(
    k: usize,
    frame: TrackFrame,
    target: &FrameSurface,
    options: &TrackOptions,
    warnings: &mut Vec<String>,
) -> (TrackFrame, AlignmentReport, Option<Motion>) {
    let alignment = options.alignment;
    let (motion, report) = align::fit(&frame.positions, target, alignment);
    let spacing = median_edge_length(&frame.positions, &frame.faces);
    let (before, after) = (report.median_distance_before, report.median_distance_after);
    // `fit` reports every alignment but `None` as applied.
    if !report.applied && align::explains_drift(&report, spacing) {
        warnings.push(format!(
            "frame {k} looks misaligned against frame {}: a rigid motion ({:.1}°, translation \
             {:.3e}) brings its median distance from {before:.3e} to {after:.3e} (the median \
             edge is {spacing:.3e}); try --align rigid",
            k - 1,
            report.rotation_degrees,
            Vector3::from(report.translation).norm()
        ));
    }
    if report.applied && after > spacing {
        warnings.push(format!(
            "frame {k} is still {after:.3e} from frame {} after alignment (median distance; the \
             median edge is {spacing:.3e}): the surfaces differ by more than a motion",
            k - 1
        ));
    }
    match (report.applied, options.keep_coordinates) {
        (false, _) => (frame, report, None),
        (true, true) => (frame, report, Some(motion)),
        (true, false) => {
            let positions = frame.positions.iter().map(|x| motion.apply(x)).collect();
            (TrackFrame { positions, ..frame }, report, None)
        }
    }
}

/// How much farther than the closest point a hit along the normal may be: a surface tilted by
/// up to `acos(1/3)` ≈ 70° against the normal is still hit; a farther hit means the line
/// missed the nearby surface (a thin feature that moved sideways) and met another part.
pub const FAR_HIT_RATIO: f64 = 3.0;

/// A vertex whose normal line misses the frame and whose closest point lies on the frame's
/// boundary, farther along the surface than this many mean edge lengths, is uncovered
/// (`trim`): farther than round-off, since boundary vertices that merely slide onto the
/// frame's edge crowd there.
const UNCOVERED_DISTANCE: f64 = 1e-6;

/// The most rounds of [`Tracker::repair_folds`] in one step for each width of the region it
/// moves ([`crate::geometry::folds::WIDENING_RINGS`]).
const FOLD_REPAIR_ROUNDS: usize = 30;

/// Area, relative to the reference's, below which a tracked triangle counts as collapsed.
const COLLAPSED_AREA: f64 = 1e-9;

/// The reference connectivity and the rules of one step.
struct Tracker<'a> {
    mesh: &'a Mesh,
    reference: &'a [Vector3<f64>],
    bound: f64,
    keep_going: bool,
    keep_uncovered: bool,
    relaxer: Option<Relaxer>,
    neighbours: VertexNeighbours,
}

/// The tracked mesh on one frame: positions, grey values, and what happened.
struct Step {
    positions: Vec<Vector3<f64>>,
    intensity: Vec<f64>,
    landing: Vec<SurfacePoint>,
    report: FrameReport,
}

/// Where one vertex went.
enum Landing {
    Hit(SurfaceSample),
    Fallback(SurfaceSample),
    Beyond(SurfaceSample),
}

impl Tracker<'_> {
    /// Moves `current` onto `frame`'s surface along the vertex normals, then relaxes it there.
    fn step(
        &self,
        k: usize,
        current: &[Vector3<f64>],
        surface: &FrameSurface,
    ) -> Result<Step, TrackError> {
        let normals = vertex_normals(self.mesh, current);
        let landings: Vec<Landing> = current
            .par_iter()
            .zip(&normals)
            .map(|(x, n)| self.land(surface, x, n))
            .collect();
        if !self.keep_uncovered {
            let uncovered = self.uncovered(surface, current, &landings);
            if !uncovered.is_empty() {
                return Err(TrackError::Uncovered {
                    frame: k,
                    vertices: uncovered,
                });
            }
        }
        let mut report = FrameReport {
            frame: k,
            ..Default::default()
        };
        let mut samples = Vec::with_capacity(current.len());
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
                        at: self.location(&[i], current),
                    })
                }
            };
            samples.push(point);
        }
        let normal_step: Vec<Vector3<f64>> = samples.iter().map(|p| p.position).collect();
        if let Some(relaxer) = &self.relaxer {
            let relaxed = relaxer
                .relax(self.mesh, current, samples, surface)
                .map_err(|detail| TrackError::Relaxation { frame: k, detail })?;
            if !self.keep_uncovered && !relaxed.clamped.is_empty() {
                return Err(TrackError::Uncovered {
                    frame: k,
                    vertices: relaxed.clamped,
                });
            }
            samples = relaxed.samples;
        }
        report.repaired_folds = self.repair_folds(current, &mut samples, surface);
        let (next, grey): (Vec<_>, Vec<_>) = samples
            .into_iter()
            .map(|p| (p.position, p.intensity))
            .unzip();
        let n = current.len() as f64;
        for ((x, y), z) in current.iter().zip(&next).zip(&normal_step) {
            let (step, relaxed) = ((y - x).norm(), (y - z).norm());
            report.mean_step += step / n;
            report.max_step = report.max_step.max(step);
            report.mean_relaxation += relaxed / n;
            report.max_relaxation = report.max_relaxation.max(relaxed);
        }
        let (landing, off): (Vec<SurfacePoint>, Vec<f64>) = (next.par_iter())
            .map(|y| surface.locate_with_distance(y))
            .unzip();
        report.max_off_surface = off.into_iter().fold(0.0, f64::max);
        self.measure_quality(k, current, &next, &mut report)?;
        Ok(Step {
            landing,
            positions: next,
            intensity: grey,
            report,
        })
    }

    /// Unfolds the triangles that turned over from `before` to `samples` (on `surface`): their
    /// vertices and two rings around them are smoothed out on the surface
    /// ([`crate::geometry::folds::smooth_out`]) until no triangle is turned over or
    /// [`FOLD_REPAIR_ROUNDS`] rounds have passed. A fold is a local tangle (a sliver that the
    /// normal step crossed over, a bump of one frame's surface), undone where it is; what is
    /// left is for [`Tracker::measure_quality`]. Returns how many triangles were turned over
    /// before.
    fn repair_folds(
        &self,
        before: &[Vector3<f64>],
        samples: &mut [SurfaceSample],
        surface: &FrameSurface,
    ) -> usize {
        // Creases already as sharp before are the surface's own; a new one is a fold.
        let creased_before = folded_halfedges(self.mesh, before);
        let turned_over = |x: &[Vector3<f64>]| -> Vec<usize> {
            (0..self.mesh.n_faces())
                .filter(|&f| {
                    let [a, b, c] = self.mesh.faces()[f].map(|v| v as usize);
                    let was = (before[b] - before[a]).cross(&(before[c] - before[a]));
                    was.dot(&(x[b] - x[a]).cross(&(x[c] - x[a]))) <= 0.0
                })
                .collect()
        };
        let folded_anew = |x: &[Vector3<f64>]| -> Vec<usize> {
            (folded_halfedges(self.mesh, x).into_iter())
                .filter(|h| creased_before.binary_search(h).is_err())
                .collect()
        };
        let turned = |x: &[Vector3<f64>]| -> Vec<usize> {
            let faces = turned_over(x).into_iter().map(|f| self.mesh.faces()[f]);
            let edges = folded_anew(x).into_iter();
            (faces.flat_map(|f| f.map(|v| v as usize)))
                .chain(edges.flat_map(|h| self.mesh.halfedge_vertices(h).map(|v| v as usize)))
                .collect()
        };
        let mut positions: Vec<Vector3<f64>> = samples.iter().map(|p| p.position).collect();
        let faults = turned_over(&positions).len() + folded_anew(&positions).len();
        if faults == 0 {
            return 0;
        }
        let onto = |_: usize, x: Vector3<f64>| surface.closest_point(&x).position;
        smooth_out_widening(
            self.mesh,
            &self.neighbours,
            &mut positions,
            FOLD_REPAIR_ROUNDS,
            turned,
            onto,
        );
        for (sample, x) in samples.iter_mut().zip(&positions) {
            if sample.position != *x {
                *sample = surface.closest_point(x);
            }
        }
        faults
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

    /// Vertices whose normal line misses the frame and whose closest point lies on the frame's
    /// boundary, farther along the surface than [`UNCOVERED_DISTANCE`] mean edges (see `trim`).
    fn uncovered(
        &self,
        surface: &FrameSurface,
        current: &[Vector3<f64>],
        landings: &[Landing],
    ) -> Vec<usize> {
        let mean_edge = crate::geometry::mean_edge_length_at(self.mesh, current);
        (landings.iter().enumerate())
            .filter_map(|(i, landing)| match landing {
                Landing::Fallback(p) | Landing::Beyond(p) => Some((i, p.position)),
                Landing::Hit(_) => None,
            })
            .filter(|(i, p)| {
                // Beyond the edge, the way to the closest point has a part along the surface;
                // off a surface that moved along its normal, it has none.
                let (_, normal) = surface.closest_point_and_normal(p);
                let offset = current[*i] - p;
                let along = (offset - normal * normal.dot(&offset)).norm();
                along > UNCOVERED_DISTANCE * mean_edge && surface.closest_point_is_on_boundary(p)
            })
            .map(|(i, _)| i)
            .collect()
    }

    /// The mean of `vertices`' positions, and whether any of them is on the boundary.
    fn location(&self, vertices: &[usize], positions: &[Vector3<f64>]) -> Location {
        let sum: Vector3<f64> = vertices.iter().map(|&v| positions[v]).sum();
        Location {
            position: (sum / vertices.len() as f64).into(),
            at_boundary: vertices.iter().any(|&v| self.mesh.is_boundary_vertex(v)),
        }
    }

    /// Edge and area changes against the reference and the previous frame, and triangles
    /// flipped in this step.
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
        let corners = |face: &[u32; 3]| face.map(|v| v as usize);
        let mut flipped = Vec::new();
        for (f, face) in self.mesh.faces().iter().enumerate() {
            let (reference, now) = (normal(self.reference, face), normal(after, face));
            if now.norm() <= COLLAPSED_AREA * reference.norm() {
                let at = self.location(&corners(face), after);
                return Err(TrackError::Collapsed {
                    frame: k,
                    face: f,
                    at,
                });
            }
            let change = (now.norm() / reference.norm() - 1.0).abs();
            report.worst_area_change = report.worst_area_change.max(change);
            if normal(before, face).dot(&now) <= 0.0 {
                flipped.push(f);
            }
        }
        let mut log_ratios = Vec::with_capacity(self.mesh.n_edges());
        for &[i, j] in self.mesh.edges() {
            let (i, j) = (i as usize, j as usize);
            let length = (after[i] - after[j]).norm();
            let change = (length / (self.reference[i] - self.reference[j]).norm() - 1.0).abs();
            report.worst_edge_change = report.worst_edge_change.max(change);
            log_ratios.push((length / (before[i] - before[j]).norm()).ln().abs());
        }
        (report.edge_log_ratio_p99, report.edge_log_ratio_max) =
            percentile_and_max(log_ratios, 0.99);
        report.flipped_triangles = flipped.len();
        // A fold at the mesh's edge is where the frame's own edge cut in: trimmed like
        // uncovered vertices (`trim`) rather than reported.
        let at_edge: Vec<usize> = (flipped.iter())
            .flat_map(|&f| corners(&self.mesh.faces()[f]))
            .filter(|&v| self.mesh.is_boundary_vertex(v))
            .collect();
        if !self.keep_uncovered && !at_edge.is_empty() {
            return Err(TrackError::Uncovered {
                frame: k,
                vertices: at_edge,
            });
        }
        match flipped.first() {
            Some(&face) if !self.keep_going => Err(TrackError::Flipped {
                frame: k,
                face,
                count: flipped.len(),
                at: self.location(&corners(&self.mesh.faces()[face]), after),
                smallest_angle: smallest_angle(self.mesh.faces()[face].map(|v| before[v as usize])),
            }),
            _ => Ok(()),
        }
    }
}

/// The smallest corner angle of a triangle, in degrees.
fn smallest_angle(x: [Vector3<f64>; 3]) -> f64 {
    (0..3)
        .map(|c| (x[(c + 1) % 3] - x[c]).angle(&(x[(c + 2) % 3] - x[c])))
        .fold(f64::INFINITY, f64::min)
        .to_degrees()
}

/// The `q`-quantile (nearest rank) and the largest of `values` (0 for none).
fn percentile_and_max(mut values: Vec<f64>, q: f64) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    values.sort_unstable_by(f64::total_cmp);
    let rank = ((q * values.len() as f64).ceil() as usize).clamp(1, values.len());
    (values[rank - 1], values[values.len() - 1])
}

fn median_edge_length(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> f64 {
    align::median(
        (faces.iter())
            .map(|f| (positions[f[0] as usize] - positions[f[1] as usize]).norm())
            .collect(),
    )
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

impl From<crate::spatial::SpatialError> for TrackError {
    fn from(e: crate::spatial::SpatialError) -> Self {
        TrackError::Surface {
            frame: e.frame,
            detail: e.detail,
        }
    }
}
