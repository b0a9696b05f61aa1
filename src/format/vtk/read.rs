//! Reading `.vtu` triangle meshes and `.pvd` collections back (what is accepted is listed in
//! [`super`]).

use super::data_array::{DataArray, Encoding};
use super::tree::{parse_document, Element, LineError};
use super::{PointArray, VTK_TRIANGLE};
use crate::format::IoError;
use nalgebra::{Vector2, Vector3};
use std::path::{Path, PathBuf};

/// A triangle mesh with its point arrays, as read from a `.vtu` file.
#[derive(Clone, Debug, PartialEq)]
pub struct VtuMesh {
    pub points: Vec<Vector3<f64>>,
    /// 0-based point indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
    /// The `<PointData>` arrays in file order.
    pub point_data: Vec<NamedArray>,
}

/// A point array that owns its values, read from a file or built to write one:
/// `values[i * components + c]` is component `c` at point `i`.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedArray {
    pub name: String,
    pub components: usize,
    pub values: Vec<f64>,
}

impl VtuMesh {
    /// The point array called `name`.
    pub fn point_array(&self, name: &str) -> Option<&NamedArray> {
        self.point_data.iter().find(|array| array.name == name)
    }
}

impl NamedArray {
    /// One value per point.
    pub fn scalars(name: &str, values: &[f64]) -> Self {
        Self {
            name: name.to_string(),
            components: 1,
            values: values.to_vec(),
        }
    }

    /// One R^3 vector per point.
    pub fn vectors(name: &str, vectors: &[Vector3<f64>]) -> Self {
        Self {
            name: name.to_string(),
            components: 3,
            values: vectors.iter().flat_map(|v| [v.x, v.y, v.z]).collect(),
        }
    }

    /// One 2-vector per point.
    pub fn vectors2(name: &str, vectors: &[Vector2<f64>]) -> Self {
        Self {
            name: name.to_string(),
            components: 2,
            values: vectors.iter().flat_map(|v| [v.x, v.y]).collect(),
        }
    }

    /// `channels.len()` components per point from channel-major values (`channels[c][i]`).
    pub fn channels(name: &str, channels: &[Vec<f64>]) -> Self {
        let n = channels.first().map_or(0, Vec::len);
        Self {
            name: name.to_string(),
            components: channels.len(),
            values: (0..n)
                .flat_map(|i| channels.iter().map(move |c| c[i]))
                .collect(),
        }
    }

    /// The array in the writer's form, e.g. to write it again with [`super::write_vtu`].
    pub fn as_point_array(&self) -> PointArray<'_> {
        PointArray {
            name: &self.name,
            components: self.components,
            values: &self.values,
        }
    }
}

/// Reads a VTK XML UnstructuredGrid of triangles (see the module docs of [`super`] for what is
/// accepted). Errors name the file and, where it helps, the line, array and cell.
pub fn read_vtu(path: &Path) -> Result<VtuMesh, IoError> {
    let bytes = crate::format::read_file(path)?;
    parse_vtu(&bytes).map_err(|e| IoError::at_line(path, e))
}

/// [`read_vtu`] from a stream; `name` stands for it in errors.
pub fn read_vtu_from(reader: impl std::io::Read, name: &Path) -> Result<VtuMesh, IoError> {
    let bytes = crate::format::read_stream(reader, name)?;
    parse_vtu(&bytes).map_err(|e| IoError::at_line(name, e))
}

/// Reads a ParaView collection: `(timestep, file)` of every `<DataSet>`, the files resolved
/// against the `.pvd`'s directory, in order of time (equal times keep their listed order).
/// Each file may be listed once: the DataSets are then no more than the directory's files,
/// however many a hostile `.pvd` lists.
pub fn read_pvd(path: &Path) -> Result<Vec<(f64, PathBuf)>, IoError> {
    let bytes = crate::format::read_file(path)?;
    let mut datasets = parse_pvd(&bytes).map_err(|e| IoError::at_line(path, e))?;
    let mut seen = std::collections::HashMap::with_capacity(datasets.len());
    for (k, (_, file)) in datasets.iter().enumerate() {
        if let Some(first) = seen.insert(file.as_str(), k) {
            let why = format!(
                "DataSet {k} lists {} again (as DataSet {first}): a collection lists each file \
                 once",
                crate::format::quoted(file)
            );
            return Err(IoError::format(path, why));
        }
    }
    drop(seen);
    datasets.sort_by(|(a, _), (b, _)| a.total_cmp(b));
    datasets
        .into_iter()
        .map(|(time, file)| {
            let resolved = crate::format::resolve_linked(path, "DataSet file", &file, &file)?;
            Ok((time, resolved))
        })
        .collect()
}

/// The root `<VTKFile>` of `bytes`, which must have `type="{kind}"`.
fn vtk_root<'a>(bytes: &'a [u8], kind: &str) -> Result<Element<'a>, LineError> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| (0, format!("not a VTK XML file: not UTF-8 text ({e})")))?;
    let root = parse_document(text)?;
    if root.name != "VTKFile" {
        return Err(root.error(format!(
            "not a VTK XML file: the root element is <{}>, not <VTKFile>",
            root.name
        )));
    }
    match root.attribute("type") {
        Some(found) if found == kind => Ok(root),
        found => Err(root.error(format!(
            "<VTKFile type=\"{}\">, expected type=\"{kind}\"",
            found.unwrap_or("")
        ))),
    }
}

fn parse_vtu(bytes: &[u8]) -> Result<VtuMesh, LineError> {
    let root = vtk_root(bytes, "UnstructuredGrid")?;
    let encoding = Encoding::of(&root)?;
    if let Some(appended) = root.child("AppendedData") {
        return Err(appended
            .error("appended VTU data is not supported; meshflow reads the files it writes"));
    }
    let grid = root.required_child("UnstructuredGrid")?;
    let piece = single_piece(grid)?;
    let n_points = count_attribute(piece, "NumberOfPoints")?;
    let n_cells = count_attribute(piece, "NumberOfCells")?;
    check_declared_size(piece, n_points, n_cells)?;
    Ok(VtuMesh {
        points: read_points(piece, n_points, encoding)?,
        triangles: read_triangles(piece, n_points, n_cells, encoding)?,
        point_data: read_point_data(piece, n_points, encoding)?,
    })
}

fn single_piece<'e, 'a>(grid: &'e Element<'a>) -> Result<&'e Element<'a>, LineError> {
    let mut pieces = grid.children_named("Piece");
    let piece = pieces
        .next()
        .ok_or_else(|| grid.error("<UnstructuredGrid> has no <Piece>"))?;
    match pieces.count() {
        0 => Ok(piece),
        more => Err(grid.error(format!(
            "<UnstructuredGrid> has {} pieces; meshflow reads single-piece files",
            more + 1
        ))),
    }
}

/// Bytes a cell takes while read: its type, offset and three corners as u64, and the
/// triangle's three u32.
const CELL_BYTES: u64 = 5 * 8 + 3 * 4;

/// Checks what the piece declares against the memory limit before anything is decoded: the
/// points (24 bytes each) with every point array's components (8 bytes each), and the cells.
/// The data present bounds each array too, but a short file may declare 10¹² points.
fn check_declared_size(piece: &Element, n_points: usize, n_cells: usize) -> Result<(), LineError> {
    let arrays = piece.child("PointData").into_iter().flat_map(|data| {
        data.children_named("DataArray")
            .map(|array| array.attribute("NumberOfComponents"))
    });
    let components = arrays.fold(3u64, |sum, k| {
        let k = k.and_then(|k| k.trim().parse().ok()).unwrap_or(1u64);
        sum.saturating_add(k)
    });
    let bytes = (n_points as u64)
        .saturating_mul(components.saturating_mul(8))
        .saturating_add((n_cells as u64).saturating_mul(CELL_BYTES));
    let what = format!("NumberOfPoints=\"{n_points}\" with NumberOfCells=\"{n_cells}\"");
    crate::limits::check_declared(what, bytes).map_err(|e| piece.error(e.to_string()))
}

/// A non-negative integer attribute of `element`.
fn count_attribute(element: &Element, name: &str) -> Result<usize, LineError> {
    let text = element
        .attribute(name)
        .ok_or_else(|| element.error(format!("<{}> has no {name}", element.name)))?;
    text.trim()
        .parse()
        .map_err(|_| element.error(format!("{name}=\"{text}\" is not a non-negative integer")))
}

/// The `DataArray` of a `<Points>` or `<Cells>` element: the first one named `name`, or (for
/// `<Points>`, whose array need not be named) the first one.
fn data_array<'e, 'a>(parent: &'e Element<'a>, name: &str) -> Result<DataArray<'e, 'a>, LineError> {
    let mut arrays = parent.children_named("DataArray");
    let element = match parent.name.as_str() {
        "Points" => arrays.next(),
        _ => arrays.find(|array| array.attribute("Name") == Some(name)),
    };
    let element = element
        .ok_or_else(|| parent.error(format!("<{}> has no DataArray '{name}'", parent.name)))?;
    DataArray::new(element, Some(name))
}

fn read_points(
    piece: &Element,
    n_points: usize,
    encoding: Encoding,
) -> Result<Vec<Vector3<f64>>, LineError> {
    let points = data_array(piece.required_child("Points")?, "Points")?;
    if points.components != 3 {
        return Err(points.error(format!("{} components, expected 3", points.components)));
    }
    let xyz = points.floats(n_points, encoding)?;
    Ok(xyz
        .chunks_exact(3)
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .collect())
}

/// The cells as triangles: every `types` entry 5 (VTK_TRIANGLE), `offsets` 3, 6, 9, … and
/// every `connectivity` entry a point of the piece.
fn read_triangles(
    piece: &Element,
    n_points: usize,
    n_cells: usize,
    encoding: Encoding,
) -> Result<Vec<[u32; 3]>, LineError> {
    let cells = piece.required_child("Cells")?;
    let types = data_array(cells, "types")?;
    if let Some((cell, ty)) = types
        .indices(n_cells, encoding)?
        .into_iter()
        .enumerate()
        .find(|&(_, ty)| ty != u64::from(VTK_TRIANGLE))
    {
        return Err(types.error(format!(
            "cell {cell} has type {ty}; meshflow reads triangles (type {VTK_TRIANGLE})"
        )));
    }
    let offsets = data_array(cells, "offsets")?;
    let ends = offsets.indices(n_cells, encoding)?;
    if let Some((cell, end)) = ends
        .iter()
        .enumerate()
        .find(|&(cell, &end)| Some(end) != (cell as u64 + 1).checked_mul(3))
    {
        return Err(offsets.error(format!(
            "cell {cell} ends at offset {end}, expected {}: every cell must be a triangle \
             of 3 points",
            3 * (cell as u64 + 1)
        )));
    }
    let connectivity = data_array(cells, "connectivity")?;
    // `n_cells` offsets fit in memory, so 3 × n_cells does not overflow.
    let corners = connectivity.indices(3 * n_cells, encoding)?;
    let triangles = corners
        .chunks_exact(3)
        .enumerate()
        .map(|(cell, corners)| triangle(cell, corners, n_points))
        .collect::<Result<Vec<_>, String>>()
        .map_err(|message| connectivity.error(message))?;
    Ok(triangles)
}

/// The three points of `cell`, each below `n_points`.
fn triangle(cell: usize, corners: &[u64], n_points: usize) -> Result<[u32; 3], String> {
    let mut triangle = [0u32; 3];
    for (slot, &point) in triangle.iter_mut().zip(corners) {
        *slot = u32::try_from(point)
            .ok()
            .filter(|&p| (p as usize) < n_points)
            .ok_or_else(|| {
                format!("cell {cell} refers to point {point}, but the piece has {n_points} points")
            })?;
    }
    Ok(triangle)
}

/// Every `<DataArray>` of `<PointData>` (absent: none), each with `n_points` tuples.
fn read_point_data(
    piece: &Element,
    n_points: usize,
    encoding: Encoding,
) -> Result<Vec<NamedArray>, LineError> {
    let Some(point_data) = piece.child("PointData") else {
        return Ok(Vec::new());
    };
    let mut arrays: Vec<NamedArray> = Vec::new();
    for element in point_data.children_named("DataArray") {
        let array = DataArray::new(element, None)?;
        if arrays.iter().any(|other| other.name == array.name) {
            return Err(array.error("a second point array of this name"));
        }
        arrays.push(NamedArray {
            values: array.floats(n_points, encoding)?,
            name: array.name,
            components: array.components,
        });
    }
    Ok(arrays)
}

/// `(timestep, file)` of every `<DataSet>` in file order, file names as written.
fn parse_pvd(bytes: &[u8]) -> Result<Vec<(f64, String)>, LineError> {
    let root = vtk_root(bytes, "Collection")?;
    let collection = root.required_child("Collection")?;
    collection
        .children_named("DataSet")
        .enumerate()
        .map(|(k, dataset)| {
            let attribute = |name: &str| {
                dataset
                    .attribute(name)
                    .ok_or_else(|| dataset.error(format!("DataSet {k} has no {name}")))
            };
            let (time, file) = (attribute("timestep")?, attribute("file")?);
            match time.trim().parse::<f64>() {
                Ok(t) if t.is_finite() => Ok((t, file.to_string())),
                _ => Err(dataset.error(format!(
                    "DataSet {k} ('{file}'): timestep \"{time}\" is not a finite number"
                ))),
            }
        })
        .collect()
}
