//! A flow scored where the truth is known at some points only: tracked cells, beads, landmarks.
//!
//! **Tracks.** `X[k][n] ∈ R³` is the position of point `n` in frame `k`, NaN where the point
//! is not tracked (a `(K, N, 3)` array). A point takes part in slab `s` when it is tracked in
//! frames `s` and `s + 1`.
//!
//! **What the flow predicts.** Material moves with the mesh plus the flow (the model's `u` is
//! relative to the mesh's own motion). With `ξ` the closest point of `X[s][n]` on frame `s`'s
//! surface (a face and barycentric coordinates, valid in every frame), `P = I − n̂ n̂ᵀ` the
//! projection onto the tangent plane of its face on frame `s`, and `x_k(ξ)` the mesh point `ξ`
//! on frame `k`:
//!
//! ```text
//! r  = P (X[s+1][n] − X[s][n] − (x_{s+1}(ξ) − x_s(ξ)))    the point's tangential displacement
//!                                                        relative to the mesh
//! r̂  = P Δt_s u_s(ξ)                                     the flow's, u_s(ξ) = Σ_a b_a u_s(v_a)
//! EPE = |r̂ − r|     (length units, per slab)             zero flow: |r|
//! DE  = ∠(r̂, r)     where |r| ≥ 10 % of the slab's largest |r|   ("points that moved")
//! ratio = |r̂| / |r| where |r| ≥ 10 % of the slab's largest |r|
//! ```
//!
//! The normal parts are left out: the surface's own normal motion is not the flow's to explain,
//! and a point's distance from a fitted surface is noise of the fit. A computed vector of
//! length zero counts as 90° (as in the module above). Summaries are plain means and medians
//! over the points (each point one vote), per slab and over all slabs.
//!
//! **Matching.** [`match_tracks`] chains per-frame point clouds into tracks by mutual nearest
//! neighbours between consecutive frames: `a ∈ A_k` and `b ∈ A_{k+1}` are one point when each
//! is the other's nearest neighbour and `|a − b| ≤ d_max`. A point left unmatched starts a new
//! track. Mutual matching is safe when points move less than about half their spacing per frame
//! (zebrafish endoderm: 3.4 µm against 27.5 µm); the default bound is half the median
//! nearest-neighbour distance of the first frame.

use super::{direction_error_degrees, maximum, AccuracyError, MOVING_FRACTION};
use crate::flow::{FlowResult, MeshSequence};
use crate::geometry::SurfacePoint;
use crate::spatial::FrameSurface;
use crate::statistics::weighted_median;
use nalgebra::Vector3;
use rayon::prelude::*;

/// Point positions per frame, `frames[k][n]`, NaN where point `n` is not tracked in frame `k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Tracks {
    frames: Vec<Vec<Vector3<f64>>>,
}

impl Tracks {
    /// Checks that every frame has the same number of points and every point is either finite
    /// or NaN in all three coordinates.
    pub fn new(frames: Vec<Vec<Vector3<f64>>>) -> Result<Self, AccuracyError> {
        let n = frames.first().map_or(0, Vec::len);
        for (frame, points) in frames.iter().enumerate() {
            if points.len() != n {
                return Err(AccuracyError::TrackCount {
                    frame,
                    expected: n,
                    got: points.len(),
                });
            }
            for (point, x) in points.iter().enumerate() {
                let untracked = x.iter().all(|c| c.is_nan());
                if !untracked && !x.iter().all(|c| c.is_finite()) {
                    return Err(AccuracyError::BadTrackPoint { frame, point });
                }
            }
        }
        Ok(Self { frames })
    }

    /// From a `(K, N, 3)` array in C order.
    pub fn from_array(shape: &[u64], data: &[f64]) -> Result<Self, AccuracyError> {
        let [k, n, 3] = *shape else {
            return Err(AccuracyError::TracksShape(shape.to_vec()));
        };
        let (k, n) = (k as usize, n as usize);
        let frames = (0..k)
            .map(|f| {
                (0..n)
                    .map(|p| Vector3::from_column_slice(&data[3 * (f * n + p)..][..3]))
                    .collect()
            })
            .collect();
        Self::new(frames)
    }

    /// The `(K, N, 3)` array (shape, C-order data), NaN where untracked.
    pub fn to_array(&self) -> (Vec<u64>, Vec<f64>) {
        let shape = vec![self.n_frames() as u64, self.n_tracks() as u64, 3];
        let data = self.frames.iter().flatten().flat_map(|x| x.iter().copied());
        (shape, data.collect())
    }

    pub fn n_frames(&self) -> usize {
        self.frames.len()
    }

    pub fn n_tracks(&self) -> usize {
        self.frames.first().map_or(0, Vec::len)
    }

    /// Where point `n` is in frame `k`, if it is tracked there.
    pub fn position(&self, k: usize, n: usize) -> Option<Vector3<f64>> {
        let x = self.frames[k][n];
        x.x.is_finite().then_some(x)
    }

    /// How many points are tracked in both frames of each slab.
    pub fn pairs_per_slab(&self) -> Vec<usize> {
        (1..self.n_frames())
            .map(|k| {
                (0..self.n_tracks())
                    .filter(|&n| self.position(k - 1, n).is_some() && self.position(k, n).is_some())
                    .count()
            })
            .collect()
    }
}

/// One tracked point in one slab (see the module docs for the symbols).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackPoint {
    pub slab: usize,
    pub track: usize,
    /// `ξ`: the closest point of `X[s][n]` on frame `s`.
    pub surface_point: SurfacePoint,
    /// `x_s(ξ)`.
    pub position: Vector3<f64>,
    /// `|X[s][n] − x_s(ξ)|`: how far the tracked point lies from the surface.
    pub distance: f64,
    /// `r`: the true tangential displacement relative to the mesh.
    pub truth: Vector3<f64>,
    /// `r̂`: the flow's displacement over the slab.
    pub computed: Vector3<f64>,
    /// `|r̂ − r|`.
    pub endpoint: f64,
    /// `∠(r̂, r)` in degrees; NaN where the point did not move.
    pub direction_degrees: f64,
    /// `|r̂| / |r|`; NaN where the point did not move.
    pub speed_ratio: f64,
}

/// Means and medians over a set of [`TrackPoint`]s.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TrackSummary {
    pub points: usize,
    /// Points that moved (direction error and speed ratio are taken over these).
    pub moving: usize,
    pub mean_endpoint: f64,
    pub median_endpoint: f64,
    /// The zero flow's: `|r|`.
    pub zero_mean_endpoint: f64,
    pub zero_median_endpoint: f64,
    pub mean_direction_degrees: f64,
    pub median_direction_degrees: f64,
    pub median_speed_ratio: f64,
    /// Median distance of the tracked points from the surface.
    pub median_distance: f64,
}

impl TrackSummary {
    fn of<'a>(points: impl Iterator<Item = &'a TrackPoint> + Clone) -> Self {
        let values = |f: fn(&TrackPoint) -> f64| -> Vec<f64> { points.clone().map(f).collect() };
        let endpoint = values(|p| p.endpoint);
        let zero = values(|p| p.truth.norm());
        let direction = values(|p| p.direction_degrees);
        Self {
            points: endpoint.len(),
            moving: direction.iter().filter(|d| !d.is_nan()).count(),
            mean_endpoint: mean(&endpoint),
            median_endpoint: median(&endpoint),
            zero_mean_endpoint: mean(&zero),
            zero_median_endpoint: median(&zero),
            mean_direction_degrees: mean(&direction),
            median_direction_degrees: median(&direction),
            median_speed_ratio: median(&values(|p| p.speed_ratio)),
            median_distance: median(&values(|p| p.distance)),
        }
    }

    /// Mean EPE relative to the zero flow's (below 1: the flow explains part of the motion).
    pub fn endpoint_ratio(&self) -> f64 {
        self.mean_endpoint / self.zero_mean_endpoint
    }
}

/// A flow scored at tracked points: every point of every slab, and their summaries.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackScores {
    pub points: Vec<TrackPoint>,
    /// Per slab (a slab without tracked pairs has `points == 0` and NaN measures).
    pub slabs: Vec<TrackSummary>,
    pub overall: TrackSummary,
}

/// How far from a frame's surface, in its bounding box's diameters, a tracked point may lie
/// ([`Tracks::check_for`]).
pub const TRACK_REACH: f64 = 10.0;

impl Tracks {
    /// Checks that the tracks fit `sequence`, which must be embedded: as many frames, and each
    /// tracked point within [`TRACK_REACH`] diameters of its frame's bounding box (a point at
    /// 1e300 would score as infinity).
    pub fn check_for(&self, sequence: &MeshSequence) -> Result<(), AccuracyError> {
        super::check_embedded(sequence)?;
        if self.n_frames() != sequence.n_frames() {
            return Err(AccuracyError::TrackFrames {
                tracks: self.n_frames(),
                frames: sequence.n_frames(),
            });
        }
        for (frame, points) in self.frames.iter().enumerate() {
            let positions = sequence.positions(frame).expect("embedded, checked above");
            let (low, high) = crate::geometry::bounding_box(positions);
            let diameter = (high - low).norm();
            for (point, x) in points.iter().enumerate().filter(|(_, x)| x.x.is_finite()) {
                let distance = (low - x).sup(&(x - high)).sup(&Vector3::zeros()).norm();
                if distance.is_nan() || distance > TRACK_REACH * diameter {
                    return Err(AccuracyError::TrackFarOff {
                        frame,
                        point,
                        distance,
                        diameter,
                    });
                }
            }
        }
        Ok(())
    }
}

/// Scores the R³ flow `vectors[s][i]` of `sequence` at `tracks` (module docs).
///
/// Errors: an intrinsic sequence, a flow of the wrong size, tracks that do not fit the
/// sequence ([`Tracks::check_for`]).
pub fn score_tracks(
    sequence: &MeshSequence,
    vectors: &[Vec<Vector3<f64>>],
    tracks: &Tracks,
) -> Result<TrackScores, AccuracyError> {
    super::check_flow(sequence, "computed", vectors)?;
    tracks.check_for(sequence)?;
    let mut points = Vec::new();
    for (s, flow) in vectors.iter().enumerate() {
        points.extend(score_slab(sequence, s, flow, tracks)?);
    }
    Ok(TrackScores::from_points(points, sequence.n_slabs()))
}

impl TrackScores {
    /// The measures and summaries of points whose `truth` and `computed` displacements are set
    /// (the other measures are recomputed): e.g. a baseline's prediction at the points of
    /// another score. Points of slabs `≥ n_slabs` count only in the overall summary.
    pub fn from_points(mut points: Vec<TrackPoint>, n_slabs: usize) -> Self {
        for s in 0..n_slabs {
            let in_slab = |p: &&mut TrackPoint| p.slab == s;
            let largest = maximum(
                &points
                    .iter_mut()
                    .filter(in_slab)
                    .map(|p| p.truth.norm())
                    .collect::<Vec<_>>(),
            );
            for p in points.iter_mut().filter(in_slab) {
                p.measure(MOVING_FRACTION * largest);
            }
        }
        let slabs = (0..n_slabs)
            .map(|s| TrackSummary::of(points.iter().filter(move |p| p.slab == s)))
            .collect();
        Self {
            overall: TrackSummary::of(points.iter()),
            slabs,
            points,
        }
    }
}

impl TrackPoint {
    /// EPE, and DE and speed ratio where `|r|` reaches `moving_threshold` (positive).
    fn measure(&mut self, moving_threshold: f64) {
        self.endpoint = (self.computed - self.truth).norm();
        let moved = moving_threshold > 0.0 && self.truth.norm() >= moving_threshold;
        (self.direction_degrees, self.speed_ratio) = match moved {
            true => (
                direction_error_degrees(&self.computed, &self.truth),
                self.computed.norm() / self.truth.norm(),
            ),
            false => (f64::NAN, f64::NAN),
        };
    }
}

/// [`score_tracks`] for a computed [`FlowResult`].
pub fn score_result(
    sequence: &MeshSequence,
    result: &FlowResult,
    tracks: &Tracks,
) -> Result<TrackScores, AccuracyError> {
    let vectors = result.vectors.as_deref().ok_or(AccuracyError::Intrinsic)?;
    score_tracks(sequence, vectors, tracks)
}

fn score_slab(
    sequence: &MeshSequence,
    s: usize,
    flow: &[Vector3<f64>],
    tracks: &Tracks,
) -> Result<Vec<TrackPoint>, AccuracyError> {
    let faces = sequence.mesh().faces();
    let here = sequence.positions(s).ok_or(AccuracyError::Intrinsic)?;
    let next = sequence.positions(s + 1).ok_or(AccuracyError::Intrinsic)?;
    let surface = FrameSurface::new(s, here, faces, sequence.intensities(s))
        .map_err(|e| AccuracyError::Surface(e.to_string()))?;
    let duration = sequence.slab_duration(s);
    let points = (0..tracks.n_tracks())
        .filter_map(|n| Some((n, tracks.position(s, n)?, tracks.position(s + 1, n)?)))
        .map(|(n, from, to)| {
            let xi = surface.locate(&from);
            let corners = faces[xi.face].map(|v| v as usize);
            let at = |values: &[Vector3<f64>]| -> Vector3<f64> {
                corners
                    .iter()
                    .zip(xi.barycentric)
                    .map(|(&v, b)| b * values[v])
                    .sum()
            };
            let position = at(here);
            let [a, b, c] = corners.map(|v| here[v]);
            let normal = (b - a).cross(&(c - a)).normalize();
            let tangential = |v: Vector3<f64>| v - normal * normal.dot(&v);
            let truth = tangential(to - from - (at(next) - position));
            let computed = tangential(duration * at(flow));
            TrackPoint {
                slab: s,
                track: n,
                surface_point: xi,
                position,
                distance: (from - position).norm(),
                truth,
                computed,
                // Set by TrackScores::from_points.
                endpoint: f64::NAN,
                direction_degrees: f64::NAN,
                speed_ratio: f64::NAN,
            }
        })
        .collect();
    Ok(points)
}

/// Chains per-frame point clouds into [`Tracks`] by mutual nearest neighbours within
/// `max_distance` (module docs); `None`: half the median nearest-neighbour distance of frame 0.
pub fn match_tracks(
    frames: &[Vec<Vector3<f64>>],
    max_distance: Option<f64>,
) -> Result<Tracks, AccuracyError> {
    Tracks::matched(frames, max_distance, |_, _| Ok(()))
}

impl Tracks {
    /// [`match_tracks`], with `check_size(frames, tracks)` called before the `frames × tracks`
    /// positions are allocated (a caller's memory limit: the count of tracks is known only
    /// once the points are matched).
    pub fn matched<E: From<AccuracyError>>(
        frames: &[Vec<Vector3<f64>>],
        max_distance: Option<f64>,
        check_size: impl FnOnce(usize, usize) -> Result<(), E>,
    ) -> Result<Self, E> {
        for (frame, points) in frames.iter().enumerate() {
            if let Some(point) = points.iter().position(|x| !x.iter().all(|c| c.is_finite())) {
                return Err(AccuracyError::BadTrackPoint { frame, point }.into());
            }
        }
        let bound = match max_distance {
            Some(d) if d > 0.0 && d.is_finite() => d,
            Some(d) => return Err(AccuracyError::MatchDistance(d).into()),
            None => default_match_distance(frames)?,
        };
        let (track_of, n_tracks) = chain(frames, bound);
        check_size(frames.len(), n_tracks)?;
        let mut positions = vec![vec![Vector3::repeat(f64::NAN); n_tracks]; frames.len()];
        for (k, tracks) in track_of.iter().enumerate() {
            for (p, &t) in tracks.iter().enumerate() {
                positions[k][t] = frames[k][p];
            }
        }
        Ok(Self::new(positions)?)
    }
}

/// `track_of[k][p]`, the track of point `p` of frame `k`, and the number of tracks: a point
/// continues the track of its mutual nearest neighbour in the frame before, else starts one.
fn chain(frames: &[Vec<Vector3<f64>>], bound: f64) -> (Vec<Vec<usize>>, usize) {
    let mut track_of: Vec<Vec<usize>> = Vec::with_capacity(frames.len());
    let mut n_tracks = 0;
    for (k, points) in frames.iter().enumerate() {
        let mut tracks = vec![usize::MAX; points.len()];
        if k > 0 {
            for (a, b) in mutual_nearest(&frames[k - 1], points, bound) {
                tracks[b] = track_of[k - 1][a];
            }
        }
        for t in tracks.iter_mut().filter(|t| **t == usize::MAX) {
            *t = n_tracks;
            n_tracks += 1;
        }
        track_of.push(tracks);
    }
    (track_of, n_tracks)
}

/// Half the median distance from a point of frame 0 to its nearest neighbour in frame 0.
pub fn default_match_distance(frames: &[Vec<Vector3<f64>>]) -> Result<f64, AccuracyError> {
    let points = frames.first().map_or(&[][..], Vec::as_slice);
    let tree = KdTree::new(points);
    let nearest: Vec<f64> = (0..points.len())
        .into_par_iter()
        .map(|i| match tree.nearest(&points[i], f64::INFINITY, Some(i)) {
            Some(j) => (points[i] - points[j]).norm(),
            None => f64::INFINITY,
        })
        .collect();
    let spacing = median(&nearest);
    match spacing > 0.0 && spacing.is_finite() {
        true => Ok(0.5 * spacing),
        false => Err(AccuracyError::NoSpacing),
    }
}

/// The pairs `(a, b)` of points of `from` and `to` that are each other's nearest neighbour
/// within `bound`.
fn mutual_nearest(from: &[Vector3<f64>], to: &[Vector3<f64>], bound: f64) -> Vec<(usize, usize)> {
    let to_tree = KdTree::new(to);
    let from_tree = KdTree::new(from);
    (0..from.len())
        .into_par_iter()
        .filter_map(|a| {
            let b = to_tree.nearest(&from[a], bound, None)?;
            (from_tree.nearest(&to[b], bound, None) == Some(a)).then_some((a, b))
        })
        .collect()
}

/// A k-d tree over points, stored as a permutation: the node of a range is its middle
/// element, split on axis `depth mod 3`, the lower half before it. Nearest-neighbour queries
/// take about `log n` steps whatever the matching distance (a grid of cells of that distance
/// degenerates to all pairs when the distance is large, and the all-pairs default distance
/// took 45 s at 100,000 points).
struct KdTree<'a> {
    points: &'a [Vector3<f64>],
    order: Vec<usize>,
}

impl<'a> KdTree<'a> {
    fn new(points: &'a [Vector3<f64>]) -> Self {
        let mut order: Vec<usize> = (0..points.len()).collect();
        Self::build(points, &mut order, 0);
        Self { points, order }
    }

    fn build(points: &[Vector3<f64>], order: &mut [usize], depth: usize) {
        if order.len() < 2 {
            return;
        }
        let (axis, mid) = (depth % 3, order.len() / 2);
        order.select_nth_unstable_by(mid, |&a, &b| points[a][axis].total_cmp(&points[b][axis]));
        let (lower, upper) = order.split_at_mut(mid);
        Self::build(points, lower, depth + 1);
        Self::build(points, &mut upper[1..], depth + 1);
    }

    /// The nearest point within `bound` of `x` other than `skip` (the lower index on a tie).
    fn nearest(&self, x: &Vector3<f64>, bound: f64, skip: Option<usize>) -> Option<usize> {
        let mut best = (bound, usize::MAX);
        self.search(&self.order, 0, x, skip, &mut best);
        (best.1 != usize::MAX).then_some(best.1)
    }

    fn search(
        &self,
        order: &[usize],
        depth: usize,
        x: &Vector3<f64>,
        skip: Option<usize>,
        best: &mut (f64, usize),
    ) {
        let Some(&p) = order.get(order.len() / 2) else {
            return;
        };
        let distance = (self.points[p] - x).norm();
        let closer = distance < best.0 || (distance == best.0 && p < best.1);
        if closer && Some(p) != skip {
            *best = (distance, p);
        }
        let mid = order.len() / 2;
        let across = x[depth % 3] - self.points[p][depth % 3];
        let (near, far) = match across < 0.0 {
            true => (&order[..mid], &order[mid + 1..]),
            false => (&order[mid + 1..], &order[..mid]),
        };
        self.search(near, depth + 1, x, skip, best);
        if across.abs() <= best.0 {
            self.search(far, depth + 1, x, skip, best);
        }
    }
}

/// The mean of the values that are not NaN; NaN if there are none.
fn mean(values: &[f64]) -> f64 {
    let kept: Vec<f64> = values.iter().copied().filter(|v| !v.is_nan()).collect();
    kept.iter().sum::<f64>() / kept.len() as f64
}

/// The (lower) median of the values that are not NaN; NaN if there are none.
fn median(values: &[f64]) -> f64 {
    weighted_median(values.iter().map(|&v| (1.0, v)).collect())
}
