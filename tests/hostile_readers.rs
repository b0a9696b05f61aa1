//! Hostile input files: headers that declare more than the file holds or the memory limit
//! allows, zero-length dimensions, absurd counts. Every one must end in a typed error that
//! names the file (and the place in it), before anything is allocated for the declared size.
//!
//! Every test sets the same low memory limit (64 MiB): the limit is process-wide and the tests
//! of this binary run in parallel.

use battery::hostile_support::npy;
use meshflow::io::IoError;
use std::path::{Path, PathBuf};

const LIMIT: u64 = 64 << 20;

fn low_limit() -> tempfile::TempDir {
    meshflow::limits::set_memory_limit(LIMIT);
    tempfile::tempdir().unwrap()
}

/// Writes `bytes` to `name` in `dir`.
fn file(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The error's text, after checking that it names `path` and is one line.
fn message<T: std::fmt::Debug>(result: Result<T, IoError>, path: &Path) -> String {
    let error = result.expect_err("hostile input must fail");
    let text = error.to_string();
    assert_eq!(error.path(), path, "{text}");
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(!text.contains('\n'), "one line: {text}");
    text
}

#[test]
fn npy_zero_dimension_with_terabyte_rows_is_refused() {
    let dir = low_limit();
    let path = file(
        &dir,
        "huge.npy",
        &npy("<f8", "(1000000000000, 0, 4, 4)", &[]),
    );
    let text = message(meshflow::io::read_npy_float(&path), &path);
    assert!(
        text.contains("dimension 1 of shape [1000000000000, 0, 4, 4] is 0"),
        "{text}"
    );
    let text = message(meshflow::io::read_npy_image(&path), &path);
    assert!(text.contains("dimension 1"), "{text}");
}

/// Found by `fuzz_readers`: a version-2 header's length is a `u32`, and npyz allocated it before
/// reading (one flipped byte asked for 660 MB).
#[test]
fn npy_header_lengths_beyond_the_file_are_refused() {
    let dir = low_limit();
    let mut bytes = npy("<f8", "(2,)", &[0; 16]);
    bytes[6] = 2;
    let header = u16::from_le_bytes([bytes[8], bytes[9]]);
    let declared = u32::from(header) | 0x2700_0000;
    bytes.splice(8..10, declared.to_le_bytes());
    let path = file(&dir, "long_header.npy", &bytes);
    let text = message(meshflow::io::read_npy_float(&path), &path);
    let expected = format!("not a valid .npy file (its header declares {declared} bytes");
    assert!(text.contains(&expected), "{text}");
}

#[test]
fn npy_widening_over_the_limit_is_refused_before_allocating() {
    let dir = low_limit();
    // 10 MB of uint8 read as f64 is 80 MB, over 64 MiB.
    let count = 10_000_000;
    let path = file(
        &dir,
        "wide.npy",
        &npy("|u1", &format!("({count},)"), &vec![7; count]),
    );
    let text = message(meshflow::io::read_npy_image(&path), &path);
    assert!(
        text.contains("shape [10000000] (read as 8-byte values) declares 80.0 MB")
            && text.contains("--memory-limit"),
        "{text}"
    );
    // As f32 it is 40 MB, under the limit.
    let (shape, values) = meshflow::io::read_npy_f32(&path).unwrap();
    assert_eq!(
        (shape, values.len(), values[0]),
        (vec![count as u64], count, 7.0)
    );
}

#[test]
fn npy_indices_over_the_limit_are_refused_before_allocating() {
    let dir = low_limit();
    // 20 MB of int8 indices are 80 MB of u32.
    let count = 20_000_000;
    let path = file(
        &dir,
        "faces.npy",
        &npy("|i1", &format!("({count},)"), &vec![1; count]),
    );
    let text = message(meshflow::io::read_npy_indices(&path), &path);
    assert!(text.contains("declares 80.0 MB"), "{text}");
    let path = file(&dir, "empty.npy", &npy("<i8", "(0, 3)", &[]));
    let text = message(meshflow::io::read_npy_indices(&path), &path);
    assert!(text.contains("dimension 0 of shape [0, 3] is 0"), "{text}");
    let path = file(
        &dir,
        "negative.npy",
        &npy("<i2", "(3,)", &[1, 0, 255, 255, 2, 0]),
    );
    let text = message(meshflow::io::read_npy_indices(&path), &path);
    assert!(text.contains("entry 1 is -1, not a vertex index"), "{text}");
}

const MTX_BANNER: &str = "%%MatrixMarket matrix coordinate real general\n";

#[test]
fn mtx_declared_entries_over_the_limit_are_refused() {
    let dir = low_limit();
    let text = format!("{MTX_BANNER}% comment\n3 3 1000000000000\n1 1 2.0\n");
    let path = file(&dir, "huge.mtx", text.as_bytes());
    let text = message(meshflow::io::read_matrix_market(&path), &path);
    assert!(
        text.contains("line 3: 1000000000000 entries declares 24.0 TB"),
        "{text}"
    );
    let text = format!("{MTX_BANNER}1000000000000 1000000000000 1\n1 1 2.0\n");
    let path = file(&dir, "wide.mtx", text.as_bytes());
    let text = message(meshflow::io::read_matrix_market(&path), &path);
    assert!(text.contains("--memory-limit"), "{text}");
}

#[test]
fn mtx_without_size_line_ends_with_an_error() {
    // sprs looped forever on this.
    let dir = low_limit();
    let path = file(&dir, "banner.mtx", MTX_BANNER.as_bytes());
    let text = message(meshflow::io::read_matrix_market(&path), &path);
    assert!(text.contains("no size line"), "{text}");
}

#[test]
fn mtx_bad_entries_name_their_line() {
    let dir = low_limit();
    for (body, expected) in [
        (
            "2 2 2\n1 1 1.0\n3 1 1.0\n",
            "line 4: entry (3, 1) lies outside the 2 × 2 matrix",
        ),
        ("2 2 1\n1 1 nan\n", "line 3: '1 1 nan' has no finite value"),
        (
            "2 2 2\n1 1 1.0\n",
            "truncated file: 1 entries of the 2 declared",
        ),
        (
            "2 2 1\n1 1 1.0\n2 2 1.0\n",
            "line 4: more entries than the 1",
        ),
        ("2 -2 1\n", "line 2: '2 -2 1' does not start with 3"),
    ] {
        let path = file(&dir, "bad.mtx", format!("{MTX_BANNER}{body}").as_bytes());
        let text = message(meshflow::io::read_matrix_market(&path), &path);
        assert!(text.contains(expected), "{text}");
    }
}

/// A binary little-endian PLY header declaring `vertices` vertices of uchar coordinates and
/// one face with a uint-counted list.
fn ply_header(vertices: usize) -> Vec<u8> {
    format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty uchar x\n\
         property uchar y\nproperty uchar z\nelement face 1\n\
         property list uint int vertex_indices\nend_header\n"
    )
    .into_bytes()
}

#[test]
fn ply_vertices_over_the_limit_are_refused_before_allocating() {
    let dir = low_limit();
    // 9 MB of one-byte coordinates are 72 MB of f64 positions.
    let vertices = 3_000_000;
    let mut bytes = ply_header(vertices);
    bytes.extend(vec![1u8; 3 * vertices]);
    bytes.extend([3, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    let path = file(&dir, "wide.ply", &bytes);
    let text = message(meshflow::io::ply::read_ply(&path), &path);
    assert!(
        text.contains("element 'vertex' of 3000000 records declares 72.0 MB"),
        "{text}"
    );
}

#[test]
fn ply_list_longer_than_the_file_is_refused() {
    let dir = low_limit();
    let mut bytes = ply_header(3);
    bytes.extend([0, 0, 0, 1, 0, 0, 0, 1, 0]);
    bytes.extend(4_000_000_000u32.to_le_bytes());
    bytes.extend([0; 12]);
    let path = file(&dir, "list.ply", &bytes);
    let text = message(meshflow::io::ply::read_ply(&path), &path);
    assert!(
        text.contains("truncated file: the data ends in face 0 (the header declares 1)"),
        "{text}"
    );
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n200 0 1 2\n";
    let path = file(&dir, "list_ascii.ply", ascii.as_bytes());
    let text = message(meshflow::io::ply::read_ply(&path), &path);
    assert!(text.contains("the data ends in face 0"), "{text}");
}

/// Found by tests/fuzz_readers.rs: npyz's parse error quotes the header over several lines.
#[test]
fn npy_bad_header_error_is_one_line() {
    let dir = low_limit();
    let mut bytes = npy("<f8", "(2, 3)", &[0; 48]);
    bytes[10] = b'z';
    let path = file(&dir, "bad.npy", &bytes);
    let text = message(meshflow::io::read_npy_float(&path), &path);
    assert!(
        text.contains("not a valid .npy file (could not parse"),
        "{text}"
    );
}

/// Found by tests/fuzz_readers.rs: quick-xml quotes a closing tag with a line break in it.
#[test]
fn vtu_xml_error_with_a_line_break_is_one_line() {
    let dir = low_limit();
    let text = "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n\
                <UnstructuredGrid>\n</UnstructuredGrid?\n<x>\n</VTKFile>\n";
    let path = file(&dir, "bad.vtu", text.as_bytes());
    let text = message(meshflow::io::vtk::read_vtu(&path), &path);
    assert!(text.contains("not well-formed XML"), "{text}");
}

#[test]
fn times_file_non_finite_values_name_their_line() {
    let dir = low_limit();
    for (text, expected) in [
        ("0\n0.5\nnan\n", "line 3: 'nan' is not a finite time"),
        ("0, 1e400\n", "line 1: '1e400' is not a finite time"),
        ("# t\n\ninf\n", "line 3: 'inf' is not a finite time"),
    ] {
        let path = file(&dir, "times.txt", text.as_bytes());
        let text = message(meshflow::io::read_times_file(&path), &path);
        assert!(text.contains(expected), "{text}");
    }
    let path = dir.path().join("missing.txt");
    assert_eq!(meshflow::io::read_times_file(&path).unwrap(), None);
}

/// The error reading a one-triangle glTF whose only animation channel has `target` (JSON).
fn animation_channel_error(target: &str) -> String {
    let dir = low_limit();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
"buffers":[{{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}}],
"bufferViews":[{{"buffer":0,"byteLength":36}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
"animations":[{{"samplers":[{{"input":0,"output":0}}],"channels":[{{"sampler":0,"target":{target}}}]}}]}}"#
    );
    let path = file(&dir, "bad.gltf", json.as_bytes());
    let options = meshflow::format::gltf::AnimationOptions::default();
    let result = meshflow::io::gltf_read::read_gltf_animation(&path, &options);
    message(result, &path)
}

/// Found by tests/fuzz_readers.rs: `gltf` panicked reading an unknown animation target path.
#[test]
fn gltf_unknown_animation_path_is_an_error() {
    let text = animation_channel_error(r#"{"node":0,"path":"weighus"}"#);
    assert!(
        text.contains("animation 0, channel 0: target path \"weighus\" is not translation"),
        "{text}"
    );
}

/// Found by tests/fuzz_readers.rs: `gltf` panicked reading an animation channel whose target
/// node does not exist.
#[test]
fn gltf_animation_target_node_out_of_range_is_an_error() {
    let text = animation_channel_error(r#"{"node":7,"path":"translation"}"#);
    assert!(
        text.contains("animation 0, channel 0: target node 7 does not exist (1 nodes)"),
        "{text}"
    );
}

/// A glTF of one triangle list: `vertices` float positions (a fan of points on a line, as
/// data need not be a good mesh to be read) in `data.bin`, and `extra` JSON members.
fn gltf_with(dir: &tempfile::TempDir, vertices: usize, mesh: &str, extra: &str) -> PathBuf {
    let bytes: Vec<u8> = (0..3 * vertices)
        .flat_map(|k| ((k % 7) as f32).to_le_bytes())
        .collect();
    file(dir, "data.bin", &bytes);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"meshes":[{mesh}],
"buffers":[{{"byteLength":{length},"uri":"data.bin"}}],
"bufferViews":[{{"buffer":0,"byteLength":{length}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{vertices},"type":"VEC3","min":[0,0,0],"max":[6,6,6]}}]{extra}}}"#,
        length = bytes.len()
    );
    file(dir, "a.gltf", json.as_bytes())
}

/// Found by review: primitives or morph targets that share one accessor multiply its size
/// without more data (here 2000 targets of 30 000 vertices, 2.9 GB).
#[test]
fn gltf_morph_targets_times_vertices_over_the_limit_are_refused() {
    let dir = low_limit();
    let targets = vec![r#"{"POSITION":0}"#; 2000].join(",");
    let mesh =
        format!(r#"{{"primitives":[{{"attributes":{{"POSITION":0}},"targets":[{targets}]}}]}}"#);
    let path = gltf_with(&dir, 30_000, &mesh, r#","nodes":[{"mesh":0}]"#);
    let text = message(meshflow::io::gltf_read::read_gltf_geometry(&path), &path);
    assert!(
        text.contains("mesh 0 (1 primitives: vertices × morph targets, indices) declares 2.9 GB")
            && text.contains("--memory-limit"),
        "{text}"
    );
}

/// Found by review: a buffer's data is decoded to 8-byte values, so an accessor within its
/// buffer can still declare more than the limit.
#[test]
fn gltf_accessor_decoded_over_the_limit_is_refused() {
    let dir = low_limit();
    // 5 MB of u8 keyframe times: 80 MB of f64 while decoding.
    let count = 5_000_000;
    file(&dir, "times.bin", &vec![1; count]);
    let extra = r#","nodes":[{"mesh":0}],
"animations":[{"samplers":[{"input":1,"output":0}],"channels":[{"sampler":0,"target":{"node":0,"path":"translation"}}]}]"#;
    let path = gltf_with(
        &dir,
        3,
        r#"{"primitives":[{"attributes":{"POSITION":0}}]}"#,
        extra,
    );
    let json = std::fs::read_to_string(&path).unwrap().replace(
        r#""buffers":["#,
        &format!(r#""buffers":[{{"byteLength":{count},"uri":"times.bin"}},"#),
    );
    // Buffer 0 is now times.bin: move the views and add the times' accessor.
    let json = json
        .replace(r#""buffer":0"#, r#""buffer":1"#)
        .replace(
            r#""bufferViews":["#,
            &format!(r#""bufferViews":[{{"buffer":0,"byteLength":{count}}},"#),
        )
        .replace(r#""bufferView":0"#, r#""bufferView":1"#)
        .replace(
            r#""max":[6,6,6]}]"#,
            &format!(
                r#""max":[6,6,6]}},{{"bufferView":0,"componentType":5121,"count":{count},"type":"SCALAR"}}]"#
            ),
        );
    std::fs::write(&path, json).unwrap();
    let options = meshflow::format::gltf::AnimationOptions::default();
    let result = meshflow::io::gltf_read::read_gltf_animation(&path, &options);
    let text = message(result, &path);
    assert!(
        text.contains(
            "animation 0, sampler 0, input (accessor 1) with count 5000000 declares 80.0 MB"
        ),
        "{text}"
    );
}

/// Found by review: every buffer naming the same file read it whole again.
#[test]
fn gltf_buffers_sharing_a_file_over_the_limit_are_refused() {
    let dir = low_limit();
    let path = gltf_with(
        &dir,
        300_000,
        r#"{"primitives":[{"attributes":{"POSITION":0}}]}"#,
        r#","nodes":[{"mesh":0}]"#,
    );
    let copies = vec![r#"{"byteLength":3600000,"uri":"data.bin"}"#; 100].join(",");
    let json = std::fs::read_to_string(&path)
        .unwrap()
        .replace(r#""buffers":["#, &format!(r#""buffers":[{copies},"#));
    std::fs::write(&path, json).unwrap();
    let text = message(meshflow::io::gltf_read::read_gltf_geometry(&path), &path);
    assert!(
        text.contains("the byteLength of its 101 buffers declares 363.6 MB"),
        "{text}"
    );
}

/// `nodes` JSON of a chain `0 → 1 → … → depth` (each the child of the one before), the mesh
/// on the last node.
fn chain(depth: usize) -> String {
    let links = (1..=depth).map(|k| format!(r#"{{"children":[{k}]}}"#));
    let nodes: Vec<String> = links.chain([r#"{"mesh":0}"#.to_string()]).collect();
    format!(r#","nodes":[{}]"#, nodes.join(","))
}

/// Found by `fuzz_readers`: a glb with a 60,000-node chain took 120 MB while its JSON (1.4 MB)
/// was held parsed twice. The parsed size is checked before parsing (a deep chain that fits is
/// read in `untrusted_files::deep_node_chains_are_read_without_recursion`).
#[test]
fn gltf_json_parsed_over_the_limit_is_refused() {
    let dir = low_limit();
    let mesh = r#"{"primitives":[{"attributes":{"POSITION":0}}]}"#;
    let path = gltf_with(&dir, 3, mesh, &chain(60_000));
    let text = message(meshflow::io::gltf_read::read_gltf_geometry(&path), &path);
    let length = std::fs::metadata(&path).unwrap().len();
    let expected = format!("the glTF JSON of {length} bytes, parsed twice declares");
    assert!(
        text.contains(&expected) && text.contains("--memory-limit"),
        "{text}"
    );
}

/// Found by review: a cycle away from the mesh's ancestry, and a node with two parents, were
/// taken without a word (glTF allows neither).
#[test]
fn gltf_node_cycles_and_second_parents_name_the_node() {
    let dir = low_limit();
    let mesh = r#"{"primitives":[{"attributes":{"POSITION":0}}]}"#;
    for (nodes, expected) in [
        (
            r#","nodes":[{"mesh":0},{"children":[2]},{"children":[1]}]"#,
            "the node hierarchy has a cycle through node 1",
        ),
        (
            r#","nodes":[{"mesh":0,"children":[0]}]"#,
            "the node hierarchy has a cycle through node 0",
        ),
        (
            r#","nodes":[{"mesh":0},{"children":[0]},{"children":[0],"name":"b"}]"#,
            "node 0 is a child of both node 1 and node 2 (\"b\")",
        ),
    ] {
        let path = gltf_with(&dir, 3, mesh, nodes);
        let text = message(meshflow::io::gltf_read::read_gltf_geometry(&path), &path);
        assert!(text.contains(expected), "{text}");
    }
}

/// Found by review: `--fps` times the animation's duration made any number of frames of the
/// whole mesh.
#[test]
fn gltf_fps_frames_over_the_limit_name_fps() {
    use meshflow::io::gltf_write::{write_glb_animation, AnimationFrame};
    use nalgebra::Vector3;
    let dir = low_limit();
    let positions = [Vector3::zeros(), Vector3::x(), Vector3::y()];
    let frames = [0.0, 1.0].map(|time| AnimationFrame {
        time,
        positions: &positions,
        colors: &[[0.5; 3]; 3],
    });
    let path = dir.path().join("a.glb");
    write_glb_animation(&path, &[[0, 1, 2]], &frames).unwrap();
    let options = meshflow::format::gltf::AnimationOptions {
        fps: Some(1e6),
        ..Default::default()
    };
    let result = meshflow::io::gltf_read::read_gltf_animation(&path, &options);
    let text = message(result, &path);
    assert!(
        text.contains("--fps 1000000 gives 1000001 frames of 3 vertices, which declares 208.0 MB"),
        "{text}"
    );
}

/// Found by review: a short VTU declaring 10¹² points failed only when its data ran out;
/// now its declared size is named before anything is decoded.
#[test]
fn vtu_declared_points_over_the_limit_are_refused() {
    let dir = low_limit();
    let text = "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n<UnstructuredGrid>\n\
                <Piece NumberOfPoints=\"1000000000000\" NumberOfCells=\"1\">\n<Points>\n\
                <DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 \
                1 0 0 0 1 0</DataArray>\n</Points>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    let path = file(&dir, "huge.vtu", text.as_bytes());
    let text = message(meshflow::io::vtk::read_vtu(&path), &path);
    assert!(
        text.contains(
            "line 4: NumberOfPoints=\"1000000000000\" with NumberOfCells=\"1\" declares 24.0 TB"
        ) && text.contains("--memory-limit"),
        "{text}"
    );
}

#[path = "../examples/hostile_battery/main.rs"]
#[allow(dead_code)]
mod battery;

/// The hostile battery (`examples/hostile_battery`), both rounds, through the binary: every
/// case ends as it must (refused in one line where it must be), within its time and memory,
/// with every file outside the outputs unchanged.
#[test]
fn the_hostile_battery_holds() {
    let binary = Path::new(env!("CARGO_BIN_EXE_meshflow"));
    assert_eq!(
        battery::run_battery(binary),
        0,
        "cases failed: see the table above"
    );
}
