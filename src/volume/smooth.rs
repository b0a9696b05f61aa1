//! Separable Gaussian smoothing in physical units (module docs of [`super`]).

use super::{Volume, VolumeError};
use crate::limits;
use rayon::prelude::*;

impl Volume {
    /// The volume convolved with a Gaussian of standard deviation `sigma` (physical units):
    /// `σ/d` voxels along each axis, truncated at 3σ and normalized, mirrored at the boundary
    /// (folded onto the mirrored axis, or its mean, for Gaussians as wide as the volume).
    /// `sigma = 0` returns a copy. The working copies (two of the values) are checked against
    /// the memory limit first.
    pub fn smoothed(&self, sigma: f64) -> Result<Volume, VolumeError> {
        check_sigma(sigma)?;
        self.check_smoothing_memory()?;
        self.clone().into_smoothed(sigma)
    }

    /// [`Volume::smoothed`] in place, for a volume not needed afterwards: no copy is made.
    pub fn into_smoothed(mut self, sigma: f64) -> Result<Volume, VolumeError> {
        check_sigma(sigma)?;
        self.check_smoothing_memory()?;
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
                filter => convolve_axis(&mut self.values, length, stride, &filter),
            }
        }
        Ok(self)
    }

    fn check_smoothing_memory(&self) -> Result<(), VolumeError> {
        let what = format!("smoothing a volume of {:?} voxels", self.shape);
        limits::check_items(what, self.values.len() as u64, 2 * 4 + 8)
            .map_err(|e| VolumeError::Setting(e.to_string()))
    }
}

fn check_sigma(sigma: f64) -> Result<(), VolumeError> {
    match sigma.is_finite() && sigma >= 0.0 {
        true => Ok(()),
        false => Err(VolumeError::Sigma(sigma)),
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

    /// The filtered lines of `block`: `length` rows of `width` values each, one line per
    /// column, written into `out` (same layout). Each output is `Σ w_m x[mirror(n + m)]` summed
    /// in `f64` in tap order, so a column gives what it would alone.
    fn apply(&self, block: &[f32], length: usize, width: usize, out: &mut [f32]) {
        let period = 2 * (length as i64 - 1);
        let mirrored = |i: i64| -> usize {
            let m = i.rem_euclid(period);
            (if m < length as i64 { m } else { period - m }) as usize
        };
        let row = |r: usize| &block[r * width..(r + 1) * width];
        match self {
            Self::Identity => out.copy_from_slice(block),
            Self::Mean => {
                let mut sum = vec![0.0f64; width];
                for r in 0..length {
                    sum.iter_mut()
                        .zip(row(r))
                        .for_each(|(s, &v)| *s += f64::from(v));
                }
                for r in 0..length {
                    let target = &mut out[r * width..(r + 1) * width];
                    target
                        .iter_mut()
                        .zip(&sum)
                        .for_each(|(o, s)| *o = (s / length as f64) as f32);
                }
            }
            Self::Taps(taps) => {
                let mut sum = vec![0.0f64; width];
                for n in 0..length {
                    sum.fill(0.0);
                    for &(offset, w) in taps {
                        let source = row(mirrored(n as i64 + offset));
                        sum.iter_mut()
                            .zip(source)
                            .for_each(|(s, &v)| *s += w * f64::from(v));
                    }
                    let target = &mut out[n * width..(n + 1) * width];
                    target
                        .iter_mut()
                        .zip(&sum)
                        .for_each(|(o, &s)| *o = s as f32);
                }
            }
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

/// Filters every line along one axis (`length` values `stride` apart). The values are
/// `outer` blocks of `length × stride`; each block is cut into column ranges of at most
/// [`COLUMNS`], which are filtered in parallel as contiguous rows (the lines of the x axis,
/// stride 1, are taken [`COLUMNS`] lines at a time, transposed).
fn convolve_axis(values: &mut [f32], length: usize, stride: usize, filter: &AxisFilter) {
    if stride == 1 {
        // Rows along x: transpose groups of lines so that each is a column.
        values.par_chunks_mut(length * COLUMNS).for_each(|chunk| {
            let width = chunk.len() / length;
            let mut block = vec![0.0f32; chunk.len()];
            for (c, line) in chunk.chunks_exact(length).enumerate() {
                line.iter()
                    .enumerate()
                    .for_each(|(n, &v)| block[n * width + c] = v);
            }
            let mut out = vec![0.0f32; chunk.len()];
            filter.apply(&block, length, width, &mut out);
            for (c, line) in chunk.chunks_exact_mut(length).enumerate() {
                line.iter_mut()
                    .enumerate()
                    .for_each(|(n, v)| *v = out[n * width + c]);
            }
        });
        return;
    }
    let outer = values.len() / (length * stride);
    let ranges: Vec<(usize, usize, usize)> = (0..outer)
        .flat_map(|o| {
            (0..stride)
                .step_by(COLUMNS)
                .map(move |c| (o, c, COLUMNS.min(stride - c)))
        })
        .collect();
    // A batch of ranges at a time, so that the filtered copies held stay small.
    for batch in ranges.chunks(BATCH) {
        let shared = &*values;
        let filtered: Vec<Vec<f32>> = batch
            .par_iter()
            .map(|&(o, c, width)| {
                let base = o * length * stride + c;
                let mut block = Vec::with_capacity(length * width);
                for n in 0..length {
                    block.extend_from_slice(&shared[base + n * stride..][..width]);
                }
                let mut out = vec![0.0f32; block.len()];
                filter.apply(&block, length, width, &mut out);
                out
            })
            .collect();
        for (&(o, c, width), out) in batch.iter().zip(filtered) {
            let base = o * length * stride + c;
            for n in 0..length {
                values[base + n * stride..][..width].copy_from_slice(&out[n * width..][..width]);
            }
        }
    }
}

/// Column ranges filtered between write-backs.
const BATCH: usize = 64;

/// The most columns filtered together: a block of `length × COLUMNS` values stays in cache.
const COLUMNS: usize = 256;

#[cfg(test)]
mod tests {
    use super::*;

    /// The filter applied to one line at a time, straight from its definition.
    fn by_lines(values: &[f32], length: usize, stride: usize, filter: &AxisFilter) -> Vec<f32> {
        let mut out = values.to_vec();
        let starts = (0..values.len()).filter(|&at| (at / stride).is_multiple_of(length));
        for start in starts {
            let line: Vec<f32> = (0..length).map(|n| values[start + n * stride]).collect();
            let mut filtered = vec![0.0; length];
            filter.apply(&line, length, 1, &mut filtered);
            (0..length).for_each(|n| out[start + n * stride] = filtered[n]);
        }
        out
    }

    #[test]
    fn blocks_of_columns_filter_as_single_lines_do_bit_for_bit() {
        // Axes longer and shorter than a block of columns, kernels short, folded and the mean.
        let shape = [3usize, 5, 300];
        let n: usize = shape.iter().product();
        let values: Vec<f32> = (0..n).map(|i| ((i * 7919) % 1009) as f32 * 0.37).collect();
        let [nz, ny, nx] = shape;
        for (length, stride) in [(nx, 1), (ny, nx), (nz, nx * ny)] {
            for s in [0.7, 1.9, 2.5, 40.0, 1e4] {
                let filter = AxisFilter::new(s, length);
                let mut blocked = values.clone();
                convolve_axis(&mut blocked, length, stride, &filter);
                let expected = by_lines(&values, length, stride, &filter);
                assert!(
                    blocked
                        .iter()
                        .zip(&expected)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "axis of {length} (stride {stride}), s = {s}"
                );
            }
        }
    }
}
