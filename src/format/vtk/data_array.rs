//! Decoding VTK XML `<DataArray>` elements (the layouts are described in [`super`]).
//!
//! Read: `format="ascii"` (whitespace-separated numbers) and `format="binary"` (inline base64
//! of a byte-count header and the data, uncompressed), in either byte order, with a UInt32 or
//! UInt64 header, the header encoded in one base64 stream with the data or on its own (two
//! streams, as some writers do). Types Int8 … Int64, UInt8 … UInt64, Float32, Float64.
//! Values become `f64` ([`DataArray::floats`]) or non-negative integers
//! ([`DataArray::indices`], integer types only). ASCII numbers are parsed as their declared
//! type, so a Float32 array reads the same from ASCII as from binary.
//!
//! Every size is checked against the data before anything is allocated for it: the header
//! against the decoded bytes, the bytes or tokens against the count the caller expects.

use super::tree::{Element, LineError};
use base64::engine::general_purpose::STANDARD;
use base64::Engine;
use std::borrow::Cow;

/// How binary arrays are laid out in one file (attributes of `<VTKFile>`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Encoding {
    big_endian: bool,
    /// Size of the byte-count header: 4 (UInt32) or 8 (UInt64).
    header_bytes: usize,
}

impl Encoding {
    /// The encoding `root` declares: `byte_order` (default LittleEndian) and `header_type`
    /// (default UInt32, as in version 0.1 files). Compressed files are refused.
    pub fn of(root: &Element) -> Result<Self, LineError> {
        if let Some(compressor) = root.attribute("compressor").filter(|c| !c.is_empty()) {
            return Err(root.error(format!(
                "compressed VTU (compressor=\"{compressor}\") is not supported; meshflow reads \
                 the files it writes"
            )));
        }
        let big_endian = match root.attribute("byte_order").unwrap_or("LittleEndian") {
            "LittleEndian" => false,
            "BigEndian" => true,
            other => {
                return Err(root.error(format!(
                    "byte_order=\"{other}\" is neither LittleEndian nor BigEndian"
                )))
            }
        };
        let header_bytes = match root.attribute("header_type").unwrap_or("UInt32") {
            "UInt32" => 4,
            "UInt64" => 8,
            other => {
                return Err(root.error(format!(
                    "header_type=\"{other}\" is neither UInt32 nor UInt64"
                )))
            }
        };
        Ok(Self {
            big_endian,
            header_bytes,
        })
    }
}

/// A VTK scalar type name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ScalarType {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

/// One decoded value, before conversion to what the caller needs.
#[derive(Clone, Copy, Debug)]
enum Scalar {
    Float(f64),
    Signed(i64),
    Unsigned(u64),
}

impl ScalarType {
    const ALL: [Self; 10] = [
        Self::Int8,
        Self::UInt8,
        Self::Int16,
        Self::UInt16,
        Self::Int32,
        Self::UInt32,
        Self::Int64,
        Self::UInt64,
        Self::Float32,
        Self::Float64,
    ];

    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|ty| ty.name() == name)
    }

    fn name(self) -> &'static str {
        match self {
            Self::Int8 => "Int8",
            Self::UInt8 => "UInt8",
            Self::Int16 => "Int16",
            Self::UInt16 => "UInt16",
            Self::Int32 => "Int32",
            Self::UInt32 => "UInt32",
            Self::Int64 => "Int64",
            Self::UInt64 => "UInt64",
            Self::Float32 => "Float32",
            Self::Float64 => "Float64",
        }
    }

    /// Bytes per value.
    fn size(self) -> usize {
        match self {
            Self::Int8 | Self::UInt8 => 1,
            Self::Int16 | Self::UInt16 => 2,
            Self::Int32 | Self::UInt32 | Self::Float32 => 4,
            Self::Int64 | Self::UInt64 | Self::Float64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::Float32 | Self::Float64)
    }

    /// The value in `raw` (exactly [`Self::size`] bytes) in the given byte order.
    fn decode(self, raw: &[u8], big_endian: bool) -> Scalar {
        // Little-endian bytes, zero-padded to 8.
        let mut b = [0u8; 8];
        b[..raw.len()].copy_from_slice(raw);
        if big_endian {
            b[..raw.len()].reverse();
        }
        let [b0, b1, b2, b3, ..] = b;
        match self {
            Self::Int8 => Scalar::Signed(i8::from_le_bytes([b0]).into()),
            Self::UInt8 => Scalar::Unsigned(b0.into()),
            Self::Int16 => Scalar::Signed(i16::from_le_bytes([b0, b1]).into()),
            Self::UInt16 => Scalar::Unsigned(u16::from_le_bytes([b0, b1]).into()),
            Self::Int32 => Scalar::Signed(i32::from_le_bytes([b0, b1, b2, b3]).into()),
            Self::UInt32 => Scalar::Unsigned(u32::from_le_bytes([b0, b1, b2, b3]).into()),
            Self::Int64 => Scalar::Signed(i64::from_le_bytes(b)),
            Self::UInt64 => Scalar::Unsigned(u64::from_le_bytes(b)),
            Self::Float32 => Scalar::Float(f32::from_le_bytes([b0, b1, b2, b3]).into()),
            Self::Float64 => Scalar::Float(f64::from_le_bytes(b)),
        }
    }

    /// One ASCII number of this type; integers must lie in the type's range.
    fn parse(self, token: &str) -> Option<Scalar> {
        match self {
            Self::Float32 => token.parse::<f32>().ok().map(|x| Scalar::Float(x.into())),
            Self::Float64 => token.parse::<f64>().ok().map(Scalar::Float),
            integer => {
                let value: i128 = token.parse().ok()?;
                let bits = 8 * integer.size() as u32;
                let signed = matches!(
                    integer,
                    Self::Int8 | Self::Int16 | Self::Int32 | Self::Int64
                );
                let (min, max) = match signed {
                    true => (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1),
                    false => (0, (1i128 << bits) - 1),
                };
                if !(min..=max).contains(&value) {
                    return None;
                }
                Some(match signed {
                    true => Scalar::Signed(value as i64),
                    false => Scalar::Unsigned(value as u64),
                })
            }
        }
    }
}

impl std::fmt::Display for Scalar {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Float(x) => write!(f, "{x}"),
            Self::Signed(i) => write!(f, "{i}"),
            Self::Unsigned(u) => write!(f, "{u}"),
        }
    }
}

impl Scalar {
    /// The value as f64 (integers beyond 2^53 rounded to nearest).
    fn to_f64(self) -> f64 {
        match self {
            Self::Float(x) => x,
            Self::Signed(i) => i as f64,
            Self::Unsigned(u) => u as f64,
        }
    }

    /// The value as a non-negative integer; `None` for negative values (and floats).
    fn to_index(self) -> Option<u64> {
        match self {
            Self::Signed(i) => u64::try_from(i).ok(),
            Self::Unsigned(u) => Some(u),
            Self::Float(_) => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Binary,
}

/// A `<DataArray>` element with its attributes checked.
#[derive(Debug)]
pub(super) struct DataArray<'e, 'a> {
    element: &'e Element<'a>,
    pub name: String,
    scalar_type: ScalarType,
    pub components: usize,
    format: Format,
}

impl<'e, 'a> DataArray<'e, 'a> {
    /// Reads the attributes of `element`: `type`, `format`, `NumberOfComponents` (default 1)
    /// and `Name` (`default_name` when absent; `None` makes the name required).
    pub fn new(element: &'e Element<'a>, default_name: Option<&str>) -> Result<Self, LineError> {
        let name = match (
            element.attribute("Name").filter(|n| !n.is_empty()),
            default_name,
        ) {
            (Some(name), _) | (None, Some(name)) => name.to_string(),
            (None, None) => return Err(element.error("a <DataArray> has no Name")),
        };
        let fail = |message: String| element.error(format!("DataArray '{name}': {message}"));
        let scalar_type = match element.attribute("type") {
            None => return Err(fail("no type".into())),
            Some(ty) => ScalarType::from_name(ty).ok_or_else(|| {
                fail(format!(
                    "type \"{ty}\" is not supported (Int8 … Int64, UInt8 … UInt64, Float32, \
                     Float64)"
                ))
            })?,
        };
        let format = match element.attribute("format") {
            Some("ascii") => Format::Ascii,
            Some("binary") => Format::Binary,
            Some("appended") => {
                return Err(fail(
                    "appended VTU data is not supported; meshflow reads the files it writes".into(),
                ))
            }
            Some(other) => return Err(fail(format!("unknown format \"{other}\""))),
            None => return Err(fail("no format attribute".into())),
        };
        let components = match element.attribute("NumberOfComponents") {
            None => 1,
            Some(text) => match text.trim().parse::<usize>() {
                Ok(k) if k > 0 => k,
                _ => {
                    return Err(fail(format!(
                        "NumberOfComponents=\"{text}\" is not positive"
                    )))
                }
            },
        };
        Ok(Self {
            element,
            name,
            scalar_type,
            components,
            format,
        })
    }

    /// An error about this array, at its line.
    pub fn error(&self, message: impl std::fmt::Display) -> LineError {
        self.element
            .error(format!("DataArray '{}': {message}", self.name))
    }

    /// `tuples × components` values as f64, point-major.
    pub fn floats(&self, tuples: usize, encoding: Encoding) -> Result<Vec<f64>, LineError> {
        self.values(tuples, encoding, |value| Ok(value.to_f64()))
    }

    /// `count` single-component non-negative integers; the array must have an integer type.
    pub fn indices(&self, count: usize, encoding: Encoding) -> Result<Vec<u64>, LineError> {
        if !self.scalar_type.is_integer() {
            return Err(self.error(format!(
                "type {} is not an integer type",
                self.scalar_type.name()
            )));
        }
        if self.components != 1 {
            return Err(self.error(format!("{} components, expected 1", self.components)));
        }
        self.values(count, encoding, |value| {
            value
                .to_index()
                .ok_or_else(|| format!("is {value}, not a non-negative integer"))
        })
    }

    /// `tuples × components` values through `convert`, once the data is known to hold exactly
    /// that many.
    fn values<T>(
        &self,
        tuples: usize,
        encoding: Encoding,
        convert: impl Fn(Scalar) -> Result<T, String>,
    ) -> Result<Vec<T>, LineError> {
        let count = tuples.checked_mul(self.components).ok_or_else(|| {
            self.error(format!(
                "{tuples} tuples × {} components is too many",
                self.components
            ))
        })?;
        let expected = match self.components {
            1 => format!("{count}"),
            k => format!("{count} = {tuples} × {k} components"),
        };
        let convert = |(k, value): (usize, Scalar)| {
            convert(value).map_err(|message| self.error(format!("value {k} {message}")))
        };
        match self.format {
            Format::Ascii => {
                let values = self
                    .ascii_scalars(count)
                    .enumerate()
                    .map(|(k, value)| convert((k, value?)))
                    .collect::<Result<Vec<T>, _>>()?;
                if values.len() != count {
                    let found = match values.len() > count {
                        true => "more".to_string(),
                        false => values.len().to_string(),
                    };
                    return Err(self.error(format!("holds {found} values, expected {expected}")));
                }
                Ok(values)
            }
            Format::Binary => {
                let ty = self.scalar_type;
                self.binary_data(count, encoding, &expected)?
                    .chunks_exact(ty.size())
                    .map(|raw| ty.decode(raw, encoding.big_endian))
                    .enumerate()
                    .map(convert)
                    .collect()
            }
        }
    }

    /// The numbers of an ASCII array: at most one more than `count`, so that a huge array is
    /// not parsed in vain.
    fn ascii_scalars(&self, count: usize) -> impl Iterator<Item = Result<Scalar, LineError>> + '_ {
        let ty = self.scalar_type;
        self.element
            .text
            .split_ascii_whitespace()
            .take(count.saturating_add(1))
            .enumerate()
            .map(move |(k, token)| {
                ty.parse(token).ok_or_else(|| {
                    let token: String = token.chars().take(30).collect();
                    self.error(format!(
                        "value {k} '{token}' is not a number of type {}",
                        ty.name()
                    ))
                })
            })
    }

    /// The data bytes of a binary array, checked to hold `count` values.
    fn binary_data(
        &self,
        count: usize,
        encoding: Encoding,
        expected: &str,
    ) -> Result<Vec<u8>, LineError> {
        let ty = self.scalar_type;
        let data = decode_binary(&self.element.text, encoding).map_err(|m| self.error(m))?;
        if Some(data.len()) != count.checked_mul(ty.size()) {
            return Err(self.error(format!(
                "holds {} bytes, expected {expected} {} values of {}",
                data.len(),
                ty.name(),
                match ty.size() {
                    1 => "1 byte".to_string(),
                    size => format!("{size} bytes"),
                }
            )));
        }
        Ok(data)
    }
}

/// The data bytes of an inline binary array: base64 (whitespace ignored) of a byte-count header
/// and the data, in one stream or as two (the header's stream then ends in padding).
fn decode_binary(text: &str, encoding: Encoding) -> Result<Vec<u8>, String> {
    let text = text.trim_ascii();
    let base64: Cow<[u8]> = match text.bytes().any(|b| b.is_ascii_whitespace()) {
        true => text.bytes().filter(|b| !b.is_ascii_whitespace()).collect(),
        false => Cow::Borrowed(text.as_bytes()),
    };
    let header_bytes = encoding.header_bytes;
    let header_chars = 4 * header_bytes.div_ceil(3);
    let decode = |chars: &[u8]| {
        STANDARD
            .decode(chars)
            .map_err(|e| format!("invalid base64: {e}"))
    };
    let separate_header = base64.len() > header_chars && base64[header_chars - 1] == b'=';
    let (header, data) = match separate_header {
        true => (
            decode(&base64[..header_chars])?,
            decode(&base64[header_chars..])?,
        ),
        false => {
            let mut block = decode(&base64)?;
            if block.len() < header_bytes {
                return Err(format!(
                    "{} bytes, too short for its {header_bytes}-byte header",
                    block.len()
                ));
            }
            let data = block.split_off(header_bytes);
            (block, data)
        }
    };
    let announced = header_value(&header, encoding);
    if announced != Some(data.len() as u64) {
        return Err(format!(
            "the header announces {} bytes, but {} follow",
            announced.map_or_else(|| "?".to_string(), |n| n.to_string()),
            data.len()
        ));
    }
    Ok(data)
}

/// The byte count in a decoded header (`None` when it has the wrong length).
fn header_value(header: &[u8], encoding: Encoding) -> Option<u64> {
    let ty = match (header.len(), encoding.header_bytes) {
        (4, 4) => ScalarType::UInt32,
        (8, 8) => ScalarType::UInt64,
        _ => return None,
    };
    ty.decode(header, encoding.big_endian).to_index()
}
