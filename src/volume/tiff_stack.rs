//! Multi-page grey TIFF stacks, read with the `tiff` crate under the memory limit: a plain
//! stack is one frame, a page per slice; an ImageJ hyperstack (`frames=`, `slices=`,
//! `channels=` in its ImageDescription, as Fiji and tifffile write 4-D and 5-D recordings)
//! holds its frames in `TZC` page order, and one frame of one channel is read page by page,
//! the others' pages never decoded.
//!
//! A TIFF is a list of page directories that may all point at one small compressed strip: a
//! 73 kB file can declare 64 pages of 8192² pixels, 4.3 GB once inflated. So the pages are
//! walked first, without decoding, and the caller checks what it will hold (a frame, or all
//! of them) against the memory limit ([`crate::limits`]); the decoder's own [`Limits`] bound
//! each page's buffer and so the inflation of its strips. Every error names the file and,
//! where there is one, the page.

use super::read::Metadata;
use crate::format::IoError;
use crate::limits;
use nalgebra::Vector3;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use tiff::decoder::ifd::Value;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

type TiffDecoder = Decoder<BufReader<File>>;

/// The pages of a stack as its directories declare them, and how ImageJ's hyperstack
/// metadata orders them: `frames × slices × channels` pages, the channel changing fastest
/// (ImageJ's and tifffile's `TZCYX`). A file without that metadata is one frame of one
/// channel, a slice per page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Layout {
    pub pages: usize,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub slices: usize,
    pub channels: usize,
}

impl Layout {
    fn values_per_page(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The page of `slice` in `frame` for `channel`.
    fn page(&self, frame: usize, slice: usize, channel: usize) -> usize {
        (frame * self.slices + slice) * self.channels + channel
    }
}

/// The pages of `file`, walked without decoding, each page's buffer checked against the
/// memory limit (what a frame or the whole file takes is the caller's to check).
pub(super) fn layout(file: &Path) -> Result<Layout, IoError> {
    let mut decoder = open(file)?;
    let hyperstack = imagej_hyperstack(&mut decoder).map_err(|why| IoError::format(file, why))?;
    let mut layout = walk(&mut decoder, file)?;
    let Some([frames, slices, channels]) = hyperstack else {
        return Ok(layout);
    };
    let declared = frames.saturating_mul(slices).saturating_mul(channels);
    if declared != layout.pages {
        return Err(IoError::format(
            file,
            format!(
                "its ImageJ metadata declares {frames} frames × {slices} slices × {channels} channels = {declared} pages, the file has {}",
                layout.pages
            ),
        ));
    }
    (layout.frames, layout.slices, layout.channels) = (frames, slices, channels);
    Ok(layout)
}

/// An open stack whose frames are read one at a time: the decoder keeps the page offsets it
/// has walked, so a frame late in a long hyperstack is not found by walking from page 0.
pub(super) struct StackReader {
    decoder: TiffDecoder,
    /// The file's ImageJ voxel-size metadata.
    pub metadata: Metadata,
}

impl StackReader {
    pub fn open(file: &Path) -> Result<Self, IoError> {
        let mut decoder = open(file)?;
        let metadata = imagej_voxel_size(&mut decoder);
        Ok(Self { decoder, metadata })
    }

    /// Frame `frame` of channel `channel` of `file` as `layout` declared it (values `f32`,
    /// C order: slice, row, column), read page by page.
    pub fn read_frame(
        &mut self,
        file: &Path,
        layout: &Layout,
        frame: usize,
        channel: usize,
    ) -> Result<Vec<f32>, IoError> {
        let decoder = &mut self.decoder;
        let mut values = Vec::with_capacity(layout.slices * layout.values_per_page());
        for slice in 0..layout.slices {
            let page = layout.page(frame, slice, channel);
            decoder
                .seek_to_image(page)
                .map_err(|e| unreadable(file, Some(page), e))?;
            check_page(decoder, file, page, layout)?;
            let decoded = decoder
                .read_image()
                .map_err(|e| unreadable(file, Some(page), e))?;
            append_values(decoded, layout, &mut values)
                .map_err(|message| IoError::format(file, format!("page {page}: {message}")))?;
        }
        Ok(values)
    }
}

/// `[frames, slices, channels]` from an ImageJ ImageDescription that names frames or
/// channels (each absent one is 1); `None` for any other file, a plain stack. A count that is
/// there but not a positive whole number (`frames=0`, `frames=-3`) is an error: dropped, it
/// would make the file another stack than its metadata says.
fn imagej_hyperstack(decoder: &mut TiffDecoder) -> Result<Option<[usize; 3]>, String> {
    let Ok(description) = decoder.get_tag_ascii_string(Tag::ImageDescription) else {
        return Ok(None);
    };
    if !description.starts_with("ImageJ") {
        return Ok(None);
    }
    let count = |key: &str| -> Result<Option<usize>, String> {
        let Some(said) =
            (description.lines()).find_map(|line| line.strip_prefix(key)?.strip_prefix('='))
        else {
            return Ok(None);
        };
        match said.trim().parse::<usize>() {
            Ok(n) if n > 0 => Ok(Some(n)),
            _ => Err(format!(
                "its ImageJ metadata says {key}={}: not a positive count",
                crate::format::quoted(said.trim())
            )),
        }
    };
    let (frames, channels) = (count("frames")?, count("channels")?);
    if frames.is_none() && channels.is_none() {
        return Ok(None);
    }
    Ok(Some([
        frames.unwrap_or(1),
        count("slices")?.unwrap_or(1),
        channels.unwrap_or(1),
    ]))
}

/// A decoder whose buffers stay within the memory limit.
fn open(file: &Path) -> Result<TiffDecoder, IoError> {
    check_entry_counts(file)?;
    let reader = File::open(file).map_err(|e| IoError::file(file, e))?;
    let length = reader.metadata().map_err(|e| IoError::file(file, e))?.len();
    let to_usize = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
    // A page's buffer within the memory limit; compressed data and tag values no longer than
    // the file that holds them.
    let mut limits = Limits::default();
    limits.decoding_buffer_size = to_usize(limits::memory_limit());
    limits.intermediate_buffer_size = to_usize(length);
    limits.ifd_value_size = limits.ifd_value_size.min(to_usize(length));
    let decoder = Decoder::new(BufReader::new(reader)).map_err(|e| unreadable(file, None, e))?;
    Ok(decoder.with_limits(limits))
}

/// Refuses a directory entry that declares more values than the file holds: the `tiff` crate
/// allocates an entry's values by its declared count before it checks its limits (one flipped
/// count byte in a 268-byte file took 268 MB). Walks the raw page directories, classic and
/// BigTIFF; what it cannot read it leaves to the decoder to report.
fn check_entry_counts(file: &Path) -> Result<(), IoError> {
    let Some(mut reader) = RawTiff::open(file).map_err(|e| IoError::file(file, e))? else {
        return Ok(());
    };
    let mut seen = std::collections::HashSet::new();
    let mut page = 0;
    while let Some(offset) = reader.next.filter(|&o| o != 0 && seen.insert(o)) {
        match reader.largest_entry(offset) {
            Ok(bytes) if bytes > reader.length => {
                return Err(IoError::format(
                    file,
                    format!(
                    "page {page}: a tag declares {bytes} bytes of values, more than the file's {}",
                    reader.length
                ),
                ))
            }
            Ok(_) => page += 1,
            Err(_) => return Ok(()),
        }
    }
    Ok(())
}

/// The raw directory chain of a TIFF file.
struct RawTiff {
    reader: BufReader<File>,
    length: u64,
    little: bool,
    big: bool,
    /// The next directory's offset.
    next: Option<u64>,
}

impl RawTiff {
    /// `None` where the header is not a TIFF's (the decoder reports it).
    fn open(file: &Path) -> std::io::Result<Option<Self>> {
        use std::io::Read;
        let file = File::open(file)?;
        let length = file.metadata()?.len();
        let mut reader = BufReader::new(file);
        let mut header = [0u8; 4];
        if reader.read_exact(&mut header).is_err() {
            return Ok(None);
        }
        let little = header[..2] == *b"II";
        let version = match little {
            true => u16::from_le_bytes([header[2], header[3]]),
            false => u16::from_be_bytes([header[2], header[3]]),
        };
        let mut raw = Self {
            reader,
            length,
            little,
            big: version == 43,
            next: None,
        };
        if raw.big {
            raw.read_uint(4)?; // offset size and padding
        }
        raw.next = raw.read_offset().ok();
        Ok(Some(raw))
    }

    fn read_uint(&mut self, bytes: usize) -> std::io::Result<u64> {
        use std::io::Read;
        let mut buffer = [0u8; 8];
        self.reader.read_exact(&mut buffer[..bytes])?;
        let value = match self.little {
            true => buffer[..bytes]
                .iter()
                .rev()
                .fold(0u64, |v, &b| v << 8 | b as u64),
            false => buffer[..bytes].iter().fold(0u64, |v, &b| v << 8 | b as u64),
        };
        Ok(value)
    }

    fn read_offset(&mut self) -> std::io::Result<u64> {
        self.read_uint(if self.big { 8 } else { 4 })
    }

    /// The most bytes of values any entry of the directory at `offset` declares; moves on to
    /// the next directory.
    fn largest_entry(&mut self, offset: u64) -> std::io::Result<u64> {
        use std::io::{Seek, SeekFrom};
        self.reader.seek(SeekFrom::Start(offset))?;
        let entries = self.read_uint(if self.big { 8 } else { 2 })?;
        let mut largest = 0u64;
        for _ in 0..entries.min(self.length) {
            self.read_uint(2)?; // tag
            let item = match self.read_uint(2)? {
                3 | 8 => 2,
                4 | 9 | 11 | 13 => 4,
                5 | 10 | 12 | 16 | 17 | 18 => 8,
                _ => 1,
            };
            let count = self.read_offset()?;
            self.read_offset()?; // value or its offset
            largest = largest.max(count.saturating_mul(item));
        }
        self.next = Some(self.read_offset()?);
        Ok(largest)
    }
}

fn unreadable(file: &Path, page: Option<usize>, e: tiff::TiffError) -> IoError {
    let message = match page {
        Some(page) => format!("page {page}: not a readable TIFF page ({e})"),
        None => format!("not a readable TIFF ({e})"),
    };
    IoError::format(file, message)
}

/// Walks every page directory (the decoder left at the last one): one size, grey samples of
/// a supported width, each page's decoding within the memory limit.
fn walk(decoder: &mut TiffDecoder, file: &Path) -> Result<Layout, IoError> {
    let (width, height) = decoder
        .dimensions()
        .map_err(|e| unreadable(file, Some(0), e))?;
    let mut layout = Layout {
        pages: 0,
        width,
        height,
        frames: 1,
        slices: 0,
        channels: 1,
    };
    loop {
        let sample_bytes = check_page(decoder, file, layout.pages, &layout)?;
        layout.pages += 1;
        layout.slices = layout.pages;
        // One page decoded at its own sample width (twice: the decoder may stage a strip's
        // samples before they reach the page) and its f32 values.
        let bytes = (4 + 2 * sample_bytes).saturating_mul(layout.values_per_page() as u64);
        let what = format!("a page of {width} × {height} pixels");
        limits::check_declared(what, bytes).map_err(|e| IoError::too_large(file, e))?;
        if !decoder.more_images() {
            return Ok(layout);
        }
        decoder
            .next_image()
            .map_err(|e| unreadable(file, Some(layout.pages), e))?;
    }
}

/// Page `page` (the decoder's current one): of the first page's size, grey, and of a sample
/// width the reader converts, which it returns in bytes.
fn check_page(
    decoder: &mut TiffDecoder,
    file: &Path,
    page: usize,
    layout: &Layout,
) -> Result<u64, IoError> {
    let bad = |message: String| IoError::format(file, format!("page {page}: {message}"));
    let (width, height) = decoder
        .dimensions()
        .map_err(|e| unreadable(file, Some(page), e))?;
    if (width, height) != (layout.width, layout.height) || width == 0 || height == 0 {
        return Err(bad(format!(
            "{width} × {height} pixels, page 0 is {} × {}: a stack's pages must be of one, non-zero size",
            layout.width, layout.height
        )));
    }
    match decoder
        .colortype()
        .map_err(|e| unreadable(file, Some(page), e))?
    {
        ColorType::Gray(bits @ (8 | 16 | 32 | 64)) => Ok(u64::from(bits / 8)),
        ColorType::Gray(bits) => Err(bad(format!(
            "{bits}-bit samples are not supported (grey samples of 8, 16, 32 or 64 bits)"
        ))),
        other => Err(bad(format!(
            "{other:?}: a volume must be grey (one sample per pixel)"
        ))),
    }
}

/// Appends a decoded page's values as `f32`; a float64 value that does not fit single
/// precision is an error naming its pixel.
fn append_values(
    page: DecodingResult,
    layout: &Layout,
    values: &mut Vec<f32>,
) -> Result<(), String> {
    let start = values.len();
    match page {
        DecodingResult::U8(v) => values.extend(v.into_iter().map(f32::from)),
        DecodingResult::U16(v) => values.extend(v.into_iter().map(f32::from)),
        DecodingResult::U32(v) => values.extend(v.into_iter().map(|x| x as f32)),
        DecodingResult::U64(v) => values.extend(v.into_iter().map(|x| x as f32)),
        DecodingResult::I8(v) => values.extend(v.into_iter().map(f32::from)),
        DecodingResult::I16(v) => values.extend(v.into_iter().map(f32::from)),
        DecodingResult::I32(v) => values.extend(v.into_iter().map(|x| x as f32)),
        DecodingResult::I64(v) => values.extend(v.into_iter().map(|x| x as f32)),
        DecodingResult::F32(v) => values.extend(v),
        DecodingResult::F64(v) => extend_narrowed(&v, layout.width as usize, values)?,
        _ => return Err("16-bit float samples are not supported".into()),
    }
    let count = layout.values_per_page();
    match values.len() - start {
        got if got == count => Ok(()),
        got => Err(format!("{got} values decoded, {count} pixels declared")),
    }
}

/// float64 values narrowed to `f32`; one too large for it is named by its pixel.
fn extend_narrowed(page: &[f64], width: usize, values: &mut Vec<f32>) -> Result<(), String> {
    for (at, &v) in page.iter().enumerate() {
        let narrowed = v as f32;
        if v.is_finite() && !narrowed.is_finite() {
            let pixel = format!("pixel (y {}, x {})", at / width, at % width);
            return Err(super::does_not_fit_f32(v, &pixel));
        }
        values.push(narrowed);
    }
    Ok(())
}

/// `(d_x, d_y, d_z)` from ImageJ's metadata: `1 / XResolution`, `1 / YResolution` (pixels per
/// unit) and `spacing=` of the ImageDescription. Found only where all three are there; any of
/// them present but not a positive, normal number is [`Metadata::Invalid`], named by its tag.
fn imagej_voxel_size(decoder: &mut TiffDecoder) -> Metadata {
    let Ok(description) = decoder.get_tag_ascii_string(Tag::ImageDescription) else {
        return Metadata::None;
    };
    if !description.starts_with("ImageJ") {
        return Metadata::None;
    }
    let Some(spacing) = description
        .lines()
        .find_map(|line| line.strip_prefix("spacing="))
    else {
        return Metadata::None;
    };
    let z = spacing
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|d| super::is_length(*d));
    let Some(z) = z else {
        return Metadata::Invalid(format!(
            "spacing={spacing} in the ImageJ ImageDescription is not a positive number"
        ));
    };
    let x = resolution_voxel(decoder, Tag::XResolution, "XResolution");
    let y = resolution_voxel(decoder, Tag::YResolution, "YResolution");
    match (x, y) {
        (Err(why), _) | (_, Err(why)) => Metadata::Invalid(why),
        (Ok(Some(x)), Ok(Some(y))) => Metadata::Found(Vector3::new(x, y, z)),
        _ => Metadata::None,
    }
}

/// `1 / tag` (a resolution in pixels per unit) as a voxel side; `None` where the tag is
/// absent.
fn resolution_voxel(
    decoder: &mut TiffDecoder,
    tag: Tag,
    name: &str,
) -> Result<Option<f64>, String> {
    let (side, said) = match decoder.get_tag(tag) {
        Err(_) => return Ok(None),
        Ok(Value::Rational(n, d)) => (d as f64 / n as f64, format!("{n}/{d}")),
        Ok(Value::SRational(n, d)) => (d as f64 / n as f64, format!("{n}/{d}")),
        Ok(Value::Float(v)) => (1.0 / v as f64, v.to_string()),
        Ok(Value::Double(v)) => (1.0 / v, v.to_string()),
        Ok(other) => (f64::NAN, format!("{other:?}")),
    };
    match super::is_length(side) {
        true => Ok(Some(side)),
        false => Err(format!(
            "{name} {said} (pixels per unit) does not give a positive voxel size"
        )),
    }
}
