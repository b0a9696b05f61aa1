//! glTF: bit-exact round trips of written animations, resampling, node transforms, textures,
//! and clear errors (naming the file) for broken or unsupported files.

use base64::Engine;
use meshflow::io::gltf_read::{read_gltf_animation, read_gltf_frame};
use meshflow::io::gltf_write::{write_glb_animation, AnimationFrame};
use meshflow::io::{IoError, LoadOptions};
use nalgebra::Vector3;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A 3 × 3 grid of vertices (8 triangles) moving over `times`, with grey colours; every
/// coordinate and colour is a multiple of 1/1024 below 16, so float32 holds them and their
/// differences exactly.
struct Animation {
    faces: Vec<[u32; 3]>,
    times: Vec<f64>,
    positions: Vec<Vec<Vector3<f64>>>,
    greys: Vec<Vec<f64>>,
}

impl Animation {
    fn grid(times: &[f64]) -> Self {
        let mut faces = Vec::new();
        for row in 0..2u32 {
            for col in 0..2u32 {
                let v = 3 * row + col;
                faces.push([v, v + 1, v + 4]);
                faces.push([v, v + 4, v + 3]);
            }
        }
        let positions = (0..times.len())
            .map(|k| {
                (0..9)
                    .map(|v| {
                        let (x, y) = ((v % 3) as f64, (v / 3) as f64);
                        let wobble = ((7 * v + 13 * k) % 50) as f64 / 1024.0;
                        Vector3::new(x + wobble, y - 3.0 * wobble, 0.5 * k as f64 + wobble)
                    })
                    .collect()
            })
            .collect();
        let greys = (0..times.len())
            .map(|k| {
                (0..9)
                    .map(|v| ((37 * v + 101 * k) % 1024) as f64 / 1024.0)
                    .collect()
            })
            .collect();
        Self {
            faces,
            times: times.to_vec(),
            positions,
            greys,
        }
    }

    fn write(&self, path: &Path) -> Result<(), IoError> {
        let colors: Vec<Vec<[f64; 3]>> = self
            .greys
            .iter()
            .map(|g| g.iter().map(|&g| [g; 3]).collect())
            .collect();
        let frames: Vec<AnimationFrame> = (0..self.times.len())
            .map(|k| AnimationFrame {
                time: self.times[k],
                positions: &self.positions[k],
                colors: &colors[k],
            })
            .collect();
        write_glb_animation(path, &self.faces, &frames)
    }
}

const TIMES: [f64; 4] = [0.0, 0.5, 1.25, 2.0];

/// Options that resample an animation at `fps` frames per unit of time.
fn at_fps(fps: f64) -> LoadOptions {
    LoadOptions {
        fps: Some(fps),
        ..LoadOptions::default()
    }
}

fn written(dir: &Path, animation: &Animation) -> PathBuf {
    let path = dir.join("moving.glb");
    animation.write(&path).unwrap();
    path
}

#[test]
fn written_animation_reads_back_bit_identically() {
    let dir = tempfile::tempdir().unwrap();
    let animation = Animation::grid(&TIMES);
    let path = written(dir.path(), &animation);
    let sequence = read_gltf_animation(&path, &LoadOptions::default()).unwrap();
    assert_eq!(sequence.faces, animation.faces);
    assert_eq!(sequence.positions, animation.positions);
    assert_eq!(greys(sequence.images.unwrap()), animation.greys);
    assert_eq!(sequence.times.unwrap(), TIMES);
    assert_eq!(sequence.sources, vec![path.clone(); TIMES.len()]);
    // The static reader sees frame 0.
    let frame = read_gltf_frame(&path).unwrap();
    assert_eq!(frame.positions, animation.positions[0]);
    assert_eq!(frame.image.unwrap().to_grey(), animation.greys[0]);
}

#[test]
fn written_file_is_a_valid_glb() {
    let dir = tempfile::tempdir().unwrap();
    let path = written(dir.path(), &Animation::grid(&TIMES));
    let bytes = std::fs::read(&path).unwrap();
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!((word(4), word(8)), (2, bytes.len()));
    let json_length = word(12);
    assert_eq!((&bytes[16..20], json_length % 4), (&b"JSON"[..], 0));
    let bin_at = 20 + json_length;
    assert_eq!(
        (&bytes[bin_at + 4..bin_at + 8], word(bin_at) % 4),
        (&b"BIN\0"[..], 0)
    );
    assert_eq!(bin_at + 8 + word(bin_at), bytes.len());
    let json: Value = serde_json::from_slice(&bytes[20..bin_at]).unwrap();
    let primitive = &json["meshes"][0]["primitives"][0];
    assert_eq!(
        primitive["targets"].as_array().unwrap().len(),
        TIMES.len() - 1
    );
    assert_eq!(
        json["animations"][0]["samplers"][0]["interpolation"],
        "LINEAR"
    );
    // The gltf crate's validation (POSITION min/max, indices, …) accepts it.
    let (document, _, _) = gltf::import(&path).unwrap();
    assert_eq!(document.meshes().len(), 1);
}

/// `(1 − s) a + s b` componentwise.
fn lerp(a: &Vector3<f64>, b: &Vector3<f64>, s: f64) -> Vector3<f64> {
    a * (1.0 - s) + b * s
}

#[test]
fn resampling_interpolates_the_frames_linearly() {
    let dir = tempfile::tempdir().unwrap();
    let animation = Animation::grid(&TIMES);
    let sequence = read_gltf_animation(&written(dir.path(), &animation), &at_fps(4.0)).unwrap();
    let times = sequence.times.unwrap();
    assert_eq!(times, (0..=8).map(|i| i as f64 / 4.0).collect::<Vec<_>>());
    let intensities = greys(sequence.images.unwrap());
    for (f, &t) in times.iter().enumerate() {
        let k = TIMES
            .partition_point(|&tk| tk <= t)
            .clamp(1, TIMES.len() - 1)
            - 1;
        let s = (t - TIMES[k]) / (TIMES[k + 1] - TIMES[k]);
        let (before, after) = (&animation.positions[k], &animation.positions[k + 1]);
        let (grey_before, grey_after) = (&animation.greys[k], &animation.greys[k + 1]);
        for (v, (position, grey)) in sequence.positions[f]
            .iter()
            .zip(&intensities[f])
            .enumerate()
        {
            let expected = lerp(&before[v], &after[v], s);
            assert!((position - expected).norm() < 1e-12, "t = {t}");
            let expected = (1.0 - s) * grey_before[v] + s * grey_after[v];
            assert!((grey - expected).abs() < 1e-12, "t = {t}");
        }
    }
}

#[test]
fn a_single_frame_is_a_static_mesh_without_animation() {
    let dir = tempfile::tempdir().unwrap();
    let animation = Animation::grid(&[3.0]);
    let path = written(dir.path(), &animation);
    let frame = read_gltf_frame(&path).unwrap();
    assert_eq!(frame.positions, animation.positions[0]);
    assert_eq!(frame.faces, animation.faces);
    let error = read_gltf_animation(&path, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(error.contains("moving.glb"), "{error}");
    assert!(error.contains("no morph-target animation"), "{error}");
}

#[test]
fn writer_rejects_inconsistent_frames() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.glb");
    let animation = Animation::grid(&TIMES);
    let positions = &animation.positions[0];
    let colors = vec![[0.5; 3]; 9];
    let good = AnimationFrame {
        time: 0.0,
        positions,
        colors: &colors,
    };
    let later = AnimationFrame { time: 1.0, ..good };
    let mut infinite = positions.clone();
    infinite[4].y = f64::INFINITY;
    let cases = [
        (vec![], "no frames"),
        (
            vec![
                good,
                AnimationFrame {
                    positions: &positions[..8],
                    ..later
                },
            ],
            "frame 1 has 8 positions",
        ),
        (
            vec![
                good,
                AnimationFrame {
                    colors: &[],
                    ..later
                },
            ],
            "frame 1 has 0 colours",
        ),
        (
            vec![
                good,
                AnimationFrame {
                    positions: &infinite,
                    ..later
                },
            ],
            "not a finite float32",
        ),
        (vec![good, good], "increase strictly"),
        // Distinct in f64, equal in float32.
        (
            vec![
                good,
                later,
                AnimationFrame {
                    time: 1.0 + 1e-12,
                    ..good
                },
            ],
            "increase strictly",
        ),
    ];
    for (frames, message) in cases {
        let error = write_glb_animation(&path, &animation.faces, &frames)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("bad.glb") && error.contains(message),
            "{error}"
        );
        assert!(!path.exists());
    }
    let error = write_glb_animation(&path, &[[0, 1, 9]], &[good]).unwrap_err();
    assert!(error.to_string().contains("face 0"), "{error}");
}

/// A hand-built glTF: accessors over one base64 data-URI buffer.
#[derive(Default)]
struct HandMade {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl HandMade {
    /// A float accessor of `kind` ("SCALAR", "VEC2", …), with min/max.
    fn floats(&mut self, kind: &str, values: &[f32]) -> usize {
        let width = width(kind);
        let column = |c: usize| values.iter().skip(c).step_by(width).copied();
        let min: Vec<f32> = (0..width)
            .map(|c| column(c).fold(f32::INFINITY, f32::min))
            .collect();
        let max: Vec<f32> = (0..width)
            .map(|c| column(c).fold(f32::NEG_INFINITY, f32::max))
            .collect();
        let bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessor(json!({
            "bufferView": view, "componentType": 5126, "count": values.len() / width,
            "type": kind, "min": min, "max": max,
        }))
    }

    /// An accessor of normalized `u8` components.
    fn normalized_u8(&mut self, kind: &str, values: &[u8]) -> usize {
        let view = self.view(values);
        self.accessor(json!({
            "bufferView": view, "componentType": 5121, "normalized": true,
            "count": values.len() / width(kind), "type": kind,
        }))
    }

    /// An index accessor of unsigned integers of `size` bytes (1, 2 or 4).
    fn indices(&mut self, values: &[u32], size: usize) -> usize {
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|x| x.to_le_bytes()[..size].to_vec())
            .collect();
        let component_type = [5121, 5123, 0, 5125][size - 1];
        let view = self.view(&bytes);
        self.accessor(json!({
            "bufferView": view, "componentType": component_type, "count": values.len(),
            "type": "SCALAR",
        }))
    }

    fn view(&mut self, bytes: &[u8]) -> usize {
        while self.bytes.len() % 4 != 0 {
            self.bytes.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bytes.len(), "byteLength": bytes.len(),
        }));
        self.bytes.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// The document `rest` (nodes, meshes, …) with this buffer, written to `dir/name`.
    fn write(self, dir: &Path, name: &str, mut rest: Value) -> PathBuf {
        let encoded = base64::engine::general_purpose::STANDARD.encode(&self.bytes);
        rest["asset"] = json!({ "version": "2.0" });
        rest["buffers"] = json!([{
            "byteLength": self.bytes.len(),
            "uri": format!("data:application/octet-stream;base64,{encoded}"),
        }]);
        rest["bufferViews"] = Value::Array(self.views);
        rest["accessors"] = Value::Array(self.accessors);
        let path = dir.join(name);
        std::fs::write(&path, rest.to_string()).unwrap();
        path
    }
}

fn width(kind: &str) -> usize {
    match kind {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        _ => 4,
    }
}

/// The corners (0, 0, 0), (1, 0, 0), (0, 1, 0).
const TRIANGLE: [f32; 9] = [0., 0., 0., 1., 0., 0., 0., 1., 0.];

/// One triangle on node 0 whose morph target 0 lifts vertex 0 by 1 in z, with the weight
/// animated over keyframes 0 and 1 by a sampler of `interpolation` with `outputs`.
fn lifted_triangle(interpolation: &str, outputs: &[f32]) -> (HandMade, Value) {
    let mut gltf = HandMade::default();
    let position = gltf.floats("VEC3", &TRIANGLE);
    let lift = gltf.floats("VEC3", &[0., 0., 1., 0., 0., 0., 0., 0., 0.]);
    let indices = gltf.indices(&[0, 1, 2], 2);
    let times = gltf.floats("SCALAR", &[0.0, 1.0]);
    let weights = gltf.floats("SCALAR", outputs);
    let document = json!({
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{
            "attributes": { "POSITION": position }, "indices": indices,
            "targets": [{ "POSITION": lift }],
        }] }],
        "animations": [{
            "samplers": [{ "input": times, "output": weights, "interpolation": interpolation }],
            "channels": [{ "sampler": 0, "target": { "node": 0, "path": "weights" } }],
        }],
    });
    (gltf, document)
}

/// [`lifted_triangle`] (LINEAR) on a scaled and translated child of a rotated and translated
/// parent node.
fn transformed_triangle(dir: &Path) -> PathBuf {
    let (gltf, mut document) = lifted_triangle("LINEAR", &[0.0, 1.0]);
    let half_turn = std::f32::consts::FRAC_1_SQRT_2;
    document["nodes"] = json!([
        { "children": [1], "translation": [10, 20, 30], "rotation": [0, 0, half_turn, half_turn] },
        { "mesh": 0, "translation": [1, 0, 0], "scale": [2, 3, 4] },
    ]);
    document["animations"][0]["channels"][0]["target"]["node"] = json!(1);
    gltf.write(dir, "transformed.gltf", document)
}

fn assert_close(actual: &[Vector3<f64>], expected: &[[f64; 3]]) {
    assert_eq!(actual.len(), expected.len());
    for (a, e) in actual.iter().zip(expected) {
        assert!((a - Vector3::from(*e)).norm() < 1e-6, "{a} != {e:?}");
    }
}

#[test]
fn node_transforms_of_the_node_and_its_parents_are_applied() {
    let dir = tempfile::tempdir().unwrap();
    let path = transformed_triangle(dir.path());
    // World = T(10, 20, 30) · R_z(90°) · T(1, 0, 0) · S(2, 3, 4),
    // where R_z maps (x, y, z) to (−y, x, z).
    let base = [[10.0, 21.0, 30.0], [10.0, 23.0, 30.0], [7.0, 21.0, 30.0]];
    let frame = read_gltf_frame(&path).unwrap();
    assert_close(&frame.positions, &base);
    assert_eq!(frame.faces, vec![[0, 1, 2]]);
    assert!(frame.image.is_none());
    let sequence = read_gltf_animation(&path, &LoadOptions::default()).unwrap();
    assert_eq!(sequence.times.unwrap(), [0.0, 1.0]);
    assert_close(&sequence.positions[0], &base);
    // The lift (0, 0, 1) is scaled by 4 in z.
    let lifted = [[10.0, 21.0, 34.0], base[1], base[2]];
    assert_close(&sequence.positions[1], &lifted);
    assert!(sequence.images.is_none());
}

/// A sampler's interpolation, its outputs and the weight they give at time `s`.
type InterpolationCase = (&'static str, &'static [f32], fn(f64) -> f64);

#[test]
fn step_and_cubic_spline_weights_follow_the_gltf_formulas() {
    // Keyframes at 0 and 1, so s = t. CUBICSPLINE outputs per keyframe: in-tangent, value,
    // out-tangent; here value 0 → 1 with out-tangent b₀ = 1 and in-tangent a₁ = 2.
    let cases: [InterpolationCase; 3] = [
        ("LINEAR", &[0.0, 1.0], |s| s),
        ("STEP", &[0.0, 1.0], |s| if s < 1.0 { 0.0 } else { 1.0 }),
        ("CUBICSPLINE", &[0.0, 0.0, 1.0, 2.0, 1.0, 0.0], |s| {
            let (s2, s3) = (s * s, s * s * s);
            (3.0 * s2 - 2.0 * s3) + (s3 - 2.0 * s2 + s) + 2.0 * (s3 - s2)
        }),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (interpolation, outputs, weight) in cases {
        let (gltf, document) = lifted_triangle(interpolation, outputs);
        let path = gltf.write(dir.path(), "lifted.gltf", document);
        let sequence = read_gltf_animation(&path, &at_fps(4.0)).unwrap();
        for (t, positions) in sequence.times.unwrap().iter().zip(&sequence.positions) {
            let lift = positions[0].z;
            assert!(
                (lift - weight(*t)).abs() < 1e-12,
                "{interpolation} at {t}: {lift}"
            );
        }
    }
}

/// Two triangles as two primitives: the first with `u8` indices and float grey colours, the
/// second without indices and, if `second_coloured`, with normalized `u8` RGBA colours.
fn two_primitives(dir: &Path, second_coloured: bool) -> PathBuf {
    let mut gltf = HandMade::default();
    let first = gltf.floats("VEC3", &TRIANGLE);
    let indices = gltf.indices(&[0, 1, 2], 1);
    let grey = gltf.floats("VEC3", &[0.25; 9]);
    let second = gltf.floats("VEC3", &[2., 0., 0., 3., 0., 0., 2., 1., 0.]);
    let mut attributes = json!({ "POSITION": second });
    if second_coloured {
        let rgba = [255, 255, 255, 0, 51, 51, 51, 255, 0, 0, 0, 255];
        attributes["COLOR_0"] = json!(gltf.normalized_u8("VEC4", &rgba));
    }
    gltf.write(
        dir,
        "two.gltf",
        json!({
            "nodes": [{ "mesh": 0 }],
            "meshes": [{ "primitives": [
                { "attributes": { "POSITION": first, "COLOR_0": grey }, "indices": indices },
                { "attributes": attributes },
            ] }],
        }),
    )
}

#[test]
fn primitives_are_merged_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let frame = read_gltf_frame(&two_primitives(dir.path(), true)).unwrap();
    assert_eq!(frame.faces, vec![[0, 1, 2], [3, 4, 5]]);
    assert_eq!(frame.positions[3], Vector3::new(2.0, 0.0, 0.0));
    // Normalized u8: c / 255, alpha ignored.
    assert_eq!(
        frame.image.unwrap().to_grey(),
        [0.25, 0.25, 0.25, 1.0, 0.2, 0.0]
    );
    // Grey values only if every primitive has them.
    let frame = read_gltf_frame(&two_primitives(dir.path(), false)).unwrap();
    assert_eq!(frame.positions.len(), 6);
    assert!(frame.image.is_none());
}

#[test]
fn a_static_frame_uses_the_default_weights_and_sparse_targets() {
    let dir = tempfile::tempdir().unwrap();
    let mut gltf = HandMade::default();
    let position = gltf.floats("VEC3", &TRIANGLE);
    // A sparse accessor without a buffer view: zeros except vertex 2, lifted by 5.
    let indices = gltf.view(&[2]);
    let values = gltf.view(&[0f32, 0.0, 5.0].map(f32::to_le_bytes).concat());
    let lift = gltf.accessor(json!({
        "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 5],
        "sparse": {
            "count": 1,
            "indices": { "bufferView": indices, "componentType": 5121 },
            "values": { "bufferView": values },
        },
    }));
    let path = gltf.write(
        dir.path(),
        "sparse.gltf",
        json!({
            "nodes": [{ "mesh": 0 }],
            "meshes": [{
                "primitives": [{
                    "attributes": { "POSITION": position },
                    "targets": [{ "POSITION": lift }],
                }],
                "weights": [0.5],
            }],
        }),
    );
    let frame = read_gltf_frame(&path).unwrap();
    let expected = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 2.5]];
    assert_eq!(frame.positions, expected.map(Vector3::from));
}

/// The 2 × 2 grey texture: top row 0, 100; bottom row 200, 255.
const TEXELS: [u8; 4] = [0, 100, 200, 255];

/// Two non-indexed triangles with texture coordinates, textured by a PNG next to the file;
/// morph target 0 shifts every coordinate by (0.5, 0).
fn textured_triangles(dir: &Path) -> PathBuf {
    image::GrayImage::from_raw(2, 2, TEXELS.to_vec())
        .unwrap()
        .save(dir.join("grey texture.png"))
        .unwrap();
    let mut gltf = HandMade::default();
    let position = gltf.floats(
        "VEC3",
        &[
            0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.,
        ],
    );
    let uv = gltf.floats(
        "VEC2",
        &[
            0.25, 0.25, 0.5, 0.5, 0.5, 0.25, 0.0, 0.25, 0.75, 0.75, 0.25, 0.5,
        ],
    );
    let shift = gltf.floats("VEC2", &[0.5, 0.0].repeat(6));
    let times = gltf.floats("SCALAR", &[0.0, 1.0]);
    let weights = gltf.floats("SCALAR", &[0.0, 1.0]);
    gltf.write(
        dir,
        "textured.gltf",
        json!({
            "nodes": [{ "mesh": 0 }],
            "meshes": [{ "primitives": [{
                "attributes": { "POSITION": position, "TEXCOORD_0": uv },
                "targets": [{ "TEXCOORD_0": shift }],
                "material": 0,
            }] }],
            "materials": [{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }],
            "textures": [{ "source": 0 }],
            "images": [{ "uri": "grey%20texture.png" }],
            "animations": [{
                "samplers": [{ "input": times, "output": weights }],
                "channels": [{ "sampler": 0, "target": { "node": 0, "path": "weights" } }],
            }],
        }),
    )
}

/// Bilinear interpolation by hand: texel `(x, y)` has its centre at `((x + ½)/2, (y + ½)/2)`.
fn by_hand(samples: &[[f64; 4]]) -> Vec<f64> {
    samples
        .iter()
        .map(|weights| {
            let sum: f64 = weights
                .iter()
                .zip(TEXELS)
                .map(|(w, t)| w * f64::from(t))
                .sum();
            sum / 255.0
        })
        .collect()
}

fn assert_all_close(actual: &[f64], expected: &[f64]) {
    assert_eq!(actual.len(), expected.len());
    for (a, e) in actual.iter().zip(expected) {
        assert!((a - e).abs() < 1e-6, "{actual:?} != {expected:?}");
    }
}

#[test]
fn textured_meshes_sample_the_base_colour_texture_bilinearly() {
    let dir = tempfile::tempdir().unwrap();
    let path = textured_triangles(dir.path());
    // Weights of texels (top-left, top-right, bottom-left, bottom-right) at each coordinate.
    let base = by_hand(&[
        [1.0, 0.0, 0.0, 0.0],     // (0.25, 0.25): the top-left centre
        [0.25, 0.25, 0.25, 0.25], // (0.5, 0.5): between all four
        [0.5, 0.5, 0.0, 0.0],     // (0.5, 0.25): between the top two
        [0.5, 0.5, 0.0, 0.0],     // (0, 0.25): wraps around to the right column
        [0.0, 0.0, 0.0, 1.0],     // (0.75, 0.75): the bottom-right centre
        [0.5, 0.0, 0.5, 0.0],     // (0.25, 0.5): between the left two
    ]);
    let shifted = by_hand(&[
        [0.0, 1.0, 0.0, 0.0],     // (0.75, 0.25)
        [0.25, 0.25, 0.25, 0.25], // (1.0, 0.5)
        [0.5, 0.5, 0.0, 0.0],     // (1.0, 0.25)
        [0.5, 0.5, 0.0, 0.0],     // (0.5, 0.25)
        [0.0, 0.0, 1.0, 0.0],     // (1.25, 0.75): wraps to the bottom-left centre
        [0.0, 0.5, 0.0, 0.5],     // (0.75, 0.5)
    ]);
    let frame = read_gltf_frame(&path).unwrap();
    assert_eq!(frame.faces, vec![[0, 1, 2], [3, 4, 5]]);
    assert_all_close(&frame.image.unwrap().to_grey(), &base);
    let intensities = read_gltf_animation(&path, &LoadOptions::default())
        .unwrap()
        .images
        .map(greys)
        .unwrap();
    assert_all_close(&intensities[0], &base);
    assert_all_close(&intensities[1], &shifted);
}

/// The error message of reading `path` both ways, which must agree.
fn read_error(path: &Path) -> String {
    let frame = read_gltf_frame(path).unwrap_err().to_string();
    let animation = read_gltf_animation(path, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert_eq!(frame, animation);
    frame
}

#[test]
fn broken_files_give_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.gltf");
    std::fs::write(&text, "hello").unwrap();
    let valid = std::fs::read(written(dir.path(), &Animation::grid(&TIMES))).unwrap();
    let truncated = dir.path().join("truncated.glb");
    std::fs::write(&truncated, &valid[..valid.len() / 2]).unwrap();
    let header_only = dir.path().join("header.glb");
    std::fs::write(&header_only, &valid[..10]).unwrap();
    let empty = HandMade::default().write(dir.path(), "empty.gltf", json!({}));
    let cases = [
        (text, "not a glTF file"),
        (truncated, "truncated GLB"),
        (header_only, "truncated GLB"),
        (empty, "no mesh"),
        (dir.path().join("missing.glb"), "No such file"),
    ];
    for (path, message) in cases {
        let error = read_error(&path);
        let name = path.file_name().unwrap().to_string_lossy();
        assert!(error.contains(&*name) && error.contains(message), "{error}");
    }
}

/// A one-triangle document whose primitive is patched by `edit`.
fn patched_triangle(
    dir: &Path,
    name: &str,
    edit: impl FnOnce(&mut Value, &mut HandMade),
) -> PathBuf {
    let mut gltf = HandMade::default();
    let position = gltf.floats("VEC3", &TRIANGLE);
    let mut primitive = json!({ "attributes": { "POSITION": position } });
    edit(&mut primitive, &mut gltf);
    gltf.write(
        dir,
        name,
        json!({ "nodes": [{ "mesh": 0 }], "meshes": [{ "primitives": [primitive] }] }),
    )
}

#[test]
fn unsupported_or_inconsistent_meshes_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases = [
        (
            patched_triangle(d, "points.gltf", |p, _| p["mode"] = json!(0)),
            "mesh 0, primitive 0: Points primitive",
        ),
        (
            patched_triangle(d, "index.gltf", |p, g| {
                p["indices"] = json!(g.indices(&[0, 1, 3], 4))
            }),
            "index 3 beyond the 3 vertices",
        ),
        (
            patched_triangle(d, "position.gltf", |p, _| {
                p["attributes"]["POSITION"] = json!(7)
            }),
            "POSITION refers to accessor 7",
        ),
        (
            patched_triangle(d, "stride.gltf", |_, g| g.views[0]["byteStride"] = json!(4)),
            "byte stride 4 below the element size 12",
        ),
        (
            patched_triangle(d, "short.gltf", |_, g| g.views[0]["byteLength"] = json!(24)),
            "exceed the 24 bytes",
        ),
        (
            patched_triangle(d, "colors.gltf", |p, g| {
                p["attributes"]["COLOR_0"] = json!(g.floats("VEC3", &[0.5; 6]))
            }),
            "COLOR_0 (accessor 1) has 2 elements, expected 3",
        ),
        (
            patched_triangle(d, "target.gltf", |p, g| {
                p["attributes"]["COLOR_0"] = json!(g.floats("VEC3", &[0.5; 9]));
                p["targets"] = json!([{ "COLOR_0": 9 }]);
            }),
            "COLOR_0 refers to accessor 9",
        ),
    ];
    for (path, message) in cases {
        let error = read_gltf_frame(&path).unwrap_err().to_string();
        let name = path.file_name().unwrap().to_string_lossy();
        assert!(error.contains(&*name) && error.contains(message), "{error}");
    }
    let static_mesh = patched_triangle(d, "static.gltf", |_, _| {});
    let error = read_gltf_animation(&static_mesh, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("static.gltf: the mesh has no morph targets"),
        "{error}"
    );
    assert!(
        error.contains("for one file per frame use a directory"),
        "{error}"
    );
}

#[test]
fn bad_frame_rates_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let path = written(dir.path(), &Animation::grid(&TIMES));
    for fps in [0.0, -2.0, f64::NAN] {
        let error = read_gltf_animation(&path, &at_fps(fps))
            .unwrap_err()
            .to_string();
        assert!(error.contains("frame rate must be positive"), "{error}");
    }
}

/// [`lifted_triangle`] with grey colours that never change and four animations: 0 "Idle" moves
/// another node, 1 "Lift" drives target 0 (vertex 0 up in z) over keyframes 0, 1, 2 "Slide"
/// drives target 1 (vertex 1 along x) over 0, 2, 3, and 3 (unnamed) drives target 0 over 5, 6.
fn clips_triangle(dir: &Path) -> PathBuf {
    let mut gltf = HandMade::default();
    let position = gltf.floats("VEC3", &TRIANGLE);
    let grey = gltf.floats("VEC3", &[0.25, 0.25, 0.25, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0]);
    let lift = gltf.floats("VEC3", &[0., 0., 1., 0., 0., 0., 0., 0., 0.]);
    let slide = gltf.floats("VEC3", &[0., 0., 0., 1., 0., 0., 0., 0., 0.]);
    let indices = gltf.indices(&[0, 1, 2], 2);
    let mut sampler = |times: &[f32], kind: &str, values: &[f32]| json!({ "input": gltf.floats("SCALAR", times), "output": gltf.floats(kind, values) });
    let idle = sampler(&[0.0, 1.0], "VEC3", &[0., 0., 0., 1., 1., 1.]);
    let lifting = sampler(&[0.0, 1.0], "SCALAR", &[0., 0., 1., 0.]);
    let sliding = sampler(&[0.0, 2.0, 3.0], "SCALAR", &[0., 0., 0., 1., 0., 2.]);
    let late = sampler(&[5.0, 6.0], "SCALAR", &[0.5, 0., 0., 0.]);
    let animation = |name: Option<&str>, sampler: Value, node: usize, path: &str| {
        let mut animation = json!({
            "samplers": [sampler],
            "channels": [{ "sampler": 0, "target": { "node": node, "path": path } }],
        });
        if let Some(name) = name {
            animation["name"] = json!(name);
        }
        animation
    };
    let document = json!({
        "nodes": [{ "mesh": 0 }, { "name": "lamp" }],
        "meshes": [{ "primitives": [{
            "attributes": { "POSITION": position, "COLOR_0": grey }, "indices": indices,
            "targets": [{ "POSITION": lift }, { "POSITION": slide }],
        }] }],
        "animations": [
            animation(Some("Idle"), idle, 1, "translation"),
            animation(Some("Lift"), lifting, 0, "weights"),
            animation(Some("Slide"), sliding, 0, "weights"),
            animation(None, late, 0, "weights"),
        ],
    });
    gltf.write(dir, "clips.gltf", document)
}

fn choosing(animation: &str) -> LoadOptions {
    LoadOptions {
        animation: Some(animation.to_string()),
        ..LoadOptions::default()
    }
}

#[test]
fn animations_are_chosen_by_name_or_index_else_the_first_that_moves_the_mesh() {
    use meshflow::io::gltf_read::AnimationClip;
    use meshflow::io::LoadWarning;
    let dir = tempfile::tempdir().unwrap();
    let path = clips_triangle(dir.path());
    let clip = |index: usize, name: Option<&str>, moves_mesh: bool| AnimationClip {
        index,
        name: name.map(str::to_string),
        moves_mesh,
    };
    let clips = vec![
        clip(0, Some("Idle"), false),
        clip(1, Some("Lift"), true),
        clip(2, Some("Slide"), true),
        clip(3, None, true),
    ];

    // None chosen: "Lift", with a warning that lists the four.
    let lifted = read_gltf_animation(&path, &LoadOptions::default()).unwrap();
    assert_eq!(lifted.times.as_deref(), Some([0.0, 1.0].as_slice()));
    assert_close(
        &lifted.positions[1],
        &[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    );
    let warning = LoadWarning::SeveralAnimations {
        file: path.clone(),
        clips: clips.clone(),
        chosen: clips[1].clone(),
    };
    assert_eq!(lifted.warnings, vec![warning.clone()]);
    assert_eq!(
        warning.to_string(),
        format!(
            "{}: 4 animations (0: \"Idle\" (no morph weights), 1: \"Lift\", 2: \"Slide\", \
             3: (unnamed)); read 1: \"Lift\", the first that moves the mesh; choose one with \
             --animation NAME|INDEX",
            path.display()
        )
    );

    // By name, and by index (the unnamed one): no warning.
    let slid = read_gltf_animation(&path, &choosing("Slide")).unwrap();
    assert_eq!(slid.times.as_deref(), Some([0.0, 2.0, 3.0].as_slice()));
    assert_close(
        &slid.positions[2],
        &[[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    );
    assert!(slid.warnings.is_empty());
    let late = read_gltf_animation(&path, &choosing("3")).unwrap();
    assert_eq!(late.times.as_deref(), Some([5.0, 6.0].as_slice()));
    assert_close(
        &late.positions[0],
        &[[0.0, 0.0, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    );

    let listing = "0: \"Idle\" (no morph weights), 1: \"Lift\", 2: \"Slide\", 3: (unnamed)";
    for (choice, message) in [
        (
            "Jump",
            format!("no animation \"Jump\": the file has {listing}"),
        ),
        ("4", format!("no animation \"4\": the file has {listing}")),
        (
            "Idle",
            format!(
                "animation 0: \"Idle\" (no morph weights) does not animate the morph weights \
                 of the mesh: the file has {listing}"
            ),
        ),
    ] {
        let error = read_gltf_animation(&path, &choosing(choice))
            .unwrap_err()
            .to_string();
        assert_eq!(error, format!("{}: {message}", path.display()));
    }
    // One animation: nothing to warn about.
    let (gltf, document) = lifted_triangle("LINEAR", &[0.0, 1.0]);
    let single = gltf.write(dir.path(), "single.gltf", document);
    assert!(read_gltf_animation(&single, &LoadOptions::default())
        .unwrap()
        .warnings
        .is_empty());
}

/// The grey value (luma) of every frame's colours.
fn greys(images: Vec<meshflow::io::VertexValues>) -> Vec<Vec<f64>> {
    images.iter().map(|v| v.to_grey()).collect()
}
