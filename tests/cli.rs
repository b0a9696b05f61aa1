//! The `meshflow` binary: outputs equal the library's numbers; bad input gives one line on
//! stderr, a non-zero exit code and no output files.

mod common;

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{read_matrix_market, read_npy, read_obj};
use std::path::Path;
use std::process::{Command, Output};

fn meshflow(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_meshflow"))
        .args(args)
        .output()
        .unwrap()
}

fn shipped(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("meshes")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

#[test]
fn operators_command_writes_the_library_operators() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("ops");
    let mesh_path = shipped("torus.obj");
    let run = meshflow(&["operators", &mesh_path, "--out", dir.to_str().unwrap()]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );

    let obj = read_obj(Path::new(&mesh_path)).unwrap();
    let mesh = meshflow::mesh::Mesh::new(obj.positions.len(), obj.faces).unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &obj.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    // Independent of the binary: the library's operators, built from the same file.
    let expected = fem::exported_operators(&mesh, &geometry, &connection);
    assert_eq!(
        expected.each_ref().map(|(name, _)| *name),
        ["cotan", "mass_scalar", "stiffness", "mass"]
    );
    for (name, matrix) in &expected {
        let written = read_matrix_market(&dir.join(format!("{name}.mtx"))).unwrap();
        assert_eq!(
            (written.nrows(), written.ncols()),
            (matrix.nrows(), matrix.ncols()),
            "{name}"
        );
        assert_eq!(
            common::relative_value_difference(matrix, &written),
            0.0,
            "{name}"
        );
    }
    let frames = read_npy(&dir.join("frames.npy")).unwrap();
    assert_eq!(frames.shape, vec![512, 2, 3]);
    let library = vertex_frames_in_r3(&mesh, &geometry, &connection, &obj.positions).unwrap();
    for (i, p) in library.iter().enumerate() {
        for k in 0..2 {
            for d in 0..3 {
                assert_eq!(frames.data[6 * i + 3 * k + d], p[(d, k)]);
            }
        }
    }
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains("512 vertices") && stdout.contains("Euler characteristic 0"),
        "{stdout}"
    );
}

/// Runs `operators` on `mesh_text` and returns stderr, checking the failure contract.
fn failing_operators(mesh_text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = dir.path().join("input.obj");
    std::fs::write(&mesh_path, mesh_text).unwrap();
    let out = dir.path().join("out");
    let run = meshflow(&[
        "operators",
        mesh_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(stderr.contains("input.obj"), "names the file: {stderr}");
    assert!(
        !out.exists() || std::fs::read_dir(&out).unwrap().next().is_none(),
        "no output files"
    );
    stderr
}

#[test]
fn bad_meshes_fail_with_one_line_naming_file_and_element() {
    let square = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
    let cases = [
        (
            format!("{square}f 1 2 3\nf 1 2 4\n"),
            "inconsistent orientation",
        ),
        (
            format!("{square}f 1 2 3\nf 1 3 4\nf 1 3 2\n"),
            "non-manifold edge",
        ),
        (
            format!("{square}v 5 5 5\nf 1 2 3\nf 1 3 4\n"),
            "vertex 4 is not used",
        ),
        ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n".to_string(), "face 0"),
        (
            "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n".to_string(),
            "vertex 1 has a non-finite position",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".to_string(), "line 4"),
        (String::new(), "no faces"),
    ];
    for (text, expected) in cases {
        let stderr = failing_operators(&text);
        assert!(stderr.contains(expected), "{expected:?} not in {stderr}");
    }
}

#[test]
fn missing_input_and_unwritable_output_are_reported() {
    let run = meshflow(&[
        "operators",
        "/nonexistent/mesh.obj",
        "--out",
        "/tmp/meshflow-never",
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("/nonexistent/mesh.obj") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(!Path::new("/tmp/meshflow-never").exists());

    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("file");
    std::fs::write(&blocker, "not a directory").unwrap();
    let out = blocker.join("out");
    let run = meshflow(&[
        "operators",
        &shipped("patch.obj"),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("file/out"));
}
