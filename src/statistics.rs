//! Medians of per-element values (faces, vertices, tracked points): the robust statistics that
//! the accuracy scores, the tracker's alignment and the flow's automatic scales (`auto` `λ`
//! and `ε`) share; and the mean of an image's channels per vertex, which readers, tracking and
//! the flow's grey picture share. Written by hand: short functions over
//! `select_nth_unstable`, a sort and a sum need no crate.

/// The (upper, for an even count) median of `values`; 0 for none.
pub fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let middle = values.len() / 2;
    *values.select_nth_unstable_by(middle, f64::total_cmp).1
}

/// The value at which the cumulative weight of the pairs `(w, e)` (NaN `e` left out), sorted by
/// `e`, first reaches half the total; NaN if there are none.
pub fn weighted_median(mut pairs: Vec<(f64, f64)>) -> f64 {
    pairs.retain(|(_, e)| !e.is_nan());
    pairs.sort_by(|a, b| a.1.total_cmp(&b.1));
    let half = 0.5 * pairs.iter().map(|(w, _)| w).sum::<f64>();
    let mut cumulative = 0.0;
    for (w, e) in &pairs {
        cumulative += w;
        if cumulative >= half {
            return *e;
        }
    }
    f64::NAN
}

/// The unweighted mean over channels per vertex (`channels[c][i]`).
pub fn channel_mean(channels: &[Vec<f64>]) -> Vec<f64> {
    let scale = 1.0 / channels.len() as f64;
    (0..channels.first().map_or(0, Vec::len))
        .map(|i| channels.iter().map(|c| c[i]).sum::<f64>() * scale)
        .collect()
}
