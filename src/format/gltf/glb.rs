//! The binary glTF container (GLB, glTF 2.0 §4.4), shared by the glTF reader and writer.
//!
//! ```text
//! header:  magic "glTF" | version 2 (u32) | total length in bytes (u32)
//! chunk 0: length (u32) | "JSON" | UTF-8 JSON, padded with spaces to a multiple of 4
//! chunk 1: length (u32) | "BIN\0" | binary buffer 0, padded with zeros to a multiple of 4
//! ```
//!
//! All integers little-endian; the BIN chunk is optional and is the data of the document's
//! buffer 0 when that buffer has no `uri`.

use std::io::Write;

const MAGIC: &[u8; 4] = b"glTF";
const VERSION: u32 = 2;
const JSON_CHUNK: &[u8; 4] = b"JSON";
const BIN_CHUNK: &[u8; 4] = b"BIN\0";
const HEADER_LENGTH: usize = 12;
const CHUNK_HEADER_LENGTH: usize = 8;

/// The chunks of a GLB file.
pub(crate) struct Glb<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
}

/// Whether `bytes` start like a GLB file (rather than a JSON `.gltf`).
pub(crate) fn is_glb(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Splits a GLB file into its chunks; the message says what is malformed. Chunks after the
/// first two, and a second chunk of unknown type, are ignored as the format asks.
pub(crate) fn split(bytes: &[u8]) -> Result<Glb<'_>, String> {
    if !is_glb(bytes) {
        return Err("not a GLB file (it does not start with \"glTF\")".into());
    }
    let header = bytes
        .get(..HEADER_LENGTH)
        .ok_or("truncated GLB: the 12-byte header is incomplete")?;
    let version = read_u32(&header[4..8]);
    if version != VERSION {
        return Err(format!("GLB version {version}; only glTF 2.0 is supported"));
    }
    let declared = read_u32(&header[8..12]) as usize;
    if declared > bytes.len() || declared < HEADER_LENGTH {
        return Err(format!(
            "truncated GLB: the header declares {declared} bytes, the file has {}",
            bytes.len()
        ));
    }
    let (kind, json, rest) =
        chunk(&bytes[HEADER_LENGTH..declared])?.ok_or("GLB without a JSON chunk")?;
    if kind != JSON_CHUNK {
        let kind = String::from_utf8_lossy(kind);
        return Err(format!("the first GLB chunk has type {kind:?}, not JSON"));
    }
    let bin = chunk(rest)?.and_then(|(kind, bin, _)| (kind == BIN_CHUNK).then_some(bin));
    Ok(Glb { json, bin })
}

/// A chunk's type and data, and the bytes after it.
type Chunk<'a> = (&'a [u8], &'a [u8], &'a [u8]);

/// The chunk at the start of `bytes`; `None` if `bytes` is empty.
fn chunk(bytes: &[u8]) -> Result<Option<Chunk<'_>>, String> {
    if bytes.is_empty() {
        return Ok(None);
    }
    let header = bytes
        .get(..CHUNK_HEADER_LENGTH)
        .ok_or("truncated GLB: incomplete chunk header")?;
    let length = read_u32(&header[..4]) as usize;
    let rest = &bytes[CHUNK_HEADER_LENGTH..];
    let data = rest.get(..length).ok_or_else(|| {
        format!(
            "truncated GLB: a chunk declares {length} bytes, {} remain",
            rest.len()
        )
    })?;
    Ok(Some((&header[4..8], data, &rest[length..])))
}

fn read_u32(bytes: &[u8]) -> u32 {
    u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])
}

/// Writes a GLB file with the given JSON and binary buffer (each padded as the format
/// requires). Fails if the file would exceed the format's 4 GiB limit.
pub(crate) fn write(w: &mut impl Write, json: &[u8], bin: &[u8]) -> std::io::Result<()> {
    let json_padded = json.len().next_multiple_of(4);
    let bin_padded = bin.len().next_multiple_of(4);
    let total = HEADER_LENGTH + 2 * CHUNK_HEADER_LENGTH + json_padded + bin_padded;
    let total = u32::try_from(total).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the glTF data exceed the 4 GiB limit of a GLB file",
        )
    })?;
    w.write_all(MAGIC)?;
    w.write_all(&VERSION.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    write_chunk(w, JSON_CHUNK, json, json_padded, b' ')?;
    write_chunk(w, BIN_CHUNK, bin, bin_padded, 0)
}

fn write_chunk(
    w: &mut impl Write,
    kind: &[u8; 4],
    data: &[u8],
    padded_length: usize,
    padding: u8,
) -> std::io::Result<()> {
    // The caller checked that the whole file, hence this chunk, fits in a u32.
    w.write_all(&(padded_length as u32).to_le_bytes())?;
    w.write_all(kind)?;
    w.write_all(data)?;
    w.write_all(&vec![padding; padded_length - data.len()])
}
