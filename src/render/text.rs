//! Bitmap text for labels: the public-domain 8×8 font of the `font8x8` crate.
//!
//! Each character is an 8 × 8 cell; row `r` of a glyph is a byte whose bit `k` (least
//! significant first) is the pixel in column `k`. A font pixel is drawn as a square of `size`
//! output pixels into the supersampled canvas, so text is `8 · size` pixels tall and each
//! character advances `8 · size` pixels. `|` is drawn as a solid bar (the font's is broken). Basic Latin, Latin-1 (e.g. `°`, `±`) and Greek
//! (e.g. `α`, `γ`) are covered; other characters show as `?`.

use super::raster::Canvas;
pub use crate::format::format_number;
use font8x8::{UnicodeFonts, BASIC_FONTS, GREEK_FONTS, LATIN_FONTS};

/// Font cells per character along each axis.
const CELLS: f64 = 8.0;

/// Colour of labels: near-black.
pub const TEXT_COLOUR: [f64; 3] = [0.1, 0.1, 0.1];

/// A solid vertical bar: the font's `|` is broken (`¦`), which misreads in `|u|`.
const SOLID_BAR: [u8; 8] = [0x18; 8];

/// The 8 × 8 bitmap of `c` (that of `?` when the font lacks it).
pub fn glyph(c: char) -> [u8; 8] {
    if c == '|' {
        return SOLID_BAR;
    }
    BASIC_FONTS
        .get(c)
        .or_else(|| LATIN_FONTS.get(c))
        .or_else(|| GREEK_FONTS.get(c))
        .or_else(|| BASIC_FONTS.get('?'))
        .unwrap_or([0; 8])
}

/// Font pixel size (output pixels per font pixel) that suits a picture `height` pixels tall:
/// text about 2.7 % of the height, at least 8 pixels.
pub fn text_size_for(height: u32) -> f64 {
    (height as f64 / 300.0).round().max(1.0)
}

/// Width of `text` in output pixels at font pixel size `size`.
pub fn text_width(text: &str, size: f64) -> f64 {
    text.chars().count() as f64 * CELLS * size
}

/// Height of a line of text in output pixels at font pixel size `size`.
pub fn text_height(size: f64) -> f64 {
    CELLS * size
}

/// Draws `text` with its top-left corner at `top_left` (output pixels).
pub fn draw_text(canvas: &mut Canvas, text: &str, top_left: [f64; 2], size: f64, colour: [f64; 3]) {
    for (index, c) in text.chars().enumerate() {
        let left = top_left[0] + index as f64 * CELLS * size;
        for (row, bits) in glyph(c).iter().enumerate() {
            for column in (0..8).filter(|k| bits & (1 << k) != 0) {
                let x = left + column as f64 * size;
                let y = top_left[1] + row as f64 * size;
                canvas.fill_rect([x, y, x + size, y + size], colour);
            }
        }
    }
}

/// `x` with three significant digits: fixed notation from 0.001 to 9999, scientific outside
/// (`0.123`, `12.3`, `4.56e-5`); `0` for zero.
pub fn format_value(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor();
    if (-3.0..4.0).contains(&magnitude) {
        let decimals = (2.0 - magnitude).max(0.0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.2e}")
    }
}
