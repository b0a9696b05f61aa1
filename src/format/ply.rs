//! Stanford PLY: triangle meshes with per-vertex colours and scalar properties.
//!
//! A PLY file is an ASCII header followed by a body:
//!
//! ```text
//! ply
//! format binary_little_endian 1.0          (or ascii 1.0, binary_big_endian 1.0)
//! comment made by hand                     (comment and obj_info lines are ignored)
//! element vertex 8
//! property float x                         (a scalar: type, name)
//! property uchar red
//! element face 6
//! property list uchar int vertex_indices   (a list: count type, item type, name)
//! end_header
//! <the 8 vertex records, then the 6 face records>
//! ```
//!
//! The body holds the declared number of records of each element, elements in header order, each
//! record its properties in header order: in ASCII as whitespace-separated numbers, in binary as
//! packed values of the declared types in the declared byte order, a list as its length followed
//! by that many items. Scalar types: `char`/`int8`, `uchar`/`uint8`, `short`/`int16`,
//! `ushort`/`uint16`, `int`/`int32`, `uint`/`uint32`, `float`/`float32`, `double`/`float64`.
//!
//! Read: element `vertex` (scalar properties `x y z` required) and element `face` with a list
//! `vertex_indices` (or `vertex_index`) of 0-based vertex indices; polygons are fan-triangulated
//! `(0, k, k + 1)`. Triangle strips, element `tristrips` with a list `vertex_indices`, are read
//! too (after the faces, in file order): `−1` restarts a strip, and triangle `k` of a strip
//! (counted from its start) is `(v_k, v_{k+1}, v_{k+2})` for even `k`, `(v_{k+1}, v_k,
//! v_{k+2})` for odd `k`, so that all have the orientation of the first; triangles with a
//! repeated vertex (strips repeat vertices to turn) are skipped. Colours come from `red green blue` when all three are present: integer types
//! divided by their maximum (`uchar` by 255, `ushort` by 65535, …), float types as stored. `alpha`
//! is dropped; every other scalar vertex property is kept as f64, in header order. List
//! properties of vertices, other face and strip properties and all other elements are skipped. Element
//! numbers in error messages count from 0, like the indices in the file.
//!
//! Before an element is read, its declared count is checked against the bytes left (a binary
//! value takes its size, an ASCII number at least two bytes with its separator), so a header that
//! claims 10^12 vertices in a small file is reported as truncated instead of allocated for.
//!
//! Write: positions, colours and properties as `double` (ASCII in Rust's shortest round-trip
//! form), faces as `list uchar int vertex_indices`, so reading the file back gives the same bits.

use super::{write_atomically, IoError};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// A triangle mesh as stored in a PLY file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    pub positions: Vec<Vector3<f64>>,
    /// 0-based vertex indices: polygons fan-triangulated, then the triangles of the strips.
    pub faces: Vec<[u32; 3]>,
    /// One RGB colour per vertex when the file has `red green blue`, scaled to [0, 1] for
    /// integer types.
    pub colors: Option<Vec<[f64; 3]>>,
    /// Every other scalar vertex property (not `x y z`, the colour channels or `alpha`), in header
    /// order: name and one value per vertex.
    pub properties: Vec<(String, Vec<f64>)>,
}

/// How [`write_ply`] encodes the body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    Ascii,
    BinaryLittleEndian,
}

/// Reads a PLY file (see the module docs for what is read and what is skipped).
pub fn read_ply(path: &Path) -> Result<PlyMesh, IoError> {
    ply_from_bytes(&super::read_file(path)?, path)
}

/// [`read_ply`] from a stream; `name` stands for it in errors.
pub fn read_ply_from(reader: impl std::io::Read, name: &Path) -> Result<PlyMesh, IoError> {
    ply_from_bytes(&super::read_stream(reader, name)?, name)
}

/// The PLY mesh in `bytes`, read from `path`.
fn ply_from_bytes(bytes: &[u8], path: &Path) -> Result<PlyMesh, IoError> {
    parse_ply(bytes).map_err(|e| match e {
        PlyError::At(e) => IoError::at_line(path, e),
        PlyError::Budget(e) => IoError::too_large(path, e),
    })
}

/// A failure of [`parse_ply`]: at a line (0: the whole file), or a declared size over the
/// memory limit.
enum PlyError {
    At(ParseError),
    Budget(crate::limits::OverBudget),
}

impl From<ParseError> for PlyError {
    fn from(e: ParseError) -> Self {
        Self::At(e)
    }
}

/// Checks what a vertex, face or strip element will take in memory, which a file of one-byte
/// properties declares at up to 24 times its size: 3 coordinates (and 3 colour channels) of
/// 8 bytes a vertex, 12 bytes a triangle.
fn check_budget(element: &Element, layout: &VertexLayout) -> Result<(), PlyError> {
    let per_record = match element.name.as_str() {
        "vertex" => 24 + 24 * u64::from(layout.has_colors) + 8 * layout.extra_names.len() as u64,
        "face" | "tristrips" => 12,
        _ => return Ok(()),
    };
    let what = format!("element '{}' of {} records", element.name, element.count);
    crate::limits::check_items(what, element.count, per_record).map_err(PlyError::Budget)
}

/// Writes a triangle mesh with optional per-vertex colours and named per-vertex properties;
/// every number is written as a `double`, so reading the file back gives the same bits.
pub fn write_ply(
    path: &Path,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    colors: Option<&[[f64; 3]]>,
    properties: &[(&str, &[f64])],
    encoding: PlyEncoding,
) -> Result<(), IoError> {
    check_output(positions.len(), faces, colors, properties)
        .map_err(|message| IoError::format(path, message))?;
    write_atomically(path, |w| {
        write_header(
            w,
            positions.len(),
            faces.len(),
            colors.is_some(),
            properties,
            encoding,
        )?;
        for (i, p) in positions.iter().enumerate() {
            let values = [p.x, p.y, p.z]
                .into_iter()
                .chain(colors.map(|c| c[i]).into_iter().flatten())
                .chain(properties.iter().map(|(_, values)| values[i]));
            write_vertex(w, values, encoding)?;
        }
        faces
            .iter()
            .try_for_each(|face| write_face(w, face, encoding))
    })
}

// ---------------------------------------------------------------------------------------------
// Writing

/// Names the reader would not give back as properties.
const RESERVED_NAMES: [&str; 7] = ["x", "y", "z", "red", "green", "blue", "alpha"];

fn check_output(
    n: usize,
    faces: &[[u32; 3]],
    colors: Option<&[[f64; 3]]>,
    properties: &[(&str, &[f64])],
) -> Result<(), String> {
    if let Some(colors) = colors.filter(|c| c.len() != n) {
        return Err(format!("{} colours for {n} vertices", colors.len()));
    }
    for (k, (name, values)) in properties.iter().enumerate() {
        if name.is_empty() || name.contains(char::is_whitespace) {
            return Err(format!(
                "property name '{name}' must be non-empty without spaces"
            ));
        }
        if RESERVED_NAMES.contains(name) || properties[..k].iter().any(|(n, _)| n == name) {
            return Err(format!("property name '{name}' is reserved or used twice"));
        }
        if values.len() != n {
            return Err(format!(
                "property '{name}' has {} values for {n} vertices",
                values.len()
            ));
        }
    }
    // Indices are written as `int`.
    let limit = n.min(i32::MAX as usize + 1);
    crate::mesh::check_index_range(faces, limit).map_err(|e| e.to_string())
}

fn write_header(
    w: &mut impl Write,
    n_vertices: usize,
    n_faces: usize,
    has_colors: bool,
    properties: &[(&str, &[f64])],
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
    };
    writeln!(w, "ply\nformat {format} 1.0\ncomment written by meshflow")?;
    writeln!(w, "element vertex {n_vertices}")?;
    let colors: &[&str] = if has_colors {
        &RESERVED_NAMES[3..6]
    } else {
        &[]
    };
    let names = RESERVED_NAMES[..3]
        .iter()
        .chain(colors)
        .chain(properties.iter().map(|(name, _)| name));
    for name in names {
        writeln!(w, "property double {name}")?;
    }
    writeln!(w, "element face {n_faces}")?;
    writeln!(w, "property list uchar int vertex_indices\nend_header")
}

fn write_vertex(
    w: &mut impl Write,
    mut values: impl Iterator<Item = f64>,
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    match encoding {
        PlyEncoding::Ascii => {
            for (k, value) in values.enumerate() {
                let separator = if k == 0 { "" } else { " " };
                write!(w, "{separator}{value}")?;
            }
            writeln!(w)
        }
        PlyEncoding::BinaryLittleEndian => {
            values.try_for_each(|value| w.write_all(&value.to_le_bytes()))
        }
    }
}

fn write_face(
    w: &mut impl Write,
    &[a, b, c]: &[u32; 3],
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    match encoding {
        PlyEncoding::Ascii => writeln!(w, "3 {a} {b} {c}"),
        PlyEncoding::BinaryLittleEndian => {
            w.write_all(&[3])?;
            // check_output guarantees that the indices fit in an `int`.
            [a, b, c]
                .iter()
                .try_for_each(|&v| w.write_all(&(v as i32).to_le_bytes()))
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Reading: the header

/// `(line, message)`; line 0 for errors without a line (binary data, the file as a whole).
type ParseError = (usize, String);

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Self::I8 => "char",
            Self::U8 => "uchar",
            Self::I16 => "short",
            Self::U16 => "ushort",
            Self::I32 => "int",
            Self::U32 => "uint",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// The smallest and largest value of an integer type; `None` for float types.
    fn integer_range(self) -> Option<(i64, i64)> {
        match self {
            Self::I8 => Some((i8::MIN.into(), i8::MAX.into())),
            Self::U8 => Some((0, u8::MAX.into())),
            Self::I16 => Some((i16::MIN.into(), i16::MAX.into())),
            Self::U16 => Some((0, u16::MAX.into())),
            Self::I32 => Some((i32::MIN.into(), i32::MAX.into())),
            Self::U32 => Some((0, u32::MAX.into())),
            Self::F32 | Self::F64 => None,
        }
    }

    /// The stored value that means full intensity in a colour channel of this type.
    fn full_intensity(self) -> f64 {
        self.integer_range().map_or(1.0, |(_, max)| max as f64)
    }

    /// A value from its `size()` bytes.
    fn decode(self, raw: &[u8], big_endian: bool) -> f64 {
        let mut le = [0u8; 8];
        le[..raw.len()].copy_from_slice(raw);
        if big_endian {
            le[..raw.len()].reverse();
        }
        let [a, b, c, d, ..] = le;
        match self {
            Self::I8 => i8::from_le_bytes([a]).into(),
            Self::U8 => a.into(),
            Self::I16 => i16::from_le_bytes([a, b]).into(),
            Self::U16 => u16::from_le_bytes([a, b]).into(),
            Self::I32 => i32::from_le_bytes([a, b, c, d]).into(),
            Self::U32 => u32::from_le_bytes([a, b, c, d]).into(),
            Self::F32 => f32::from_le_bytes([a, b, c, d]).into(),
            Self::F64 => f64::from_le_bytes(le),
        }
    }

    /// An ASCII number of this type: integer types must be integers in range.
    fn parse_text(self, token: &str) -> Option<f64> {
        match self.integer_range() {
            Some((min, max)) => token
                .parse::<i64>()
                .ok()
                .filter(|v| (min..=max).contains(v))
                .map(|v| v as f64),
            None => token.parse().ok(),
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

impl Kind {
    /// The type of the first value of a record of this property.
    fn leading_type(self) -> Scalar {
        match self {
            Kind::Scalar(ty) | Kind::List { count: ty, .. } => ty,
        }
    }
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

#[derive(Clone, Copy, Debug)]
enum Format {
    Ascii,
    Binary { big_endian: bool },
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Where the body starts: its byte offset and, for ASCII messages, its line number.
    body_start: usize,
    body_line: usize,
}

impl Header {
    fn element(&self, name: &str) -> Option<&Element> {
        self.elements.iter().find(|e| e.name == name)
    }
}

fn parse_header(bytes: &[u8]) -> Result<Header, ParseError> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut start = 0;
    let mut number = 0;
    while start < bytes.len() {
        let end = bytes[start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |p| start + p);
        number += 1;
        let line = String::from_utf8_lossy(&bytes[start..end]);
        if number == 1 && line.trim() != "ply" {
            return Err((0, "not a PLY file (the first line must be 'ply')".into()));
        }
        let mut tokens = line.split_whitespace();
        let at_line = |message: String| (number, message);
        match tokens.next() {
            Some("end_header") => {
                let format = format.ok_or((0, "the header has no 'format' line".to_string()))?;
                return Ok(Header {
                    format,
                    elements,
                    body_start: (end + 1).min(bytes.len()),
                    body_line: number + 1,
                });
            }
            Some("format") => format = Some(parse_format(tokens).map_err(at_line)?),
            Some("element") => {
                let element = parse_element(tokens).map_err(at_line)?;
                if elements.iter().any(|e| e.name == element.name) {
                    return Err(at_line(format!(
                        "element '{}' declared twice",
                        element.name
                    )));
                }
                elements.push(element);
            }
            Some("property") => {
                let property = parse_property(tokens).map_err(at_line)?;
                let element = elements
                    .last_mut()
                    .ok_or_else(|| at_line("a property before any element".into()))?;
                if element.properties.iter().any(|p| p.name == property.name) {
                    return Err(at_line(format!(
                        "property '{}' declared twice in element '{}'",
                        property.name, element.name
                    )));
                }
                element.properties.push(property);
            }
            Some("ply" | "comment" | "obj_info") | None => {}
            Some(other) => return Err(at_line(format!("unknown header keyword '{other}'"))),
        }
        start = end + 1;
    }
    Err((0, "the header has no 'end_header' line".into()))
}

fn parse_format<'a>(mut tokens: impl Iterator<Item = &'a str>) -> Result<Format, String> {
    let format = match tokens.next() {
        Some("ascii") => Format::Ascii,
        Some("binary_little_endian") => Format::Binary { big_endian: false },
        Some("binary_big_endian") => Format::Binary { big_endian: true },
        other => {
            return Err(format!(
                "unknown format '{}' (expected ascii, binary_little_endian or binary_big_endian)",
                other.unwrap_or_default()
            ))
        }
    };
    match tokens.next() {
        Some("1.0" | "1") => Ok(format),
        other => Err(format!(
            "unsupported PLY version '{}' (expected 1.0)",
            other.unwrap_or_default()
        )),
    }
}

fn parse_element<'a>(mut tokens: impl Iterator<Item = &'a str>) -> Result<Element, String> {
    let (Some(name), Some(count)) = (tokens.next(), tokens.next()) else {
        return Err("expected 'element <name> <count>'".into());
    };
    let count = count
        .parse()
        .map_err(|_| format!("element count '{count}' is not a non-negative integer"))?;
    Ok(Element {
        name: name.to_string(),
        count,
        properties: Vec::new(),
    })
}

fn parse_property<'a>(mut tokens: impl Iterator<Item = &'a str>) -> Result<Property, String> {
    let kind = match tokens.next() {
        Some("list") => {
            let count = scalar_type(tokens.next())?;
            if count.integer_range().is_none() {
                return Err(format!(
                    "a list length must have an integer type, not '{}'",
                    count.name()
                ));
            }
            let item = scalar_type(tokens.next())?;
            Kind::List { count, item }
        }
        ty => Kind::Scalar(scalar_type(ty)?),
    };
    let name = tokens.next().ok_or("property without a name")?;
    Ok(Property {
        name: name.to_string(),
        kind,
    })
}

fn scalar_type(token: Option<&str>) -> Result<Scalar, String> {
    let token = token.ok_or("property without a type")?;
    Scalar::from_name(token).ok_or_else(|| {
        format!(
            "unsupported property type '{token}' (PLY has char, uchar, short, ushort, int, uint, \
             float, double and int8 … float64)"
        )
    })
}

/// Where each vertex property goes.
#[derive(Clone, Copy, Debug)]
enum Slot {
    Coordinate(usize),
    Channel(usize),
    Extra(usize),
    Skip,
}

struct VertexLayout {
    /// One slot per property of the vertex element.
    slots: Vec<Slot>,
    has_colors: bool,
    extra_names: Vec<String>,
}

impl VertexLayout {
    fn new(element: &Element) -> Result<Self, String> {
        let has_scalar = |name: &str| {
            element
                .properties
                .iter()
                .any(|p| p.name == name && matches!(p.kind, Kind::Scalar(_)))
        };
        if let Some(axis) = ["x", "y", "z"].into_iter().find(|&a| !has_scalar(a)) {
            return Err(format!(
                "the vertex element has no scalar property '{axis}'"
            ));
        }
        let has_colors = ["red", "green", "blue"].into_iter().all(has_scalar);
        let mut extra_names = Vec::new();
        let slots = element
            .properties
            .iter()
            .map(|p| match (p.kind, p.name.as_str()) {
                (Kind::List { .. }, _) | (_, "alpha") => Slot::Skip,
                (_, "x") => Slot::Coordinate(0),
                (_, "y") => Slot::Coordinate(1),
                (_, "z") => Slot::Coordinate(2),
                (_, "red") if has_colors => Slot::Channel(0),
                (_, "green") if has_colors => Slot::Channel(1),
                (_, "blue") if has_colors => Slot::Channel(2),
                (_, name) => {
                    extra_names.push(name.to_string());
                    Slot::Extra(extra_names.len() - 1)
                }
            })
            .collect();
        Ok(Self {
            slots,
            has_colors,
            extra_names,
        })
    }
}

/// The position of the vertex index list among the properties of a face or strip element.
fn index_list(element: &Element) -> Result<usize, String> {
    let position = element
        .properties
        .iter()
        .position(|p| matches!(p.name.as_str(), "vertex_indices" | "vertex_index"))
        .ok_or(format!(
            "the {} element has no 'vertex_indices' (or 'vertex_index') property",
            element.name
        ))?;
    match element.properties[position].kind {
        Kind::List { .. } => Ok(position),
        Kind::Scalar(_) => Err(format!(
            "face property '{}' must be a list",
            element.properties[position].name
        )),
    }
}

// ---------------------------------------------------------------------------------------------
// Reading: the body

fn parse_ply(bytes: &[u8]) -> Result<PlyMesh, PlyError> {
    let header = parse_header(bytes)?;
    let vertices = header
        .element("vertex")
        .ok_or((0, "the file has no vertex element".to_string()))?;
    let layout = VertexLayout::new(vertices).map_err(|m| (0, m))?;
    let [faces, strips] = ["face", "tristrips"].map(|name| header.element(name));
    if !faces.into_iter().chain(strips).any(|e| e.count > 0) {
        return Err(PlyError::At((
            0,
            "no faces: the file has no face or tristrips element, or empty ones (a point \
             cloud, not a mesh)"
                .to_string(),
        )));
    }
    let list = |element: Option<&Element>| {
        element
            .filter(|e| e.count > 0)
            .map(index_list)
            .transpose()
            .map_err(|m| (0, m))
    };
    let plan = Plan {
        layout,
        index_list: list(faces)?.unwrap_or(0),
        strip_list: list(strips)?.unwrap_or(0),
        vertex_count: vertices.count,
    };
    let body = &bytes[header.body_start..];
    Ok(match header.format {
        Format::Ascii => read_body(AsciiBody::new(body, header.body_line), &header, &plan)?,
        Format::Binary { big_endian } => read_body(
            BinaryBody {
                bytes: body,
                pos: 0,
                big_endian,
            },
            &header,
            &plan,
        )?,
    })
}

/// What the header says about the vertex, face and strip records.
struct Plan {
    layout: VertexLayout,
    /// The positions of the index lists among the face and the strip properties.
    index_list: usize,
    strip_list: usize,
    vertex_count: u64,
}

/// A failure inside one record, located by the caller.
#[derive(Debug)]
enum RecordError {
    /// The data ended.
    End,
    /// An ASCII token that is not a number of the declared type.
    NotANumber {
        line: usize,
        token: String,
        ty: Scalar,
    },
    /// A value that is not acceptable where it stands.
    Invalid { line: usize, message: String },
}

/// The values of a PLY body, ASCII or binary.
trait Body {
    /// The next value, of type `ty`.
    fn value(&mut self, ty: Scalar) -> Result<f64, RecordError>;
    /// Skips `n` values of type `ty`.
    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), RecordError>;
    /// The fewest bytes one value of type `ty` can take.
    fn min_bytes(&self, ty: Scalar) -> u64;
    /// The bytes not read yet.
    fn remaining(&self) -> u64;
    /// The line of the last value read, for messages; 0 in binary, which has no lines.
    fn line(&self) -> usize;

    fn invalid(&self, message: String) -> RecordError {
        RecordError::Invalid {
            line: self.line(),
            message,
        }
    }
}

struct AsciiBody<'a> {
    text: &'a [u8],
    pos: usize,
    /// The line at `pos`.
    scan_line: usize,
    /// The line of the last token returned.
    token_line: usize,
}

impl<'a> AsciiBody<'a> {
    fn new(text: &'a [u8], first_line: usize) -> Self {
        Self {
            text,
            pos: 0,
            scan_line: first_line,
            token_line: first_line,
        }
    }

    fn token(&mut self) -> Result<&'a [u8], RecordError> {
        while let Some(&b) = self.text.get(self.pos).filter(|b| b.is_ascii_whitespace()) {
            self.scan_line += usize::from(b == b'\n');
            self.pos += 1;
        }
        let start = self.pos;
        while self
            .text
            .get(self.pos)
            .is_some_and(|b| !b.is_ascii_whitespace())
        {
            self.pos += 1;
        }
        self.token_line = self.scan_line;
        match &self.text[start..self.pos] {
            [] => Err(RecordError::End),
            token => Ok(token),
        }
    }
}

impl Body for AsciiBody<'_> {
    fn value(&mut self, ty: Scalar) -> Result<f64, RecordError> {
        let token = self.token()?;
        std::str::from_utf8(token)
            .ok()
            .and_then(|t| ty.parse_text(t))
            .ok_or_else(|| RecordError::NotANumber {
                line: self.token_line,
                token: String::from_utf8_lossy(token).chars().take(40).collect(),
                ty,
            })
    }

    fn skip(&mut self, _: Scalar, n: u64) -> Result<(), RecordError> {
        (0..n).try_for_each(|_| self.token().map(|_| ()))
    }

    fn min_bytes(&self, _: Scalar) -> u64 {
        2
    }

    fn remaining(&self) -> u64 {
        (self.text.len() - self.pos) as u64
    }

    fn line(&self) -> usize {
        self.token_line
    }
}

struct BinaryBody<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Body for BinaryBody<'_> {
    fn value(&mut self, ty: Scalar) -> Result<f64, RecordError> {
        let raw = self
            .bytes
            .get(self.pos..self.pos + ty.size())
            .ok_or(RecordError::End)?;
        self.pos += ty.size();
        Ok(ty.decode(raw, self.big_endian))
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), RecordError> {
        let length = n
            .checked_mul(ty.size() as u64)
            .filter(|&length| length <= self.remaining())
            .ok_or(RecordError::End)?;
        self.pos += length as usize;
        Ok(())
    }

    fn min_bytes(&self, ty: Scalar) -> u64 {
        ty.size() as u64
    }

    fn remaining(&self) -> u64 {
        (self.bytes.len() - self.pos) as u64
    }

    fn line(&self) -> usize {
        0
    }
}

fn read_body<B: Body>(mut body: B, header: &Header, plan: &Plan) -> Result<PlyMesh, PlyError> {
    let mut mesh = PlyMesh::default();
    let mut strip_triangles = Vec::new();
    // An element without properties has no bytes, whatever its count.
    for element in header.elements.iter().filter(|e| !e.properties.is_empty()) {
        check_fits(&body, element)?;
        check_budget(element, &plan.layout)?;
        match element.name.as_str() {
            "vertex" => read_vertices(&mut body, element, &plan.layout, &mut mesh)?,
            "face" => mesh.faces = read_faces(&mut body, element, plan)?,
            "tristrips" => strip_triangles = read_strips(&mut body, element, plan)?,
            _ => skip_records(&mut body, element)?,
        }
    }
    mesh.faces.extend(strip_triangles);
    Ok(mesh)
}

/// Fails when the bytes left cannot hold the element's declared records, before anything is
/// allocated for them.
fn check_fits(body: &impl Body, element: &Element) -> Result<(), ParseError> {
    let per_record: u64 = element
        .properties
        .iter()
        .map(|p| body.min_bytes(p.kind.leading_type()))
        .sum();
    let needed = per_record.checked_mul(element.count);
    // + 1: the last ASCII number of the file needs no separator.
    if needed.is_some_and(|needed| needed <= body.remaining() + 1) {
        return Ok(());
    }
    let needed = needed.map_or("more than 2^64".into(), |n| format!("at least {n}"));
    Err((
        0,
        format!(
            "truncated file: the header declares {} '{}' records, which need {needed} bytes, \
             but only {} bytes are left",
            element.count,
            element.name,
            body.remaining()
        ),
    ))
}

/// Places a record failure: element, record number and property, and the line in ASCII.
fn locate<'a>(
    element: &'a Element,
    index: u64,
    property: &'a Property,
) -> impl Fn(RecordError) -> ParseError + 'a {
    move |error| match error {
        RecordError::End => (
            0,
            format!(
                "truncated file: the data ends in {} {index} (the header declares {})",
                element.name, element.count
            ),
        ),
        RecordError::NotANumber { line, token, ty } => (
            line,
            format!(
                "'{token}' is not a valid {} (property '{}' of {} {index})",
                ty.name(),
                property.name,
                element.name
            ),
        ),
        RecordError::Invalid { line, message } => {
            (line, format!("{} {index}: {message}", element.name))
        }
    }
}

/// Capacity for `count` records: the count has passed [`check_fits`], so it is bounded by the
/// file size.
fn capacity(count: u64) -> usize {
    usize::try_from(count).unwrap_or(0)
}

fn read_vertices(
    body: &mut impl Body,
    element: &Element,
    layout: &VertexLayout,
    mesh: &mut PlyMesh,
) -> Result<(), ParseError> {
    let n = capacity(element.count);
    let mut positions = Vec::with_capacity(n);
    let mut colors = Vec::with_capacity(if layout.has_colors { n } else { 0 });
    let mut extras = vec![Vec::with_capacity(n); layout.extra_names.len()];
    for index in 0..element.count {
        let mut position = Vector3::zeros();
        let mut color = [0.0; 3];
        for (property, &slot) in element.properties.iter().zip(&layout.slots) {
            let at = locate(element, index, property);
            let ty = match property.kind {
                Kind::Scalar(ty) => ty,
                list => {
                    skip_property(body, list).map_err(at)?;
                    continue;
                }
            };
            let value = body.value(ty).map_err(at)?;
            match slot {
                Slot::Coordinate(axis) => position[axis] = value,
                Slot::Channel(channel) => color[channel] = value / ty.full_intensity(),
                Slot::Extra(k) => extras[k].push(value),
                Slot::Skip => {}
            }
        }
        positions.push(position);
        if layout.has_colors {
            colors.push(color);
        }
    }
    mesh.positions = positions;
    mesh.colors = layout.has_colors.then_some(colors);
    mesh.properties = layout.extra_names.iter().cloned().zip(extras).collect();
    Ok(())
}

fn read_faces(
    body: &mut impl Body,
    element: &Element,
    plan: &Plan,
) -> Result<Vec<[u32; 3]>, ParseError> {
    let mut faces = Vec::with_capacity(capacity(element.count));
    let mut corners = Vec::new();
    read_index_lists(body, element, plan.index_list, |body, count, item| {
        read_corners(body, count, item, plan.vertex_count, &mut corners)?;
        let fan = (1..corners.len() - 1).map(|k| [corners[0], corners[k], corners[k + 1]]);
        faces.extend(fan);
        Ok(())
    })?;
    Ok(faces)
}

fn read_strips(
    body: &mut impl Body,
    element: &Element,
    plan: &Plan,
) -> Result<Vec<[u32; 3]>, ParseError> {
    let mut triangles = Vec::new();
    let mut strip = Vec::new();
    read_index_lists(body, element, plan.strip_list, |body, count, item| {
        let n = list_length(body, count, item)?;
        strip.clear();
        for _ in 0..n {
            let value = body.value(item)?;
            if value == -1.0 {
                add_strip(&strip, &mut triangles);
                strip.clear();
                continue;
            }
            let vertex = vertex_index(value, plan.vertex_count).map_err(|m| body.invalid(m))?;
            strip.push(vertex);
        }
        add_strip(&strip, &mut triangles);
        Ok(())
    })?;
    Ok(triangles)
}

/// Reads the records of a face or strip element: the index list (property `list`, with its
/// count and item types) by `read`, the other properties skipped.
fn read_index_lists<B: Body>(
    body: &mut B,
    element: &Element,
    list: usize,
    mut read: impl FnMut(&mut B, Scalar, Scalar) -> Result<(), RecordError>,
) -> Result<(), ParseError> {
    for index in 0..element.count {
        for (k, property) in element.properties.iter().enumerate() {
            let at = locate(element, index, property);
            match property.kind {
                Kind::List { count, item } if k == list => read(body, count, item).map_err(at)?,
                kind => skip_property(body, kind).map_err(at)?,
            }
        }
    }
    Ok(())
}

/// The triangles of one strip (see the module docs), those with a repeated vertex skipped.
fn add_strip(strip: &[u32], triangles: &mut Vec<[u32; 3]>) {
    for (k, window) in strip.windows(3).enumerate() {
        let [a, b, c] = [window[0], window[1], window[2]];
        if a != b && b != c && a != c {
            triangles.push(if k % 2 == 0 { [a, b, c] } else { [b, a, c] });
        }
    }
}

/// Reads one polygon's vertex indices into `corners` (at least 3, each naming a vertex).
fn read_corners(
    body: &mut impl Body,
    count: Scalar,
    item: Scalar,
    vertex_count: u64,
    corners: &mut Vec<u32>,
) -> Result<(), RecordError> {
    let n = list_length(body, count, item)?;
    if n < 3 {
        return Err(body.invalid(format!("{n} vertex indices; a face needs at least 3")));
    }
    corners.clear();
    for _ in 0..n {
        let value = body.value(item)?;
        let index = vertex_index(value, vertex_count).map_err(|m| body.invalid(m))?;
        corners.push(index);
    }
    Ok(())
}

fn vertex_index(value: f64, vertex_count: u64) -> Result<u32, String> {
    if value < 0.0 {
        return Err(format!("negative vertex index {value}"));
    }
    if value.fract() != 0.0 {
        return Err(format!("vertex index {value} is not an integer"));
    }
    u32::try_from(value as u64)
        .ok()
        .filter(|&v| u64::from(v) < vertex_count)
        .ok_or_else(|| {
            format!("vertex index {value} is out of range (the file has {vertex_count} vertices)")
        })
}

/// The length of a list whose count is of type `ty`; one longer than the bytes left for its
/// `item`s can hold is the end of the data (it would otherwise be skipped token by token or
/// grow a polygon until the data ends).
fn list_length(body: &mut impl Body, ty: Scalar, item: Scalar) -> Result<u64, RecordError> {
    let value = body.value(ty)?;
    if value < 0.0 {
        return Err(body.invalid(format!("negative list length {value}")));
    }
    // An integer type (checked in the header), so exact.
    let n = value as u64;
    // + 1: the last ASCII number of the file needs no separator.
    if n.saturating_mul(body.min_bytes(item)) > body.remaining() + 1 {
        return Err(RecordError::End);
    }
    Ok(n)
}

fn skip_property(body: &mut impl Body, kind: Kind) -> Result<(), RecordError> {
    match kind {
        Kind::Scalar(ty) => body.skip(ty, 1),
        Kind::List { count, item } => {
            let n = list_length(body, count, item)?;
            body.skip(item, n)
        }
    }
}

fn skip_records(body: &mut impl Body, element: &Element) -> Result<(), ParseError> {
    for index in 0..element.count {
        for property in &element.properties {
            skip_property(body, property.kind).map_err(locate(element, index, property))?;
        }
    }
    Ok(())
}
