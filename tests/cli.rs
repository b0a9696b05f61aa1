//! The `meshflow` binary: outputs equal the library's numbers; bad input gives one line on
//! stderr, a non-zero exit code and no output files.

mod common;

use common::{meshflow, meshflow_ok, shipped};
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{read_matrix_market, read_npy, read_obj};
use std::path::Path;

#[test]
fn operators_command_writes_the_library_operators() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("ops");
    let mesh_path = shipped("torus.obj");
    let run = meshflow_ok(&["operators", &mesh_path, "--out", dir.to_str().unwrap()]);

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

/// Copies the shipped rotating-sphere frames into a fresh directory, for editing.
fn sample_copy() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for k in 0..6 {
        let name = format!("frame_{k}.obj");
        std::fs::copy(
            Path::new(&shipped("rotating_sphere")).join(&name),
            dir.path().join(&name),
        )
        .unwrap();
    }
    dir
}

#[test]
fn solve_command_writes_the_library_flow() {
    let out = tempfile::tempdir().unwrap();
    let input = shipped("rotating_sphere");
    meshflow_ok(&[
        "solve",
        &input,
        "--out",
        out.path().to_str().unwrap(),
        "--gamma",
        "0.01",
    ]);
    let flow = read_npy(&out.path().join("flow.npy")).unwrap();
    let intrinsic = read_npy(&out.path().join("flow_intrinsic.npy")).unwrap();
    assert_eq!(
        (flow.shape.as_slice(), intrinsic.shape.as_slice()),
        ([5, 642, 3].as_slice(), [5, 642, 2].as_slice())
    );

    let sequence = meshflow::io::load_sequence(Path::new(&input), &Default::default())
        .unwrap()
        .sequence;
    let params = meshflow::flow::FlowParams {
        gamma: 0.01,
        ..Default::default()
    };
    let expected = meshflow::flow::compute_flow(&sequence, &params).unwrap();
    let values: Vec<f64> = expected
        .vectors
        .unwrap()
        .iter()
        .flatten()
        .flat_map(|u| [u.x, u.y, u.z])
        .collect();
    let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(scale > 0.01);
    assert!(values
        .iter()
        .zip(&flow.data)
        .all(|(a, b)| (a - b).abs() <= 1e-12 * scale));

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["slabs"], 5);
    assert_eq!(summary["vertices"], 642);
    assert_eq!(summary["params"]["gamma"], 0.01);
    assert!(summary["relative_residual"].as_f64().unwrap() < 1e-8);
    assert!(summary["energy"].as_f64().unwrap() < summary["energy_at_zero"].as_f64().unwrap());
    for term in ["data", "speed", "spatial", "temporal"] {
        assert!(summary["energy_terms"][term].is_number(), "{term}");
    }
    assert!(summary["iterations"].is_number() && summary["seconds"]["total"].is_number());
}

/// Runs `solve` with `args` appended and checks the failure contract; returns stderr.
fn failing_solve(input: &Path, args: &[&str]) -> String {
    let out = tempfile::tempdir().unwrap();
    let target = out.path().join("result");
    let mut all = vec![
        "solve",
        input.to_str().unwrap(),
        "--out",
        target.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    let run = meshflow(&all);
    assert!(!run.status.success(), "{args:?} should fail");
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(!target.exists(), "no output for {args:?}");
    stderr
}

#[test]
fn solve_rejects_bad_sequences_and_parameters() {
    let dir = sample_copy();
    let cases: [(&[&str], &str); 6] = [
        (&["--alpha", "-1"], "alpha"),
        (&["--gamma", "0"], "gamma"),
        (&["--beta", "nan"], "beta"),
        (&["--times", "0,1,2,2,3,4"], "strictly increasing"),
        (&["--times", "0,1,2"], "expected 6 frame times"),
        (&["--intensity", "/nonexistent/i.npy"], "/nonexistent/i.npy"),
    ];
    for (args, expected) in cases {
        let stderr = failing_solve(dir.path(), args);
        assert!(stderr.contains(expected), "{expected:?} not in {stderr}");
    }
    let intensity = dir.path().join("wrong.npy");
    meshflow::io::write_npy(&intensity, &[6, 641], &vec![0.5; 6 * 641]).unwrap();
    let stderr = failing_solve(dir.path(), &["--intensity", intensity.to_str().unwrap()]);
    assert!(stderr.contains("expected (6, 642)"), "{stderr}");

    // A frame with a vertex less: named by file.
    let frame = dir.path().join("frame_3.obj");
    let text = std::fs::read_to_string(&frame).unwrap();
    let first_v = text.find("\nv ").unwrap();
    let next_line = first_v + 1 + text[first_v + 1..].find('\n').unwrap();
    std::fs::write(
        &frame,
        format!("{}{}", &text[..first_v], &text[next_line..]),
    )
    .unwrap();
    let stderr = failing_solve(dir.path(), &[]);
    assert!(
        stderr.contains("frame_3.obj") && stderr.contains("641 vertices"),
        "{stderr}"
    );
    // Only one frame left.
    for k in 1..6 {
        std::fs::remove_file(dir.path().join(format!("frame_{k}.obj"))).unwrap();
    }
    assert!(failing_solve(dir.path(), &[]).contains("at least 2 frames"));
}

#[test]
fn solve_reports_undetermined_flow_and_suggests_beta() {
    // A flat square whose image varies along x only: nothing fixes the y component.
    let dir = tempfile::tempdir().unwrap();
    let surface = meshflow::shapes::grid(4, 4, 1.0, 1.0);
    for k in 0..3 {
        let grey: Vec<[f64; 3]> = surface
            .positions
            .iter()
            .map(|p| [(3.0 * p.x - 0.1 * k as f64).sin(); 3])
            .collect();
        meshflow::io::write_obj(
            &dir.path().join(format!("f{k}.obj")),
            &surface.positions,
            &surface.faces,
            Some(&grey),
        )
        .unwrap();
    }
    let stderr = failing_solve(dir.path(), &[]);
    assert!(stderr.contains("beta > 0"), "{stderr}");
    let out = tempfile::tempdir().unwrap();
    meshflow_ok(&[
        "solve",
        dir.path().to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
        "--beta",
        "0.001",
    ]);
}

#[test]
fn solve_checks_the_output_location_before_reading_anything() {
    // The input is broken too, but the unwritable output is what is reported: nothing is read
    // or solved when the result could not be saved.
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("file");
    std::fs::write(&blocker, "not a directory").unwrap();
    let out = blocker.join("out");
    let run = meshflow(&[
        "solve",
        "/nonexistent/frames",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("file/out") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}
