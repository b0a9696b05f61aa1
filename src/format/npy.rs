//! NumPy `.npy` arrays through npyz: float64 (or float32) data, integer index arrays.

use super::{write_all_atomically, FileContents, IoError};
use crate::format::temporary_beside;
use npyz::WriterBuilder;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek};
use std::path::{Path, PathBuf};

/// A float64 array in C (row-major) order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<u64>,
    pub data: Vec<f64>,
}

/// Writes `data` (C order) as a little-endian `.npy` of the given shape (`f64` → float64,
/// `i64` → int64, …).
pub fn write_npy<T: npyz::AutoSerialize + Copy>(
    path: &Path,
    shape: &[u64],
    data: &[T],
) -> Result<(), IoError> {
    write_all_atomically(vec![(path, npy_contents(path, shape, data)?)])
}

/// What [`write_npy`] writes to `path`, for [`write_all_atomically`]: `data` in C order as an
/// array of `shape`, which must hold as many values.
pub fn npy_contents<'a, T: npyz::AutoSerialize + Copy>(
    path: &Path,
    shape: &'a [u64],
    data: &'a [T],
) -> Result<FileContents<'a>, IoError> {
    let expected: u64 = shape.iter().product();
    if expected != data.len() as u64 {
        return Err(IoError::format(
            path,
            format!(
                "shape {shape:?} needs {expected} values, got {}",
                data.len()
            ),
        ));
    }
    Ok(Box::new(move |w| {
        let mut writer = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(w)
            .begin_nd()?;
        writer.extend(data.iter().copied())?;
        writer.finish()
    }))
}

/// A float64 `.npy` of a known shape written in pieces (slab by slab as the slabs arrive), as
/// atomically as [`write_npy`]: it is filled beside `path` and appears there only when
/// [`NpyRows::finish`] has checked that every value of the shape came.
pub struct NpyRows {
    path: PathBuf,
    temporary: PathBuf,
    /// The temporary file itself, synced before the rename (`writer` owns a clone).
    file: File,
    writer: Option<npyz::NpyWriter<f64, BufWriter<File>>>,
}

impl NpyRows {
    pub fn create(path: &Path, shape: &[u64]) -> Result<Self, IoError> {
        let temporary = temporary_beside(path)?;
        let in_file = |source| IoError::file(path, source);
        let file = File::create(&temporary).map_err(in_file)?;
        let mut rows = Self {
            path: path.to_path_buf(),
            file: file.try_clone().map_err(in_file)?,
            temporary,
            writer: None,
        };
        let writer = (npyz::WriteOptions::new().default_dtype().shape(shape))
            .writer(BufWriter::new(file))
            .begin_nd()
            .map_err(in_file)?;
        rows.writer = Some(writer);
        Ok(rows)
    }

    /// Appends values in C order.
    pub fn extend(&mut self, values: impl IntoIterator<Item = f64>) -> Result<(), IoError> {
        let writer = self.writer.as_mut().expect("open until finished");
        writer
            .extend(values)
            .map_err(|source| IoError::file(&self.path, source))
    }

    /// Checks the count, syncs and renames the file onto its path.
    pub fn finish(mut self) -> Result<(), IoError> {
        let writer = self.writer.take().expect("finished once");
        (writer.finish())
            .and_then(|()| self.file.sync_all())
            .and_then(|()| std::fs::rename(&self.temporary, &self.path))
            .map_err(|source| IoError::file(&self.path, source))
    }
}

impl Drop for NpyRows {
    fn drop(&mut self) {
        // Unfinished or failed: nothing appears at the path.
        let _ = std::fs::remove_file(&self.temporary);
    }
}

/// Reads a float64 `.npy` file in C order (either byte order), checking that the header's shape
/// matches the data actually present before allocating for it.
pub fn read_npy(path: &Path) -> Result<NpyArray, IoError> {
    read_floats(path, &[8], "float64")
}

/// [`read_npy_float`] from a stream (read into memory within the memory limit); `name` stands
/// for it in errors.
pub fn read_npy_from(reader: impl Read, name: &Path) -> Result<NpyArray, IoError> {
    let bytes = super::read_stream(reader, name)?;
    let length = bytes.len() as u64;
    let cursor = std::io::Cursor::new(bytes);
    let file = npy_of(
        name,
        cursor,
        length,
        |t| is_float_of(t, &[4, 8]),
        "float32 or float64",
    )?;
    Ok(float_rows(name, file, &|_| true)?.0)
}

/// Reads a float32 or float64 `.npy` file like [`read_npy`]; float32 values are widened to
/// f64 exactly.
pub fn read_npy_float(path: &Path) -> Result<NpyArray, IoError> {
    read_floats(path, &[4, 8], "float32 or float64")
}

/// A float `.npy` whose item size (bytes) is one of `sizes`, described as `expected`.
fn read_floats(path: &Path, sizes: &[u64], expected: &str) -> Result<NpyArray, IoError> {
    let file = open_npy(path, |t| is_float_of(t, sizes), expected)?;
    Ok(float_rows(path, file, &|_| true)?.0)
}

fn is_float_of(t: &npyz::TypeStr, sizes: &[u64]) -> bool {
    t.type_char() == npyz::TypeChar::Float && sizes.contains(&t.size_field())
}

/// Which rows of an array (indices along its first axis: the frames of a sequence) to read.
pub type KeepRows<'a> = &'a dyn Fn(usize) -> bool;

/// The rows `keep` of a float32 or float64 `.npy` ([`read_npy_float`]) as float64, the others
/// skipped on disk, never read: the array of the kept rows (its first axis their count) and the
/// number of rows in the file. What a rank reading its time window of a long recording needs.
pub fn read_npy_float_rows(path: &Path, keep: KeepRows) -> Result<(NpyArray, u64), IoError> {
    let file = open_npy(path, |t| is_float_of(t, &[4, 8]), "float32 or float64")?;
    float_rows(path, file, keep)
}

/// [`read_npy_float_rows`] of an opened float32 or float64 file.
fn float_rows<R: Read + Seek>(
    path: &Path,
    file: NpyFile<R>,
    keep: KeepRows,
) -> Result<(NpyArray, u64), IoError> {
    let single = matches!(file.dtype(), npyz::DType::Plain(t) if t.size_field() == 4);
    let Rows { shape, data, of } = match single {
        true => kept_rows(path, file, keep, |v: f32| f64::from(v))?,
        false => kept_rows(path, file, keep, |v: f64| v)?,
    };
    Ok((NpyArray { shape, data }, of))
}

/// The rows `keep` of an image `.npy` ([`read_npy_image`]), as [`read_npy_float_rows`] reads
/// them.
pub fn read_npy_image_rows(path: &Path, keep: KeepRows) -> Result<(NpyArray, u64), IoError> {
    let Rows { shape, data, of } = read_image(path, keep, f64::from, |v| v, f64::from, f64::from)?;
    Ok((NpyArray { shape, data }, of))
}

/// Some rows of an array ([`kept_rows`]).
struct Rows<U> {
    /// The shape of the kept rows (the first axis their count).
    shape: Vec<u64>,
    data: Vec<U>,
    /// Rows in the file.
    of: u64,
}

/// The rows `keep` of `file`, each element converted by `to`, seeking past the others.
///
/// The rows are visited lazily (a header may declare 10¹² of them) and the output is checked
/// against the memory limit before it is allocated.
fn kept_rows<T: npyz::Deserialize, U, R: Read + Seek>(
    path: &Path,
    file: NpyFile<R>,
    keep: KeepRows,
    to: impl Fn(T) -> U,
) -> Result<Rows<U>, IoError> {
    let mut shape = file.shape().to_vec();
    check_output::<U>(path, &shape)?;
    // A 0-dimensional array is one row of one value.
    let rows = shape.first().copied().unwrap_or(1);
    let row: u64 = shape.iter().skip(1).product();
    let mut reader = file
        .data::<T>()
        .map_err(|e| IoError::format(path, e.to_string()))?;
    let kept = || (0..rows).filter(|&r| keep(r as usize));
    // Bounded by the bytes present ([`open_npy`]) and by the limit (above).
    let count = kept().count() as u64;
    let mut data = Vec::with_capacity((count * row) as usize);
    for r in kept() {
        reader.seek_to(r * row).map_err(|e| corrupt(path, e))?;
        for value in reader.by_ref().take(row as usize) {
            data.push(to(value.map_err(|e| corrupt(path, e))?));
        }
    }
    if let Some(first) = shape.first_mut() {
        *first = count;
    }
    Ok(Rows {
        shape,
        data,
        of: rows,
    })
}

/// Checks that the whole of an array of `shape`, read as `U` values (f64 output of u8 input:
/// 8 bytes a value), fits the memory limit; overflow counts as over it.
fn check_output<U>(path: &Path, shape: &[u64]) -> Result<(), IoError> {
    let values = shape
        .iter()
        .try_fold(1u64, |acc, &d| acc.checked_mul(d))
        .unwrap_or(u64::MAX);
    let item = std::mem::size_of::<U>() as u64;
    crate::limits::check_items(
        format!("shape {shape:?} (read as {item}-byte values)"),
        values,
        item,
    )
    .map_err(|e| IoError::too_large(path, e))
}

/// The longest header read: NumPy itself refuses headers over 10,000 bytes by default.
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Refuses a header whose declared length (a `u32` from format version 2 on) exceeds the file
/// or [`MAX_HEADER_BYTES`]: npyz allocates the declared length before reading it. Leaves
/// `reader` at the start.
fn check_header_length(
    path: &Path,
    reader: &mut (impl Read + Seek),
    length: u64,
) -> Result<(), IoError> {
    use std::io::SeekFrom;
    let mut prefix = [0u8; 12];
    let read = reader
        .read(&mut prefix)
        .map_err(|e| IoError::file(path, e))?;
    reader
        .seek(SeekFrom::Start(0))
        .map_err(|e| IoError::file(path, e))?;
    let (declared, start) = match (read, prefix[6]) {
        (10.., 1) => (u64::from(u16::from_le_bytes([prefix[8], prefix[9]])), 10),
        (12.., 2 | 3) => (
            u64::from(u32::from_le_bytes([
                prefix[8], prefix[9], prefix[10], prefix[11],
            ])),
            12,
        ),
        _ => return Ok(()), // npyz names what is wrong
    };
    let available = length.saturating_sub(start);
    if declared > available.min(MAX_HEADER_BYTES) {
        return Err(IoError::format(
            path,
            format!(
                "not a valid .npy file (its header declares {declared} bytes; the file holds \
                 {available} after the prefix, and headers longer than {MAX_HEADER_BYTES} bytes \
                 are refused)"
            ),
        ));
    }
    Ok(())
}

/// The first line of an error: npyz's header errors quote the header over several lines.
fn first_line(error: &impl std::fmt::Display) -> String {
    let text = error.to_string();
    text.lines()
        .next()
        .unwrap_or_default()
        .trim_end()
        .to_string()
}

fn corrupt(path: &Path, e: std::io::Error) -> IoError {
    IoError::format(path, format!("truncated or corrupt data ({e})"))
}

/// The element types of images and volumes: what microscopes and image tools write.
const IMAGE_TYPES: &str = "float32, float64, uint8 or uint16";

fn is_image_type(t: &npyz::TypeStr) -> bool {
    use npyz::TypeChar::{Float, Uint};
    match t.type_char() {
        Float => matches!(t.size_field(), 4 | 8),
        Uint => matches!(t.size_field(), 1 | 2),
        _ => false,
    }
}

/// Reads a float32, float64, uint8 or uint16 `.npy` (microscope volumes) as `f32` values in C
/// order, with its shape; float64 values are rounded to the nearest `f32`.
pub fn read_npy_f32(path: &Path) -> Result<(Vec<u64>, Vec<f32>), IoError> {
    read_npy_f32_rows(path, &|_| true)
}

/// [`read_npy_f32`] of the rows `keep` only (the others skipped on disk): their shape (the
/// first axis their count) and values, and the number of rows in the file.
pub fn read_npy_f32_rows(path: &Path, keep: KeepRows) -> Result<(Vec<u64>, Vec<f32>), IoError> {
    let rows = read_image(path, keep, |v| v, |v| v as f32, f32::from, f32::from)?;
    Ok((rows.shape, rows.data))
}

/// Reads a float32, float64, uint8 or uint16 `.npy` (per-vertex images: what microscopes and
/// image tools write) as `f64` values in C order, exactly, with its shape.
pub fn read_npy_image(path: &Path) -> Result<NpyArray, IoError> {
    Ok(read_npy_image_rows(path, &|_| true)?.0)
}

/// The rows `keep` of an image `.npy` ([`IMAGE_TYPES`]) with each element type converted by
/// its function ([`kept_rows`]).
fn read_image<U>(
    path: &Path,
    keep: KeepRows,
    from_f32: fn(f32) -> U,
    from_f64: fn(f64) -> U,
    from_u8: fn(u8) -> U,
    from_u16: fn(u16) -> U,
) -> Result<Rows<U>, IoError> {
    use npyz::TypeChar::Float;
    let file = open_npy(path, is_image_type, IMAGE_TYPES)?;
    let npyz::DType::Plain(dtype) = file.dtype() else {
        unreachable!("open_npy accepts plain types only")
    };
    match (dtype.type_char(), dtype.size_field()) {
        (Float, 4) => kept_rows(path, file, keep, from_f32),
        (Float, _) => kept_rows(path, file, keep, from_f64),
        (_, 1) => kept_rows(path, file, keep, from_u8),
        _ => kept_rows(path, file, keep, from_u16),
    }
}

/// Reads an integer `.npy` of vertex indices (int8…int64 or uint8…uint64, either byte order,
/// C order) as `u32`, with its shape; negative or ≥ 2³² values are errors naming the entry.
pub fn read_npy_indices(path: &Path) -> Result<(Vec<u64>, Vec<u32>), IoError> {
    use npyz::TypeChar::{Int, Uint};
    let file = open_npy(
        path,
        |t| matches!(t.type_char(), Int | Uint),
        "an integer type",
    )?;
    let shape = file.shape().to_vec();
    let npyz::DType::Plain(dtype) = file.dtype() else {
        unreachable!("open_npy accepts plain integer types only")
    };
    let indices = match (dtype.type_char(), dtype.size_field()) {
        (Int, 1) => indices::<i8>(path, file),
        (Int, 2) => indices::<i16>(path, file),
        (Int, 4) => indices::<i32>(path, file),
        (Int, _) => indices::<i64>(path, file),
        (_, 1) => indices::<u8>(path, file),
        (_, 2) => indices::<u16>(path, file),
        (_, 4) => indices::<u32>(path, file),
        _ => indices::<u64>(path, file),
    }?;
    Ok((shape, indices))
}

/// The values of an integer `file` of element type `T` as vertex indices, streamed (no
/// intermediate array) into an output checked against the memory limit first.
fn indices<T: npyz::Deserialize + Into<i128>>(
    path: &Path,
    file: NpyFile,
) -> Result<Vec<u32>, IoError> {
    check_output::<u32>(path, file.shape())?;
    let values = file
        .data::<T>()
        .map_err(|e| IoError::format(path, e.to_string()))?;
    let mut indices = Vec::with_capacity(values.len() as usize);
    for (at, value) in values.enumerate() {
        let v: i128 = value.map_err(|e| corrupt(path, e))?.into();
        let index = u32::try_from(v)
            .map_err(|_| IoError::format(path, format!("entry {at} is {v}, not a vertex index")))?;
        indices.push(index);
    }
    Ok(indices)
}

/// An open `.npy` file (or stream read into memory), positioned at its data.
type NpyFile<R = BufReader<File>> = npyz::NpyFile<R>;

/// Opens `path` and parses its header, checks the dtype with `accepts` (described as
/// `expected` in the error), C order, and that the shape fits the bytes present (before
/// anything is allocated for it); nothing of the data is read yet.
fn open_npy(
    path: &Path,
    accepts: impl Fn(&npyz::TypeStr) -> bool,
    expected: &str,
) -> Result<NpyFile, IoError> {
    let (file, length) = super::open_regular(path)?;
    npy_of(path, BufReader::new(file), length, accepts, expected)
}

/// [`open_npy`] of the `length` bytes of `reader`, which `path` names in errors.
fn npy_of<R: Read + Seek>(
    path: &Path,
    mut reader: R,
    length: u64,
    accepts: impl Fn(&npyz::TypeStr) -> bool,
    expected: &str,
) -> Result<NpyFile<R>, IoError> {
    let in_file = |e| IoError::file(path, e);
    check_header_length(path, &mut reader, length)?;
    let header = npyz::NpyHeader::from_reader(&mut reader).map_err(|e| {
        IoError::format(path, format!("not a valid .npy file ({})", first_line(&e)))
    })?;
    let data_offset = reader.stream_position().map_err(in_file)?;
    let file = npyz::NpyFile::with_header(header, reader);
    let dtype = file.dtype();
    let npyz::DType::Plain(type_str) = &dtype else {
        return Err(IoError::format(
            path,
            format!("dtype is {}, expected {expected}", dtype.descr()),
        ));
    };
    if !accepts(type_str) {
        return Err(IoError::format(
            path,
            format!("dtype is {}, expected {expected}", dtype.descr()),
        ));
    }
    if file.order() != npyz::Order::C {
        return Err(IoError::format(
            path,
            "array is in Fortran order; save it with C order (np.ascontiguousarray)",
        ));
    }
    let shape = file.shape();
    if let Some(axis) = shape.iter().position(|&d| d == 0) {
        return Err(IoError::format(
            path,
            format!("dimension {axis} of shape {shape:?} is 0 (an empty array)"),
        ));
    }
    let item = type_str.size_field();
    let needed = shape.iter().try_fold(item, |acc, &d| acc.checked_mul(d));
    let present = length.saturating_sub(data_offset);
    if needed != Some(present) {
        return Err(IoError::format(
            path,
            format!("shape {shape:?} does not fit the {present} bytes of data (truncated or corrupt file)"),
        ));
    }
    Ok(file)
}

/// Writes `rows[k][n]` as a float64 `.npy` of shape (K, N, 3) (all rows of equal length).
pub fn write_npy_vectors(path: &Path, rows: &[Vec<nalgebra::Vector3<f64>>]) -> Result<(), IoError> {
    let (k, n) = (rows.len() as u64, rows.first().map_or(0, Vec::len) as u64);
    let values: Vec<f64> = rows
        .iter()
        .flatten()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    write_npy(path, &[k, n, 3], &values)
}
