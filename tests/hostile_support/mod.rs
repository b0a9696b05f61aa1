//! Hand-built input files for the hostile-input tests: TIFF stacks whose every header field
//! can be set (page counts, sizes, strip offsets and lengths that lie), NPY headers, CSV text.
#![allow(dead_code)]

/// One page directory of a hand-built grey TIFF.
#[derive(Clone, Debug)]
pub struct Page {
    pub width: u32,
    pub height: u32,
    pub bits: u16,
    /// 1: none, 8: deflate.
    pub compression: u16,
    /// 1: unsigned integer, 3: IEEE float.
    pub sample_format: u16,
    /// Where its one strip is, and how long it says it is.
    pub strip_offset: u32,
    pub strip_bytes: u32,
}

impl Page {
    /// An uncompressed page of `width × height` bytes whose strip is at offset 8.
    pub fn bytes(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            bits: 8,
            compression: 1,
            sample_format: 1,
            strip_offset: 8,
            strip_bytes: width * height,
        }
    }
}

/// A little-endian TIFF: the header, `strip` at offset 8, then one directory per page, each
/// pointing at the next.
pub fn tiff_bytes(pages: &[Page], strip: &[u8]) -> Vec<u8> {
    let mut out = b"II*\0".to_vec();
    let first_ifd = 8 + strip.len() as u32 + (strip.len() as u32 & 1);
    out.extend(first_ifd.to_le_bytes());
    out.extend(strip);
    if strip.len() % 2 == 1 {
        out.push(0);
    }
    for (n, page) in pages.iter().enumerate() {
        let entries: [(u16, u16, u32); 10] = [
            (256, 4, page.width),
            (257, 4, page.height),
            (258, 3, page.bits as u32),
            (259, 3, page.compression as u32),
            (262, 3, 1),
            (273, 4, page.strip_offset),
            (277, 3, 1),
            (278, 4, page.height),
            (279, 4, page.strip_bytes),
            (339, 3, page.sample_format as u32),
        ];
        out.extend((entries.len() as u16).to_le_bytes());
        for (tag, kind, value) in entries {
            out.extend(tag.to_le_bytes());
            out.extend(kind.to_le_bytes());
            out.extend(1u32.to_le_bytes());
            match kind {
                3 => out.extend([(value as u16).to_le_bytes(), [0, 0]].concat()),
                _ => out.extend(value.to_le_bytes()),
            }
        }
        let next = match n + 1 < pages.len() {
            true => out.len() as u32 + 4,
            false => 0,
        };
        out.extend(next.to_le_bytes());
    }
    out
}

/// A valid stack of `pages` pages of `width × height` u8 pixels, all pages sharing the strip.
pub fn small_tiff(pages: usize, width: u32, height: u32) -> Vec<u8> {
    let strip: Vec<u8> = (0..width * height).map(|v| (v % 251) as u8).collect();
    tiff_bytes(&vec![Page::bytes(width, height); pages], &strip)
}

/// A version 1.0 `.npy` with dtype `descr`, `shape` as Python writes the tuple (`(3,)`,
/// `(2, 4)`) and `data` after the header (not checked against the shape: the header may lie).
pub fn npy(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out.extend(data);
    out
}

/// `shape` as Python writes the tuple.
pub fn shape_tuple(shape: &[u64]) -> String {
    let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
    match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    }
}

/// A version 1.0 `.npy` of little-endian float64 `values` with `shape` ([`npy`]).
pub fn npy_bytes(shape: &[u64], values: &[f64]) -> Vec<u8> {
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    npy("<f8", &shape_tuple(shape), &data)
}

/// Small OME-Zarr images written by `zarrs` itself (an independent writer of every codec
/// chain meshflow reads), for the reader's tests, its fuzzing and the hostile battery.
pub mod zarr {
    use serde_json::{json, Value};
    use std::path::{Path, PathBuf};
    use std::sync::Arc;
    use zarrs::array::Array;
    use zarrs::filesystem::FilesystemStore;

    /// (t, z, y, x) of every small image: chunks of (1, 2, 3, 4) leave partial ones at the edges.
    pub const SHAPE: [usize; 4] = [2, 5, 7, 6];

    /// The value at `(t, z, y, x)`: distinct, exact in `u16` and `f32`.
    pub fn value(t: usize, z: usize, y: usize, x: usize) -> u16 {
        (t * 1000 + z * 100 + y * 10 + x) as u16
    }

    /// Every value in C order.
    pub fn values() -> Vec<u16> {
        let [nt, nz, ny, nx] = SHAPE;
        let mut values = Vec::with_capacity(nt * nz * ny * nx);
        for t in 0..nt {
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        values.push(value(t, z, y, x));
                    }
                }
            }
        }
        values
    }

    fn bytes(endian: &str) -> Value {
        json!({"name": "bytes", "configuration": {"endian": endian}})
    }

    /// The chains written as Zarr v3: a name, the codecs, and the chunk grid's chunk shape.
    pub fn v3_chains() -> Vec<(&'static str, Value, [u64; 4])> {
        let chunk = [1, 2, 3, 4];
        let zstd = json!({"name": "zstd", "configuration": {"level": 3, "checksum": true}});
        let gzip = json!({"name": "gzip", "configuration": {"level": 5}});
        let crc = json!({"name": "crc32c"});
        let blosc = json!({"name": "blosc", "configuration": {"cname": "lz4", "clevel": 5,
            "shuffle": "shuffle", "typesize": 2, "blocksize": 0}});
        let shards = |location: &str, inner: Value| {
            json!([{"name": "sharding_indexed", "configuration": {"chunk_shape": chunk,
                "codecs": inner, "index_codecs": [bytes("little"), crc.clone()],
                "index_location": location}}])
        };
        vec![
            ("v3 bytes", json!([bytes("little")]), chunk),
            (
                "v3 big-endian gzip",
                json!([bytes("big"), gzip.clone()]),
                chunk,
            ),
            ("v3 zstd", json!([bytes("little"), zstd.clone()]), chunk),
            ("v3 blosc", json!([bytes("little"), blosc]), chunk),
            (
                "v3 transposed crc32c",
                json!([{"name": "transpose", "configuration": {"order": [0, 3, 1, 2]}},
                    bytes("little"), crc.clone()]),
                chunk,
            ),
            (
                "v3 shards",
                shards("end", json!([bytes("little"), zstd])),
                [1, 4, 6, 8],
            ),
            (
                "v3 shards indexed at the start",
                shards("start", json!([bytes("little"), gzip])),
                [1, 4, 6, 8],
            ),
        ]
    }

    /// The compressors written as Zarr v2 (`id`), with their order.
    pub fn v2_chains() -> Vec<(&'static str, Value, &'static str)> {
        vec![
            ("v2 F order", Value::Null, "F"),
            ("v2 gzip", json!({"id": "gzip", "level": 1}), "C"),
            ("v2 zstd", json!({"id": "zstd", "level": 1}), "C"),
            (
                "v2 blosc",
                json!({"id": "blosc", "cname": "zstd", "clevel": 3, "shuffle": 1, "blocksize": 0}),
                "C",
            ),
        ]
    }

    fn multiscales(version: &str) -> Value {
        let axis =
            |name: &str, kind: &str| json!({"name": name, "type": kind, "unit": "micrometer"});
        json!([{"version": version, "axes": [json!({"name": "t", "type": "time"}),
            axis("z", "space"), axis("y", "space"), axis("x", "space")],
            "datasets": [{"path": "0", "coordinateTransformations": [
                {"type": "scale", "scale": [1.0, 2.0, 0.5, 0.5]}]}]}])
    }

    fn write_json(file: &Path, value: &Value) {
        std::fs::create_dir_all(file.parent().unwrap()).unwrap();
        std::fs::write(file, serde_json::to_vec_pretty(value).unwrap()).unwrap();
    }

    /// Fills the array `0` of `image` (its metadata written) through `zarrs`.
    fn fill(image: &Path) {
        let store = Arc::new(FilesystemStore::new(image).unwrap());
        let array = Array::open(store, "/0").unwrap();
        array
            .store_array_subset(&array.subset_all(), &values()[..])
            .unwrap();
    }

    /// An NGFF 0.5 image at `image` of `codecs` (v3) and chunks of `chunk`, fill value 9.
    pub fn write_v3(image: &Path, codecs: &Value, chunk: [u64; 4]) -> PathBuf {
        let group = json!({"zarr_format": 3, "node_type": "group",
            "attributes": {"ome": {"version": "0.5", "multiscales": multiscales("0.5")}}});
        write_json(&image.join("zarr.json"), &group);
        let array = json!({"zarr_format": 3, "node_type": "array", "shape": SHAPE,
            "data_type": "uint16",
            "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunk}},
            "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
            "fill_value": 9, "codecs": codecs});
        write_json(&image.join("0/zarr.json"), &array);
        fill(image);
        image.to_path_buf()
    }

    /// An NGFF 0.4 image at `image` with `compressor` (v2) in `order`, fill value 9.
    pub fn write_v2(image: &Path, compressor: &Value, order: &str) -> PathBuf {
        write_json(&image.join(".zgroup"), &json!({"zarr_format": 2}));
        write_json(
            &image.join(".zattrs"),
            &json!({"multiscales": multiscales("0.4")}),
        );
        let array = json!({"zarr_format": 2, "shape": SHAPE, "chunks": [1, 2, 3, 4],
            "dtype": "<u2", "compressor": compressor, "fill_value": 9, "order": order,
            "filters": null, "dimension_separator": "/"});
        write_json(&image.join("0/.zarray"), &array);
        fill(image);
        image.to_path_buf()
    }

    /// Every chain, written under `dir`: its name and image.
    pub fn write_all(dir: &Path) -> Vec<(&'static str, PathBuf)> {
        let mut images = Vec::new();
        for (i, (name, codecs, chunk)) in v3_chains().into_iter().enumerate() {
            images.push((
                name,
                write_v3(&dir.join(format!("v3_{i}.zarr")), &codecs, chunk),
            ));
        }
        for (i, (name, compressor, order)) in v2_chains().into_iter().enumerate() {
            images.push((
                name,
                write_v2(&dir.join(format!("v2_{i}.zarr")), &compressor, order),
            ));
        }
        images
    }

    /// The files of `image` below its array, sorted: chunks and shards.
    pub fn chunk_files(image: &Path) -> Vec<PathBuf> {
        let mut files = Vec::new();
        let mut stack = vec![image.join("0")];
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).unwrap().flatten() {
                let path = entry.path();
                let name = entry.file_name().to_string_lossy().into_owned();
                if path.is_dir() {
                    stack.push(path);
                } else if !name.starts_with('.') && name != "zarr.json" {
                    files.push(path);
                }
            }
        }
        files.sort();
        files
    }
}
