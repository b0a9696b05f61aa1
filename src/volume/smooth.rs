//! Separable Gaussian smoothing in physical units (module docs of [`super`]).

use super::{Volume, VolumeError};
use crate::limits;
use rayon::prelude::*;

impl Volume {
    /// The volume convolved with a Gaussian of standard deviation `sigma` (physical units):
    /// `σ/d` voxels along each axis, truncated at 3σ and normalized, mirrored at the boundary
    /// (folded onto the mirrored axis, or its mean, for Gaussians as wide as the volume).
    /// `sigma = 0` returns a copy. The
    /// working copies (two of the values) are checked against the memory limit first.
    pub fn smoothed(&self, sigma: f64) -> Result<Volume, VolumeError> {
        if !(sigma.is_finite() && sigma >= 0.0) {
            return Err(VolumeError::Sigma(sigma));
        }
        let what = format!("smoothing a volume of {:?} voxels", self.shape);
        limits::check_items(what, self.values.len() as u64, 2 * 4 + 8)
            .map_err(|e| VolumeError::Setting(e.to_string()))?;
        let mut values = self.values.clone();
        let [nz, ny, nx] = self.shape;
        // (axis length, stride, voxel size) for x, y, z.
        let axes = [
            (nx, 1, self.voxel_size.x),
            (ny, nx, self.voxel_size.y),
            (nz, nx * ny, self.voxel_size.z),
        ];
        for (length, stride, size) in axes {
            match AxisFilter::new(sigma / size, length) {
                AxisFilter::Identity => {}
                filter => convolve_axis(&mut values, length, stride, &filter),
            }
        }
        Ok(Volume {
            values,
            ..self.clone()
        })
    }
}

/// A Gaussian of `s` voxels on an axis of `length` voxels mirrored at both ends (period
/// `P = 2(length − 1)`), in a form whose cost is bounded by the axis, not by `s`: the kernel
/// as offset–weight taps, folded onto one period where it is longer than that (exact: the
/// mirrored line repeats with period `P`), and for `s ≥ P` the line's mean (the periodic sum of
/// such a Gaussian differs from a constant by less than `e^{−2π²} ≈ 3e-9` of it), so that
/// `--smooth 1e9` neither allocates a kernel of 6e9 taps nor runs for hours.
enum AxisFilter {
    Identity,
    Taps(Vec<(i64, f64)>),
    Mean,
}

impl AxisFilter {
    fn new(s: f64, length: usize) -> Self {
        if s < 1e-2 || length < 2 {
            return Self::Identity;
        }
        let period = 2 * (length as i64 - 1);
        if s >= period as f64 {
            return Self::Mean;
        }
        let kernel = gaussian_kernel(s);
        let radius = (kernel.len() / 2) as i64;
        let taps = (kernel.iter().enumerate()).map(|(m, &w)| (m as i64 - radius, w));
        if kernel.len() as i64 <= period {
            return Self::Taps(taps.collect());
        }
        let mut folded = vec![0.0; period as usize];
        for (offset, w) in taps {
            folded[offset.rem_euclid(period) as usize] += w;
        }
        Self::Taps((0..).zip(folded).collect())
    }

    /// The filtered line.
    fn apply(&self, line: &[f64]) -> Vec<f32> {
        let length = line.len() as i64;
        let mirrored = |i: i64| -> usize {
            let period = 2 * (length - 1);
            let m = i.rem_euclid(period);
            (if m < length { m } else { period - m }) as usize
        };
        match self {
            Self::Identity => line.iter().map(|&v| v as f32).collect(),
            Self::Mean => vec![(line.iter().sum::<f64>() / line.len() as f64) as f32; line.len()],
            Self::Taps(taps) => (0..length)
                .map(|n| {
                    (taps.iter())
                        .map(|&(offset, w)| w * line[mirrored(n + offset)])
                        .sum::<f64>() as f32
                })
                .collect(),
        }
    }
}

/// `w_m ∝ exp(−m²/2s²)` for `|m| ≤ ⌈3s⌉`, summing to 1.
fn gaussian_kernel(s: f64) -> Vec<f64> {
    let radius = (3.0 * s).ceil() as i64;
    let weights: Vec<f64> = (-radius..=radius)
        .map(|m| (-(m * m) as f64 / (2.0 * s * s)).exp())
        .collect();
    let total: f64 = weights.iter().sum();
    weights.iter().map(|w| w / total).collect()
}

/// Filters every line along one axis (`length` values `stride` apart); lines in parallel.
fn convolve_axis(values: &mut [f32], length: usize, stride: usize, filter: &AxisFilter) {
    let line_starts: Vec<usize> = (0..values.len())
        .filter(|&start| (start / stride) % length == 0)
        .collect();
    let lines: Vec<(usize, Vec<f32>)> = line_starts
        .par_iter()
        .map(|&start| {
            let line: Vec<f64> = (0..length)
                .map(|n| values[start + n * stride] as f64)
                .collect();
            (start, filter.apply(&line))
        })
        .collect();
    for (start, line) in lines {
        for (n, v) in line.into_iter().enumerate() {
            values[start + n * stride] = v;
        }
    }
}
