//! 3-D images (microscope volumes): values on a regular grid, read from NPY and TIFF stacks,
//! interpolated trilinearly, smoothed by a Gaussian in physical units, and read along the
//! normals of a surface ([`sample`]). Knows nothing of meshes but positions and normals.
//!
//! # Conventions
//!
//! A volume of shape `(n_z, n_y, n_x)` holds `v[k][j][i]` (C order, index `(k·n_y + j)·n_x + i`:
//! the `(z, y, x)` order in which NumPy, h5py and tifffile read stacks; a TIFF's pages are `k`).
//! Voxel `(k, j, i)` is the value at its centre
//!
//! ```text
//! x(k, j, i) = o + (i·d_x, j·d_y, k·d_z)      o: origin, d: voxel size (physical units)
//! ```
//!
//! **Trilinear interpolation.** A point `p` has grid coordinates `g = ((p − o)_x/d_x, …)`; with
//! `g = c + f` (`c` integer, `f ∈ [0, 1)³`),
//!
//! ```text
//! v(p) = Σ_{a,b,e ∈ {0,1}} w_a(f_x) w_b(f_y) w_e(f_z) v[c_z+e][c_y+b][c_x+a],   w_0(t) = 1 − t, w_1(t) = t
//! ```
//!
//! exact for functions linear in `x, y, z`. A point is **inside** when every grid coordinate
//! lies in `[0, n − 1]` (the box of voxel centres); elsewhere the volume has no value (`None`).
//!
//! **Gaussian smoothing** ([`Volume::smoothed`]) with standard deviation `σ` in physical units
//! is separable: along each axis a sampled, normalized Gaussian of `σ/d` voxels, truncated at
//! `3σ/d`. The boundary is mirrored (`v[−1] = v[1]`), which keeps a constant volume constant
//! and does not darken the rim as zero padding would. A kernel longer than the mirrored axis
//! is folded onto it, and a Gaussian at least as wide as that (σ ≥ 2(n − 1) voxels) averages
//! the axis, so the cost never grows with σ beyond the volume's size.

mod ome_zarr;
mod read;
pub mod sample;
mod smooth;
mod tiff_stack;
mod zarr_chunks;
mod zarr_store;

pub use ome_zarr::is_ome_zarr;
pub use read::{
    count_volume_frames, read_volumes, VolumeFrames, VolumeOptions, VolumeStream, VoxelSizeSource,
};
pub use sample::{
    sample_sequence, sample_shell, sample_stream, FrameSampler, Misplacement, PlacementReport,
    Reduce, SampleOptions, SampledSequence, Shell, StreamEvent,
};

use nalgebra::Vector3;
use std::path::PathBuf;

/// A 3-D image: `f32` values on a grid of voxel centres (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// `(n_z, n_y, n_x)`.
    shape: [usize; 3],
    values: Vec<f32>,
    /// `(d_x, d_y, d_z)`.
    voxel_size: Vector3<f64>,
    origin: Vector3<f64>,
}

/// Why a volume could not be built, read or sampled. Variants name the file, frame or voxel.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VolumeError {
    #[error("a volume of shape {shape:?} needs {expected} values, got {got}")]
    ValueCount {
        shape: [usize; 3],
        expected: usize,
        got: usize,
    },
    #[error("a volume needs at least one voxel, got shape {0:?}")]
    Empty([usize; 3]),
    #[error("voxel (z {k}, y {j}, x {i}) is {value}: volumes must be finite")]
    NonFinite {
        k: usize,
        j: usize,
        i: usize,
        value: f32,
    },
    #[error("the voxel size must be three positive, normal numbers (x, y, z), got ({}, {}, {})", .0[0], .0[1], .0[2])]
    VoxelSize([f64; 3]),
    #[error("the origin must be finite, got ({}, {}, {})", .0[0], .0[1], .0[2])]
    Origin([f64; 3]),
    #[error("the smoothing σ must be a number ≥ 0 (physical units), got {0}")]
    Sigma(f64),
    #[error("frame {frame} ({}) is {got:?} voxels (z, y, x), frame 0 is {expected:?}: every frame must have one shape", file.display())]
    FrameShape {
        frame: usize,
        file: PathBuf,
        expected: [usize; 3],
        got: [usize; 3],
    },
    #[error("{0}")]
    Setting(String),
    /// A frame's surface lies mostly outside its volume, or within a voxel or two: wrong units,
    /// voxel size or origin.
    #[error("{0}")]
    Misplaced(Box<sample::PlacementReport>),
    #[error(
        "invalid voxel size in the metadata: {0}; give the voxel size with --voxel-size X,Y,Z"
    )]
    Metadata(String),
    #[error("{volumes} volume frames for {frames} surface frames")]
    FrameCount { volumes: usize, frames: usize },
    #[error("frame {frame}: {positions} positions but {normals} normals")]
    NormalCount {
        frame: usize,
        positions: usize,
        normals: usize,
    },
}

impl Volume {
    /// Checks the shape against the values, that every value is finite, and that the voxel
    /// size is positive and the origin finite.
    pub fn new(
        shape: [usize; 3],
        values: Vec<f32>,
        voxel_size: Vector3<f64>,
        origin: Vector3<f64>,
    ) -> Result<Self, VolumeError> {
        let expected = shape.iter().product::<usize>();
        if expected == 0 {
            return Err(VolumeError::Empty(shape));
        }
        if values.len() != expected {
            return Err(VolumeError::ValueCount {
                shape,
                expected,
                got: values.len(),
            });
        }
        check_voxel_size(&voxel_size)?;
        if !origin.iter().all(|c| c.is_finite()) {
            return Err(VolumeError::Origin(origin.into()));
        }
        if let Some(at) = values.iter().position(|v| !v.is_finite()) {
            let [_, ny, nx] = shape;
            return Err(VolumeError::NonFinite {
                k: at / (ny * nx),
                j: at / nx % ny,
                i: at % nx,
                value: values[at],
            });
        }
        Ok(Self {
            shape,
            values,
            voxel_size,
            origin,
        })
    }

    /// `(n_z, n_y, n_x)`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// `(d_x, d_y, d_z)`.
    pub fn voxel_size(&self) -> Vector3<f64> {
        self.voxel_size
    }

    pub fn origin(&self) -> Vector3<f64> {
        self.origin
    }

    /// The values in C order, `(k·n_y + j)·n_x + i`.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// The centre of voxel `(k, j, i)`.
    pub fn position(&self, k: usize, j: usize, i: usize) -> Vector3<f64> {
        self.origin + Vector3::new(i as f64, j as f64, k as f64).component_mul(&self.voxel_size)
    }

    /// `[low, high]`: the box of voxel centres, `o` to `o + ((n_x − 1) d_x, (n_y − 1) d_y,
    /// (n_z − 1) d_z)`, where [`Volume::sample`] has values.
    pub fn bounds(&self) -> [Vector3<f64>; 2] {
        let [n_z, n_y, n_x] = self.shape;
        [self.origin, self.position(n_z - 1, n_y - 1, n_x - 1)]
    }

    /// Whether `p` lies in [`Volume::bounds`] (where the volume has a value).
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        let [low, high] = self.bounds();
        (0..3).all(|a| p[a] >= low[a] && p[a] <= high[a])
    }

    /// The same volume placed elsewhere: another voxel size and origin.
    pub fn placed(
        self,
        voxel_size: Vector3<f64>,
        origin: Vector3<f64>,
    ) -> Result<Self, VolumeError> {
        Self::new(self.shape, self.values, voxel_size, origin)
    }

    /// The trilinear interpolation at `p`; `None` outside the box of voxel centres.
    pub fn sample(&self, p: &Vector3<f64>) -> Option<f64> {
        let g = (p - self.origin).component_div(&self.voxel_size);
        // Grid axes in (x, y, z) order: n_x, n_y, n_z.
        let n = [self.shape[2], self.shape[1], self.shape[0]];
        let mut base = [0usize; 3];
        let mut fraction = [0.0; 3];
        for axis in 0..3 {
            let last = (n[axis] - 1) as f64;
            if !(g[axis] >= 0.0 && g[axis] <= last) {
                return None;
            }
            // The cell's lower corner, kept one below the last voxel so the upper one exists.
            let c = (g[axis].floor() as usize).min(n[axis].saturating_sub(2));
            base[axis] = c;
            fraction[axis] = g[axis] - c as f64;
        }
        let at = |i: usize, j: usize, k: usize| -> f64 {
            let (i, j, k) = (i.min(n[0] - 1), j.min(n[1] - 1), k.min(n[2] - 1));
            self.values[(k * n[1] + j) * n[0] + i] as f64
        };
        let [i, j, k] = base;
        let [fx, fy, fz] = fraction;
        let lerp = |a: f64, b: f64, t: f64| a + t * (b - a);
        let plane = |k: usize| {
            lerp(
                lerp(at(i, j, k), at(i + 1, j, k), fx),
                lerp(at(i, j + 1, k), at(i + 1, j + 1, k), fx),
                fy,
            )
        };
        Some(lerp(plane(k), plane(k + 1), fz))
    }
}

/// Whether `d` can be a length of a voxel: positive, finite and normal (a subnormal size such
/// as 1e-320 turns grid coordinates infinite).
fn is_length(d: f64) -> bool {
    d.is_normal() && d > 0.0
}

/// "WHERE is 1e300, which does not fit single precision …": a float64 value that `f32`
/// volumes cannot hold.
fn does_not_fit_f32(value: f64, place: &str) -> String {
    format!(
        "{place} is {value:e}, which does not fit single precision (f32, magnitudes up to {:e}): rescale the values",
        f32::MAX
    )
}

fn check_voxel_size(voxel_size: &Vector3<f64>) -> Result<(), VolumeError> {
    match voxel_size.iter().all(|&d| is_length(d)) {
        true => Ok(()),
        false => Err(VolumeError::VoxelSize((*voxel_size).into())),
    }
}
