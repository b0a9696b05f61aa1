//! Line charts of several series against one x axis, e.g. per slab the mean divergence, mean
//! areal rate and mean curl of a flow over time (drawn whole by [`super::series_chart`]).
//!
//! # Ranges
//!
//! Each axis spans the finite data it shows: `[lo, hi]`, the smallest and largest finite
//! value (for y, over every series, counting only points whose x is finite too). A degenerate
//! range `lo = hi = v` is widened to `v ∓ 0.1 |v|` (`∓ 1` at zero), no data gives `[0, 1]`,
//! and then both ends are padded by 5 % of the span, so no point sits on an axis.
//!
//! # Mapping
//!
//! With the plot area `[x₀, x₁] × [y₀, y₁]` in output pixels (y down), a data point goes to
//!
//! ```text
//! px = x₀ + (x − lo_x)/(hi_x − lo_x) · (x₁ − x₀),    py = y₁ − (y − lo_y)/(hi_y − lo_y) · (y₁ − y₀),
//! ```
//!
//! so larger values are higher. Points with a non-finite coordinate are not drawn and break
//! their series' line (a gap where a value is missing, not a bridge over it).
//!
//! # Ticks
//!
//! Three to eight per axis: the multiples inside the range of a step `m · 10ᵏ`,
//! `m ∈ {1, 2, 5, 10}`, the one nearest `span / 5`; labels are [`format_number`]s. A grey
//! zero line is drawn when the y range contains 0.
//!
//! # Layout
//!
//! Margins and text size as the other pictures (see [`super::legend`]): the title on the top
//! line, the y tick labels left of the plot area, the x tick labels and the x label below it,
//! the legend (a square swatch of each series' colour and its name, one line each) right of
//! it. Series `k` is drawn in [`series_colour`]`(k)`, colorous's CATEGORY10, as a
//! [`LINE_WIDTH`]-pixel polyline with a [`MARKER_SIDE`]-pixel square at each point.

use super::colormap::finite_range;
use super::glyphs::draw_segment;
use super::legend::{margin, LINE_COLOUR};
use super::raster::Canvas;
use super::text::{draw_text, format_number, text_height, text_size_for, text_width, TEXT_COLOUR};
use super::RenderError;
use std::ops::RangeInclusive;

/// One named line of a chart: a value per x value (non-finite values are gaps).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Series<'a> {
    pub name: &'a str,
    pub values: &'a [f64],
}

/// Accepted chart sides, output pixels.
pub const CHART_SIDES: RangeInclusive<u32> = 16..=8192;

/// Width of series lines, output pixels.
pub const LINE_WIDTH: f64 = 2.0;

/// Side of the square marking each point, output pixels.
pub const MARKER_SIDE: f64 = 5.0;

/// Colour of the line at y = 0: light, so the series stay in front.
pub const ZERO_LINE_COLOUR: [f64; 3] = [0.7, 0.7, 0.7];

/// Width of the axes and the zero line, output pixels.
const AXIS_WIDTH: f64 = 1.0;

/// Length of tick marks below and left of the plot area, output pixels.
const TICK_LENGTH: f64 = 4.0;

/// Fraction of the span added at both ends of a range.
const PADDING: f64 = 0.05;

/// Ticks aimed at per axis.
const TARGET_TICKS: f64 = 5.0;

/// Most ticks drawn on an axis: a guard for ranges where rounding defeats the step.
const MAX_TICKS: usize = 12;

/// The colour of series `k`: CATEGORY10, repeating after ten series.
pub fn series_colour(k: usize) -> [f64; 3] {
    let colour = colorous::CATEGORY10[k % colorous::CATEGORY10.len()];
    [colour.r, colour.g, colour.b].map(|c| c as f64 / 255.0)
}

/// Checks that a `width × height` chart is within [`CHART_SIDES`].
pub(crate) fn check_chart_size(width: u32, height: u32) -> Result<(), RenderError> {
    if CHART_SIDES.contains(&width) && CHART_SIDES.contains(&height) {
        Ok(())
    } else {
        Err(RenderError::Size {
            reason: format!(
                "a {width}×{height} chart: each side must be between {} and {} pixels",
                CHART_SIDES.start(),
                CHART_SIDES.end()
            ),
        })
    }
}

/// Checks that every series has one value per x value.
pub(crate) fn check_series_lengths(x: &[f64], series: &[Series]) -> Result<(), RenderError> {
    match series.iter().find(|s| s.values.len() != x.len()) {
        None => Ok(()),
        Some(wrong) => Err(RenderError::SeriesLength {
            name: wrong.name.to_string(),
            expected: x.len(),
            got: wrong.values.len(),
        }),
    }
}

/// Where the parts of a chart go; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct PlotLayout {
    /// The plot area `[x₀, y₀, x₁, y₁]`, output pixels, y down.
    pub area: [f64; 4],
    /// The data range shown along x, padded.
    pub x_range: (f64, f64),
    /// The data range shown along y, padded, shared by all series.
    pub y_range: (f64, f64),
    x_ticks: Vec<f64>,
    y_ticks: Vec<f64>,
    legend_left: f64,
    text_size: f64,
    gap: f64,
}

impl PlotLayout {
    /// The layout of a `width × height` chart of `series` against `x` (lengths unchecked:
    /// points beyond the shorter of the two are ignored).
    pub fn new(width: u32, height: u32, x: &[f64], series: &[Series]) -> Self {
        let x_range = axis_range(finite_range(x));
        let y_range = axis_range(finite_range(&drawable_values(x, series)));
        let (x_ticks, y_ticks) = (nice_ticks(x_range), nice_ticks(y_range));
        let gap = margin(height);
        let text_size = text_size_for(height);
        let line = text_height(text_size);
        let y_labels = widest(y_ticks.iter().map(|&v| format_number(v)), text_size);
        let names = widest(series.iter().map(|s| s.name), text_size);
        let legend_width = if series.is_empty() {
            0.0
        } else {
            gap + line + 0.5 * gap + names
        };
        let left = gap + y_labels + 0.5 * gap + TICK_LENGTH;
        let right = width as f64 - gap - legend_width;
        let top = 2.0 * gap + 1.5 * line;
        let bottom = height as f64 - 2.0 * gap - 2.0 * line - TICK_LENGTH;
        Self {
            area: [left, top, right, bottom],
            x_range,
            y_range,
            x_ticks,
            y_ticks,
            legend_left: right + gap,
            text_size,
            gap,
        }
    }

    /// The output-pixel position of the data point `(x, y)`; `None` when it is not finite.
    pub fn pixel(&self, x: f64, y: f64) -> Option<[f64; 2]> {
        let [x0, y0, x1, y1] = self.area;
        let fraction = |v: f64, (lo, hi): (f64, f64)| (v - lo) / (hi - lo);
        let pixel = [
            x0 + fraction(x, self.x_range) * (x1 - x0),
            y1 - fraction(y, self.y_range) * (y1 - y0),
        ];
        pixel.iter().all(|c| c.is_finite()).then_some(pixel)
    }

    /// The box `[x₀, y₀, x₁, y₁]` of the legend swatch of series `k`.
    pub fn swatch(&self, k: usize) -> [f64; 4] {
        let line = text_height(self.text_size);
        let top = self.area[1] + 1.5 * line * k as f64;
        [self.legend_left, top, self.legend_left + line, top + line]
    }

    /// Draws the zero line, the axes, their ticks and tick labels, and `x_label` centred below.
    pub fn draw_axes(&self, canvas: &mut Canvas, x_label: &str) {
        let [x0, y0, x1, y1] = self.area;
        self.draw_zero_line(canvas);
        canvas.fill_rect([x0 - AXIS_WIDTH, y0, x0, y1 + AXIS_WIDTH], LINE_COLOUR);
        canvas.fill_rect([x0 - AXIS_WIDTH, y1, x1, y1 + AXIS_WIDTH], LINE_COLOUR);
        let line = text_height(self.text_size);
        let below_ticks = y1 + TICK_LENGTH + 0.5 * self.gap;
        for (x, [px, _]) in self.tick_pixels(&self.x_ticks, |x| (x, self.y_range.0)) {
            canvas.fill_rect([px - 0.5, y1, px + 0.5, y1 + TICK_LENGTH], LINE_COLOUR);
            self.write_centred(canvas, &format_number(x), px, below_ticks);
        }
        for (y, [_, py]) in self.tick_pixels(&self.y_ticks, |y| (self.x_range.0, y)) {
            canvas.fill_rect([x0 - TICK_LENGTH, py - 0.5, x0, py + 0.5], LINE_COLOUR);
            let label = format_number(y);
            let right = x0 - TICK_LENGTH - 0.5 * self.gap;
            let left = right - text_width(&label, self.text_size);
            self.write(canvas, &label, [left, py - 0.5 * line]);
        }
        self.write_centred(
            canvas,
            x_label,
            0.5 * (x0 + x1),
            below_ticks + line + 0.5 * self.gap,
        );
    }

    /// Draws one series: segments between consecutive drawable points and a square at each.
    pub fn draw_series(&self, canvas: &mut Canvas, x: &[f64], values: &[f64], colour: [f64; 3]) {
        let pixels: Vec<Option<[f64; 2]>> = x
            .iter()
            .zip(values)
            .map(|(&x, &y)| self.pixel(x, y))
            .collect();
        for pair in pixels.windows(2) {
            if let [Some(from), Some(to)] = pair {
                draw_segment(canvas, *from, *to, LINE_WIDTH, colour);
            }
        }
        let half = 0.5 * MARKER_SIDE;
        for [px, py] in pixels.into_iter().flatten() {
            canvas.fill_rect([px - half, py - half, px + half, py + half], colour);
        }
    }

    /// Draws the legend: series `k`'s swatch in [`series_colour`]`(k)` and its name.
    pub fn draw_legend(&self, canvas: &mut Canvas, series: &[Series]) {
        for (k, s) in series.iter().enumerate() {
            let swatch = self.swatch(k);
            canvas.fill_rect(swatch, series_colour(k));
            self.write(canvas, s.name, [swatch[2] + 0.5 * self.gap, swatch[1]]);
        }
    }

    /// The horizontal line at y = 0 across the plot area, when the y range contains 0.
    fn draw_zero_line(&self, canvas: &mut Canvas) {
        let (lo, hi) = self.y_range;
        if !(lo < 0.0 && 0.0 < hi) {
            return;
        }
        if let Some([_, py]) = self.pixel(self.x_range.0, 0.0) {
            let half = 0.5 * AXIS_WIDTH;
            canvas.fill_rect(
                [self.area[0], py - half, self.area[2], py + half],
                ZERO_LINE_COLOUR,
            );
        }
    }

    /// The ticks with the pixel positions of the data points `point(tick)`, where finite.
    fn tick_pixels(
        &self,
        ticks: &[f64],
        point: impl Fn(f64) -> (f64, f64),
    ) -> Vec<(f64, [f64; 2])> {
        ticks
            .iter()
            .filter_map(|&tick| {
                let (x, y) = point(tick);
                Some((tick, self.pixel(x, y)?))
            })
            .collect()
    }

    fn write(&self, canvas: &mut Canvas, text: &str, top_left: [f64; 2]) {
        draw_text(canvas, text, top_left, self.text_size, TEXT_COLOUR);
    }

    /// Writes `text` horizontally centred on `centre`, its top at `top`.
    fn write_centred(&self, canvas: &mut Canvas, text: &str, centre: f64, top: f64) {
        let left = centre - 0.5 * text_width(text, self.text_size);
        self.write(canvas, text, [left, top]);
    }
}

/// The width of the widest of `texts` at font pixel size `size`, 0 for none.
fn widest<S: AsRef<str>>(texts: impl Iterator<Item = S>, size: f64) -> f64 {
    texts
        .map(|text| text_width(text.as_ref(), size))
        .fold(0.0, f64::max)
}

/// The y values of the points that can be drawn: both coordinates finite.
fn drawable_values(x: &[f64], series: &[Series]) -> Vec<f64> {
    series
        .iter()
        .flat_map(|s| x.iter().zip(s.values))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|(_, &y)| y)
        .collect()
}

/// The range an axis shows for data spanning `range`: widened when degenerate, `[0, 1]`
/// without data, padded by [`PADDING`] of the span at both ends.
fn axis_range(range: Option<(f64, f64)>) -> (f64, f64) {
    let (lo, hi) = widened(range.unwrap_or((0.0, 1.0)));
    // Scaling before subtracting keeps the pad finite where the span overflows (data near
    // ±f64::MAX); such ranges still end up infinite, and `pixel` then places nothing.
    let pad = PADDING * hi - PADDING * lo;
    (lo - pad, hi + pad)
}

/// `(lo, hi)`, or `v ∓ 0.1 |v|` when `lo = hi = v` (`∓ 1` when `v` is zero or too small for
/// a tenth of it to move it).
fn widened((lo, hi): (f64, f64)) -> (f64, f64) {
    if hi > lo {
        return (lo, hi);
    }
    let half = match 0.1 * lo.abs() {
        half if lo - half < lo => half,
        _ => 1.0,
    };
    (lo - half, hi + half)
}

/// The multiples of [`nice_step`] within `[lo, hi]`; none when there is no usable step.
fn nice_ticks((lo, hi): (f64, f64)) -> Vec<f64> {
    let Some(step) = nice_step(hi - lo) else {
        return Vec::new();
    };
    let (first, last) = ((lo / step).ceil() as i64, (hi / step).floor() as i64);
    (first..=last)
        .take(MAX_TICKS)
        .map(|k| k as f64 * step)
        .filter(|tick| tick.is_finite())
        .collect()
}

/// The step `m · 10ᵏ`, `m ∈ {1, 2, 5, 10}`, nearest `span / 5` (Heckbert's rounding of the
/// mantissa: below 1.5 → 1, below 3 → 2, below 7 → 5, else 10); `None` for a span that is not
/// positive and finite.
fn nice_step(span: f64) -> Option<f64> {
    let rough = span / TARGET_TICKS;
    if !(rough > 0.0 && rough.is_finite()) {
        return None;
    }
    let decade = 10f64.powf(rough.log10().floor());
    let mantissa = match rough / decade {
        m if m < 1.5 => 1.0,
        m if m < 3.0 => 2.0,
        m if m < 7.0 => 5.0,
        _ => 10.0,
    };
    Some(mantissa * decade).filter(|step| *step > 0.0 && step.is_finite())
}
