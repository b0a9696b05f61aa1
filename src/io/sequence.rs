//! A directory of OBJ frames as a [`MeshSequence`].

use super::{read_npy, read_obj, IoError, ObjMesh};
use crate::flow::MeshSequence;
use crate::mesh::Mesh;
use crate::Error;
use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// The `.obj` files of `dir` in natural order (`frame_2` before `frame_10`).
pub fn obj_frames(dir: &Path) -> Result<Vec<PathBuf>, IoError> {
    let entries = std::fs::read_dir(dir).map_err(|e| IoError::file(dir, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| IoError::file(dir, e))?.path();
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
        {
            files.push(path);
        }
    }
    files.sort_by(|a, b| natural_order(&a.to_string_lossy(), &b.to_string_lossy()));
    Ok(files)
}

/// Loads one frame per OBJ file of `dir`. Intensities come from `intensity` (a float64 `.npy`
/// of shape `(K, V)`) when given, else from the vertex colours: the value itself when
/// `r = g = b` (unclamped), Rec. 709 luma `0.2126 r + 0.7152 g + 0.0722 b` otherwise.
/// `times = None` means `0, 1, 2, …`.
pub fn load_obj_sequence(
    dir: &Path,
    intensity: Option<&Path>,
    times: Option<Vec<f64>>,
) -> Result<MeshSequence, Error> {
    let files = obj_frames(dir)?;
    if files.is_empty() {
        return Err(IoError::format(dir, "no .obj files in this directory").into());
    }
    let frames = files
        .iter()
        .map(|f| read_obj(f))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &frames[0];
    for (k, (frame, file)) in frames.iter().zip(&files).enumerate().skip(1) {
        check_same_connectivity(first, frame, k).map_err(|m| IoError::format(file, m))?;
    }
    let mesh = Mesh::new(first.positions.len(), first.faces.clone())
        .map_err(|e| Error::from(e).in_file(&files[0]))?;
    let intensities = match intensity {
        Some(path) => intensity_array(path, frames.len(), mesh.n_vertices())?,
        None => frames
            .iter()
            .zip(&files)
            .map(|(frame, file)| {
                grey_values(frame).ok_or_else(|| {
                    IoError::format(
                        file,
                        "no vertex colours to take intensities from; give --intensity FILE.npy",
                    )
                })
            })
            .collect::<Result<_, _>>()?,
    };
    let positions = frames.into_iter().map(|f| f.positions).collect();
    MeshSequence::new(mesh, positions, intensities, times).map_err(|e| in_frame_file(e, &files))
}

/// Attaches the file of the frame a sequence error names.
fn in_frame_file(error: crate::flow::FlowError, files: &[PathBuf]) -> Error {
    use crate::flow::FlowError::{Frame, NonFiniteIntensity};
    match &error {
        Frame { frame, .. } | NonFiniteIntensity { frame, .. } => {
            let file = files[*frame].clone();
            Error::from(error).in_file(file)
        }
        _ => error.into(),
    }
}

fn check_same_connectivity(first: &ObjMesh, frame: &ObjMesh, k: usize) -> Result<(), String> {
    if frame.positions.len() != first.positions.len() {
        return Err(format!(
            "frame {k} has {} vertices, frame 0 has {}",
            frame.positions.len(),
            first.positions.len()
        ));
    }
    if frame.faces != first.faces {
        let face = frame
            .faces
            .iter()
            .zip(&first.faces)
            .position(|(a, b)| a != b)
            .unwrap_or(first.faces.len().min(frame.faces.len()));
        return Err(format!("frame {k} has different faces than frame 0 (first difference at face {face}; {} vs {} faces)", frame.faces.len(), first.faces.len()));
    }
    Ok(())
}

fn grey_values(frame: &ObjMesh) -> Option<Vec<f64>> {
    let colors = frame.colors.as_ref()?;
    Some(
        colors
            .iter()
            .map(|&[r, g, b]| {
                if r == g && g == b {
                    r
                } else {
                    0.2126 * r + 0.7152 * g + 0.0722 * b
                }
            })
            .collect(),
    )
}

fn intensity_array(
    path: &Path,
    n_frames: usize,
    n_vertices: usize,
) -> Result<Vec<Vec<f64>>, IoError> {
    let array = read_npy(path)?;
    if array.shape != [n_frames as u64, n_vertices as u64] {
        return Err(IoError::format(
            path,
            format!("intensity array has shape {:?}, expected ({n_frames}, {n_vertices}) = (frames, vertices)", array.shape),
        ));
    }
    Ok(array.data.chunks(n_vertices).map(<[f64]>::to_vec).collect())
}

/// Compares strings with digit runs ordered by value: `f2 < f10`.
pub fn natural_order(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    loop {
        match (x.first(), y.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(p), Some(q)) if p.is_ascii_digit() && q.is_ascii_digit() => {
                let (dx, rx) = split_digits(x);
                let (dy, ry) = split_digits(y);
                let (tx, ty) = (dx.trim_start_matches('0'), dy.trim_start_matches('0'));
                let order = tx
                    .len()
                    .cmp(&ty.len())
                    .then_with(|| tx.cmp(ty))
                    .then_with(|| dx.len().cmp(&dy.len()));
                if order != Ordering::Equal {
                    return order;
                }
                (x, y) = (rx, ry);
            }
            (Some(p), Some(q)) => {
                if p != q {
                    return p.cmp(q);
                }
                (x, y) = (&x[1..], &y[1..]);
            }
        }
    }
}

fn split_digits(s: &[u8]) -> (&str, &[u8]) {
    let n = s.iter().take_while(|c| c.is_ascii_digit()).count();
    (std::str::from_utf8(&s[..n]).expect("ASCII digits"), &s[n..])
}
