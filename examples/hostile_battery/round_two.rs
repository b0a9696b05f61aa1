//! The second round's cases (issue 67): run directories whose manifests name files outside
//! them (with `--force`, the files a forced output would remove), OME-Zarr stores that link
//! outside themselves or hold FIFOs and devices, chunk bombs (sparse, zstd, gzip, blosc, shard
//! indexes, a million absent chunks), runs whose files are FIFOs, links or edited, no-data
//! masks that are not masks, absurd tracks, points and flows, and messages that must stay one
//! short line. Nearly every case must be refused, with a message that says why.

use super::hostile_support::zarr;
use super::round_one::write;
use super::{Case, Expect};
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// What a refusal of a manifest that lists files outside its run says.
const FOREIGN: &str = "not a file meshflow writes in its directory";
/// What a store says of a key that leads out of it.
const OUT_OF_STORE: &str = "leads out of the store";

pub(super) fn cases(base: &Path, binary: &Path) -> Vec<Case> {
    std::fs::create_dir_all(base).unwrap();
    let mut cases = Vec::new();
    forced_outputs(base, binary, &mut cases);
    zarr_stores(base, &mut cases);
    runs(base, binary, &mut cases);
    masks_and_values(base, &mut cases);
    cases
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn out(base: &Path, name: &str) -> String {
    p(&base.join(format!("out_{name}"))).to_string()
}

/// `count` frames of the shipped rotating sphere in `base/name`.
fn frames(base: &Path, name: &str, count: usize) -> PathBuf {
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rotating_sphere");
    let dir = base.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    for k in 0..count {
        let name = format!("frame_{k}.obj");
        std::fs::copy(shipped.join(&name), dir.join(&name)).unwrap();
    }
    dir
}

/// `meshflow solve frames --out run`, which must work.
fn solve(binary: &Path, frames: &Path, run: &Path) -> PathBuf {
    let status = Command::new(binary)
        .args(["solve", p(frames), "--out", p(run), "--quiet"])
        .stdout(Stdio::null())
        .status()
        .expect("the binary starts");
    assert!(status.success(), "the run of the battery");
    run.to_path_buf()
}

/// A copy of directory `from` at `to` (links copied as links).
fn copy_dir(from: &Path, to: &Path) -> PathBuf {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap().flatten() {
        let target = to.join(entry.file_name());
        let kind = entry.file_type().unwrap();
        if kind.is_dir() {
            copy_dir(&entry.path(), &target);
        } else if kind.is_symlink() {
            let link = std::fs::read_link(entry.path()).unwrap();
            std::os::unix::fs::symlink(link, &target).unwrap();
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
    to.to_path_buf()
}

/// `dir`'s manifest, changed by `edit`.
fn edit_manifest(dir: &Path, edit: impl FnOnce(&mut Value)) {
    let file = dir.join("meshflow_run.json");
    let mut json: Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    edit(&mut json);
    std::fs::write(&file, json.to_string()).unwrap();
}

fn fifo(path: &Path) {
    let name = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: `name` is a valid C string; mkfifo only creates the node.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o644) }, 0, "mkfifo");
}

fn symlink(target: &Path, link: &Path) {
    let _ = std::fs::remove_file(link);
    let _ = std::fs::remove_dir_all(link);
    std::os::unix::fs::symlink(target, link).unwrap();
}

/// `--force` into runs whose manifests list `../victim.txt` and an absolute path beside a file
/// of the user's: every command that writes a directory refuses, and the victims stay.
fn forced_outputs(base: &Path, binary: &Path, cases: &mut Vec<Case>) {
    let frames = frames(base, "frames", 3);
    let run = solve(binary, &frames, &base.join("run"));
    write(base, "victim.txt", b"my thesis".to_vec());
    let absolute = write(base, "victim_abs.txt", b"my data".to_vec());
    let planted = |name: &str| -> String {
        let dir = copy_dir(&run, &base.join(name));
        edit_manifest(&dir, |json| {
            let files = json["files"].as_array_mut().unwrap();
            files.push(Value::from("../victim.txt"));
            files.push(Value::from(p(&absolute)));
        });
        write(&dir, "mine.txt", b"not meshflow's".to_vec());
        p(&dir).to_string()
    };
    let points = base.join("points");
    std::fs::create_dir_all(&points).unwrap();
    for k in 0..2 {
        let values: Vec<f64> = (0..40)
            .flat_map(|i| {
                let (a, b) = (i as f64 * 0.7, i as f64 * 0.37 + 0.1 * k as f64);
                [a.cos() * b.sin(), a.sin() * b.sin(), 0.3 * b.cos()]
            })
            .collect();
        meshflow::format::write_npy(&points.join(format!("p{k}.npy")), &[40, 3], &values).unwrap();
    }
    let frame = frames.join("frame_0.obj");
    let runs = p(&run).to_string();
    let commands: [(&str, Vec<&str>); 7] = [
        ("solve", vec!["solve", p(&frames)]),
        ("surface", vec!["surface", p(&points)]),
        ("analyze", vec!["analyze", &runs]),
        ("advect", vec!["advect", &runs]),
        ("render", vec!["render", &runs]),
        ("track", vec!["track", p(&frames)]),
        ("operators", vec!["operators", p(&frame)]),
    ];
    for (name, mut args) in commands {
        let target = planted(&format!("forced_{name}"));
        args.extend(["--out", &target, "--force"]);
        cases.push(Case::new(
            &format!("--force: {name} over a planted manifest"),
            &args,
            Expect::Refused(FOREIGN),
        ));
    }
    let target = planted("rendered_in_place");
    cases.push(Case::new(
        "render RUN whose manifest lists ../victim",
        &["render", &target],
        Expect::Refused(FOREIGN),
    ));
}

/// The arguments that sample `store` onto two frames of the sphere, which lies inside it.
fn sample_args(base: &Path, store: &Path, name: &str, extra: &[&str]) -> Vec<String> {
    let frames2 = base.join("frames2");
    let mut args: Vec<String> = ["sample", p(store), p(&frames2), "--out", &out(base, name)]
        .map(String::from)
        .to_vec();
    args.extend(["--voxel-size", "1,1,1", "--origin=-3,-3,-2.5"].map(String::from));
    args.extend(extra.iter().map(|a| a.to_string()));
    args
}

fn sample_case(base: &Path, store: &Path, name: &str, extra: &[&str], expect: Expect) -> Case {
    let args = sample_args(base, store, name, extra);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    Case::new(name, &args, expect)
}

/// The chunk of frame 0 at the store's origin.
fn first_chunk(store: &Path) -> PathBuf {
    zarr::chunk_files(store)[0].clone()
}

/// OME-Zarr stores (written by `zarrs`) with links, FIFOs, devices, bombs and lies.
fn zarr_stores(base: &Path, cases: &mut Vec<Case>) {
    frames(base, "frames2", 2);
    let bytes = json!([{"name": "bytes", "configuration": {"endian": "little"}}]);
    let chunk = [1, 2, 3, 4];
    let valid = zarr::write_v3(&base.join("store.zarr"), &bytes, chunk);
    let copy = |name: &str| copy_dir(&valid, &base.join(format!("{name}.zarr")));
    cases.push(sample_case(
        base,
        &valid,
        "zarr: a valid store",
        &[],
        Expect::Succeeds,
    ));

    let store = copy("chunk_link");
    let outside = write(base, "outside.bin", vec![7u8; 48]);
    symlink(&outside, &first_chunk(&store));
    cases.push(sample_case(
        base,
        &store,
        "zarr: chunk linked outside",
        &[],
        Expect::Refused(OUT_OF_STORE),
    ));

    let other = copy("other");
    let store = copy("array_link");
    symlink(&other.join("0"), &store.join("0"));
    cases.push(sample_case(
        base,
        &store,
        "zarr: array linked to another store",
        &[],
        Expect::Refused(OUT_OF_STORE),
    ));

    for (name, file) in [
        ("array zarr.json", "0/zarr.json"),
        ("group zarr.json", "zarr.json"),
    ] {
        let store = copy(&format!("passwd_{}", file.replace('/', "_")));
        symlink(Path::new("/etc/passwd"), &store.join(file));
        cases.push(sample_case(
            base,
            &store,
            &format!("zarr: {name} linked to /etc/passwd"),
            &[],
            Expect::Refused(OUT_OF_STORE),
        ));
    }
    let v2 = zarr::write_v2(&base.join("v2.zarr"), &Value::Null, "C");
    for file in [".zattrs", "0/.zarray"] {
        let store = copy_dir(
            &v2,
            &base.join(format!("v2_{}.zarr", file.replace('/', "_"))),
        );
        symlink(Path::new("/etc/passwd"), &store.join(file));
        cases.push(sample_case(
            base,
            &store,
            &format!("zarr v2: {file} linked to /etc/passwd"),
            &[],
            Expect::Refused(OUT_OF_STORE),
        ));
    }
    let store = copy("dev_zero");
    symlink(Path::new("/dev/zero"), &first_chunk(&store));
    cases.push(sample_case(
        base,
        &store,
        "zarr: chunk linked to /dev/zero",
        &[],
        Expect::Refused(OUT_OF_STORE),
    ));
    cases.push(sample_case(
        base,
        &store,
        "zarr: /dev/zero, external files allowed",
        &["--allow-external-files"],
        Expect::Refused("not a regular file"),
    ));
    let store = copy("fifo");
    let chunk_file = first_chunk(&store);
    std::fs::remove_file(&chunk_file).unwrap();
    fifo(&chunk_file);
    cases.push(sample_case(
        base,
        &store,
        "zarr: chunk that is a FIFO",
        &[],
        Expect::Refused("not a regular file"),
    ));

    // Bombs.
    let store = copy("sparse");
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(first_chunk(&store))
        .unwrap();
    file.set_len(50_000_000_000).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: a 50 GB sparse chunk",
        &[],
        Expect::Refused("over the"),
    ));

    let zstd_codecs = json!([{"name": "bytes", "configuration": {"endian": "little"}},
        {"name": "zstd", "configuration": {"level": 3, "checksum": false}}]);
    let zstd_store = zarr::write_v3(&base.join("zstd.zarr"), &zstd_codecs, chunk);
    let store = copy_dir(&zstd_store, &base.join("zstd_declares.zarr"));
    let mut frame = vec![0x28, 0xb5, 0x2f, 0xfd, 0xc0, 0x00];
    frame.extend((1u64 << 50).to_le_bytes());
    frame.extend([1, 0, 0]);
    std::fs::write(first_chunk(&store), &frame).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: 17-byte zstd frame of 2^50 bytes",
        &[],
        Expect::Refused("zstd"),
    ));
    let store = copy_dir(&zstd_store, &base.join("zstd_bomb.zarr"));
    let mut encoder = zstd::stream::Encoder::new(Vec::new(), 3).unwrap();
    let zeros = vec![0u8; 1 << 24];
    for _ in 0..64 {
        encoder.write_all(&zeros).unwrap(); // 1 GiB
    }
    std::fs::write(first_chunk(&store), encoder.finish().unwrap()).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: zstd bomb of 1 GiB",
        &[],
        Expect::Refused("inflates past"),
    ));

    let gzip_codecs = json!([{"name": "bytes", "configuration": {"endian": "little"}},
        {"name": "gzip", "configuration": {"level": 1}}]);
    let gzip_store = zarr::write_v3(&base.join("gzip.zarr"), &gzip_codecs, chunk);
    // A bomb larger than any chunk's encoding is refused by its size; a smaller one inflates
    // until it passes the chunk's size.
    for (mebibytes, expect) in [(256, "over the"), (32, "inflates past")] {
        let store = copy_dir(
            &gzip_store,
            &base.join(format!("gzip_bomb_{mebibytes}.zarr")),
        );
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        for _ in 0..mebibytes / 16 {
            encoder.write_all(&zeros).unwrap();
        }
        std::fs::write(first_chunk(&store), encoder.finish().unwrap()).unwrap();
        let name = format!("zarr: gzip bomb of {mebibytes} MiB");
        cases.push(sample_case(
            base,
            &store,
            &name,
            &[],
            Expect::Refused(expect),
        ));
    }
    let store = copy_dir(&gzip_store, &base.join("gzip_cut.zarr"));
    let chunk_file = first_chunk(&store);
    let bytes = std::fs::read(&chunk_file).unwrap();
    std::fs::write(&chunk_file, &bytes[..bytes.len() / 2]).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: a gzip chunk cut short names it",
        &[],
        Expect::Refused("chunk 0/c/0/0/0/0"),
    ));

    let blosc_codecs = json!([{"name": "bytes", "configuration": {"endian": "little"}},
        {"name": "blosc", "configuration": {"cname": "lz4", "clevel": 5, "shuffle": "shuffle", "typesize": 2, "blocksize": 0}}]);
    let store = zarr::write_v3(&base.join("blosc_lie.zarr"), &blosc_codecs, chunk);
    let chunk_file = first_chunk(&store);
    let mut bytes = std::fs::read(&chunk_file).unwrap();
    bytes[4..8].copy_from_slice(&(i32::MAX as u32).to_le_bytes());
    std::fs::write(&chunk_file, bytes).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: blosc header declaring 2 GB",
        &[],
        Expect::Refused("blosc"),
    ));

    let shards = json!([{"name": "sharding_indexed", "configuration": {"chunk_shape": chunk,
        "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}],
        "index_codecs": [{"name": "bytes", "configuration": {"endian": "little"}}, {"name": "crc32c"}]}}]);
    let store = zarr::write_v3(&base.join("shard_index.zarr"), &shards, [1, 4, 6, 8]);
    let shard = first_chunk(&store);
    let mut bytes = std::fs::read(&shard).unwrap();
    let n = 2 * 2 * 2; // inner chunks of a shard
    let index = bytes.len() - 4 - 16 * n;
    bytes[index..index + 8].copy_from_slice(&(u64::MAX - 9).to_le_bytes());
    let sum = crc32c::crc32c(&bytes[index..bytes.len() - 4]);
    let end = bytes.len();
    bytes[end - 4..].copy_from_slice(&sum.to_le_bytes());
    std::fs::write(&shard, bytes).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: shard index offset 2^64-10",
        &[],
        Expect::Refused("places inner chunk"),
    ));

    let store = copy("tiny_chunks");
    let array = store.join("0/zarr.json");
    let mut metadata: Value = serde_json::from_slice(&std::fs::read(&array).unwrap()).unwrap();
    metadata["shape"] = json!([2, 400, 400, 400]);
    metadata["chunk_grid"]["configuration"]["chunk_shape"] = json!([1, 1, 1, 1]);
    std::fs::write(&array, metadata.to_string()).unwrap();
    for file in zarr::chunk_files(&store) {
        std::fs::remove_file(file).unwrap();
    }
    cases.push(sample_case(
        base,
        &store,
        "zarr: 400^3 one-voxel chunks, none stored",
        &[],
        Expect::Refused("a frame is"),
    ));

    let store = copy("no_depth");
    let array = store.join("0/zarr.json");
    let mut metadata: Value = serde_json::from_slice(&std::fs::read(&array).unwrap()).unwrap();
    metadata["shape"] = json!([2, 0, 7, 6]);
    std::fs::write(&array, metadata.to_string()).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: no voxels in z",
        &[],
        Expect::Refused("no_depth.zarr"),
    ));

    let store = copy("absent");
    for file in zarr::chunk_files(&store) {
        std::fs::remove_file(file).unwrap();
    }
    cases.push(sample_case(
        base,
        &store,
        "zarr: every chunk absent",
        &[],
        Expect::Refused("none of its"),
    ));

    let store = copy("partly_absent");
    std::fs::remove_file(first_chunk(&store)).unwrap();
    cases.push(sample_case(
        base,
        &store,
        "zarr: one chunk absent (a warning)",
        &[],
        Expect::Succeeds,
    ));

    let transformed = |name: &str, transform: Value| -> PathBuf {
        let store = copy(name);
        let group = store.join("zarr.json");
        let mut metadata: Value = serde_json::from_slice(&std::fs::read(&group).unwrap()).unwrap();
        metadata["attributes"]["ome"]["multiscales"][0]["datasets"][0]
            ["coordinateTransformations"] = transform;
        std::fs::write(&group, metadata.to_string()).unwrap();
        store
    };
    let affine = transformed(
        "affine",
        json!([{"type": "affine", "affine": [[2, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 1, 0]]}]),
    );
    let args = sample_args(base, &affine, "zarr: affine transformation", &[]);
    let without_size: Vec<&str> = args.iter().map(String::as_str).take(5).collect();
    cases.push(Case::new(
        "zarr: affine transformation",
        &without_size,
        Expect::Refused("does not apply"),
    ));
    cases.push(sample_case(
        base,
        &affine,
        "zarr: affine, --voxel-size given",
        &[],
        Expect::Succeeds,
    ));
    let bare = transformed("no_scale", json!([]));
    let args = sample_args(base, &bare, "zarr: no scale", &["--allow-outside"]);
    let without_size: Vec<&str> = args
        .iter()
        .map(String::as_str)
        .take(5)
        .chain(["--allow-outside"])
        .collect();
    cases.push(Case::new(
        "zarr: no scale (1 x 1 x 1, a warning)",
        &without_size,
        Expect::Any,
    ));
}

/// Runs whose manifests, pvd files and flows were edited, or are FIFOs and links.
fn runs(base: &Path, binary: &Path, cases: &mut Vec<Case>) {
    let run = base.join("run");
    let copy = |name: &str| copy_dir(&run, &base.join(name));

    let dir = copy("pvd_run");
    let datasets: String = (0..200_000)
        .map(|k| format!("<DataSet timestep=\"{k}\" part=\"0\" file=\"flow_0000.vtu\"/>\n"))
        .collect();
    let pvd = format!("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n{datasets}</Collection>\n</VTKFile>\n");
    std::fs::write(dir.join("flow.pvd"), pvd).unwrap();
    cases.push(Case::new(
        "run: flow.pvd of 200,000 DataSets",
        &["render", p(&dir), "--out", &out(base, "pvd")],
        Expect::Refused("again"),
    ));

    let dir = copy("fifo_run");
    std::fs::remove_file(dir.join("meshflow_run.json")).unwrap();
    fifo(&dir.join("meshflow_run.json"));
    cases.push(Case::new(
        "run: manifest a FIFO (advect)",
        &["advect", p(&dir), "--out", &out(base, "fifo_a")],
        Expect::Refused("not a regular file"),
    ));
    // render reads flow.pvd and its slabs, not the manifest: it must not block on it.
    cases.push(Case::new(
        "run: manifest a FIFO (render)",
        &["render", p(&dir), "--out", &out(base, "fifo_r")],
        Expect::Any,
    ));

    let frames_changed = frames(base, "frames_changed", 3);
    let dir = solve(binary, &frames_changed, &base.join("run_changed"));
    let frame = frames_changed.join("frame_2.obj");
    let mut text = std::fs::read_to_string(&frame).unwrap();
    text.push_str("# changed\n");
    std::fs::write(&frame, text).unwrap();
    edit_manifest(&dir, |json| {
        let inputs = json["inputs"].as_array_mut().unwrap();
        inputs.retain(|entry| !entry["path"].as_str().unwrap().ends_with("frame_2.obj"));
    });
    for command in ["advect", "analyze"] {
        cases.push(Case::new(
            &format!("run: changed input, entry deleted ({command})"),
            &[command, p(&dir), "--out", &out(base, command)],
            Expect::Refused("recorded no fingerprint"),
        ));
    }

    let dir = copy("absolute_input");
    edit_manifest(&dir, |json| json["solve"]["input"] = Value::from("/etc"));
    cases.push(Case::new(
        "run: absolute solve input",
        &["advect", p(&dir), "--out", &out(base, "abs")],
        Expect::Refused("absolute path"),
    ));
    let dir = copy("absolute_intensity");
    edit_manifest(&dir, |json| {
        json["solve"]["load"]["intensity"] = Value::from("/etc/passwd")
    });
    cases.push(Case::new(
        "run: absolute intensity",
        &["analyze", p(&dir), "--out", &out(base, "absi")],
        Expect::Refused("absolute path"),
    ));

    let dir = copy("huge_manifest");
    let manifest = std::fs::OpenOptions::new()
        .write(true)
        .open(dir.join("meshflow_run.json"))
        .unwrap();
    manifest.set_len(300_000_000).unwrap();
    cases.push(Case::new(
        "run: manifest of 300 MB",
        &["advect", p(&dir), "--out", &out(base, "huge")],
        Expect::Refused("at most"),
    ));

    let dir = copy("linked_flow");
    let elsewhere = base.join("elsewhere_flow.npy");
    std::fs::rename(dir.join("flow_intrinsic.npy"), &elsewhere).unwrap();
    symlink(&elsewhere, &dir.join("flow_intrinsic.npy"));
    cases.push(Case::new(
        "run: flow_intrinsic.npy linked outside",
        &["advect", p(&dir), "--out", &out(base, "lflow")],
        Expect::Refused("leads out"),
    ));

    let dir = copy("huge_flow");
    let flow = meshflow::format::read_npy_float(&dir.join("flow_intrinsic.npy")).unwrap();
    let scaled: Vec<f64> = flow.data.iter().map(|v| v * 1e305).collect();
    meshflow::format::write_npy(&dir.join("flow_intrinsic.npy"), &flow.shape, &scaled).unwrap();
    edit_manifest(&dir, |_| {});
    cases.push(Case::new(
        "run: flow x 1e305 (advect)",
        &["advect", p(&dir), "--out", &out(base, "hflow")],
        Expect::Refused("not a flow on it"),
    ));
}

/// No-data masks that are links, FIFOs, directories, devices or hold NaN; absurd tracks and
/// points; a CSV field of 50 MB; ImageJ frame counts that are no counts.
fn masks_and_values(base: &Path, cases: &mut Vec<Case>) {
    let sphere = meshflow::shapes::icosphere(2);
    let positions: Vec<Vec<nalgebra::Vector3<f64>>> =
        (0..3).map(|_| sphere.positions.clone()).collect();
    let grey: Vec<Vec<f64>> = (0..3)
        .map(|k| {
            sphere
                .positions
                .iter()
                .map(|x| (3.0 * x.x + 0.2 * k as f64).sin())
                .collect()
        })
        .collect();
    let sequence = |name: &str| -> PathBuf {
        let dir = base.join(name);
        std::fs::create_dir_all(&dir).unwrap();
        meshflow::format::write_npy_sequence(
            &dir,
            &positions,
            &sphere.faces,
            Some(&grey),
            &[0.0, 1.0, 2.0],
        )
        .unwrap();
        dir
    };
    let n = sphere.positions.len();
    let shape = [3, n as u64];
    let mask = base.join("outside_mask.npy");
    meshflow::format::write_npy(&mask, &shape, &vec![0.0f64; 3 * n]).unwrap();
    let solve_case = |dir: &Path, name: &str, expect| {
        Case::new(
            name,
            &[
                "solve",
                p(dir),
                "--out",
                &out(base, name.split(':').next().unwrap()),
            ],
            expect,
        )
    };
    let dir = sequence("mask_link");
    symlink(&mask, &dir.join("no_data.npy"));
    cases.push(solve_case(
        &dir,
        "mask: no_data.npy linked outside",
        Expect::Refused("leads out"),
    ));
    let dir = sequence("mask_fifo");
    fifo(&dir.join("no_data.npy"));
    cases.push(solve_case(
        &dir,
        "mask: no_data.npy a FIFO",
        Expect::Refused("not a regular file"),
    ));
    let dir = sequence("mask_dir");
    std::fs::create_dir(dir.join("no_data.npy")).unwrap();
    cases.push(solve_case(
        &dir,
        "mask: no_data.npy a directory",
        Expect::Refused("not a regular file"),
    ));
    let dir = sequence("mask_zero");
    symlink(Path::new("/dev/zero"), &dir.join("no_data.npy"));
    cases.push(solve_case(
        &dir,
        "mask: no_data.npy /dev/zero",
        Expect::Refused("no_data.npy"),
    ));
    let dir = sequence("mask_nan");
    let mut values = vec![0.0f64; 3 * n];
    values[n + 5] = f64::NAN;
    meshflow::format::write_npy(&dir.join("no_data.npy"), &shape, &values).unwrap();
    cases.push(solve_case(
        &dir,
        "mask: NaN in no_data.npy",
        Expect::Refused("holds 0 or 1"),
    ));
    let dir = sequence("mask_shape");
    meshflow::format::write_npy(&dir.join("no_data.npy"), &[2, 5], &[0.0; 10]).unwrap();
    cases.push(solve_case(
        &dir,
        "mask: of the wrong shape",
        Expect::Refused("no-data mask has shape"),
    ));
    let dir = sequence("mask_ok");
    let mut values = vec![0.0f64; 3 * n];
    values[7] = 1.0;
    meshflow::format::write_npy(&dir.join("no_data.npy"), &shape, &values).unwrap();
    cases.push(solve_case(
        &dir,
        "mask: a valid no_data.npy",
        Expect::Succeeds,
    ));

    let frames = base.join("frames");
    let tracks = base.join("tracks.npy");
    let mut values: Vec<f64> = (0..3 * 4 * 3)
        .map(|i| ((i % 3) as f64 - 1.0) * 0.5)
        .collect();
    values[13] = 1e300;
    meshflow::format::write_npy(&tracks, &[3, 4, 3], &values).unwrap();
    cases.push(Case::new(
        "tracks at 1e300",
        &[
            "solve",
            p(&frames),
            "--ground-truth-tracks",
            p(&tracks),
            "--out",
            &out(base, "tracks"),
        ],
        Expect::Refused("not a point on it"),
    ));

    let points = base.join("points_big");
    std::fs::create_dir_all(&points).unwrap();
    for k in 0..2 {
        let mut values: Vec<f64> = (0..30).map(|i| (i * 7 % 11) as f64).collect();
        values[4] = 1e308;
        meshflow::format::write_npy(&points.join(format!("p{k}.npy")), &[10, 3], &values).unwrap();
    }
    cases.push(Case::new(
        "match of points at 1e308",
        &["match", p(&points), "--out", &out(base, "m.npy")],
        Expect::Refused("within ±1e50"),
    ));

    let csv = base.join("csv_field");
    std::fs::create_dir_all(&csv).unwrap();
    for k in 0..2 {
        let mut text = String::from("x,y,z\n1,2,3\n4,5,6\n");
        if k == 1 {
            text.push_str(&format!("7,8,{}\n", "9".repeat(50_000_000) + "x"));
        }
        std::fs::write(csv.join(format!("c{k}.csv")), text).unwrap();
    }
    cases.push(Case::new(
        "csv field of 50 MB",
        &["surface", p(&csv), "--out", &out(base, "csv")],
        Expect::Refused("not a number"),
    ));

    let frames2 = base.join("frames2");
    for said in ["0", "-3"] {
        let stack = base.join(format!("frames_{said}.tif"));
        imagej_stack(&stack, said);
        cases.push(Case::new(
            &format!("ImageJ frames={said}"),
            &[
                "sample",
                p(&stack),
                p(&frames2),
                "--out",
                &out(base, "ij.npy"),
            ],
            Expect::Refused("not a positive count"),
        ));
    }
}

/// An ImageJ hyperstack of 2 × 4 pages of 6 × 6 whose description says `frames={frames}`.
fn imagej_stack(file: &Path, frames: &str) {
    use tiff::encoder::colortype::Gray16;
    use tiff::encoder::TiffEncoder;
    use tiff::tags::Tag;
    let mut encoder = TiffEncoder::new(std::fs::File::create(file).unwrap()).unwrap();
    for page in 0..8 {
        let mut image = encoder.new_image::<Gray16>(6, 6).unwrap();
        if page == 0 {
            let description =
                format!("ImageJ=1.54f\nimages=8\nslices=4\nframes={frames}\nhyperstack=true\n");
            image
                .encoder()
                .write_tag(Tag::ImageDescription, description.as_str())
                .unwrap();
        }
        image.write_data(&[page as u16; 36]).unwrap();
    }
}
