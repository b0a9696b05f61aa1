//! VTK XML output, checked independently: the binary blocks decoded by hand, the whole file
//! read back through vtkio, and the `.pvd` collection against its exact text.

use base64::engine::general_purpose::STANDARD;
use base64::Engine;
use meshflow::io::vtk::{write_pvd, write_vtu, PointArray};
use meshflow::shapes::icosphere;
use nalgebra::Vector3;
use std::path::Path;
use vtkio::model::{Attribute, CellType, DataSet, IOBuffer, Piece, VertexNumbers};

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

fn write_sample(path: &Path, s: &Sample) {
    let point_data = [
        PointArray {
            name: "flow",
            components: 3,
            values: &s.flow,
        },
        PointArray {
            name: "intensity",
            components: 1,
            values: &s.intensity,
        },
    ];
    write_vtu(path, &s.positions, &s.faces, &point_data).unwrap();
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
    let vtk = vtkio::Vtk::import(&path).unwrap();
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an UnstructuredGrid: {:?}", vtk.data);
    };
    assert_eq!(pieces.len(), 1);
    let Piece::Inline(piece) = &pieces[0] else {
        panic!("piece not inline");
    };
    let IOBuffer::F64(points) = &piece.points else {
        panic!("points are not Float64: {:?}", piece.points);
    };
    let expected: Vec<f64> = s.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    assert_eq!(bits(points), bits(&expected));

    let VertexNumbers::XML {
        connectivity,
        offsets,
    } = &piece.cells.cell_verts
    else {
        panic!("cells not in XML form");
    };
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
