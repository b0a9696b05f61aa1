//! `meshflow analyze`: the library's analysis of a finished run, written as NPY, ParaView and
//! JSON; broken runs fail in one line with nothing written.

mod common;

use common::{listing, meshflow, meshflow_error, meshflow_ok, shipped};
use meshflow::analysis::analyze_flow;
use meshflow::io::{load_sequence, read_npy, LoadOptions};
use nalgebra::Vector2;
use std::path::Path;

fn solve(input: &str, out: &Path) {
    let out = out.to_str().unwrap();
    meshflow_ok(&[
        "solve", input, "--out", out, "--format", "npy,vtu", "--quiet",
    ]);
}

/// The shipped sphere turns rigidly: its flow is almost all co-exact (a rotation is `J∇z`),
/// divergence-free on average, and the files hold the library's numbers.
#[test]
fn analyze_writes_the_analysis_of_a_run() {
    let dir = tempfile::tempdir().unwrap();
    let (run, out) = (dir.path().join("run"), dir.path().join("analysis"));
    solve(&shipped("rotating_sphere"), &run);
    let done = meshflow_ok(&[
        "analyze",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--png",
        "--slabs",
        "0,last",
        "--size",
        "320x240",
    ]);
    let stdout = String::from_utf8_lossy(&done.stdout);
    assert!(stdout.contains("5 slabs x 1280 faces analysed"), "{stdout}");
    assert!(stdout.contains("pictures: 7 PNG files"), "{stdout}");
    let written = listing(&out);
    for name in [
        "curl_0000.png",
        "areal_rate_0004.png",
        "divergence_0004.png",
        "time_series.png",
    ] {
        assert!(written.contains(&name.to_string()), "{name}: {written:?}");
    }
    // The texture turns counter-clockwise about z: positive curl (red) at the north pole,
    // seen from the default view's upper half.
    let curl = image::open(out.join("curl_0000.png")).unwrap().to_rgb8();
    let [r, _, b] = curl.get_pixel(160, 40).0;
    assert!(r > b + 40, "north of the sphere is red: {r} {b}");
    for name in [
        "summary.json",
        "analysis.pvd",
        "analysis_0004.vtu",
        "divergence.npy",
        "hodge_coexact.npy",
        "areal_rate.npy",
        "principal_rates.npy",
        "faces.npy",
    ] {
        assert!(written.contains(&name.to_string()), "{name}: {written:?}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for slab in summary["slabs"].as_array().unwrap() {
        let share = slab["coexact_energy"].as_f64().unwrap() / slab["energy"].as_f64().unwrap();
        assert!(share > 0.95, "{slab}");
        let divergence = slab["mean_divergence"].as_f64().unwrap().abs();
        assert!(
            divergence < 1e-6 * slab["mean_speed"].as_f64().unwrap(),
            "{slab}"
        );
    }
    // The same numbers as the library's, from the run's own flow.
    let loaded = load_sequence(
        Path::new(&shipped("rotating_sphere")),
        &LoadOptions::default(),
    )
    .unwrap();
    let flow = read_npy(&run.join("flow_intrinsic.npy")).unwrap();
    let (s, v) = (flow.shape[0] as usize, flow.shape[1] as usize);
    let vectors: Vec<Vec<Vector2<f64>>> = (0..s)
        .map(|k| {
            (0..v)
                .map(|i| {
                    let at = 2 * (k * v + i);
                    Vector2::new(flow.data[at], flow.data[at + 1])
                })
                .collect()
        })
        .collect();
    let expected = analyze_flow(&loaded.sequence, &vectors).unwrap();
    let divergence = read_npy(&out.join("divergence.npy")).unwrap();
    assert_eq!(divergence.shape, vec![5, 642]);
    let rows: Vec<f64> = expected
        .iter()
        .flat_map(|a| a.vertex_divergence.clone())
        .collect();
    assert_eq!(divergence.data, rows);
    let coexact = read_npy(&out.join("hodge_coexact.npy")).unwrap();
    assert_eq!(coexact.shape, vec![5, 1280, 3]);
    // --format npy leaves out ParaView; glTF is not an analysis format.
    let npy_only = dir.path().join("npy_only");
    let npy = npy_only.to_str().unwrap();
    meshflow_ok(&[
        "analyze",
        run.to_str().unwrap(),
        "--out",
        npy,
        "--format",
        "npy",
    ]);
    let written = listing(&npy_only);
    assert!(written.contains(&"curl.npy".to_string()), "{written:?}");
    assert!(
        !written
            .iter()
            .any(|f| f.ends_with(".vtu") || f.ends_with(".pvd")),
        "{written:?}"
    );
    let refused = meshflow(&[
        "analyze",
        run.to_str().unwrap(),
        "--out",
        npy,
        "--format",
        "glb",
    ]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("takes npy and vtu"));
}

/// The shipped sample's files copied into the new directory `into`.
fn copy_of_the_sample(into: &Path) -> std::path::PathBuf {
    std::fs::create_dir(into).unwrap();
    for entry in std::fs::read_dir(shipped("rotating_sphere")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, into.join(path.file_name().unwrap())).unwrap();
    }
    into.to_path_buf()
}

/// A run without a manifest (an older version's, or not a run), and a run whose input lost a
/// frame: one line naming what is wrong, and no output.
#[test]
fn broken_runs_fail_in_one_line_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_of_the_sample(&dir.path().join("frames"));
    let run = dir.path().join("run");
    solve(input.to_str().unwrap(), &run);
    let out = dir.path().join("analysis");
    let failing = |run: &Path, expected: &str| {
        let done = meshflow(&[
            "analyze",
            run.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&done.stderr);
        assert_eq!(done.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(expected), "{expected}: {stderr}");
        assert!(!out.exists(), "no output");
        assert_eq!(
            listing(dir.path()),
            ["frames", "run"].map(String::from).to_vec()
        );
    };
    let manifest = run.join("meshflow_run.json");
    let saved = std::fs::read(&manifest).unwrap();
    std::fs::remove_file(&manifest).unwrap();
    failing(&run, "not a meshflow output (no meshflow_run.json)");
    std::fs::write(&manifest, "{\"format\": \"meshflow run\", ").unwrap();
    failing(&run, "meshflow_run.json: corrupt run manifest");
    std::fs::write(&manifest, &saved).unwrap();
    let frame = input.join("frame_3.obj");
    let frame_bytes = std::fs::read(&frame).unwrap();
    std::fs::remove_file(&frame).unwrap();
    failing(&run, "frame_3.obj is gone since the run; solve again");
    let mut edited = frame_bytes.clone();
    edited.extend_from_slice(b"# edited\n");
    std::fs::write(&frame, &edited).unwrap();
    failing(&run, "frame_3.obj changed since the run");
    std::fs::write(&frame, &frame_bytes).unwrap();
    let flow = run.join("flow_intrinsic.npy");
    let flow_bytes = std::fs::read(&flow).unwrap();
    let mut poisoned = flow_bytes.clone();
    let last = poisoned.len() - 8;
    poisoned[last..].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(&flow, &poisoned).unwrap();
    failing(&run, "holds NaN: not a flow");
    std::fs::remove_file(&flow).unwrap();
    failing(&run, "flow_intrinsic.npy");
}

/// An edited manifest cannot make `analyze` or `advect` read a file the solve did not read:
/// the run's recorded inputs (sizes and BLAKE3 hashes) must hold.
#[test]
fn an_edited_manifest_reads_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    solve(&shipped("rotating_sphere"), &run);
    let elsewhere = copy_of_the_sample(&dir.path().join("elsewhere"));
    let manifest = run.join("meshflow_run.json");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let absolute = serde_json::Value::from(elsewhere.to_str().unwrap());
    // The solve's record (relative to the run), an absolute path in it, and the command line
    // that an earlier version's manifest holds instead (relative to a working directory that
    // the manifest names).
    let recorded = json["solve"].clone();
    json["solve"]["input"] = absolute.clone();
    let mut relative = json.clone();
    relative["solve"]["input"] = serde_json::Value::from("../elsewhere");
    let mut earlier = json.clone();
    earlier.as_object_mut().unwrap().remove("solve");
    earlier["commands"][0][2] = absolute;
    let edited = "which the run did not read (was meshflow_run.json edited?)";
    let cases = [
        (
            &json,
            &[][..],
            "is an absolute path: a run names its inputs relative to itself",
        ),
        (&json, &["--allow-external-files"][..], edited),
        (&relative, &[][..], edited),
        (
            &earlier,
            &[][..],
            "relative to a working directory that it names itself",
        ),
        (&earlier, &["--allow-external-files"][..], edited),
    ];
    for (edited_json, flags, expected) in cases {
        std::fs::write(&manifest, edited_json.to_string()).unwrap();
        for command in ["analyze", "advect"] {
            let out = dir.path().join(command);
            let (run, out_text) = (run.to_str().unwrap(), out.to_str().unwrap());
            let mut args = vec![command, run, "--out", out_text];
            args.extend(flags);
            meshflow_error(&args, expected);
            assert!(!out.exists());
        }
    }
    json["solve"] = recorded;
    json["inputs"] = serde_json::Value::Array(Vec::new());
    std::fs::write(&manifest, json.to_string()).unwrap();
    let out = dir.path().join("analysis");
    let args = [
        "analyze",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    meshflow_error(&args, "records no fingerprints of its inputs");
}

/// `--out` naming the run itself is refused before anything is written: the run would be
/// replaced by its own analysis (or trajectories).
#[test]
fn the_run_is_never_its_own_output() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    solve(&shipped("rotating_sphere"), &run);
    let before = listing(&run);
    for command in ["analyze", "advect"] {
        let inside = run.join("sub");
        for (out, relation) in [
            (&run, "is the input"),
            (&inside, "lies inside the input directory"),
        ] {
            let args = [
                command,
                run.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ];
            meshflow_error(&args, relation);
            assert_eq!(listing(&run), before, "{command} left the run alone");
        }
    }
}

/// A file added beside the input since the solve is not the run's: `analyze` still reads the
/// run (a frame removed or changed is named, see `broken_runs_fail_in_one_line_without_output`).
/// A frame whose fingerprint the manifest lost is refused: the load would read it unchecked.
#[test]
fn a_new_file_beside_the_input_is_not_a_change_a_frame_without_its_record_is() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_of_the_sample(&dir.path().join("frames"));
    let run = dir.path().join("run");
    solve(input.to_str().unwrap(), &run);
    std::fs::write(input.join("notes.txt"), "taken on a Tuesday").unwrap();
    let out = dir.path().join("analysis");
    let args = [
        "analyze",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    meshflow_ok(&args);
    assert!(out.join("summary.json").exists());
    // A frame changed, and its fingerprint deleted from the manifest: refused all the same.
    let frame = input.join("frame_2.obj");
    let mut text = std::fs::read_to_string(&frame).unwrap();
    text.push_str("# edited\n");
    std::fs::write(&frame, text).unwrap();
    let manifest = run.join("meshflow_run.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    let inputs = json["inputs"].as_array_mut().unwrap();
    inputs.retain(|entry| !entry["path"].as_str().unwrap().ends_with("frame_2.obj"));
    std::fs::write(&manifest, json.to_string()).unwrap();
    meshflow_error(
        &args,
        "frame_2.obj, of which the run recorded no fingerprint",
    );
}

/// The library reads a solve's output back without the command line: the manifest's record
/// names the input and how it was loaded, and the flow read back is `flow_intrinsic.npy`'s
/// rows at the mesh vertices. A manifest without a record is refused in one line.
#[test]
fn the_library_reads_a_run_back_from_its_record() {
    use meshflow::run::{read_flow, SolveInput};
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let input = shipped("rotating_sphere");
    let out = run.to_str().unwrap();
    meshflow_ok(&[
        "solve",
        &input,
        "--out",
        out,
        "--format",
        "npy",
        "--channels",
        "luma",
        "--quiet",
    ]);
    let solved = SolveInput::of_run(&run).unwrap();
    // Recorded relative to the run, read back as the same directory.
    assert!(solved.input.is_relative() || solved.input.starts_with(&run));
    assert_eq!(
        solved.input.canonicalize().unwrap(),
        Path::new(&input).canonicalize().unwrap()
    );
    let options = LoadOptions {
        channels: meshflow::io::Channels::Luma,
        ..LoadOptions::default()
    };
    assert_eq!(solved.load, options);
    let loaded = solved.load().unwrap();
    let flow = read_flow(&run, &loaded).unwrap();
    let array = read_npy(&run.join("flow_intrinsic.npy")).unwrap();
    let (s, v) = (
        loaded.sequence.n_slabs(),
        loaded.vertex_map.n_file_vertices(),
    );
    assert_eq!(array.shape, [s as u64, v as u64, 2]);
    for (slab, field) in flow.iter().enumerate() {
        for (m, vector) in field.iter().enumerate() {
            let row = 2 * (slab * v + loaded.vertex_map.representative(m));
            let stored = Vector2::new(array.data[row], array.data[row + 1]);
            assert_eq!(*vector, stored, "slab {slab}, mesh vertex {m}");
        }
    }

    let manifest = run.join("meshflow_run.json");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json.as_object_mut().unwrap().remove("solve");
    std::fs::write(&manifest, json.to_string()).unwrap();
    let error = SolveInput::of_run(&run).unwrap_err().to_string();
    assert!(error.contains("its manifest records no solve"), "{error}");
}
