//! OME-Zarr images (NGFF 0.4 on Zarr v2, NGFF 0.5 on Zarr v3), read one time point at a time.
//!
//! An OME-Zarr image is a directory: a Zarr group whose attributes hold `multiscales` (NGFF
//! 0.4: `.zattrs`; 0.5: `zarr.json` under `attributes.ome`), and one array per resolution level
//! (`datasets[l].path`, finest first). Its `axes` name the array's dimensions among `t`, `c`,
//! `z`, `y`, `x` (types `time`, `channel`, `space`); `z`, `y` and `x` must be there. Level `l`'s
//! `coordinateTransformations` (a `scale`, then optionally a `translation`, each preceded by
//! the multiscale's own, which apply after) give the voxel size and the position of voxel
//! `(0, 0, 0)` along each axis, in the axes' `unit` (e.g. `micrometer`).
//!
//! Frame `k` is the `(z, y, x)` block at `t = k` (one frame without a `t` axis) and the chosen
//! channel (`c = 0` by default); it is read as its own array subset, so a recording larger
//! than memory streams frame by frame, and a coarse level reads only its own chunks. Values
//! (any integer or float type) become `f32`. The arrays are read by `zarrs` (filesystem store;
//! blosc, gzip, zstd and sharding codecs); the NGFF metadata is a small JSON document, read here.

use super::VolumeError;
use crate::format::{format_number, IoError};
use crate::{limits, Error};
use nalgebra::Vector3;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::{Array, ArraySubset};
use zarrs::filesystem::FilesystemStore;

/// Whether `path` is an OME-Zarr image: a directory with `zarr.json` (v3) or `.zattrs` (v2).
pub fn is_ome_zarr(path: &Path) -> bool {
    path.is_dir() && (path.join("zarr.json").is_file() || path.join(".zattrs").is_file())
}

/// The dimensions of the array: where `t` and `c` are, if there, and `z, y, x`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axes {
    t: Option<usize>,
    c: Option<usize>,
    zyx: [usize; 3],
}

/// One resolution level of an OME-Zarr image, opened (module docs).
pub struct OmeZarr {
    path: PathBuf,
    array: Array<FilesystemStore>,
    axes: Axes,
    channel: usize,
    /// `(n_z, n_y, n_x)`.
    shape: [usize; 3],
    frames: usize,
    /// `(d_x, d_y, d_z)` and the position of voxel `(0, 0, 0)`, from the metadata.
    pub voxel_size: Vector3<f64>,
    pub translation: Vector3<f64>,
    /// What the metadata said, for a report.
    pub said: String,
}

impl OmeZarr {
    /// Level `level` of the image at `path`, channel `channel` (0 when `None`); one frame's
    /// size is checked against the memory limit.
    pub fn open(path: &Path, channel: Option<usize>, level: usize) -> Result<Self, Error> {
        let bad = |message: String| Error::from(IoError::format(path, message));
        let multiscale = multiscale(path)?;
        let axes = axes(&multiscale).map_err(bad)?;
        let datasets = (multiscale.get("datasets").and_then(Value::as_array))
            .filter(|d| !d.is_empty())
            .ok_or_else(|| bad("multiscales[0] has no datasets".into()))?;
        let dataset = datasets.get(level).ok_or_else(|| {
            bad(format!(
                "--resolution-level {level}: the image has levels 0 … {}",
                datasets.len() - 1
            ))
        })?;
        let array_path = (dataset.get("path").and_then(Value::as_str))
            .ok_or_else(|| bad(format!("datasets[{level}] has no path")))?;
        // A hostile image must not name an array outside its own directory.
        let inside = |part: &str| !part.is_empty() && part != ".." && part != ".";
        if !array_path.split(['/', '\\']).all(inside) {
            return Err(bad(format!(
                "datasets[{level}].path '{array_path}' leaves the image's directory"
            )));
        }
        let store = FilesystemStore::new(path).map_err(|e| bad(e.to_string()))?;
        let array = Array::open(Arc::new(store), &format!("/{array_path}"))
            .map_err(|e| bad(format!("array {array_path}: {e}")))?;
        let dims = array.shape().to_vec();
        if dims.len() != axes.count() {
            return Err(bad(format!(
                "array {array_path} has {} dimensions for {} axes",
                dims.len(),
                axes.count()
            )));
        }
        let channels = axes.c.map_or(1, |c| dims[c] as usize);
        let channel = channel.unwrap_or(0);
        if channel >= channels {
            return Err(bad(format!(
                "--channel {channel}: the image has channels 0 … {}",
                channels.saturating_sub(1)
            )));
        }
        let shape = axes.zyx.map(|a| dims[a] as usize);
        if shape.contains(&0) {
            return Err(VolumeError::Empty(shape).into());
        }
        let [z, y, x] = shape;
        let voxels = (z as u64).saturating_mul(y as u64).saturating_mul(x as u64);
        let what = format!("an OME-Zarr frame of {z} × {y} × {x} voxels");
        // The f32 frame, and the values as stored (up to 8 bytes each) while converted.
        limits::check_declared(what, voxels.saturating_mul(12))
            .map_err(|e| IoError::too_large(path, e))?;
        let (voxel_size, translation, unit) =
            placement(&multiscale, dataset, &axes).map_err(bad)?;
        let said = format!(
            "OME-Zarr metadata of {} (level {level}, {array_path}): {} × {} × {}{}",
            path.display(),
            format_number(voxel_size.x),
            format_number(voxel_size.y),
            format_number(voxel_size.z),
            unit.map(|u| format!(" {u}")).unwrap_or_default()
        );
        Ok(Self {
            path: path.to_path_buf(),
            frames: axes.t.map_or(1, |t| dims[t] as usize),
            array,
            axes,
            channel,
            shape,
            voxel_size,
            translation,
            said,
        })
    }

    pub fn n_frames(&self) -> usize {
        self.frames
    }

    /// `(n_z, n_y, n_x)`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// Frame `k`'s values in `(z, y, x)` C order, as `f32`.
    pub fn frame(&self, k: usize) -> Result<Vec<f32>, Error> {
        let mut ranges = vec![0..1u64; self.axes.count()];
        if let Some(t) = self.axes.t {
            ranges[t] = k as u64..k as u64 + 1;
        }
        if let Some(c) = self.axes.c {
            ranges[c] = self.channel as u64..self.channel as u64 + 1;
        }
        for (&axis, &n) in self.axes.zyx.iter().zip(&self.shape) {
            ranges[axis] = 0..n as u64;
        }
        // The subset comes in the array's dimension order: with z, y, x in that order and t
        // and c single, the frame's C order.
        self.read_as_f32(&ArraySubset::new_with_ranges(&ranges))
    }

    /// The subset's values converted to `f32` from whichever numeric type the array holds.
    fn read_as_f32(&self, subset: &ArraySubset) -> Result<Vec<f32>, Error> {
        macro_rules! as_f32 {
            ($($t:ty),*) => {$(
                if let Ok(values) = self.array.retrieve_array_subset::<Vec<$t>>(subset) {
                    return Ok(values.into_iter().map(|v| v as f32).collect());
                }
            )*};
        }
        as_f32!(u16, u8, f32, f64, i16, u32, i32, i8, u64, i64);
        let data_type = format!("{:?}", self.array.data_type());
        let message = format!("cannot read its values as numbers (data type {data_type})");
        Err(IoError::format(&self.path, message).into())
    }
}

impl Axes {
    fn count(&self) -> usize {
        3 + usize::from(self.t.is_some()) + usize::from(self.c.is_some())
    }
}

/// `multiscales[0]` of the image's attributes (NGFF 0.5 under `ome`, 0.4 at the top).
fn multiscale(path: &Path) -> Result<Value, Error> {
    let read = |name: &str| -> Result<Option<Value>, Error> {
        let file = path.join(name);
        if !file.is_file() {
            return Ok(None);
        }
        let bytes = crate::format::read_file(&file)?;
        let json = serde_json::from_slice(&bytes)
            .map_err(|e| IoError::format(&file, format!("not JSON: {e}")))?;
        Ok(Some(json))
    };
    let attributes = match read("zarr.json")? {
        Some(group) => group.get("attributes").and_then(|a| a.get("ome")).cloned(),
        None => read(".zattrs")?,
    };
    (attributes.as_ref())
        .and_then(|a| a.get("multiscales"))
        .and_then(|m| m.get(0))
        .cloned()
        .ok_or_else(|| {
            IoError::format(path, "no OME-Zarr multiscales in its attributes (an image group written by ome-zarr-py, napari or Fiji has them)").into()
        })
}

/// The axes by name; z, y and x required.
fn axes(multiscale: &Value) -> Result<Axes, String> {
    let list =
        (multiscale.get("axes").and_then(Value::as_array)).ok_or("multiscales[0] has no axes")?;
    let names: Vec<&str> = list
        .iter()
        .map(|a| {
            a.get("name")
                .and_then(Value::as_str)
                .or(a.as_str())
                .unwrap_or("")
        })
        .collect();
    let find = |name: &str| names.iter().position(|&n| n == name);
    let spatial = ["z", "y", "x"].map(find);
    match spatial {
        [Some(z), Some(y), Some(x)] if z < y && y < x && names.len() == 3 + others(&names) => {
            Ok(Axes {
                t: find("t"),
                c: find("c"),
                zyx: [z, y, x],
            })
        }
        _ => Err(format!(
            "axes {names:?}: meshflow reads images with axes z, y, x in that order, optionally t and c"
        )),
    }
}

/// How many of `t` and `c` are among `names`.
fn others(names: &[&str]) -> usize {
    names.iter().filter(|&&n| n == "t" || n == "c").count()
}

/// Voxel size and translation along x, y, z, and the spatial unit.
type Placement = (Vector3<f64>, Vector3<f64>, Option<String>);

/// Voxel size and translation of `dataset` along x, y, z (the multiscale's transformations
/// applied after the dataset's), and the spatial unit.
fn placement(multiscale: &Value, dataset: &Value, axes: &Axes) -> Result<Placement, String> {
    let n = axes.count();
    let (mut scale, mut translation) = (vec![1.0; n], vec![0.0; n]);
    for transforms in [dataset, multiscale].map(|v| v.get("coordinateTransformations")) {
        for transform in transforms.and_then(Value::as_array).into_iter().flatten() {
            let numbers = |key: &str| -> Result<Vec<f64>, String> {
                let list = transform.get(key).and_then(Value::as_array);
                let values: Vec<f64> = list
                    .into_iter()
                    .flatten()
                    .filter_map(Value::as_f64)
                    .collect();
                match values.len() == n {
                    true => Ok(values),
                    false => Err(format!(
                        "a {key} transformation of {} numbers for {n} axes",
                        values.len()
                    )),
                }
            };
            match transform.get("type").and_then(Value::as_str) {
                Some("scale") => {
                    let s = numbers("scale")?;
                    for a in 0..n {
                        scale[a] *= s[a];
                        translation[a] *= s[a];
                    }
                }
                Some("translation") => {
                    let t = numbers("translation")?;
                    (0..n).for_each(|a| translation[a] += t[a]);
                }
                _ => {}
            }
        }
    }
    let [z, y, x] = axes.zyx;
    let voxel_size = Vector3::new(scale[x], scale[y], scale[z]);
    if !voxel_size.iter().all(|d| d.is_normal() && *d > 0.0) {
        return Err(format!(
            "its scale gives the voxel size {voxel_size:?}: not positive"
        ));
    }
    let unit = (multiscale.get("axes").and_then(|a| a.get(x)))
        .and_then(|a| a.get("unit"))
        .and_then(Value::as_str)
        .map(str::to_string);
    Ok((
        voxel_size,
        Vector3::new(translation[x], translation[y], translation[z]),
        unit,
    ))
}
