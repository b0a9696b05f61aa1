//! A volume read onto a surface: per vertex, samples along its normal over a shell, reduced to
//! one value.
//!
//! With `x_i` a vertex, `n_i` its unit normal (outward for a surface oriented counter-clockwise
//! seen from outside) and a shell `[−a, b]` of `L` layers, the samples are
//!
//! ```text
//! s_{i,l} = v(x_i + o_l n_i),   o_l = −a + l (a + b) / (L − 1),  l = 0 … L−1   (o_0 = 0 if L = 1)
//! ```
//!
//! (`v` trilinear, [`super::Volume::sample`]), reduced by the maximum (a maximum-intensity
//! projection in the shell: bright cells near the surface show whatever their exact depth), the
//! mean, or one layer. A vertex whose shell leaves the volume, at any layer, gets 0 and is
//! counted: a partial shell would bias the maximum and the mean against the vertices whose
//! shell is whole, and 0 is what a dark region of a fluorescence image reads anyway.

use super::{Volume, VolumeError};
use crate::connection::vertex_normals;
use crate::limits;
use crate::mesh::Mesh;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::str::FromStr;

/// How the samples of a vertex's shell become its value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Reduce {
    /// The brightest sample: a maximum-intensity projection.
    #[default]
    Max,
    Mean,
    /// Sample `l` (0: the innermost).
    Layer(usize),
}

impl FromStr for Reduce {
    type Err = String;

    /// `max`, `mean` or `layer:L`.
    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "max" => Ok(Self::Max),
            "mean" => Ok(Self::Mean),
            _ => text
                .strip_prefix("layer:")
                .and_then(|l| l.parse().ok())
                .map(Self::Layer)
                .ok_or_else(|| format!("'{text}': expected max, mean or layer:L (L = 0, 1, …)")),
        }
    }
}

/// The shell along each normal, physical units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shell {
    /// `a`: how far inside (against the normal).
    pub inside: f64,
    /// `b`: how far outside.
    pub outside: f64,
    /// `L ≥ 1` samples, evenly spaced from `−a` to `b` (one: at the surface).
    pub layers: usize,
}

impl Shell {
    fn check(&self, reduce: Reduce) -> Result<(), VolumeError> {
        let bad = |message: String| Err(VolumeError::Setting(message));
        if !(self.inside.is_finite() && self.outside.is_finite())
            || self.inside < 0.0
            || self.outside < 0.0
        {
            return bad(format!(
                "the shell must be two distances ≥ 0 (inside, outside), got {}, {}",
                self.inside, self.outside
            ));
        }
        if self.layers == 0 {
            return bad("the shell needs at least one layer".into());
        }
        match reduce {
            Reduce::Layer(l) if l >= self.layers => bad(format!(
                "layer {l} of a shell of {} layers (0 … {})",
                self.layers,
                self.layers - 1
            )),
            _ => Ok(()),
        }
    }

    /// `layers × vertices × frames` samples, 8 bytes each, checked against the memory limit:
    /// a bound on the time they take (and on the offsets' memory) that `--layers 1000000000`
    /// would otherwise not have.
    fn check_cost(&self, vertices: usize, frames: usize) -> Result<(), VolumeError> {
        let what = format!(
            "--layers {} × {vertices} vertices × {frames} frames of shell samples",
            self.layers
        );
        let samples = (self.layers as u64)
            .saturating_mul(vertices as u64)
            .saturating_mul(frames as u64);
        limits::check_items(what, samples, 8).map_err(|e| VolumeError::Setting(e.to_string()))
    }

    /// `o_l` for every layer.
    fn offsets(&self) -> Vec<f64> {
        match self.layers {
            1 => vec![0.0],
            n => (0..n)
                .map(|l| -self.inside + l as f64 * (self.inside + self.outside) / (n - 1) as f64)
                .collect(),
        }
    }
}

/// One frame's values per vertex, and how many vertices' shells left the volume (value 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled {
    pub values: Vec<f64>,
    pub outside: usize,
}

/// The reduced shell samples at every vertex (module docs).
pub fn sample_shell(
    volume: &Volume,
    positions: &[Vector3<f64>],
    normals: &[Vector3<f64>],
    shell: &Shell,
    reduce: Reduce,
) -> Result<Sampled, VolumeError> {
    shell.check(reduce)?;
    if positions.len() != normals.len() {
        return Err(VolumeError::NormalCount {
            frame: 0,
            positions: positions.len(),
            normals: normals.len(),
        });
    }
    shell.check_cost(positions.len(), 1)?;
    let offsets = shell.offsets();
    let values: Vec<Option<f64>> = positions
        .par_iter()
        .zip(normals)
        .map(|(x, n)| reduce_shell(volume, x, n, &offsets, reduce))
        .collect();
    Ok(Sampled {
        outside: values.iter().filter(|v| v.is_none()).count(),
        values: values.into_iter().map(|v| v.unwrap_or(0.0)).collect(),
    })
}

/// The samples of one vertex's shell reduced as they are taken; `None` where one leaves the
/// volume.
fn reduce_shell(
    volume: &Volume,
    x: &Vector3<f64>,
    n: &Vector3<f64>,
    offsets: &[f64],
    reduce: Reduce,
) -> Option<f64> {
    let (mut max, mut sum, mut chosen) = (f64::NEG_INFINITY, 0.0, 0.0);
    for (l, o) in offsets.iter().enumerate() {
        let sample = volume.sample(&(x + *o * n))?;
        max = max.max(sample);
        sum += sample;
        if reduce == Reduce::Layer(l) {
            chosen = sample;
        }
    }
    Some(match reduce {
        Reduce::Max => max,
        Reduce::Mean => sum / offsets.len() as f64,
        Reduce::Layer(_) => chosen,
    })
}

/// How a recording is carried onto a surface: Gaussian pre-smoothing, shell, reduction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleOptions {
    /// `σ` of the Gaussian applied to each volume first (physical units; 0: none); `None`:
    /// [`DEFAULT_SMOOTHING_VOXELS`] of the smallest voxel side.
    pub smoothing: Option<f64>,
    /// `None`: ± two of the largest voxel sides, [`DEFAULT_LAYERS`] layers.
    pub shell: Option<Shell>,
    pub reduce: Reduce,
}

/// Layers of the default shell.
pub const DEFAULT_LAYERS: usize = 9;

/// Default `σ` in smallest voxel sides: on the zebrafish recording (cells about 10 µm across,
/// voxels 1.68 µm in-plane) 2 voxels (3.4 µm) scored best and no smoothing worst
/// (`examples/zebrafish.rs`); shot noise of a voxel is not structure the flow can follow.
pub const DEFAULT_SMOOTHING_VOXELS: f64 = 2.0;

impl Default for SampleOptions {
    /// The default smoothing, the default shell, the maximum.
    fn default() -> Self {
        Self {
            smoothing: None,
            shell: None,
            reduce: Reduce::Max,
        }
    }
}

impl SampleOptions {
    /// The Gaussian's `σ` for `volume`: the given one, else [`DEFAULT_SMOOTHING_VOXELS`] of
    /// its smallest voxel side.
    pub fn smoothing_for(&self, volume: &Volume) -> f64 {
        self.smoothing
            .unwrap_or_else(|| DEFAULT_SMOOTHING_VOXELS * volume.voxel_size().min())
    }

    /// The shell for `volume`: the given one, else ±2 of its largest voxel sides (a shell that
    /// spans a few slices of the coarsest axis, so a surface a voxel off still sees the cells).
    pub fn shell_for(&self, volume: &Volume) -> Shell {
        self.shell.unwrap_or_else(|| {
            let reach = 2.0 * volume.voxel_size().max();
            Shell {
                inside: reach,
                outside: reach,
                layers: DEFAULT_LAYERS,
            }
        })
    }
}

/// Every frame of a moving surface read from its volume: `values[k][i]` for mesh vertex `i`
/// of frame `k`, `outside[k]` the vertices whose shell left volume `k`.
#[derive(Clone, Debug, PartialEq)]
pub struct SampledSequence {
    pub values: Vec<Vec<f64>>,
    pub outside: Vec<usize>,
    /// The shell used.
    pub shell: Shell,
    /// The Gaussian's `σ` used (0: none).
    pub smoothing: f64,
}

/// Carries `volumes[k]` onto frame `k` of the surface (`positions[k]` of `mesh`'s vertices)
/// along the corner-angle-weighted vertex normals (outward for counter-clockwise faces), each
/// volume smoothed first (see [`SampleOptions::smoothing_for`]; `σ = 0`: not at all).
pub fn sample_sequence(
    volumes: &[Volume],
    mesh: &Mesh,
    positions: &[Vec<Vector3<f64>>],
    options: &SampleOptions,
) -> Result<SampledSequence, VolumeError> {
    if volumes.len() != positions.len() {
        return Err(VolumeError::FrameCount {
            volumes: volumes.len(),
            frames: positions.len(),
        });
    }
    let Some(first) = volumes.first() else {
        return Err(VolumeError::FrameCount {
            volumes: 0,
            frames: 0,
        });
    };
    let sampler = FrameSampler::new(first, options, mesh.n_vertices(), volumes.len())?;
    let mut sequence = sampler.empty(volumes.len());
    for (frame, (volume, x)) in volumes.iter().zip(positions).enumerate() {
        let sampled = sampler.sample(volume, mesh, x, frame)?;
        sequence.values.push(sampled.values);
        sequence.outside.push(sampled.outside);
    }
    Ok(sequence)
}

/// [`sample_sequence`] one frame at a time, for volumes read one at a time
/// ([`super::VolumeStream`]): the smoothing and shell are chosen from the first volume.
#[derive(Clone, Debug)]
pub struct FrameSampler {
    sigma: f64,
    shell: Shell,
    reduce: Reduce,
}

impl FrameSampler {
    /// The sampler of `n_frames` volumes like `first` onto `n_vertices` vertices; the shell's
    /// cost is checked for all of them.
    pub fn new(
        first: &Volume,
        options: &SampleOptions,
        n_vertices: usize,
        n_frames: usize,
    ) -> Result<Self, VolumeError> {
        let sigma = options.smoothing_for(first);
        if !(sigma.is_finite() && sigma >= 0.0) {
            return Err(VolumeError::Sigma(sigma));
        }
        let shell = options.shell_for(first);
        shell.check(options.reduce)?;
        shell.check_cost(n_vertices, n_frames)?;
        Ok(Self {
            sigma,
            shell,
            reduce: options.reduce,
        })
    }

    /// Frame `frame`'s `volume` read along the normals of the mesh at `x`.
    pub fn sample(
        &self,
        volume: &Volume,
        mesh: &Mesh,
        x: &[Vector3<f64>],
        frame: usize,
    ) -> Result<Sampled, VolumeError> {
        if x.len() != mesh.n_vertices() {
            return Err(VolumeError::NormalCount {
                frame,
                positions: x.len(),
                normals: mesh.n_vertices(),
            });
        }
        let smoothed = (self.sigma > 0.0)
            .then(|| volume.smoothed(self.sigma))
            .transpose()?;
        let volume = smoothed.as_ref().unwrap_or(volume);
        let normals = vertex_normals(mesh, x);
        sample_shell(volume, x, &normals, &self.shell, self.reduce)
    }

    /// A sequence of no frames yet, with room for `n_frames`, and the smoothing and shell used.
    pub fn empty(&self, n_frames: usize) -> SampledSequence {
        SampledSequence {
            values: Vec::with_capacity(n_frames),
            outside: Vec::with_capacity(n_frames),
            shell: self.shell,
            smoothing: self.sigma,
        }
    }
}
