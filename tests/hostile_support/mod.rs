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
