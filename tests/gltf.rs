//! glTF: bit-exact round trips of written animations, resampling, node transforms, textures,
//! and clear errors (naming the file) for broken or unsupported files.

use base64::Engine;
use meshflow::format::gltf::{read_gltf_animation, read_gltf_frame, AnimationOptions};
use meshflow::format::gltf::{write_glb_animation, AnimationFrame};
use meshflow::format::IoError;
use nalgebra::{Matrix4, Quaternion, UnitQuaternion, Vector3, Vector4};
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
fn at_fps(fps: f64) -> AnimationOptions {
    AnimationOptions {
        fps: Some(fps),
        ..AnimationOptions::default()
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
    let sequence = read_gltf_animation(&path, &AnimationOptions::default()).unwrap();
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
    let error = read_gltf_animation(&path, &AnimationOptions::default())
        .unwrap_err()
        .to_string();
    assert!(error.contains("moving.glb"), "{error}");
    assert!(error.contains("no animation moves the mesh"), "{error}");
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
        self.integers("SCALAR", values, size)
    }

    /// An accessor of `kind` of unsigned integers of `size` bytes (1, 2 or 4).
    fn integers(&mut self, kind: &str, values: &[u32], size: usize) -> usize {
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|x| x.to_le_bytes()[..size].to_vec())
            .collect();
        let component_type = [5121, 5123, 0, 5125][size - 1];
        let view = self.view(&bytes);
        self.accessor(json!({
            "bufferView": view, "componentType": component_type,
            "count": values.len() / width(kind), "type": kind,
        }))
    }

    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
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
        "MAT4" => 16,
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
    let sequence = read_gltf_animation(&path, &AnimationOptions::default()).unwrap();
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
    let intensities = read_gltf_animation(&path, &AnimationOptions::default())
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
    let animation = read_gltf_animation(path, &AnimationOptions::default())
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
    let error = read_gltf_animation(&static_mesh, &AnimationOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("static.gltf: no animation moves the mesh"),
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

fn choosing(animation: &str) -> AnimationOptions {
    AnimationOptions {
        animation: Some(animation.to_string()),
        ..AnimationOptions::default()
    }
}

#[test]
fn animations_are_chosen_by_name_or_index_else_the_first_that_moves_the_mesh() {
    use meshflow::format::gltf::{AnimationClip, ImplicitClip};
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
    let lifted = read_gltf_animation(&path, &AnimationOptions::default()).unwrap();
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
    let implicit = ImplicitClip {
        clips: clips.clone(),
        chosen: clips[1].clone(),
    };
    assert_eq!(lifted.implicit_clip, Some(implicit));
    assert_eq!(
        warning.to_string(),
        format!(
            "{}: 4 animations (0: \"Idle\" (does not move the mesh), 1: \"Lift\", 2: \"Slide\", \
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
    assert!(slid.implicit_clip.is_none());
    let late = read_gltf_animation(&path, &choosing("3")).unwrap();
    assert_eq!(late.times.as_deref(), Some([5.0, 6.0].as_slice()));
    assert_close(
        &late.positions[0],
        &[[0.0, 0.0, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    );

    let listing = "0: \"Idle\" (does not move the mesh), 1: \"Lift\", 2: \"Slide\", 3: (unnamed)";
    for (choice, message) in [
        (
            "Jump",
            format!("no animation \"Jump\": the file has {listing}"),
        ),
        ("4", format!("no animation \"4\": the file has {listing}")),
        (
            "Idle",
            format!("animation 0: \"Idle\" does not move the mesh: the file has {listing}"),
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
    assert!(read_gltf_animation(&single, &AnimationOptions::default())
        .unwrap()
        .implicit_clip
        .is_none());
}

/// The grey value (luma) of every frame's colours.
fn greys(images: Vec<meshflow::io::VertexValues>) -> Vec<Vec<f64>> {
    images.iter().map(|v| v.to_grey()).collect()
}

// Skinned meshes: a strip of 2 × 6 vertices bent by two joints.

/// The strip's triangles: vertex `6 row + col` is at `(col, row, 0)`.
fn strip_faces() -> Vec<u32> {
    (0..5)
        .flat_map(|c| [c, c + 1, c + 7, c, c + 7, c + 6])
        .collect()
}

/// The skin weights (hip, knee) of the strip's columns as stored: they blend across the
/// middle, and column 2's sum to 0.8 (normalized when read).
const COLUMN_WEIGHTS: [[f32; 2]; 6] = [
    [1.0, 0.0],
    [1.0, 0.0],
    [0.6, 0.2],
    [0.25, 0.75],
    [0.0, 1.0],
    [0.0, 1.0],
];

// The rig: "root" (node 0) → "hip" (node 1, joint 0) → "knee" (node 2, joint 1); the strip is
// on node 3, whose own translation a skinned mesh ignores.
const ROOT_TRANSLATION: [f32; 3] = [1.0, 2.0, 3.0];
/// 0.4 rad about x.
const ROOT_ROTATION: [f32; 4] = [0.198_669_33, 0.0, 0.0, 0.980_066_6];
const ROOT_SCALE: [f32; 3] = [2.0, 2.0, 2.0];
/// 0.1 rad about z.
const HIP_ROTATION: [f32; 4] = [0.0, 0.0, 0.049_979_17, 0.998_750_3];
const KNEE_TRANSLATION: [f32; 3] = [2.5, 0.0, 0.0];
/// Column-major, as glTF stores matrices; neither is the inverse of the bind pose, and the
/// second is not even a rigid motion.
const INVERSE_BINDS: [[f32; 16]; 2] = [
    [
        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., -0.5, -0.5, 0., 1.,
    ],
    [
        0.98, -0.2, 0., 0., 0.2, 0.98, 0., 0., 0., 0., 1.1, 0., -2.4, -0.1, 0.05, 1.,
    ],
];

// Animation 1, "Bend".
/// Hip rotation, LINEAR (slerp): 0.3 and 1.2 rad about z, then 2 rad about (0, 1, 1)/√2
/// stored with the opposite sign (the shorter arc turns it back).
const HIP_TIMES: [f32; 3] = [0.0, 1.0, 2.0];
const HIP_ROTATIONS: [[f32; 4]; 3] = [
    [0.0, 0.0, 0.149_438_13, 0.988_771_1],
    [0.0, 0.0, 0.564_642_5, 0.825_335_6],
    [0.0, -0.595_009_8, -0.595_009_8, -0.540_302_3],
];
/// Knee rotation, CUBICSPLINE: per keyframe in-tangent, value (−0.2, then 0.9 rad about z),
/// out-tangent.
const KNEE_TIMES: [f32; 2] = [0.0, 1.5];
const KNEE_ROTATIONS: [[f32; 4]; 6] = [
    [0.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, -0.099_833_42, 0.995_004_2],
    [0.0, 0.1, 0.3, -0.05],
    [0.1, 0.0, 0.2, 0.0],
    [0.0, 0.0, 0.434_965_53, 0.900_447_1],
    [0.0, 0.0, 0.0, 0.0],
];
/// Knee translation, STEP.
const STEP_TIMES: [f32; 3] = [0.0, 0.5, 2.0];
const KNEE_TRANSLATIONS: [[f32; 3]; 3] = [[2.5, 0.0, 0.0], [2.5, 0.5, 0.0], [3.0, 0.0, 0.25]];
/// Root translation and scale, LINEAR; also the morph weight (0 to 1) of the morphed strip.
const ROOT_TIMES: [f32; 2] = [0.0, 2.0];
const ROOT_TRANSLATIONS: [[f32; 3]; 2] = [[1.0, 2.0, 3.0], [0.0, -1.0, 1.0]];
const ROOT_SCALES: [[f32; 3]; 2] = [[2.0, 2.0, 2.0], [1.0, 1.5, 2.5]];
/// The union of the keyframe times above; "Bend" also moves the strip's node at 0.25 and 3,
/// which does not count.
const BEND_TIMES: [f64; 5] = [0.0, 0.5, 1.0, 1.5, 2.0];

/// A stored weight as the morphed strip stores it: normalized `u8`.
fn as_u8(weight: f32) -> u8 {
    (weight * 255.0).round() as u8
}

/// The skinned strip with animations 0 "Idle" (moves only the strip's node) and 1 "Bend".
/// With `morphed`, a morph target lifts column `c` by `c/8` in z, its weight animated by
/// "Bend" too, and the skin weights are normalized `u8` in two sets: `JOINTS_0`/`WEIGHTS_0`
/// for the hip (`u8` joints), `JOINTS_1`/`WEIGHTS_1` for the knee (`u16` joints).
fn skinned_strip(morphed: bool) -> (HandMade, Value) {
    let mut gltf = HandMade::default();
    let corners: Vec<f32> = (0..12)
        .flat_map(|v| [(v % 6) as f32, (v / 6) as f32, 0.0])
        .collect();
    let position = gltf.floats("VEC3", &corners);
    let indices = gltf.indices(&strip_faces(), 1);
    let mut primitive = json!({ "attributes": { "POSITION": position }, "indices": indices });
    let attributes = &mut primitive["attributes"];
    let per_vertex = |weight: &dyn Fn([f32; 2]) -> [f32; 4]| -> Vec<f32> {
        (0..12)
            .flat_map(|v| weight(COLUMN_WEIGHTS[v % 6]))
            .collect()
    };
    if morphed {
        let set = |joint: usize| -> Vec<u8> {
            per_vertex(&|w| [w[joint], 0.0, 0.0, 0.0])
                .into_iter()
                .map(as_u8)
                .collect()
        };
        attributes["JOINTS_0"] = json!(gltf.integers("VEC4", &[0; 48], 1));
        attributes["WEIGHTS_0"] = json!(gltf.normalized_u8("VEC4", &set(0)));
        attributes["JOINTS_1"] = json!(gltf.integers("VEC4", &[1, 0, 0, 0].repeat(12), 2));
        attributes["WEIGHTS_1"] = json!(gltf.normalized_u8("VEC4", &set(1)));
        let lift: Vec<f32> = (0..12)
            .flat_map(|v| [0.0, 0.0, (v % 6) as f32 / 8.0])
            .collect();
        primitive["targets"] = json!([{ "POSITION": gltf.floats("VEC3", &lift) }]);
    } else {
        attributes["JOINTS_0"] = json!(gltf.integers("VEC4", &[0, 1, 0, 0].repeat(12), 1));
        let weights = per_vertex(&|[hip, knee]| [hip, knee, 0.0, 0.0]);
        attributes["WEIGHTS_0"] = json!(gltf.floats("VEC4", &weights));
    }
    let inverse_binds = gltf.floats("MAT4", &INVERSE_BINDS.concat());
    let mut sampler = |times: &[f32], kind: &str, values: &[f32], interpolation: &str| {
        json!({
            "input": gltf.floats("SCALAR", times), "output": gltf.floats(kind, values),
            "interpolation": interpolation,
        })
    };
    let mut bend = vec![
        sampler(&HIP_TIMES, "VEC4", &HIP_ROTATIONS.concat(), "LINEAR"),
        sampler(&KNEE_TIMES, "VEC4", &KNEE_ROTATIONS.concat(), "CUBICSPLINE"),
        sampler(&STEP_TIMES, "VEC3", &KNEE_TRANSLATIONS.concat(), "STEP"),
        sampler(&ROOT_TIMES, "VEC3", &ROOT_TRANSLATIONS.concat(), "LINEAR"),
        sampler(&ROOT_TIMES, "VEC3", &ROOT_SCALES.concat(), "LINEAR"),
        sampler(&[0.25, 3.0], "VEC3", &[0., 0., 0., 5., 5., 5.], "LINEAR"),
    ];
    let idle = sampler(&[0.0, 1.0], "VEC3", &[0., 0., 0., 1., 1., 1.], "LINEAR");
    let mut targets = vec![
        (1, "rotation"),
        (2, "rotation"),
        (2, "translation"),
        (0, "translation"),
        (0, "scale"),
        (3, "translation"),
    ];
    if morphed {
        bend.push(sampler(&ROOT_TIMES, "SCALAR", &[0.0, 1.0], "LINEAR"));
        targets.push((3, "weights"));
    }
    let channels: Vec<Value> = targets
        .iter()
        .enumerate()
        .map(|(i, (node, path))| json!({ "sampler": i, "target": { "node": node, "path": path } }))
        .collect();
    let document = json!({
        "scenes": [{ "nodes": [0, 3] }],
        "nodes": [
            {
                "name": "root", "children": [1], "translation": ROOT_TRANSLATION,
                "rotation": ROOT_ROTATION, "scale": ROOT_SCALE,
            },
            { "name": "hip", "children": [2], "rotation": HIP_ROTATION },
            { "name": "knee", "translation": KNEE_TRANSLATION },
            { "name": "strip", "mesh": 0, "skin": 0, "translation": [100, 0, 0] },
        ],
        "meshes": [{ "primitives": [primitive] }],
        "skins": [{ "joints": [1, 2], "inverseBindMatrices": inverse_binds }],
        "animations": [
            {
                "name": "Idle", "samplers": [idle],
                "channels": [{ "sampler": 0, "target": { "node": 3, "path": "translation" } }],
            },
            { "name": "Bend", "samplers": bend, "channels": channels },
        ],
    });
    (gltf, document)
}

fn vec3(v: [f32; 3]) -> Vector3<f64> {
    Vector3::from(v.map(f64::from))
}

/// A stored quaternion `(x, y, z, w)`, normalized.
fn rotation(q: [f32; 4]) -> UnitQuaternion<f64> {
    let [x, y, z, w] = q.map(f64::from);
    UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z))
}

/// `T · R · S`.
fn trs(
    translation: Vector3<f64>,
    rotation: UnitQuaternion<f64>,
    scale: Vector3<f64>,
) -> Matrix4<f64> {
    Matrix4::new_translation(&translation)
        * rotation.to_homogeneous()
        * Matrix4::new_nonuniform_scaling(&scale)
}

/// The keyframe interval `[t_k, t_{k+1}]` of `t` and the fraction `s` of it (0 before the
/// first keyframe, 1 after the last).
fn segment(times: &[f32], t: f64) -> (usize, f64) {
    let k = times
        .iter()
        .rposition(|&tk| f64::from(tk) <= t)
        .unwrap_or(0)
        .min(times.len() - 2);
    let (t0, t1) = (f64::from(times[k]), f64::from(times[k + 1]));
    (k, ((t - t0) / (t1 - t0)).clamp(0.0, 1.0))
}

/// The knee's CUBICSPLINE rotation at `t` (one interval), normalized.
fn knee_rotation(t: f64) -> UnitQuaternion<f64> {
    let (_, s) = segment(&KNEE_TIMES, t);
    let dt = f64::from(KNEE_TIMES[1] - KNEE_TIMES[0]);
    let key = |i: usize| Vector4::from(KNEE_ROTATIONS[i].map(f64::from));
    let (v0, out0, in1, v1) = (key(1), key(2), key(3), key(4));
    let (s2, s3) = (s * s, s * s * s);
    let q = v0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + out0 * (dt * (s3 - 2.0 * s2 + s))
        + v1 * (-2.0 * s3 + 3.0 * s2)
        + in1 * (dt * (s3 - s2));
    UnitQuaternion::new_normalize(Quaternion::from(q))
}

/// The strip by an independent linear-blend skinning: joint matrices built with nalgebra
/// straight from the stored values, at time `t` of "Bend" (`None`: the nodes' own transforms,
/// no morph).
fn bent_strip(t: Option<f64>, morphed: bool) -> Vec<[f64; 3]> {
    let one = Vector3::repeat(1.0);
    let (root_translation, root_scale, hip_rotation, knee_translation, knee, morph) = match t {
        None => (
            vec3(ROOT_TRANSLATION),
            vec3(ROOT_SCALE),
            rotation(HIP_ROTATION),
            vec3(KNEE_TRANSLATION),
            UnitQuaternion::identity(),
            0.0,
        ),
        Some(t) => {
            let (k, s) = segment(&HIP_TIMES, t);
            let hip = rotation(HIP_ROTATIONS[k]).slerp(&rotation(HIP_ROTATIONS[k + 1]), s);
            let (k, s) = segment(&STEP_TIMES, t);
            let knee_translation = vec3(KNEE_TRANSLATIONS[if s < 1.0 { k } else { k + 1 }]);
            let (_, s) = segment(&ROOT_TIMES, t);
            let lerp = |[a, b]: [[f32; 3]; 2]| vec3(a) * (1.0 - s) + vec3(b) * s;
            let (translation, scale) = (lerp(ROOT_TRANSLATIONS), lerp(ROOT_SCALES));
            (
                translation,
                scale,
                hip,
                knee_translation,
                knee_rotation(t),
                s,
            )
        }
    };
    let root = trs(root_translation, rotation(ROOT_ROTATION), root_scale);
    let hip = root * trs(Vector3::zeros(), hip_rotation, one);
    let knee = hip * trs(knee_translation, knee, one);
    let inverse_bind = |j: usize| Matrix4::from_column_slice(&INVERSE_BINDS[j].map(f64::from));
    let joints = [hip * inverse_bind(0), knee * inverse_bind(1)];
    (0..12)
        .map(|v| {
            let column = v % 6;
            let lift = if morphed {
                morph * column as f64 / 8.0
            } else {
                0.0
            };
            let stored = |w: f32| match morphed {
                true => f64::from(as_u8(w)) / 255.0,
                false => f64::from(w),
            };
            let [hip, knee] = COLUMN_WEIGHTS[column].map(stored);
            let blended = (joints[0] * hip + joints[1] * knee) / (hip + knee);
            let p = blended * Vector4::new(column as f64, (v / 6) as f64, lift, 1.0);
            [p.x, p.y, p.z]
        })
        .collect()
}

#[test]
fn skinned_meshes_follow_linear_blend_skinning_at_keyframes_and_between() {
    let dir = tempfile::tempdir().unwrap();
    let (gltf, document) = skinned_strip(false);
    let path = gltf.write(dir.path(), "strip.gltf", document);
    let frame = read_gltf_frame(&path).unwrap();
    assert_close(&frame.positions, &bent_strip(None, false));
    assert_eq!(
        frame.faces,
        strip_faces()
            .chunks(3)
            .map(|f| [f[0], f[1], f[2]])
            .collect::<Vec<_>>()
    );
    let sequence = read_gltf_animation(&path, &AnimationOptions::default()).unwrap();
    assert_eq!(sequence.times.as_deref(), Some(BEND_TIMES.as_slice()));
    for (&t, positions) in BEND_TIMES.iter().zip(&sequence.positions) {
        assert_close(positions, &bent_strip(Some(t), false));
    }
    let implicit = sequence.implicit_clip.expect("two animations, none named");
    let clips: Vec<String> = implicit.clips.iter().map(ToString::to_string).collect();
    assert_eq!(
        clips,
        ["0: \"Idle\" (does not move the mesh)", "1: \"Bend\""]
    );
    assert_eq!(implicit.chosen.to_string(), "1: \"Bend\"");
    // Between keyframes: slerp, the cubic spline, the step and the linear root.
    let resampled = read_gltf_animation(&path, &at_fps(8.0)).unwrap();
    let times = resampled.times.unwrap();
    assert_eq!(times, (0..=16).map(|i| i as f64 / 8.0).collect::<Vec<_>>());
    for (&t, positions) in times.iter().zip(&resampled.positions) {
        assert_close(positions, &bent_strip(Some(t), false));
    }
    // The bend is real: the tip moves far, relative to the hip, between the keyframes.
    let tip = |f: usize| Vector3::from(bent_strip(Some(times[f]), false)[5]);
    assert!((tip(4) - tip(12)).norm() > 1.0);
}

#[test]
fn morph_targets_are_applied_before_skinning() {
    let dir = tempfile::tempdir().unwrap();
    let (gltf, document) = skinned_strip(true);
    let path = gltf.write(dir.path(), "morphed.gltf", document);
    assert_close(
        &read_gltf_frame(&path).unwrap().positions,
        &bent_strip(None, true),
    );
    for options in [AnimationOptions::default(), at_fps(8.0)] {
        let sequence = read_gltf_animation(&path, &options).unwrap();
        for (&t, positions) in sequence.times.unwrap().iter().zip(&sequence.positions) {
            assert_close(positions, &bent_strip(Some(t), true));
        }
    }
}

#[test]
fn animated_node_transforms_move_a_mesh_without_skin() {
    // transformed_triangle, its parent also turning from 90° to 180° about z over [0, 2].
    let dir = tempfile::tempdir().unwrap();
    let (mut gltf, mut document) = lifted_triangle("LINEAR", &[0.0, 1.0]);
    let half_turn = std::f32::consts::FRAC_1_SQRT_2;
    let turn = json!({
        "input": gltf.floats("SCALAR", &[0.0, 2.0]),
        "output": gltf.floats("VEC4", &[0., 0., half_turn, half_turn, 0., 0., 1., 0.]),
    });
    document["nodes"] = json!([
        { "children": [1], "translation": [10, 20, 30], "rotation": [0, 0, half_turn, half_turn] },
        { "mesh": 0, "translation": [1, 0, 0], "scale": [2, 3, 4] },
    ]);
    let animation = &mut document["animations"][0];
    animation["channels"][0]["target"]["node"] = json!(1);
    animation["samplers"].as_array_mut().unwrap().push(turn);
    animation["channels"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "sampler": 1, "target": { "node": 0, "path": "rotation" } }));
    let path = gltf.write(dir.path(), "turning.gltf", document);
    let sequence = read_gltf_animation(&path, &AnimationOptions::default()).unwrap();
    assert_eq!(sequence.times.as_deref(), Some([0.0, 1.0, 2.0].as_slice()));
    for (&t, positions) in [0.0, 1.0, 2.0].iter().zip(&sequence.positions) {
        let angle = std::f64::consts::FRAC_PI_2 * (1.0 + t / 2.0);
        let parent = trs(
            Vector3::new(10.0, 20.0, 30.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle),
            Vector3::repeat(1.0),
        );
        let world = parent
            * trs(
                Vector3::x(),
                UnitQuaternion::identity(),
                Vector3::new(2.0, 3.0, 4.0),
            );
        let lift = t.min(1.0);
        let expected: Vec<[f64; 3]> = [[0.0, 0.0, lift], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
            .iter()
            .map(|&[x, y, z]| {
                let p = world * Vector4::new(x, y, z, 1.0);
                [p.x, p.y, p.z]
            })
            .collect();
        assert_close(positions, &expected);
    }
}

/// [`skinned_strip`] (not morphed) changed by `edit`, written to `dir/name`.
fn broken_strip(dir: &Path, name: &str, edit: impl FnOnce(&mut Value, &mut HandMade)) -> PathBuf {
    let (mut gltf, mut document) = skinned_strip(false);
    edit(&mut document, &mut gltf);
    gltf.write(dir, name, document)
}

/// The per-vertex weights of the strip (hip, knee) with vertex `v`'s replaced by `weights`.
fn strip_weights(v: usize, weights: [f32; 4]) -> Vec<f32> {
    let mut all: Vec<f32> = (0..12)
        .flat_map(|u| {
            let [hip, knee] = COLUMN_WEIGHTS[u % 6];
            [hip, knee, 0.0, 0.0]
        })
        .collect();
    all[4 * v..4 * v + 4].copy_from_slice(&weights);
    all
}

#[test]
fn broken_skins_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fn attributes(document: &mut Value) -> &mut Value {
        &mut document["meshes"][0]["primitives"][0]["attributes"]
    }
    let prefix = "mesh 0, primitive 0";
    // Accessors 0 POSITION, 1 indices, 2 JOINTS_0, 3 WEIGHTS_0, 4 inverseBindMatrices, then
    // the animations' and those the edits add (from 19).
    let cases = [
        (
            broken_strip(d, "joint.gltf", |doc, g| {
                let mut joints = [0, 1, 0, 0].repeat(12);
                joints[4 * 5 + 1] = 2;
                attributes(doc)["JOINTS_0"] = json!(g.integers("VEC4", &joints, 1));
            }),
            format!(
                "{prefix}: JOINTS_0 (accessor 19): vertex 5 names joint 2, but the skin has 2 \
                 joints"
            ),
        ),
        (
            broken_strip(d, "zero.gltf", |doc, g| {
                let weights = strip_weights(7, [0.0; 4]);
                attributes(doc)["WEIGHTS_0"] = json!(g.floats("VEC4", &weights));
            }),
            format!("{prefix}: vertex 7 has no joint: its skin weights are all zero"),
        ),
        (
            broken_strip(d, "negative.gltf", |doc, g| {
                let weights = strip_weights(3, [1.5, -0.5, 0.0, 0.0]);
                attributes(doc)["WEIGHTS_0"] = json!(g.floats("VEC4", &weights));
            }),
            format!("{prefix}: WEIGHTS_0 (accessor 19): vertex 3 has the negative weight -0.5"),
        ),
        (
            broken_strip(d, "infinite.gltf", |doc, g| {
                let weights = strip_weights(4, [f32::INFINITY, 0.0, 0.0, 0.0]);
                attributes(doc)["WEIGHTS_0"] = json!(g.floats("VEC4", &weights));
            }),
            format!("{prefix}, WEIGHTS_0 (accessor 19): element 4 is not finite"),
        ),
        (
            broken_strip(d, "float.gltf", |doc, g| {
                let joints = [0., 1., 0., 0.].repeat(12);
                attributes(doc)["JOINTS_0"] = json!(g.floats("VEC4", &joints));
            }),
            format!(
                "{prefix}: JOINTS_0 (accessor 19) has components of type F32; joint indices \
                 are unsigned bytes or shorts"
            ),
        ),
        (
            broken_strip(d, "unweighted.gltf", |doc, _| {
                attributes(doc).as_object_mut().unwrap().remove("WEIGHTS_0");
            }),
            format!("{prefix}: JOINTS_0 without WEIGHTS_0"),
        ),
        (
            broken_strip(d, "unjointed.gltf", |doc, _| {
                attributes(doc).as_object_mut().unwrap().remove("WEIGHTS_0");
                attributes(doc).as_object_mut().unwrap().remove("JOINTS_0");
            }),
            format!("{prefix}: its node has a skin, but it has no JOINTS_0 and WEIGHTS_0"),
        ),
        (
            broken_strip(d, "binds.gltf", |doc, g| {
                doc["skins"][0]["inverseBindMatrices"] = json!(g.floats("MAT4", &INVERSE_BINDS[0]));
            }),
            "skin 0, inverseBindMatrices (accessor 19) has 1 elements, expected 2".to_string(),
        ),
        (
            broken_strip(d, "jointless.gltf", |doc, _| {
                doc["skins"][0] = json!({ "joints": [] });
            }),
            "skin 0 has no joints".to_string(),
        ),
    ];
    for (path, message) in cases {
        let error = read_error(&path);
        assert_eq!(error, format!("{}: {message}", path.display()));
    }
}

#[test]
fn animations_of_skins_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fn bend(document: &mut Value) -> &mut Value {
        &mut document["animations"][1]
    }
    let cases = [
        (
            broken_strip(d, "matrix.gltf", |doc, _| {
                let matrix = [
                    1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 2.5, 0., 0., 1.,
                ];
                doc["nodes"][2] = json!({ "name": "knee", "matrix": matrix });
            }),
            "animation 1 animates the rotation of node 2 (\"knee\"), which has a matrix; glTF \
             animates only nodes given by translation, rotation and scale",
        ),
        (
            broken_strip(d, "twice.gltf", |doc, _| {
                let channel = bend(doc)["channels"][0].clone();
                bend(doc)["channels"].as_array_mut().unwrap().push(channel);
            }),
            "animation 1 animates the rotation of node 1 (\"hip\") twice",
        ),
        (
            broken_strip(d, "unmorphed.gltf", |doc, g| {
                let times = g.floats("SCALAR", &[0.0, 1.0]);
                let sampler = json!({ "input": times, "output": g.floats("SCALAR", &[0.0, 1.0]) });
                bend(doc)["samplers"].as_array_mut().unwrap().push(sampler);
                let channel = json!({ "sampler": 6, "target": { "node": 3, "path": "weights" } });
                bend(doc)["channels"].as_array_mut().unwrap().push(channel);
            }),
            "animation 1 animates the weights of node 3 (\"strip\"), whose mesh has no morph \
             targets",
        ),
        (
            broken_strip(d, "null.gltf", |doc, g| {
                let mut rotations = HIP_ROTATIONS.concat();
                rotations[4..8].fill(0.0);
                bend(doc)["samplers"][0]["output"] = json!(g.floats("VEC4", &rotations));
            }),
            "animation 1, sampler 0, output: the rotation of keyframe 1 is the zero quaternion",
        ),
        (
            broken_strip(d, "still.gltf", |doc, _| {
                doc["animations"] = json!([doc["animations"][0].clone()]);
            }),
            "no animation moves the mesh (its morph weights, skin joints or node transforms); \
             for one file per frame use a directory",
        ),
    ];
    for (path, message) in cases {
        let error = read_gltf_animation(&path, &AnimationOptions::default())
            .unwrap_err()
            .to_string();
        assert_eq!(error, format!("{}: {message}", path.display()));
    }
}
