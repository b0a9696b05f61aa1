//! A moving, coloured triangle mesh as an animated binary glTF 2.0 file (`.glb`).
//!
//! The file holds one node with one mesh of one triangle primitive (`u32` indices). Frame 0
//! is the base geometry (`POSITION`, and `COLOR_0` as float RGB); each further frame `k` is
//! morph target `k − 1`, holding the deltas `frame k − frame 0` of both attributes. One
//! animation drives the node's morph `weights` with LINEAR interpolation between one-hot
//! keyframes at the frame times `t_k`:
//!
//! ```text
//! keyframe 0:      w = (0, …, 0)
//! keyframe k ≥ 1:  w_j = 1 if j = k − 1, else 0
//! ```
//!
//! so for `t = (1 − s) t_k + s t_{k+1}` the mesh is `(1 − s) frame k + s frame k+1`: any
//! glTF viewer plays the sequence moving piecewise linearly between the frames.
//!
//! # Precision
//!
//! glTF stores float32. Positions, colours and times are rounded to `f32` (relative error
//! ≤ 2⁻²⁴ ≈ 6·10⁻⁸) and the deltas are computed in `f32` from the rounded values, so a reader
//! recovers frame `k` as `f32(p₀) + (f32(p_k) − f32(p₀))`. The subtraction is exact whenever
//! the difference is a float32, e.g. when `p_k` and `p₀` are within a factor 2 of each other
//! (Sterbenz's lemma) or both multiples of 2⁻¹⁰ below 2¹⁴ in magnitude; otherwise it adds
//! one rounding of the delta (relative error ≤ 2⁻²⁴ of the delta).

use super::glb;
use crate::format::{write_atomically, IoError};
use nalgebra::Vector3;
use serde_json::{json, Value};
use std::path::Path;

/// One frame of an animation to write: its time, vertex positions and RGB vertex colours
/// (one per vertex, normally in `[0, 1]`).
#[derive(Clone, Copy, Debug)]
pub struct AnimationFrame<'a> {
    pub time: f64,
    pub positions: &'a [Vector3<f64>],
    pub colors: &'a [[f64; 3]],
}

/// glTF `componentType` codes.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
/// glTF `bufferView.target` codes: vertex attributes and vertex indices.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
/// glTF `primitive.mode` of triangle lists.
const TRIANGLES: u32 = 4;

/// Writes `frames` (at least one, all with the same number of vertices, times strictly
/// increasing) of the mesh with triangles `faces` as one animated `.glb` file; see the module
/// documentation for the layout. A single frame gives a static mesh without animation (and
/// its time is not stored).
pub fn write_glb_animation(
    path: &Path,
    faces: &[[u32; 3]],
    frames: &[AnimationFrame],
) -> Result<(), IoError> {
    let (json, bin) = encode(faces, frames).map_err(|message| IoError::format(path, message))?;
    write_atomically(path, |w| glb::write(w, json.as_bytes(), &bin))
}

/// The glTF JSON and binary buffer of the animation, or what is wrong with the input.
fn encode(faces: &[[u32; 3]], frames: &[AnimationFrame]) -> Result<(String, Vec<u8>), String> {
    let (base, later) = frames
        .split_first()
        .ok_or("no frames to write: an animation needs at least one")?;
    let vertex_count = base.positions.len();
    check_connectivity(faces, vertex_count)?;
    for (k, frame) in frames.iter().enumerate() {
        check_vertex_count(frame, k, vertex_count)?;
    }
    let base_positions = frame_positions(base, 0)?;
    let base_colors = frame_colors(base, 0)?;

    let mut buffer = Buffer::default();
    let attributes = json!({
        "POSITION": buffer.push_floats(&base_positions, VEC3, Some(ARRAY_BUFFER)),
        "COLOR_0": buffer.push_floats(&base_colors, VEC3, Some(ARRAY_BUFFER)),
    });
    let indices = buffer.push_indices(faces);
    let mut targets = Vec::with_capacity(later.len());
    for (k, frame) in (1..).zip(later) {
        let position_deltas = deltas(&frame_positions(frame, k)?, &base_positions, k)?;
        let color_deltas = deltas(&frame_colors(frame, k)?, &base_colors, k)?;
        targets.push(json!({
            "POSITION": buffer.push_floats(&position_deltas, VEC3, Some(ARRAY_BUFFER)),
            "COLOR_0": buffer.push_floats(&color_deltas, VEC3, Some(ARRAY_BUFFER)),
        }));
    }
    let mut primitive = json!({
        "attributes": attributes,
        "indices": indices,
        "mode": TRIANGLES,
    });
    let mut mesh = json!({});
    let mut root = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("meshflow ", env!("CARGO_PKG_VERSION")),
        },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
    });
    if !targets.is_empty() {
        // glTF forbids empty `targets`, `weights` and `animations` arrays: a single frame is
        // a static mesh.
        mesh["weights"] = json!(vec![0.0; targets.len()]);
        root["animations"] = json!([weights_animation(&mut buffer, frames)?]);
        primitive["targets"] = Value::Array(targets);
    }
    mesh["primitives"] = json!([primitive]);
    root["meshes"] = json!([mesh]);
    root["buffers"] = json!([{ "byteLength": buffer.bytes.len() }]);
    root["bufferViews"] = Value::Array(buffer.views);
    root["accessors"] = Value::Array(buffer.accessors);
    Ok((root.to_string(), buffer.bytes))
}

/// The animation of node 0's morph weights: one-hot keyframes at the frame times.
fn weights_animation(buffer: &mut Buffer, frames: &[AnimationFrame]) -> Result<Value, String> {
    let times = to_f32(frames.iter().map(|f| f.time), || "the frame times".into())?;
    if let Some(k) = (1..times.len()).find(|&k| times[k] <= times[k - 1]) {
        return Err(format!(
            "frame times must increase strictly (in float32): frame {k} at {} follows {}",
            frames[k].time,
            frames[k - 1].time
        ));
    }
    let targets = frames.len() - 1;
    let mut weights = vec![0.0f32; frames.len() * targets];
    for k in 1..frames.len() {
        weights[k * targets + (k - 1)] = 1.0;
    }
    Ok(json!({
        "samplers": [{
            "input": buffer.push_floats(&times, SCALAR, None),
            "output": buffer.push_floats(&weights, SCALAR, None),
            "interpolation": "LINEAR",
        }],
        "channels": [{ "sampler": 0, "target": { "node": 0, "path": "weights" } }],
    }))
}

fn check_connectivity(faces: &[[u32; 3]], vertex_count: usize) -> Result<(), String> {
    if vertex_count == 0 || faces.is_empty() {
        return Err("the mesh has no vertices or no triangles".into());
    }
    crate::mesh::check_index_range(faces, vertex_count).map_err(|e| e.to_string())
}

/// Frame `k`'s positions as flat float32 (x, y, z per vertex).
fn frame_positions(frame: &AnimationFrame, k: usize) -> Result<Vec<f32>, String> {
    let values = frame.positions.iter().flat_map(|p| [p.x, p.y, p.z]);
    to_f32(values, || format!("the positions of frame {k}"))
}

/// Checks that frame `k` has as many positions and colours as frame 0 has vertices.
fn check_vertex_count(frame: &AnimationFrame, k: usize, vertex_count: usize) -> Result<(), String> {
    for (what, count) in [
        ("positions", frame.positions.len()),
        ("colours", frame.colors.len()),
    ] {
        if count != vertex_count {
            return Err(format!(
                "frame {k} has {count} {what}, frame 0 has {vertex_count} vertices"
            ));
        }
    }
    Ok(())
}

/// Frame `k`'s colours as flat float32 (r, g, b per vertex).
fn frame_colors(frame: &AnimationFrame, k: usize) -> Result<Vec<f32>, String> {
    let values = frame.colors.iter().flatten().copied();
    to_f32(values, || format!("the colours of frame {k}"))
}

/// Rounds to float32, rejecting values that are not finite there.
fn to_f32(
    values: impl Iterator<Item = f64>,
    what: impl Fn() -> String,
) -> Result<Vec<f32>, String> {
    values
        .map(|x| {
            let rounded = x as f32;
            if rounded.is_finite() {
                Ok(rounded)
            } else {
                Err(format!("{} contain {x}, not a finite float32", what()))
            }
        })
        .collect()
}

/// `frame − base` in float32 (see the module documentation on precision).
fn deltas(frame: &[f32], base: &[f32], k: usize) -> Result<Vec<f32>, String> {
    let deltas = frame.iter().zip(base).map(|(a, b)| f64::from(a - b));
    to_f32(deltas, || {
        format!("the differences of frame {k} to frame 0")
    })
}

/// Accessor types: glTF name and number of components.
type ElementType = (&'static str, usize);
const SCALAR: ElementType = ("SCALAR", 1);
const VEC3: ElementType = ("VEC3", 3);

/// The binary buffer under construction, with its buffer views and accessors (one view per
/// accessor, all 4-byte aligned since every component is 4 bytes).
#[derive(Default)]
struct Buffer {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    /// Appends a float accessor with its `min`/`max` (which glTF requires of positions and
    /// animation inputs); returns its index.
    fn push_floats(
        &mut self,
        values: &[f32],
        (name, width): ElementType,
        target: Option<u32>,
    ) -> usize {
        let (min, max) = bounds(values, width);
        let view = self.push_view(values.iter().flat_map(|x| x.to_le_bytes()), target);
        self.push_accessor(json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": values.len() / width,
            "type": name,
            "min": min,
            "max": max,
        }))
    }

    /// Appends the triangle indices as an unsigned-int accessor; returns its index.
    fn push_indices(&mut self, faces: &[[u32; 3]]) -> usize {
        let bytes = faces.iter().flatten().flat_map(|i| i.to_le_bytes());
        let view = self.push_view(bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.push_accessor(json!({
            "bufferView": view,
            "componentType": UNSIGNED_INT,
            "count": 3 * faces.len(),
            "type": "SCALAR",
        }))
    }

    fn push_view(&mut self, bytes: impl Iterator<Item = u8>, target: Option<u32>) -> usize {
        let offset = self.bytes.len();
        self.bytes.extend(bytes);
        let mut view = json!({
            "buffer": 0,
            "byteOffset": offset,
            "byteLength": self.bytes.len() - offset,
        });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.views.push(view);
        self.views.len() - 1
    }

    fn push_accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}

/// Componentwise minimum and maximum of elements of `width` components.
fn bounds(values: &[f32], width: usize) -> (Vec<f32>, Vec<f32>) {
    let mut min = vec![f32::INFINITY; width];
    let mut max = vec![f32::NEG_INFINITY; width];
    for element in values.chunks_exact(width) {
        for (c, &x) in element.iter().enumerate() {
            min[c] = min[c].min(x);
            max[c] = max[c].max(x);
        }
    }
    (min, max)
}
