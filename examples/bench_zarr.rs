//! Reading OME-Zarr frames: meshflow's reader (its own store and bounded chunk decoding,
//! `volume/zarr_store.rs`, `volume/zarr_chunks.rs`) against `zarrs`' own `FilesystemStore` and
//! codecs (what meshflow read through before), on the same images written by `zarrs`: frames
//! of 128 × 512 × 512 u16 (a smooth pattern with noise) in chunks of 32 × 256 × 256, raw, zstd,
//! gzip and blosc, and in shards of 64 × 512 × 512 of such chunks. Prints seconds per frame
//! (the best of three reads of every frame) and checks that both read the same values.
//!
//! ```text
//! cargo run --release --example bench_zarr [FRAMES]
//! ```

use meshflow::volume::{VolumeOptions, VolumeStream};
use serde_json::{json, Value};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use zarrs::array::{Array, ArraySubset};
use zarrs::filesystem::FilesystemStore;

const SHAPE: [u64; 3] = [128, 512, 512];

fn main() {
    let frames: u64 = std::env::args()
        .nth(1)
        .map_or(2, |n| n.parse().expect("FRAMES"));
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bytes = json!({"name": "bytes", "configuration": {"endian": "little"}});
    let chunk = [1, 32, 256, 256];
    let chains: [(&str, Value, [u64; 4]); 5] = [
        ("raw", json!([bytes]), chunk),
        (
            "zstd",
            json!([bytes, {"name": "zstd", "configuration": {"level": 3, "checksum": false}}]),
            chunk,
        ),
        (
            "gzip",
            json!([bytes, {"name": "gzip", "configuration": {"level": 5}}]),
            chunk,
        ),
        (
            "blosc",
            json!([bytes, {"name": "blosc", "configuration": {"cname": "lz4", "clevel": 5, "shuffle": "shuffle", "typesize": 2, "blocksize": 0}}]),
            chunk,
        ),
        (
            "zstd shards",
            json!([{"name": "sharding_indexed", "configuration": {"chunk_shape": chunk,
            "codecs": [bytes, {"name": "zstd", "configuration": {"level": 3, "checksum": false}}],
            "index_codecs": [bytes, {"name": "crc32c"}]}}]),
            [1, 64, 512, 512],
        ),
    ];
    println!(
        "{frames} frames of {SHAPE:?} u16, {} threads",
        rayon::current_num_threads()
    );
    println!(
        "{:<12} {:>10} {:>14} {:>14} {:>7}",
        "chunks", "MB stored", "meshflow s", "zarrs s", "ratio"
    );
    for (name, codecs, chunk) in chains {
        let image = dir.path().join(format!("{}.zarr", name.replace(' ', "_")));
        write_image(&image, &codecs, chunk, frames);
        let stored = directory_bytes(&image) as f64 / 1e6;
        let (ours, values) = best_of_three(|| read_meshflow(&image, frames));
        let (theirs, expected) = best_of_three(|| read_zarrs(&image, frames));
        assert_eq!(values, expected, "{name}: the readers disagree");
        println!(
            "{name:<12} {stored:>10.1} {:>14.3} {:>14.3} {:>7.2}",
            ours / frames as f64,
            theirs / frames as f64,
            ours / theirs
        );
    }
}

/// The smallest seconds of three runs of `read`, and what it read.
fn best_of_three(read: impl Fn() -> Vec<f32>) -> (f64, Vec<f32>) {
    let mut best = (f64::INFINITY, Vec::new());
    for _ in 0..3 {
        let start = Instant::now();
        let values = read();
        let seconds = start.elapsed().as_secs_f64();
        if seconds < best.0 {
            best = (seconds, values);
        }
    }
    best
}

fn read_meshflow(image: &Path, frames: u64) -> Vec<f32> {
    let stream = VolumeStream::open(image, &VolumeOptions::default()).expect("opens");
    let mut values = Vec::new();
    for volume in stream.take(frames as usize) {
        values.extend_from_slice(volume.expect("a frame").0.values());
    }
    values
}

fn read_zarrs(image: &Path, frames: u64) -> Vec<f32> {
    let array = Array::open(Arc::new(FilesystemStore::new(image).unwrap()), "/0").unwrap();
    let mut values = Vec::new();
    for t in 0..frames {
        let [z, y, x] = SHAPE;
        let subset = ArraySubset::new_with_ranges(&[t..t + 1, 0..z, 0..y, 0..x]);
        let frame: Vec<u16> = array.retrieve_array_subset(&subset).unwrap();
        values.extend(frame.into_iter().map(f32::from));
    }
    values
}

/// An NGFF 0.5 image of `frames` frames with `codecs` and chunks of `chunk`, written by zarrs.
fn write_image(image: &Path, codecs: &Value, chunk: [u64; 4], frames: u64) {
    let [z, y, x] = SHAPE;
    let group = json!({"zarr_format": 3, "node_type": "group", "attributes": {"ome": {
        "version": "0.5", "multiscales": [{"version": "0.5",
        "axes": [{"name": "t", "type": "time"}, {"name": "z", "type": "space"},
            {"name": "y", "type": "space"}, {"name": "x", "type": "space"}],
        "datasets": [{"path": "0", "coordinateTransformations": [
            {"type": "scale", "scale": [1.0, 2.0, 1.0, 1.0]}]}]}]}}});
    let array = json!({"zarr_format": 3, "node_type": "array", "shape": [frames, z, y, x],
        "data_type": "uint16",
        "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunk}},
        "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
        "fill_value": 0, "codecs": codecs});
    std::fs::create_dir_all(image.join("0")).unwrap();
    std::fs::write(image.join("zarr.json"), group.to_string()).unwrap();
    std::fs::write(image.join("0/zarr.json"), array.to_string()).unwrap();
    let array = Array::open(Arc::new(FilesystemStore::new(image).unwrap()), "/0").unwrap();
    for t in 0..frames {
        let mut state = 0x2545_f491_4f6c_dd1d_u64 ^ t;
        let values: Vec<u16> = (0..z * y * x)
            .map(|n| {
                let (k, j, i) = (n / (y * x), n / x % y, n % x);
                let smooth = 2000.0
                    * (1.0
                        + ((i + 3 * t) as f64 * 0.05).sin()
                            * (j as f64 * 0.03).cos()
                            * (k as f64 * 0.1).sin());
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (smooth as u64 + state % 64) as u16
            })
            .collect();
        let subset = ArraySubset::new_with_ranges(&[t..t + 1, 0..z, 0..y, 0..x]);
        array.store_array_subset(&subset, &values[..]).unwrap();
    }
}

fn directory_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|entry| match entry.file_type().unwrap().is_dir() {
            true => directory_bytes(&entry.path()),
            false => entry.metadata().unwrap().len(),
        })
        .sum()
}
