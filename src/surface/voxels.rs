//! The bright layer of a 3-D image as weighted points, so that a sheet or cap (an endoderm on a
//! yolk, an epithelium) can be fitted from the volumes alone, as [`super::fit_surface`] fits
//! one through cell centres.
//!
//! Per volume: a Gaussian smoothing of `σ` and a threshold `c` (Otsu's, or a value), as
//! [`super::find_surface`] does (its steps 1 and 2). Every voxel above it becomes a point at
//! its centre `x_v` with the weight of its brightness above the threshold,
//!
//! ```text
//! w_v = v − c   (v > c),
//! ```
//!
//! so that the weighted spline ([`super::fit_surface_weighted`]) passes through the
//! intensity-weighted middle of the layer: bright nuclei pull, dim rims little, the background
//! not at all. A volume of 10⁷ voxels may have 10⁶ above the threshold; every `s`-th of them in
//! C order is kept (`s = ⌈n / MAX_POINTS⌉`), which keeps their density even and the fit's cost
//! bounded (the weights carry the brightness, the count only the density).

use super::isosurface::{smoothed_threshold, IsosurfaceError, IsosurfaceOptions};
use crate::volume::Volume;
use nalgebra::Vector3;

/// The most points taken from one volume.
pub const MAX_POINTS: usize = 200_000;

/// The length that [`super::FitOptions::smoothing`] and `margin` count for points taken from
/// volumes, in the largest voxel side: on the zebrafish 57 µm, near the 63 µm mean spacing of
/// its cell centres, so that one `--smoothing` means about the same through voxels as through
/// cells.
pub const SPACING_IN_VOXELS: f64 = 8.0;

/// [`SPACING_IN_VOXELS`] of `volume`'s largest voxel side: the `length` of
/// [`super::fit_surface_weighted`] for its [`foreground_points`].
pub fn voxel_spacing(volume: &Volume) -> f64 {
    SPACING_IN_VOXELS * volume.voxel_size().max()
}

/// One volume's bright voxels as weighted points, and what the threshold found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ForegroundPoints {
    #[serde(skip)]
    pub points: Vec<Vector3<f64>>,
    /// `v − c`, positive.
    #[serde(skip)]
    pub weights: Vec<f64>,
    /// `c`, in the image's values.
    pub threshold: f64,
    /// Voxels above it.
    pub foreground_voxels: usize,
    /// Their share of the volume.
    pub foreground_share: f64,
    /// Every `stride`-th foreground voxel is a point.
    pub stride: usize,
}

/// The voxels of `volume` above its threshold as weighted points (module docs).
pub fn foreground_points(
    volume: &Volume,
    options: &IsosurfaceOptions,
) -> Result<ForegroundPoints, IsosurfaceError> {
    let sigma = options.smoothing.unwrap_or(volume.voxel_size().max());
    let (smoothed, threshold) = smoothed_threshold(volume.clone(), sigma, options)?;
    let values = smoothed.values();
    let foreground_voxels = values.iter().filter(|&&v| v > threshold).count();
    let stride = foreground_voxels.div_ceil(MAX_POINTS).max(1);
    let [_, n_y, n_x] = volume.shape();
    let (points, weights): (Vec<Vector3<f64>>, Vec<f64>) = (values.iter().enumerate())
        .filter(|(_, &v)| v > threshold)
        .step_by(stride)
        .map(|(at, &v)| {
            let (k, j, i) = (at / (n_y * n_x), at / n_x % n_y, at % n_x);
            (volume.position(k, j, i), f64::from(v - threshold))
        })
        .unzip();
    Ok(ForegroundPoints {
        points,
        weights,
        threshold: f64::from(threshold),
        foreground_voxels,
        foreground_share: foreground_voxels as f64 / values.len() as f64,
        stride,
    })
}
