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
//! (any integer or float type) become `f32`.
//!
//! A store is many files, each as hostile as any input: every one is read through
//! [`ContainedStore`] (no key outside the store, after links; no FIFO or device; sizes bounded
//! before reading). `zarrs` parses the array metadata through it; the chunks are decoded here,
//! each codec bounded by the chunk's decoded size ([`super::zarr_chunks`]). A frame is at most
//! [`MAX_CHUNKS_PER_FRAME`] chunks; one none of whose chunks is stored is an error, not a frame
//! of fill values, and a frame with some missing says how many ([`OmeZarr::frame`]). A
//! coordinate transformation other than `scale`, `translation` and `identity` (`affine`,
//! `rotation`) is not applied silently: the voxel size must then be given.

use super::read::Metadata;
use super::zarr_chunks::{Codecs, Element, Pieces, Place, Target};
use super::zarr_store::{ContainedStore, METADATA_MOST_BYTES};
use super::VolumeError;
use crate::format::{format_number, quoted, IoError};
use crate::{limits, Error};
use nalgebra::Vector3;
use rayon::prelude::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::{Array, ArrayMetadata, ArrayMetadataOptions, ArraySubset};
use zarrs::metadata::v3::ArrayMetadataV3;

/// Whether `path` is an OME-Zarr image: a directory with `zarr.json` (v3) or `.zattrs` (v2).
pub fn is_ome_zarr(path: &Path) -> bool {
    path.is_dir() && (path.join("zarr.json").is_file() || path.join(".zattrs").is_file())
}

/// The most chunks (files) one frame may take: each is a file to look up, and a frame of
/// 400³ one-voxel chunks, none of them stored, is 64 million look-ups of nothing.
pub const MAX_CHUNKS_PER_FRAME: u64 = 1 << 20;

/// The most inner chunks of shards one frame may take.
pub const MAX_INNER_CHUNKS_PER_FRAME: u64 = 1 << 24;

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
    /// The array's path in the store, for messages.
    array_path: String,
    array: Array<ContainedStore>,
    /// The store, its values bounded by a chunk's largest encoded size.
    chunks: ContainedStore,
    codecs: Codecs,
    element: Element,
    fill: f32,
    axes: Axes,
    channel: usize,
    /// `(n_z, n_y, n_x)`.
    shape: [usize; 3],
    frames: usize,
    /// The position of voxel `(0, 0, 0)`, from the metadata (zero where it gives none).
    pub translation: Vector3<f64>,
    /// What the metadata says of the voxel size: found (with a report), absent, or not
    /// understood.
    pub metadata: Metadata,
}

impl OmeZarr {
    /// Level `level` of the image at `path`, channel `channel` (0 when `None`); one frame's
    /// size, its chunks' count and their decoded size are checked against the memory limit.
    /// Every file is read through [`ContainedStore`].
    pub fn open(path: &Path, channel: Option<usize>, level: usize) -> Result<Self, Error> {
        let bad = |message: String| Error::from(IoError::format(path, message));
        let store = ContainedStore::new(path, METADATA_MOST_BYTES)?;
        let multiscale = multiscale(path, &store)?;
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
                "datasets[{level}].path {} leaves the image's directory",
                quoted(array_path)
            )));
        }
        let in_array = |why: String| bad(format!("array {}: {why}", quoted(array_path)));
        let array = Array::open(Arc::new(store.clone()), &format!("/{array_path}"))
            .map_err(|e| in_array(e.to_string()))?;
        let dims = array.shape().to_vec();
        if dims.len() != axes.count() {
            return Err(in_array(format!(
                "{} dimensions for {} axes",
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
            return Err(Error::from(VolumeError::Empty(shape)).in_file(path));
        }
        let [z, y, x] = shape;
        let voxels = (z as u64).saturating_mul(y as u64).saturating_mul(x as u64);
        let what = format!("an OME-Zarr frame of {z} × {y} × {x} voxels");
        limits::check_declared(what, voxels.saturating_mul(4))
            .map_err(|e| IoError::too_large(path, e))?;
        let (codecs, element, fill) = chain(&array).map_err(&in_array)?;
        let chunk_shape = (array.chunk_shape(&vec![0; dims.len()]))
            .map_err(|e| in_array(e.to_string()))?
            .iter()
            .map(|n| n.get())
            .collect::<Vec<u64>>();
        check_chunk_counts(&array, &axes, &codecs, &chunk_shape).map_err(&in_array)?;
        // A frame, and each thread's chunk while it is decoded: the stored bytes and the
        // decoded ones.
        let threads = rayon::current_num_threads() as u64;
        let per_chunk = (codecs.decoded_bytes(&chunk_shape, element))
            .saturating_add(codecs.encoded_most(&chunk_shape, element));
        let what = format!(
            "an OME-Zarr frame of {z} × {y} × {x} voxels, and {threads} chunks of {chunk_shape:?} \
             being decoded"
        );
        limits::check_declared(
            what,
            (voxels * 4).saturating_add(threads.saturating_mul(per_chunk)),
        )
        .map_err(|e| IoError::too_large(path, e))?;
        let chunks = store.with_most(codecs.encoded_most(&chunk_shape, element));
        let (translation, metadata) =
            placement(&multiscale, dataset, &axes, path, level, array_path);
        Ok(Self {
            path: path.to_path_buf(),
            array_path: array_path.to_string(),
            frames: axes.t.map_or(1, |t| dims[t] as usize),
            array,
            chunks,
            codecs,
            element,
            fill,
            axes,
            channel,
            shape,
            translation,
            metadata,
        })
    }

    pub fn n_frames(&self) -> usize {
        self.frames
    }

    /// `(n_z, n_y, n_x)`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// Frame `k`'s values in `(z, y, x)` C order, as `f32`, and how many of its chunks were
    /// not stored (read as the fill value). A frame none of whose chunks is stored is an
    /// error: it would be the fill value alone.
    pub fn frame(&self, k: usize) -> Result<(Vec<f32>, Pieces), Error> {
        let rank = self.axes.count();
        let (mut start, mut extent) = (vec![0u64; rank], vec![1u64; rank]);
        if let Some(t) = self.axes.t {
            start[t] = k as u64;
        }
        if let Some(c) = self.axes.c {
            start[c] = self.channel as u64;
        }
        for (&axis, &n) in self.axes.zyx.iter().zip(&self.shape) {
            extent[axis] = n as u64;
        }
        let mut values = vec![0f32; self.shape.iter().product()];
        let pieces = self.read_region(&start, &extent, &mut values)?;
        if pieces.missing == pieces.chunks {
            let why = format!(
                "frame {k}: none of its {} chunks is stored in array {}: the frame would be the \
                 fill value {} alone",
                pieces.chunks,
                quoted(&self.array_path),
                self.fill
            );
            return Err(IoError::format(&self.path, why).into());
        }
        Ok((values, pieces))
    }

    /// The region `start`, `extent` (of singleton `t` and `c`) into `values`, in bands of
    /// chunks along z decoded in parallel, each band its own rows of `values`.
    fn read_region(
        &self,
        start: &[u64],
        extent: &[u64],
        values: &mut [f32],
    ) -> Result<Pieces, Error> {
        let ranges: Vec<_> = start.iter().zip(extent).map(|(&s, &e)| s..s + e).collect();
        let region = ArraySubset::new_with_ranges(&ranges);
        let in_array = |why: String| {
            Error::from(IoError::format(
                &self.path,
                format!("array {}: {why}", quoted(&self.array_path)),
            ))
        };
        let chunks = (self.array.chunks_in_array_subset(&region).ok().flatten())
            .ok_or_else(|| in_array("its chunks cannot be found for the frame".into()))?;
        let z = self.axes.zyx[0];
        let plane = values.len() / extent[z] as usize;
        let mut bands = Vec::new();
        let mut rest = values;
        for band in chunks.start()[z]..chunks.start()[z] + chunks.shape()[z] {
            let mut indices = chunks.start().to_vec();
            indices[z] = band;
            let place = self
                .array
                .chunk_subset(&indices)
                .map_err(|e| in_array(e.to_string()))?;
            let first = place.start()[z].max(start[z]);
            let end = (place.start()[z] + place.shape()[z]).min(start[z] + extent[z]);
            let (held, after) = rest.split_at_mut((end - first) as usize * plane);
            bands.push((band, (first - start[z]) as usize * plane, held));
            rest = after;
        }
        bands
            .into_par_iter()
            .map(|(band, offset, held)| {
                let mut target = Target {
                    start,
                    extent,
                    offset,
                    values: held,
                };
                self.read_band(&chunks, band, &mut target)
            })
            .try_reduce(Pieces::default, |mut a, b| {
                a += b;
                Ok(a)
            })
    }

    /// The chunks of z index `band` among `chunks`, decoded into `target`.
    fn read_band(
        &self,
        chunks: &ArraySubset,
        band: u64,
        target: &mut Target,
    ) -> Result<Pieces, Error> {
        let z = self.axes.zyx[0];
        let mut lower = chunks.start().to_vec();
        lower[z] = band;
        let mut upper = chunks.end_exc();
        upper[z] = band + 1;
        let mut pieces = Pieces::default();
        let mut indices = lower.clone();
        loop {
            pieces += self.read_chunk(&indices, target)?;
            // The next chunk of the band: an odometer over the chunk indices.
            let Some(d) = (0..indices.len())
                .rev()
                .find(|&d| indices[d] + 1 < upper[d])
            else {
                return Ok(pieces);
            };
            indices[d] += 1;
            indices[d + 1..].copy_from_slice(&lower[d + 1..]);
        }
    }

    /// The chunk at `indices` into `target`: decoded, or the fill value where it is not stored.
    fn read_chunk(&self, indices: &[u64], target: &mut Target) -> Result<Pieces, Error> {
        let key = self.array.chunk_key(indices);
        let in_chunk = |why: String| {
            let message = format!(
                "array {}, chunk {}: {why}",
                quoted(&self.array_path),
                key.as_str()
            );
            Error::from(IoError::format(&self.path, message))
        };
        let subset = self
            .array
            .chunk_subset(indices)
            .map_err(|e| in_chunk(e.to_string()))?;
        let place = Place {
            origin: subset.start().to_vec(),
            shape: subset.shape().to_vec(),
        };
        match self.chunks.read(key.as_str())? {
            None => {
                target.fill(&place, self.fill);
                let n = self.codecs.stored_pieces(&place.shape);
                Ok(Pieces {
                    chunks: n,
                    missing: n,
                })
            }
            Some(bytes) => (self.codecs)
                .decode_into(&bytes, &place, self.element, self.fill, target)
                .map_err(in_chunk),
        }
    }
}

/// The array's codec chain, element type and fill value, from its metadata as Zarr v3 (a v2
/// array's converted).
fn chain(array: &Array<ContainedStore>) -> Result<(Codecs, Element, f32), String> {
    let options = ArrayMetadataOptions::default()
        .with_metadata_convert_version(zarrs::config::MetadataConvertVersion::V3);
    let ArrayMetadata::V3(metadata) = array.metadata_opt(&options) else {
        return Err("its metadata does not convert to Zarr v3".into());
    };
    let ArrayMetadataV3 {
        data_type, codecs, ..
    } = metadata;
    let name = serde_json::to_value(&data_type).map_err(|e| e.to_string())?;
    let name = match &name {
        Value::String(name) => name.clone(),
        other => other
            .get("name")
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_string(),
    };
    let element = Element::named(&name)?;
    let codecs = serde_json::to_value(&codecs).map_err(|e| e.to_string())?;
    let codecs = codecs.as_array().cloned().unwrap_or_default();
    let chain = Codecs::parse(&codecs, array.shape().len(), element)?;
    let fill = array.fill_value().as_ne_bytes();
    let fill = match fill.len() == element.size() {
        true => element.value(fill, cfg!(target_endian = "big")),
        false => return Err(format!("a fill value of {} bytes for {name}", fill.len())),
    };
    Ok((chain, element, fill))
}

/// Refuses arrays whose frame would be more chunks (files), or inner chunks of shards, than a
/// frame may take: each costs a look-up or a decode even where nothing is stored.
fn check_chunk_counts(
    array: &Array<ContainedStore>,
    axes: &Axes,
    codecs: &Codecs,
    chunk_shape: &[u64],
) -> Result<(), String> {
    let grid = array.chunk_grid_shape();
    let files = axes
        .zyx
        .iter()
        .fold(1u64, |n, &a| n.saturating_mul(grid[a]));
    let inner = files.saturating_mul(codecs.stored_pieces(chunk_shape));
    if files > MAX_CHUNKS_PER_FRAME || inner > MAX_INNER_CHUNKS_PER_FRAME {
        return Err(format!(
            "chunks of {chunk_shape:?}: a frame is {files} chunks ({inner} inner chunks), over the \
             {MAX_CHUNKS_PER_FRAME} ({MAX_INNER_CHUNKS_PER_FRAME}) meshflow reads a frame in"
        ));
    }
    Ok(())
}

impl Axes {
    fn count(&self) -> usize {
        3 + usize::from(self.t.is_some()) + usize::from(self.c.is_some())
    }
}

/// `multiscales[0]` of the image's attributes (NGFF 0.5 under `ome`, 0.4 at the top), read
/// through the image's `store`.
fn multiscale(path: &Path, store: &ContainedStore) -> Result<Value, Error> {
    let read = |name: &str| -> Result<Option<Value>, Error> {
        let Some(bytes) = store.read(name)? else {
            return Ok(None);
        };
        let json = serde_json::from_slice(&bytes)
            .map_err(|e| IoError::format(store.file_of(name), format!("not JSON: {e}")))?;
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

/// The translation of `dataset` along x, y, z (the multiscale's transformations applied after
/// the dataset's), and what the metadata says of the voxel size for
/// [`super::read`]'s choice of the voxel size: found (with a report naming the image, level
/// and array), absent (no `scale`: the caller's `--voxel-size`, else 1 × 1 × 1 with a warning),
/// or not understood (an `affine`, `rotation` or other transformation meshflow does not apply,
/// a scale that is no positive size: an error unless `--voxel-size` is given).
fn placement(
    multiscale: &Value,
    dataset: &Value,
    axes: &Axes,
    path: &Path,
    level: usize,
    array_path: &str,
) -> (Vector3<f64>, Metadata) {
    match transformations(multiscale, dataset, axes) {
        Err(why) => (Vector3::zeros(), Metadata::Invalid(why)),
        Ok(None) => (Vector3::zeros(), Metadata::None),
        Ok(Some((voxel_size, translation))) => {
            let unit = (multiscale.get("axes").and_then(|a| a.get(axes.zyx[2])))
                .and_then(|a| a.get("unit"))
                .and_then(Value::as_str)
                .map(|u| format!(" {}", u.chars().take(40).collect::<String>().escape_debug()))
                .unwrap_or_default();
            let said = format!(
                "OME-Zarr metadata of {} (level {level}, {array_path}): {} × {} × {}{unit}",
                path.display(),
                format_number(voxel_size.x),
                format_number(voxel_size.y),
                format_number(voxel_size.z),
            );
            (translation, Metadata::Said(voxel_size, said))
        }
    }
}

/// A voxel size and the position of voxel `(0, 0, 0)`, along x, y, z.
type VoxelPlacement = (Vector3<f64>, Vector3<f64>);

/// The voxel size and translation along x, y, z that `dataset`'s and then `multiscale`'s
/// coordinate transformations give; `None` where neither has a `scale`.
fn transformations(
    multiscale: &Value,
    dataset: &Value,
    axes: &Axes,
) -> Result<Option<VoxelPlacement>, String> {
    let n = axes.count();
    let (mut scale, mut translation) = (vec![1.0; n], vec![0.0; n]);
    let mut scaled = false;
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
                    scaled = true;
                }
                Some("translation") => {
                    let t = numbers("translation")?;
                    (0..n).for_each(|a| translation[a] += t[a]);
                }
                Some("identity") => {}
                other => {
                    return Err(format!(
                        "a coordinate transformation of type {}, which meshflow does not apply \
                         (it reads scale and translation; give --voxel-size and --origin)",
                        quoted(other.unwrap_or("(none)"))
                    ))
                }
            }
        }
    }
    if !scaled {
        return Ok(None);
    }
    let [z, y, x] = axes.zyx;
    let voxel_size = Vector3::new(scale[x], scale[y], scale[z]);
    let translation = Vector3::new(translation[x], translation[y], translation[z]);
    if !voxel_size.iter().all(|d| d.is_normal() && *d > 0.0) {
        return Err(format!(
            "its scale gives the voxel size {voxel_size:?}: not positive"
        ));
    }
    if !translation.iter().all(|t| t.is_finite()) {
        return Err(format!("its translation {translation:?} is not finite"));
    }
    Ok(Some((voxel_size, translation)))
}
