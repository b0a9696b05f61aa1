//! Reading volumes: NPY arrays of shape `(Z, Y, X)` (one frame) or `(K, Z, Y, X)` (K frames),
//! multi-page TIFF stacks (pages = z, one frame per file) and ImageJ hyperstacks (`frames=`
//! × `slices=` × `channels=` pages in one file, [`super::tiff_stack`]), OME-Zarr images
//! ([`super::ome_zarr`]), and directories or globs of NPY and TIFF files (natural order).
//! Values become `f32`.
//!
//! [`VolumeStream`] reads a recording one frame at a time, so that one longer than memory
//! streams through: a frame of a `(K, Z, Y, X)` `.npy` is read from its rows (the others
//! skipped by seeking), a frame of a hyperstack from its pages, a frame of an OME-Zarr image
//! from its chunks. `.npy` files are read, not memory-mapped: a mapped file that another
//! process truncates faults the reader (SIGBUS) instead of giving an error, and the reads
//! convert each frame to `f32` anyway.
//!
//! TIFF is read with the `tiff` crate (image-rs, pure Rust): grey samples of 8 to 64 bits
//! (integers or floats), one strip or tile layout as the file has it. The voxel size comes
//! from, in this order: the caller (`--voxel-size`), ImageJ's metadata in the first file
//! (`spacing=` in the ImageDescription for z, `XResolution`/`YResolution` in pixels per unit
//! for x and y), or `1 × 1 × 1`, which [`VoxelSizeSource::Default`] reports so the caller can
//! warn. Metadata that is there but not a positive number is an error unless the caller gives
//! the voxel size ([`VoxelSizeSource::GivenOverInvalid`]).
//!
//! Files are hostile: before any values are read, every file's header or page directories are
//! read alone ([`count_volume_frames`]), so that a frame count, a shape or a size that the
//! memory limit ([`crate::limits`]) does not allow is an error before anything is allocated.

use super::ome_zarr::{is_ome_zarr, OmeZarr};
use super::tiff_stack::StackReader;
use super::{tiff_stack, Volume, VolumeError};
use crate::format::{
    format_number, frame_files, read_npy_f32, read_npy_f32_rows, read_npy_image_rows, IoError,
};
use crate::{limits, Error};
use nalgebra::Vector3;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

/// Where volumes are in space, and what of an OME-Zarr image is read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VolumeOptions {
    /// `(d_x, d_y, d_z)`; `None`: from the files' metadata, else `1 × 1 × 1`.
    pub voxel_size: Option<Vector3<f64>>,
    /// The centre of voxel `(0, 0, 0)` (added to an OME-Zarr image's own translation).
    pub origin: Vector3<f64>,
    /// OME-Zarr or an ImageJ hyperstack TIFF: the channel (`None`: 0).
    pub channel: Option<usize>,
    /// OME-Zarr: the resolution level (0: the finest).
    pub resolution_level: usize,
}

/// Where the voxel size of [`VolumeFrames`] came from.
#[derive(Clone, Debug, PartialEq)]
pub enum VoxelSizeSource {
    /// Given by the caller.
    Given,
    /// Given by the caller, in place of the first file's invalid metadata (what was wrong).
    GivenOverInvalid(String),
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

/// What a file's metadata says about the voxel size.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Metadata {
    None,
    Found(Vector3<f64>),
    /// Found, with its own report (an OME-Zarr image's scale and unit).
    Said(Vector3<f64>, String),
    /// There, but not a voxel size: which tag said what.
    Invalid(String),
}

/// Reads the volumes that `path` names (module docs): a `.npy` (one frame `(Z, Y, X)` or
/// `(K, Z, Y, X)`), a `.tif`/`.tiff` stack, or a directory or glob of such files. Every error
/// names the file.
pub fn read_volumes(path: &Path, options: &VolumeOptions) -> Result<VolumeFrames, Error> {
    if is_ome_zarr(path) {
        return read_ome_zarr(path, options);
    }
    check_options(path, options)?;
    let files = volume_files(path)?;
    let declared = declare_all(path, &files, Held::All, options.channel)?;
    let mut volumes = Vec::with_capacity(declared.iter().map(|d| d.frames).sum());
    let mut frame_files = Vec::with_capacity(volumes.capacity());
    // From the first file's metadata (or the caller).
    let mut chosen: Option<(Vector3<f64>, VoxelSizeSource)> = None;
    for (file, declared) in files.iter().zip(&declared) {
        let (stacks, metadata) = read_file(file, declared)?;
        if chosen.is_none() {
            chosen = Some(choose_voxel_size(options.voxel_size, metadata, file)?);
        }
        let voxel_size = chosen.as_ref().expect("chosen above").0;
        for values in stacks {
            let volume = Volume::new(declared.shape, values, voxel_size, options.origin)
                .map_err(|e| Error::from(e).in_file(file))?;
            volumes.push(volume);
            frame_files.push(file.clone());
        }
    }
    let (_, voxel_size_source) = chosen.expect("frame_files gives one file at least");
    Ok(VolumeFrames {
        volumes,
        voxel_size_source,
        files: frame_files,
    })
}

/// The frames of a recording read one at a time, as [`read_volumes`] reads them all: at most
/// one frame's values are held (a frame of a `(K, Z, Y, X)` `.npy` is read from its rows, the
/// others skipped on disk), so a recording longer than memory streams through. The voxel size
/// is chosen from the first file read ([`VolumeStream::voxel_size_source`]).
pub struct VolumeStream {
    /// What the caller named.
    path: PathBuf,
    options: VolumeOptions,
    files: Vec<PathBuf>,
    declared: Vec<Declared>,
    chosen: Option<(Vector3<f64>, VoxelSizeSource)>,
    /// The next frame: its file and its index in the file.
    file: usize,
    in_file: usize,
    /// An OME-Zarr image, the one "file".
    zarr: Option<OmeZarr>,
    /// The TIFF being read, open from one of its frames to the next.
    stack: Option<StackReader>,
    /// Of the frame read last (an OME-Zarr image's): how many of how many chunks were not
    /// stored, where some were not.
    missing: Option<(u64, u64)>,
}

impl VolumeStream {
    /// The volumes that `path` names (as [`read_volumes`]), their headers checked, one
    /// frame's size against the memory limit; nothing read yet.
    pub fn open(path: &Path, options: &VolumeOptions) -> Result<Self, Error> {
        if is_ome_zarr(path) {
            if let Some(voxel_size) = options.voxel_size {
                super::check_voxel_size(&voxel_size).map_err(|e| Error::from(e).in_file(path))?;
            }
            let image = OmeZarr::open(path, options.channel, options.resolution_level)?;
            let declared = Declared {
                frames: image.n_frames(),
                shape: image.shape(),
                float64: false,
                tiff: None,
            };
            return Ok(Self {
                path: path.to_path_buf(),
                options: options.clone(),
                files: vec![path.to_path_buf()],
                declared: vec![declared],
                chosen: None,
                file: 0,
                in_file: 0,
                zarr: Some(image),
                stack: None,
                missing: None,
            });
        }
        check_options(path, options)?;
        let files = volume_files(path)?;
        let declared = declare_all(path, &files, Held::One, options.channel)?;
        Ok(Self {
            path: path.to_path_buf(),
            options: options.clone(),
            files,
            declared,
            chosen: None,
            file: 0,
            in_file: 0,
            zarr: None,
            stack: None,
            missing: None,
        })
    }

    pub fn n_frames(&self) -> usize {
        self.declared.iter().map(|d| d.frames).sum()
    }

    /// `(n_z, n_y, n_x)` of every frame.
    pub fn shape(&self) -> [usize; 3] {
        self.declared[0].shape
    }

    /// The voxel size used, once the first frame has been read.
    pub fn voxel_size(&self) -> Option<Vector3<f64>> {
        self.chosen.as_ref().map(|(size, _)| *size)
    }

    /// The centre of voxel `(0, 0, 0)`: the caller's origin, plus an OME-Zarr image's own
    /// translation.
    pub fn origin(&self) -> Option<Vector3<f64>> {
        let shift = self
            .zarr
            .as_ref()
            .map_or(Vector3::zeros(), |i| i.translation);
        self.chosen.as_ref().map(|_| self.options.origin + shift)
    }

    /// The path it was opened on.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Of the frame read last: how many of its chunks were not stored and read as the fill
    /// value, and how many it has, where some were not (an OME-Zarr image written without
    /// its empty chunks, or a damaged one).
    pub fn missing_chunks(&self) -> Option<(u64, u64)> {
        self.missing
    }

    /// Where the voxel size came from, once the first frame has been read.
    pub fn voxel_size_source(&self) -> Option<&VoxelSizeSource> {
        self.chosen.as_ref().map(|(_, source)| source)
    }

    /// The next frame's volume and its file.
    fn read_next(&mut self) -> Result<(Volume, PathBuf), Error> {
        let (file, declared) = (&self.files[self.file], &self.declared[self.file]);
        let mut origin = self.options.origin;
        let (values, metadata) = match (&self.zarr, declared.frames) {
            (Some(image), _) => {
                let (values, pieces) = image.frame(self.in_file)?;
                self.missing = (pieces.missing > 0).then_some((pieces.missing, pieces.chunks));
                origin += image.translation;
                (values, image.metadata.clone())
            }
            (None, _) if declared.tiff.is_some() => {
                tiff_frame(file, declared, self.in_file, &mut self.stack)?
            }
            (None, 1) => {
                let (mut stacks, metadata) = read_file(file, declared)?;
                (stacks.pop().expect("one frame"), metadata)
            }
            (None, _) => (npy_frame(file, declared, self.in_file)?, Metadata::None),
        };
        if self.chosen.is_none() {
            self.chosen = Some(choose_voxel_size(self.options.voxel_size, metadata, file)?);
        }
        let voxel_size = self.chosen.as_ref().expect("chosen above").0;
        let volume = Volume::new(declared.shape, values, voxel_size, origin)
            .map_err(|e| Error::from(e).in_file(file))?;
        let file = file.clone();
        self.advance();
        Ok((volume, file))
    }

    /// Frames `wanted`, in that order, from a stream not read from yet: the frames held are
    /// checked against the memory limit first, each is read once (the others passed over
    /// unread, [`VolumeStream::skip_frame`]), and one asked twice is copied.
    pub fn read_frames(&mut self, wanted: &[usize]) -> Result<Vec<Volume>, Error> {
        let n_frames = self.n_frames();
        if let Some(&k) = wanted.iter().find(|&&k| k >= n_frames) {
            let message = format!("frame {k}: the recording has frames 0 … {}", n_frames - 1);
            return Err(IoError::format(&self.path, message).into());
        }
        if (self.file, self.in_file) != (0, 0) {
            let message = "frames are read from a stream not read from yet";
            return Err(IoError::format(&self.path, message).into());
        }
        let shape = self.shape();
        let frames = wanted.len() as u64;
        let voxels = frames.saturating_mul(shape.iter().product::<usize>() as u64);
        limits::check_declared(volume_frames(frames, shape), voxels.saturating_mul(4))
            .map_err(|e| IoError::too_large(&self.path, e))?;
        let mut order = wanted.to_vec();
        order.sort_unstable();
        order.dedup();
        let mut held: Vec<Option<Volume>> = Vec::with_capacity(order.len());
        let mut next = 0;
        for &k in &order {
            (next..k).for_each(|_| self.skip_frame());
            let read = self.next().expect("k < n_frames, read in order");
            held.push(Some(read?.0));
            next = k + 1;
        }
        // Each frame moves out at its last place in `wanted`, and is copied for any earlier.
        let mut out = Vec::with_capacity(wanted.len());
        for (at, k) in wanted.iter().enumerate() {
            let slot = &mut held[order.binary_search(k).expect("held")];
            let again = wanted[at + 1..].contains(k);
            out.push(match again {
                true => slot.clone().expect("not moved before its last use"),
                false => slot.take().expect("moved once"),
            });
        }
        Ok(out)
    }

    /// Passes over the next frame without reading it (nothing is decoded or held): a frame of
    /// a `(K, Z, Y, X)` `.npy`, a hyperstack or an OME-Zarr image is read by seeking.
    pub fn skip_frame(&mut self) {
        if self.file < self.files.len() {
            self.advance();
        }
    }

    fn advance(&mut self) {
        self.in_file += 1;
        if self.in_file == self.declared[self.file].frames {
            (self.file, self.in_file, self.stack) = (self.file + 1, 0, None);
        }
    }
}

impl Iterator for VolumeStream {
    type Item = Result<(Volume, PathBuf), Error>;

    fn next(&mut self) -> Option<Self::Item> {
        (self.file < self.files.len()).then(|| self.read_next())
    }
}

/// Frame `k` of a TIFF stack or hyperstack through `reader` (opened on the first frame read),
/// page by page, and the file's voxel-size metadata. Each page is checked against the
/// declared layout as it is read.
fn tiff_frame(
    file: &Path,
    declared: &Declared,
    k: usize,
    reader: &mut Option<StackReader>,
) -> Result<(Vec<f32>, Metadata), Error> {
    let (layout, channel) = declared.tiff.as_ref().expect("a TIFF");
    let reader = match reader {
        Some(reader) => reader,
        None => reader.insert(StackReader::open(file)?),
    };
    let values = reader.read_frame(file, layout, k, *channel)?;
    Ok((values, reader.metadata.clone()))
}

/// Frame `k` of a `(K, Z, Y, X)` `.npy`, its other rows skipped on disk.
fn npy_frame(file: &Path, declared: &Declared, k: usize) -> Result<Vec<f32>, Error> {
    let (shape, values) = read_npy_f32_rows(file, &|row| row == k)?;
    let [z, y, x] = declared.shape;
    if shape != [1, z as u64, y as u64, x as u64] {
        return Err(IoError::format(file, "changed while it was read").into());
    }
    if declared.float64 {
        let whole = [declared.frames as u64, z as u64, y as u64, x as u64];
        check_narrowed(file, &whole, &values, k)?;
    }
    Ok(values)
}

/// The number of frames that `path` holds (as [`read_volumes`] would read them), from the
/// files' headers and page directories alone: checked before the volumes are streamed
/// ([`VolumeStream`]), so one frame at a time is what must fit the memory limit.
pub fn count_volume_frames(path: &Path) -> Result<usize, Error> {
    if is_ome_zarr(path) {
        return Ok(OmeZarr::open(path, None, 0)?.n_frames());
    }
    let files = volume_files(path)?;
    Ok(declare_all(path, &files, Held::One, None)?
        .iter()
        .map(|d| d.frames)
        .sum())
}

/// An OME-Zarr image's frames, all held: each frame's size was checked when the image was
/// opened, all of them here.
fn read_ome_zarr(path: &Path, options: &VolumeOptions) -> Result<VolumeFrames, Error> {
    let mut stream = VolumeStream::open(path, options)?;
    let all: Vec<usize> = (0..stream.n_frames()).collect();
    let volumes = stream.read_frames(&all)?;
    Ok(VolumeFrames {
        files: vec![path.to_path_buf(); volumes.len()],
        volumes,
        voxel_size_source: stream
            .voxel_size_source()
            .cloned()
            .unwrap_or(VoxelSizeSource::Given),
    })
}

/// "1 volume frame of 3 × 4 × 5 voxels", "2 volume frames of …".
fn volume_frames(frames: u64, [z, y, x]: [usize; 3]) -> String {
    let plural = if frames == 1 { "" } else { "s" };
    format!("{frames} volume frame{plural} of {z} × {y} × {x} voxels")
}

/// The voxel size given, and no OME-Zarr options for other files.
fn check_options(path: &Path, options: &VolumeOptions) -> Result<(), Error> {
    if let Some(voxel_size) = options.voxel_size {
        super::check_voxel_size(&voxel_size).map_err(|e| Error::from(e).in_file(path))?;
    }
    if options.resolution_level > 0 {
        let message =
            "--resolution-level applies to OME-Zarr images (a directory with zarr.json or .zattrs)";
        return Err(IoError::format(path, message).into());
    }
    Ok(())
}

fn volume_files(path: &Path) -> Result<Vec<PathBuf>, IoError> {
    frame_files(path, is_volume_file, "volumes (.npy, .tif, .tiff)")
}

fn is_volume_file(path: &Path) -> bool {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(extension.as_deref(), Some("npy" | "tif" | "tiff"))
}

fn is_npy(file: &Path) -> bool {
    file.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// What a file declares in its header or page directories, before its values are read.
#[derive(Clone, Copy, Debug)]
struct Declared {
    frames: usize,
    /// `(n_z, n_y, n_x)` of each frame.
    shape: [usize; 3],
    /// float64 values, rounded to `f32` when read.
    float64: bool,
    /// A TIFF's pages, and the channel read.
    tiff: Option<(tiff_stack::Layout, usize)>,
}

/// How many frames a reader holds at once.
#[derive(Clone, Copy, PartialEq)]
enum Held {
    All,
    One,
}

/// What every file declares: at least one voxel a frame, one shape for all frames, and the
/// frames `held` at once within the memory limit.
fn declare_all(
    path: &Path,
    files: &[PathBuf],
    held: Held,
    channel: Option<usize>,
) -> Result<Vec<Declared>, Error> {
    let mut all: Vec<Declared> = Vec::with_capacity(files.len());
    let mut frames = 0u64;
    for file in files {
        let declared = declare(file, channel)?;
        if let Some(first) = all.first().filter(|first| first.shape != declared.shape) {
            let error = VolumeError::FrameShape {
                frame: frames as usize,
                file: file.clone(),
                expected: first.shape,
                got: declared.shape,
            };
            return Err(Error::from(error).in_file(path));
        }
        frames += declared.frames as u64;
        let frames = match held {
            Held::All => frames,
            Held::One => 1,
        };
        let [z, y, x] = declared.shape;
        let per_frame = [z, y, x]
            .iter()
            .fold(1u64, |n, &d| n.saturating_mul(d as u64));
        // The f32 values of the frames so far, and one frame read at up to 8 bytes a value
        // and split off its file's array; each frame's volume and file name besides.
        let bytes = (frames
            .saturating_add(3)
            .saturating_mul(per_frame.saturating_mul(4)))
        .saturating_add(frames.saturating_mul(FRAME_BYTES));
        let what = volume_frames(frames, [z, y, x]);
        limits::check_declared(what, bytes).map_err(|e| IoError::too_large(file, e))?;
        all.push(declared);
    }
    Ok(all)
}

/// What a frame takes besides its values: its [`Volume`], its file's name, their allocations.
const FRAME_BYTES: u64 =
    (std::mem::size_of::<Volume>() + std::mem::size_of::<PathBuf>() + 64) as u64;

fn declare(file: &Path, channel: Option<usize>) -> Result<Declared, IoError> {
    if is_npy(file) {
        if let Some(c) = channel {
            let message = format!("--channel {c}: an .npy volume has no channels (--channel applies to OME-Zarr images and ImageJ hyperstacks)");
            return Err(IoError::format(file, message));
        }
        let (shape, float64) = npy_header(file)?;
        let (frames, frame) = frames_of(file, &shape)?;
        return Ok(Declared {
            frames,
            shape: frame,
            float64,
            tiff: None,
        });
    }
    let layout = tiff_stack::layout(file)?;
    if let Some(c) = channel.filter(|&c| c >= layout.channels) {
        let message = match layout.channels {
            1 => format!("--channel {c}: the stack has one channel (no ImageJ hyperstack metadata naming more)"),
            n => format!("--channel {c}: the hyperstack has channels 0 … {}", n - 1),
        };
        return Err(IoError::format(file, message));
    }
    Ok(Declared {
        frames: layout.frames,
        shape: [layout.slices, layout.height as usize, layout.width as usize],
        float64: false,
        tiff: Some((layout, channel.unwrap_or(0))),
    })
}

/// `(frames, (Z, Y, X))` of an NPY shape: `(Z, Y, X)` or `(K, Z, Y, X)`, every axis non-zero.
fn frames_of(file: &Path, shape: &[u64]) -> Result<(usize, [usize; 3]), IoError> {
    let bad = |why: &str| IoError::format(file, format!("shape {shape:?}: {why}"));
    let dims: Vec<usize> = shape
        .iter()
        .map(|&n| usize::try_from(n).map_err(|_| bad("too large")))
        .collect::<Result<_, _>>()?;
    let (frames, frame) = match dims[..] {
        [z, y, x] => (1, [z, y, x]),
        [k, z, y, x] => (k, [z, y, x]),
        _ => return Err(bad("a volume is (Z, Y, X), or (K, Z, Y, X) for K frames")),
    };
    match dims.contains(&0) {
        true => Err(bad("no voxels (every axis of a volume needs at least one)")),
        false => Ok((frames, frame)),
    }
}

/// The largest `.npy` header read: NumPy writes a few hundred bytes, and its own reader
/// refuses more than 10 kB; the length field could declare 4 GB.
const MAX_NPY_HEADER: u64 = 1 << 20;

/// The shape of an `.npy` and whether it holds float64, from its header alone (its length
/// checked before it is read).
fn npy_header(file: &Path) -> Result<(Vec<u64>, bool), IoError> {
    let bad = |why: String| IoError::format(file, format!("not a valid .npy file ({why})"));
    let mut reader =
        std::io::BufReader::new(std::fs::File::open(file).map_err(|e| IoError::file(file, e))?);
    let mut start = [0u8; 12];
    reader
        .read_exact(&mut start)
        .map_err(|e| bad(e.to_string()))?;
    let length = match start[6] {
        1 => u64::from(u16::from_le_bytes([start[8], start[9]])),
        _ => u64::from(u32::from_le_bytes([
            start[8], start[9], start[10], start[11],
        ])),
    };
    if length > MAX_NPY_HEADER {
        return Err(bad(format!("a header of {length} bytes")));
    }
    reader.rewind().map_err(|e| IoError::file(file, e))?;
    let header = npyz::NpyHeader::from_reader(reader).map_err(|e| bad(e.to_string()))?;
    let npy = npyz::NpyFile::with_header(header, std::io::empty());
    let float64 = matches!(npy.dtype(), npyz::DType::Plain(t)
        if t.type_char() == npyz::TypeChar::Float && t.size_field() == 8);
    Ok((npy.shape().to_vec(), float64))
}

/// The frames' values of one file and its voxel-size metadata.
fn read_file(file: &Path, declared: &Declared) -> Result<(Vec<Vec<f32>>, Metadata), Error> {
    if declared.tiff.is_some() {
        let (mut reader, mut metadata) = (None, Metadata::None);
        let mut frames = Vec::with_capacity(declared.frames);
        for k in 0..declared.frames {
            let (values, said) = tiff_frame(file, declared, k, &mut reader)?;
            frames.push(values);
            metadata = said;
        }
        return Ok((frames, metadata));
    }
    let (shape, values) = read_npy_f32(file)?;
    if frames_of(file, &shape)? != (declared.frames, declared.shape) {
        return Err(IoError::format(file, "changed while it was read").into());
    }
    if declared.float64 {
        check_narrowed(file, &shape, &values, 0)?;
    }
    Ok((split_frames(values, declared.frames), Metadata::None))
}

/// `values` cut into `frames` equal frames, each taken off the end so that no more than one
/// frame is held twice.
fn split_frames(mut values: Vec<f32>, frames: usize) -> Vec<Vec<f32>> {
    let per_frame = values.len() / frames;
    let mut split: Vec<Vec<f32>> = (1..frames)
        .rev()
        .map(|k| values.split_off(k * per_frame))
        .collect();
    values.shrink_to_fit();
    split.push(values);
    split.reverse();
    split
}

/// A float64 `.npy` of `shape` whose finite value became infinite in `f32`: the value and its
/// voxel, from the file's own row (read again, on this error only). `values` start at row
/// `first_row`.
fn check_narrowed(
    file: &Path,
    shape: &[u64],
    values: &[f32],
    first_row: usize,
) -> Result<(), IoError> {
    let Some(at) = values.iter().position(|v| v.is_infinite()) else {
        return Ok(());
    };
    let row_length: usize = shape[1..].iter().map(|&n| n as usize).product();
    let at = first_row * row_length + at;
    let row = at / row_length;
    let (original, _) = read_npy_image_rows(file, &|r| r == row)?;
    let value = original.data[at % row_length];
    if !value.is_finite() {
        return Ok(()); // a true infinity: Volume::new names it
    }
    let dims: Vec<usize> = shape.iter().map(|&n| n as usize).collect();
    Err(IoError::format(
        file,
        super::does_not_fit_f32(value, &voxel_name(at, &dims)),
    ))
}

/// "voxel (z 1, y 0, x 3)" or "frame 2, voxel (…)" of flat index `at` in an array of `dims`.
fn voxel_name(at: usize, dims: &[usize]) -> String {
    let [.., z, y, x] = dims[..] else {
        return format!("value {at}");
    };
    let per_frame = z * y * x;
    let (frame, at) = (at / per_frame, at % per_frame);
    let voxel = format!("voxel (z {}, y {}, x {})", at / (y * x), at / x % y, at % x);
    match dims.len() {
        4 => format!("frame {frame}, {voxel}"),
        _ => voxel,
    }
}

/// The voxel size and where it came from: given, else the first file's valid metadata, else
/// `1 × 1 × 1`; invalid metadata is an error naming the file unless a size is given.
fn choose_voxel_size(
    given: Option<Vector3<f64>>,
    metadata: Metadata,
    file: &Path,
) -> Result<(Vector3<f64>, VoxelSizeSource), Error> {
    Ok(match (given, metadata) {
        (Some(size), Metadata::Invalid(why)) => (size, VoxelSizeSource::GivenOverInvalid(why)),
        (Some(size), _) => (size, VoxelSizeSource::Given),
        (None, Metadata::Found(size)) => {
            let said = format!(
                "ImageJ metadata of {}: {} × {} × {}",
                file.display(),
                format_number(size.x),
                format_number(size.y),
                format_number(size.z)
            );
            (size, VoxelSizeSource::File(said))
        }
        (None, Metadata::Said(size, said)) => (size, VoxelSizeSource::File(said)),
        (None, Metadata::Invalid(why)) => {
            return Err(Error::from(VolumeError::Metadata(why)).in_file(file))
        }
        (None, Metadata::None) => (Vector3::repeat(1.0), VoxelSizeSource::Default),
    })
}
