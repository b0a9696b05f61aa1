//! OME-Zarr images in (`meshflow::volume`, issue 40): NGFF 0.5 on Zarr v3 and NGFF 0.4 on
//! Zarr v2, written here by hand from the specifications (uncompressed chunks, so the test does
//! not lean on the reader's own writer), read frame by frame with their axes, channel,
//! resolution level, scale and translation; the same values as the same data in NPY, through
//! `sample` too; one-line errors for a channel or level that is not there.

mod common;
mod hostile_support;

use common::{meshflow_error, meshflow_ok, surface, write_npy};
use meshflow::volume::{read_volumes, VolumeOptions, VolumeStream, VoxelSizeSource};
use nalgebra::Vector3;
use serde_json::json;
use std::path::Path;

/// (t, c, z, y, x) of the finest level.
const SHAPE: [usize; 5] = [3, 2, 24, 24, 24];

/// The value at `(t, c, z, y, x)`: distinct everywhere, exact in `u16` and `f32`.
fn value(t: usize, c: usize, z: usize, y: usize, x: usize) -> u16 {
    (t * 7919 + c * 3001 + z * 577 + y * 31 + x) as u16 % 60000
}

/// Level 1 halves y and x: the value at its voxel is that of level 0 at `(2y, 2x)`.
fn shape_of(level: usize) -> [usize; 5] {
    let [t, c, z, y, x] = SHAPE;
    match level {
        0 => SHAPE,
        _ => [t, c, z, y / 2, x / 2],
    }
}

fn level_value(level: usize, [t, c, z, y, x]: [usize; 5]) -> u16 {
    let step = if level == 0 { 1 } else { 2 };
    value(t, c, z, step * y, step * x)
}

/// One (t, c) block of level `level` (a chunk), little-endian u16 in C order.
fn chunk_bytes(level: usize, t: usize, c: usize) -> Vec<u8> {
    let [_, _, nz, ny, nx] = shape_of(level);
    let mut bytes = Vec::with_capacity(2 * nz * ny * nx);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                bytes.extend(level_value(level, [t, c, z, y, x]).to_le_bytes());
            }
        }
    }
    bytes
}

/// The multiscales of both versions: micrometres, voxel 0.5 × 0.5 × 2 at level 0 shifted by
/// 10 in z, level 1 twice as coarse in y and x.
fn multiscales(version: &str) -> serde_json::Value {
    let axis = |name: &str, kind: &str| match kind {
        "space" => json!({"name": name, "type": kind, "unit": "micrometer"}),
        _ => json!({"name": name, "type": kind}),
    };
    json!([{
        "version": version,
        "axes": [axis("t", "time"), axis("c", "channel"), axis("z", "space"), axis("y", "space"), axis("x", "space")],
        "datasets": [
            {"path": "s0", "coordinateTransformations": [
                {"type": "scale", "scale": [1.0, 1.0, 2.0, 0.5, 0.5]},
                {"type": "translation", "translation": [0.0, 0.0, 10.0, 0.0, 0.0]}]},
            {"path": "s1", "coordinateTransformations": [
                {"type": "scale", "scale": [1.0, 1.0, 2.0, 1.0, 1.0]},
                {"type": "translation", "translation": [0.0, 0.0, 10.0, 0.25, 0.25]}]}
        ]
    }])
}

fn write_json(file: &Path, value: &serde_json::Value) {
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    std::fs::write(file, serde_json::to_vec_pretty(value).unwrap()).unwrap();
}

fn write_chunk(file: &Path, bytes: &[u8]) {
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    std::fs::write(file, bytes).unwrap();
}

/// NGFF 0.5: a Zarr v3 group with `attributes.ome`, arrays with the `bytes` codec, chunk keys
/// `c/t/c/0/0/0`.
fn write_v3(image: &Path) {
    let group = json!({"zarr_format": 3, "node_type": "group",
        "attributes": {"ome": {"version": "0.5", "multiscales": multiscales("0.5")}}});
    write_json(&image.join("zarr.json"), &group);
    for level in 0..2 {
        let shape = shape_of(level);
        let [_, _, z, y, x] = shape;
        let array = json!({
            "zarr_format": 3, "node_type": "array", "shape": shape, "data_type": "uint16",
            "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [1, 1, z, y, x]}},
            "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
            "fill_value": 0, "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}],
            "dimension_names": ["t", "c", "z", "y", "x"]
        });
        let dir = image.join(format!("s{level}"));
        write_json(&dir.join("zarr.json"), &array);
        for t in 0..shape[0] {
            for c in 0..shape[1] {
                let key = dir.join(format!("c/{t}/{c}/0/0/0"));
                write_chunk(&key, &chunk_bytes(level, t, c));
            }
        }
    }
}

/// NGFF 0.4: a Zarr v2 group with `.zattrs`, arrays without compressor, chunk keys `t/c/0/0/0`.
fn write_v2(image: &Path) {
    write_json(&image.join(".zgroup"), &json!({"zarr_format": 2}));
    write_json(
        &image.join(".zattrs"),
        &json!({"multiscales": multiscales("0.4")}),
    );
    for level in 0..2 {
        let shape = shape_of(level);
        let [_, _, z, y, x] = shape;
        let array = json!({
            "zarr_format": 2, "shape": shape, "chunks": [1, 1, z, y, x], "dtype": "<u2",
            "compressor": null, "fill_value": 0, "order": "C", "filters": null,
            "dimension_separator": "/"
        });
        let dir = image.join(format!("s{level}"));
        write_json(&dir.join(".zarray"), &array);
        for t in 0..shape[0] {
            for c in 0..shape[1] {
                write_chunk(
                    &dir.join(format!("{t}/{c}/0/0/0")),
                    &chunk_bytes(level, t, c),
                );
            }
        }
    }
}

fn options(channel: Option<usize>, level: usize) -> VolumeOptions {
    VolumeOptions {
        channel,
        resolution_level: level,
        ..VolumeOptions::default()
    }
}

/// Every frame of channel `c` at `level`: its values, voxel size, origin and the report.
fn check_read(image: &Path, c: usize, level: usize) {
    let read = read_volumes(image, &options(Some(c), level)).unwrap();
    let shape = shape_of(level);
    assert_eq!(read.volumes.len(), shape[0]);
    for (t, volume) in read.volumes.iter().enumerate() {
        assert_eq!(volume.shape(), [shape[2], shape[3], shape[4]]);
        let mut expected = Vec::new();
        for z in 0..shape[2] {
            for y in 0..shape[3] {
                for x in 0..shape[4] {
                    expected.push(f32::from(level_value(level, [t, c, z, y, x])));
                }
            }
        }
        assert_eq!(volume.values(), &expected[..], "frame {t}");
        let side = if level == 0 { 0.5 } else { 1.0 };
        assert_eq!(volume.voxel_size(), Vector3::new(side, side, 2.0));
        let shift = if level == 0 { 0.0 } else { 0.25 };
        assert_eq!(volume.origin(), Vector3::new(shift, shift, 10.0));
    }
    let VoxelSizeSource::File(said) = &read.voxel_size_source else {
        panic!("{:?}", read.voxel_size_source)
    };
    assert!(said.contains(&format!("level {level}")), "{said}");
    assert!(said.ends_with("micrometer"), "{said}");
}

#[test]
fn ngff_05_and_04_read_frame_by_frame_with_channel_level_and_placement() {
    let dir = tempfile::tempdir().unwrap();
    let (v3, v2) = (dir.path().join("v3.zarr"), dir.path().join("v2.zarr"));
    write_v3(&v3);
    write_v2(&v2);
    for image in [&v3, &v2] {
        for (c, level) in [(0, 0), (1, 0), (1, 1)] {
            check_read(image, c, level);
        }
        let stream = VolumeStream::open(image, &options(None, 0)).unwrap();
        assert_eq!(stream.n_frames(), 3);
        assert_eq!(meshflow::volume::count_volume_frames(image).unwrap(), 3);
        // A given voxel size wins over the metadata.
        let given = VolumeOptions {
            voxel_size: Some(Vector3::new(1.0, 1.0, 1.0)),
            ..VolumeOptions::default()
        };
        let read = read_volumes(image, &given).unwrap();
        assert_eq!(read.voxel_size_source, VoxelSizeSource::Given);
        assert_eq!(read.volumes[0].voxel_size(), Vector3::repeat(1.0));
    }
}

/// `sample` reads an OME-Zarr image as it reads the same channel written as NPY (with the
/// voxel size and origin the metadata gives): the same intensity to the last bit.
#[test]
fn sample_reads_ome_zarr_as_the_same_data_in_npy() {
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("image.zarr");
    write_v3(&image);
    // Channel 1 of the image, as (K, Z, Y, X) float32.
    let mut values = Vec::new();
    for t in 0..2 {
        for z in 0..SHAPE[2] {
            for y in 0..SHAPE[3] {
                for x in 0..SHAPE[4] {
                    values.push(f32::from(value(t, 1, z, y, x)));
                }
            }
        }
    }
    let npy = dir.path().join("channel1.npy");
    let [_, _, z, y, x] = SHAPE.map(|n| n as u64);
    write_npy(&npy, &[2, z, y, x], &values);
    // A sphere of radius 10 about the origin, inside the image's box once centred on it.
    let (_, seq) = surface(dir.path());
    let two_frames = dir.path().join("two.zarr");
    write_v3(&two_frames);
    let zarr_json = two_frames.join("s0/zarr.json");
    let mut array: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&zarr_json).unwrap()).unwrap();
    array["shape"][0] = json!(2);
    write_json(&zarr_json, &array);
    std::fs::remove_dir_all(two_frames.join("s1")).unwrap();
    let mut group: serde_json::Value =
        serde_json::from_slice(&std::fs::read(two_frames.join("zarr.json")).unwrap()).unwrap();
    group["attributes"]["ome"]["multiscales"][0]["datasets"]
        .as_array_mut()
        .unwrap()
        .truncate(1);
    write_json(&two_frames.join("zarr.json"), &group);
    let name = |p: &Path| p.to_str().unwrap().to_string();
    let (from_zarr, from_npy) = (dir.path().join("zarr.npy"), dir.path().join("npy.npy"));
    // Unit voxels about the sphere: the image's own translation (10 in z) is added to
    // --origin.
    meshflow_ok(&[
        "sample",
        &name(&two_frames),
        &name(&seq),
        "--channel",
        "1",
        "--voxel-size",
        "1,1,1",
        "--origin=-11.5,-11.5,-21.5",
        "--out",
        &name(&from_zarr),
    ]);
    meshflow_ok(&[
        "sample",
        &name(&npy),
        &name(&seq),
        "--voxel-size",
        "1,1,1",
        "--origin=-11.5,-11.5,-11.5",
        "--out",
        &name(&from_npy),
    ]);
    let read = |p: &Path| meshflow::format::read_npy(p).unwrap().data;
    assert_eq!(read(&from_zarr), read(&from_npy));
    // The vertices whose ±2-voxel shell stays inside the box (radius 10 + 2 > 11.5 leaves
    // some out) read the image, and never 0 there.
    let intensity = read(&from_zarr);
    let inside = intensity.iter().filter(|&&v| v > 0.0).count();
    assert!(
        inside > intensity.len() / 2,
        "{inside} of {}",
        intensity.len()
    );
    // What is not there is named.
    let args = |flag: &str, n: &str| {
        vec![
            "sample".to_string(),
            name(&two_frames),
            name(&seq),
            flag.into(),
            n.into(),
        ]
    };
    let run = |a: Vec<String>, expected: &str| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        meshflow_error(&a, expected)
    };
    run(
        args("--channel", "2"),
        "--channel 2: the image has channels 0 … 1",
    );
    run(
        args("--resolution-level", "1"),
        "--resolution-level 1: the image has levels 0 … 0",
    );
    let on_npy = vec![
        "sample".to_string(),
        name(&npy),
        name(&seq),
        "--channel".into(),
        "1".into(),
    ];
    run(
        on_npy,
        "--channel applies to OME-Zarr images and ImageJ hyperstacks",
    );
}

/// An image whose metadata names an array outside its directory is refused before anything
/// is opened there.
#[test]
fn a_dataset_path_outside_the_image_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("image.zarr");
    write_v3(&image);
    for path in ["../s0", "s0/../../s0", "/s0"] {
        let group_file = image.join("zarr.json");
        let mut group: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&group_file).unwrap()).unwrap();
        group["attributes"]["ome"]["multiscales"][0]["datasets"][0]["path"] = json!(path);
        write_json(&group_file, &group);
        let error = read_volumes(&image, &VolumeOptions::default()).unwrap_err();
        assert!(
            error.to_string().contains("leaves the image's directory"),
            "{path}: {error}"
        );
    }
}

/// The finest level as an ImageJ hyperstack, as Fiji and tifffile write one: `TZC` pages of
/// u16, `frames=`, `slices=`, `channels=` and the voxel size (0.5 × 0.5 × 2 µm) in the first
/// page's tags. `declared_frames` is what the metadata says.
fn write_hyperstack(file: &Path, declared_frames: usize) {
    use tiff::encoder::colortype::Gray16;
    use tiff::encoder::{Rational, TiffEncoder};
    use tiff::tags::Tag;
    let [nt, nc, nz, ny, nx] = SHAPE;
    let mut encoder = TiffEncoder::new(std::fs::File::create(file).unwrap()).unwrap();
    for t in 0..nt {
        for z in 0..nz {
            for c in 0..nc {
                let page: Vec<u16> = (0..ny * nx)
                    .map(|n| value(t, c, z, n / nx, n % nx))
                    .collect();
                let mut image = encoder.new_image::<Gray16>(nx as u32, ny as u32).unwrap();
                if (t, z, c) == (0, 0, 0) {
                    let description = format!(
                        "ImageJ=1.54f\nimages={}\nchannels={nc}\nslices={nz}\nframes={declared_frames}\nhyperstack=true\nmode=grayscale\nunit=micron\nspacing=2.0\nloop=false\n",
                        nt * nz * nc
                    );
                    let tags = image.encoder();
                    tags.write_tag(Tag::ImageDescription, description.as_str())
                        .unwrap();
                    let per_micron = || Rational { n: 2, d: 1 };
                    tags.write_tag(Tag::XResolution, per_micron()).unwrap();
                    tags.write_tag(Tag::YResolution, per_micron()).unwrap();
                }
                image.write_data(&page).unwrap();
            }
        }
    }
}

/// One recording as OME-Zarr, as an ImageJ hyperstack and as a `(K, Z, Y, X)` `.npy` of one
/// channel reads as the same volumes to the bit, whole or a frame at a time; the hyperstack
/// gives its voxel size and channels as the image does.
#[test]
fn ome_zarr_imagej_hyperstack_and_npy_read_as_the_same_volumes() {
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("image.zarr");
    write_v3(&image);
    let stack = dir.path().join("stack.tif");
    write_hyperstack(&stack, SHAPE[0]);
    let [nt, _, nz, ny, nx] = SHAPE;
    let channel1: Vec<f32> = (0..nt * nz * ny * nx)
        .map(|n| {
            let (t, z, y, x) = (n / (nz * ny * nx), n / (ny * nx) % nz, n / nx % ny, n % nx);
            f32::from(value(t, 1, z, y, x))
        })
        .collect();
    let npy = dir.path().join("channel1.npy");
    write_npy(&npy, &[nt, nz, ny, nx].map(|n| n as u64), &channel1);

    let placed = VolumeOptions {
        channel: Some(1),
        ..VolumeOptions::default()
    };
    let from_zarr = read_volumes(&image, &placed).unwrap();
    let from_tiff = read_volumes(&stack, &placed).unwrap();
    let from_npy = read_volumes(&npy, &VolumeOptions::default()).unwrap();
    assert_eq!(from_tiff.volumes.len(), nt);
    let streamed: Vec<_> = VolumeStream::open(&stack, &placed)
        .unwrap()
        .map(|read| read.unwrap().0)
        .collect();
    for t in 0..nt {
        let expected = &channel1[t * nz * ny * nx..][..nz * ny * nx];
        for (name, volume) in [
            ("zarr", &from_zarr.volumes[t]),
            ("tiff", &from_tiff.volumes[t]),
            ("tiff, streamed", &streamed[t]),
            ("npy", &from_npy.volumes[t]),
        ] {
            assert_eq!(volume.shape(), [nz, ny, nx], "{name}");
            assert_eq!(volume.values(), expected, "{name}, frame {t}");
        }
        assert_eq!(
            from_tiff.volumes[t].voxel_size(),
            Vector3::new(0.5, 0.5, 2.0)
        );
        assert_eq!(
            from_tiff.volumes[t].voxel_size(),
            from_zarr.volumes[t].voxel_size()
        );
    }
    // Channel 0 by default, as for OME-Zarr.
    let first = read_volumes(&stack, &VolumeOptions::default()).unwrap();
    assert_eq!(
        first.volumes[2].values()[5],
        f32::from(value(2, 0, 0, 0, 5))
    );

    let message = |path: &Path, options: &VolumeOptions| {
        let message = read_volumes(path, options).unwrap_err().to_string();
        assert!(message.contains(path.file_name().unwrap().to_str().unwrap()));
        message
    };
    let third = VolumeOptions {
        channel: Some(2),
        ..VolumeOptions::default()
    };
    let said = message(&stack, &third);
    assert!(
        said.contains("--channel 2: the hyperstack has channels 0 … 1"),
        "{said}"
    );
    let lying = dir.path().join("lying.tif");
    write_hyperstack(&lying, 5);
    let said = message(&lying, &VolumeOptions::default());
    assert!(
        said.contains("declares 5 frames × 24 slices × 2 channels = 240 pages, the file has 144"),
        "{said}"
    );
}

/// Every codec chain meshflow reads, written by `zarrs` (an independent writer): gzip, zstd,
/// blosc, crc32c, big-endian, transposed (v3) and F-order (v2) chunks, shards with their index
/// at either end, partial chunks at the edges; each reads back as written. A chunk removed
/// reads as the fill value and is counted; a frame none of whose chunks is stored is an error.
#[test]
fn every_codec_chain_written_by_zarrs_reads_back_as_written() {
    use hostile_support::zarr;
    let dir = tempfile::tempdir().unwrap();
    let [_, nz, ny, nx] = zarr::SHAPE;
    for (name, image) in zarr::write_all(dir.path()) {
        let read = read_volumes(&image, &VolumeOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(read.volumes.len(), 2, "{name}");
        for (t, volume) in read.volumes.iter().enumerate() {
            assert_eq!(volume.shape(), [nz, ny, nx], "{name}");
            let expected = &zarr::values()[t * nz * ny * nx..(t + 1) * nz * ny * nx];
            let expected: Vec<f32> = expected.iter().map(|&v| f32::from(v)).collect();
            assert_eq!(volume.values(), &expected[..], "{name}, frame {t}");
            assert_eq!(volume.voxel_size(), Vector3::new(0.5, 0.5, 2.0), "{name}");
        }
        // One chunk (or shard) of frame 0 removed: its voxels read as the fill value 9.
        let files = zarr::chunk_files(&image);
        let frame_of = |file: &Path| {
            let key = file
                .strip_prefix(image.join("0"))
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let key = key.strip_prefix("c/").unwrap_or(&key).to_string();
            key.split('/').next().unwrap().parse::<usize>().unwrap()
        };
        let first = files.iter().find(|f| frame_of(f) == 0).unwrap();
        std::fs::remove_file(first).unwrap();
        let mut stream = VolumeStream::open(&image, &VolumeOptions::default()).unwrap();
        let (volume, _) = stream.next().unwrap().unwrap();
        assert_eq!(volume.values()[0], 9.0, "{name}");
        let (missing, chunks) = stream.missing_chunks().unwrap();
        assert!(
            missing >= 1 && missing < chunks,
            "{name}: {missing} of {chunks}"
        );
        // Frame 1's chunks all removed: an error naming the frame, not a frame of nines.
        for file in files.iter().filter(|f| frame_of(f) == 1) {
            std::fs::remove_file(file).unwrap();
        }
        let error = read_volumes(&image, &VolumeOptions::default())
            .unwrap_err()
            .to_string();
        assert!(error.contains("frame 1: none of its"), "{name}: {error}");
    }
}
