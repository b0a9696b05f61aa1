//! The `meshflow` binary: outputs equal the library's numbers; bad input gives one line on
//! stderr, a non-zero exit code and no output files.

mod common;

use common::{is_progress_line, listing, meshflow, meshflow_ok, meshflow_with_progress, shipped};
use meshflow::accuracy::{compare_result, FlowErrors};
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::flow::Warping;
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
    // A Möbius strip of three quads: top 1..3, bottom 4..6, the last quad joins top to bottom.
    let moebius =
        "v 1 0 0\nv -0.5 0.87 0\nv -0.5 -0.87 0\nv 1 0 1\nv -0.5 0.87 1\nv -0.5 -0.87 1\n\
        f 1 4 5\nf 1 5 2\nf 2 5 6\nf 2 6 3\nf 3 6 1\nf 3 1 4\n";
    let cases = [
        (moebius.to_string(), "not orientable"),
        (
            format!("{square}f 1 2 3\nf 1 3 4\nf 1 3 2\n"),
            "non-manifold edge",
        ),
        (
            format!("{square}v 2 2 0\nv 3 2 0\nf 1 2 3\nf 3 5 6\n"),
            "file vertex 2 has 2 separate fans",
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
        let repairable = ["orientable", "non-manifold", "fans"];
        if repairable.iter().any(|r| expected.contains(r)) {
            assert!(stderr.contains("use --repair"), "{stderr}");
        }
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

/// The library's flow of a file input with smoothness `gamma` (other parameters default),
/// independently of the binary.
fn library_flow(
    input: &str,
    gamma: f64,
) -> (meshflow::flow::MeshSequence, meshflow::flow::FlowResult) {
    let sequence = meshflow::io::load_sequence(Path::new(input), &Default::default())
        .unwrap()
        .sequence;
    let params = meshflow::flow::FlowParams {
        gamma: meshflow::flow::Weight::Value(gamma),
        ..Default::default()
    };
    let flow = meshflow::flow::compute_flow(&sequence, &params).unwrap();
    (sequence, flow)
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

    let (_, expected) = library_flow(&input, 0.01);
    let values: Vec<f64> = expected
        .vectors
        .as_ref()
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
    // As given, as used (the default time scale resolved with the data's scales), and the scales.
    assert_eq!(summary["params"]["gamma"]["value"], 0.01);
    assert_eq!(summary["params"]["alpha"]["relative"], 1.0);
    assert_eq!(summary["weights"]["gamma"], 0.01);
    let weights = expected.weights;
    assert_eq!(json_f64(&summary["weights"]["alpha"]), weights.alpha);
    assert_eq!(
        json_f64(&summary["scales"]["gradient"]),
        expected.scales.gradient
    );
    assert!(summary["relative_residual"].as_f64().unwrap() < 1e-8);
    assert!(summary["energy"].as_f64().unwrap() < summary["energy_at_zero"].as_f64().unwrap());
    for term in ["data", "speed", "spatial", "temporal"] {
        assert!(summary["energy_terms"][term].is_number(), "{term}");
    }
    assert!(summary["iterations"].is_number() && summary["seconds"]["total"].is_number());
}

#[test]
fn solve_finishes_when_its_reader_has_gone() {
    // `meshflow solve … | head`: stdout and stderr closed while the run still writes to them.
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("flow");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_meshflow"))
        .args(["solve", &shipped("rotating_sphere"), "--out"])
        .arg(&dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert!(status.success(), "{status}");
    assert!(summary(&dir)["relative_residual"].as_f64().unwrap() < 1e-8);
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
fn solve_reports_undetermined_flow_and_suggests_a_speed_penalty() {
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
    assert!(stderr.contains("--speed-penalty 0.01"), "{stderr}");
    let out = tempfile::tempdir().unwrap();
    meshflow_ok(&[
        "solve",
        dir.path().to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
        "--speed-penalty",
        "0.01",
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

/// Point array `name` of a `.vtu` file, read back through vtkio.
fn vtu_point_array(path: &Path, name: &str) -> Vec<f64> {
    use vtkio::model::{Attribute, DataSet, IOBuffer, Piece};
    let vtk = vtkio::Vtk::import(path).unwrap();
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("{}: not an UnstructuredGrid", path.display());
    };
    let Piece::Inline(piece) = &pieces[0] else {
        panic!("piece not inline");
    };
    piece
        .data
        .point
        .iter()
        .find_map(|attribute| match attribute {
            Attribute::DataArray(array) if array.name == name => match &array.data {
                IOBuffer::F64(values) => Some(values.clone()),
                other => panic!("'{name}' is not Float64: {other:?}"),
            },
            _ => None,
        })
        .unwrap_or_else(|| panic!("{}: no point array '{name}'", path.display()))
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// `|a − b| ≤ tolerance · max(|b|, 1e-300)` for every pair.
/// Relative closeness, entry by entry; NaN (an undefined measure) matches only NaN.
fn assert_close(a: &[f64], b: &[f64], tolerance: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        if x.is_nan() || y.is_nan() {
            assert!(x.is_nan() && y.is_nan(), "{what}[{k}]: {x} vs {y}");
            continue;
        }
        assert!(
            (x - y).abs() <= tolerance * y.abs().max(1e-300),
            "{what}[{k}]: {x} vs {y}"
        );
    }
}

fn json_f64(value: &serde_json::Value) -> f64 {
    value
        .as_f64()
        .unwrap_or_else(|| panic!("not a number: {value}"))
}

#[test]
fn solve_with_ground_truth_writes_the_library_errors() {
    let out = tempfile::tempdir().unwrap();
    let input = shipped("rotating_sphere");
    let truth_file = Path::new(&input).join("ground_truth.npy");
    let run = meshflow_ok(&[
        "solve",
        &input,
        "--out",
        out.path().to_str().unwrap(),
        "--gamma",
        "0.01",
        "--ground-truth",
        truth_file.to_str().unwrap(),
    ]);

    // The shipped file is the synthetic sequence's true flow ω ẑ × x, bitwise.
    let synthetic = meshflow::synth::rotating_sphere(3, 6, 1.0, 0.05).unwrap();
    let shipped_truth = read_npy(&truth_file).unwrap();
    assert_eq!(shipped_truth.shape, vec![5, 642, 3]);
    let values: Vec<f64> = synthetic
        .flow
        .iter()
        .flatten()
        .flat_map(|u| [u.x, u.y, u.z])
        .collect();
    assert_eq!(shipped_truth.data, values);

    // The library on the same files, compared with the synthetic truth.
    let (sequence, flow) = library_flow(&input, 0.01);
    let expected = compare_result(&sequence, &flow, &synthetic.flow).unwrap();
    assert!(expected.mean_angular_degrees > 0.1, "{expected:?}");

    let reported = &summary(out.path())["ground_truth"];
    assert_eq!(reported["file"], truth_file.to_str().unwrap());
    let zero = FlowErrors::zero_flow(&sequence, &synthetic.flow).unwrap();
    for (json, errors) in [(reported, &expected), (&reported["zero_flow"], &zero)] {
        let overall = [
            ("mean_angular_error_degrees", errors.mean_angular_degrees),
            (
                "mean_direction_error_degrees",
                errors.mean_direction_degrees,
            ),
            ("relative_endpoint_error", errors.relative_endpoint),
            ("median_speed_ratio", errors.median_speed_ratio),
            ("moving_fraction", errors.moving_fraction),
            ("mean_endpoint_error", errors.mean_endpoint),
            ("max_angular_error_degrees", errors.max_angular_degrees),
            ("max_endpoint_error", errors.max_endpoint),
        ];
        for (key, value) in overall {
            assert_close(&[json_f64(&json[key])], &[value], 1e-12, key);
        }
    }
    assert_eq!(
        json_f64(&reported["zero_flow"]["relative_endpoint_error"]),
        1.0
    );
    let slabs = reported["slabs"].as_array().unwrap();
    assert_eq!(slabs.len(), 5);
    for (slab, errors) in slabs.iter().zip(&expected.slabs) {
        let pairs = [
            ("mean_angular_error_degrees", errors.mean_angular_degrees),
            ("mean_endpoint_error", errors.mean_endpoint),
            ("duration", errors.duration),
            ("area", errors.area),
        ];
        for (key, value) in pairs {
            assert_close(&[json_f64(&slab[key])], &[value], 1e-12, key);
        }
    }

    for (name, per_vertex) in [
        ("angular_error", &expected.angular_degrees),
        ("endpoint_error", &expected.endpoint),
        ("direction_error", &expected.direction_degrees),
    ] {
        let array = read_npy(&out.path().join(format!("{name}.npy"))).unwrap();
        assert_eq!(array.shape, vec![5, 642], "{name}");
        assert_close(&array.data, &per_vertex.concat(), 1e-9, name);
        let vtu = vtu_point_array(&out.path().join("flow_0003.vtu"), name);
        assert_close(&vtu, &per_vertex[3], 1e-9, name);
    }
    let stdout = String::from_utf8_lossy(&run.stdout);
    for line in [
        format!(
            "ground truth: flow: angular error {:.2}°",
            expected.mean_angular_degrees
        ),
        format!(
            "relative endpoint error {:.1} %",
            100.0 * expected.relative_endpoint
        ),
        format!("zero flow: angular error {:.2}°", zero.mean_angular_degrees),
    ] {
        assert!(stdout.contains(&line), "{line:?} not in {stdout}");
    }
}

/// The shipped sample with a copy of vertex `copied` inserted as the files' vertex 0 and used
/// by one face in place of the original: welding numbers the mesh vertices differently from
/// the files.
fn sample_with_duplicate(copied: usize) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for k in 0..6 {
        let name = format!("frame_{k}.obj");
        let obj = read_obj(&Path::new(&shipped("rotating_sphere")).join(&name)).unwrap();
        let mut positions = vec![obj.positions[copied]];
        positions.extend(&obj.positions);
        let mut colors = obj.colors.unwrap();
        colors.insert(0, colors[copied]);
        let mut faces: Vec<[u32; 3]> = obj.faces.iter().map(|f| f.map(|v| v + 1)).collect();
        let user = obj
            .faces
            .iter()
            .position(|f| f.contains(&(copied as u32)))
            .unwrap();
        faces[user] = faces[user].map(|v| if v == copied as u32 + 1 { 0 } else { v });
        meshflow::io::write_obj(&dir.path().join(&name), &positions, &faces, Some(&colors))
            .unwrap();
    }
    dir
}

#[test]
fn ground_truth_is_mapped_through_the_welding() {
    let copied = 5;
    let input = sample_with_duplicate(copied);
    // The shipped truth in the files' numbering: file vertex 0 is vertex `copied` again.
    let truth = read_npy(
        Path::new(&shipped("rotating_sphere"))
            .join("ground_truth.npy")
            .as_path(),
    )
    .unwrap();
    let rows: Vec<&[f64]> = truth.data.chunks(3).collect();
    let with_copy: Vec<f64> = rows
        .chunks(642)
        .flat_map(|slab| {
            std::iter::once(slab[copied])
                .chain(slab.iter().copied())
                .flatten()
                .copied()
                .collect::<Vec<_>>()
        })
        .collect();
    let truth_file = input.path().join("truth.npy");
    meshflow::io::write_npy(&truth_file, &[5, 643, 3], &with_copy).unwrap();

    let solve = |input: &str, truth: &str| {
        let out = tempfile::tempdir().unwrap();
        meshflow_ok(&[
            "solve",
            input,
            "--out",
            out.path().to_str().unwrap(),
            "--gamma",
            "0.01",
            "--ground-truth",
            truth,
        ]);
        out
    };
    let welded = solve(input.path().to_str().unwrap(), truth_file.to_str().unwrap());
    let plain_truth = format!("{}/ground_truth.npy", shipped("rotating_sphere"));
    let plain = solve(&shipped("rotating_sphere"), &plain_truth);

    // NPY outputs are in the files' numbering: file vertex 0 is the copy of original vertex
    // `copied`, file vertex i ≥ 1 is original i − 1.
    let original = |i: usize| if i == 0 { copied } else { i - 1 };
    let welded_errors = read_npy(&welded.path().join("angular_error.npy")).unwrap();
    let plain_errors = read_npy(&plain.path().join("angular_error.npy")).unwrap();
    assert_eq!(welded_errors.shape, vec![5, 643]);
    let permuted: Vec<f64> = (0..5)
        .flat_map(|s| (0..643).map(move |i| (s, i)))
        .map(|(s, i)| plain_errors.data[s * 642 + original(i)])
        .collect();
    assert_close(&welded_errors.data, &permuted, 1e-6, "angular_error");
    // Mesh vertex 0 is file vertices 0 and copied + 1; file vertices 1..=copied keep their
    // numbers, later ones move down by one.
    let (shape, map) =
        meshflow::io::read_npy_indices(&welded.path().join("vertex_map.npy")).unwrap();
    assert_eq!(shape, vec![643]);
    let expected: Vec<u32> = (0..643u32)
        .map(|i| match i {
            i if i <= copied as u32 => i,
            i if i == copied as u32 + 1 => 0,
            i => i - 1,
        })
        .collect();
    assert_eq!(map, expected);
    assert!(!plain.path().join("vertex_map.npy").exists());

    // The two copies disagree: refused, naming both file vertices.
    let mut broken = with_copy.clone();
    broken[3 * (copied + 1)] += 1e-3;
    meshflow::io::write_npy(&truth_file, &[5, 643, 3], &broken).unwrap();
    let stderr = failing_solve(
        input.path(),
        &["--ground-truth", truth_file.to_str().unwrap()],
    );
    assert!(
        stderr.contains("truth.npy")
            && stderr.contains(&format!("file vertices 0 and {}", copied + 1)),
        "{stderr}"
    );
}

#[test]
fn solve_reruns_replace_the_earlier_output_as_a_whole() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let out_arg = out.to_str().unwrap();
    let input = shipped("rotating_sphere");
    let truth = shipped("rotating_sphere/ground_truth.npy");
    meshflow_ok(&["solve", &input, "--out", out_arg, "--ground-truth", &truth]);
    let first = [
        "angular_error.npy",
        "direction_error.npy",
        "endpoint_error.npy",
        "flow.glb",
        "flow.npy",
        "flow.pvd",
        "flow_0000.vtu",
        "flow_0001.vtu",
        "flow_0002.vtu",
        "flow_0003.vtu",
        "flow_0004.vtu",
        "flow_intrinsic.npy",
        "meshflow_run.json",
        "summary.json",
        "velocity.npy",
    ];
    assert_eq!(listing(&out), first);
    // Three frames, NPY only: nothing of the five-slab run is left.
    let three = format!("{input}/frame_[0-2].obj");
    meshflow_ok(&["solve", &three, "--out", out_arg, "--format", "npy"]);
    let second = [
        "flow.npy",
        "flow_intrinsic.npy",
        "meshflow_run.json",
        "summary.json",
        "velocity.npy",
    ];
    assert_eq!(listing(&out), second);
    assert_eq!(read_npy(&out.join("flow.npy")).unwrap().shape, [2, 642, 3]);
    let manifest = meshflow::io::RunManifest::read(&out).unwrap();
    assert_eq!(
        manifest.commands,
        [["meshflow", "solve", &three, "--out", out_arg, "--format", "npy"]]
    );

    // A run that fails after staging (a ground truth for five slabs) leaves it untouched.
    let before = std::fs::read(out.join("flow.npy")).unwrap();
    let run = meshflow(&["solve", &three, "--out", out_arg, "--ground-truth", &truth]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert_eq!(listing(&out), second);
    assert_eq!(std::fs::read(out.join("flow.npy")).unwrap(), before);
    assert_eq!(listing(dir.path()), ["run"], "no staging directory is left");

    // A directory meshflow did not write: refused before the input is even looked at.
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let run = meshflow(&["solve", "/nonexistent/frames", "--out", out_arg]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1));
    assert_eq!(
        stderr.trim(),
        format!(
            "meshflow: error: {out_arg}: holds files that meshflow did not write (notes.txt); \
             choose another output directory, empty it, or add --force to write into it (its \
             other files stay)"
        )
    );
    meshflow_ok(&[
        "solve", &input, "--out", out_arg, "--force", "--format", "npy",
    ]);
    assert_eq!(
        listing(&out),
        [
            "flow.npy",
            "flow_intrinsic.npy",
            "meshflow_run.json",
            "notes.txt",
            "summary.json",
            "velocity.npy"
        ]
    );
}

#[test]
fn operators_replace_their_own_output_and_refuse_others() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ops");
    let out_arg = out.to_str().unwrap();
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("stale.mtx"), "old").unwrap();
    let run = meshflow(&["operators", "/nonexistent/mesh.obj", "--out", out_arg]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.code() == Some(1) && stderr.contains("not a meshflow output (stale.mtx)"),
        "{stderr}"
    );
    let written = [
        "cotan.mtx",
        "frames.npy",
        "mass.mtx",
        "mass_scalar.mtx",
        "meshflow_run.json",
        "stiffness.mtx",
    ];
    std::fs::remove_file(out.join("stale.mtx")).unwrap();
    meshflow_ok(&["operators", &shipped("patch.obj"), "--out", out_arg]);
    assert_eq!(listing(&out), written);
    let patch = read_npy(&out.join("frames.npy")).unwrap().shape;
    meshflow_ok(&["operators", &shipped("torus.obj"), "--out", out_arg]);
    assert_eq!(listing(&out), written);
    let torus = read_npy(&out.join("frames.npy")).unwrap().shape;
    assert_eq!((patch, torus), (vec![117, 2, 3], vec![512, 2, 3]));
}

#[test]
fn unquoted_globs_get_a_hint() {
    let input = shipped("rotating_sphere");
    let frames: Vec<String> = (0..3).map(|k| format!("{input}/frame_{k}.obj")).collect();
    let run = meshflow(&["solve", &frames[0], &frames[1], &frames[2], "--out", "o"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2));
    assert_eq!(
        stderr.trim(),
        format!(
            "meshflow: error: unexpected argument '{}' found; it looks like the shell \
             expanded a glob into many files: quote it ('{input}/*.obj') or give the \
             directory ({input}) (see meshflow --help)",
            frames[1]
        )
    );
    // Other stray arguments get no hint.
    let run = meshflow(&["solve", &input, "extra.txt", "--out", "o"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(
        stderr.trim(),
        "meshflow: error: unexpected argument 'extra.txt' found (see meshflow --help)"
    );
}

#[test]
fn animations_are_chosen_on_the_command_line() {
    use meshflow::io::gltf_write::{write_glb_animation, AnimationFrame};
    let dir = tempfile::tempdir().unwrap();
    let sphere = meshflow::shapes::icosphere(1);
    let colours: Vec<[f64; 3]> = sphere.positions.iter().map(|p| [p.x.abs(); 3]).collect();
    let frames: Vec<AnimationFrame> = [0.0, 1.0]
        .iter()
        .map(|&time| AnimationFrame {
            time,
            positions: &sphere.positions,
            colors: &colours,
        })
        .collect();
    let file = dir.path().join("one.glb");
    write_glb_animation(&file, &sphere.faces, &frames).unwrap();
    let out = dir.path().join("out");
    let solve = |animation: &str| {
        meshflow(&[
            "solve",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--animation",
            animation,
            "--beta",
            "1",
        ])
    };
    assert!(solve("0").status.success());
    let run = solve("walk");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1));
    assert!(
        stderr.contains("one.glb: no animation \"walk\": the file has 0: (unnamed)"),
        "{stderr}"
    );
    let run = meshflow(&[
        "solve",
        &shipped("rotating_sphere"),
        "--out",
        out.to_str().unwrap(),
        "--animation",
        "0",
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("--animation applies to a glTF animation"),
        "{stderr}"
    );
}

#[test]
fn operators_builds_the_mesh_as_solve_does_without_textures() {
    let dir = tempfile::tempdir().unwrap();
    // A square of two faces, the second using its own copy (vertex 5) of vertex 2; a triangle
    // hanging at vertex 2 by that vertex alone; an unused vertex 4; a material library that
    // does not exist (textures are not read).
    let obj = "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 7 7 7\nv 1 1 0\n\
        v 2 1 0\nv 2 2 0\nvt 0 0\nusemtl paint\nf 1/1 2/1 3/1\nf 1/1 6/1 4/1\nf 3/1 7/1 8/1\n";
    let mesh_path = dir.path().join("square.obj");
    std::fs::write(&mesh_path, obj).unwrap();
    let run = meshflow(&[
        "operators",
        mesh_path.to_str().unwrap(),
        "--out",
        dir.path().join("refused").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("file vertex 2 (welded with file vertex 5) has 2 separate fans")
            && stderr.contains("use --repair"),
        "{stderr}"
    );

    let out = dir.path().join("ops");
    let run = meshflow_ok(&[
        "operators",
        mesh_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--repair",
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("dropped 1 vertex that no face uses (e.g. file vertex 4)")
            && stderr.contains("repaired: split 1 non-manifold vertex into 2"),
        "{stderr}"
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains("7 vertices (welded 1 duplicate vertex), 3 faces")
            && stdout.contains("Euler characteristic 2"),
        "{stdout}"
    );
    // Mesh vertex 2 is file vertices 2 and 5; 3 is vertex 2's piece in the hanging triangle.
    let table = std::fs::read(out.join("vertex_map.npy")).unwrap();
    let table = npyz::NpyFile::new(&table[..]).unwrap();
    assert_eq!(
        table.into_vec::<i64>().unwrap(),
        vec![0, 1, 2, 4, -1, 2, 5, 6]
    );
    assert_eq!(
        read_npy(&out.join("frames.npy")).unwrap().shape,
        vec![7, 2, 3]
    );
    assert_eq!(
        read_matrix_market(&out.join("cotan.mtx")).unwrap().nrows(),
        7
    );

    // solve does read the material library, and says which file asked for it.
    let frames = dir.path().join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..2 {
        std::fs::write(frames.join(format!("f{k}.obj")), obj).unwrap();
    }
    let stderr = failing_solve(&frames, &["--repair"]);
    assert!(
        stderr.contains("f0.obj: mtllib \"missing.mtl\": cannot read")
            && stderr.contains("missing.mtl: No such file"),
        "{stderr}"
    );
}

/// `meshflow track` on OBJ frames meshed each on its own writes the library's tracked
/// sequence as an NPY directory that `solve` reads; `solve` on the raw frames points to
/// `track`; a step bound too small is one line naming frame and vertex, with no output.
#[test]
fn track_command_writes_the_library_tracking_for_solve() {
    use meshflow::synth::remeshed_pulsating_sphere;
    use meshflow::track::{track, TrackOptions};
    let scene = remeshed_pulsating_sphere(2, 3, 0.1, 0.5).unwrap();
    let work = tempfile::tempdir().unwrap();
    let frames = work.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    for (k, frame) in scene.frames.iter().enumerate() {
        let grey: Vec<[f64; 3]> = frame.intensity.iter().map(|&g| [g; 3]).collect();
        let path = frames.join(format!("frame_{k}.obj"));
        meshflow::io::write_obj(&path, &frame.positions, &frame.faces, Some(&grey)).unwrap();
    }
    let (frames, tracked) = (frames.to_str().unwrap(), work.path().join("tracked"));
    let tracked = tracked.to_str().unwrap();
    meshflow_ok(&["track", frames, "--out", tracked]);

    let expected = track(&scene.frames, None, &TrackOptions::default()).unwrap();
    let positions = read_npy(&Path::new(tracked).join("positions.npy")).unwrap();
    assert_eq!(positions.shape, vec![3, 162, 3]);
    let library: Vec<f64> = (0..3)
        .flat_map(|k| expected.sequence.positions(k).unwrap().to_vec())
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    let difference = positions
        .data
        .iter()
        .zip(&library)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(difference < 1e-12, "{difference:e}");
    assert!(listing(Path::new(tracked)).contains(&"track.json".to_string()));

    let out = work.path().join("flow");
    meshflow_ok(&["solve", tracked, "--out", out.to_str().unwrap()]);
    let raw = meshflow(&["solve", frames, "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&raw.stderr);
    assert!(
        !raw.status.success() && stderr.contains("`meshflow track`"),
        "{stderr}"
    );

    let refused = work.path().join("refused");
    let run = meshflow(&[
        "track",
        frames,
        "--max-step",
        "1e-6",
        "--out",
        refused.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("frame 1: vertex 0 (at ("), "{stderr}");
    assert!(!refused.exists(), "no output for a failed run");
}

/// `--large-motion` warps (its flow differs from the single solve's), says each warp in the
/// log and reports every solve's share; `--levels` above 1 with `--warps 0` is refused in one
/// line.
#[test]
fn large_motion_flags_choose_coarse_to_fine_warping() {
    let work = tempfile::tempdir().unwrap();
    let input = shipped("rotating_sphere");
    let out = |name: &str| work.path().join(name).to_str().unwrap().to_string();
    meshflow_ok(&["solve", &input, "--out", &out("linear"), "--format", "npy"]);
    let warped = meshflow_with_progress(&[
        "solve",
        &input,
        "--out",
        &out("warped"),
        "--format",
        "npy,vtu",
        "--large-motion",
        "--png",
        "--slabs",
        "0",
    ]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&warped.stdout),
        String::from_utf8_lossy(&warped.stderr),
    );
    assert!(warped.status.success(), "{stderr}");
    let solves = Warping::LARGE_MOTION.solves();
    // stderr is a pipe here: plain progress lines, one per warp.
    for k in 1..=solves {
        let said = format!("] warping: solve {k} of {solves} (level");
        assert!(
            stderr.lines().any(|l| l.contains(&said)),
            "{said}: {stderr}"
        );
    }
    assert!(stderr.lines().all(is_progress_line), "{stderr}");
    let summary = summary(&work.path().join("warped"));
    let steps = summary["seconds"]["steps"].as_array().unwrap();
    assert_eq!(steps.len(), solves, "{summary}");
    let step_seconds: f64 = steps.iter().map(|s| s["seconds"].as_f64().unwrap()).sum();
    let total = summary["seconds"]["total"].as_f64().unwrap();
    assert!(step_seconds <= total, "{step_seconds} > {total}");
    assert!(
        stdout.contains(&format!("{solves} solves (level ")),
        "{stdout}"
    );
    let written = listing(&work.path().join("warped"));
    assert!(
        written.contains(&"residual_0000.png".to_string()),
        "{written:?}"
    );
    let pictures = written.iter().filter(|f| f.ends_with(".png")).count();
    let said = format!(
        "pictures: {pictures} PNG files for 1 slab in {}",
        out("warped")
    );
    assert!(stdout.contains(&said), "{said}: {stdout}");
    let flow = |name: &str| {
        read_npy(&work.path().join(name).join("flow.npy"))
            .unwrap()
            .data
    };
    let (linear, warped) = (flow("linear"), flow("warped"));
    let difference = linear
        .iter()
        .zip(&warped)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(difference > 1e-6, "warping changed nothing");
    let run = meshflow(&[
        "solve",
        &input,
        "--out",
        &out("bad"),
        "--levels",
        "3",
        "--warps",
        "0",
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(stderr.contains("warps"), "{stderr}");
    // --quiet: no progress at all.
    let quiet = meshflow_with_progress(&["solve", &input, "--out", &out("quiet"), "--quiet"]);
    assert!(
        quiet.status.success() && quiet.stderr.is_empty(),
        "{quiet:?}"
    );
    // Each warp is a whole solve: a count no one means is refused before any work.
    let run = meshflow(&["solve", &input, "--out", &out("many"), "--warps", "100000"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("warps") && stderr.contains("at most 20"),
        "{stderr}"
    );
}

/// `meshflow advect` follows every vertex of a run along its flow: on the shipped rotating
/// sphere (0.05 rad per frame about z) they end near where the rotation takes them, and the
/// reparametrized sequence it writes is one `solve` reads, with a far smaller image change.
#[test]
fn advect_command_follows_the_vertices_of_a_run() {
    let work = tempfile::tempdir().unwrap();
    let (run, out) = (work.path().join("run"), work.path().join("advected"));
    let input = shipped("rotating_sphere");
    meshflow_ok(&[
        "solve",
        &input,
        "--out",
        run.to_str().unwrap(),
        "--format",
        "npy",
    ]);
    let printed = meshflow_ok(&[
        "advect",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let trajectories = read_npy(&out.join("trajectories.npy")).unwrap();
    assert_eq!(trajectories.shape, vec![6, 642, 3]);
    let start = read_obj(&Path::new(&input).join("frame_0.obj"))
        .unwrap()
        .positions;
    let turn = nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), 5.0 * 0.05);
    let mut mean_distance = 0.0;
    for (i, x0) in start.iter().enumerate() {
        let first = nalgebra::Vector3::from_column_slice(&trajectories.data[3 * i..3 * i + 3]);
        assert!((first - x0).norm() < 1e-12);
        let row = 3 * (5 * 642 + i);
        let last = nalgebra::Vector3::from_column_slice(&trajectories.data[row..row + 3]);
        mean_distance += (last - turn * x0).norm() / start.len() as f64;
    }
    // 0.25 rad of rotation moves the vertices by 0.196 on average; the default weights' flow
    // is slower than the truth and leaves 0.057 (--large-motion: 0.037).
    assert!(mean_distance < 0.07, "{mean_distance}");
    let stdout = String::from_utf8_lossy(&printed.stdout);
    assert!(stdout.contains("frame   5: mean image change"), "{stdout}");
    meshflow_ok(&[
        "solve",
        out.to_str().unwrap(),
        "--out",
        work.path().join("again").to_str().unwrap(),
    ]);

    // Seeds off the surface start at their closest points; only the paths are written.
    let seeds_file = work.path().join("seeds.npy");
    let seeds: Vec<f64> = [start[10] * 1.02, start[300] * 0.99]
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    meshflow::io::write_npy(&seeds_file, &[2, 3], &seeds).unwrap();
    let seeded = work.path().join("seeded");
    meshflow_ok(&[
        "advect",
        run.to_str().unwrap(),
        "--seeds",
        seeds_file.to_str().unwrap(),
        "--out",
        seeded.to_str().unwrap(),
    ]);
    let paths = read_npy(&seeded.join("trajectories.npy")).unwrap();
    assert_eq!(paths.shape, vec![6, 2, 3]);
    let first = nalgebra::Vector3::from_column_slice(&paths.data[0..3]);
    assert!((first - start[10]).norm() < 1e-9, "{first:?}");
    assert!(!seeded.join("positions.npy").exists());
}

/// `--channels` on an isoluminant colour sequence (NPY with a channel axis): every channel
/// sees the rotation and the outputs carry them; luma sees nothing and says so; channel weights
/// reach the library and `summary.json`.
#[test]
fn channels_choose_what_the_data_term_sees() {
    use meshflow::synth::{isoluminant, rotating_sphere_in_channels};
    let scene = rotating_sphere_in_channels(isoluminant, 3, 3, 1.0, 0.05).unwrap();
    let sequence = &scene.sequence;
    let work = tempfile::tempdir().unwrap();
    let input = work.path().join("colour");
    std::fs::create_dir_all(&input).unwrap();
    let positions: Vec<_> = (0..3)
        .map(|k| sequence.positions(k).unwrap().to_vec())
        .collect();
    meshflow::io::write_npy_sequence(
        &input,
        &positions,
        sequence.mesh().faces(),
        None,
        sequence.times(),
    )
    .unwrap();
    let v = sequence.mesh().n_vertices();
    let rgb: Vec<f64> = (0..3)
        .flat_map(|k| (0..v).flat_map(move |i| (0..3).map(move |c| (k, i, c))))
        .map(|(k, i, c)| sequence.channels(k)[c][i])
        .collect();
    meshflow::io::write_npy(&input.join("intensity.npy"), &[3, v as u64, 3], &rgb).unwrap();
    let input = input.to_str().unwrap().to_string();
    let out = |name: &str| work.path().join(name).to_str().unwrap().to_string();

    meshflow_ok(&["solve", &input, "--out", &out("rgb"), "--format", "npy,vtu"]);
    assert_eq!(summary(&work.path().join("rgb"))["channels"], 3);
    let image = vtu_point_array(&work.path().join("rgb").join("flow_0000.vtu"), "image");
    assert_eq!(image.len(), 3 * v);
    assert_eq!(image[3 * 7 + 2], sequence.channels(0)[2][7]);
    let library = meshflow::flow::compute_flow(sequence, &Default::default()).unwrap();
    let errors = compare_result(sequence, &library, &scene.flow).unwrap();
    assert!(
        errors.mean_angular_degrees < 3.0,
        "{}",
        errors.mean_angular_degrees
    );

    let luma = meshflow(&["solve", &input, "--out", &out("luma"), "--channels", "luma"]);
    let stderr = String::from_utf8_lossy(&luma.stderr);
    assert!(
        !luma.status.success() && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(stderr.contains("do not vary"), "{stderr}");

    meshflow_ok(&[
        "solve",
        &input,
        "--out",
        &out("weighted"),
        "--format",
        "npy",
        "--channel-weights",
        "1,2,0.5",
    ]);
    let weights = &summary(&work.path().join("weighted"))["params"]["channel_weights"];
    assert_eq!(weights, &serde_json::json!([1.0, 2.0, 0.5]));
    let wrong = meshflow(&[
        "solve",
        &input,
        "--out",
        &out("wrong"),
        "--channel-weights",
        "1,1",
    ]);
    let stderr = String::from_utf8_lossy(&wrong.stderr);
    assert!(
        !wrong.status.success() && stderr.contains("expected 3 channel weights"),
        "{stderr}"
    );
}

/// Broken NPY arrays are reported against the file at fault: a NaN grey value names
/// `intensity.npy` (frame, vertex), a face index out of range names `faces.npy`.
#[test]
fn npy_errors_name_the_array_at_fault() {
    let dir = tempfile::tempdir().unwrap();
    let surface = meshflow::shapes::grid(3, 3, 1.0, 1.0);
    let positions = vec![surface.positions.clone(); 3];
    let mut grey: Vec<Vec<f64>> = (0..3).map(|k| vec![0.1 * k as f64 + 0.2; 16]).collect();
    grey[2][7] = f64::NAN;
    meshflow::io::write_npy_sequence(
        dir.path(),
        &positions,
        &surface.faces,
        Some(&grey),
        &[0.0, 1.0, 2.0],
    )
    .unwrap();
    let stderr = failing_solve(dir.path(), &[]);
    assert!(
        stderr.contains("intensity.npy: frame 2: intensity at vertex 7 is NaN"),
        "{stderr}"
    );

    let mut faces = surface.faces.clone();
    faces[5][1] = 9999;
    grey[2][7] = 0.5;
    meshflow::io::write_npy_sequence(
        dir.path(),
        &positions,
        &faces,
        Some(&grey),
        &[0.0, 1.0, 2.0],
    )
    .unwrap();
    let stderr = failing_solve(dir.path(), &[]);
    assert!(
        stderr.contains("faces.npy: face 5 refers to vertex 9999"),
        "{stderr}"
    );
}

/// Microscopes write integer images: a uint16 `intensity.npy` beside NPY arrays and a uint8
/// `--intensity` give the flow of the same values as float64.
#[test]
fn integer_images_are_read_like_their_float_values() {
    use npyz::WriterBuilder;
    let write_u = |path: &Path, shape: &[u64], values: &[u64], bits: u32| {
        let mut file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        if bits == 8 {
            let mut w = npyz::WriteOptions::<u8>::new()
                .default_dtype()
                .shape(shape)
                .writer(&mut file)
                .begin_nd()
                .unwrap();
            w.extend(values.iter().map(|&v| v as u8)).unwrap();
            w.finish().unwrap();
        } else {
            let mut w = npyz::WriteOptions::<u16>::new()
                .default_dtype()
                .shape(shape)
                .writer(&mut file)
                .begin_nd()
                .unwrap();
            w.extend(values.iter().map(|&v| v as u16)).unwrap();
            w.finish().unwrap();
        }
    };
    let dir = tempfile::tempdir().unwrap();
    let sphere = meshflow::shapes::icosphere(2);
    let n = sphere.positions.len();
    let values: Vec<u64> = (0..3)
        .flat_map(|k| {
            sphere
                .positions
                .iter()
                .map(move |p| (120.0 + 100.0 * (3.0 * p.x + 0.2 * k as f64).sin()) as u64)
        })
        .collect();
    let floats: Vec<Vec<f64>> = values
        .chunks(n)
        .map(|f| f.iter().map(|&v| v as f64).collect())
        .collect();
    let positions = vec![sphere.positions.clone(); 3];
    let (float_dir, int_dir) = (dir.path().join("float"), dir.path().join("u16"));
    for d in [&float_dir, &int_dir] {
        std::fs::create_dir(d).unwrap();
        meshflow::io::write_npy_sequence(
            d,
            &positions,
            &sphere.faces,
            Some(&floats),
            &[0.0, 1.0, 2.0],
        )
        .unwrap();
    }
    write_u(&int_dir.join("intensity.npy"), &[3, n as u64], &values, 16);
    let u8_file = dir.path().join("grey_u8.npy");
    write_u(&u8_file, &[3, n as u64], &values, 8);
    let flow_of = |input: &Path, extra: &[&str]| {
        let out = dir.path().join(format!(
            "run_{}",
            extra.len() + input.to_string_lossy().len()
        ));
        let mut args = vec![
            "solve",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--format",
            "npy",
        ];
        args.extend_from_slice(extra);
        meshflow_ok(&args);
        read_npy(&out.join("flow.npy")).unwrap().data
    };
    let float_flow = flow_of(&float_dir, &[]);
    assert_eq!(flow_of(&int_dir, &[]), float_flow);
    assert_eq!(
        flow_of(&float_dir, &["--intensity", u8_file.to_str().unwrap()]),
        float_flow
    );
}

/// An output directory that is the input or holds it is refused, even with `--force`, before
/// anything is written: the frames stay as they were and the next run still reads them.
#[test]
fn an_output_that_is_or_holds_the_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    let sphere = meshflow::shapes::icosphere(2);
    for k in 0..3 {
        let grey: Vec<[f64; 3]> = (sphere.positions.iter())
            .map(|p| [(3.0 * p.x + 0.1 * k as f64).sin() * 0.4 + 0.5; 3])
            .collect();
        let path = frames.join(format!("f{k}.obj"));
        meshflow::io::write_obj(&path, &sphere.positions, &sphere.faces, Some(&grey)).unwrap();
    }
    let before = listing(&frames);
    let input = frames.to_str().unwrap();
    let glob = format!("{input}/f*.obj");
    let parent = dir.path().to_str().unwrap();
    for (source, out, relation) in [
        (input, input, "is the input"),
        (glob.as_str(), input, "is the input"),
        (input, parent, "holds the input"),
    ] {
        let run = meshflow(&["solve", source, "--out", out, "--force"]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains(relation) && stderr.contains("choose another output directory"),
            "{stderr}"
        );
        assert_eq!(listing(&frames), before);
    }
    let run = meshflow(&["track", input, "--out", input, "--force"]);
    assert_eq!(run.status.code(), Some(1));
    assert_eq!(listing(&frames), before);
    meshflow_ok(&[
        "solve",
        input,
        "--out",
        dir.path().join("run").to_str().unwrap(),
    ]);
}

/// A run solved with a relative input path is advected from any directory: the manifest
/// records where the solve ran, and `advect` reads the input from there.
#[test]
fn advect_finds_a_relative_input_from_another_directory() {
    let work = tempfile::tempdir().unwrap();
    let copy = work.path().join("data");
    std::fs::create_dir(&copy).unwrap();
    let shipped_dir = std::path::PathBuf::from(shipped("rotating_sphere"));
    for entry in std::fs::read_dir(&shipped_dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "obj" || e == "txt") {
            std::fs::copy(&path, copy.join(path.file_name().unwrap())).unwrap();
        }
    }
    let run_in = |dir: &Path, args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_meshflow"))
            .current_dir(dir)
            .args(args)
            .output()
            .unwrap()
    };
    let solve = run_in(
        work.path(),
        &["solve", "data", "--out", "run", "--format", "npy"],
    );
    assert!(
        solve.status.success(),
        "{}",
        String::from_utf8_lossy(&solve.stderr)
    );
    let elsewhere = tempfile::tempdir().unwrap();
    let run = work.path().join("run");
    let out = elsewhere.path().join("advected");
    let advect = run_in(
        elsewhere.path(),
        &[
            "advect",
            run.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert!(
        advect.status.success(),
        "{}",
        String::from_utf8_lossy(&advect.stderr)
    );
    assert!(out.join("trajectories.npy").exists());
}

/// A run that was killed leaves its staging directory behind; the next run into the same
/// output removes it when its process is gone, and leaves a live process's staging alone.
#[test]
fn staging_left_by_a_killed_run_is_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let dead = dir.path().join(".run.partial-4000000000");
    let alive = dir
        .path()
        .join(format!(".run.partial-{}", std::process::id()));
    for stale in [&dead, &alive] {
        std::fs::create_dir(stale).unwrap();
        std::fs::write(stale.join("flow.npy"), "half-written").unwrap();
    }
    let out = dir.path().join("run");
    let input = shipped("rotating_sphere");
    meshflow_ok(&[
        "solve",
        &input,
        "--out",
        out.to_str().unwrap(),
        "--format",
        "npy",
    ]);
    assert!(!dead.exists(), "the dead run's staging is removed");
    assert!(alive.exists(), "a live process's staging stays");
    assert_eq!(listing(dir.path()).len(), 2, "{:?}", listing(dir.path()));
}

/// Interrupted (SIGINT, Ctrl-C) or terminated (SIGTERM, e.g. by a batch system) in the middle
/// of a run, meshflow removes its staging directory and exits with 130: nothing is left.
#[cfg(unix)]
#[test]
fn an_interrupted_run_leaves_nothing_behind() {
    for signal in [libc::SIGINT, libc::SIGTERM] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        // Twenty warps of eight levels: seconds of work, so the signal comes in the middle.
        let child = std::process::Command::new(env!("CARGO_BIN_EXE_meshflow"))
            .args(["solve", &shipped("rotating_sphere"), "--out"])
            .arg(&out)
            .args(["--levels", "8", "--warps", "20", "--quiet"])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let staging = dir.path().join(format!(".run.partial-{}", child.id()));
        let start = std::time::Instant::now();
        while !staging.exists() && start.elapsed().as_secs() < 30 {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert!(staging.exists(), "the run stages its output");
        // SAFETY: sends a signal to the child process started above.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
        let run = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(130), "signal {signal}: {stderr}");
        assert_eq!(stderr.trim(), "meshflow: interrupted: nothing was written");
        assert!(listing(dir.path()).is_empty(), "{:?}", listing(dir.path()));
    }
}

/// An output directory that is a mount point (a Docker volume) cannot be renamed or removed:
/// the run stages inside it and moves its files in, for a new output, a rerun and new pictures
/// alike. Needs a private mount namespace (`unshare -m`, as root); skipped where there is none.
#[cfg(target_os = "linux")]
#[test]
fn output_into_a_mount_point_is_written_in_place() {
    let namespace = std::process::Command::new("unshare")
        .args(["-m", "true"])
        .output();
    if !namespace.is_ok_and(|o| o.status.success()) {
        println!("skipped: no private mount namespace here (unshare -m)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let volume = dir.path().join("volume");
    std::fs::create_dir(&volume).unwrap();
    let (bin, input) = (env!("CARGO_BIN_EXE_meshflow"), shipped("rotating_sphere"));
    let v = volume.display();
    let script = format!(
        "set -e; mount -t tmpfs tmpfs {v}; \
         {bin} solve {input} --out {v} --format npy,vtu --quiet; \
         {bin} solve {input} --out {v} --format npy,vtu --gamma 0.01 --quiet; \
         {bin} render {v} --slabs 0 --quiet; \
         ls -A {v}; grep -c '\"solve\",' {v}/meshflow_run.json"
    );
    let run = std::process::Command::new("unshare")
        .args(["-m", "sh", "-c", &script])
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr),
    );
    assert!(run.status.success(), "{stdout}\n{stderr}");
    let entries: Vec<&str> = stdout.lines().collect();
    for expected in [
        "flow.npy",
        "flow_0004.vtu",
        "summary.json",
        "meshflow_run.json",
    ] {
        assert!(entries.contains(&expected), "{expected}: {entries:?}");
    }
    assert!(
        entries.contains(&"flow_0000.png"),
        "render's pictures: {entries:?}"
    );
    assert!(!stdout.contains(".meshflow.partial"), "{entries:?}");
    // The rerun replaced the first run (one solve command recorded, then the render).
    assert_eq!(entries.last(), Some(&"1"), "{stdout}");
}

/// A frame file cut short (a copy interrupted, a disk full) is reported as truncated, whether
/// it stops inside a vertex line, inside a face line or between face lines.
#[test]
fn a_truncated_obj_frame_is_reported_as_truncated() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = meshflow::shapes::icosphere(2);
    let grey: Vec<[f64; 3]> = sphere
        .positions
        .iter()
        .map(|p| [0.5 + 0.4 * p.x; 3])
        .collect();
    for k in 0..3 {
        let path = dir.path().join(format!("f{k}.obj"));
        meshflow::io::write_obj(&path, &sphere.positions, &sphere.faces, Some(&grey)).unwrap();
    }
    let whole = std::fs::read_to_string(dir.path().join("f2.obj")).unwrap();
    let last_vertex = whole.rfind("\nv ").unwrap() + 1;
    let first_face = whole.find("\nf ").unwrap() + 1;
    let tenth_face = first_face + whole[first_face..].match_indices("\nf ").nth(9).unwrap().0 + 1;
    let cuts = [
        // Inside the last vertex line, after its position: the colour is missing.
        whole[..last_vertex + whole[last_vertex..].find(' ').unwrap() + 1].len() + 20,
        // Inside a face line.
        tenth_face + 4,
        // Between face lines.
        tenth_face,
    ];
    for cut in cuts {
        let cut = whole.floor_char_boundary(cut);
        std::fs::write(dir.path().join("f2.obj"), &whole[..cut]).unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let out = elsewhere.path().join("out");
        let run = meshflow(&[
            "solve",
            dir.path().to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("f2.obj") && stderr.contains("truncated"),
            "cut at {cut}: {stderr}"
        );
        assert!(!stderr.contains("meshflow track"), "{stderr}");
    }
}
