//! Wavefront OBJ: the subset that carries a triangle mesh with per-vertex colours or a texture.
//!
//! Read: `v x y z [w]` and `v x y z r g b` (colours, unclamped), `vt u [v [w]]`, `f` with `v`,
//! `v/vt`, `v//vn` or `v/vt/vn` references (negative = relative), polygons fan-triangulated,
//! `mtllib` and `usemtl` (for textures, see [`super::mtl`]). Other statements (`vn`, `o`, `g`,
//! `s`, …) are skipped.
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
    /// `(u, v)` of each `vt` line, `v` upwards.
    pub texcoords: Vec<[f64; 2]>,
    /// Per face: the texture coordinates of its corners, when its `f` line gives them.
    pub face_texcoords: Vec<Option<[u32; 3]>>,
    /// Per face: the index into `materials` of the `usemtl` in force, if any.
    pub face_materials: Vec<Option<u32>>,
    /// Material names in order of first `usemtl`.
    pub materials: Vec<String>,
    /// The `mtllib` file names, relative to the OBJ file.
    pub material_libraries: Vec<String>,
}

/// Reads an OBJ file (see the module docs for the supported subset).
pub fn read_obj(path: &Path) -> Result<ObjMesh, IoError> {
    obj_from_bytes(&super::read_file(path)?, path)
}

/// [`read_obj`] from a stream; `name` stands for it in errors (and `mtllib` names are the
/// caller's to resolve).
pub fn read_obj_from(reader: impl std::io::Read, name: &Path) -> Result<ObjMesh, IoError> {
    obj_from_bytes(&super::read_stream(reader, name)?, name)
}

/// The OBJ geometry in `bytes`, read from `path`.
fn obj_from_bytes(bytes: &[u8], path: &Path) -> Result<ObjMesh, IoError> {
    let text = String::from_utf8_lossy(bytes);
    parse_obj(&text).map_err(|(line, message)| {
        // A statement that breaks off where the file does: the file was cut short.
        let cut = line > 0 && line == text.lines().count() && !text.ends_with('\n');
        let message = match cut && !message.contains("truncated") {
            true => format!("{message} (the file ends inside this line: it looks truncated)"),
            false => message,
        };
        IoError::at_line(path, (line, message))
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
    let mut material = None;
    // (line) of each face, for range checks once all `v` and `vt` lines are known.
    let mut face_lines = Vec::new();
    let mut corners = Vec::new();
    for (number, line) in text.lines().enumerate().map(|(n, l)| (n + 1, l)) {
        // ASCII whitespace only: Unicode's `split_whitespace` was a fifth of reading a frame.
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => {
                let (position, color) = parse_vertex(tokens).map_err(|m| (number, m))?;
                mesh.positions.push(position);
                colors.extend(color);
            }
            Some("vt") => mesh
                .texcoords
                .push(parse_texcoord(tokens).map_err(|m| (number, m))?),
            Some("f") => {
                corners.clear();
                for token in tokens {
                    let corner = face_corner(token, mesh.positions.len(), mesh.texcoords.len());
                    corners.push(corner.map_err(|m| (number, m))?);
                }
                if corners.len() < 3 {
                    return Err((
                        number,
                        format!("a face needs at least 3 vertices, found {}", corners.len()),
                    ));
                }
                for k in 1..corners.len() - 1 {
                    let [a, b, c] = [corners[0], corners[k], corners[k + 1]];
                    mesh.faces.push([a.0, b.0, c.0]);
                    mesh.face_texcoords
                        .push(a.1.zip(b.1).zip(c.1).map(|((a, b), c)| [a, b, c]));
                    mesh.face_materials.push(material);
                    face_lines.push(number);
                }
            }
            Some("usemtl") => material = Some(material_index(&mut mesh.materials, rest(line, 6))),
            Some("mtllib") => mesh.material_libraries.push(rest(line, 6).to_string()),
            _ => {}
        }
    }
    check_face_references(&mesh, &face_lines)?;
    let n = mesh.positions.len();
    mesh.colors = match colors.len() {
        0 => None,
        k if k == n => Some(colors),
        // Only the very last vertex lacks its colour and the file stops in mid-line: the
        // file was cut short, not written with colours for some vertices.
        k if k + 1 == n && !text.ends_with('\n') && last_line_starts(text, "v ") => {
            return Err((
                text.lines().count(),
                "the file ends inside a vertex line: it looks truncated".into(),
            ))
        }
        k => {
            return Err((
                0,
                format!("{k} of {n} vertices have colours: give all or none"),
            ))
        }
    };
    Ok(mesh)
}

/// Whether the last line of `text` starts with `keyword`.
fn last_line_starts(text: &str, keyword: &str) -> bool {
    text.lines()
        .last()
        .is_some_and(|l| l.trim_start().starts_with(keyword))
}

/// The text after a keyword of `len` bytes, trimmed: names may contain spaces.
fn rest(line: &str, len: usize) -> &str {
    line.trim_start()[len..].trim()
}

fn material_index(materials: &mut Vec<String>, name: &str) -> u32 {
    let index = materials.iter().position(|m| m == name).unwrap_or_else(|| {
        materials.push(name.to_string());
        materials.len() - 1
    });
    index as u32
}

/// Faces may refer forward, so the ranges are checked once the file is read.
fn check_face_references(mesh: &ObjMesh, face_lines: &[usize]) -> Result<(), ParseError> {
    let (n, n_vt) = (mesh.positions.len(), mesh.texcoords.len());
    for ((face, texcoords), &line) in mesh.faces.iter().zip(&mesh.face_texcoords).zip(face_lines) {
        if let Some(&bad) = face.iter().find(|&&v| v as usize >= n) {
            return Err((
                line,
                format!(
                    "vertex {} does not exist (the file has {n} vertices)",
                    bad as u64 + 1
                ),
            ));
        }
        if let Some(&bad) = texcoords.iter().flatten().find(|&&t| t as usize >= n_vt) {
            return Err((
                line,
                format!(
                    "texture coordinate {} does not exist (the file has {n_vt})",
                    bad as u64 + 1
                ),
            ));
        }
    }
    Ok(())
}

fn parse_numbers<'a, const N: usize>(
    tokens: impl Iterator<Item = &'a str>,
) -> Result<([f64; N], usize), String> {
    let mut values = [0.0; N];
    let mut count = 0;
    for token in tokens {
        let value = token
            .parse::<f64>()
            .map_err(|_| format!("'{token}' is not a number"))?;
        if count < N {
            values[count] = value;
        }
        count += 1;
    }
    Ok((values, count))
}

fn parse_vertex<'a>(
    tokens: impl Iterator<Item = &'a str>,
) -> Result<(Vector3<f64>, Option<[f64; 3]>), String> {
    let (v, count) = parse_numbers::<7>(tokens)?;
    let position = Vector3::new(v[0], v[1], v[2]);
    match count {
        3 | 4 => Ok((position, None)),
        6 | 7 => Ok((position, Some([v[3], v[4], v[5]]))),
        n => Err(format!("a vertex needs 3, 4, 6 or 7 numbers, found {n}")),
    }
}

fn parse_texcoord<'a>(tokens: impl Iterator<Item = &'a str>) -> Result<[f64; 2], String> {
    match parse_numbers::<3>(tokens)? {
        (t, 1..=3) => Ok([t[0], t[1]]),
        (_, n) => Err(format!(
            "a texture coordinate needs 1 to 3 numbers, found {n}"
        )),
    }
}

/// The 0-based vertex and texture-coordinate indices of a face token `v[/vt[/vn]]`.
fn face_corner(
    token: &str,
    n_vertices: usize,
    n_texcoords: usize,
) -> Result<(u32, Option<u32>), String> {
    // A byte search: a `char` pattern's searcher cost more than the parse of a short token.
    let slash = |t: &str| t.bytes().position(|b| b == b'/');
    let (vertex, texcoord) = match slash(token) {
        Some(i) => {
            let rest = &token[i + 1..];
            (
                &token[..i],
                Some(&rest[..slash(rest).unwrap_or(rest.len())]),
            )
        }
        None => (token, None),
    };
    let vertex = resolve_reference(vertex, n_vertices)
        .map_err(|m| format!("'{token}' is not a vertex reference{m}"))?;
    let texcoord = match texcoord {
        Some(t) if !t.is_empty() => Some(
            resolve_reference(t, n_texcoords)
                .map_err(|m| format!("'{token}' has a bad texture coordinate reference{m}"))?,
        ),
        _ => None,
    };
    Ok((vertex, texcoord))
}

/// A 1-based OBJ index (negative: counts back from the `n_defined` entries read so far) as a
/// 0-based index; the error is a suffix for the caller's message.
fn resolve_reference(text: &str, n_defined: usize) -> Result<u32, String> {
    let index: i64 = text.parse().map_err(|_| String::new())?;
    let resolved = match index {
        i if i > 0 => i - 1,
        i if i < 0 => n_defined as i64 + i,
        _ => return Err(": index 0 is invalid (OBJ indices start at 1)".into()),
    };
    u32::try_from(resolved).map_err(|_| format!(": reference {index} is out of range"))
}
