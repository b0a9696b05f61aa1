//! Wavefront OBJ: the subset that carries a triangle mesh with per-vertex colours.
//!
//! Read: `v x y z [w]` and `v x y z r g b` (colours, unclamped), `f` with `v`, `v/vt`, `v//vn`
//! or `v/vt/vn` references (negative = relative), polygons fan-triangulated. Other statements
//! (`vt`, `vn`, `o`, `g`, `s`, `usemtl`, `mtllib`, …) are skipped.
//!
//! Why not tobj: it renumbers vertices by first use in the faces, which drops isolated vertices
//! silently and breaks the identity "vertex i of frame k is vertex i of frame k + 1" whenever the
//! faces do not list vertices in file order. Here vertex `i` is the `i`-th `v` line, always, and
//! every error names its line.

use super::{write_atomically, IoError};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// A triangle mesh as stored in an OBJ file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjMesh {
    pub positions: Vec<Vector3<f64>>,
    pub faces: Vec<[u32; 3]>,
    /// One RGB colour per vertex when the file gives colours on its `v` lines.
    pub colors: Option<Vec<[f64; 3]>>,
}

/// Reads an OBJ file (see the module docs for the supported subset).
pub fn read_obj(path: &Path) -> Result<ObjMesh, IoError> {
    let text = std::fs::read(path).map_err(|e| IoError::file(path, e))?;
    let text = String::from_utf8_lossy(&text);
    parse_obj(&text).map_err(|(line, message)| match line {
        0 => IoError::format(path, message),
        line => IoError::Parse {
            path: path.to_path_buf(),
            line,
            message,
        },
    })
}

/// Writes positions, triangles and optional per-vertex colours; numbers are printed in their
/// shortest round-trip form, so reading the file back gives the same bits.
pub fn write_obj(
    path: &Path,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    colors: Option<&[[f64; 3]]>,
) -> Result<(), IoError> {
    write_atomically(path, |w| {
        writeln!(w, "# written by meshflow")?;
        for (i, p) in positions.iter().enumerate() {
            write!(w, "v {} {} {}", p.x, p.y, p.z)?;
            if let Some([r, g, b]) = colors.map(|c| c[i]) {
                write!(w, " {r} {g} {b}")?;
            }
            writeln!(w)?;
        }
        for [a, b, c] in faces {
            writeln!(w, "f {} {} {}", a + 1, b + 1, c + 1)?;
        }
        Ok(())
    })
}

/// `(line, message)`; line 0 for errors about the whole file.
type ParseError = (usize, String);

fn parse_obj(text: &str) -> Result<ObjMesh, ParseError> {
    let mut mesh = ObjMesh::default();
    let mut colors = Vec::new();
    // (line, vertex index) of each face corner, checked once all `v` lines are known.
    let mut face_lines = Vec::new();
    for (number, line) in text.lines().enumerate().map(|(n, l)| (n + 1, l)) {
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("v") => {
                let values = tokens
                    .map(|t| {
                        t.parse::<f64>()
                            .map_err(|_| (number, format!("'{t}' is not a number")))
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                let (position, color) = split_vertex(&values).ok_or_else(|| {
                    (
                        number,
                        format!(
                            "a vertex needs 3, 4, 6 or 7 numbers, found {}",
                            values.len()
                        ),
                    )
                })?;
                mesh.positions.push(position);
                colors.extend(color);
            }
            Some("f") => {
                let corners = tokens
                    .map(|t| vertex_reference(t, mesh.positions.len()).map_err(|m| (number, m)))
                    .collect::<Result<Vec<_>, _>>()?;
                if corners.len() < 3 {
                    return Err((
                        number,
                        format!("a face needs at least 3 vertices, found {}", corners.len()),
                    ));
                }
                for k in 1..corners.len() - 1 {
                    mesh.faces.push([corners[0], corners[k], corners[k + 1]]);
                    face_lines.push(number);
                }
            }
            _ => {}
        }
    }
    let n = mesh.positions.len();
    for (face, &line) in mesh.faces.iter().zip(&face_lines) {
        if let Some(&bad) = face.iter().find(|&&v| v as usize >= n) {
            return Err((
                line,
                format!(
                    "vertex {} does not exist (the file has {n} vertices)",
                    bad as u64 + 1
                ),
            ));
        }
    }
    mesh.colors = match colors.len() {
        0 => None,
        k if k == n => Some(colors),
        k => {
            return Err((
                0,
                format!("{k} of {n} vertices have colours: give all or none"),
            ))
        }
    };
    Ok(mesh)
}

fn split_vertex(values: &[f64]) -> Option<(Vector3<f64>, Option<[f64; 3]>)> {
    let position = Vector3::new(*values.first()?, *values.get(1)?, *values.get(2)?);
    match values.len() {
        3 | 4 => Some((position, None)),
        6 | 7 => Some((position, Some([values[3], values[4], values[5]]))),
        _ => None,
    }
}

/// The 0-based vertex index of a face token `v[/vt[/vn]]`; negative indices count back from the
/// `n_defined` vertices read so far.
fn vertex_reference(token: &str, n_defined: usize) -> Result<u32, String> {
    let index_text = token.split('/').next().unwrap_or_default();
    let index: i64 = index_text
        .parse()
        .map_err(|_| format!("'{token}' is not a vertex reference"))?;
    let resolved = match index {
        i if i > 0 => i - 1,
        i if i < 0 => n_defined as i64 + i,
        _ => return Err("vertex index 0 is invalid (OBJ indices start at 1)".into()),
    };
    u32::try_from(resolved).map_err(|_| format!("vertex reference {index} is out of range"))
}
