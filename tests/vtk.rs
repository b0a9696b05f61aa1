//! VTK XML output, checked independently: the binary blocks decoded by hand, the whole file
//! read back through vtkio, and the `.pvd` collection against its exact text. VTK XML input:
//! our own files read back bit-exact, files written by vtkio or by hand (ASCII, Float32,
//! UInt32 headers, big-endian) read with the numbers vtkio reads, a `meshflow solve` output read
//! back as its NPY arrays and OBJ frames, and malformed files rejected with errors, never a
//! panic.

mod common;

use base64::engine::general_purpose::STANDARD;
use base64::Engine;
use meshflow::io::vtk::{
    read_pvd, read_vtu, write_pvd, write_vtu, NamedArray, PointArray, VtuMesh,
};
use meshflow::io::{read_mesh, read_npy};
use meshflow::shapes::icosphere;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType, IOBuffer,
    Piece, UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

/// Decodes one array (header and data in one base64 stream), checking the header against the
/// data.
fn decode_block(text: &str) -> Vec<u8> {
    let block = STANDARD.decode(text).unwrap();
    let (header, data) = block.split_at(8);
    let announced = u64::from_le_bytes(header.try_into().unwrap());
    assert_eq!(announced, data.len() as u64, "header of block {text:.20}…");
    data.to_vec()
}

/// Every `<DataArray …>` element's attributes and text, in file order.
fn data_arrays(xml: &str) -> Vec<(&str, &str)> {
    xml.split("<DataArray ")
        .skip(1)
        .map(|rest| {
            let (attributes, rest) = rest.split_once('>').unwrap();
            let (text, _) = rest.split_once("</DataArray>").unwrap();
            (attributes, text.trim())
        })
        .collect()
}

fn f64_values(bytes: &[u8]) -> Vec<f64> {
    bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// An icosphere with a 3-component array (awkward bits: tiny offsets, -0.0, subnormals) and a
/// 1-component array.
struct Sample {
    positions: Vec<Vector3<f64>>,
    faces: Vec<[u32; 3]>,
    flow: Vec<f64>,
    intensity: Vec<f64>,
}

fn sample() -> Sample {
    let sphere = icosphere(1);
    let positions: Vec<Vector3<f64>> = sphere
        .positions
        .iter()
        .map(|p| p * (1.0 + 1e-3 * p.x) + Vector3::repeat(1e-17))
        .collect();
    let flow = positions
        .iter()
        .enumerate()
        .flat_map(|(i, p)| [p.y * 1e-300, -0.0, 5e-324 * i as f64 + p.z])
        .collect();
    let intensity = positions.iter().map(|p| p.x.atan2(p.y) / 7.0).collect();
    Sample {
        positions,
        faces: sphere.faces,
        flow,
        intensity,
    }
}

impl Sample {
    fn point_arrays(&self) -> Vec<PointArray<'_>> {
        vec![
            PointArray {
                name: "flow",
                components: 3,
                values: &self.flow,
            },
            PointArray {
                name: "intensity",
                components: 1,
                values: &self.intensity,
            },
        ]
    }
}

fn write_sample(path: &Path, s: &Sample) {
    write_vtu(path, &s.positions, &s.faces, &s.point_arrays()).unwrap();
}

#[test]
fn vtu_blocks_follow_the_vtk_binary_layout() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.vtu");
    let s = sample();
    write_sample(&path, &s);
    let xml = std::fs::read_to_string(&path).unwrap();
    assert!(xml.contains(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">"
    ));
    assert!(xml.contains("<Piece NumberOfPoints=\"42\" NumberOfCells=\"80\">"));
    let arrays = data_arrays(&xml);
    let attributes: Vec<&str> = arrays.iter().map(|(a, _)| *a).collect();
    assert_eq!(
        attributes,
        [
            "type=\"Float64\" Name=\"flow\" NumberOfComponents=\"3\" format=\"binary\"",
            "type=\"Float64\" Name=\"intensity\" NumberOfComponents=\"1\" format=\"binary\"",
            "type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\"",
            "type=\"Int64\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"binary\"",
            "type=\"Int64\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"binary\"",
            "type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"binary\"",
        ]
    );
    let blocks: Vec<Vec<u8>> = arrays.iter().map(|(_, text)| decode_block(text)).collect();
    assert_eq!(bits(&f64_values(&blocks[0])), bits(&s.flow));
    assert_eq!(bits(&f64_values(&blocks[1])), bits(&s.intensity));
    let points: Vec<f64> = s.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    assert_eq!(bits(&f64_values(&blocks[2])), bits(&points));
    let connectivity: Vec<u8> = s
        .faces
        .iter()
        .flatten()
        .flat_map(|&v| i64::from(v).to_le_bytes())
        .collect();
    assert_eq!(blocks[3], connectivity);
    assert_eq!(
        &blocks[4][..16],
        [3, 0, 0, 0, 0, 0, 0, 0, 6, 0, 0, 0, 0, 0, 0, 0]
    );
    assert_eq!(blocks[5], vec![5u8; 80]);
}

#[test]
fn vtu_reads_back_bit_exact_through_vtkio() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.vtu");
    let s = sample();
    write_sample(&path, &s);
    let piece = vtkio_piece(&path);
    let IOBuffer::F64(points) = &piece.points else {
        panic!("points are not Float64: {:?}", piece.points);
    };
    let expected: Vec<f64> = s.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    assert_eq!(bits(points), bits(&expected));

    let (connectivity, offsets) = xml_cells(&piece);
    let expected: Vec<u64> = s.faces.iter().flatten().map(|&v| v.into()).collect();
    assert_eq!(connectivity, &expected);
    let expected: Vec<u64> = (1..=s.faces.len() as u64).map(|k| 3 * k).collect();
    assert_eq!(offsets, &expected);
    assert_eq!(piece.cells.types, vec![CellType::Triangle; s.faces.len()]);

    let arrays: Vec<(&str, &IOBuffer)> = piece
        .data
        .point
        .iter()
        .map(|attribute| match attribute {
            Attribute::DataArray(array) => (array.name.as_str(), &array.data),
            Attribute::Field { name, .. } => panic!("unexpected field data '{name}'"),
        })
        .collect();
    assert_eq!(arrays.len(), 2);
    for ((name, data), (expected_name, expected)) in arrays
        .into_iter()
        .zip([("flow", &s.flow), ("intensity", &s.intensity)])
    {
        assert_eq!(name, expected_name);
        let IOBuffer::F64(values) = data else {
            panic!("'{name}' is not Float64");
        };
        assert_eq!(bits(values), bits(expected), "{name}");
    }
}

#[test]
fn vtu_names_are_xml_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("names.vtu");
    let sphere = icosphere(0);
    let values = vec![1.0; 12];
    let array = PointArray {
        name: "a<b> & \"c\" 'd'",
        components: 1,
        values: &values,
    };
    write_vtu(&path, &sphere.positions, &sphere.faces, &[array]).unwrap();
    let xml = std::fs::read_to_string(&path).unwrap();
    assert!(xml.contains("Name=\"a&lt;b&gt; &amp; &quot;c&quot; &apos;d&apos;\""));
}

#[test]
fn vtu_rejects_mismatched_arrays_and_faces() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.vtu");
    let sphere = icosphere(0);
    let values = vec![0.0; 35];
    let failure = |components: usize, faces: &[[u32; 3]]| {
        let array = PointArray {
            name: "flow",
            components,
            values: &values,
        };
        let error = write_vtu(&path, &sphere.positions, faces, &[array]).unwrap_err();
        assert!(!path.exists());
        error.to_string()
    };
    let text = failure(3, &sphere.faces);
    assert!(
        text.contains(
            "bad.vtu: point array 'flow' has 35 values, expected 12 points × 3 components"
        ),
        "{text}"
    );
    assert!(failure(0, &sphere.faces).contains("'flow' has 0 components"));
    let whole = vec![0.0; 36];
    let twice = [("u", &whole), ("u", &whole)].map(|(name, values)| PointArray {
        name,
        components: 3,
        values,
    });
    let text = write_vtu(&path, &sphere.positions, &sphere.faces, &twice)
        .unwrap_err()
        .to_string();
    assert!(text.contains("two point arrays are named 'u'"), "{text}");
    let text = write_vtu(&path, &sphere.positions, &[[0, 1, 12]], &[])
        .unwrap_err()
        .to_string();
    assert!(
        text.contains("face 0 refers to vertex 12, but the mesh has 12 vertices"),
        "{text}"
    );
}

#[test]
fn pvd_lists_the_datasets_with_their_times() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flow.pvd");
    let datasets = vec![
        (0.0, "frame_000.vtu".to_string()),
        (0.1, "frame_001.vtu".to_string()),
        (1.0 / 3.0, "odd & <named>.vtu".to_string()),
    ];
    write_pvd(&path, &datasets).unwrap();
    let expected = "<?xml version=\"1.0\"?>\n\
        <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n\
        \x20 <Collection>\n\
        \x20   <DataSet timestep=\"0\" part=\"0\" file=\"frame_000.vtu\"/>\n\
        \x20   <DataSet timestep=\"0.1\" part=\"0\" file=\"frame_001.vtu\"/>\n\
        \x20   <DataSet timestep=\"0.3333333333333333\" part=\"0\" \
        file=\"odd &amp; &lt;named&gt;.vtu\"/>\n\
        \x20 </Collection>\n\
        </VTKFile>\n";
    assert_eq!(std::fs::read_to_string(&path).unwrap(), expected);
    // The times read back exactly.
    let times: Vec<f64> = expected
        .split("timestep=\"")
        .skip(1)
        .map(|rest| rest.split('"').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(times, datasets.iter().map(|(t, _)| *t).collect::<Vec<_>>());
    // vtkio has no reader for collections (no `.pvd` file type).
    assert!(vtkio::Vtk::import(&path).is_err());

    let error = write_pvd(&path, &[(f64::NAN, "x.vtu".into())]).unwrap_err();
    assert!(error
        .to_string()
        .contains("time NaN of 'x.vtu' is not finite"));
}

// ---------------------------------------------------------------------------------------------
// Reading

fn point_bits(points: &[Vector3<f64>]) -> Vec<u64> {
    points
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .map(f64::to_bits)
        .collect()
}

/// The names, component counts and value bits of a mesh's point arrays.
fn array_bits(mesh: &VtuMesh) -> Vec<(&str, usize, Vec<u64>)> {
    mesh.point_data
        .iter()
        .map(|a| (a.name.as_str(), a.components, bits(&a.values)))
        .collect()
}

#[test]
fn vtu_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.vtu");
    let s = sample();
    let tangent: Vec<f64> = (0..2 * s.positions.len())
        .map(|k| (k as f64).sqrt() * -1e-9)
        .collect();
    let tensor: Vec<f64> = (0..9 * s.positions.len())
        .map(|k| 1.0 / (k as f64 - 100.5))
        .collect();
    let mut point_data = s.point_arrays();
    point_data.extend([
        PointArray {
            name: "flow_intrinsic",
            components: 2,
            values: &tangent,
        },
        PointArray {
            name: "tensor & <more>",
            components: 9,
            values: &tensor,
        },
    ]);
    write_vtu(&path, &s.positions, &s.faces, &point_data).unwrap();
    let mesh = read_vtu(&path).unwrap();
    assert_eq!(point_bits(&mesh.points), point_bits(&s.positions));
    assert_eq!(mesh.triangles, s.faces);
    let expected: Vec<(&str, usize, Vec<u64>)> = point_data
        .iter()
        .map(|a| (a.name, a.components, bits(a.values)))
        .collect();
    assert_eq!(array_bits(&mesh), expected);
    let intensity = mesh.point_array("intensity").unwrap();
    assert_eq!(bits(&intensity.values), bits(&s.intensity));
    assert!(mesh.point_array("speed").is_none());

    // Written again from what was read: the same bytes.
    let again = dir.path().join("again.vtu");
    let arrays: Vec<PointArray> = mesh.point_data.iter().map(|a| a.as_point_array()).collect();
    write_vtu(&again, &mesh.points, &mesh.triangles, &arrays).unwrap();
    assert_eq!(
        std::fs::read(&again).unwrap(),
        std::fs::read(&path).unwrap()
    );
}

#[test]
fn pvd_round_trip_gives_times_and_resolved_paths() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flow.pvd");
    let names = ["flow_0000.vtu", "sub/flow_0001.vtu", "odd & <named>.vtu"];
    let datasets: Vec<(f64, String)> = [0.0, 0.1, 1.0 / 3.0]
        .into_iter()
        .zip(names.map(String::from))
        .collect();
    write_pvd(&path, &datasets).unwrap();
    // The listed files must exist and lie beside the collection (`io::resolve_linked`).
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    for name in names.iter().chain(&["a.vtu", "b.vtu", "c.vtu", "d.vtu"]) {
        std::fs::write(dir.path().join(name), b"").unwrap();
    }
    let read = read_pvd(&path).unwrap();
    let expected: Vec<(f64, PathBuf)> = datasets
        .iter()
        .map(|(t, name)| (*t, dir.path().join(name)))
        .collect();
    assert_eq!(read, expected);

    // Listed out of order (and with two parts at one time): sorted by time, ties as listed.
    let shuffled = [
        (2.5, "c.vtu".to_string()),
        (-1.0, "a.vtu".to_string()),
        (2.5, "d.vtu".to_string()),
        (1e-300, "b.vtu".to_string()),
    ];
    write_pvd(&path, &shuffled).unwrap();
    let read: Vec<(f64, String)> = read_pvd(&path)
        .unwrap()
        .into_iter()
        .map(|(t, p)| (t, p.file_name().unwrap().to_string_lossy().into_owned()))
        .collect();
    let expected = [(-1.0, "a"), (1e-300, "b"), (2.5, "c"), (2.5, "d")]
        .map(|(t, name)| (t, format!("{name}.vtu")));
    assert_eq!(read, expected);
}

/// The values of a vtkio buffer as f64.
fn io_buffer_f64(buffer: &IOBuffer) -> Vec<f64> {
    match buffer {
        IOBuffer::F32(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::F64(v) => v.clone(),
        IOBuffer::I8(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::I16(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::I32(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::I64(v) => v.iter().map(|&x| x as f64).collect(),
        IOBuffer::U8(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::U16(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::U32(v) => v.iter().map(|&x| x.into()).collect(),
        IOBuffer::U64(v) => v.iter().map(|&x| x as f64).collect(),
        other => panic!("unexpected buffer {other:?}"),
    }
}

/// The single inline piece of the UnstructuredGrid vtkio reads from `path`.
fn vtkio_piece(path: &Path) -> UnstructuredGridPiece {
    let vtk = Vtk::import(path).unwrap();
    let DataSet::UnstructuredGrid { mut pieces, .. } = vtk.data else {
        panic!("not an UnstructuredGrid: {:?}", vtk.data);
    };
    assert_eq!(pieces.len(), 1);
    let Some(Piece::Inline(piece)) = pieces.pop() else {
        panic!("piece not inline");
    };
    *piece
}

/// Connectivity and offsets of a piece's cells.
fn xml_cells(piece: &UnstructuredGridPiece) -> (&Vec<u64>, &Vec<u64>) {
    let VertexNumbers::XML {
        connectivity,
        offsets,
    } = &piece.cells.cell_verts
    else {
        panic!("cells not in XML form");
    };
    (connectivity, offsets)
}

/// The piece vtkio reads from `path`, its numbers converted to f64.
fn vtkio_mesh(path: &Path) -> VtuMesh {
    let piece = vtkio_piece(path);
    let (connectivity, offsets) = xml_cells(&piece);
    assert_eq!(offsets.len(), connectivity.len() / 3);
    let point_data = piece
        .data
        .point
        .iter()
        .map(|attribute| match attribute {
            Attribute::DataArray(a) => NamedArray {
                name: a.name.clone(),
                components: a.num_comp(),
                values: io_buffer_f64(&a.data),
            },
            Attribute::Field { name, .. } => panic!("unexpected field data '{name}'"),
        })
        .collect();
    VtuMesh {
        points: io_buffer_f64(&piece.points)
            .chunks_exact(3)
            .map(Vector3::from_column_slice)
            .collect(),
        triangles: connectivity
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]].map(|v| u32::try_from(v).unwrap()))
            .collect(),
        point_data,
    }
}

/// Asserts that our reader and vtkio read the same numbers from `path`.
fn assert_reads_like_vtkio(path: &Path) -> VtuMesh {
    let mesh = read_vtu(path).unwrap();
    let theirs = vtkio_mesh(path);
    assert_eq!(point_bits(&mesh.points), point_bits(&theirs.points));
    assert_eq!(mesh.triangles, theirs.triangles);
    assert_eq!(array_bits(&mesh), array_bits(&theirs));
    mesh
}

#[test]
fn vtkio_binary_file_reads_back_with_its_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("vtkio.vtu");
    let sphere = icosphere(1);
    let n = sphere.positions.len();
    let points: Vec<f32> = sphere
        .positions
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .map(|x| x as f32 * 1.1)
        .collect();
    let velocity: Vec<f32> = (0..3 * n).map(|k| (k as f32).sin() / 3.0).collect();
    let label: Vec<i32> = (0..n as i32).map(|i| i * 1_000_003 - 7_000_000).collect();
    let pair: Vec<u16> = (0..2 * n as u16).map(|k| k.wrapping_mul(1999)).collect();
    let sign: Vec<i8> = (0..n)
        .map(|i| if i % 2 == 0 { -128 } else { 127 })
        .collect();
    let exact: Vec<f64> = (0..n).map(|i| (i as f64).exp() * 1e-200).collect();
    let array = |name: &str, elem, data: IOBuffer| {
        Attribute::DataArray(DataArray {
            name: name.into(),
            elem,
            data,
        })
    };
    let vtk = Vtk {
        version: Version::new((1, 0)),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: points.clone().into(),
            cells: Cells {
                cell_verts: VertexNumbers::XML {
                    connectivity: sphere.faces.iter().flatten().map(|&v| v.into()).collect(),
                    offsets: (1..=sphere.faces.len() as u64).map(|k| 3 * k).collect(),
                },
                types: vec![CellType::Triangle; sphere.faces.len()],
            },
            data: Attributes {
                point: vec![
                    array("velocity", ElementType::Vectors, velocity.clone().into()),
                    array("label", ElementType::Generic(1), label.clone().into()),
                    array("pair", ElementType::Generic(2), pair.clone().into()),
                    array("sign", ElementType::Generic(1), sign.clone().into()),
                    array("exact", ElementType::Generic(1), exact.clone().into()),
                ],
                cell: vec![],
            },
        }),
    };
    vtk.export(&path).unwrap();
    let xml = std::fs::read_to_string(&path).unwrap();
    for declaration in [
        "type=\"Float32\"",
        "type=\"UInt64\" Name=\"connectivity\"",
        "type=\"Int32\" Name=\"label\"",
        "type=\"Int8\"",
        "type=\"UInt16\"",
    ] {
        assert!(xml.contains(declaration), "{declaration} in {xml:.2000}");
    }

    let mesh = assert_reads_like_vtkio(&path);
    // And the numbers vtkio was given, converted exactly.
    let xyz: Vec<f64> = mesh.points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    assert_eq!(
        xyz,
        points.iter().map(|&x| f64::from(x)).collect::<Vec<_>>()
    );
    assert_eq!(mesh.triangles, sphere.faces);
    let values = |name: &str| mesh.point_array(name).unwrap().values.clone();
    assert_eq!(
        values("velocity"),
        velocity.iter().map(|&x| x.into()).collect::<Vec<f64>>()
    );
    assert_eq!(
        values("label"),
        label.iter().map(|&x| x.into()).collect::<Vec<f64>>()
    );
    assert_eq!(
        values("pair"),
        pair.iter().map(|&x| x.into()).collect::<Vec<f64>>()
    );
    assert_eq!(values("sign")[..2], [-128.0, 127.0]);
    assert_eq!(bits(&values("exact")), bits(&exact));
    assert_eq!(mesh.point_array("pair").unwrap().components, 2);
}

/// A hand-written ASCII UnstructuredGrid (version 0.1: no header_type) with a cell-data array,
/// a comment and line breaks inside the arrays.
const ASCII_VTU: &str = r#"<?xml version="1.0"?>
<!-- two triangles on four points -->
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="4" NumberOfCells="2">
      <PointData Scalars="level" Vectors="velocity">
        <DataArray type="Float32" Name="velocity" NumberOfComponents="3" format="ascii">
          0.1 0.2 0.3
          -1.5 2.5e-3 7
          1e-40 -0 3.4028235e38
          0.7 0.8 0.9
        </DataArray>
        <DataArray type="Int16" Name="level" format="ascii">-300 0 7 32767</DataArray>
        <DataArray type="UInt64" Name="id" format="ascii">
          0 1 9007199254740993 18446744073709551615
        </DataArray>
        <DataArray type="Float64" Name="precise" format="ascii">
          0.1 -2.2250738585072014e-308 1e300 0.30000000000000004
        </DataArray>
      </PointData>
      <CellData>
        <DataArray type="Int32" Name="cell_id" format="ascii">10 11</DataArray>
      </CellData>
      <Points>
        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii">
          0 0 0  1 0 0  0 1 0  0.5 0.5 1e-3
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 1 3 2</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">3 6</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">5 5</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#;

#[test]
fn ascii_file_reads_like_vtkio_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ascii.vtu");
    std::fs::write(&path, ASCII_VTU).unwrap();
    let mesh = assert_reads_like_vtkio(&path);
    // A byte-order mark changes nothing.
    let marked = dir.path().join("marked.vtu");
    std::fs::write(&marked, format!("\u{feff}{ASCII_VTU}")).unwrap();
    assert_eq!(read_vtu(&marked).unwrap(), mesh);
    // The numbers of the text, Float32 ones rounded to f32 as their type says.
    let f32s = |values: &[f32]| values.iter().map(|&x| f64::from(x)).collect::<Vec<_>>();
    assert_eq!(
        point_bits(&mesh.points),
        bits(&f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 0.5, 0.5, 1e-3]))
    );
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [1, 3, 2]]);
    let values = |name: &str| mesh.point_array(name).unwrap().values.clone();
    let velocity = f32s(&[
        0.1,
        0.2,
        0.3,
        -1.5,
        2.5e-3,
        7.0,
        1e-40,
        -0.0,
        f32::MAX,
        0.7,
        0.8,
        0.9,
    ]);
    assert_eq!(bits(&values("velocity")), bits(&velocity));
    assert_ne!(values("velocity")[0], 0.1, "Float32 text is rounded to f32");
    assert_eq!(values("level"), [-300.0, 0.0, 7.0, 32767.0]);
    // Integers beyond 2^53 round to the nearest f64.
    assert_eq!(
        values("id"),
        [0.0, 1.0, 9007199254740992.0, 18446744073709551616.0]
    );
    assert_eq!(
        bits(&values("precise")),
        bits(&[0.1, -2.2250738585072014e-308, 1e300, 0.1 + 0.2])
    );
    assert_eq!(mesh.point_data.len(), 4, "cell data is not point data");
}

/// One inline binary array: base64 of a `header_bytes`-byte count (`announced`) and `data`,
/// in one stream or as two.
fn binary_text(
    announced: u64,
    data: &[u8],
    header_bytes: usize,
    big_endian: bool,
    split: bool,
) -> String {
    let mut header = announced.to_le_bytes()[..header_bytes].to_vec();
    if big_endian {
        header.reverse();
    }
    match split {
        false => STANDARD.encode([header.as_slice(), data].concat()),
        true => STANDARD.encode(&header) + &STANDARD.encode(data),
    }
}

/// The ASCII test file with every array binary, in the given byte order and header width;
/// `split` encodes each header on its own and breaks the base64 into lines.
fn binary_variant(header_bytes: usize, big_endian: bool, split: bool) -> String {
    let header_type = if header_bytes == 4 {
        "UInt32"
    } else {
        "UInt64"
    };
    let byte_order = if big_endian {
        "BigEndian"
    } else {
        "LittleEndian"
    };
    let mut xml = ASCII_VTU
        .replace(
            "version=\"0.1\" byte_order=\"LittleEndian\"",
            &format!("version=\"1.0\" byte_order=\"{byte_order}\" header_type=\"{header_type}\""),
        )
        .replace("format=\"ascii\"", "format=\"binary\"");
    for element in data_arrays(ASCII_VTU) {
        let (attributes, text) = element;
        let ty = attributes.split('"').nth(1).unwrap();
        let bytes: Vec<u8> = text
            .split_ascii_whitespace()
            .flat_map(|token| typed_bytes(ty, token, big_endian))
            .collect();
        let mut encoded = binary_text(bytes.len() as u64, &bytes, header_bytes, big_endian, split);
        if split {
            let lines: Vec<&str> = encoded
                .as_bytes()
                .chunks(10)
                .map(|chunk| std::str::from_utf8(chunk).unwrap())
                .collect();
            encoded = lines.join("\n  ");
        }
        xml = xml.replacen(text, &encoded, 1);
    }
    xml
}

/// `token` as a value of VTK type `ty`, in the given byte order.
fn typed_bytes(ty: &str, token: &str, big_endian: bool) -> Vec<u8> {
    let mut le = match ty {
        "Float32" => token.parse::<f32>().unwrap().to_le_bytes().to_vec(),
        "Float64" => token.parse::<f64>().unwrap().to_le_bytes().to_vec(),
        "Int16" => token.parse::<i16>().unwrap().to_le_bytes().to_vec(),
        "Int32" => token.parse::<i32>().unwrap().to_le_bytes().to_vec(),
        "Int64" => token.parse::<i64>().unwrap().to_le_bytes().to_vec(),
        "UInt8" => token.parse::<u8>().unwrap().to_le_bytes().to_vec(),
        "UInt64" => token.parse::<u64>().unwrap().to_le_bytes().to_vec(),
        other => panic!("type {other}"),
    };
    if big_endian {
        le.reverse();
    }
    le
}

#[test]
fn binary_headers_byte_orders_and_split_streams_read_alike() {
    let dir = tempfile::tempdir().unwrap();
    let ascii_path = dir.path().join("ascii.vtu");
    std::fs::write(&ascii_path, ASCII_VTU).unwrap();
    let ascii = read_vtu(&ascii_path).unwrap();
    for header_bytes in [4, 8] {
        for big_endian in [false, true] {
            for split in [false, true] {
                let path = dir
                    .path()
                    .join(format!("{header_bytes}{big_endian}{split}.vtu"));
                std::fs::write(&path, binary_variant(header_bytes, big_endian, split)).unwrap();
                let case =
                    format!("{header_bytes}-byte header, big endian {big_endian}, split {split}");
                let mesh = match split {
                    // vtkio decodes one stream only.
                    false => assert_reads_like_vtkio(&path),
                    true => read_vtu(&path).unwrap(),
                };
                assert_eq!(
                    point_bits(&mesh.points),
                    point_bits(&ascii.points),
                    "{case}"
                );
                assert_eq!(mesh.triangles, ascii.triangles, "{case}");
                assert_eq!(array_bits(&mesh), array_bits(&ascii), "{case}");
            }
        }
    }
}

#[test]
fn solve_output_reads_back_as_flow_npy_and_obj_frames() {
    let out = tempfile::tempdir().unwrap();
    let input = PathBuf::from(common::shipped("rotating_sphere"));
    common::meshflow_ok(&[
        "solve",
        input.to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
    ]);
    let flow = read_npy(&out.path().join("flow.npy")).unwrap();
    let intrinsic = read_npy(&out.path().join("flow_intrinsic.npy")).unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    let times: Vec<f64> = summary["times"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_f64().unwrap())
        .collect();
    let datasets = read_pvd(&out.path().join("flow.pvd")).unwrap();
    let (slabs, n) = (flow.shape[0] as usize, flow.shape[1] as usize);
    assert_eq!((slabs, n, datasets.len()), (5, 642, 5));
    let max_speed = summary["max_speed"].as_f64().unwrap();
    assert!(max_speed > 0.01, "a real flow: {max_speed}");
    for (s, (time, file)) in datasets.iter().enumerate() {
        assert_eq!(*time, times[s], "slab {s} starts at frame {s}");
        assert_eq!(file, &out.path().join(format!("flow_{s:04}.vtu")));
        let mesh = read_vtu(file).unwrap();
        let frame = read_mesh(&input.join(format!("frame_{s}.obj"))).unwrap();
        assert_eq!(
            point_bits(&mesh.points),
            point_bits(&frame.positions),
            "slab {s}"
        );
        assert_eq!(mesh.triangles, frame.faces, "slab {s}");
        let slab =
            |npy: &meshflow::io::NpyArray, k: usize| npy.data[s * n * k..(s + 1) * n * k].to_vec();
        let array = |name: &str| mesh.point_array(name).unwrap();
        assert_eq!(
            bits(&array("flow").values),
            bits(&slab(&flow, 3)),
            "slab {s}"
        );
        assert_eq!(
            bits(&array("flow_intrinsic").values),
            bits(&slab(&intrinsic, 2)),
            "slab {s}"
        );
        assert_eq!(array("flow_intrinsic").components, 2);
        let speeds: Vec<f64> = slab(&flow, 3)
            .chunks_exact(3)
            .map(|u| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt())
            .collect();
        let worst = speeds
            .iter()
            .zip(&array("speed").values)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 1e-15 * max_speed, "slab {s}: speed off by {worst}");
        let grey = frame
            .image
            .expect("the shipped frames are coloured")
            .to_grey();
        assert_eq!(bits(&array("intensity").values), bits(&grey), "slab {s}");
    }
}

/// Writes `bytes` as `name` in a fresh directory, reads it and returns the error message,
/// checking that it names the file.
fn vtu_error(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    let message = read_vtu(&path).unwrap_err().to_string();
    assert!(
        message.contains(&path.display().to_string()),
        "names the file: {message}"
    );
    message
}

#[test]
fn malformed_vtu_files_are_errors_naming_file_and_fault() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.vtu");
    write_sample(&path, &sample());
    let valid = std::fs::read_to_string(&path).unwrap();
    let flow_line = valid.find("Name=\"flow\"").unwrap();
    let compressed = {
        let vtk = Vtk::import(&path).unwrap();
        vtk.try_into_xml_format(vtkio::xml::Compressor::ZLib, 9)
            .unwrap()
            .to_string()
    };
    let replace = |from: &str, to: &str| {
        assert!(valid.contains(from), "{from}");
        valid.replacen(from, to, 1)
    };
    let ascii_replace = |from: &str, to: &str| {
        assert!(ASCII_VTU.contains(from), "{from}");
        ASCII_VTU.replacen(from, to, 1)
    };
    // A base64 block whose header announces 16 bytes, followed by 24.
    let lying = binary_text(16, &[0; 24], 8, false, false);
    let blocks = data_arrays(&valid);
    let expect = |case: &str, text: &str, expected: &str| {
        let message = vtu_error(&format!("{case}.vtu"), text.as_bytes());
        assert!(message.contains(expected), "{case}: {message}");
    };
    // Truncation and sizes that disagree with the data.
    expect(
        "truncated",
        &valid[..flow_line + 400],
        "line 7: the file ends inside <DataArray> (opened at line 6)",
    );
    expect(
        "truncated base64",
        &replace(blocks[0].1, &blocks[0].1[..101]),
        "DataArray 'flow': invalid base64",
    );
    expect(
        "header lies",
        &replace(blocks[1].1, &lying),
        "line 9: DataArray 'intensity': the header announces 16 bytes, but 24 follow",
    );
    expect(
        "more points",
        &replace("NumberOfPoints=\"42\"", "NumberOfPoints=\"43\""),
        "DataArray 'Points': holds 1008 bytes, expected 129 = 43 × 3 components Float64 values \
         of 8 bytes",
    );
    expect(
        "huge counts",
        &replace(
            "NumberOfPoints=\"42\" NumberOfCells=\"80\"",
            "NumberOfPoints=\"6148914691236517206\" NumberOfCells=\"4000000000000000000\"",
        ),
        "line 4: NumberOfPoints=\"6148914691236517206\" with NumberOfCells=\"4000000000000000000\" \
         declares more than 18 EB, over the memory limit",
    );
    expect(
        "more cells",
        &replace("NumberOfCells=\"80\"", "NumberOfCells=\"100000\""),
        "DataArray 'types': holds 80 bytes, expected 100000 UInt8 values of 1 byte",
    );
    expect(
        "too few",
        &ascii_replace("-300 0 7 32767", "-300 0 7"),
        "line 13: DataArray 'level': holds 3 values, expected 4",
    );
    expect(
        "too many",
        &ascii_replace("-300 0 7 32767", "-300 0 7 1 2"),
        "DataArray 'level': holds more values, expected 4",
    );
    // Cells that are not triangles of the piece's points.
    expect(
        "quad",
        &ascii_replace("format=\"ascii\">5 5", "format=\"ascii\">5 9"),
        "DataArray 'types': cell 1 has type 9; meshflow reads triangles (type 5)",
    );
    expect(
        "four corners",
        &ascii_replace(">3 6<", ">4 6<"),
        "DataArray 'offsets': cell 0 ends at offset 4, expected 3",
    );
    expect(
        "outside",
        &ascii_replace("0 1 2 1 3 2", "0 1 2 1 4 2"),
        "DataArray 'connectivity': cell 1 refers to point 4, but the piece has 4 points",
    );
    expect(
        "negative",
        &ascii_replace("0 1 2 1 3 2", "0 1 2 1 -3 2"),
        "DataArray 'connectivity': value 4 is -3, not a non-negative integer",
    );
    expect(
        "float cells",
        &ascii_replace(
            "\"Int32\" Name=\"connectivity\"",
            "\"Float32\" Name=\"connectivity\"",
        ),
        "DataArray 'connectivity': type Float32 is not an integer type",
    );
    // Numbers that are not of their type.
    expect(
        "out of type",
        &ascii_replace("-300 0 7 32767", "-300 0 7 32768"),
        "DataArray 'level': value 3 '32768' is not a number of type Int16",
    );
    expect(
        "not a number",
        &ascii_replace("0.7 0.8 0.9", "0.7 0,8 0.9"),
        "DataArray 'velocity': value 10 '0,8' is not a number of type Float32",
    );
    // What meshflow does not read.
    expect(
        "compressed",
        &compressed,
        "compressed VTU (compressor=\"vtkZLibDataCompressor\") is not supported; meshflow \
         reads the files it writes",
    );
    expect(
        "appended",
        &ascii_replace(
            "\"level\" format=\"ascii\"",
            "\"level\" format=\"appended\" offset=\"0\"",
        ),
        "DataArray 'level': appended VTU data is not supported",
    );
    // Missing or repeated parts, other files.
    expect(
        "missing points",
        &ascii_replace("<Points>", "<Pointz>").replace("</Points>", "</Pointz>"),
        "<Piece> has no <Points> element",
    );
    expect(
        "missing offsets",
        &ascii_replace("Name=\"offsets\"", "Name=\"offset\""),
        "<Cells> has no DataArray 'offsets'",
    );
    expect(
        "two arrays",
        &ascii_replace("Name=\"id\"", "Name=\"level\""),
        "DataArray 'level': a second point array of this name",
    );
    expect(
        "poly data",
        &ascii_replace("type=\"UnstructuredGrid\"", "type=\"PolyData\""),
        "<VTKFile type=\"PolyData\">, expected type=\"UnstructuredGrid\"",
    );
    expect(
        "not XML",
        "solid cube\nfacet normal 0 0 1\n",
        "text outside the root element: 'solid cube",
    );
    expect(
        "HTML",
        "<html><body>404</body></html>",
        "not a VTK XML file: the root element is <html>",
    );
    expect(
        "mismatched",
        &ascii_replace("</Cells>", "</Cell>"),
        "line 33: not well-formed XML",
    );
    expect(
        "two pieces",
        &ascii_replace("</Piece>", "</Piece><Piece NumberOfPoints=\"0\"/>"),
        "<UnstructuredGrid> has 2 pieces; meshflow reads single-piece files",
    );
    expect("empty", "", "no XML element in the file");
    expect(
        "deep",
        &"<a>".repeat(100_000),
        "line 1: elements nested deeper than 64 levels",
    );
    let message = vtu_error("binary.vtu", &[0x89, b'P', b'N', b'G', 0xff, 0]);
    assert!(
        message.contains("not a VTK XML file: not UTF-8 text"),
        "{message}"
    );
    let missing = dir.path().join("missing.vtu");
    let message = read_vtu(&missing).unwrap_err().to_string();
    assert!(message.contains("missing.vtu"), "{message}");
}

#[test]
fn malformed_pvd_files_are_errors_naming_file_and_dataset() {
    // Each case is the inside of `<Collection>`, or a whole file when it starts with `<VTKFile`.
    let cases = [
        (
            "\n<DataSet file=\"a.vtu\"/>",
            "line 2: DataSet 0 has no timestep",
        ),
        ("<DataSet timestep=\"0\"/>", "DataSet 0 has no file"),
        (
            "<DataSet timestep=\"0\" file=\"a.vtu\"/>\n<DataSet timestep=\"one\" file=\"b.vtu\"/>",
            "line 2: DataSet 1 ('b.vtu'): timestep \"one\" is not a finite number",
        ),
        (
            "<DataSet timestep=\"inf\" file=\"a.vtu\"/>",
            "timestep \"inf\" is not a finite number",
        ),
        ("<DataSet", "not well-formed XML"),
        (
            "<VTKFile type=\"UnstructuredGrid\"/>",
            "<VTKFile type=\"UnstructuredGrid\">, expected type=\"Collection\"",
        ),
        (
            "<VTKFile type=\"Collection\"></VTKFile>",
            "<VTKFile> has no <Collection> element",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (k, (text, expected)) in cases.into_iter().enumerate() {
        let path = dir.path().join(format!("case{k}.pvd"));
        let file = match text.starts_with("<VTKFile") {
            true => text.to_string(),
            false => {
                format!("<VTKFile type=\"Collection\"><Collection>{text}</Collection></VTKFile>")
            }
        };
        std::fs::write(&path, file).unwrap();
        let message = read_pvd(&path).unwrap_err().to_string();
        assert!(message.contains(&path.display().to_string()), "{message}");
        assert!(message.contains(expected), "{expected:?} not in {message}");
    }
    // An empty collection is no error.
    let path = dir.path().join("empty.pvd");
    std::fs::write(
        &path,
        "<VTKFile type=\"Collection\"><Collection/></VTKFile>",
    )
    .unwrap();
    assert_eq!(read_pvd(&path).unwrap(), vec![]);
}

#[test]
fn truncated_and_corrupted_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sample.vtu");
    write_sample(&path, &sample());
    let written = std::fs::read(&path).unwrap();
    let originals = [written, ASCII_VTU.as_bytes().to_vec()];
    let probe = dir.path().join("probe.vtu");
    let read = |bytes: &[u8]| {
        std::fs::write(&probe, bytes).unwrap();
        read_vtu(&probe)
    };
    let (mut accepted, mut rejected) = (0, 0);
    for original in &originals {
        // Only the final newline may go.
        let complete = original.len() - 1;
        for cut in (0..original.len())
            .step_by(97)
            .chain([complete - 1, complete])
        {
            let result = read(&original[..cut]);
            assert_eq!(result.is_err(), cut < complete, "cut at {cut}");
        }
        for at in (5..original.len()).step_by(97) {
            for mask in [0x01, 0x10, 0x40, 0x80, 0xff] {
                let mut bytes = original.clone();
                bytes[at] ^= mask;
                match read(&bytes) {
                    Ok(_) => accepted += 1,
                    Err(error) => {
                        assert!(error.to_string().contains("probe.vtu"), "{error}");
                        rejected += 1;
                    }
                }
            }
        }
    }
    // Most flips break the base64 or the XML; some change a number and still read.
    assert!(
        rejected > accepted && accepted > 0,
        "{rejected} rejected, {accepted} accepted"
    );
}
