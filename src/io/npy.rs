//! NumPy `.npy` arrays through npyz: float64 (or float32) data, integer index arrays.

use super::{write_atomically, IoError};
use npyz::WriterBuilder;
use std::path::Path;

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
    write_atomically(path, |w| {
        let mut writer = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(w)
            .begin_nd()?;
        writer.extend(data.iter().copied())?;
        writer.finish()
    })
}

/// Reads a float64 `.npy` file in C order (either byte order), checking that the header's shape
/// matches the data actually present before allocating for it.
pub fn read_npy(path: &Path) -> Result<NpyArray, IoError> {
    read_floats(path, &[8], "float64")
}

/// Reads a float32 or float64 `.npy` file like [`read_npy`]; float32 values are widened to
/// f64 exactly.
pub fn read_npy_float(path: &Path) -> Result<NpyArray, IoError> {
    read_floats(path, &[4, 8], "float32 or float64")
}

/// A float `.npy` whose item size (bytes) is one of `sizes`, described as `expected`.
fn read_floats(path: &Path, sizes: &[u64], expected: &str) -> Result<NpyArray, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::file(path, e))?;
    let file = open_npy(
        path,
        &bytes,
        |t| t.type_char() == npyz::TypeChar::Float && sizes.contains(&t.size_field()),
        expected,
    )?;
    let shape = file.shape().to_vec();
    let single = matches!(file.dtype(), npyz::DType::Plain(t) if t.size_field() == 4);
    let data = match single {
        true => file
            .into_vec::<f32>()
            .map(|values| values.into_iter().map(f64::from).collect()),
        false => file.into_vec::<f64>(),
    }
    .map_err(|e| IoError::format(path, format!("truncated or corrupt data ({e})")))?;
    Ok(NpyArray { shape, data })
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
    read_image(path, |v| v, |v| v as f32, f32::from, f32::from)
}

/// Reads a float32, float64, uint8 or uint16 `.npy` (per-vertex images: what microscopes and
/// image tools write) as `f64` values in C order, exactly, with its shape.
pub fn read_npy_image(path: &Path) -> Result<NpyArray, IoError> {
    let (shape, data) = read_image(path, f64::from, |v| v, f64::from, f64::from)?;
    Ok(NpyArray { shape, data })
}

/// An image `.npy` ([`IMAGE_TYPES`]) with each element type converted by its function.
fn read_image<U>(
    path: &Path,
    from_f32: fn(f32) -> U,
    from_f64: fn(f64) -> U,
    from_u8: fn(u8) -> U,
    from_u16: fn(u16) -> U,
) -> Result<(Vec<u64>, Vec<U>), IoError> {
    use npyz::TypeChar::Float;
    let bytes = std::fs::read(path).map_err(|e| IoError::file(path, e))?;
    let file = open_npy(path, &bytes, is_image_type, IMAGE_TYPES)?;
    let shape = file.shape().to_vec();
    let corrupt =
        |e: std::io::Error| IoError::format(path, format!("truncated or corrupt data ({e})"));
    let npyz::DType::Plain(dtype) = file.dtype() else {
        unreachable!("open_npy accepts plain types only")
    };
    let values = match (dtype.type_char(), dtype.size_field()) {
        (Float, 4) => convert(file.into_vec::<f32>().map_err(corrupt)?, from_f32),
        (Float, _) => convert(file.into_vec::<f64>().map_err(corrupt)?, from_f64),
        (_, 1) => convert(file.into_vec::<u8>().map_err(corrupt)?, from_u8),
        _ => convert(file.into_vec::<u16>().map_err(corrupt)?, from_u16),
    };
    Ok((shape, values))
}

fn convert<T, U>(values: Vec<T>, to: impl Fn(T) -> U) -> Vec<U> {
    values.into_iter().map(to).collect()
}

/// Reads an integer `.npy` of vertex indices (int8…int64 or uint8…uint64, either byte order,
/// C order) as `u32`, with its shape; negative or ≥ 2³² values are errors naming the entry.
pub fn read_npy_indices(path: &Path) -> Result<(Vec<u64>, Vec<u32>), IoError> {
    use npyz::TypeChar::{Int, Uint};
    let bytes = std::fs::read(path).map_err(|e| IoError::file(path, e))?;
    let file = open_npy(
        path,
        &bytes,
        |t| matches!(t.type_char(), Int | Uint),
        "an integer type",
    )?;
    let shape = file.shape().to_vec();
    let corrupt =
        |e: std::io::Error| IoError::format(path, format!("truncated or corrupt data ({e})"));
    let npyz::DType::Plain(dtype) = file.dtype() else {
        unreachable!("open_npy accepts plain integer types only")
    };
    let values: Vec<i128> = match (dtype.type_char(), dtype.size_field()) {
        (Int, 1) => widen(file.into_vec::<i8>().map_err(corrupt)?),
        (Int, 2) => widen(file.into_vec::<i16>().map_err(corrupt)?),
        (Int, 4) => widen(file.into_vec::<i32>().map_err(corrupt)?),
        (Int, _) => widen(file.into_vec::<i64>().map_err(corrupt)?),
        (_, 1) => widen(file.into_vec::<u8>().map_err(corrupt)?),
        (_, 2) => widen(file.into_vec::<u16>().map_err(corrupt)?),
        (_, 4) => widen(file.into_vec::<u32>().map_err(corrupt)?),
        _ => widen(file.into_vec::<u64>().map_err(corrupt)?),
    };
    let indices = values
        .iter()
        .enumerate()
        .map(|(at, &v)| {
            u32::try_from(v).map_err(|_| {
                IoError::format(path, format!("entry {at} is {v}, not a vertex index"))
            })
        })
        .collect::<Result<_, _>>()?;
    Ok((shape, indices))
}

fn widen<T: Into<i128>>(values: Vec<T>) -> Vec<i128> {
    values.into_iter().map(Into::into).collect()
}

/// Parses the header, checks the dtype with `accepts` (described as `expected` in the error),
/// C order, and that the shape fits the bytes present (before anything is allocated for it).
fn open_npy<'a>(
    path: &Path,
    bytes: &'a [u8],
    accepts: impl Fn(&npyz::TypeStr) -> bool,
    expected: &str,
) -> Result<npyz::NpyFile<&'a [u8]>, IoError> {
    let file = npyz::NpyFile::new(bytes)
        .map_err(|e| IoError::format(path, format!("not a valid .npy file ({e})")))?;
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
    let item = type_str.size_field();
    let needed = shape.iter().try_fold(item, |acc, &d| acc.checked_mul(d));
    let present = bytes.len().saturating_sub(data_offset(bytes)) as u64;
    if needed != Some(present) {
        return Err(IoError::format(
            path,
            format!("shape {shape:?} does not fit the {present} bytes of data (truncated or corrupt file)"),
        ));
    }
    Ok(file)
}

/// Where the data starts: magic (6 bytes), version (2), header length (2 bytes in format 1.0,
/// 4 bytes later), header.
fn data_offset(bytes: &[u8]) -> usize {
    let le = |range: std::ops::Range<usize>| {
        bytes
            .get(range)
            .map(|b| b.iter().rev().fold(0usize, |acc, &x| acc << 8 | x as usize))
    };
    match bytes.get(6) {
        Some(1) => 10 + le(8..10).unwrap_or(0),
        _ => 12 + le(8..12).unwrap_or(0),
    }
}

/// Writes a sequence as the NPY directory that `meshflow solve` reads: `positions.npy`
/// (K, V, 3) float64, `faces.npy` (F, 3) int64, `intensity.npy` (K, V) float64 when given, and
/// `times.txt` (one time per line).
pub fn write_npy_sequence(
    dir: &Path,
    positions: &[Vec<nalgebra::Vector3<f64>>],
    faces: &[[u32; 3]],
    intensities: Option<&[Vec<f64>]>,
    times: &[f64],
) -> Result<(), IoError> {
    let (k, v) = (
        positions.len() as u64,
        positions.first().map_or(0, Vec::len) as u64,
    );
    write_npy_vectors(&dir.join("positions.npy"), positions)?;
    let indices: Vec<i64> = faces.iter().flatten().map(|&i| i as i64).collect();
    write_npy(&dir.join("faces.npy"), &[faces.len() as u64, 3], &indices)?;
    if let Some(intensities) = intensities {
        let values: Vec<f64> = intensities.iter().flatten().copied().collect();
        write_npy(&dir.join("intensity.npy"), &[k, v], &values)?;
    }
    write_atomically(&dir.join("times.txt"), |w| {
        use std::io::Write;
        times.iter().try_for_each(|t| writeln!(w, "{t}"))
    })
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
