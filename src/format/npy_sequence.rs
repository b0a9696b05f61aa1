//! The NPY sequence: a moving mesh as a directory of arrays, read, written and given channels
//! here only.
//!
//! | file | shape | dtype |
//! |---|---|---|
//! | `positions.npy` | (K, V, 3) | float32 or float64 |
//! | `faces.npy` | (F, 3), 0-based, counter-clockwise | any integer |
//! | `intensity.npy` (optional) | (K, V) grey values, or (K, V, C) channels | float32, float64, uint8, uint16 |
//! | `times.txt` (optional) | K numbers | text |
//! | `no_data.npy` (optional, beside the image) | (K, V), 1 where a vertex has no data (`meshflow sample`: its shell left the volume) | uint8 |
//!
//! An intensity array named elsewhere (`--intensity`) has the same layout, with V the files'
//! or the mesh's vertex count ([`read_intensity_array`]).

use super::{npy_contents, write_all_atomically, write_npy, write_npy_vectors};
use super::{read_npy_float_rows, read_npy_image_rows, read_npy_indices, write_atomically};
use super::{IoError, KeepRows, RawSequence, VertexValues};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// The positions, (K, V, 3).
pub const POSITIONS: &str = "positions.npy";
/// The triangles, (F, 3).
pub const FACES: &str = "faces.npy";
/// The image, (K, V) or (K, V, C).
pub const INTENSITY: &str = "intensity.npy";
/// The frame times, one number per frame.
pub const TIMES: &str = "times.txt";
/// Beside an image sampled from volumes: (K, V) uint8, 1 where a vertex has no data.
pub const NO_DATA: &str = "no_data.npy";

/// The no-data mask that goes with the image `image`: `no_data.npy` beside `intensity.npy`,
/// `NAME_no_data.npy` beside any other `NAME.npy`.
pub fn no_data_file(image: &Path) -> PathBuf {
    let name = image.file_name().map(|n| n.to_string_lossy().into_owned());
    let companion = match name.as_deref() {
        Some(INTENSITY) | None => NO_DATA.to_string(),
        Some(name) => {
            let stem = name.strip_suffix(".npy").unwrap_or(name);
            format!("{stem}_{NO_DATA}")
        }
    };
    image.with_file_name(companion)
}

/// Writes a no-data mask `mask[k][i]` (frame, vertex) as (K, V) uint8.
pub fn write_no_data(path: &Path, mask: &[Vec<bool>]) -> Result<(), IoError> {
    let v = mask.first().map_or(0, Vec::len);
    let values: Vec<u8> = mask.iter().flatten().map(|&m| m as u8).collect();
    write_npy(path, &[mask.len() as u64, v as u64], &values)
}

/// A sampled image (as [`write_intensity_array`]) and its no-data mask (as [`write_no_data`])
/// written together ([`write_all_atomically`]): a failure leaves both as they were, never a
/// new image beside an old mask.
pub fn write_image_and_no_data(
    image_path: &Path,
    image: &[Vec<Vec<f64>>],
    mask_path: &Path,
    mask: &[Vec<bool>],
) -> Result<(), IoError> {
    let (image_shape, image_values) = intensity_array(image);
    let v = mask.first().map_or(0, Vec::len);
    let mask_shape = [mask.len() as u64, v as u64];
    let mask_values: Vec<u8> = mask.iter().flatten().map(|&m| m as u8).collect();
    let files = vec![
        (
            image_path,
            npy_contents(image_path, &image_shape, &image_values)?,
        ),
        (
            mask_path,
            npy_contents(mask_path, &mask_shape, &mask_values)?,
        ),
    ];
    write_all_atomically(files)
}

/// Writes a sequence as the NPY directory that `meshflow solve` reads: `positions.npy`
/// (K, V, 3) float64, `faces.npy` (F, 3) int64, `intensity.npy` (K, V) float64 when given, and
/// `times.txt` (one time per line).
pub fn write_npy_sequence(
    dir: &Path,
    positions: &[Vec<Vector3<f64>>],
    faces: &[[u32; 3]],
    intensities: Option<&[Vec<f64>]>,
    times: &[f64],
) -> Result<(), IoError> {
    write_npy_vectors(&dir.join(POSITIONS), positions)?;
    let indices: Vec<i64> = faces.iter().flatten().map(|&i| i as i64).collect();
    write_npy(&dir.join(FACES), &[faces.len() as u64, 3], &indices)?;
    if let Some(intensities) = intensities {
        let grey: Vec<Vec<Vec<f64>>> = intensities.iter().map(|f| vec![f.clone()]).collect();
        write_intensity_array(&dir.join(INTENSITY), &grey)?;
    }
    write_atomically(&dir.join(TIMES), |w| {
        use std::io::Write;
        times.iter().try_for_each(|t| writeln!(w, "{t}"))
    })
}

/// Writes an image `image[k][c][i]` (frame, channel, vertex) as an intensity array in the
/// layout [`read_intensity_array`] reads: (K, V) float64 for one channel, (K, V, C) for
/// several.
pub fn write_intensity_array(path: &Path, image: &[Vec<Vec<f64>>]) -> Result<(), IoError> {
    let (shape, values) = intensity_array(image);
    write_npy(path, &shape, &values)
}

/// The shape and values of an image `[k][c][i]`: (K, V), or (K, V, C) for several channels.
fn intensity_array(image: &[Vec<Vec<f64>>]) -> (Vec<u64>, Vec<f64>) {
    let k = image.len();
    let c = image.first().map_or(1, Vec::len);
    let v = image.first().and_then(|f| f.first()).map_or(0, Vec::len);
    let values: Vec<f64> = (image.iter())
        .flat_map(|frame| (0..v).flat_map(move |i| frame.iter().map(move |ch| ch[i])))
        .collect();
    let shape: Vec<u64> = match c {
        1 => vec![k as u64, v as u64],
        _ => vec![k as u64, v as u64, c as u64],
    };
    (shape, values)
}

/// The frames `keep` of an NPY directory (see the module documentation; the other rows of its
/// arrays are not read), and how many frames it has. `times.txt` is the loader's (it applies
/// to every format).
pub fn read_npy_sequence(dir: &Path, keep: KeepRows) -> Result<(RawSequence, usize), IoError> {
    let positions_file = dir.join(POSITIONS);
    let (array, k_all) = read_npy_float_rows(&positions_file, keep)?;
    let [k, v, 3] = array.shape[..] else {
        let mut shape = array.shape.clone();
        if let Some(first) = shape.first_mut() {
            *first = k_all;
        }
        return Err(IoError::format(
            &positions_file,
            format!("shape {shape:?}, expected (frames, vertices, 3)"),
        ));
    };
    let coordinates = split_frames(&array.data, k as usize, 3 * v as usize);
    let positions: Vec<Vec<Vector3<f64>>> = coordinates
        .iter()
        .map(|frame| {
            frame
                .chunks_exact(3)
                .map(Vector3::from_column_slice)
                .collect()
        })
        .collect();
    let faces_file = dir.join(FACES);
    let (shape, indices) = read_npy_indices(&faces_file)?;
    if !matches!(shape[..], [_, 3]) {
        return Err(IoError::format(
            &faces_file,
            format!("shape {shape:?}, expected (faces, 3)"),
        ));
    }
    let faces: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|f| [f[0], f[1], f[2]])
        .collect();
    // Checked here, so that the error names the file at fault, not positions.npy.
    if let Some((face, &vertex)) = (faces.iter().enumerate())
        .find_map(|(f, corners)| Some((f, corners.iter().find(|&&i| i as u64 >= v)?)))
    {
        let message =
            format!("face {face} refers to vertex {vertex}, but positions.npy has {v} vertices");
        return Err(IoError::format(&faces_file, message));
    }
    let intensity_file = dir.join(INTENSITY);
    let images = match intensity_file.exists() {
        true => {
            let counts = [VertexCount::new(v as usize, "vertices")];
            Some(read_intensity_rows(IMAGE, &intensity_file, k_all as usize, &counts, keep)?.0)
        }
        false => None,
    };
    if let Some(message) = images.as_deref().and_then(first_non_finite) {
        return Err(IoError::format(&intensity_file, message));
    }
    let raw = RawSequence {
        faces,
        positions,
        images,
        times: None,
        sources: vec![positions_file; k as usize],
        implicit_clip: None,
    };
    Ok((raw, k_all as usize))
}

/// Where the first value that is not a finite number is, as a sentence.
fn first_non_finite(frames: &[VertexValues]) -> Option<String> {
    frames.iter().enumerate().find_map(|(k, frame)| {
        let channels = frame.clone().into_channels();
        channels.iter().enumerate().find_map(|(c, values)| {
            let (i, value) = values.iter().enumerate().find(|(_, x)| !x.is_finite())?;
            let channel = match channels.len() {
                1 => String::new(),
                _ => format!(", channel {c}"),
            };
            Some(format!(
                "frame {k}: intensity at vertex {i}{channel} is {value}"
            ))
        })
    })
}

/// What [`read_intensity_rows`] calls an image in its errors.
pub(crate) const IMAGE: &str = "intensity array";

/// A number of vertices an image may have rows for, and what they are.
#[derive(Clone, Copy, Debug)]
pub(crate) struct VertexCount {
    n: usize,
    what: &'static str,
}

impl VertexCount {
    pub(crate) fn new(n: usize, what: &'static str) -> Self {
        VertexCount { n, what }
    }
}

/// The image of an intensity `.npy`: (frames, vertices) grey values or (frames, vertices,
/// channels).
pub fn read_intensity_array(
    path: &Path,
    n_frames: usize,
    n_vertices: usize,
) -> Result<Vec<VertexValues>, IoError> {
    let counts = [VertexCount::new(n_vertices, "vertices")];
    Ok(read_intensity_rows(IMAGE, path, n_frames, &counts, &|_| true)?.0)
}

/// [`read_intensity_array`] with rows for any of the vertex `counts` (say, the files' and the
/// mesh's, when they differ): the image and which count its rows matched. The first matching
/// count wins, so equal counts are never ambiguous. Only the frames `keep` are read.
pub(crate) fn read_intensity_rows(
    what: &str,
    path: &Path,
    n_frames: usize,
    counts: &[VertexCount],
    keep: KeepRows,
) -> Result<(Vec<VertexValues>, usize), IoError> {
    let (array, rows) = read_npy_image_rows(path, keep)?;
    let mut shape = array.shape.clone();
    if let Some(first) = shape.first_mut() {
        *first = rows;
    }
    let matches = |v: u64| counts.iter().position(|c| c.n as u64 == v);
    let k = n_frames as u64;
    let (count, channels) = match shape[..] {
        [a, b] if a == k && matches(b).is_some() => (matches(b), None),
        [a, b, c] if a == k && matches(b).is_some() && c > 0 => (matches(b), Some(c as usize)),
        _ => {
            return Err(IoError::format(
                path,
                intensity_shape_error(what, &shape, n_frames, counts),
            ))
        }
    };
    let count = count.expect("matched above");
    let row = counts[count].n * channels.unwrap_or(1);
    let images = split_frames(&array.data, array.shape[0] as usize, row)
        .into_iter()
        .map(|frame| VertexValues::from_rows(frame, channels))
        .collect();
    Ok((images, count))
}

/// `WHAT has shape (4, 10), expected (3, 1528) = (frames, vertices in the files) or
/// (3, 1224) = (frames, …), each optionally with a third axis of channels`.
fn intensity_shape_error(
    what: &str,
    shape: &[u64],
    n_frames: usize,
    counts: &[VertexCount],
) -> String {
    let expected: Vec<String> = (counts.iter().enumerate())
        .filter(|(i, c)| counts[..*i].iter().all(|earlier| earlier.n != c.n))
        .map(|(_, c)| c)
        .map(|c| format!("({n_frames}, {}) = (frames, {})", c.n, c.what))
        .collect();
    format!(
        "{what} has shape {shape:?}, expected {}, or with a third axis of channels",
        expected.join(" or ")
    )
}

/// `n_frames` rows of `row_length` values (which may be 0) from a C-order array.
fn split_frames<T: Clone>(data: &[T], n_frames: usize, row_length: usize) -> Vec<Vec<T>> {
    (0..n_frames)
        .map(|k| data[k * row_length..(k + 1) * row_length].to_vec())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What is written is read back: positions and faces exactly, a grey image as one
    /// channel, a written channel image in place of it as those channels.
    #[test]
    fn a_written_sequence_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let positions: Vec<Vec<Vector3<f64>>> = (0..3)
            .map(|k| {
                (0..4)
                    .map(|i| Vector3::new(i as f64, k as f64, 0.5))
                    .collect()
            })
            .collect();
        let faces = [[0, 1, 2], [0, 2, 3]];
        let grey: Vec<Vec<f64>> = (0..3).map(|k| vec![k as f64 + 0.25; 4]).collect();
        write_npy_sequence(
            dir.path(),
            &positions,
            &faces,
            Some(&grey),
            &[0.0, 1.0, 2.5],
        )
        .unwrap();
        let (raw, frames) = read_npy_sequence(dir.path(), &|_| true).unwrap();
        assert_eq!(
            (frames, raw.positions, raw.faces),
            (3, positions, faces.to_vec())
        );
        let read: Vec<VertexValues> = grey.iter().cloned().map(VertexValues::Grey).collect();
        assert_eq!(raw.images, Some(read));

        let image: Vec<Vec<Vec<f64>>> = (0..3)
            .map(|k| (0..2).map(|c| vec![(10 * k + c) as f64; 4]).collect())
            .collect();
        write_intensity_array(&dir.path().join(INTENSITY), &image).unwrap();
        let (raw, _) = read_npy_sequence(dir.path(), &|k| k != 1).unwrap();
        let kept = [&image[0], &image[2]].map(|frame| VertexValues::Channels(frame.clone()));
        assert_eq!(raw.images, Some(kept.to_vec()));
        assert_eq!(raw.positions.len(), 2);
    }
}
