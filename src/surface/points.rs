//! Point clouds per frame from files: `(N, 3)` NPY or CSV files (one frame each, a directory
//! or glob in natural order), or one `(K, N, 3)` NPY of tracks (rows that are NaN dropped).

use crate::io::{frame_files, read_npy_float, IoError};
use crate::Error;
use nalgebra::Vector3;
use std::path::Path;

/// The points of every frame that `path` names (module docs). CSV: three numbers per line
/// (x, y, z; commas or white space between them), an optional header line, `#` comments.
/// Errors name the file and line or row.
pub fn read_points(path: &Path) -> Result<Vec<Vec<Vector3<f64>>>, Error> {
    let files = frame_files(path, is_points_file, "point files (.npy, .csv)")?;
    let mut frames = Vec::new();
    for file in &files {
        let is_csv = file
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        match is_csv {
            true => frames.push(read_csv(file)?),
            false => frames.extend(read_npy_points(file, files.len() == 1)?),
        }
    }
    Ok(frames)
}

fn is_points_file(path: &Path) -> bool {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(extension.as_deref(), Some("npy" | "csv"))
}

/// `(N, 3)`: one frame; `(K, N, 3)` (alone): K frames without their all-NaN rows.
fn read_npy_points(file: &Path, alone: bool) -> Result<Vec<Vec<Vector3<f64>>>, IoError> {
    let array = read_npy_float(file)?;
    let rows = |data: &[f64]| -> Vec<Vector3<f64>> {
        data.chunks_exact(3)
            .map(Vector3::from_column_slice)
            .collect()
    };
    match array.shape[..] {
        [_, 3] => Ok(vec![rows(&array.data)]),
        [_, n, 3] if alone => Ok(array
            .data
            .chunks_exact(3 * n as usize)
            .map(|frame| {
                rows(frame)
                    .into_iter()
                    .filter(|p| !p.iter().all(|c| c.is_nan()))
                    .collect()
            })
            .collect()),
        _ => Err(IoError::format(
            file,
            format!(
                "shape {:?}: points are (N, 3) per file, or one (frames, N, 3) file",
                array.shape
            ),
        )),
    }
}

fn read_csv(file: &Path) -> Result<Vec<Vector3<f64>>, IoError> {
    let text = std::fs::read_to_string(file).map_err(|e| IoError::file(file, e))?;
    let mut points = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        let numbers: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
        match numbers {
            Ok(v) if v.len() == 3 => points.push(Vector3::new(v[0], v[1], v[2])),
            Ok(v) => {
                return Err(IoError::at_line(
                    file,
                    (n + 1, format!("{} numbers, expected x, y, z", v.len())),
                ))
            }
            // A header: the first line that holds text.
            Err(_) if points.is_empty() && n == first_content_line(&text) => {}
            Err(_) => {
                return Err(IoError::at_line(
                    file,
                    (n + 1, format!("'{line}' is not three numbers x, y, z")),
                ))
            }
        }
    }
    Ok(points)
}

/// The index of the first line that is not blank or a comment.
fn first_content_line(text: &str) -> usize {
    text.lines()
        .position(|l| !l.split('#').next().unwrap_or("").trim().is_empty())
        .unwrap_or(0)
}
