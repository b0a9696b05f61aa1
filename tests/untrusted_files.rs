//! Files named inside other files are read only where the naming file lies (glTF buffer and
//! image URIs, OBJ `mtllib`, MTL `map_Kd`), and declared sizes meet `--memory-limit`: what an
//! attacker's file names outside its directory is refused in one line, before it is read.

mod common;

use common::{listing, meshflow, meshflow_error};
use std::path::Path;

/// Four vertices (f32) and two triangles (u16) of a unit square: the 60 bytes of the buffer.
fn square_buffer() -> Vec<u8> {
    let positions: [f32; 12] = [0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bytes: Vec<u8> = positions.iter().flat_map(|v| v.to_le_bytes()).collect();
    bytes.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    bytes
}

/// A `.gltf` of the square whose buffer is the file at `uri`.
fn square_gltf(uri: &str) -> String {
    serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": uri, "byteLength": 60}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0
    })
    .to_string()
}

/// `meshflow operators FILE --out OUT` with `extra` options: its exit code and stderr.
fn operators(file: &Path, out: &Path, extra: &[&str]) -> (Option<i32>, String) {
    let mut args = vec![
        "operators",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let done = meshflow(&args);
    (
        done.status.code(),
        String::from_utf8_lossy(&done.stderr).into_owned(),
    )
}

#[test]
fn gltf_buffers_outside_the_file_directory_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    std::fs::create_dir(&model).unwrap();
    std::fs::create_dir(model.join("folder")).unwrap();
    // A buffer outside the model's directory, as a link would lead to.
    let outside = dir.path().join("outside.bin");
    std::fs::write(&outside, square_buffer()).unwrap();
    std::fs::write(model.join("square.bin"), square_buffer()).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&outside, model.join("link.bin")).unwrap();
    let out = dir.path().join("out");
    let cases = [
        ("/etc/passwd", "an absolute path"),
        ("/proc/self/environ", "an absolute path"),
        ("/dev/zero", "an absolute path"),
        (
            "../../../../etc/passwd",
            "leads out of the file's directory",
        ),
        (
            "%2e%2e/%2e%2e/%2e%2e/etc/passwd",
            "leads out of the file's directory",
        ),
        (
            "folder/%2E%2E/%2e%2e/outside.bin",
            "leads out of the file's directory",
        ),
        ("folder", "is not a regular file"),
        #[cfg(unix)]
        ("link.bin", "a link that leads out of the file's directory"),
    ];
    let gltf = model.join("square.gltf");
    for (uri, why) in cases {
        std::fs::write(&gltf, square_gltf(uri)).unwrap();
        let (code, stderr) = operators(&gltf, &out, &[]);
        assert_eq!(code, Some(1), "{uri}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{uri}: {stderr}");
        let named = format!("square.gltf: buffer 0 uri {uri:?}: ");
        assert!(
            stderr.contains(&named) && stderr.contains(why),
            "{uri}: {stderr}"
        );
        assert!(
            !stderr.contains("root:"),
            "nothing of the file leaks: {stderr}"
        );
        assert!(!out.exists(), "{uri}: no output");
    }
    // A buffer beside the file is read.
    std::fs::write(&gltf, square_gltf("square.bin")).unwrap();
    let (code, stderr) = operators(&gltf, &out, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        listing(&model),
        ["folder", "link.bin", "square.bin", "square.gltf"]
    );
}

#[test]
fn external_files_are_read_only_when_allowed_and_never_devices() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    std::fs::create_dir(&model).unwrap();
    let outside = dir.path().join("outside.bin");
    std::fs::write(&outside, square_buffer()).unwrap();
    let gltf = model.join("square.gltf");
    let out = dir.path().join("out");
    std::fs::write(&gltf, square_gltf(outside.to_str().unwrap())).unwrap();
    let (code, stderr) = operators(&gltf, &out, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("--allow-external-files"), "{stderr}");
    let (code, stderr) = operators(&gltf, &out, &["--allow-external-files"]);
    assert_eq!(code, Some(0), "{stderr}");
    let relative = "../outside.bin";
    std::fs::write(&gltf, square_gltf(relative)).unwrap();
    let (code, stderr) = operators(&gltf, &out, &["--allow-external-files"]);
    assert_eq!(code, Some(0), "{relative}: {stderr}");
    std::fs::write(&gltf, square_gltf("/dev/zero")).unwrap();
    let (code, stderr) = operators(&gltf, &out, &["--allow-external-files"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("\"/dev/zero\": /dev/zero is not a regular file"),
        "{stderr}"
    );
}

#[test]
fn obj_material_libraries_and_textures_stay_beside_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    std::fs::create_dir(&model).unwrap();
    let obj = |mtllib: &str| {
        format!(
            "mtllib {mtllib}\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
             usemtl skin\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
        )
    };
    let out = dir.path().join("out");
    let file = model.join("square.obj");
    let solve = [
        "solve",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    for (mtllib, why) in [
        ("/etc/passwd", "an absolute path"),
        ("../../../etc/passwd", "leads out of the file's directory"),
    ] {
        std::fs::write(&file, obj(mtllib)).unwrap();
        meshflow_error(&solve, &format!("square.obj: mtllib {mtllib:?}: {why}"));
    }
    std::fs::write(dir.path().join("secret.png"), b"not read").unwrap();
    let library = "newmtl skin\nmap_Kd ../secret.png\n";
    std::fs::write(model.join("skin.mtl"), library).unwrap();
    std::fs::write(&file, obj("skin.mtl")).unwrap();
    let refused = "skin.mtl: material 'skin': map_Kd \"../secret.png\": leads out";
    meshflow_error(&solve, refused);
    assert!(!out.exists());
}

#[test]
fn the_memory_limit_is_checked_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("square.bin"), square_buffer()).unwrap();
    let gltf = dir.path().join("square.gltf");
    std::fs::write(&gltf, square_gltf("square.bin")).unwrap();
    let out = dir.path().join("out");
    let size = std::fs::metadata(&gltf).unwrap().len();
    let (code, stderr) = operators(&gltf, &out, &["--memory-limit", "100"]);
    assert_eq!(code, Some(1), "{stderr}");
    let expected = format!(
        "square.gltf: the file declares {size} bytes, over the memory limit of 100 bytes \
         (--memory-limit)"
    );
    assert!(stderr.contains(&expected), "{stderr}");
    let (code, stderr) = operators(&gltf, &out, &["--memory-limit", "lots"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("'lots' is not a size"), "{stderr}");
    let (code, stderr) = operators(&gltf, &out, &["--memory-limit", "1.5G"]);
    assert_eq!(code, Some(0), "{stderr}");
}

/// The solve checks the space-time system against the memory limit before assembling it: a
/// sequence of small files can make a large system.
#[test]
fn the_solve_refuses_a_system_over_the_memory_limit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let input = common::shipped("rotating_sphere");
    let solve = ["solve", &input, "--out", out.to_str().unwrap()];
    // 5 slabs × 642 vertices × 2 unknowns × 140 bytes.
    meshflow_error(
        &[&solve[..], &["--memory-limit", "200K"]].concat(),
        "the space-time system of 5 slabs × 642 vertices (6420 unknowns, 140 bytes each at \
         least) declares 898.8 kB, over the memory limit of 204.8 kB (--memory-limit)",
    );
    assert!(!out.exists());
}

/// A FIFO where a file should be would block the reader forever (nobody writes to it): it is
/// refused as not a regular file, for the arrays and the meshes alike.
#[cfg(unix)]
#[test]
fn fifos_are_refused_not_waited_for() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for name in ["positions.npy", "frame_0.obj"] {
        let input = dir.path().join(name.replace('.', "_"));
        std::fs::create_dir(&input).unwrap();
        let fifo = input.join(name);
        let c_path = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o644) }, 0);
        if name.ends_with(".obj") {
            std::fs::copy(
                format!("{}/frame_1.obj", common::shipped("rotating_sphere")),
                input.join("frame_1.obj"),
            )
            .unwrap();
        }
        let solve = [
            "solve",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        meshflow_error(&solve, &format!("{name}: not a regular file"));
    }
}

/// A chain of 100,000 nested nodes (each the only child of the next) is read without
/// recursion: no stack overflow, and the mesh is found at its bottom.
#[test]
fn deep_node_chains_are_read_without_recursion() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("square.bin"), square_buffer()).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&square_gltf("square.bin")).unwrap();
    let depth = 100_000;
    let mut nodes = vec![serde_json::json!({"mesh": 0})];
    nodes.extend((0..depth).map(|k| serde_json::json!({"children": [k]})));
    json["nodes"] = serde_json::Value::Array(nodes);
    json["scenes"] = serde_json::json!([{"nodes": [depth]}]);
    let gltf = dir.path().join("chain.gltf");
    std::fs::write(&gltf, json.to_string()).unwrap();
    let (code, stderr) = operators(&gltf, &dir.path().join("out"), &[]);
    assert_eq!(code, Some(0), "{stderr}");
}
