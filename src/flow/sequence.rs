//! A deforming surface with an image on it: the input of the flow.

use super::FlowError;
use crate::connection::{vertex_frames_in_r3, Connection};
use crate::geometry::{edge_lengths, IntrinsicGeometry};
use crate::mesh::Mesh;
use nalgebra::{Matrix3x2, Vector3};

/// Frames `k = 0..K−1` of one mesh connectivity: geometry per frame (positions, or edge lengths
/// for an intrinsic sequence), a grey value per vertex and frame, and strictly increasing times.
///
/// Validated on construction: at least two frames, matching counts, finite values, no
/// degenerate face in any frame.
#[derive(Clone, Debug)]
pub struct MeshSequence {
    mesh: Mesh,
    positions: Option<Vec<Vec<Vector3<f64>>>>,
    edge_lengths: Vec<Vec<f64>>,
    intensities: Vec<Vec<f64>>,
    times: Vec<f64>,
}

impl MeshSequence {
    /// A sequence of embedded frames. `times = None` means `0, 1, 2, …`.
    pub fn new(
        mesh: Mesh,
        positions: Vec<Vec<Vector3<f64>>>,
        intensities: Vec<Vec<f64>>,
        times: Option<Vec<f64>>,
    ) -> Result<Self, FlowError> {
        let lengths = positions
            .iter()
            .enumerate()
            .map(|(frame, p)| {
                edge_lengths(&mesh, p).map_err(|source| FlowError::Frame { frame, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut sequence = Self::from_edge_lengths(mesh, lengths, intensities, times)?;
        sequence.positions = Some(positions);
        Ok(sequence)
    }

    /// An intrinsic sequence: one length per edge (indexed like [`Mesh::edges`]) per frame, no
    /// embedding. Everything but the push-forward to R^3 works on it.
    pub fn from_edge_lengths(
        mesh: Mesh,
        edge_lengths: Vec<Vec<f64>>,
        intensities: Vec<Vec<f64>>,
        times: Option<Vec<f64>>,
    ) -> Result<Self, FlowError> {
        let n_frames = edge_lengths.len();
        if n_frames < 2 {
            return Err(FlowError::TooFewFrames(n_frames));
        }
        for (frame, lengths) in edge_lengths.iter().enumerate() {
            IntrinsicGeometry::new(&mesh, lengths.clone())
                .map_err(|source| FlowError::Frame { frame, source })?;
        }
        check_intensities(&mesh, &intensities, n_frames)?;
        let times = times.unwrap_or_else(|| (0..n_frames).map(|k| k as f64).collect());
        check_times(&times, n_frames)?;
        Ok(Self {
            mesh,
            positions: None,
            edge_lengths,
            intensities,
            times,
        })
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

    pub fn intensities(&self, k: usize) -> &[f64] {
        &self.intensities[k]
    }
}

fn check_intensities(
    mesh: &Mesh,
    intensities: &[Vec<f64>],
    n_frames: usize,
) -> Result<(), FlowError> {
    if intensities.len() != n_frames {
        return Err(FlowError::CountMismatch {
            what: "intensity frames",
            expected: n_frames,
            got: intensities.len(),
        });
    }
    for (frame, values) in intensities.iter().enumerate() {
        if values.len() != mesh.n_vertices() {
            return Err(FlowError::Frame {
                frame,
                source: crate::geometry::GeometryError::CountMismatch {
                    what: "intensities (one per vertex)",
                    expected: mesh.n_vertices(),
                    got: values.len(),
                },
            });
        }
    }
    check_finite_intensities(intensities, |_| true)
}

/// Fails on the first non-finite grey value at a vertex that `checked` selects.
pub(crate) fn check_finite_intensities(
    intensities: &[Vec<f64>],
    checked: impl Fn(usize) -> bool,
) -> Result<(), FlowError> {
    for (frame, values) in intensities.iter().enumerate() {
        let bad = |(i, v): &(usize, &f64)| !v.is_finite() && checked(*i);
        if let Some((vertex, _)) = values.iter().enumerate().find(bad) {
            return Err(FlowError::NonFiniteIntensity {
                frame,
                vertex,
                value: values[vertex],
            });
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
