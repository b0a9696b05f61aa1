//! The Middlebury optical-flow colour coding, with its seam closed.
//!
//! Baker, Scharstein, Lewis, Roth, Black & Szeliski, "A Database and Evaluation Methodology for
//! Optical Flow", IJCV 92 (2011), code `computeColor.m` / `flowToColor`. A vector `(u, v)`,
//! already divided by a flow scale, gets
//!
//! ```text
//! hue:        a = atan2(−v, −u) / π ∈ [−1, 1],   f_k = (a + 1)/2 · (55 − 1)
//!             c = (1 − λ) W[⌊f_k⌋] + λ W[⌊f_k⌋ + 1],   λ = f_k − ⌊f_k⌋
//! saturation: r = |(u, v)|,   colour = 1 − r (1 − c)  for r ≤ 1,   0.75 c  for r > 1
//! ```
//!
//! with `W` the 55-colour wheel: red → yellow in 15 steps, yellow → green 6, green → cyan 4,
//! cyan → blue 11, blue → magenta 13, magenta → red 6, each entry `⌊255 i / n⌋ / 255` as in
//! the reference except the last segment's (see *The seam, closed*); the index `⌊f_k⌋ + 1`
//! is taken modulo 55. So the zero vector is white, `r = 1` gives the pure wheel colour, and
//! longer vectors are dimmed.
//!
//! # Orientation
//!
//! `u` plays the role of the reference's image `x` (right) and `v` of its image `y` (down):
//! `(1, 0)` is red, `(0, 1)` yellow-orange, `(−1, 0)` cyan-blue, `(0, −1)` violet. Applied to
//! intrinsic components in a vertex frame `(e₁, e₂)`, where `e₂` is `e₁` turned by +90°
//! (counter-clockwise seen from outside the surface), the hues therefore run red → yellow →
//! green → cyan → blue → magenta *counter-clockwise*, whereas on a Middlebury picture (y down)
//! they run clockwise on the screen: a surface picture is the mirror image of the usual key.
//!
//! # The seam, closed
//!
//! The reference spreads its 55 entries over 54 intervals, so its last entry `(1, 0, 43/255)`
//! and its first `(1, 0, 0)` are never blended: at the direction `+u` the blue channel jumps by
//! `43/255`, a seam on every picture of a rotating surface. Here the magenta → red segment
//! instead ramps blue down in `⌊255 i / 5⌋` steps, so its 6 entries run `255, 204, …, 51, 0`
//! and the last one *is* red: the wheel closes and the colour is Lipschitz in the angle
//! everywhere (at most `(64/255) · 54/(2π) ≈ 2.2` per radian, the green → cyan steps). Entries
//! 0–49, the first five segments and magenta itself, are the reference's, so every direction
//! but the last 5/54 of the turn (33°, from magenta towards `+u` coming from `−v`) gets
//! exactly the reference's colour.

use std::f64::consts::PI;

/// One segment of the wheel: `steps` entries from `start`, along which one channel ramps up
/// (`rising`) or down in steps of `⌊255 i / ramp⌋`. The reference's segments have
/// `ramp = steps` and end one step short of the next segment's start.
struct Segment {
    steps: usize,
    ramp: usize,
    start: [usize; 3],
    channel: usize,
    rising: bool,
}

const fn segment(steps: usize, start: [usize; 3], channel: usize, rising: bool) -> Segment {
    Segment {
        steps,
        ramp: steps,
        start,
        channel,
        rising,
    }
}

/// A segment whose last entry reaches the ramp's end (`ramp = steps − 1`): the closing one.
const fn closing_segment(steps: usize, start: [usize; 3], channel: usize, rising: bool) -> Segment {
    Segment {
        ramp: steps - 1,
        ..segment(steps, start, channel, rising)
    }
}

/// The wheel on a 0..=255 scale: the reference's, closed at red (see the module docs).
const SEGMENTS: [Segment; 6] = [
    segment(15, [255, 0, 0], 1, true),    // red → yellow: green rises
    segment(6, [255, 255, 0], 0, false),  // yellow → green: red falls
    segment(4, [0, 255, 0], 2, true),     // green → cyan: blue rises
    segment(11, [0, 255, 255], 1, false), // cyan → blue: green falls
    segment(13, [0, 0, 255], 0, true),    // blue → magenta: red rises
    closing_segment(6, [255, 0, 255], 2, false), // magenta → red: blue falls to 0
];
const WHEEL_SIZE: usize = 55;

/// Factor applied to vectors longer than the scale (the reference's "out of range" dimming).
const OUT_OF_RANGE_DIMMING: f64 = 0.75;

impl Segment {
    /// Entry `i < steps` of this segment, in `[0, 1]`; integer arithmetic as in the reference.
    fn entry(&self, i: usize) -> [f64; 3] {
        let ramp = 255 * i / self.ramp;
        let mut colour = self.start;
        colour[self.channel] = if self.rising { ramp } else { 255 - ramp };
        colour.map(|c| c as f64 / 255.0)
    }
}

/// Wheel entry `k` (taken modulo the wheel size).
fn wheel_entry(k: usize) -> [f64; 3] {
    let mut k = k % WHEEL_SIZE;
    for segment in &SEGMENTS {
        if k < segment.steps {
            return segment.entry(k);
        }
        k -= segment.steps;
    }
    unreachable!("the segments add up to WHEEL_SIZE")
}

/// The Middlebury colour of the vector `(u, v)` (already scaled so that length 1 is full
/// saturation), RGB in `[0, 1]`. See the module documentation for the orientation. Vectors
/// with a non-finite component are black (the reference's colour for unknown flow).
pub fn flow_color(u: f64, v: f64) -> [f64; 3] {
    if !(u.is_finite() && v.is_finite()) {
        return [0.0; 3];
    }
    let hue = wheel_color((-v).atan2(-u) / PI);
    let radius = u.hypot(v);
    hue.map(|c| {
        if radius <= 1.0 {
            1.0 - radius * (1.0 - c)
        } else {
            OUT_OF_RANGE_DIMMING * c
        }
    })
}

/// The wheel colour at `a ∈ [−1, 1]`, linearly interpolated between neighbouring entries
/// (`a = 1` is entry 54, red like entry 0, so both ends of the range give the same colour).
fn wheel_color(a: f64) -> [f64; 3] {
    let position = (a + 1.0) / 2.0 * (WHEEL_SIZE - 1) as f64;
    let k0 = position.floor() as usize;
    let fraction = position - k0 as f64;
    let (c0, c1) = (wheel_entry(k0), wheel_entry(k0 + 1));
    std::array::from_fn(|c| (1.0 - fraction) * c0[c] + fraction * c1[c])
}

/// A robust flow scale: the 99th percentile (nearest rank, `⌈0.99 n⌉`-th smallest) of the
/// finite, non-negative `speeds`, so a few outliers do not wash out the picture. Falls back to
/// the largest such speed when the percentile is zero, and to `1.0` when all speeds are zero
/// (or none is usable); the result is always positive.
pub fn robust_max(speeds: &[f64]) -> f64 {
    let mut usable: Vec<f64> = speeds
        .iter()
        .copied()
        .filter(|s| s.is_finite() && *s >= 0.0)
        .collect();
    if usable.is_empty() {
        return 1.0;
    }
    let rank = (99 * usable.len()).div_ceil(100);
    let (_, &mut percentile, _) = usable.select_nth_unstable_by(rank - 1, f64::total_cmp);
    let largest = usable.iter().copied().fold(0.0, f64::max);
    if percentile > 0.0 {
        percentile
    } else if largest > 0.0 {
        largest
    } else {
        1.0
    }
}

/// Below this fraction of [`robust_max`] a vector does not count as moving for
/// [`arrow_scale`].
pub const MOVING_FRACTION: f64 = 0.1;

/// The length of the reference arrow: the 75th percentile (nearest rank) of the speeds of the
/// moving part, those of at least [`MOVING_FRACTION`] of [`robust_max`]. Arrows are then
/// sized by the typical motion, where the 99th percentile of all speeds (a few fast spots)
/// made most of them dots; the faster quarter is drawn longer than the arrow spacing.
/// Positive, like [`robust_max`], which it never exceeds.
pub fn arrow_scale(speeds: &[f64]) -> f64 {
    let top = robust_max(speeds);
    let mut moving: Vec<f64> = (speeds.iter().copied())
        .filter(|s| s.is_finite() && *s >= MOVING_FRACTION * top)
        .collect();
    if moving.is_empty() {
        return top;
    }
    let rank = (3 * moving.len()).div_ceil(4);
    let (_, &mut typical, _) = moving.select_nth_unstable_by(rank - 1, f64::total_cmp);
    match typical > 0.0 {
        true => typical.min(top),
        false => top,
    }
}

/// [`flow_color`] of each vector divided by `scale`, a positive flow scale such as
/// [`robust_max`] of the speeds (a zero scale makes every vector non-finite, hence black).
pub fn flow_colors(vectors: &[[f64; 2]], scale: f64) -> Vec<[f64; 3]> {
    vectors
        .iter()
        .map(|&[u, v]| flow_color(u / scale, v / scale))
        .collect()
}
