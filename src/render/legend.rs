//! Keys and labels drawn over a picture: the colour-wheel disc of flow pictures, the reference
//! arrow of arrow pictures, the colour bar of scalar pictures, and a title line.
//!
//! # The wheel legend
//!
//! A disc of radius `ρ = 0.11 H` in the bottom-right corner whose point at offset `(dx, dy)`
//! pixels from the centre (y down) has the colour `flow_color(dx/ρ, dy/ρ)`: the disc is the
//! Middlebury key in screen directions, its rim is a vector of the flow scale, so the colour of
//! a surface point tells the direction in which it moves on the screen and its speed relative
//! to the scale written left of the disc on the bottom line (`|u| = 0.123`). A thin dark
//! outline and cross-hairs mark the rim and the axes.
//!
//! # Placement
//!
//! Everything keeps a margin of `max(4, 0.03 H)` pixels from the picture's edges; text is
//! `8 · text_size_for(H)` pixels tall (see [`super::text`]). The title goes top-left, the
//! wheel and the arrow key bottom-right with their labels to their left on the bottom line
//! (outside the circle that [`super::Camera::framing`] gives the object in landscape
//! pictures), the colour bar at the right, vertically centred.

use super::color_wheel::flow_color;
use super::glyphs::{draw_arrow, ArrowStyle};
use super::raster::Canvas;
use super::text::{draw_text, format_value, text_height, text_size_for, text_width, TEXT_COLOUR};

/// Wheel radius as a fraction of the picture height.
const WHEEL_RADIUS: f64 = 0.11;

/// Colour of outlines and cross-hairs.
pub(crate) const LINE_COLOUR: [f64; 3] = [0.2, 0.2, 0.2];

/// Outline width, output pixels.
const OUTLINE: f64 = 1.0;

/// Cross-hair width, output pixels.
const CROSS_HAIR: f64 = 0.6;

/// A disc in output-pixel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disc {
    pub centre: [f64; 2],
    pub radius: f64,
}

/// Distance kept from the picture's edges.
pub(crate) fn margin(height: u32) -> f64 {
    (0.03 * height as f64).max(4.0)
}

/// Where the wheel legend of a `width × height` picture goes.
pub fn wheel_disc(width: u32, height: u32) -> Disc {
    let radius = WHEEL_RADIUS * height as f64;
    let inset = margin(height) + radius;
    Disc {
        centre: [width as f64 - inset, height as f64 - inset],
        radius,
    }
}

/// The text that gives a flow scale: `|u| = 0.123`.
pub fn scale_label(scale: f64) -> String {
    format!("|u| = {}", format_value(scale))
}

/// Draws the colour-wheel legend for flow scale `scale` (the rim) with its label to its left.
pub fn draw_wheel_legend(canvas: &mut Canvas, scale: f64) {
    let Disc { centre, radius } = wheel_disc(canvas.width(), canvas.height());
    let offset = |p: [f64; 2]| [p[0] - centre[0], p[1] - centre[1]];
    let reach = radius + OUTLINE;
    let bounds = [
        centre[0] - reach,
        centre[1] - reach,
        centre[0] + reach,
        centre[1] + reach,
    ];
    canvas.paint(bounds, |p| {
        let [dx, dy] = offset(p);
        let r = dx.hypot(dy);
        let on_line = r > radius || dx.abs() <= CROSS_HAIR / 2.0 || dy.abs() <= CROSS_HAIR / 2.0;
        if r > reach {
            None
        } else if on_line {
            Some(LINE_COLOUR)
        } else {
            Some(flow_color(dx / radius, dy / radius))
        }
    });
    let gap = margin(canvas.height());
    draw_bottom_label(canvas, &scale_label(scale), centre[0] - reach - 0.5 * gap);
}

/// Writes `text` on the bottom line of the picture, ending at `right`.
fn draw_bottom_label(canvas: &mut Canvas, text: &str, right: f64) {
    let size = text_size_for(canvas.height());
    let top = canvas.height() as f64 - margin(canvas.height()) - text_height(size);
    draw_text(
        canvas,
        text,
        [right - text_width(text, size), top],
        size,
        TEXT_COLOUR,
    );
}

/// Draws the arrow key: the arrow of a vector of length `scale` (`length` pixels) in the
/// bottom-right corner, pointing right, with `|u| = scale` written to its left.
pub fn draw_arrow_key(canvas: &mut Canvas, scale: f64, length: f64, style: &ArrowStyle) {
    let height = canvas.height();
    let gap = margin(height);
    let right = canvas.width() as f64 - gap;
    let middle = height as f64 - gap - 0.5 * text_height(text_size_for(height));
    draw_arrow(
        canvas,
        [right - length, middle],
        [right, middle],
        style.width,
        style.colour,
    );
    draw_bottom_label(canvas, &scale_label(scale), right - length - 0.5 * gap);
}

/// The box `[x0, y0, x1, y1]` of the colour bar of a `width × height` picture.
pub fn colour_bar_box(width: u32, height: u32) -> [f64; 4] {
    let h = height as f64;
    let (bar_width, bar_height) = (0.035 * h, 0.5 * h);
    let right = width as f64 - margin(height);
    let top = 0.5 * (h - bar_height);
    [right - bar_width, top, right, top + bar_height]
}

/// Draws a vertical colour bar, `colour(min)` at the bottom to `colour(max)` at the top, with
/// an outline and the two values written to its left.
pub fn draw_colour_bar(
    canvas: &mut Canvas,
    (min, max): (f64, f64),
    colour: impl Fn(f64) -> [f64; 3],
) {
    let [x0, y0, x1, y1] = colour_bar_box(canvas.width(), canvas.height());
    canvas.paint([x0, y0, x1, y1], |[_, y]| {
        Some(colour(min + (y1 - y) / (y1 - y0) * (max - min)))
    });
    for edge in [
        [x0 - OUTLINE, y0 - OUTLINE, x1 + OUTLINE, y0],
        [x0 - OUTLINE, y1, x1 + OUTLINE, y1 + OUTLINE],
        [x0 - OUTLINE, y0, x0, y1],
        [x1, y0, x1 + OUTLINE, y1],
    ] {
        canvas.fill_rect(edge, LINE_COLOUR);
    }
    let size = text_size_for(canvas.height());
    let gap = 0.5 * margin(canvas.height());
    for (value, y) in [(max, y0), (min, y1)] {
        let label = format_value(value);
        let left = x0 - gap - text_width(&label, size);
        draw_text(
            canvas,
            &label,
            [left, y - 0.5 * text_height(size)],
            size,
            TEXT_COLOUR,
        );
    }
}

/// Writes `title` in the top-left corner.
pub fn draw_title(canvas: &mut Canvas, title: &str) {
    let gap = margin(canvas.height());
    draw_text(
        canvas,
        title,
        [gap, gap],
        text_size_for(canvas.height()),
        TEXT_COLOUR,
    );
}
