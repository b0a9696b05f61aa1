//! Decoding a Zarr array's chunks into a region of it, every step bounded.
//!
//! A chunk is stored encoded by the array's codec chain (Zarr v3; a v2 array's `order`,
//! `dtype` and `compressor` are the same chain, as `zarrs` converts them): array-to-array codecs
//! (`transpose`), one array-to-bytes codec (`bytes`, or `sharding_indexed`: a shard of inner
//! chunks, each encoded by the inner chain, found through an index), then bytes-to-bytes
//! codecs (`gzip`, `zstd`, `blosc`, `crc32c`). Decoding runs the chain backwards.
//!
//! Why by hand rather than through `zarrs`' codecs: those inflate whatever a chunk holds before
//! looking at its size (a 17-byte zstd frame that declares 2⁵⁰ bytes is allocated, a 2 GB gzip
//! bomb is inflated whole) and trust a shard index (an offset of 2⁶⁴ − 10 panics). Here the size
//! every step must give is known before it runs, from the chunk's shape and element type:
//!
//! - each bytes-to-bytes codec inflates into at most that size and stops there (gzip and zstd
//!   stream through a bounded reader; blosc's header must declare exactly that size, and its
//!   own validation runs before `zarrs`' blosc allocates it; crc32c is verified);
//! - the `bytes` codec's input must have exactly `elements × element size` bytes;
//! - a shard index must have its fixed size, and every entry must lie inside the shard;
//! - values are converted to `f32` straight into the region's buffer, so a chunk costs its
//!   decoded bytes alone, and a missing chunk nothing but the fill value written.
//!
//! The caller checks a chunk's decoded size against the memory limit when it opens the array
//! ([`Codecs::decoded_bytes`]); errors are sentences that the caller prefixes with the store,
//! array and chunk key.

use serde_json::Value;
use std::borrow::Cow;
use std::io::Read;
use std::sync::Arc;
use zarrs::array::codec::api::{BytesRepresentation, BytesToBytesCodecTraits, Codec, CodecOptions};
use zarrs::metadata::v3::MetadataV3;

/// The element types meshflow reads, by their Zarr v3 names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Element {
    Bool,
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl Element {
    /// The element type named `name` (v3: `uint16`, `float32`, …).
    pub fn named(name: &str) -> Result<Self, String> {
        Ok(match name {
            "bool" => Self::Bool,
            "uint8" => Self::U8,
            "int8" => Self::I8,
            "uint16" => Self::U16,
            "int16" => Self::I16,
            "uint32" => Self::U32,
            "int32" => Self::I32,
            "uint64" => Self::U64,
            "int64" => Self::I64,
            "float32" => Self::F32,
            "float64" => Self::F64,
            other => {
                return Err(format!(
                    "data type {}: meshflow reads bool, (u)int8 to (u)int64, float32 and float64",
                    crate::format::quoted(other)
                ))
            }
        })
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Self::Bool | Self::U8 | Self::I8 => 1,
            Self::U16 | Self::I16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
            Self::U64 | Self::I64 | Self::F64 => 8,
        }
    }

    /// The elements in `bytes` (one per [`Self::size`] bytes), little- or big-endian, as `f32`
    /// into `out`: [`Self::value`] with the type chosen once for the row.
    pub fn convert(self, bytes: &[u8], big_endian: bool, out: &mut [f32]) {
        fn each<const N: usize>(
            bytes: &[u8],
            out: &mut [f32],
            big_endian: bool,
            f: fn([u8; N]) -> f32,
        ) {
            for (slot, word) in out.iter_mut().zip(bytes.chunks_exact(N)) {
                let mut word: [u8; N] = word.try_into().expect("N bytes");
                if big_endian {
                    word.reverse();
                }
                *slot = f(word);
            }
        }
        match self {
            Self::Bool => each::<1>(bytes, out, false, |[b]| f32::from(b != 0)),
            Self::U8 => each::<1>(bytes, out, false, |[b]| f32::from(b)),
            Self::I8 => each::<1>(bytes, out, false, |[b]| f32::from(b as i8)),
            Self::U16 => each(bytes, out, big_endian, |w| f32::from(u16::from_le_bytes(w))),
            Self::I16 => each(bytes, out, big_endian, |w| f32::from(i16::from_le_bytes(w))),
            Self::U32 => each(bytes, out, big_endian, |w| u32::from_le_bytes(w) as f32),
            Self::I32 => each(bytes, out, big_endian, |w| i32::from_le_bytes(w) as f32),
            Self::U64 => each(bytes, out, big_endian, |w| u64::from_le_bytes(w) as f32),
            Self::I64 => each(bytes, out, big_endian, |w| i64::from_le_bytes(w) as f32),
            Self::F32 => each(bytes, out, big_endian, f32::from_le_bytes),
            Self::F64 => each(bytes, out, big_endian, |w| f64::from_le_bytes(w) as f32),
        }
    }

    /// The element in `bytes` (its [`Self::size`] bytes), little- or big-endian, as `f32`.
    pub fn value(self, bytes: &[u8], big_endian: bool) -> f32 {
        fn word<const N: usize>(bytes: &[u8], big_endian: bool) -> [u8; N] {
            let mut word: [u8; N] = bytes[..N].try_into().expect("N bytes");
            if big_endian {
                word.reverse();
            }
            word
        }
        match self {
            Self::Bool => f32::from(bytes[0] != 0),
            Self::U8 => f32::from(bytes[0]),
            Self::I8 => f32::from(bytes[0] as i8),
            Self::U16 => f32::from(u16::from_le_bytes(word(bytes, big_endian))),
            Self::I16 => f32::from(i16::from_le_bytes(word(bytes, big_endian))),
            Self::U32 => u32::from_le_bytes(word(bytes, big_endian)) as f32,
            Self::I32 => i32::from_le_bytes(word(bytes, big_endian)) as f32,
            Self::U64 => u64::from_le_bytes(word(bytes, big_endian)) as f32,
            Self::I64 => i64::from_le_bytes(word(bytes, big_endian)) as f32,
            Self::F32 => f32::from_le_bytes(word(bytes, big_endian)),
            Self::F64 => f64::from_le_bytes(word(bytes, big_endian)) as f32,
        }
    }
}

/// A chunk's codec chain, as read from the array's v3 metadata.
#[derive(Debug)]
pub(super) struct Codecs {
    /// A `transpose` codec's `order`: dimension `i` of the encoded chunk is dimension
    /// `order[i]` of the array.
    order: Option<Vec<usize>>,
    layout: Layout,
    /// The bytes-to-bytes codecs, in encoding order.
    compressors: Vec<Compressor>,
}

/// The array-to-bytes codec.
#[derive(Debug)]
enum Layout {
    /// The elements in C order of the (transposed) chunk.
    Bytes {
        big_endian: bool,
    },
    Shards(Box<Sharding>),
}

/// `sharding_indexed`: a shard of inner chunks of `chunk_shape`, each encoded by `codecs`,
/// found through an index of `(offset, length)` pairs encoded by `index`.
#[derive(Debug)]
struct Sharding {
    chunk_shape: Vec<u64>,
    codecs: Codecs,
    index: Codecs,
    index_at_end: bool,
}

#[derive(Debug)]
enum Compressor {
    Gzip,
    Zstd,
    Crc32c,
    /// `zarrs`' own blosc codec (c-blosc), called once the header is checked.
    Blosc(Arc<dyn BytesToBytesCodecTraits>),
}

/// What the bytes codec of an index entry is: two little-endian `u64`.
const INDEX_ENTRY_BYTES: u64 = 16;

/// An index entry of an inner chunk that is not stored.
const EMPTY_ENTRY: (u64, u64) = (u64::MAX, u64::MAX);

impl Codecs {
    /// The chain of `codecs` (v3 metadata, JSON), for chunks of `rank` dimensions of
    /// `element`s.
    pub fn parse(codecs: &[Value], rank: usize, element: Element) -> Result<Self, String> {
        let mut order = None;
        let mut layout = None;
        let mut compressors = Vec::new();
        for codec in codecs {
            let (name, configuration) = match codec {
                Value::String(name) => (name.as_str(), None),
                _ => (
                    codec.get("name").and_then(Value::as_str).unwrap_or(""),
                    codec.get("configuration"),
                ),
            };
            let field = |key: &str| configuration.and_then(|c| c.get(key));
            match (name, &layout) {
                ("transpose", None) if order.is_none() => {
                    order = Some(permutation(field("order"), rank)?);
                }
                ("bytes" | "endian", None) => {
                    let big_endian = match field("endian").and_then(Value::as_str) {
                        Some("big") => true,
                        Some("little") => false,
                        None if element.size() == 1 => false,
                        _ => return Err("a bytes codec without its endian".into()),
                    };
                    layout = Some(Layout::Bytes { big_endian });
                }
                ("sharding_indexed", None) if order.is_none() => {
                    let sharding = Sharding::parse(configuration, rank, element)?;
                    layout = Some(Layout::Shards(Box::new(sharding)));
                }
                ("gzip", Some(_)) => compressors.push(Compressor::Gzip),
                ("zstd", Some(_)) => compressors.push(Compressor::Zstd),
                ("crc32c", Some(_)) => compressors.push(Compressor::Crc32c),
                ("blosc", Some(_)) => {
                    let metadata: MetadataV3 = serde_json::from_value(codec.clone())
                        .map_err(|e| format!("its blosc codec: {e}"))?;
                    match Codec::from_metadata(&metadata) {
                        Ok(Codec::BytesToBytes(blosc)) => {
                            compressors.push(Compressor::Blosc(blosc))
                        }
                        _ => return Err("its blosc codec cannot be made".into()),
                    }
                }
                _ => {
                    return Err(format!(
                        "codec {} where it stands: meshflow reads chunks of transpose, then \
                         bytes or sharding_indexed (no transpose before it), then gzip, zstd, \
                         blosc or crc32c",
                        crate::format::quoted(name)
                    ))
                }
            }
        }
        match layout {
            Some(layout) => Ok(Self {
                order,
                layout,
                compressors,
            }),
            None => Err("a codec chain without an array-to-bytes codec".into()),
        }
    }

    /// The bytes a chunk of `shape` takes decoded, at the most ([`Self::decode_into`] holds
    /// one at a time): the element bytes of the chunk, or of one inner chunk and a shard's index.
    pub fn decoded_bytes(&self, shape: &[u64], element: Element) -> u64 {
        let elements = shape.iter().fold(1u64, |n, &d| n.saturating_mul(d));
        let bytes = elements.saturating_mul(element.size() as u64);
        match &self.layout {
            Layout::Bytes { .. } => bytes,
            Layout::Shards(sharding) => {
                let inner = sharding
                    .codecs
                    .decoded_bytes(&sharding.chunk_shape, element);
                let entries = sharding.inner_chunks(shape);
                inner.saturating_add(entries.saturating_mul(INDEX_ENTRY_BYTES))
            }
        }
    }

    /// The most bytes a chunk of `shape` may take encoded: its decoded size and room for what
    /// a compressor adds to incompressible data (headers, stored blocks, checksums).
    pub fn encoded_most(&self, shape: &[u64], element: Element) -> u64 {
        let elements = shape.iter().fold(1u64, |n, &d| n.saturating_mul(d));
        let bytes = elements.saturating_mul(element.size() as u64);
        let index = match &self.layout {
            Layout::Bytes { .. } => 0,
            Layout::Shards(s) => s.inner_chunks(shape).saturating_mul(INDEX_ENTRY_BYTES + 64),
        };
        let total = bytes.saturating_add(index);
        total.saturating_add(total / 8).saturating_add(1 << 16)
    }

    /// How many chunks a chunk of `shape` is made of where it is stored: itself, or a shard's
    /// inner chunks.
    pub fn stored_pieces(&self, shape: &[u64]) -> u64 {
        match &self.layout {
            Layout::Bytes { .. } => 1,
            Layout::Shards(sharding) => sharding.inner_chunks(shape),
        }
    }

    /// Decodes `encoded`, the chunk at `place`, and writes its values that lie in `target`'s
    /// region; how many (inner) chunks were there and how many of them were not stored.
    pub fn decode_into(
        &self,
        encoded: &[u8],
        place: &Place,
        element: Element,
        fill: f32,
        target: &mut Target,
    ) -> Result<Pieces, String> {
        let decoded_length = match &self.layout {
            Layout::Bytes { .. } => Some(place.elements()?.saturating_mul(element.size())),
            Layout::Shards(_) => None,
        };
        let bytes = self.unwrap_bytes(encoded, decoded_length, place, element)?;
        match &self.layout {
            Layout::Bytes { big_endian } => {
                let strides = self.strides(&place.shape);
                let size = element.size();
                target.copy(place, &strides, |row, from, stride| match stride {
                    1 => element.convert(
                        &bytes[from * size..(from + row.len()) * size],
                        *big_endian,
                        row,
                    ),
                    _ => (row.iter_mut().enumerate()).for_each(|(j, slot)| {
                        let at = (from + j * stride) * size;
                        *slot = element.value(&bytes[at..at + size], *big_endian);
                    }),
                });
                Ok(Pieces {
                    chunks: 1,
                    missing: 0,
                })
            }
            Layout::Shards(sharding) => sharding.decode_into(&bytes, place, element, fill, target),
        }
    }

    /// `encoded` through the bytes-to-bytes codecs backwards, each bounded: to exactly
    /// `decoded_length` bytes at the end where that is known, else to the chunk's bound.
    fn unwrap_bytes<'a>(
        &self,
        encoded: &'a [u8],
        decoded_length: Option<usize>,
        place: &Place,
        element: Element,
    ) -> Result<Cow<'a, [u8]>, String> {
        let bound = usize::try_from(self.encoded_most(&place.shape, element)).unwrap_or(usize::MAX);
        let mut bytes = Cow::Borrowed(encoded);
        for (at, compressor) in self.compressors.iter().enumerate().rev() {
            let last = at == 0;
            let most = match (last, decoded_length) {
                (true, Some(length)) => length,
                _ => bound,
            };
            bytes = Cow::Owned(compressor.decode(&bytes, most)?);
        }
        match decoded_length {
            Some(length) if bytes.len() != length => Err(format!(
                "{} bytes decoded where its shape and data type take {length}",
                bytes.len()
            )),
            _ => Ok(bytes),
        }
    }

    /// The stride of each array dimension in the decoded chunk of `shape`: C order over the
    /// chunk's dimensions as the transpose codec ordered them.
    fn strides(&self, shape: &[u64]) -> Vec<usize> {
        let rank = shape.len();
        let order: Vec<usize> = match &self.order {
            Some(order) => order.clone(),
            None => (0..rank).collect(),
        };
        let mut strides = vec![0; rank];
        let mut stride = 1usize;
        for &dimension in order.iter().rev() {
            strides[dimension] = stride;
            stride *= shape[dimension] as usize;
        }
        strides
    }
}

/// `order` as a permutation of `0..rank`.
fn permutation(order: Option<&Value>, rank: usize) -> Result<Vec<usize>, String> {
    let order: Option<Vec<usize>> = order.and_then(Value::as_array).and_then(|list| {
        list.iter()
            .map(|v| v.as_u64().map(|v| v as usize))
            .collect()
    });
    let mut sorted = order.clone().unwrap_or_default();
    sorted.sort_unstable();
    match order {
        Some(order) if sorted == (0..rank).collect::<Vec<_>>() => Ok(order),
        _ => Err(format!(
            "a transpose order that is no permutation of 0 … {}",
            rank - 1
        )),
    }
}

impl Compressor {
    /// `bytes` decoded into at most `most` bytes.
    fn decode(&self, bytes: &[u8], most: usize) -> Result<Vec<u8>, String> {
        let bounded = |reader: &mut dyn Read, what: &str| -> Result<Vec<u8>, String> {
            // The size a chunk decodes to is known and within the memory limit: room for it
            // at once (up to 64 MiB: an intermediate stage's bound may be larger than it needs).
            let mut out = Vec::with_capacity(most.saturating_add(1).min(1 << 26));
            let limit = (most as u64).saturating_add(1);
            (reader.take(limit).read_to_end(&mut out)).map_err(|e| format!("{what}: {e}"))?;
            match out.len() > most {
                true => Err(format!("{what} inflates past the {most} bytes it can hold")),
                false => Ok(out),
            }
        };
        match self {
            Self::Gzip => bounded(&mut flate2::read::GzDecoder::new(bytes), "gzip"),
            Self::Zstd => {
                let mut decoder =
                    zstd::stream::read::Decoder::new(bytes).map_err(|e| format!("zstd: {e}"))?;
                bounded(&mut decoder, "zstd")
            }
            Self::Crc32c => {
                let Some(split) = bytes.len().checked_sub(4) else {
                    return Err("crc32c: fewer than the 4 bytes of a checksum".into());
                };
                let (data, sum) = bytes.split_at(split);
                let stored = u32::from_le_bytes(sum.try_into().expect("4 bytes"));
                match crc32c::crc32c(data) == stored {
                    true => Ok(data.to_vec()),
                    false => Err("crc32c: the checksum does not match (a corrupt chunk)".into()),
                }
            }
            Self::Blosc(codec) => decode_blosc(codec.as_ref(), bytes, most),
        }
    }
}

/// A blosc buffer decoded by `codec`, once its 16-byte header declares at most `most` bytes and
/// its own length: c-blosc allocates what the header says.
fn decode_blosc(
    codec: &dyn BytesToBytesCodecTraits,
    bytes: &[u8],
    most: usize,
) -> Result<Vec<u8>, String> {
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|w| u32::from_le_bytes(w.try_into().unwrap()))
    };
    let (Some(nbytes), Some(cbytes)) = (word(4), word(12)) else {
        return Err("blosc: shorter than its 16-byte header".into());
    };
    if nbytes as usize > most || cbytes as usize != bytes.len() {
        return Err(format!(
            "blosc: its header declares {nbytes} bytes from {cbytes}, where the chunk holds at \
             most {most} from {}",
            bytes.len()
        ));
    }
    let representation = BytesRepresentation::BoundedSize(most as u64);
    let options = CodecOptions::default();
    let decoded = codec.decode(Cow::Borrowed(bytes), &representation, &options);
    match decoded {
        Ok(decoded) if decoded.len() <= most => Ok(decoded.into_owned()),
        Ok(decoded) => Err(format!("blosc: {} bytes, over {most}", decoded.len())),
        Err(e) => Err(format!("blosc: {e}")),
    }
}

impl Sharding {
    fn parse(configuration: Option<&Value>, rank: usize, element: Element) -> Result<Self, String> {
        let field = |key: &str| configuration.and_then(|c| c.get(key));
        let chunk_shape: Vec<u64> = (field("chunk_shape").and_then(Value::as_array))
            .and_then(|list| list.iter().map(Value::as_u64).collect())
            .filter(|shape: &Vec<u64>| shape.len() == rank && !shape.contains(&0))
            .ok_or("sharding_indexed: no chunk_shape of positive sizes for each dimension")?;
        let list = |key: &str| -> Result<Vec<Value>, String> {
            match field(key) {
                Some(Value::Array(list)) => Ok(list.clone()),
                None if key == "index_codecs" => Ok(Vec::new()),
                _ => Err(format!("sharding_indexed: no list of {key}")),
            }
        };
        let codecs = Codecs::parse(&list("codecs")?, rank, element)?;
        let index = Codecs::parse(&list("index_codecs")?, rank + 1, Element::U64)?;
        let index_fixed = matches!(index.layout, Layout::Bytes { .. })
            && index
                .compressors
                .iter()
                .all(|c| matches!(c, Compressor::Crc32c));
        if !index_fixed {
            return Err(
                "sharding_indexed: an index codec chain of other than bytes and crc32c".into(),
            );
        }
        let index_at_end = match field("index_location").and_then(Value::as_str) {
            None | Some("end") => true,
            Some("start") => false,
            Some(other) => return Err(format!("sharding_indexed: index_location {other:?}")),
        };
        Ok(Self {
            chunk_shape,
            codecs,
            index,
            index_at_end,
        })
    }

    /// The inner chunks of a shard of `shape` (a shape that is no multiple of the inner chunks'
    /// counts the chunks that would cover it).
    fn inner_chunks(&self, shape: &[u64]) -> u64 {
        (shape.iter().zip(&self.chunk_shape))
            .fold(1u64, |n, (&s, &c)| n.saturating_mul(s.div_ceil(c)))
    }

    /// The inner chunks of the shard `shard` at `place` that lie in `target`'s region, decoded
    /// into it.
    fn decode_into(
        &self,
        shard: &[u8],
        place: &Place,
        element: Element,
        fill: f32,
        target: &mut Target,
    ) -> Result<Pieces, String> {
        if (place.shape.iter().zip(&self.chunk_shape)).any(|(&s, &c)| s % c != 0) {
            return Err(format!(
                "a shard of {:?} is no whole number of inner chunks of {:?}",
                place.shape, self.chunk_shape
            ));
        }
        let grid: Vec<u64> = (place.shape.iter().zip(&self.chunk_shape))
            .map(|(s, c)| s / c)
            .collect();
        let entries = self.index(shard, &grid)?;
        let mut pieces = Pieces::default();
        for (at, entry) in entries.iter().enumerate() {
            let origin = unravel(at as u64, &grid)
                .iter()
                .zip(&self.chunk_shape)
                .zip(&place.origin)
                .map(|((g, c), o)| o + g * c)
                .collect();
            let inner = Place {
                origin,
                shape: self.chunk_shape.clone(),
            };
            if !target.meets(&inner) {
                continue;
            }
            pieces.chunks += 1;
            if *entry == EMPTY_ENTRY {
                pieces.missing += 1;
                target.fill(&inner, fill);
                continue;
            }
            let (offset, length) = *entry;
            let bytes = &shard[offset as usize..(offset + length) as usize];
            let decoded = self
                .codecs
                .decode_into(bytes, &inner, element, fill, target);
            decoded.map_err(|e| format!("inner chunk {at}: {e}"))?;
        }
        Ok(pieces)
    }

    /// The shard's index: `(offset, length)` of each inner chunk in C order of `grid`, each
    /// checked to lie inside the shard (or to be [`EMPTY_ENTRY`]).
    fn index(&self, shard: &[u8], grid: &[u64]) -> Result<Vec<(u64, u64)>, String> {
        let n = grid.iter().product::<u64>();
        let checksums = self.index.compressors.len() as u64 * 4;
        let size = n
            .saturating_mul(INDEX_ENTRY_BYTES)
            .saturating_add(checksums);
        let length = shard.len() as u64;
        if size > length {
            return Err(format!(
                "a shard of {length} bytes, shorter than its index of {n} entries ({size} bytes)"
            ));
        }
        let index = match self.index_at_end {
            true => &shard[(length - size) as usize..],
            false => &shard[..size as usize],
        };
        let mut shape: Vec<u64> = grid.to_vec();
        shape.push(2);
        let place = Place {
            origin: vec![0; shape.len()],
            shape,
        };
        let decoded = (self.index)
            .unwrap_bytes(
                index,
                Some((n * INDEX_ENTRY_BYTES) as usize),
                &place,
                Element::U64,
            )
            .map_err(|e| format!("its shard index: {e}"))?;
        let big_endian = matches!(self.index.layout, Layout::Bytes { big_endian: true });
        let word = |at: usize| {
            let mut bytes: [u8; 8] = decoded[8 * at..8 * at + 8].try_into().expect("8 bytes");
            if big_endian {
                bytes.reverse();
            }
            u64::from_le_bytes(bytes)
        };
        (0..n as usize)
            .map(|k| {
                let entry = (word(2 * k), word(2 * k + 1));
                let inside = entry
                    .0
                    .checked_add(entry.1)
                    .is_some_and(|end| end <= length);
                match entry == EMPTY_ENTRY || inside {
                    true => Ok(entry),
                    false => Err(format!(
                        "its shard index places inner chunk {k} at bytes {} + {} of a shard of \
                         {length}",
                        entry.0, entry.1
                    )),
                }
            })
            .collect()
    }
}

/// The multi-index of the `at`-th element in C order of `shape`.
fn unravel(mut at: u64, shape: &[u64]) -> Vec<u64> {
    let mut index = vec![0; shape.len()];
    for (i, &n) in shape.iter().enumerate().rev() {
        index[i] = at % n;
        at /= n;
    }
    index
}

/// How many (inner) chunks a decode met, and how many of them were not stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Pieces {
    pub chunks: u64,
    pub missing: u64,
}

impl std::ops::AddAssign for Pieces {
    fn add_assign(&mut self, other: Self) {
        self.chunks += other.chunks;
        self.missing += other.missing;
    }
}

/// Where a chunk lies in the array: the index of its first element and its shape.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Place {
    pub origin: Vec<u64>,
    pub shape: Vec<u64>,
}

impl Place {
    /// Its number of elements, refused where it does not fit in memory's index range.
    fn elements(&self) -> Result<usize, String> {
        let n = self.shape.iter().try_fold(1u64, |n, &d| n.checked_mul(d));
        n.and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| format!("a chunk of {:?} elements", self.shape))
    }
}

/// A region of the array being read (per dimension its first index and extent) and the part
/// of its buffer (C order over the extents) held here: `values[0]` is the region's element
/// number `offset`.
pub(super) struct Target<'a> {
    pub start: &'a [u64],
    pub extent: &'a [u64],
    pub offset: usize,
    pub values: &'a mut [f32],
}

impl Target<'_> {
    /// Whether `place` meets the part of the region held here.
    fn meets(&self, place: &Place) -> bool {
        self.overlap(place).is_some()
    }

    /// Per dimension, the range of array indices where `place` and the held part of the
    /// region overlap; `None` where they do not.
    fn overlap(&self, place: &Place) -> Option<Vec<std::ops::Range<u64>>> {
        let strides = self.strides();
        let first = self.offset;
        let last = first + self.values.len();
        let mut ranges = Vec::with_capacity(self.start.len());
        for d in 0..self.start.len() {
            let low = place.origin[d].max(self.start[d]);
            let high = (place.origin[d].saturating_add(place.shape[d]))
                .min(self.start[d] + self.extent[d]);
            if low >= high {
                return None;
            }
            ranges.push(low..high);
        }
        // The held part is whole rows of the outermost dimension that varies: clip to it.
        let Some(outer) = (0..self.start.len()).find(|&d| self.extent[d] > 1) else {
            return Some(ranges); // a region of one element
        };
        let rows = (first / strides[outer]) as u64..(last / strides[outer]) as u64;
        let low = ranges[outer].start.max(self.start[outer] + rows.start);
        let high = ranges[outer].end.min(self.start[outer] + rows.end);
        ranges[outer] = low..high;
        (low < high).then_some(ranges)
    }

    /// C-order strides over the region's extents.
    fn strides(&self) -> Vec<usize> {
        let mut strides = vec![1usize; self.extent.len()];
        for d in (0..self.extent.len().saturating_sub(1)).rev() {
            strides[d] = strides[d + 1] * self.extent[d + 1] as usize;
        }
        strides
    }

    /// Writes the elements of `place` in the held region a row (along the last dimension) at
    /// a time: `write(row, from, stride)` fills `row` with the chunk's elements at `from`,
    /// `from + stride`, … of its buffer (`chunk_strides` per dimension).
    fn copy(
        &mut self,
        place: &Place,
        chunk_strides: &[usize],
        write: impl Fn(&mut [f32], usize, usize),
    ) {
        let Some(ranges) = self.overlap(place) else {
            return;
        };
        let strides = self.strides();
        let rank = ranges.len();
        let last = rank - 1;
        let mut index: Vec<u64> = ranges.iter().map(|r| r.start).collect();
        loop {
            let out = (0..rank)
                .map(|d| (index[d] - self.start[d]) as usize * strides[d])
                .sum::<usize>()
                - self.offset;
            let from = (0..rank)
                .map(|d| (index[d] - place.origin[d]) as usize * chunk_strides[d])
                .sum::<usize>();
            let row = (ranges[last].end - ranges[last].start) as usize;
            write(&mut self.values[out..out + row], from, chunk_strides[last]);
            // The next row: the odometer over all dimensions but the last.
            let mut d = last;
            loop {
                if d == 0 {
                    return;
                }
                d -= 1;
                index[d] += 1;
                if index[d] < ranges[d].end {
                    break;
                }
                index[d] = ranges[d].start;
            }
        }
    }

    /// Writes `fill` where `place` meets the held region.
    pub fn fill(&mut self, place: &Place, fill: f32) {
        let strides = vec![0; place.shape.len()];
        self.copy(place, &strides, |row, _, _| row.fill(fill));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn codecs(json: &str, rank: usize, element: Element) -> Codecs {
        Codecs::parse(
            &serde_json::from_str::<Vec<Value>>(json).unwrap(),
            rank,
            element,
        )
        .unwrap()
    }

    fn read(
        codecs: &Codecs,
        encoded: &[u8],
        place: &Place,
        extent: &[u64],
    ) -> Result<Vec<f32>, String> {
        let n = extent.iter().product::<u64>() as usize;
        let mut values = vec![-1.0; n];
        let start = vec![0; extent.len()];
        let mut target = Target {
            start: &start,
            extent,
            offset: 0,
            values: &mut values,
        };
        codecs.decode_into(encoded, place, Element::U16, 7.0, &mut target)?;
        Ok(values)
    }

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        encoder.write_all(data).unwrap();
        encoder.finish().unwrap()
    }

    #[test]
    fn a_gzip_chunk_decodes_into_the_region_and_a_bomb_stops_at_its_size() {
        let chain = codecs(
            r#"[{"name":"bytes","configuration":{"endian":"little"}},{"name":"gzip","configuration":{"level":1}}]"#,
            2,
            Element::U16,
        );
        let raw: Vec<u8> = (0u16..6).flat_map(|v| v.to_le_bytes()).collect();
        let place = Place {
            origin: vec![0, 0],
            shape: vec![2, 3],
        };
        // A region of 2 × 2 sees the chunk's first two columns.
        assert_eq!(
            read(&chain, &gzip(&raw), &place, &[2, 2]).unwrap(),
            [0.0, 1.0, 3.0, 4.0]
        );
        let bomb = gzip(&vec![0u8; 50_000_000]);
        let error = read(&chain, &bomb, &place, &[2, 2]).unwrap_err();
        assert!(error.contains("inflates past the 12 bytes"), "{error}");
    }

    #[test]
    fn a_transposed_chunk_is_read_in_array_order() {
        let chain = codecs(
            r#"[{"name":"transpose","configuration":{"order":[1,0]}},{"name":"bytes","configuration":{"endian":"big"}}]"#,
            2,
            Element::U16,
        );
        // Stored as the 3 × 2 transpose, big-endian: element (i, j) of the array at j * 2 + i.
        let stored: Vec<u8> = [0u16, 3, 1, 4, 2, 5]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        let place = Place {
            origin: vec![0, 0],
            shape: vec![2, 3],
        };
        assert_eq!(
            read(&chain, &stored, &place, &[2, 3]).unwrap(),
            [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
        );
    }

    #[test]
    fn shard_indexes_are_checked_before_use() {
        let chain = codecs(
            r#"[{"name":"sharding_indexed","configuration":{"chunk_shape":[1,2],
            "codecs":[{"name":"bytes","configuration":{"endian":"little"}}],
            "index_codecs":[{"name":"bytes","configuration":{"endian":"little"}},{"name":"crc32c"}]}}]"#,
            2,
            Element::U16,
        );
        let place = Place {
            origin: vec![0, 0],
            shape: vec![2, 2],
        };
        let shard = |entries: [(u64, u64); 2], data: &[u8]| {
            let mut bytes = data.to_vec();
            let index: Vec<u8> = entries
                .iter()
                .flat_map(|(o, n)| [o.to_le_bytes(), n.to_le_bytes()])
                .flatten()
                .collect();
            let sum = crc32c::crc32c(&index);
            bytes.extend(index);
            bytes.extend(sum.to_le_bytes());
            bytes
        };
        let data: Vec<u8> = [10u16, 11].iter().flat_map(|v| v.to_le_bytes()).collect();
        let good = shard([(0, 4), EMPTY_ENTRY], &data);
        assert_eq!(
            read(&chain, &good, &place, &[2, 2]).unwrap(),
            [10.0, 11.0, 7.0, 7.0]
        );
        let beyond = shard([(u64::MAX - 9, 4), EMPTY_ENTRY], &data);
        let error = read(&chain, &beyond, &place, &[2, 2]).unwrap_err();
        assert!(error.contains("places inner chunk 0"), "{error}");
        let mut corrupt = good.clone();
        let last = corrupt.len() - 1;
        corrupt[last] ^= 1;
        assert!(read(&chain, &corrupt, &place, &[2, 2])
            .unwrap_err()
            .contains("checksum"));
    }

    #[test]
    fn a_zstd_frame_declaring_petabytes_is_refused_without_allocating_them() {
        let chain = codecs(
            r#"[{"name":"bytes","configuration":{"endian":"little"}},{"name":"zstd","configuration":{"level":1,"checksum":false}}]"#,
            2,
            Element::U16,
        );
        let place = Place {
            origin: vec![0, 0],
            shape: vec![2, 3],
        };
        // A frame header with a content size of 2^50 and nothing after it.
        let mut frame = vec![0x28, 0xb5, 0x2f, 0xfd, 0xc0, 0x00];
        frame.extend((1u64 << 50).to_le_bytes());
        assert!(read(&chain, &frame, &place, &[2, 3]).is_err());
        let good = zstd::bulk::compress(&[1u8, 0, 2, 0, 3, 0, 4, 0, 5, 0, 6, 0], 1).unwrap();
        assert_eq!(
            read(&chain, &good, &place, &[2, 3]).unwrap(),
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
        );
    }
}
