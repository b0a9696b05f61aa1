//! Every reader of a self-contained format takes a stream beside a path, and reads the same
//! from both; a stream longer than the memory limit is refused by name, not read whole.

use meshflow::format::ply::{read_ply, read_ply_from, write_ply, PlyEncoding};
use meshflow::format::vtk::{read_vtu, read_vtu_from, write_vtu};
use meshflow::format::{read_matrix_market, read_matrix_market_from, write_matrix_market};
use meshflow::format::{read_npy, read_npy_from, read_obj, read_obj_from, write_npy};
use meshflow::shapes::icosphere;
use std::path::Path;

/// The bytes of `path` as a stream.
fn stream(path: &Path) -> std::io::Cursor<Vec<u8>> {
    std::io::Cursor::new(std::fs::read(path).unwrap())
}

#[test]
fn streams_read_as_files_do_and_within_the_memory_limit() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = icosphere(1);
    let name = Path::new("<stdin>");

    let obj = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/icosphere.obj");
    let from_file = read_obj(&obj).unwrap();
    assert_eq!(from_file.positions.len(), 642);
    assert_eq!(read_obj_from(stream(&obj), name).unwrap(), from_file);

    let ply = dir.path().join("sphere.ply");
    let grey: Vec<f64> = sphere.positions.iter().map(|p| p.z).collect();
    let properties = [("intensity", grey.as_slice())];
    let binary = PlyEncoding::BinaryLittleEndian;
    write_ply(
        &ply,
        &sphere.positions,
        &sphere.faces,
        None,
        &properties,
        binary,
    )
    .unwrap();
    let from_file = read_ply(&ply).unwrap();
    assert_eq!(from_file.positions, sphere.positions);
    assert_eq!(read_ply_from(stream(&ply), name).unwrap(), from_file);

    let vtu = dir.path().join("sphere.vtu");
    write_vtu(&vtu, &sphere.positions, &sphere.faces, &[]).unwrap();
    let from_file = read_vtu(&vtu).unwrap();
    assert_eq!(read_vtu_from(stream(&vtu), name).unwrap(), from_file);

    let npy = dir.path().join("values.npy");
    let values: Vec<f64> = (0..12).map(|i| i as f64 / 3.0).collect();
    write_npy(&npy, &[3, 4], &values).unwrap();
    let from_stream = read_npy_from(stream(&npy), name).unwrap();
    assert_eq!(
        (from_stream.shape.clone(), from_stream.data.clone()),
        (vec![3, 4], values)
    );
    let from_file = read_npy(&npy).unwrap();
    assert_eq!(
        (from_file.shape, from_file.data),
        (from_stream.shape, from_stream.data)
    );

    let mtx = dir.path().join("laplacian.mtx");
    let mesh = sphere.mesh().unwrap();
    let geometry = meshflow::geometry::IntrinsicGeometry::from_positions(&mesh, &sphere.positions);
    let laplacian = meshflow::fem::cotan_laplacian(&mesh, &geometry.unwrap());
    write_matrix_market(&mtx, &laplacian).unwrap();
    let from_file = read_matrix_market(&mtx).unwrap();
    let from_stream = read_matrix_market_from(stream(&mtx), name).unwrap();
    assert_eq!(from_stream.val(), from_file.val());
    assert_eq!(from_stream.row_idx(), from_file.row_idx());

    // Over the limit: refused, naming the stream; the limit restored for nothing else here.
    let limit = meshflow::limits::memory_limit();
    meshflow::limits::set_memory_limit(1000);
    let error = read_obj_from(stream(&obj), name).unwrap_err().to_string();
    meshflow::limits::set_memory_limit(limit);
    assert!(error.starts_with("<stdin>: "), "{error}");
    assert!(error.contains("the stream"), "{error}");
}
