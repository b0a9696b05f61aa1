//! Separable Gaussian smoothing in physical units (module docs of [`super`]).

use super::{Volume, VolumeError};
use rayon::prelude::*;

impl Volume {
    /// The volume convolved with a Gaussian of standard deviation `sigma` (physical units):
    /// `σ/d` voxels along each axis, truncated at 3σ and normalized, mirrored at the boundary.
    /// `sigma = 0` returns a copy.
    pub fn smoothed(&self, sigma: f64) -> Result<Volume, VolumeError> {
        if !(sigma.is_finite() && sigma >= 0.0) {
            return Err(VolumeError::Sigma(sigma));
        }
        let mut values = self.values.clone();
        let [nz, ny, nx] = self.shape;
        // (axis length, stride, voxel size) for x, y, z.
        let axes = [
            (nx, 1, self.voxel_size.x),
            (ny, nx, self.voxel_size.y),
            (nz, nx * ny, self.voxel_size.z),
        ];
        for (length, stride, size) in axes {
            let kernel = gaussian_kernel(sigma / size);
            if kernel.len() > 1 && length > 1 {
                convolve_axis(&mut values, length, stride, &kernel);
            }
        }
        Ok(Volume {
            values,
            ..self.clone()
        })
    }
}

/// `w_m ∝ exp(−m²/2s²)` for `|m| ≤ ⌈3s⌉`, summing to 1 (`[1]` for `s` below a hundredth of
/// a voxel).
fn gaussian_kernel(s: f64) -> Vec<f64> {
    if s < 1e-2 {
        return vec![1.0];
    }
    let radius = (3.0 * s).ceil() as i64;
    let weights: Vec<f64> = (-radius..=radius)
        .map(|m| (-(m * m) as f64 / (2.0 * s * s)).exp())
        .collect();
    let total: f64 = weights.iter().sum();
    weights.iter().map(|w| w / total).collect()
}

/// Convolves every line along one axis (`length` values `stride` apart) with `kernel`
/// (odd length, centred), mirroring at both ends; lines in parallel.
fn convolve_axis(values: &mut [f32], length: usize, stride: usize, kernel: &[f64]) {
    let radius = (kernel.len() / 2) as i64;
    let line_starts: Vec<usize> = (0..values.len())
        .filter(|&start| (start / stride) % length == 0)
        .collect();
    let mirrored = |i: i64| -> usize {
        let period = 2 * (length as i64 - 1);
        let m = i.rem_euclid(period);
        (if m < length as i64 { m } else { period - m }) as usize
    };
    let lines: Vec<(usize, Vec<f32>)> = line_starts
        .par_iter()
        .map(|&start| {
            let line: Vec<f64> = (0..length)
                .map(|n| values[start + n * stride] as f64)
                .collect();
            let smoothed = (0..length as i64)
                .map(|n| {
                    kernel
                        .iter()
                        .enumerate()
                        .map(|(m, w)| w * line[mirrored(n + m as i64 - radius)])
                        .sum::<f64>() as f32
                })
                .collect();
            (start, smoothed)
        })
        .collect();
    for (start, line) in lines {
        for (n, v) in line.into_iter().enumerate() {
            values[start + n * stride] = v;
        }
    }
}
