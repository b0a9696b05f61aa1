//! Point clouds per frame from files: `(N, 3)` NPY or CSV files (one frame each, a directory
//! or glob in natural order), or one `(K, N, 3)` NPY of tracks (rows that are NaN dropped).

use super::MAX_COORDINATE;
use crate::format::{format_number, frame_files, quoted, read_npy_float, IoError};
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

/// `(N, 3)`: one frame; `(K, N, 3)` (alone): K frames without their all-NaN rows. Any other
/// row that is not finite, and an array without points, is an error naming the file and row.
fn read_npy_points(file: &Path, alone: bool) -> Result<Vec<Vec<Vector3<f64>>>, IoError> {
    let array = read_npy_float(file)?;
    let bad = |why: String| IoError::format(file, format!("shape {:?}: {why}", array.shape));
    let (frames, n) = match array.shape[..] {
        [n, 3] => (1, n as usize),
        [k, n, 3] if alone => (k as usize, n as usize),
        _ => {
            return Err(bad(
                "points are (N, 3) per file, or one (frames, N, 3) file".into(),
            ))
        }
    };
    if frames == 0 || n == 0 {
        return Err(bad("no points".into()));
    }
    // Tracks (K, N, 3) mark untracked points by NaN rows.
    let tracks = array.shape.len() == 3;
    let mut all = Vec::with_capacity(frames);
    for (k, frame) in array.data.chunks_exact(3 * n).enumerate() {
        let mut points = Vec::with_capacity(n);
        for (row, p) in frame
            .chunks_exact(3)
            .map(Vector3::from_column_slice)
            .enumerate()
        {
            let untracked = tracks && p.iter().all(|c| c.is_nan());
            match (untracked, p.iter().all(|&c| is_coordinate(c))) {
                (true, _) => {}
                (false, true) => points.push(p),
                (false, false) => {
                    let frame = if tracks {
                        format!("frame {k}, ")
                    } else {
                        String::new()
                    };
                    let why = match p.iter().all(|c| c.is_finite()) {
                        true => WITHIN,
                        false => "points must be finite",
                    };
                    return Err(IoError::format(
                        file,
                        format!(
                            "{frame}row {row} is ({}, {}, {}): {why}",
                            format_number(p.x),
                            format_number(p.y),
                            format_number(p.z)
                        ),
                    ));
                }
            }
        }
        all.push(points);
    }
    Ok(all)
}

/// A CSV frame: a header is allowed on the first line that holds anything, and only where none
/// of its fields is a number (a bad first data line such as `1.0,2.0,abc` is an error, not a
/// header); every point finite.
fn read_csv(file: &Path) -> Result<Vec<Vector3<f64>>, IoError> {
    let bytes = crate::format::read_file(file)?;
    let text = String::from_utf8(bytes)
        .map_err(|e| IoError::format(file, format!("not UTF-8 text ({e})")))?;
    let mut points = Vec::new();
    let mut first = true;
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        let is_header = first && fields.iter().all(|f| f.parse::<f64>().is_err());
        first = false;
        if !is_header {
            let point = csv_point(&fields).map_err(|why| IoError::at_line(file, (n + 1, why)))?;
            points.push(point);
        }
    }
    Ok(points)
}

/// What every coordinate of a point must be.
const WITHIN: &str = "points must lie within ±1e50 (rescale them, e.g. to micrometres)";

/// Whether `c` is a coordinate that a fit and a match take: finite and within
/// [`MAX_COORDINATE`] (as [`WITHIN`] says; a test checks that it does).
fn is_coordinate(c: f64) -> bool {
    c.is_finite() && c.abs() <= MAX_COORDINATE
}

/// Three finite numbers x, y, z.
fn csv_point(fields: &[&str]) -> Result<Vector3<f64>, String> {
    if fields.len() != 3 {
        return Err(format!("{} fields, expected x, y, z", fields.len()));
    }
    let mut point = Vector3::zeros();
    for (c, field) in point.iter_mut().zip(fields) {
        *c = match field.parse::<f64>() {
            Ok(v) if is_coordinate(v) => v,
            Ok(v) if v.is_finite() => {
                return Err(format!("{} is too large: {WITHIN}", quoted(field)))
            }
            Ok(_) => return Err(format!("{} is not a finite number", quoted(field))),
            Err(_) => return Err(format!("{} is not a number", quoted(field))),
        };
    }
    Ok(point)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_bound_named_is_the_bound_checked() {
        let bound = format!("{:e}", super::MAX_COORDINATE);
        assert!(super::WITHIN.contains(&bound), "{bound}");
        assert!(super::is_coordinate(1e50) && !super::is_coordinate(1.0001e50));
        assert!(!super::is_coordinate(f64::NAN));
    }
}
