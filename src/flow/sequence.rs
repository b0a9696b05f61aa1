//! A deforming surface with an image on it: the input of the flow.

use super::FlowError;
use crate::connection::{vertex_frames_in_r3, Connection};
use crate::geometry::{edge_lengths, IntrinsicGeometry};
use crate::mesh::Mesh;
use crate::statistics::channel_mean;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use nalgebra::{Matrix3x2, Vector3};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// The image on a sequence: `C ≥ 1` channels (grey, RGB, any stack of stains), one value per
/// channel, vertex and frame. `frames[k][c][i]` is channel `c` at vertex `i` in frame `k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Images {
    frames: Vec<Vec<Vec<f64>>>,
}

impl Images {
    /// Several channels per frame: `frames[k][c][i]`.
    pub fn from_channels(frames: Vec<Vec<Vec<f64>>>) -> Self {
        Self { frames }
    }

    /// One grey channel per frame: `frames[k][i]`.
    pub fn grey(frames: Vec<Vec<f64>>) -> Self {
        Self {
            frames: frames.into_iter().map(|grey| vec![grey]).collect(),
        }
    }

    pub fn n_frames(&self) -> usize {
        self.frames.len()
    }

    /// The channels of frame `k`.
    pub fn frame(&self, k: usize) -> &[Vec<f64>] {
        &self.frames[k]
    }

    pub fn into_frames(self) -> Vec<Vec<Vec<f64>>> {
        self.frames
    }
}

/// Frames `k = 0..K−1` of one mesh connectivity: geometry per frame (positions, or edge lengths
/// for an intrinsic sequence), an image of `C ≥ 1` channels per vertex and frame ([`Images`]),
/// and strictly increasing times.
///
/// Validated on construction: at least two frames, matching counts (the same number of
/// channels in every frame), finite values, no degenerate face in any frame.
#[derive(Clone, Debug)]
pub struct MeshSequence {
    mesh: Mesh,
    positions: Option<Vec<Vec<Vector3<f64>>>>,
    edge_lengths: Vec<Vec<f64>>,
    images: Images,
    /// The mean of the channels per frame when there are several (what [`Self::intensities`]
    /// shows), `None` for one channel.
    channel_means: Option<Vec<Vec<f64>>>,
    times: Vec<f64>,
    /// The symbolic Cholesky analysis of every frame's scalar `M + τL` (the mesh's pattern),
    /// once computed ([`super::pyramid::heat_symbolic`]).
    heat_symbolic: OnceLock<Arc<SymbolicCholesky<usize>>>,
    /// The symbolic Cholesky analysis of the slab blocks (the mesh's vertex pattern, two DOFs
    /// per vertex), once a solve has made it: every solve of the sequence (warps, levels,
    /// reweightings) factors blocks of the same pattern ([`SpaceTimeSystem::assemble`]).
    slab_symbolic: OnceLock<Arc<SymbolicCholesky<usize>>>,
}

impl MeshSequence {
    /// A sequence of embedded frames with a grey value per vertex and frame (`intensities[k][i]`).
    /// `times = None` means `0, 1, 2, …`.
    pub fn new(
        mesh: Mesh,
        positions: Vec<Vec<Vector3<f64>>>,
        intensities: Vec<Vec<f64>>,
        times: Option<Vec<f64>>,
    ) -> Result<Self, FlowError> {
        Self::with_images(mesh, positions, Images::grey(intensities), times)
    }

    /// [`Self::new`] with an image of any number of channels.
    pub fn with_images(
        mesh: Mesh,
        positions: Vec<Vec<Vector3<f64>>>,
        images: Images,
        times: Option<Vec<f64>>,
    ) -> Result<Self, FlowError> {
        let lengths = positions
            .iter()
            .enumerate()
            .map(|(frame, p)| {
                edge_lengths(&mesh, p).map_err(|source| FlowError::Frame { frame, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut sequence = Self::from_edge_lengths_with_images(mesh, lengths, images, times)?;
        sequence.positions = Some(positions);
        Ok(sequence)
    }

    /// An intrinsic sequence: one length per edge (indexed like [`Mesh::edges`]) per frame, no
    /// embedding, and a grey value per vertex and frame. Everything but the push-forward to R^3
    /// works on it.
    pub fn from_edge_lengths(
        mesh: Mesh,
        edge_lengths: Vec<Vec<f64>>,
        intensities: Vec<Vec<f64>>,
        times: Option<Vec<f64>>,
    ) -> Result<Self, FlowError> {
        Self::from_edge_lengths_with_images(mesh, edge_lengths, Images::grey(intensities), times)
    }

    /// [`Self::from_edge_lengths`] with an image of any number of channels.
    pub fn from_edge_lengths_with_images(
        mesh: Mesh,
        edge_lengths: Vec<Vec<f64>>,
        images: Images,
        times: Option<Vec<f64>>,
    ) -> Result<Self, FlowError> {
        let n_frames = edge_lengths.len();
        if n_frames < 2 {
            return Err(FlowError::TooFewFrames(n_frames));
        }
        // In parallel; the first bad frame's error, whatever the timing.
        let checked: Vec<Result<(), FlowError>> = (edge_lengths.par_iter().enumerate())
            .map(|(frame, lengths)| {
                IntrinsicGeometry::check(&mesh, lengths)
                    .map_err(|source| FlowError::Frame { frame, source })
            })
            .collect();
        checked.into_iter().collect::<Result<(), _>>()?;
        check_images(&mesh, &images, n_frames)?;
        let times = times.unwrap_or_else(|| (0..n_frames).map(|k| k as f64).collect());
        check_times(&times, n_frames)?;
        let channel_means = (images.frame(0).len() > 1)
            .then(|| images.frames.iter().map(|f| channel_mean(f)).collect());
        Ok(Self {
            mesh,
            positions: None,
            edge_lengths,
            images,
            channel_means,
            times,
            heat_symbolic: OnceLock::new(),
            slab_symbolic: OnceLock::new(),
        })
    }

    /// Where [`super::pyramid::heat_symbolic`] keeps its analysis.
    pub(super) fn heat_symbolic_cache(&self) -> &OnceLock<Arc<SymbolicCholesky<usize>>> {
        &self.heat_symbolic
    }

    /// Where the space-time systems of this sequence keep their slab blocks' analysis
    /// ([`SpaceTimeSystem::assemble`]).
    pub(super) fn slab_symbolic_cache(&self) -> &OnceLock<Arc<SymbolicCholesky<usize>>> {
        &self.slab_symbolic
    }

    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    pub fn n_frames(&self) -> usize {
        self.times.len()
    }

    /// `S = K − 1`: one flow field per pair of consecutive frames.
    pub fn n_slabs(&self) -> usize {
        self.n_frames() - 1
    }

    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// Positions of frame `k`, `None` for an intrinsic sequence.
    pub fn positions(&self, k: usize) -> Option<&[Vector3<f64>]> {
        self.positions.as_ref().map(|p| p[k].as_slice())
    }

    pub fn edge_lengths(&self, k: usize) -> &[f64] {
        &self.edge_lengths[k]
    }

    /// The geometry of slab `s = [t_s, t_{s+1}]`: every edge length is the mean of its lengths
    /// in frames `s` and `s + 1` (`docs/discretization.md` §3).
    pub fn slab_geometry(&self, s: usize) -> Result<IntrinsicGeometry, FlowError> {
        let mean = self.edge_lengths[s]
            .iter()
            .zip(&self.edge_lengths[s + 1])
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        IntrinsicGeometry::new(&self.mesh, mean)
            .map_err(|source| FlowError::Slab { slab: s, source })
    }

    /// The orthonormal vertex frames `P_i` in R³ of slab `s` on frame `s`
    /// (`docs/discretization.md` §8): the frames of [`crate::flow::FlowResult::vectors`].
    /// `None` for an intrinsic sequence.
    pub fn slab_frames(&self, s: usize) -> Result<Option<Vec<Matrix3x2<f64>>>, FlowError> {
        let Some(positions) = self.positions(s) else {
            return Ok(None);
        };
        let geometry = self.slab_geometry(s)?;
        let connection = Connection::new(&self.mesh, &geometry);
        vertex_frames_in_r3(&self.mesh, &geometry, &connection, positions)
            .map(Some)
            .map_err(|source| FlowError::Slab { slab: s, source })
    }

    /// `Δt_s = t_{s+1} − t_s`.
    pub fn slab_duration(&self, s: usize) -> f64 {
        self.times[s + 1] - self.times[s]
    }

    /// The grey value per vertex of frame `k`: the image itself when it has one channel, the
    /// mean of its channels otherwise. Pictures and outputs show it; the data term uses every
    /// channel ([`Self::channels`]).
    pub fn intensities(&self, k: usize) -> &[f64] {
        match &self.channel_means {
            Some(means) => &means[k],
            None => &self.images.frames[k][0],
        }
    }

    /// `C`, the number of image channels (1 for grey).
    pub fn n_channels(&self) -> usize {
        self.images.frame(0).len()
    }

    /// The channels of frame `k`: `channels(k)[c][i]`.
    pub fn channels(&self, k: usize) -> &[Vec<f64>] {
        self.images.frame(k)
    }

    pub fn images(&self) -> &Images {
        &self.images
    }

    /// Frames `frames` of this sequence as a sequence of their own (at least two; times kept),
    /// e.g. the frames one time window of a distributed solve needs.
    pub fn frames(&self, frames: std::ops::Range<usize>) -> Result<Self, FlowError> {
        if frames.end > self.n_frames() {
            return Err(FlowError::CountMismatch {
                what: "frames",
                expected: frames.end,
                got: self.n_frames(),
            });
        }
        let images = Images::from_channels(self.images.frames[frames.clone()].to_vec());
        let times = Some(self.times[frames.clone()].to_vec());
        let lengths = self.edge_lengths[frames.clone()].to_vec();
        let mut part =
            Self::from_edge_lengths_with_images(self.mesh.clone(), lengths, images, times)?;
        part.positions = (self.positions.as_ref()).map(|p| p[frames].to_vec());
        Ok(part)
    }
}

fn check_images(mesh: &Mesh, images: &Images, n_frames: usize) -> Result<(), FlowError> {
    if images.n_frames() != n_frames {
        return Err(FlowError::CountMismatch {
            what: "intensity frames",
            expected: n_frames,
            got: images.n_frames(),
        });
    }
    let n_channels = images.frame(0).len();
    if n_channels == 0 {
        return Err(FlowError::CountMismatch {
            what: "image channels in frame 0",
            expected: 1,
            got: 0,
        });
    }
    let vertex_mismatch = |frame: usize, got: usize| FlowError::Frame {
        frame,
        source: crate::geometry::GeometryError::CountMismatch {
            what: "intensities (one per vertex)",
            expected: mesh.n_vertices(),
            got,
        },
    };
    for (frame, channels) in images.frames.iter().enumerate() {
        if channels.len() != n_channels {
            return Err(FlowError::ChannelMismatch {
                frame,
                expected: n_channels,
                got: channels.len(),
            });
        }
        if let Some(c) = channels.iter().find(|c| c.len() != mesh.n_vertices()) {
            return Err(vertex_mismatch(frame, c.len()));
        }
    }
    check_finite_intensities(images, |_| true)
}

/// Fails on the first non-finite image value at a vertex that `checked` selects.
pub(crate) fn check_finite_intensities(
    images: &Images,
    checked: impl Fn(usize) -> bool,
) -> Result<(), FlowError> {
    for (frame, channels) in images.frames.iter().enumerate() {
        for (channel, values) in channels.iter().enumerate() {
            let bad = |(i, v): &(usize, &f64)| !v.is_finite() && checked(*i);
            if let Some((vertex, _)) = values.iter().enumerate().find(bad) {
                return Err(FlowError::NonFiniteIntensity {
                    frame,
                    vertex,
                    channel: (channels.len() > 1).then_some(channel),
                    value: values[vertex],
                });
            }
        }
    }
    Ok(())
}

fn check_times(times: &[f64], n_frames: usize) -> Result<(), FlowError> {
    if times.len() != n_frames {
        return Err(FlowError::CountMismatch {
            what: "frame times",
            expected: n_frames,
            got: times.len(),
        });
    }
    if let Some(frame) = times.iter().position(|t| !t.is_finite()) {
        return Err(FlowError::NonFiniteTime {
            frame,
            value: times[frame],
        });
    }
    match (1..n_frames).find(|&k| times[k] <= times[k - 1]) {
        Some(frame) => Err(FlowError::NonIncreasingTimes {
            frame,
            value: times[frame],
            previous: times[frame - 1],
        }),
        None => Ok(()),
    }
}
