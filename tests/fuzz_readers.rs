//! Fuzzing that stays: small valid files of every format the readers take (NPY float and
//! integer, PLY ASCII and binary, OBJ with its MTL, MatrixMarket, VTU, glTF JSON with a
//! `data:` buffer, glb) are mutated — byte flips, truncation, insertion, numbers in the text or
//! words in the binary set to extremes (0, -1, 2³¹, 2³²−1, 2⁶³, 1e308, NaN) — and read back.
//!
//! Each case must end in `Ok` or an `IoError` whose one-line message names the file (a panic
//! fails the case: proptest catches it), and the peak of live heap bytes while reading, counted
//! by the [`Counting`] allocator below, must stay under the memory limit of this binary
//! (64 MiB, set before every test) plus [`MARGIN`].
//!
//! `MESHFLOW_FUZZ_CASES` sets the cases per reader (default 2,000: about 22,000 in all, which
//! CI runs in well under a minute in release).

use meshflow::io::IoError;
use nalgebra::Vector3;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The memory limit of this binary.
const LIMIT: usize = 64 << 20;

/// What a reader may hold beyond the limit: the limit bounds each declared array, not the
/// file's bytes, parse trees and the transient copy of a growing vector, which for these
/// files of a few kilobytes stay far below 16 MiB. A reader that trusts a declared size goes
/// far past it (gigabytes) or aborts.
const MARGIN: usize = 16 << 20;

/// Live heap bytes, and their peak since the last [`reset_peak`].
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

/// The system allocator, counting live bytes and their peak.
struct Counting;

impl Counting {
    fn grew(bytes: usize) {
        let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
        PEAK.fetch_max(live, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let pointer = unsafe { System.alloc(layout) };
        if !pointer.is_null() {
            Self::grew(layout.size());
        }
        pointer
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let pointer = unsafe { System.alloc_zeroed(layout) };
        if !pointer.is_null() {
            Self::grew(layout.size());
        }
        pointer
    }

    unsafe fn dealloc(&self, pointer: *mut u8, layout: Layout) {
        unsafe { System.dealloc(pointer, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, pointer: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let moved = unsafe { System.realloc(pointer, layout, size) };
        if !moved.is_null() {
            // Counted as the new block beside the old one: what a moving realloc holds.
            Self::grew(size);
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        moved
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// One test at a time, so that the peak is the reader's, not another test's.
static SERIAL: Mutex<()> = Mutex::new(());

/// Sets the peak to the live bytes now and returns them.
fn reset_peak() -> usize {
    let live = LIVE.load(Ordering::Relaxed);
    PEAK.store(live, Ordering::Relaxed);
    live
}

fn cases() -> u32 {
    std::env::var("MESHFLOW_FUZZ_CASES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(2000)
}

/// Extremes written over a number of the text.
const TEXT_EXTREMES: [&str; 9] = [
    "0",
    "-1",
    "2147483648",
    "4294967295",
    "9223372036854775808",
    "18446744073709551616",
    "1e308",
    "NaN",
    "-1e308",
];

/// Extremes written over a 4-byte word of the data (little-endian).
const WORD_EXTREMES: [u32; 5] = [0, u32::MAX, 1 << 31, 1 << 16, 0x7fff_ffff];

/// The glTF members that size an allocation, and extremes written over their numbers.
const SIZE_KEYS: [&str; 4] = [
    "\"count\":",
    "\"byteLength\":",
    "\"byteStride\":",
    "\"byteOffset\":",
];
const SIZE_EXTREMES: [&str; 3] = ["2147483648", "4294967295", "1000000000000"];

/// Lengths of node chains appended to a glTF's nodes.
const CHAIN_DEPTHS: [usize; 3] = [2, 1000, 30_000];

/// One change to a file.
#[derive(Clone, Debug)]
enum Mutation {
    Flip(prop::sample::Index, u8),
    Truncate(prop::sample::Index),
    Insert(prop::sample::Index, Vec<u8>),
    /// The `Index`-th run of digits of the file replaced by an extreme.
    Number(prop::sample::Index, usize),
    /// The 4-byte word at `Index` replaced by an extreme.
    Word(prop::sample::Index, usize),
    /// The number of the `Index`-th glTF size member ([`SIZE_KEYS`]) replaced by an extreme.
    Size(prop::sample::Index, usize),
    /// A chain of [`CHAIN_DEPTHS`] nodes appended to a glTF's nodes, its last the parent of
    /// node 0 (a second parent, when it has one) or, when `true`, of the chain's first (a
    /// cycle).
    Chain(usize, bool),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    use prop::sample::Index;
    prop_oneof![
        3 => (any::<Index>(), 1u8..=255).prop_map(|(at, bits)| Mutation::Flip(at, bits)),
        1 => any::<Index>().prop_map(Mutation::Truncate),
        1 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, bytes)| Mutation::Insert(at, bytes)),
        4 => (any::<Index>(), 0..TEXT_EXTREMES.len()).prop_map(|(at, k)| Mutation::Number(at, k)),
        2 => (any::<Index>(), 0..WORD_EXTREMES.len()).prop_map(|(at, k)| Mutation::Word(at, k)),
        3 => (any::<Index>(), 0..SIZE_EXTREMES.len()).prop_map(|(at, k)| Mutation::Size(at, k)),
        1 => (0..CHAIN_DEPTHS.len(), any::<bool>()).prop_map(|(k, cycle)| Mutation::Chain(k, cycle)),
    ]
}

/// The byte ranges of the runs of ASCII digits of `bytes`.
fn digit_runs(bytes: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut runs = Vec::new();
    let mut start = None;
    for (at, byte) in bytes.iter().chain([&b' ']).enumerate() {
        match (byte.is_ascii_digit(), start) {
            (true, None) => start = Some(at),
            (false, Some(from)) => {
                runs.push(from..at);
                start = None;
            }
            _ => {}
        }
    }
    runs
}

fn apply(bytes: &mut Vec<u8>, mutation: &Mutation) {
    if bytes.is_empty() {
        return;
    }
    match mutation {
        Mutation::Flip(at, bits) => {
            let at = at.index(bytes.len());
            bytes[at] ^= bits;
        }
        Mutation::Truncate(at) => bytes.truncate(at.index(bytes.len())),
        Mutation::Insert(at, new) => {
            let at = at.index(bytes.len());
            bytes.splice(at..at, new.iter().copied());
        }
        Mutation::Number(at, k) => {
            let runs = digit_runs(bytes);
            if !runs.is_empty() {
                let run = runs[at.index(runs.len())].clone();
                bytes.splice(run, TEXT_EXTREMES[*k].bytes());
            }
        }
        Mutation::Word(at, k) if bytes.len() >= 4 => {
            let at = at.index(bytes.len() - 3);
            bytes[at..at + 4].copy_from_slice(&WORD_EXTREMES[*k].to_le_bytes());
        }
        Mutation::Word(..) => {}
        Mutation::Size(at, k) => on_json(bytes, |json| set_size(json, at, SIZE_EXTREMES[*k])),
        Mutation::Chain(k, cycle) => {
            on_json(bytes, |json| add_chain(json, CHAIN_DEPTHS[*k], *cycle))
        }
    }
}

/// Applies `change` to the JSON of a glTF: the whole file, or a GLB's JSON chunk (the GLB then
/// rebuilt around it with its lengths).
fn on_json(bytes: &mut Vec<u8>, change: impl FnOnce(&mut Vec<u8>)) {
    let json_length = |b: &[u8]| u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    if !bytes.starts_with(b"glTF") {
        return change(bytes);
    }
    if bytes.len() < 20 || bytes.len() < 20 + json_length(bytes) {
        return;
    }
    let end = 20 + json_length(bytes);
    let mut json = bytes[20..end].to_vec();
    change(&mut json);
    json.resize(json.len().next_multiple_of(4), b' ');
    let rest = bytes.split_off(end);
    bytes.truncate(12);
    bytes.extend((json.len() as u32).to_le_bytes());
    bytes.extend(b"JSON");
    bytes.extend(json);
    bytes.extend(rest);
    let total = (bytes.len() as u32).to_le_bytes();
    bytes[8..12].copy_from_slice(&total);
}

/// Replaces the number after the `at`-th size member ([`SIZE_KEYS`]) by `extreme`.
fn set_size(json: &mut Vec<u8>, at: &prop::sample::Index, extreme: &str) {
    let members: Vec<usize> = (0..json.len())
        .filter(|&i| {
            SIZE_KEYS
                .iter()
                .any(|key| json[i..].starts_with(key.as_bytes()))
        })
        .collect();
    if members.is_empty() {
        return;
    }
    let member = members[at.index(members.len())];
    let colon = member + json[member..].iter().position(|&b| b == b':').unwrap();
    let start = colon + 1;
    let digits = json[start..]
        .iter()
        .take_while(|b| b.is_ascii_digit())
        .count();
    json.splice(start..start + digits, extreme.bytes());
}

/// Appends a chain of `depth` nodes (see [`Mutation::Chain`]); JSON that no longer parses is
/// left alone.
fn add_chain(json: &mut Vec<u8>, depth: usize, cycle: bool) {
    let Ok(mut value) = serde_json::from_slice::<serde_json::Value>(json) else {
        return;
    };
    let Some(nodes) = value["nodes"].as_array_mut() else {
        return;
    };
    let first = nodes.len();
    let last_child = if cycle { first } else { 0 };
    nodes.extend((1..=depth).map(|k| {
        let child = if k == depth { last_child } else { first + k };
        serde_json::json!({ "children": [child] })
    }));
    *json = serde_json::to_vec(&value).unwrap();
}

/// Reads a file, the outcome only.
type Reader = fn(&Path) -> Result<(), IoError>;

/// Mutates `name` (one of the files `write` puts into a directory) and reads `read_name` with
/// `read` over [`cases`] cases; returns the largest peak of live heap bytes above the baseline.
fn fuzz(write: fn(&Path), name: &str, read_name: &str, read: Reader) -> usize {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    meshflow::limits::set_memory_limit(LIMIT as u64);
    let dir = tempfile::tempdir().unwrap();
    write(dir.path());
    let original = std::fs::read(dir.path().join(name)).unwrap();
    read(&dir.path().join(read_name)).expect("the unmutated file reads");
    let config = Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    };
    let largest = AtomicUsize::new(0);
    let started = std::time::Instant::now();
    let mut runner = TestRunner::new(config);
    let mutations = prop::collection::vec(mutation(), 1..4);
    let result = runner.run(&mutations, |mutations| {
        let mut bytes = original.clone();
        mutations.iter().for_each(|m| apply(&mut bytes, m));
        std::fs::write(dir.path().join(name), &bytes).unwrap();
        let path = dir.path().join(read_name);
        let baseline = reset_peak();
        let outcome = read(&path);
        let peak = PEAK.load(Ordering::Relaxed).saturating_sub(baseline);
        largest.fetch_max(peak, Ordering::Relaxed);
        prop_assert!(peak <= LIMIT + MARGIN, "peak {peak} bytes: {outcome:?}");
        if let Err(error) = outcome {
            let text = error.to_string();
            prop_assert!(text.contains(&dir.path().display().to_string()), "{text}");
            prop_assert!(!text.contains('\n'), "{text}");
        }
        Ok(())
    });
    eprintln!(
        "{read_name} ({name} mutated): {} cases, peak {} kB, {:.2} s",
        cases(),
        largest.load(Ordering::Relaxed) / 1000,
        started.elapsed().as_secs_f64()
    );
    if let Err(failure) = result {
        panic!("{read_name}: {failure}");
    }
    largest.into_inner()
}

fn tetrahedron() -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let positions = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
    ];
    (positions, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
}

fn write_npy_float(dir: &Path) {
    let values: Vec<f64> = (0..12).map(f64::from).collect();
    meshflow::io::write_npy(&dir.join("a.npy"), &[2, 2, 3], &values).unwrap();
}

fn write_npy_int(dir: &Path) {
    let values: Vec<i32> = vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    meshflow::io::write_npy(&dir.join("a.npy"), &[4, 3], &values).unwrap();
}

fn write_npy_u8(dir: &Path) {
    let values: Vec<u8> = (0..24).collect();
    meshflow::io::write_npy(&dir.join("a.npy"), &[2, 4, 3], &values).unwrap();
}

fn write_ply_with(dir: &Path, encoding: meshflow::io::ply::PlyEncoding) {
    let (positions, faces) = tetrahedron();
    let colors = [[0.5, 0.25, 1.0]; 4];
    let extra = [1.0, 2.0, 3.0, 4.0];
    let path = dir.join("a.ply");
    let properties: [(&str, &[f64]); 1] = [("quality", &extra)];
    meshflow::io::ply::write_ply(
        &path,
        &positions,
        &faces,
        Some(&colors),
        &properties,
        encoding,
    )
    .unwrap();
}

fn write_ply_ascii(dir: &Path) {
    write_ply_with(dir, meshflow::io::ply::PlyEncoding::Ascii);
}

fn write_ply_binary(dir: &Path) {
    write_ply_with(dir, meshflow::io::ply::PlyEncoding::BinaryLittleEndian);
}

fn write_obj_with_mtl(dir: &Path) {
    let obj = "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n\
               usemtl red\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\nusemtl blue\nf 1 4 3\nf 2 3 4\n";
    let mtl = "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n";
    std::fs::write(dir.join("a.obj"), obj).unwrap();
    std::fs::write(dir.join("a.mtl"), mtl).unwrap();
}

fn write_mtx(dir: &Path) {
    let text = "%%MatrixMarket matrix coordinate real symmetric\n% a comment\n3 3 4\n\
                1 1 2.0\n2 1 -1.0\n2 2 2.0\n3 3 1.5\n";
    std::fs::write(dir.join("a.mtx"), text).unwrap();
}

fn write_vtu(dir: &Path) {
    let (positions, faces) = tetrahedron();
    let values = [0.1, 0.2, 0.3, 0.4];
    let data = [meshflow::io::vtk::NamedArray::scalars("value", &values)];
    let arrays: Vec<_> = data.iter().map(|a| a.as_point_array()).collect();
    meshflow::io::vtk::write_vtu(&dir.join("a.vtu"), &positions, &faces, &arrays).unwrap();
}

/// A triangle: three float positions and three u16 indices in one `data:` buffer.
fn write_gltf(dir: &Path) {
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
"buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}],
"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]}"#;
    std::fs::write(dir.join("a.gltf"), json).unwrap();
}

fn write_glb(dir: &Path) {
    use meshflow::io::gltf_write::{write_glb_animation, AnimationFrame};
    let (positions, faces) = tetrahedron();
    let moved: Vec<_> = positions.iter().map(|p| p * 1.5).collect();
    let colors = [[0.5, 0.5, 0.5]; 4];
    let frames = [(0.0, &positions), (1.0, &moved)].map(|(time, positions)| AnimationFrame {
        time,
        positions,
        colors: &colors,
    });
    write_glb_animation(&dir.join("a.glb"), &faces, &frames).unwrap();
}

fn ok<T>(result: Result<T, IoError>) -> Result<(), IoError> {
    result.map(|_| ())
}

#[test]
fn npy_float_survives_mutation() {
    fuzz(write_npy_float, "a.npy", "a.npy", |p| {
        ok(meshflow::io::read_npy_float(p))?;
        ok(meshflow::io::read_npy_float_rows(p, &|r| r % 2 == 0))
    });
}

#[test]
fn npy_indices_survive_mutation() {
    fuzz(write_npy_int, "a.npy", "a.npy", |p| {
        ok(meshflow::io::read_npy_indices(p))
    });
}

#[test]
fn npy_image_survives_mutation() {
    fuzz(write_npy_u8, "a.npy", "a.npy", |p| {
        ok(meshflow::io::read_npy_image(p))?;
        ok(meshflow::io::read_npy_f32(p))
    });
}

#[test]
fn ply_ascii_survives_mutation() {
    fuzz(write_ply_ascii, "a.ply", "a.ply", |p| {
        ok(meshflow::io::ply::read_ply(p))
    });
}

#[test]
fn ply_binary_survives_mutation() {
    fuzz(write_ply_binary, "a.ply", "a.ply", |p| {
        ok(meshflow::io::ply::read_ply(p))
    });
}

#[test]
fn obj_survives_mutation() {
    fuzz(write_obj_with_mtl, "a.obj", "a.obj", |p| {
        ok(meshflow::io::read_mesh(p))
    });
}

#[test]
fn mtl_survives_mutation() {
    fuzz(write_obj_with_mtl, "a.mtl", "a.obj", |p| {
        ok(meshflow::io::read_mesh(p))
    });
}

#[test]
fn mtx_survives_mutation() {
    fuzz(write_mtx, "a.mtx", "a.mtx", |p| {
        ok(meshflow::io::read_matrix_market(p))
    });
}

#[test]
fn vtu_survives_mutation() {
    fuzz(write_vtu, "a.vtu", "a.vtu", |p| {
        ok(meshflow::io::vtk::read_vtu(p))
    });
}

#[test]
fn gltf_survives_mutation() {
    fuzz(write_gltf, "a.gltf", "a.gltf", |p| {
        ok(meshflow::io::read_mesh(p))
    });
}

#[test]
fn glb_survives_mutation() {
    fuzz(write_glb, "a.glb", "a.glb", |p| {
        let options = meshflow::format::gltf::AnimationOptions::default();
        ok(meshflow::io::gltf_read::read_gltf_animation(p, &options))
    });
}
