//! The Middlebury colour coding: the reference's colours in the four axis directions, white at
//! zero, saturation growing with length, continuity around the wheel, the robust scale.

use meshflow::render::color_wheel::{flow_color, flow_colors, robust_max};
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
    // +π (v = −0): f_k = 54, the last MR entry (255, 0, 255 − ⌊1275/6⌋) = (255, 0, 43).
    assert_color(flow_color(1.0, -0.0), [1.0, 0.0, 43.0 / 255.0]);
}

#[test]
fn zero_is_white_and_saturation_grows_with_length() {
    assert_eq!(flow_color(0.0, 0.0), [1.0; 3]);
    let direction = [0.6, -0.8];
    let full = flow_color(direction[0], direction[1]);
    let mut previous = [1.0; 3];
    for step in 1..=10 {
        let r = step as f64 / 10.0;
        let colour = flow_color(r * direction[0], r * direction[1]);
        assert_color(colour, full.map(|c| 1.0 - r * (1.0 - c)));
        assert!(colour.iter().zip(previous).all(|(c, p)| *c <= p));
        previous = colour;
    }
    // Beyond the scale: the wheel colour dimmed by 0.75.
    assert_color(flow_color(1.2, -1.6), full.map(|c| 0.75 * c));
}

#[test]
fn non_finite_vectors_are_black() {
    assert_eq!(flow_color(f64::NAN, 0.0), [0.0; 3]);
    assert_eq!(flow_color(0.0, f64::INFINITY), [0.0; 3]);
}

#[test]
fn colours_are_continuous_around_the_circle_except_the_reference_seam() {
    let n = 3600;
    let colours: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let angle = 2.0 * PI * i as f64 / n as f64;
            flow_color(angle.cos(), angle.sin())
        })
        .collect();
    for i in 1..n {
        let jump = distance(colours[i - 1], colours[i]);
        assert!(jump < 0.01, "jump {jump} between samples {} and {i}", i - 1);
    }
    // The wheel's 55 entries span 54 intervals: closing the circle at +u jumps by 43/255.
    let seam = distance(colours[n - 1], colours[0]);
    assert!((seam - 43.0 / 255.0).abs() < 0.01, "seam jump {seam}");
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
