//! Reading volumes: NPY arrays of shape `(Z, Y, X)` (one frame) or `(K, Z, Y, X)` (K frames),
//! multi-page TIFF stacks (pages = z, one frame per file), and directories or globs of either
//! (natural order, one frame per file). Values become `f32`.
//!
//! TIFF is read with the `tiff` crate (image-rs, pure Rust): grey u8, u16, u32, f32 and f64
//! samples, one strip or tile layout as the file has it. The voxel size comes from, in this
//! order: the caller (`--voxel-size`), ImageJ's metadata in the first file (`spacing=` in the
//! ImageDescription for z, `XResolution`/`YResolution` in pixels per unit for x and y), or
//! `1 × 1 × 1`, which [`VoxelSizeSource::Default`] reports so the caller can warn.

use super::{Volume, VolumeError};
use crate::io::{frame_files, read_npy_f32, IoError};
use crate::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use tiff::decoder::ifd::Value;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;
use tiff::ColorType;

/// Where volumes are in space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VolumeOptions {
    /// `(d_x, d_y, d_z)`; `None`: from the files' metadata, else `1 × 1 × 1`.
    pub voxel_size: Option<Vector3<f64>>,
    /// The centre of voxel `(0, 0, 0)`.
    pub origin: Vector3<f64>,
}

/// Where the voxel size of [`VolumeFrames`] came from.
#[derive(Clone, Debug, PartialEq)]
pub enum VoxelSizeSource {
    /// Given by the caller.
    Given,
    /// Read from a file's metadata: which file and what it said.
    File(String),
    /// Neither given nor found: `1 × 1 × 1`.
    Default,
}

/// The frames of a recording, one volume each, all of one shape and voxel size.
#[derive(Clone, Debug)]
pub struct VolumeFrames {
    pub volumes: Vec<Volume>,
    pub voxel_size_source: VoxelSizeSource,
    /// The file of each frame.
    pub files: Vec<PathBuf>,
}

/// Reads the volumes that `path` names (module docs): a `.npy` (one frame `(Z, Y, X)` or
/// `(K, Z, Y, X)`), a `.tif`/`.tiff` stack, or a directory or glob of such files. Every error
/// names the file.
pub fn read_volumes(path: &Path, options: &VolumeOptions) -> Result<VolumeFrames, Error> {
    let files = frame_files(path, is_volume_file, "volumes (.npy, .tif, .tiff)")?;
    let mut stacks = Vec::new();
    for file in &files {
        let in_file = |e: VolumeError| Error::from(e).in_file(file);
        for stack in read_file(file)? {
            stacks.push((file.clone(), stack));
        }
        if let Some(voxel_size) = options.voxel_size {
            super::check_voxel_size(&voxel_size).map_err(in_file)?;
        }
    }
    let (voxel_size, voxel_size_source) = match (options.voxel_size, &stacks[0].1.metadata) {
        (Some(size), _) => (size, VoxelSizeSource::Given),
        (None, Some((size, said))) => (*size, VoxelSizeSource::File(said.clone())),
        (None, None) => (Vector3::repeat(1.0), VoxelSizeSource::Default),
    };
    let expected = stacks[0].1.shape;
    let mut volumes = Vec::with_capacity(stacks.len());
    let mut frame_files = Vec::with_capacity(stacks.len());
    for (frame, (file, stack)) in stacks.into_iter().enumerate() {
        if stack.shape != expected {
            let error = VolumeError::FrameShape {
                frame,
                file: file.clone(),
                expected,
                got: stack.shape,
            };
            return Err(Error::from(error).in_file(path));
        }
        let volume = Volume::new(stack.shape, stack.values, voxel_size, options.origin)
            .map_err(|e| Error::from(e).in_file(&file))?;
        volumes.push(volume);
        frame_files.push(file);
    }
    Ok(VolumeFrames {
        volumes,
        voxel_size_source,
        files: frame_files,
    })
}

fn is_volume_file(path: &Path) -> bool {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(extension.as_deref(), Some("npy" | "tif" | "tiff"))
}

/// One frame's values as read, before it is placed in space.
struct Stack {
    shape: [usize; 3],
    values: Vec<f32>,
    /// The voxel size the file states, with a description for the user.
    metadata: Option<(Vector3<f64>, String)>,
}

/// The frames of one file (several for a `(K, Z, Y, X)` NPY).
fn read_file(file: &Path) -> Result<Vec<Stack>, Error> {
    let is_npy = file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    match is_npy {
        true => Ok(read_npy_stacks(file)?),
        false => Ok(vec![read_tiff(file)?]),
    }
}

fn read_npy_stacks(file: &Path) -> Result<Vec<Stack>, IoError> {
    let (shape, values) = read_npy_f32(file)?;
    let dims: Vec<usize> = shape.iter().map(|&n| n as usize).collect();
    let (frames, shape) = match dims[..] {
        [z, y, x] => (1, [z, y, x]),
        [k, z, y, x] => (k, [z, y, x]),
        _ => {
            return Err(IoError::format(
                file,
                format!("shape {shape:?}: a volume is (Z, Y, X), or (K, Z, Y, X) for K frames"),
            ))
        }
    };
    let per_frame = shape.iter().product::<usize>();
    Ok((0..frames)
        .map(|k| Stack {
            shape,
            values: values[k * per_frame..][..per_frame].to_vec(),
            metadata: None,
        })
        .collect())
}

/// A multi-page grey TIFF: pages are z slices, all of one size.
fn read_tiff(file: &Path) -> Result<Stack, IoError> {
    let bad = |e: tiff::TiffError| IoError::format(file, format!("not a readable TIFF ({e})"));
    let reader = std::fs::File::open(file).map_err(|e| IoError::file(file, e))?;
    let mut decoder = Decoder::new(std::io::BufReader::new(reader)).map_err(bad)?;
    let metadata = imagej_voxel_size(&mut decoder);
    let (width, height) = decoder.dimensions().map_err(bad)?;
    let mut values = Vec::new();
    let mut pages = 0;
    loop {
        let size = decoder.dimensions().map_err(bad)?;
        if size != (width, height) {
            return Err(IoError::format(
                file,
                format!(
                    "page {pages} is {} × {} pixels, page 0 is {width} × {height}: a stack's pages must be of one size",
                    size.0, size.1
                ),
            ));
        }
        match decoder.colortype().map_err(bad)? {
            ColorType::Gray(_) => {}
            other => {
                return Err(IoError::format(
                    file,
                    format!(
                        "page {pages} is {other:?}: a volume must be grey (one sample per pixel)"
                    ),
                ))
            }
        }
        values.extend(page_values(decoder.read_image().map_err(bad)?, file)?);
        pages += 1;
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().map_err(bad)?;
    }
    let shape = [pages, height as usize, width as usize];
    let description = metadata.map(|size| {
        let said = format!(
            "ImageJ metadata of {}: {} × {} × {}",
            file.display(),
            size.x,
            size.y,
            size.z
        );
        (size, said)
    });
    Ok(Stack {
        shape,
        values,
        metadata: description,
    })
}

fn page_values(page: DecodingResult, file: &Path) -> Result<Vec<f32>, IoError> {
    let widen = |values: Vec<f64>| values.into_iter().map(|v| v as f32).collect();
    Ok(match page {
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U32(v) => widen(v.into_iter().map(f64::from).collect()),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => widen(v),
        _ => {
            return Err(IoError::format(
                file,
                "sample type not supported (u8, u16, u32, f32 or f64 grey)",
            ))
        }
    })
}

/// `(d_x, d_y, d_z)` from ImageJ's metadata: `1 / XResolution`, `1 / YResolution` (pixels per
/// unit) and `spacing=` of the ImageDescription; `None` unless all three are there.
fn imagej_voxel_size<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
) -> Option<Vector3<f64>> {
    let description = decoder.get_tag_ascii_string(Tag::ImageDescription).ok()?;
    if !description.starts_with("ImageJ") {
        return None;
    }
    let spacing: f64 = description
        .lines()
        .find_map(|line| line.strip_prefix("spacing="))?
        .trim()
        .parse()
        .ok()?;
    let x = 1.0 / rational(decoder, Tag::XResolution)?;
    let y = 1.0 / rational(decoder, Tag::YResolution)?;
    let size = Vector3::new(x, y, spacing);
    size.iter()
        .all(|d| d.is_finite() && *d > 0.0)
        .then_some(size)
}

/// A RATIONAL tag as a number (`get_tag_f64` refuses rationals, the type TIFF resolutions
/// have).
fn rational<R: std::io::Read + std::io::Seek>(decoder: &mut Decoder<R>, tag: Tag) -> Option<f64> {
    match decoder.get_tag(tag).ok()? {
        Value::Rational(n, d) => Some(n as f64 / d as f64),
        Value::SRational(n, d) => Some(n as f64 / d as f64),
        Value::Float(v) => Some(v as f64),
        Value::Double(v) => Some(v),
        _ => None,
    }
}
