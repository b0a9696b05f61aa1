//! The Middlebury colour coding: the reference's colours in the four axis directions and on its
//! first 49 intervals, the closed seam (Lipschitz all the way round), white at zero,
//! saturation growing with length, the robust scale.

use meshflow::render::color_wheel::{arrow_scale, flow_color, flow_colors, robust_max};
use std::f64::consts::PI;

fn assert_color(actual: [f64; 3], expected: [f64; 3]) {
    for (a, e) in actual.iter().zip(expected) {
        assert!((a - e).abs() < 1e-12, "{actual:?} != {expected:?}");
    }
}

/// Largest channel difference.
fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f64::max)
}

/// The unit vector at `angle` (radians from `+u` towards `+v`).
fn at_angle(angle: f64) -> [f64; 3] {
    flow_color(angle.cos(), angle.sin())
}

/// Worked by hand from `computeColor.m`: `f_k = (atan2(−v, −u)/π + 1)/2 · 54`, wheel entries
/// RY 0–14, YG 15–20, GC 21–24, CB 25–35, BM 36–48, MR 49–54, each `⌊255 i / n⌋`.
#[test]
fn axis_directions_get_the_reference_colours() {
    // atan2(−0, −1) = −π: f_k = 0, entry 0 = (255, 0, 0).
    assert_color(flow_color(1.0, 0.0), [1.0, 0.0, 0.0]);
    // −π/2: f_k = 13.5, halfway between RY entries 13 (255, 221, 0) and 14 (255, 238, 0).
    assert_color(flow_color(0.0, 1.0), [1.0, 229.5 / 255.0, 0.0]);
    // −0: f_k = 27, CB entry 2: (0, 255 − ⌊510/11⌋, 255) = (0, 209, 255).
    assert_color(flow_color(-1.0, 0.0), [0.0, 209.0 / 255.0, 1.0]);
    // π/2: f_k = 40.5, between BM entries 4 (⌊1020/13⌋ = 78, 0, 255) and 5 (98, 0, 255).
    assert_color(flow_color(0.0, -1.0), [88.0 / 255.0, 0.0, 1.0]);
    // +π (v = −0): f_k = 54, the last MR entry. The reference's is (255, 0, 43); the closed
    // wheel's is red, as at −π (v = +0).
    assert_color(flow_color(1.0, -0.0), [1.0, 0.0, 0.0]);
}

/// The colour at wheel position `f_k ∈ (0, 54)`: `a = f_k/27 − 1 = atan2(−v, −u)/π`, so
/// `(−u, −v) = (cos πa, sin πa)`.
fn at_position(f_k: f64) -> [f64; 3] {
    let angle = PI * (f_k / 27.0 - 1.0);
    flow_color(-angle.cos(), -angle.sin())
}

/// Entries 0–49 are the reference's, so on the intervals between them the colour is the
/// reference's blend: the middle of an interval in each of the first five segments, with the
/// entries `⌊255 i / n⌋` worked by hand.
#[test]
fn the_first_49_intervals_are_the_reference_blend() {
    let cases: [(f64, [f64; 3]); 6] = [
        // RY entries 3 (255, 51, 0) and 4 (255, 68, 0).
        (3.5, [255.0, 59.5, 0.0]),
        // YG entries 16 (255 − 42, 255, 0) and 17 (255 − 85, 255, 0).
        (16.5, [191.5, 255.0, 0.0]),
        // GC entries 22 (0, 255, 63) and 23 (0, 255, 127).
        (22.5, [0.0, 255.0, 95.0]),
        // CB entries 30 (0, 255 − 115, 255) and 31 (0, 255 − 139, 255).
        (30.5, [0.0, 128.0, 255.0]),
        // BM entries 40 (78, 0, 255) and 41 (98, 0, 255).
        (40.5, [88.0, 0.0, 255.0]),
        // BM's last entry 48 (235, 0, 255) and MR's first, 49 = magenta.
        (48.5, [245.0, 0.0, 255.0]),
    ];
    for (f_k, expected) in cases {
        assert_color(at_position(f_k), expected.map(|c| c / 255.0));
    }
}

/// The closing segment: entries 49–54 have blue `255 − ⌊255 i / 5⌋` (the reference's
/// `255 − ⌊255 i / 6⌋` ends at 43), red 255 and green 0.
#[test]
fn the_closing_segment_ramps_magenta_down_to_red() {
    let blues = [255.0, 204.0, 153.0, 102.0, 51.0, 0.0];
    for (i, blue) in blues.into_iter().enumerate() {
        let colour = at_position((49 + i) as f64 - 1e-9);
        let expected = [1.0, 0.0, blue / 255.0];
        assert!(
            distance(colour, expected) < 1e-6,
            "entry {}: {colour:?}",
            49 + i
        );
    }
    // Halfway between entries 51 and 52.
    assert_color(at_position(51.5), [1.0, 0.0, 127.5 / 255.0]);
}

/// The steepest interval is green → cyan: 64/255 in 1/54 of the turn.
const LIPSCHITZ_PER_RADIAN: f64 = 64.0 / 255.0 * 54.0 / (2.0 * PI);

#[test]
fn colours_are_lipschitz_in_the_angle_all_the_way_round() {
    let n = 100_000;
    let step = 2.0 * PI / n as f64;
    // Start half a turn away so the old seam at angle 0 (= 2π) lies inside the sweep.
    for i in 0..=n {
        let angle = -PI + i as f64 * step;
        let jump = distance(at_angle(angle), at_angle(angle + step));
        assert!(
            jump <= LIPSCHITZ_PER_RADIAN * step * (1.0 + 1e-6),
            "jump {jump} between {angle} and {} rad (bound {})",
            angle + step,
            LIPSCHITZ_PER_RADIAN * step
        );
    }
}

/// Across `+u` from either side, down to the last bits of the angle: the reference jumps by
/// 43/255 here, the closed wheel by no more than the Lipschitz bound.
#[test]
fn there_is_no_seam_at_plus_u() {
    for epsilon in [1e-3, 1e-6, 1e-9, 1e-12, 1e-15] {
        let (below, above) = (at_angle(-epsilon), at_angle(epsilon));
        let jump = distance(below, above);
        assert!(
            jump <= LIPSCHITZ_PER_RADIAN * 2.0 * epsilon * (1.0 + 1e-6) + 1e-15,
            "jump {jump} across +u at ±{epsilon}: {below:?} / {above:?}"
        );
    }
    // The sign of a zero v picks a side of atan2's branch cut: both sides are red.
    assert_eq!(flow_color(1.0, 0.0), flow_color(1.0, -0.0));
}

#[test]
fn all_channels_stay_in_the_unit_interval() {
    for i in 0..720 {
        let angle = PI * i as f64 / 360.0;
        for r in [0.0, 0.3, 1.0, 5.0] {
            let colour = flow_color(r * angle.cos(), r * angle.sin());
            assert!(colour.iter().all(|c| (0.0..=1.0).contains(c)), "{colour:?}");
        }
    }
}

#[test]
fn robust_max_is_the_99th_percentile_of_usable_speeds() {
    let speeds: Vec<f64> = (1..=100).map(f64::from).collect();
    assert_eq!(robust_max(&speeds), 99.0);
    let mut noisy = speeds.clone();
    noisy.extend([f64::NAN, f64::INFINITY, -5.0]);
    assert_eq!(robust_max(&noisy), 99.0);
    assert_eq!(robust_max(&[3.0]), 3.0);
    // Fewer than 1 % moving: the percentile is 0, so the largest speed is used.
    let mut mostly_still = vec![0.0; 1000];
    mostly_still[17] = 5.0;
    assert_eq!(robust_max(&mostly_still), 5.0);
    assert_eq!(robust_max(&[0.0, 0.0]), 1.0);
    assert_eq!(robust_max(&[]), 1.0);
}

#[test]
fn flow_colors_divides_by_the_scale() {
    let colours = flow_colors(&[[2.0, 0.0], [0.0, 0.0], [-1.0, 0.0]], 2.0);
    assert_color(colours[0], [1.0, 0.0, 0.0]);
    assert_eq!(colours[1], [1.0; 3]);
    assert_color(colours[2], [0.5, (1.0 + 209.0 / 255.0) / 2.0, 1.0]);
}

/// Arrows are sized by the moving part: 900 vertices at rest (below a tenth of the robust
/// maximum), 100 moving at 1…4 and 2 % fast ones at 7: the 75th percentile of the moving.
#[test]
fn the_arrow_scale_is_the_typical_speed_of_the_moving_part() {
    let mut speeds = vec![0.01; 900];
    speeds.extend((0..100).map(|i| 1.0 + 3.0 * i as f64 / 99.0));
    speeds.extend([7.0; 20]);
    assert_eq!(robust_max(&speeds), 7.0);
    // 120 moving speeds: the 90th smallest.
    let mut moving: Vec<f64> = speeds.iter().copied().filter(|&s| s >= 0.7).collect();
    moving.sort_by(f64::total_cmp);
    assert_eq!(moving.len(), 120);
    assert_eq!(arrow_scale(&speeds), moving[89]);
    assert!((arrow_scale(&speeds) - (1.0 + 3.0 * 89.0 / 99.0)).abs() < 1e-12);
    // At rest everywhere, and one speed: the robust maximum's fall-backs.
    assert_eq!(arrow_scale(&[0.0; 5]), 1.0);
    assert_eq!(arrow_scale(&[2.5]), 2.5);
    assert_eq!(arrow_scale(&[f64::NAN, 3.0, 3.0]), 3.0);
}
