//! Colour maps for scalar values: a value `v` in the range `[min, max]` goes to
//! `t = (v − min) / (max − min)`, clamped to `[0, 1]`, and `t` to a colour.
//!
//! - [`grey`]: black (`t = 0`) to white (`t = 1`), for grey values (intensities);
//! - [`viridis`]: the perceptually uniform sequential map of matplotlib (via `colorous`),
//!   dark violet to yellow, for errors and other magnitudes.
//!
//! A degenerate range (`max ≤ min`) puts every value at `t = ½`. Non-finite values are black,
//! which viridis itself never shows.

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
    normalized(value, min, max).map_or([0.0; 3], |t| {
        let colour = colorous::VIRIDIS.eval_continuous(t);
        [colour.r, colour.g, colour.b].map(|c| c as f64 / 255.0)
    })
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
