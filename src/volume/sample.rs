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
//! shell is whole, and 0 is what a dark region of a fluorescence image reads anyway. Such
//! vertices have **no data** ([`Sampled::no_data`]): `meshflow sample` writes their mask beside
//! the image, and the solve flags them in its outputs.
//!
//! A frame whose vertices lie outside its volume for more than half of them, or whose whole
//! surface spans fewer than [`MIN_SURFACE_VOXELS`] voxels, is refused ([`PlacementReport`])
//! unless [`SampleOptions::allow_outside`]: that is what a voxel size in other units than the
//! surface (mm or nm against µm), a missing one or a wrong origin give, and an image of zeros
//! or of one interpolated value would otherwise pass silently to the solve.

use super::{Volume, VolumeError, VolumeStream, VoxelSizeSource};
use crate::connection::vertex_normals;
use crate::format::format_number;
use crate::limits;
use crate::mesh::Mesh;
use crate::Error;
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

/// One frame's values per vertex, and which vertices' shells left the volume (value 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled {
    pub values: Vec<f64>,
    /// How many vertices have [`Sampled::no_data`].
    pub outside: usize,
    /// Per vertex: its shell left the volume, so its value 0 is not a measurement.
    pub no_data: Vec<bool>,
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
    let no_data: Vec<bool> = values.iter().map(Option::is_none).collect();
    Ok(Sampled {
        outside: no_data.iter().filter(|&&missing| missing).count(),
        values: values.into_iter().map(|v| v.unwrap_or(0.0)).collect(),
        no_data,
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
    /// `None`: ± two of the largest voxel sides, with [`SampleOptions::layers`] layers.
    pub shell: Option<Shell>,
    /// The default shell's layers (`None`: [`DEFAULT_LAYERS`]); a given `shell` has its own.
    pub layers: Option<usize>,
    pub reduce: Reduce,
    /// Sample a frame even where most of its vertices lie outside the volume, or all of them
    /// within a voxel or two (see the module docs); off by default.
    pub allow_outside: bool,
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
            layers: None,
            reduce: Reduce::Max,
            allow_outside: false,
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
                layers: self.layers.unwrap_or(DEFAULT_LAYERS),
            }
        })
    }
}

/// Every frame of a moving surface read from its volume: `values[k][i]` for mesh vertex `i`
/// of frame `k`, `outside[k]` the number of vertices whose shell left volume `k` and
/// `no_data[k]` which they are.
#[derive(Clone, Debug, PartialEq)]
pub struct SampledSequence {
    pub values: Vec<Vec<f64>>,
    pub outside: Vec<usize>,
    pub no_data: Vec<Vec<bool>>,
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
        sequence.push(sampler.sample(volume, mesh, x, frame)?);
    }
    Ok(sequence)
}

/// What [`sample_stream`] reports as it goes.
#[derive(Clone, Copy, Debug)]
pub enum StreamEvent<'a> {
    /// The first frame was read: where the voxel size came from.
    VoxelSize(&'a VoxelSizeSource),
    /// Frame `k` was sampled.
    Sampled(usize),
    /// Frame `frame` of an OME-Zarr image lacked `missing` of its `chunks` chunks, read as the
    /// fill value.
    MissingChunks {
        frame: usize,
        missing: u64,
        chunks: u64,
    },
}

/// [`sample_sequence`] of volumes read one at a time from `stream`: only one frame's volume
/// and its smoothed copy are held, whatever the recording's length. Errors name the
/// stream's path.
pub fn sample_stream(
    stream: &mut VolumeStream,
    mesh: &Mesh,
    positions: &[Vec<Vector3<f64>>],
    options: &SampleOptions,
    on_event: &mut dyn FnMut(StreamEvent),
) -> Result<SampledSequence, Error> {
    let path = stream.path().to_path_buf();
    let in_volumes = |e: VolumeError| Error::from(e).in_file(&path);
    let n_frames = stream.n_frames();
    if n_frames != positions.len() {
        return Err(in_volumes(VolumeError::FrameCount {
            volumes: n_frames,
            frames: positions.len(),
        }));
    }
    let mut sampling: Option<(FrameSampler, SampledSequence)> = None;
    for (frame, x) in positions.iter().enumerate() {
        // A stream read from before it came here has fewer frames left than it declares.
        let Some(read) = stream.next() else {
            return Err(in_volumes(VolumeError::FrameCount {
                volumes: frame,
                frames: positions.len(),
            }));
        };
        let (volume, _) = read?;
        if let Some((missing, chunks)) = stream.missing_chunks() {
            on_event(StreamEvent::MissingChunks {
                frame,
                missing,
                chunks,
            });
        }
        if sampling.is_none() {
            if let Some(source) = stream.voxel_size_source() {
                on_event(StreamEvent::VoxelSize(source));
            }
            let sampler = FrameSampler::new(&volume, options, mesh.n_vertices(), n_frames)
                .map_err(in_volumes)?;
            let sequence = sampler.empty(n_frames);
            sampling = Some((sampler, sequence));
        }
        let (sampler, sequence) = sampling.as_mut().expect("made above");
        sequence.push(
            sampler
                .sample(&volume, mesh, x, frame)
                .map_err(in_volumes)?,
        );
        on_event(StreamEvent::Sampled(frame));
    }
    Ok(sampling.expect("a recording has a frame").1)
}

/// [`sample_sequence`] one frame at a time, for volumes read one at a time
/// ([`super::VolumeStream`]): the smoothing and shell are chosen from the first volume.
#[derive(Clone, Debug)]
pub struct FrameSampler {
    sigma: f64,
    shell: Shell,
    reduce: Reduce,
    allow_outside: bool,
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
            allow_outside: options.allow_outside,
        })
    }

    /// Frame `frame`'s `volume` read along the normals of the mesh at `x`; refused where more
    /// than half of `x` lies outside the volume or all of it within a voxel or two, unless
    /// allowed (module docs).
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
        if !self.allow_outside {
            PlacementReport::check(volume, x, frame)?;
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
            no_data: Vec::with_capacity(n_frames),
            shell: self.shell,
            smoothing: self.sigma,
        }
    }
}

impl SampledSequence {
    /// Appends the next frame.
    pub fn push(&mut self, frame: Sampled) {
        self.values.push(frame.values);
        self.outside.push(frame.outside);
        self.no_data.push(frame.no_data);
    }
}

/// How a frame's surface misses its volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Misplacement {
    /// More than half of the vertices lie outside the volume's box.
    MostlyOutside { outside: usize },
    /// The whole surface spans fewer than [`MIN_SURFACE_VOXELS`] voxels along every axis: it
    /// lies within a voxel or two, where sampling reads one interpolated value.
    WithinAVoxel { voxels: f64 },
}

/// A frame whose surface does not fit its volume, with what tells why: the volume's box (voxel
/// size, origin, extent) against the surface's.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacementReport {
    pub frame: usize,
    pub vertices: usize,
    pub misplacement: Misplacement,
    pub voxel_size: Vector3<f64>,
    pub origin: Vector3<f64>,
    /// [`Volume::bounds`].
    pub volume_box: [Vector3<f64>; 2],
    /// The bounding box of the surface's vertices.
    pub surface_box: [Vector3<f64>; 2],
}

/// Above this many orders of magnitude (base 10) between the surface's extent and the
/// volume's, the two are taken to be in different units.
const UNITS_APART: f64 = 1.3;

/// A surface must span at least this many voxels along some axis to be sampled.
pub const MIN_SURFACE_VOXELS: f64 = 2.0;

impl PlacementReport {
    /// Refuses frame `frame` when more than half of `x` lies outside `volume`, or all of it
    /// within [`MIN_SURFACE_VOXELS`] voxels (module docs).
    fn check(volume: &Volume, x: &[Vector3<f64>], frame: usize) -> Result<(), VolumeError> {
        let mut surface_box = [
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ];
        for p in x {
            surface_box[0] = surface_box[0].inf(p);
            surface_box[1] = surface_box[1].sup(p);
        }
        let outside = x.iter().filter(|p| !volume.contains(p)).count();
        let extent = (surface_box[1] - surface_box[0]).component_div(&volume.voxel_size());
        let voxels = extent.max();
        let misplacement = if 2 * outside > x.len() {
            Misplacement::MostlyOutside { outside }
        } else if voxels < MIN_SURFACE_VOXELS {
            Misplacement::WithinAVoxel { voxels }
        } else {
            return Ok(());
        };
        Err(VolumeError::Misplaced(Box::new(Self {
            frame,
            vertices: x.len(),
            misplacement,
            voxel_size: volume.voxel_size(),
            origin: volume.origin(),
            volume_box: volume.bounds(),
            surface_box,
        })))
    }

    /// `log10` of the surface's extent over the volume's, the geometric mean over the axes
    /// where both have one.
    fn scale_apart(&self) -> Option<f64> {
        let extent = |[low, high]: [Vector3<f64>; 2]| high - low;
        let (surface, volume) = (extent(self.surface_box), extent(self.volume_box));
        let logs: Vec<f64> = (0..3)
            .filter(|&a| surface[a] > 0.0 && volume[a] > 0.0)
            .map(|a| (surface[a] / volume[a]).log10())
            .collect();
        (!logs.is_empty()).then(|| logs.iter().sum::<f64>() / logs.len() as f64)
    }

    /// What is probably wrong.
    fn hint(&self) -> String {
        match self.scale_apart() {
            Some(apart) if apart.abs() > UNITS_APART => format!(
                "the surface is about {} times {} than the volume: the voxel size and the surface are probably in different units (mm, µm and nm are 1000 apart); give --voxel-size in the surface's units",
                format_number(10f64.powf(apart.abs().round())),
                if apart > 0.0 { "larger" } else { "smaller" },
            ),
            _ => "check --voxel-size (X,Y,Z, in the surface's units; without it the files' metadata or 1 × 1 × 1) and --origin".into(),
        }
    }
}

impl std::fmt::Display for PlacementReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let triple = |v: Vector3<f64>| v.iter().map(|&c| format_number(c)).collect::<Vec<_>>();
        let span = |[low, high]: [Vector3<f64>; 2]| {
            let (low, high) = (triple(low), triple(high));
            format!(
                "x {}…{}, y {}…{}, z {}…{}",
                low[0], high[0], low[1], high[1], low[2], high[2]
            )
        };
        let what = match self.misplacement {
            Misplacement::MostlyOutside { outside } => format!(
                "{outside} of {} vertices ({:.0} %) lie outside the recording",
                self.vertices,
                100.0 * outside as f64 / self.vertices as f64,
            ),
            Misplacement::WithinAVoxel { voxels } => format!(
                "the surface spans {} voxels, too few to sample",
                format_number(voxels)
            ),
        };
        write!(
            f,
            "frame {}: {what}: the volume spans {} (voxel size {}, origin {}), the surface {}; {}, or give --allow-outside to sample anyway",
            self.frame,
            span(self.volume_box),
            triple(self.voxel_size).join(" × "),
            triple(self.origin).join(", "),
            span(self.surface_box),
            self.hint(),
        )
    }
}
