//! VTK XML output for ParaView: a triangle mesh with point data as an UnstructuredGrid (`.vtu`),
//! and a time series of such files as a ParaView collection (`.pvd`).
//!
//! `.vtu` layout (VTK XML format version 1.0, the first with `header_type`):
//!
//! ```text
//! <VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
//!   <UnstructuredGrid>
//!     <Piece NumberOfPoints="n" NumberOfCells="m">
//!       <PointData>   one Float64 DataArray per point array, NumberOfComponents="k"
//!       <CellData>    the same per triangle, when there are cell arrays
//!       <Points>      Float64, 3 components: x y z of each point
//!       <Cells>       connectivity Int64: the 3 point indices of each triangle, 0-based
//!                     offsets      Int64: where each cell ends in connectivity: 3, 6, 9, …
//!                     types        UInt8: 5 (VTK_TRIANGLE) for every cell
//! ```
//!
//! Every array is `format="binary"`: inline base64, uncompressed. Its bytes are the values in
//! little-endian order, point-major for several components (`values[i * k + c]`), preceded by a
//! header: the number of data bytes as a little-endian u64; header and data are base64 encoded
//! as one stream, as VTK's own writer (`vtkXMLWriter::WriteBinaryData`) and meshio do for
//! uncompressed arrays.
//!
//! `.pvd`: `<VTKFile type="Collection">` listing `<DataSet timestep="t" part="0" file="…"/>`, times
//! in Rust's shortest round-trip form.
//!
//! # Reading
//!
//! [`read_vtu`] reads this layout back bit for bit, and the same structure as other writers
//! (VTK, vtkio, meshio) produce it uncompressed:
//!
//! - `<VTKFile type="UnstructuredGrid">` with `byte_order` LittleEndian (default) or BigEndian
//!   and `header_type` UInt32 (default, as in version 0.1 files) or UInt64; one `<Piece>`.
//! - Arrays `format="binary"` (the header may also be base64-encoded on its own, then the
//!   data; whitespace inside the base64 is ignored) or `format="ascii"`, of types Int8 … Int64,
//!   UInt8 … UInt64, Float32, Float64. Points and point data become f64; connectivity, offsets
//!   and types must have an integer type. ASCII numbers are parsed as their declared type.
//! - Cells: triangles only, i.e. every type 5 and offsets 3, 6, 9, … (the end of each cell, as
//!   above); connectivity entries must name points of the piece.
//! - `<PointData>`: every `DataArray`, named, `NumberOfPoints` tuples each; `<CellData>` and
//!   `<FieldData>` are ignored.
//!
//! Compressed files (a `compressor` attribute) and appended data (`format="appended"`,
//! `<AppendedData>`) are refused with an error: meshflow reads the files it writes. Every size
//! is checked against the data present before anything is allocated for it (a byte-count header
//! against the decoded bytes, the bytes against `NumberOfPoints` × components), so malformed
//! files give an [`IoError`] naming the file, line, array and cell, never a panic.
//!
//! [`read_pvd`] returns each `<DataSet>`'s `timestep` and `file`, the file resolved against the
//! `.pvd`'s directory, in order of time.

mod data_array;
mod read;
mod tree;

pub use read::{read_pvd, read_vtu, read_vtu_from, NamedArray, VtuMesh};

use super::{write_atomically, IoError};
use base64::engine::general_purpose::STANDARD;
use base64::Engine;
use nalgebra::Vector3;
use std::borrow::Cow;
use std::io::Write;
use std::path::Path;

/// VTK's cell type number for a linear triangle.
const VTK_TRIANGLE: u8 = 5;
/// VTK's cell type number for a single point.
const VTK_VERTEX: u8 = 1;

/// A named per-point array with `components` values per point, stored point-major:
/// `values[i * components + c]` is component `c` at point `i`.
#[derive(Clone, Copy, Debug)]
pub struct PointArray<'a> {
    pub name: &'a str,
    pub components: usize,
    pub values: &'a [f64],
}

/// Writes a triangle mesh and its point arrays as a VTK XML UnstructuredGrid (see the module
/// docs for the layout). Fails without writing when an array's length is not
/// `positions.len() × components` or a face names a missing point.
pub fn write_vtu(
    path: &Path,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    point_data: &[PointArray],
) -> Result<(), IoError> {
    write_vtu_with_cells(path, positions, faces, point_data, &[])
}

/// [`write_vtu`] with per-triangle arrays too (`<CellData>`, `faces.len() × components` values
/// each, face-major), e.g. values that are constant on each face.
pub fn write_vtu_with_cells(
    path: &Path,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    point_data: &[PointArray],
    cell_data: &[PointArray],
) -> Result<(), IoError> {
    check_arrays("point", positions.len(), point_data)
        .and_then(|()| check_arrays("cell", faces.len(), cell_data))
        .and_then(|()| {
            crate::mesh::check_index_range(faces, positions.len()).map_err(|e| e.to_string())
        })
        .map_err(|message| IoError::format(path, message))?;
    let connectivity: Vec<i64> = faces.iter().flatten().map(|&v| i64::from(v)).collect();
    let cells = Cells {
        connectivity: &connectivity,
        corners: 3,
        vtk_type: VTK_TRIANGLE,
    };
    write_unstructured(path, positions, cells, point_data, cell_data)
}

/// Points alone as a VTK XML UnstructuredGrid of vertex cells, with their point arrays: a point
/// set (tracked cells, landmarks) that ParaView draws as points or glyphs.
pub fn write_point_vtu(
    path: &Path,
    points: &[Vector3<f64>],
    point_data: &[PointArray],
) -> Result<(), IoError> {
    check_arrays("point", points.len(), point_data).map_err(|m| IoError::format(path, m))?;
    let connectivity: Vec<i64> = (0..points.len() as i64).collect();
    let cells = Cells {
        connectivity: &connectivity,
        corners: 1,
        vtk_type: VTK_VERTEX,
    };
    write_unstructured(path, points, cells, point_data, &[])
}

/// Cells of one type with `corners` points each, their point indices in a row.
struct Cells<'a> {
    connectivity: &'a [i64],
    corners: usize,
    vtk_type: u8,
}

fn write_unstructured(
    path: &Path,
    positions: &[Vector3<f64>],
    cells: Cells,
    point_data: &[PointArray],
    cell_data: &[PointArray],
) -> Result<(), IoError> {
    let n_cells = cells.connectivity.len() / cells.corners;
    let points = le_bytes(
        positions
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .map(f64::to_le_bytes),
    );
    let connectivity = le_bytes(cells.connectivity.iter().map(|v| v.to_le_bytes()));
    let corners = cells.corners as i64;
    let offsets = le_bytes((1..=n_cells as i64).map(|k| (corners * k).to_le_bytes()));
    let types = vec![cells.vtk_type; n_cells];
    write_atomically(path, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
             header_type=\"UInt64\">"
        )?;
        writeln!(w, "  <UnstructuredGrid>")?;
        writeln!(
            w,
            "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
            positions.len(),
            n_cells
        )?;
        writeln!(w, "      <PointData>")?;
        for array in point_data {
            let bytes = le_bytes(array.values.iter().map(|v| v.to_le_bytes()));
            write_data_array(w, "Float64", array.name, array.components, &bytes)?;
        }
        writeln!(w, "      </PointData>")?;
        if !cell_data.is_empty() {
            writeln!(w, "      <CellData>")?;
            for array in cell_data {
                let bytes = le_bytes(array.values.iter().map(|v| v.to_le_bytes()));
                write_data_array(w, "Float64", array.name, array.components, &bytes)?;
            }
            writeln!(w, "      </CellData>")?;
        }
        writeln!(w, "      <Points>")?;
        write_data_array(w, "Float64", "Points", 3, &points)?;
        writeln!(w, "      </Points>")?;
        writeln!(w, "      <Cells>")?;
        write_data_array(w, "Int64", "connectivity", 1, &connectivity)?;
        write_data_array(w, "Int64", "offsets", 1, &offsets)?;
        write_data_array(w, "UInt8", "types", 1, &types)?;
        writeln!(w, "      </Cells>")?;
        writeln!(w, "    </Piece>")?;
        writeln!(w, "  </UnstructuredGrid>")?;
        writeln!(w, "</VTKFile>")
    })
}

/// Writes a ParaView collection: one dataset per `(time, file name)`, file names relative to the
/// `.pvd` (as ParaView resolves them). Times must be finite.
pub fn write_pvd(path: &Path, datasets: &[(f64, String)]) -> Result<(), IoError> {
    if let Some((time, file)) = datasets.iter().find(|(time, _)| !time.is_finite()) {
        return Err(IoError::format(
            path,
            format!("time {time} of '{file}' is not finite"),
        ));
    }
    write_atomically(path, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
        )?;
        writeln!(w, "  <Collection>")?;
        for (time, file) in datasets {
            writeln!(
                w,
                "    <DataSet timestep=\"{time}\" part=\"0\" file=\"{}\"/>",
                xml_escape(file)
            )?;
        }
        writeln!(w, "  </Collection>")?;
        writeln!(w, "</VTKFile>")
    })
}

/// Each of the `kind` (point or cell) arrays has a name of its own and `n × components` values.
fn check_arrays(kind: &str, n: usize, arrays: &[PointArray]) -> Result<(), String> {
    for (k, array) in arrays.iter().enumerate() {
        let name = array.name;
        if array.components == 0 {
            return Err(format!("{kind} array '{name}' has 0 components"));
        }
        if arrays[..k].iter().any(|other| other.name == name) {
            return Err(format!("two {kind} arrays are named '{name}'"));
        }
        let expected = n.checked_mul(array.components);
        if expected != Some(array.values.len()) {
            return Err(format!(
                "{kind} array '{name}' has {} values, expected {n} {kind}s × {} components",
                array.values.len(),
                array.components
            ));
        }
    }
    Ok(())
}

fn le_bytes<const N: usize>(values: impl Iterator<Item = [u8; N]>) -> Vec<u8> {
    values.flatten().collect()
}

/// One `<DataArray>` inside a `Piece` child, its bytes in VTK's binary form (module docs).
fn write_data_array(
    w: &mut impl Write,
    vtk_type: &str,
    name: &str,
    components: usize,
    bytes: &[u8],
) -> std::io::Result<()> {
    writeln!(
        w,
        "        <DataArray type=\"{vtk_type}\" Name=\"{}\" NumberOfComponents=\"{components}\" \
         format=\"binary\">",
        xml_escape(name)
    )?;
    // No whitespace inside the base64: VTK decodes it in raw groups of 4 characters.
    let block = [&(bytes.len() as u64).to_le_bytes()[..], bytes].concat();
    writeln!(w, "          {}", STANDARD.encode(block))?;
    writeln!(w, "        </DataArray>")
}

/// `text` with the five XML special characters escaped, for attribute values.
fn xml_escape(text: &str) -> Cow<'_, str> {
    if !text.contains(['&', '<', '>', '"', '\'']) {
        return Cow::Borrowed(text);
    }
    let mut escaped = String::with_capacity(text.len() + 16);
    for c in text.chars() {
        match c {
            '&' => escaped.push_str("&amp;"),
            '<' => escaped.push_str("&lt;"),
            '>' => escaped.push_str("&gt;"),
            '"' => escaped.push_str("&quot;"),
            '\'' => escaped.push_str("&apos;"),
            c => escaped.push(c),
        }
    }
    Cow::Owned(escaped)
}
