//! NumPy `.npy` arrays of float64 through npyz.

use super::{write_atomically, IoError};
use npyz::WriterBuilder;
use std::path::Path;

/// A float64 array in C (row-major) order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<u64>,
    pub data: Vec<f64>,
}

/// Writes `data` (C order) as a little-endian float64 `.npy` of the given shape.
pub fn write_npy(path: &Path, shape: &[u64], data: &[f64]) -> Result<(), IoError> {
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
    let bytes = std::fs::read(path).map_err(|e| IoError::file(path, e))?;
    let file = npyz::NpyFile::new(&bytes[..])
        .map_err(|e| IoError::format(path, format!("not a valid .npy file ({e})")))?;
    let dtype = file.dtype();
    let is_f8 = matches!(&dtype, npyz::DType::Plain(t) if t.type_char() == npyz::TypeChar::Float && t.size_field() == 8);
    if !is_f8 {
        return Err(IoError::format(
            path,
            format!("dtype is {}, expected float64", dtype.descr()),
        ));
    }
    if file.order() != npyz::Order::C {
        return Err(IoError::format(
            path,
            "array is in Fortran order; save it with C order (np.ascontiguousarray)",
        ));
    }
    let shape = file.shape().to_vec();
    let needed = shape.iter().try_fold(8u64, |acc, &d| acc.checked_mul(d));
    let present = bytes.len().saturating_sub(data_offset(&bytes)) as u64;
    if needed != Some(present) {
        return Err(IoError::format(
            path,
            format!("shape {shape:?} does not fit the {present} bytes of data (truncated or corrupt file)"),
        ));
    }
    let data = file
        .into_vec::<f64>()
        .map_err(|e| IoError::format(path, format!("truncated or corrupt data ({e})")))?;
    Ok(NpyArray { shape, data })
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
