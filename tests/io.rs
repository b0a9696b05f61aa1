//! File formats: exact round trips, and clear errors (with line numbers) for broken files.

mod common;

use meshflow::connection::Connection;
use meshflow::fem::connection_laplacian;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{
    read_matrix_market, read_npy, read_obj, write_atomically, write_matrix_market, write_npy,
    write_obj, IoError,
};
use meshflow::shapes::icosphere;
use nalgebra::Vector3;
use std::path::Path;

fn write_file(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

#[test]
fn obj_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = icosphere(2);
    let jitter = common::noise(sphere.positions.len(), 3);
    let positions: Vec<Vector3<f64>> = sphere
        .positions
        .iter()
        .zip(&jitter)
        .map(|(p, j)| p * (1.0 + 1e-3 * j) + Vector3::repeat(1e-17))
        .collect();
    let colors: Vec<[f64; 3]> = jitter.iter().map(|&j| [j, j / 3.0, 1.7]).collect();
    let path = dir.path().join("sphere.obj");
    write_obj(&path, &positions, &sphere.faces, Some(&colors)).unwrap();
    let back = read_obj(&path).unwrap();
    assert_eq!(back.positions, positions);
    assert_eq!(back.faces, sphere.faces);
    assert_eq!(back.colors.unwrap(), colors);
}

#[test]
fn obj_reader_handles_polygons_references_and_keeps_vertex_order() {
    let dir = tempfile::tempdir().unwrap();
    let text = "# a quad and a triangle, vertices listed out of face order\n\
                v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n\
                o square\ng part\nusemtl none\ns off\n\
                f 4/1/1 1/1/1 2/1/1 3/1/1\nv 2 0.5 0\nf -4//1 -1//1 -3//1\n";
    let mesh = read_obj(&write_file(dir.path(), "quad.obj", text)).unwrap();
    assert_eq!(mesh.positions.len(), 5);
    assert_eq!(mesh.positions[3], Vector3::new(0.0, 1.0, 0.0));
    assert_eq!(mesh.faces, vec![[3, 0, 1], [3, 1, 2], [1, 4, 2]]);
    assert!(mesh.colors.is_none());
}

fn obj_error(text: &str) -> IoError {
    let dir = tempfile::tempdir().unwrap();
    read_obj(&write_file(dir.path(), "bad.obj", text)).unwrap_err()
}

#[test]
fn broken_obj_files_name_the_line() {
    let cases = [
        ("v 0 0 0\nv 1 0 zero\n", 2, "'zero' is not a number"),
        ("v 0 0 0\nv 1 0\n", 2, "needs 3, 4, 6 or 7 numbers"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
            4,
            "at least 3 vertices",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n",
            5,
            "vertex 9 does not exist",
        ),
        ("v 0 0 0\nv 1 0 0\nf 1 2 -7\n", 3, "out of range"),
    ];
    for (text, line, message) in cases {
        match obj_error(text) {
            IoError::Parse {
                line: l,
                message: m,
                ..
            } => {
                assert_eq!(l, line, "{text:?}");
                assert!(m.contains(message), "{m:?} should mention {message:?}");
            }
            other => panic!("{text:?}: unexpected {other:?}"),
        }
    }
    let partial = obj_error("v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0 0.5 0.5 0.5\nf 1 2 3\n");
    assert!(
        partial.to_string().contains("2 of 3 vertices have colours"),
        "{partial}"
    );
    let missing = read_obj(Path::new("/nonexistent/frame.obj")).unwrap_err();
    assert!(
        matches!(missing, IoError::File { .. })
            && missing.to_string().contains("/nonexistent/frame.obj")
    );
}

#[test]
fn npy_round_trip_and_validation() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.npy");
    let data: Vec<f64> = (0..24).map(|i| i as f64 * 0.1 - 1e-300).collect();
    write_npy(&path, &[2, 3, 4], &data).unwrap();
    let back = read_npy(&path).unwrap();
    assert_eq!((back.shape, back.data), (vec![2, 3, 4], data.clone()));
    assert!(write_npy(&dir.path().join("b.npy"), &[5, 5], &data).is_err());
    assert!(!dir.path().join("b.npy").exists());

    // Truncated: drop the last value.
    let bytes = std::fs::read(&path).unwrap();
    let cut = write_file(dir.path(), "cut.npy", &bytes[..bytes.len() - 8]);
    assert!(read_npy(&cut)
        .unwrap_err()
        .to_string()
        .contains("does not fit"));
    // Wrong dtype: the same header claiming int32 (same length, so the layout stays valid).
    let mut relabelled = bytes.clone();
    let at = relabelled.windows(3).position(|w| w == b"<f8").unwrap();
    relabelled[at..at + 3].copy_from_slice(b"<i4");
    let wrong = write_file(dir.path(), "int.npy", &relabelled);
    let message = read_npy(&wrong).unwrap_err().to_string();
    assert!(message.contains("expected float64"), "{message}");
    let garbage = write_file(dir.path(), "garbage.npy", b"definitely not numpy");
    assert!(read_npy(&garbage)
        .unwrap_err()
        .to_string()
        .contains("not a valid .npy"));
}

#[test]
fn matrix_market_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = icosphere(1);
    let mesh = sphere.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &sphere.positions).unwrap();
    let k = connection_laplacian(&mesh, &geometry, &Connection::new(&mesh, &geometry));
    let path = dir.path().join("k.mtx");
    write_matrix_market(&path, &k).unwrap();
    let back = read_matrix_market(&path).unwrap();
    assert_eq!(common::relative_value_difference(&k, &back), 0.0);
}

#[test]
fn failed_atomic_write_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.bin");
    std::fs::write(&target, b"old").unwrap();
    let err = write_atomically(&target, |w| {
        use std::io::Write;
        w.write_all(b"half of the new conte")?;
        Err(std::io::Error::other("disk on fire"))
    })
    .unwrap_err();
    assert!(err.to_string().contains("disk on fire"));
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary file is left"
    );
}
