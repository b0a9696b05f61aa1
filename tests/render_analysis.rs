//! Pictures for flow analysis: the diverging colour map and its symmetric range, signed
//! pictures (blue below zero, red above, with their colour bar), and line charts of series
//! (lines, markers, gaps at missing values, shared ranges, the legend, errors).

use image::RgbImage;
use meshflow::render::colormap::{diverging, symmetric_range};
use meshflow::render::legend::colour_bar_box;
use meshflow::render::plot::{series_colour, PlotLayout, ZERO_LINE_COLOUR};
use meshflow::render::{
    series_chart, signed_picture, Camera, Lighting, PictureStyle, RenderError, Series, Surface,
};
use meshflow::shapes::icosphere;
use nalgebra::Vector3;

/// Pixel `(x, y)` as RGB in [0, 1].
fn pixel(image: &RgbImage, x: u32, y: u32) -> [f64; 3] {
    image.get_pixel(x, y).0.map(|c| c as f64 / 255.0)
}

/// The pixel that contains the output-pixel position `at`.
fn pixel_at(image: &RgbImage, at: [f64; 2]) -> [f64; 3] {
    pixel(image, at[0] as u32, at[1] as u32)
}

fn max_difference(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f64::max)
}

/// Asserts that a stored pixel is within 0.25 of `colour` in every channel: a line's colour
/// where it may cover only most of the pixel.
fn assert_near(stored: [u8; 3], colour: [u8; 3]) {
    let near = (0..3).all(|c| (stored[c] as f64 - colour[c] as f64).abs() < 0.25 * 255.0);
    assert!(near, "{stored:?} is not near {colour:?}");
}

/// The stored pixel that contains the output-pixel position `at`.
fn pixel_at_bytes(image: &RgbImage, at: [f64; 2]) -> [u8; 3] {
    image.get_pixel(at[0] as u32, at[1] as u32).0
}

/// The stored pixel that contains the output-pixel position `at`.
/// A colour as the 8 bits a picture stores.
fn bytes(colour: [f64; 3]) -> [u8; 3] {
    colour.map(|c| (c * 255.0).round() as u8)
}

const WHITE: [u8; 3] = [255; 3];

#[test]
fn diverging_map_runs_from_blue_through_white_to_red() {
    let low = diverging(-1.0, -1.0, 1.0);
    let middle = diverging(0.0, -1.0, 1.0);
    let high = diverging(1.0, -1.0, 1.0);
    assert!(low[2] > low[0] + 0.2, "{low:?}");
    assert!(middle.iter().all(|&c| c > 0.9), "{middle:?}");
    assert!(high[0] > high[2] + 0.2, "{high:?}");
    // RdBu's ends, #053061 and #67001f, and the B-spline's value at its middle knot,
    // (#fddbc7 + 4 · #f7f7f7 + #d1e5f0)/6 = #f1efed; colorous truncates its f32 spline to
    // bytes, which at the blue end lands just below the knot colour in every channel.
    assert_eq!(bytes(low), [4, 47, 96]);
    assert_eq!(bytes(middle), [241, 239, 237]);
    assert_eq!(bytes(high), [103, 0, 31]);
    // Clamped outside the range, the middle for a degenerate range, black when not finite.
    assert_eq!(diverging(-7.0, -1.0, 1.0), low);
    assert_eq!(diverging(7.0, -1.0, 1.0), high);
    assert_eq!(diverging(3.0, 2.0, 2.0), middle);
    assert_eq!(diverging(f64::NAN, -1.0, 1.0), [0.0; 3]);
    assert_eq!(diverging(f64::NEG_INFINITY, -1.0, 1.0), [0.0; 3]);
    // Any range: its middle is white, so (2, 6) puts white at 4.
    assert_eq!(diverging(4.0, 2.0, 6.0), middle);
}

#[test]
fn symmetric_range_is_the_robust_largest_magnitude() {
    // |v| = {3, 1}: the 99th percentile by nearest rank, ⌈0.99 · 2⌉ = 2nd smallest, is 3.
    assert_eq!(symmetric_range(&[-3.0, 1.0, f64::NAN]), (-3.0, 3.0));
    // 1, −2, 3, …, −200 and one outlier: rank ⌈0.99 · 201⌉ = 199, so m = 199, not 10⁶.
    let mut values: Vec<f64> = (1..=200)
        .map(|k| if k % 2 == 0 { -k as f64 } else { k as f64 })
        .collect();
    values.push(1e6);
    assert_eq!(symmetric_range(&values), (-199.0, 199.0));
    // A zero percentile falls back to the largest magnitude.
    let mut zeros = vec![0.0; 200];
    zeros.push(-5.0);
    assert_eq!(symmetric_range(&zeros), (-5.0, 5.0));
    // Nothing to go by: (−1, 1).
    assert_eq!(
        symmetric_range(&[0.0, f64::NAN, f64::INFINITY]),
        (-1.0, 1.0)
    );
    assert_eq!(symmetric_range(&[]), (-1.0, 1.0));
}

/// Looks at the origin from `eye` with +y up on the screen.
fn camera_from(eye: Vector3<f64>, width: u32, height: u32) -> Camera {
    Camera::look_at(eye, Vector3::zeros(), Vector3::y(), 30.0, width, height).unwrap()
}

/// The leftmost of `columns` in which a dark grey (text) pixel lies within `rows`.
fn leftmost_dark(
    image: &RgbImage,
    columns: std::ops::Range<u32>,
    rows: std::ops::Range<u32>,
) -> Option<u32> {
    let dark_grey = |[r, g, b]: [f64; 3]| r + g + b < 1.5 && (r - b).abs() < 0.1;
    columns
        .into_iter()
        .find(|&x| rows.clone().any(|y| dark_grey(pixel(image, x, y))))
}

#[test]
fn signed_picture_shows_negative_blue_and_positive_red_with_its_bar() {
    let sphere = icosphere(4);
    let values: Vec<f64> = sphere.positions.iter().map(|p| p.z).collect();
    let range = symmetric_range(&values);
    // |z| is uniform on [0, 1] over the unit sphere, so its 99th percentile is near 0.99.
    assert!((0.97..1.0).contains(&range.1), "{range:?}");
    let style = PictureStyle {
        lighting: Lighting::unlit(),
        ..PictureStyle::default()
    };
    let (width, height) = (320, 120);
    let picture = |eye: Vector3<f64>| {
        let camera = camera_from(eye, width, height);
        let image = signed_picture(&camera, Surface::from(&sphere), &values, range, &style);
        (camera, image.unwrap())
    };
    // Each pole, seen from above it, projects to the centre and is coloured by the end of the
    // map: every vertex near it has |z| beyond the range.
    for (pole, end) in [(Vector3::z(), range.1), (-Vector3::z(), range.0)] {
        let (camera, image) = picture(4.0 * pole);
        let [x, y, _] = camera.project(&pole).unwrap();
        let colour = pixel_at(&image, [x, y]);
        let expected = diverging(end, range.0, range.1);
        assert!(
            max_difference(colour, expected) < 0.02,
            "{colour:?} vs {expected:?}"
        );
    }
    let (_, top_view) = picture(4.0 * Vector3::z());
    let red = pixel(&top_view, 160, 60);
    assert!(red[0] > red[2] + 0.2, "{red:?}");
    let (_, bottom_view) = picture(-4.0 * Vector3::z());
    let blue = pixel(&bottom_view, 160, 60);
    assert!(blue[2] > blue[0] + 0.2, "{blue:?}");
    // The bar: red at the top, white in the middle, blue at the bottom.
    let [x0, y0, x1, y1] = colour_bar_box(width, height);
    let bar_value = |y: f64| range.0 + (y1 - y) / (y1 - y0) * (range.1 - range.0);
    for y in [y0 + 2.0, 0.5 * (y0 + y1), y1 - 2.0] {
        let centre_y = y.floor() + 0.5;
        let colour = pixel_at(&top_view, [0.5 * (x0 + x1), y]);
        let expected = diverging(bar_value(centre_y), range.0, range.1);
        assert!(
            max_difference(colour, expected) < 0.03,
            "y = {y}: {colour:?}"
        );
    }
    assert!(pixel_at(&top_view, [0.5 * (x0 + x1), y0 + 2.0])[0] > 0.35);
    assert!(pixel_at(&top_view, [0.5 * (x0 + x1), y1 - 2.0])[2] > 0.35);
    // Its labels, right-aligned left of it: the bottom one, "-0.99x", starts one character
    // (8 pixels at this height) further left than the top one, "0.99x": the minus sign.
    // Columns right of the sphere (radius ≈ 58 pixels about x = 160) and left of the bar.
    let columns = 3 * width / 4..x0 as u32 - 1;
    let label_rows = |y: f64| (y as u32 - 4)..(y as u32 + 4);
    let top_label = leftmost_dark(&top_view, columns.clone(), label_rows(y0)).unwrap();
    let bottom_label = leftmost_dark(&top_view, columns, label_rows(y1)).unwrap();
    assert_eq!(top_label, bottom_label + 8);
}

#[test]
fn signed_picture_rejects_what_scalar_pictures_reject() {
    let sphere = icosphere(2);
    let camera = camera_from(4.0 * Vector3::z(), 40, 30);
    let surface = Surface::from(&sphere);
    let style = PictureStyle::default();
    let n = sphere.positions.len();
    assert!(matches!(
        signed_picture(&camera, surface, &vec![0.0; n - 1], (-1.0, 1.0), &style),
        Err(RenderError::CountMismatch { got, .. }) if got == n - 1
    ));
    assert!(matches!(
        signed_picture(&camera, surface, &vec![0.0; n], (1.0, -1.0), &style),
        Err(RenderError::Range { .. })
    ));
    // Non-finite values are drawn (black), not errors.
    let mut values = vec![0.5; n];
    values[0] = f64::NAN;
    signed_picture(&camera, surface, &values, (-1.0, 1.0), &style).unwrap();
}

/// x = 0, 1, …, 10.
fn steps() -> Vec<f64> {
    (0..=10).map(f64::from).collect()
}

#[test]
fn series_chart_draws_lines_markers_and_the_legend() {
    let x = steps();
    let rising: Vec<f64> = x.clone();
    let falling: Vec<f64> = x.iter().map(|x| 10.0 - x).collect();
    let series = [
        Series {
            name: "rising",
            values: &rising,
        },
        Series {
            name: "falling",
            values: &falling,
        },
    ];
    let (width, height) = (480, 320);
    let image = series_chart("means", "t", &x, &series, width, height).unwrap();
    assert_eq!(image.dimensions(), (width, height));
    let layout = PlotLayout::new(width, height, &x, &series);
    let [x0, y0, x1, y1] = layout.area;
    let (plot_width, plot_height) = (x1 - x0, y1 - y0);
    assert!(plot_width > 0.6 * width as f64 && plot_height > 0.6 * height as f64);
    let at = |x: f64, y: f64| layout.pixel(x, y).unwrap();
    let colour_at = |x: f64, y: f64| pixel_at_bytes(&image, at(x, y));
    let blue = bytes(series_colour(0));
    let orange = bytes(series_colour(1));
    assert_eq!(blue, [31, 119, 180]);
    assert_eq!(orange, [255, 127, 14]);
    // The rising series starts near the lower-left corner and ends near the upper-right one
    // (5 % padding of the range on each side), in its colour, and is a line in between.
    let [start_x, start_y] = at(0.0, 0.0);
    let [end_x, end_y] = at(10.0, 10.0);
    assert!((start_x - x0 - plot_width / 22.0).abs() < 1e-9);
    assert!((y1 - start_y - plot_height / 22.0).abs() < 1e-9);
    assert!((x1 - end_x - plot_width / 22.0).abs() < 1e-9);
    assert!((end_y - y0 - plot_height / 22.0).abs() < 1e-9);
    assert_eq!(colour_at(0.0, 0.0), blue);
    assert_eq!(colour_at(10.0, 10.0), blue);
    assert_near(colour_at(2.5, 2.5), blue);
    // Away from both lines: white; the falling series in its own colour.
    assert_eq!(colour_at(7.5, 5.0), WHITE);
    assert_eq!(colour_at(0.0, 10.0), orange);
    assert_near(colour_at(7.5, 2.5), orange);
    // The legend's swatches, right of the plot area.
    for (k, colour) in [(0, blue), (1, orange)] {
        let [sx0, sy0, sx1, sy1] = layout.swatch(k);
        assert!(sx0 > x1, "{sx0} {x1}");
        let centre = [0.5 * (sx0 + sx1), 0.5 * (sy0 + sy1)];
        assert_eq!(
            image.get_pixel(centre[0] as u32, centre[1] as u32).0,
            colour
        );
    }
    // The axes: a dark line along the left and bottom edges of the plot area.
    let darkest = |pixels: &mut dyn Iterator<Item = (u32, u32)>| {
        pixels
            .map(|(x, y)| pixel(&image, x, y)[0])
            .fold(1.0, f64::min)
    };
    let middle_row = (0.5 * (y0 + y1)) as u32;
    let middle_column = (0.5 * (x0 + x1)) as u32;
    assert!(darkest(&mut (x0 as u32 - 2..x0 as u32 + 1).map(|x| (x, middle_row))) < 0.5);
    assert!(darkest(&mut (y1 as u32 - 1..y1 as u32 + 2).map(|y| (middle_column, y))) < 0.5);
    // The corners stay white.
    assert_eq!(image.get_pixel(0, height - 1).0, WHITE);
    assert_eq!(image.get_pixel(width - 1, height - 1).0, WHITE);
}

#[test]
fn series_share_one_padded_range() {
    let x = steps();
    let small: Vec<f64> = x.iter().map(|x| 0.1 * x).collect();
    let mut large = x.clone();
    large[3] = -2.0;
    let series = [
        Series {
            name: "small",
            values: &small,
        },
        Series {
            name: "large",
            values: &large,
        },
    ];
    let layout = PlotLayout::new(400, 300, &x, &series);
    // y over both series, [−2, 10], padded by 5 % of 12; x [0, 10] padded by 0.5.
    let close =
        |(a, b): (f64, f64), (c, d): (f64, f64)| (a - c).abs() < 1e-12 && (b - d).abs() < 1e-12;
    assert!(close(layout.y_range, (-2.6, 10.6)), "{:?}", layout.y_range);
    assert!(close(layout.x_range, (-0.5, 10.5)), "{:?}", layout.x_range);
    // A constant series is widened by a tenth of its value before padding.
    let constant = [3.0; 11];
    let flat = [Series {
        name: "flat",
        values: &constant,
    }];
    let layout = PlotLayout::new(400, 300, &x, &flat);
    assert!(close(layout.y_range, (2.67, 3.33)), "{:?}", layout.y_range);
    // Zero, and no finite value at all.
    let zero = [Series {
        name: "zero",
        values: &[0.0; 11],
    }];
    assert!(close(
        PlotLayout::new(400, 300, &x, &zero).y_range,
        (-1.1, 1.1)
    ));
    let none = [Series {
        name: "none",
        values: &[f64::NAN; 11],
    }];
    assert!(close(
        PlotLayout::new(400, 300, &x, &none).y_range,
        (-0.05, 1.05)
    ));
}

#[test]
fn series_chart_draws_a_zero_line_when_the_values_span_zero() {
    let x = steps();
    let values: Vec<f64> = x.iter().map(|x| x - 5.0).collect();
    let series = [Series {
        name: "shifted",
        values: &values,
    }];
    let image = series_chart("", "", &x, &series, 400, 300).unwrap();
    let layout = PlotLayout::new(400, 300, &x, &series);
    // At x = 1 the line is at −4: the zero line there is grey (blended where it covers part
    // of a pixel row), and the pixels well above and below it are white.
    let [px, py] = layout.pixel(1.0, 0.0).unwrap();
    let column: Vec<[f64; 3]> = (py as u32 - 1..=py as u32 + 1)
        .map(|y| pixel(&image, px as u32, y))
        .collect();
    let greyest = column.iter().map(|c| c[0]).fold(1.0, f64::min);
    assert!(
        (ZERO_LINE_COLOUR[0] - 1e-9..0.9).contains(&greyest),
        "{column:?}"
    );
    assert!(
        column.iter().all(|c| c[0] == c[1] && c[1] == c[2]),
        "{column:?}"
    );
    assert_eq!(image.get_pixel(px as u32, py as u32 - 8).0, WHITE);
    assert_eq!(image.get_pixel(px as u32, py as u32 + 8).0, WHITE);
}

#[test]
fn missing_values_break_the_line_and_lone_points_still_show() {
    let x = [0.0, 1.0, 2.0, 3.0, 4.0];
    let gappy = [0.0, 1.0, f64::NAN, 3.0, 4.0];
    let series = [Series {
        name: "gappy",
        values: &gappy,
    }];
    let image = series_chart("gap", "t", &x, &series, 300, 200).unwrap();
    let layout = PlotLayout::new(300, 200, &x, &series);
    let colour = bytes(series_colour(0));
    let colour_at = |x: f64, y: f64| pixel_at_bytes(&image, layout.pixel(x, y).unwrap());
    assert_eq!(colour_at(1.0, 1.0), colour);
    assert_eq!(colour_at(3.0, 3.0), colour);
    assert_near(colour_at(0.5, 0.5), colour);
    // Bridging the gap would pass through (2, 2).
    assert_eq!(colour_at(2.0, 2.0), WHITE);
    assert_eq!(colour_at(1.5, 1.5), WHITE);

    // A non-finite x breaks the line too.
    let x_gap = [0.0, 1.0, f64::NAN, 3.0, 4.0];
    let line = [0.0, 1.0, 2.0, 3.0, 4.0];
    let series = [Series {
        name: "line",
        values: &line,
    }];
    let image = series_chart("gap", "t", &x_gap, &series, 300, 200).unwrap();
    let layout = PlotLayout::new(300, 200, &x_gap, &series);
    assert_eq!(
        pixel_at_bytes(&image, layout.pixel(2.0, 2.0).unwrap()),
        WHITE
    );
    assert_eq!(
        pixel_at_bytes(&image, layout.pixel(3.0, 3.0).unwrap()),
        colour
    );

    // One series of one point: a marker at the centre of the (widened) ranges.
    let lone = [Series {
        name: "lone",
        values: &[2.0],
    }];
    let image = series_chart("one", "t", &[5.0], &lone, 200, 150).unwrap();
    let layout = PlotLayout::new(200, 150, &[5.0], &lone);
    let [x0, y0, x1, y1] = layout.area;
    let centre = layout.pixel(5.0, 2.0).unwrap();
    assert!((centre[0] - 0.5 * (x0 + x1)).abs() < 1e-9);
    assert!((centre[1] - 0.5 * (y0 + y1)).abs() < 1e-9);
    assert_eq!(pixel_at_bytes(&image, centre), colour);

    // Nothing finite, nothing at all, extreme values: pictures, no panics.
    let all_nan = [Series {
        name: "nan",
        values: &[f64::NAN; 3],
    }];
    let image = series_chart("nan", "t", &[0.0, 1.0, 2.0], &all_nan, 200, 150).unwrap();
    let plot = PlotLayout::new(200, 150, &[0.0, 1.0, 2.0], &all_nan).area;
    let inside = |x: u32, y: u32| {
        (plot[0] as u32 + 1..plot[2] as u32).contains(&x)
            && (plot[1] as u32..plot[3] as u32).contains(&y)
    };
    assert!(!image
        .enumerate_pixels()
        .any(|(x, y, p)| inside(x, y) && p.0 == colour));
    series_chart("", "", &[], &[], 16, 16).unwrap();
    let empty = [Series {
        name: "empty",
        values: &[],
    }];
    series_chart("empty", "t", &[], &empty, 100, 100).unwrap();
    let extreme = [Series {
        name: "huge",
        values: &[-f64::MAX, f64::MAX, f64::INFINITY],
    }];
    series_chart("huge", "t", &[0.0, 1.0, 2.0], &extreme, 100, 100).unwrap();
}

#[test]
fn series_chart_rejects_bad_sizes_and_mismatched_lengths() {
    let x = [0.0, 1.0, 2.0, 3.0];
    let fine = [1.0, 2.0, 3.0, 4.0];
    let short = [1.0, 2.0, 3.0];
    let good = Series {
        name: "mean divergence",
        values: &fine,
    };
    for (width, height) in [(15, 100), (100, 15), (8193, 100), (100, 8193), (0, 0)] {
        let error = series_chart("", "", &x, &[good], width, height).unwrap_err();
        assert!(matches!(error, RenderError::Size { .. }), "{error:?}");
        assert!(error.to_string().contains("between 16 and 8192"), "{error}");
    }
    series_chart("", "", &x, &[good], 16, 16).unwrap();
    let bad = Series {
        name: "mean curl",
        values: &short,
    };
    let error = series_chart("", "", &x, &[good, bad], 200, 100).unwrap_err();
    assert_eq!(
        error,
        RenderError::SeriesLength {
            name: "mean curl".into(),
            expected: 4,
            got: 3
        }
    );
    let message = meshflow::Error::from(error).to_string();
    assert!(message.contains("\"mean curl\" has 3 values"), "{message}");
}
