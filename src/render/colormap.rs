//! Colour maps for scalar values: a value `v` in the range `[min, max]` goes to
//! `t = (v − min) / (max − min)`, clamped to `[0, 1]`, and `t` to a colour.
//!
//! | map | `t = 0` | `t = ½` | `t = 1` | for |
//! |---|---|---|---|---|
//! | [`grey`] | black | mid grey | white | grey values (intensities) |
//! | [`viridis`] | dark violet | teal | yellow | errors and other magnitudes |
//! | [`diverging`] | dark blue | near white | dark red | signed values: divergence, curl, areal rate |
//!
//! [`viridis`] is matplotlib's perceptually uniform sequential map and [`diverging`] is
//! ColorBrewer's RdBu read backwards (colorous's `RED_BLUE` runs red → blue, so it is
//! evaluated at `1 − t`): blue for low values, `#f1efed` exactly at the middle, red for high
//! ones, its two halves matched in lightness by design. Over a range from
//! [`symmetric_range`] the middle is zero, so the sign of a value is its hue.
//!
//! A degenerate range (`max ≤ min`) puts every value at `t = ½`. Non-finite values are black,
//! which none of the maps shows otherwise.

use super::color_wheel::robust_max;
use colorous::Gradient;

/// `t = (value − min)/(max − min)` clamped to [0, 1] (½ when `max ≤ min`); `None` for a
/// non-finite value.
fn normalized(value: f64, min: f64, max: f64) -> Option<f64> {
    if !value.is_finite() {
        return None;
    }
    Some(if max > min {
        ((value - min) / (max - min)).clamp(0.0, 1.0)
    } else {
        0.5
    })
}

/// Grey level `t` of `value` in `[min, max]` as RGB (black when `value` is not finite).
pub fn grey(value: f64, min: f64, max: f64) -> [f64; 3] {
    normalized(value, min, max).map_or([0.0; 3], |t| [t; 3])
}

/// The viridis colour of `value` in `[min, max]` as RGB (black when `value` is not finite).
pub fn viridis(value: f64, min: f64, max: f64) -> [f64; 3] {
    normalized(value, min, max).map_or([0.0; 3], |t| gradient_colour(colorous::VIRIDIS, t))
}

/// The diverging colour of `value` in `[min, max]` as RGB: blue at `min`, near white at the
/// middle, red at `max` (black when `value` is not finite).
pub fn diverging(value: f64, min: f64, max: f64) -> [f64; 3] {
    // RdBu starts at red; blue belongs to the low end.
    normalized(value, min, max).map_or([0.0; 3], |t| gradient_colour(colorous::RED_BLUE, 1.0 - t))
}

/// The colour of `gradient` at `t ∈ [0, 1]` as RGB in `[0, 1]`.
fn gradient_colour(gradient: Gradient, t: f64) -> [f64; 3] {
    let colour = gradient.eval_continuous(t);
    [colour.r, colour.g, colour.b].map(|c| c as f64 / 255.0)
}

/// A range `(−m, m)` centred on zero for [`diverging`]: `m` is the robust maximum of `|v|`
/// over the finite values ([`robust_max`]: the 99th percentile, nearest rank, so a few
/// outliers do not wash out the picture; the largest `|v|` when that percentile is zero), and
/// `(−1, 1)` when every value is zero or non-finite (or there is none).
pub fn symmetric_range(values: &[f64]) -> (f64, f64) {
    let magnitudes: Vec<f64> = values.iter().map(|v| v.abs()).collect();
    let m = robust_max(&magnitudes);
    (-m, m)
}

/// The smallest and largest finite value, `None` when there is no finite value.
pub fn finite_range(values: &[f64]) -> Option<(f64, f64)> {
    values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(None, |range, v| match range {
            None => Some((v, v)),
            Some((low, high)) => Some((v.min(low), v.max(high))),
        })
}
