//! A glTF file in memory: the validated document, its raw JSON, its buffers, and decoding of
//! accessors and images with every offset and count checked against the data.
//!
//! The `gltf` crate parses and validates the JSON; the binary data are decoded here rather
//! than with its readers, which assume well-formed layouts (a short byte stride or a zero
//! count panics there) and which cannot see morph-target `COLOR_0`/`TEXCOORD_n` deltas (the
//! crate's JSON model keeps only POSITION, NORMAL and TANGENT of morph targets).
//!
//! Accessor components decode as the glTF specification says (§3.11): floats as stored,
//! normalized `u8`/`u16` to `c / (2ⁿ − 1)`, normalized `i8`/`i16` to `max(c / (2ⁿ⁻¹ − 1), −1)`,
//! other integers to their value.

use super::glb;
use crate::format::{resolve_linked, IoError, Texture};
use base64::Engine;
use gltf::accessor::DataType;
use gltf::buffer::View;
use gltf::{Accessor, Document};
use serde_json::Value;
use std::borrow::Cow;
use std::path::Path;

/// Bytes of memory per byte of JSON text while it is held parsed twice (as a
/// `serde_json::Value` and as the `gltf` crate's document): measured 78 on a 1.4 MB chain of
/// 60,000 nodes (113 MB resident).
const PARSED_JSON_BYTES_PER_BYTE: u64 = 96;

/// A loaded glTF file.
pub(super) struct GltfFile<'p> {
    pub path: &'p Path,
    pub document: Document,
    /// The JSON as written, for what the `gltf` crate's model drops.
    raw: Value,
    buffers: Vec<Vec<u8>>,
}

impl<'p> GltfFile<'p> {
    /// Reads and validates `path` (`.gltf` JSON or `.glb` binary) and loads its buffers.
    pub fn open(path: &'p Path) -> Result<Self, IoError> {
        let error = |message: String| IoError::format(path, message);
        let bytes = crate::format::read_file(path)?;
        let (json, blob) = if glb::is_glb(&bytes) {
            let chunks = glb::split(&bytes).map_err(error)?;
            (chunks.json, chunks.bin)
        } else {
            (&bytes[..], None)
        };
        let parsed = format!("the glTF JSON of {} bytes, parsed twice", json.len());
        crate::limits::check_items(parsed, json.len() as u64, PARSED_JSON_BYTES_PER_BYTE)
            .map_err(|e| IoError::too_large(path, e))?;
        let raw: Value = serde_json::from_slice(json).map_err(|e| {
            error(format!(
                "not a glTF file: neither binary glTF nor JSON ({e})"
            ))
        })?;
        check_position_indices(&raw).map_err(error)?;
        check_animation_targets(&raw).map_err(error)?;
        let document = gltf::Gltf::from_slice(json)
            .map_err(|e| error(format!("not valid glTF 2.0: {e}")))?
            .document;
        let mut file = Self {
            path,
            document,
            raw,
            buffers: Vec::new(),
        };
        file.buffers = file.load_buffers(blob)?;
        Ok(file)
    }

    /// An error about this file.
    pub fn error(&self, message: impl Into<String>) -> IoError {
        IoError::format(self.path, message)
    }

    /// The buffers, each cut to its `byteLength`: many buffers may name the same file or the
    /// GLB BIN chunk, so only the declared lengths, checked together against the memory limit
    /// first, are held.
    fn load_buffers(&self, blob: Option<&[u8]>) -> Result<Vec<Vec<u8>>, IoError> {
        let declared = self
            .document
            .buffers()
            .fold(0u64, |sum, b| sum.saturating_add(b.length() as u64));
        let count = self.document.buffers().len();
        crate::limits::check_declared(format!("the byteLength of its {count} buffers"), declared)
            .map_err(|e| IoError::too_large(self.path, e))?;
        self.document
            .buffers()
            .map(|buffer| {
                let label = format!("buffer {}", buffer.index());
                let data = match buffer.source() {
                    gltf::buffer::Source::Bin => {
                        let bin = blob.ok_or_else(|| {
                            self.error(format!("{label} has no uri and there is no GLB BIN chunk"))
                        })?;
                        bin[..bin.len().min(buffer.length())].to_vec()
                    }
                    gltf::buffer::Source::Uri(uri) => {
                        self.read_uri(uri, &label, buffer.length() as u64)?
                    }
                };
                if data.len() < buffer.length() {
                    return Err(self.error(format!(
                        "{label} has {} bytes, its byteLength says {}",
                        data.len(),
                        buffer.length()
                    )));
                }
                Ok(data)
            })
            .collect()
    }

    /// The bytes a URI refers to, at most `most` of a referenced file: a base64 `data:` URI
    /// or a path relative to the file.
    fn read_uri(&self, uri: &str, label: &str, most: u64) -> Result<Vec<u8>, IoError> {
        if let Some(data) = uri.strip_prefix("data:") {
            let (_, encoded) = data.split_once(";base64,").ok_or_else(|| {
                self.error(format!("{label}: only base64 data URIs are supported"))
            })?;
            return base64::engine::general_purpose::STANDARD
                .decode(encoded)
                .map_err(|e| self.error(format!("{label}: invalid base64 data ({e})")));
        }
        if uri.contains(':') {
            return Err(self.error(format!(
                "{label}: unsupported URI {uri:?} (only data: URIs and relative paths)"
            )));
        }
        let relative = percent_decode(uri)
            .ok_or_else(|| self.error(format!("{label}: invalid URI {uri:?}")))?;
        let referenced = resolve_linked(self.path, &format!("{label} uri"), uri, &relative)?;
        read_prefix(&referenced, most)
    }

    /// The elements of `accessor` (whose type must have one of `widths` components), first `N`
    /// components of each, decoded to `f64`. With `expected_count` the accessor must have
    /// that many elements. `label` names the data in errors.
    pub fn read_elements<const N: usize>(
        &self,
        accessor: &Accessor,
        label: &str,
        widths: &[usize],
        expected_count: Option<usize>,
    ) -> Result<Vec<[f64; N]>, IoError> {
        debug_assert!(widths.iter().all(|&w| w >= N), "keeping {N} of {widths:?}");
        let label = format!("{label} (accessor {})", accessor.index());
        let width = accessor.dimensions().multiplicity();
        if !widths.contains(&width) {
            return Err(self.error(format!(
                "{label} has type {:?}, expected {} components",
                accessor.dimensions(),
                widths
                    .iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
                    .join(" or ")
            )));
        }
        if accessor.view().is_none() && expected_count.is_none() {
            // Nothing but the count bounds an accessor without data: it must be one we know.
            return Err(self.error(format!("{label} has no bufferView")));
        }
        if let Some(expected) = expected_count.filter(|&n| n != accessor.count()) {
            return Err(self.error(format!(
                "{label} has {} elements, expected {expected}",
                accessor.count()
            )));
        }
        // Decoding holds `width` f64 components per element, the result `N` more.
        let element_bytes = 8 * (width + N) as u64;
        crate::limits::check_items(
            format!("{label} with count {}", accessor.count()),
            accessor.count() as u64,
            element_bytes,
        )
        .map_err(|e| IoError::too_large(self.path, e))?;
        let values = self
            .decode(accessor, width)
            .map_err(|message| self.error(format!("{label}: {message}")))?;
        Ok(values
            .chunks_exact(width)
            .map(|element| std::array::from_fn(|c| element[c]))
            .collect())
    }

    /// All components of `accessor` (elements of `width` components), dense then sparse.
    fn decode(&self, accessor: &Accessor, width: usize) -> Result<Vec<f64>, String> {
        let count = accessor.count();
        if count == 0 {
            return Err("no elements".into());
        }
        let layout = Layout::of(accessor, width);
        let mut values = match accessor.view() {
            Some(view) => {
                let bytes = self.view_bytes(&view)?;
                let stride = view.stride().unwrap_or(layout.element_size);
                layout.decode(elements(
                    bytes,
                    accessor.offset(),
                    stride,
                    layout.element_size,
                    count,
                )?)
            }
            // Without a buffer view the base values are zeros (sparse accessors).
            None if accessor.sparse().is_some() => vec![0.0; count * width],
            None => return Err("neither a bufferView nor sparse values".into()),
        };
        if let Some(sparse) = accessor.sparse() {
            self.apply_sparse(&sparse, &layout, &mut values, count)?;
        }
        match values.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(format!("element {} is not finite", i / width)),
            None => Ok(values),
        }
    }

    /// Overwrites the elements a sparse accessor lists.
    fn apply_sparse(
        &self,
        sparse: &gltf::accessor::sparse::Sparse,
        layout: &Layout,
        values: &mut [f64],
        count: usize,
    ) -> Result<(), String> {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(format!("sparse count {n} outside 1..={count}"));
        }
        let (indices, replacements) = (sparse.indices(), sparse.values());
        let index_size = indices.index_type().size();
        let index_bytes = self.view_bytes(&indices.view())?;
        let index_elements = elements(index_bytes, indices.offset(), index_size, index_size, n)?;
        let value_bytes = self.view_bytes(&replacements.view())?;
        let value_elements = elements(
            value_bytes,
            replacements.offset(),
            layout.element_size,
            layout.element_size,
            n,
        )?;
        let width = layout.width;
        for (index, element) in index_elements.zip(value_elements) {
            let i = unsigned(index) as usize;
            let target = values
                .get_mut(i * width..(i + 1) * width)
                .ok_or_else(|| format!("sparse index {i} beyond the {count} elements"))?;
            target.copy_from_slice(&layout.decode(std::iter::once(element)));
        }
        Ok(())
    }

    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, view: &View) -> Result<&[u8], String> {
        let buffer = self
            .buffers
            .get(view.buffer().index())
            .ok_or("missing buffer")?;
        view.offset()
            .checked_add(view.length())
            .and_then(|end| buffer.get(view.offset()..end))
            .ok_or_else(|| {
                format!(
                    "buffer view {} ({} bytes at {}) exceeds its buffer of {} bytes",
                    view.index(),
                    view.length(),
                    view.offset(),
                    buffer.len()
                )
            })
    }

    /// The accessor of attribute `name` (`"POSITION"`, `"COLOR_0"`, …) of morph target `target`
    /// of a primitive, if the target has it. Read from the raw JSON: the `gltf` crate keeps
    /// only POSITION, NORMAL and TANGENT of morph targets.
    pub fn target_accessor(
        &self,
        primitive: &gltf::Primitive,
        mesh: usize,
        target: usize,
        name: &str,
    ) -> Result<Option<Accessor<'_>>, IoError> {
        let index =
            &self.raw["meshes"][mesh]["primitives"][primitive.index()]["targets"][target][name];
        if index.is_null() {
            return Ok(None);
        }
        index
            .as_u64()
            .and_then(|i| self.document.accessors().nth(usize::try_from(i).ok()?))
            .map(Some)
            .ok_or_else(|| {
                self.error(format!(
                    "mesh {mesh}, primitive {}, morph target {target}: {name} refers to \
                     accessor {index}, which does not exist",
                    primitive.index()
                ))
            })
    }

    /// Decodes an image (PNG or JPEG, embedded or referenced) to grey values.
    pub fn texture(&self, image: gltf::Image) -> Result<Texture, IoError> {
        let label = format!("image {}", image.index());
        let bytes: Cow<[u8]> = match image.source() {
            gltf::image::Source::View { view, .. } => Cow::Borrowed(
                self.view_bytes(&view)
                    .map_err(|message| self.error(format!("{label}: {message}")))?,
            ),
            gltf::image::Source::Uri { uri, .. } => {
                Cow::Owned(self.read_uri(uri, &label, crate::limits::memory_limit())?)
            }
        };
        Texture::decode(&bytes).map_err(|message| self.error(format!("{label}: {message}")))
    }
}

/// Component type, size and normalization of an accessor's elements.
struct Layout {
    data_type: DataType,
    normalized: bool,
    width: usize,
    element_size: usize,
}

impl Layout {
    fn of(accessor: &Accessor, width: usize) -> Self {
        let data_type = accessor.data_type();
        Self {
            data_type,
            normalized: accessor.normalized(),
            width,
            element_size: width * data_type.size(),
        }
    }

    /// The components of the given elements (each `element_size` bytes).
    fn decode<'a>(&self, elements: impl Iterator<Item = &'a [u8]>) -> Vec<f64> {
        let size = self.data_type.size();
        elements
            .flat_map(|element| element.chunks_exact(size))
            .map(|bytes| decode_component(bytes, self.data_type, self.normalized))
            .collect()
    }
}

/// One little-endian component (`bytes` has the component's size).
fn decode_component(bytes: &[u8], data_type: DataType, normalized: bool) -> f64 {
    let (value, unit) = match data_type {
        DataType::I8 => (f64::from(bytes[0] as i8), 127.0),
        DataType::I16 => (f64::from(i16::from_le_bytes([bytes[0], bytes[1]])), 32767.0),
        DataType::U8 => (f64::from(unsigned(bytes)), 255.0),
        DataType::U16 => (f64::from(unsigned(bytes)), 65535.0),
        DataType::U32 => return f64::from(unsigned(bytes)),
        DataType::F32 => return f64::from(f32::from_bits(unsigned(bytes))),
    };
    if normalized {
        (value / unit).max(-1.0)
    } else {
        value
    }
}

/// A little-endian unsigned integer of 1, 2 or 4 bytes.
fn unsigned(bytes: &[u8]) -> u32 {
    let mut word = [0u8; 4];
    word[..bytes.len()].copy_from_slice(bytes);
    u32::from_le_bytes(word)
}

/// The `count` elements of `size` bytes at `offset + i·stride` in `bytes`, after checking
/// that they all lie inside.
fn elements(
    bytes: &[u8],
    offset: usize,
    stride: usize,
    size: usize,
    count: usize,
) -> Result<impl Iterator<Item = &[u8]>, String> {
    if stride < size {
        return Err(format!(
            "byte stride {stride} below the element size {size}"
        ));
    }
    let end = match count.checked_sub(1) {
        None => Some(0),
        Some(last) => last
            .checked_mul(stride)
            .and_then(|start| start.checked_add(offset)?.checked_add(size)),
    };
    match end {
        Some(end) if end <= bytes.len() => {
            Ok((0..count).map(move |i| &bytes[offset + i * stride..][..size]))
        }
        _ => Err(format!(
            "{count} elements of {size} bytes (stride {stride}) at offset {offset} exceed the \
             {} bytes of the buffer view",
            bytes.len()
        )),
    }
}

/// The first `most` bytes of the regular file `path` (a device such as `/dev/zero` never
/// ends), each no more than the memory limit allows.
fn read_prefix(path: &Path, most: u64) -> Result<Vec<u8>, IoError> {
    use std::io::Read;
    let metadata = std::fs::metadata(path).map_err(|e| IoError::file(path, e))?;
    if !metadata.is_file() {
        return Err(IoError::format(path, "not a regular file"));
    }
    let length = metadata.len().min(most);
    crate::limits::check_declared("the file", length).map_err(|e| IoError::too_large(path, e))?;
    let mut data = Vec::with_capacity(length as usize);
    std::fs::File::open(path)
        .and_then(|file| file.take(length).read_to_end(&mut data))
        .map_err(|e| IoError::file(path, e))?;
    Ok(data)
}

/// Decodes `%XX` escapes of a relative URI.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3)?;
            let text = std::str::from_utf8(hex).ok()?;
            if !hex.iter().all(u8::is_ascii_hexdigit) {
                return None;
            }
            decoded.push(u8::from_str_radix(text, 16).ok()?);
            i += 3;
        } else {
            decoded.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(decoded).ok()
}

/// `gltf` 1.4 looks up `accessors[POSITION]` without a bounds check while validating, so an
/// out-of-range POSITION index would panic there: reject it first.
fn check_position_indices(raw: &Value) -> Result<(), String> {
    let accessor_count = raw["accessors"].as_array().map_or(0, Vec::len) as u64;
    let meshes = raw["meshes"].as_array().into_iter().flatten();
    for (m, mesh) in meshes.enumerate() {
        let primitives = mesh["primitives"].as_array().into_iter().flatten();
        for (p, primitive) in primitives.enumerate() {
            if let Some(index) = primitive["attributes"]["POSITION"].as_u64() {
                if index >= accessor_count {
                    return Err(format!(
                        "mesh {m}, primitive {p}: POSITION refers to accessor {index}, \
                         which does not exist"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// `gltf` 1.4 validates an animation's samplers and its channels' sampler indices but not the
/// channels' targets, and panics reading an unknown target path (`Checked::unwrap`) or a
/// target node that does not exist (`Target::node`): reject both first. Both found by
/// tests/fuzz_readers.rs.
fn check_animation_targets(raw: &Value) -> Result<(), String> {
    const PATHS: [&str; 4] = ["translation", "rotation", "scale", "weights"];
    let nodes = raw["nodes"].as_array().map_or(0, Vec::len);
    let animations = raw["animations"].as_array().into_iter().flatten();
    for (a, animation) in animations.enumerate() {
        let channels = animation["channels"].as_array().into_iter().flatten();
        for (c, channel) in channels.enumerate() {
            let node = channel["target"]["node"].as_u64();
            if let Some(node) = node.filter(|&n| n >= nodes as u64) {
                return Err(format!(
                    "animation {a}, channel {c}: target node {node} does not exist ({nodes} nodes)"
                ));
            }
            let path = &channel["target"]["path"];
            if !path.as_str().is_some_and(|p| PATHS.contains(&p)) {
                let shown: String = path.to_string().chars().take(40).collect();
                return Err(format!(
                    "animation {a}, channel {c}: target path {shown} is not translation, \
                     rotation, scale or weights"
                ));
            }
        }
    }
    Ok(())
}
