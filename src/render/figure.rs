//! Whole pictures of a surface and data on it, as the CLI and the examples draw them.
//!
//! Each picture draws the surface with one colour per vertex (interpolated perspective-
//! correctly and Lambert-shaded, see [`super::raster`]), adds its key, the optional label line
//! in the top-left, and downsamples:
//!
//! | picture | vertex colour | key |
//! |---|---|---|
//! | [`grey_picture`] | `grey(I_i)` over the range | – |
//! | [`flow_picture`] | `flow_color(screen_components(u_i) / scale)` | colour wheel, rim = `scale` |
//! | [`arrow_picture`] | `grey(I_i)`, plus arrows of `u_i` | reference arrow of length `scale` |
//! | [`scalar_picture`] | `viridis(v_i)` over the range | colour bar with min and max |
//! | [`signed_picture`] | `diverging(v_i)` over the range (blue < middle < red) | colour bar with its negative and positive ends |
//! | [`trajectory_picture`] | grey values, with paths of moving points as polylines (viridis along time) | a dot at each path's end |
//!
//! Arrays must have one entry per vertex, faces must name existing vertices, scales must be
//! positive and ranges finite with `min ≤ max`, or a [`RenderError`] says which is wrong.
//! Non-finite values are drawn black, non-finite positions leave out their faces.
//! [`chart_picture`] shows per-vertex colours of a parameter grid flat, without a camera, and
//! [`series_chart`] draws line charts of series against x (see [`super::plot`]).

use super::camera::{Camera, MAX_IMAGE_SIDE};
use super::color_wheel::flow_color;
use super::colormap::{diverging, grey, viridis};
use super::error::{check_count, check_positive};
use super::glyphs::{draw_arrows, draw_point_arrows, reference_arrow_length, ArrowStyle};
use super::legend::{draw_arrow_key, draw_colour_bar, draw_title, draw_wheel_legend};
pub use super::plot::Series;
use super::plot::{check_chart_size, check_series_lengths, series_colour, PlotLayout};
use super::raster::{Canvas, DEFAULT_SUPERSAMPLE};
use super::shading::Lighting;
use super::RenderError;
use crate::format::{write_atomically, IoError};
use image::codecs::png::PngEncoder;
use image::RgbImage;
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// A surface to draw: positions and counter-clockwise (or any) triangles indexing them.
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    pub positions: &'a [Vector3<f64>],
    pub faces: &'a [[u32; 3]],
}

impl<'a> From<&'a crate::shapes::Surface> for Surface<'a> {
    fn from(surface: &'a crate::shapes::Surface) -> Self {
        Self {
            positions: &surface.positions,
            faces: &surface.faces,
        }
    }
}

/// How pictures are drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct PictureStyle {
    /// Samples per pixel along each axis (antialiasing), 1 to 8 (lowered for huge pictures,
    /// see [`Canvas::new`]).
    pub supersample: u32,
    pub lighting: Lighting,
    /// Distance between arrows in output pixels.
    pub arrow_spacing: f64,
    /// A line written in the top-left corner, e.g. `slab 3  t = 0.30`.
    pub label: Option<String>,
    /// Per vertex: no data there (e.g. outside the recording the image was sampled from);
    /// such vertices are drawn in [`NO_DATA_COLOUR`] whatever their value.
    pub no_data: Option<Vec<bool>>,
}

/// The colour of vertices without data: a light blue-grey, apart from the grey scale's black
/// (a vertex outside a recording reads 0) and from the flow wheel's saturated colours.
pub const NO_DATA_COLOUR: [f64; 3] = [0.62, 0.64, 0.72];

impl Default for PictureStyle {
    /// Supersample 3, the default light, arrows 28 pixels apart, no label.
    fn default() -> Self {
        Self {
            supersample: DEFAULT_SUPERSAMPLE,
            lighting: Lighting::default(),
            arrow_spacing: ArrowStyle::default().spacing,
            label: None,
            no_data: None,
        }
    }
}

impl PictureStyle {
    fn arrows(&self) -> ArrowStyle {
        ArrowStyle {
            spacing: self.arrow_spacing,
            ..ArrowStyle::default()
        }
    }
}

/// A pseudo-random grey in [0, 1) for each of `n` vertices (a fixed hash of the index), so that
/// a [`grey_picture`] shows the triangulation itself: how meshes of one surface differ.
pub fn mosaic_values(n: usize) -> Vec<f64> {
    (0..n as u64)
        .map(|i| {
            let x = i.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            ((x ^ (x >> 29)) >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

/// The surface with every vertex a [`mosaic_values`] grey, labelled: a picture of the
/// triangulation (how a tracked mesh rides along, how remeshed frames differ).
pub fn mosaic_picture(
    camera: &Camera,
    surface: Surface,
    label: String,
) -> Result<RgbImage, RenderError> {
    let style = PictureStyle {
        label: Some(label),
        ..Default::default()
    };
    let values = mosaic_values(surface.positions.len());
    grey_picture(camera, surface, &values, (0.0, 1.0), &style)
}

/// The surface shaded in grey: `intensity` (one per vertex) mapped over `range` = (black,
/// white).
pub fn grey_picture(
    camera: &Camera,
    surface: Surface,
    intensity: &[f64],
    range: (f64, f64),
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    let canvas = grey_surface(camera, surface, intensity, range, style)?;
    Ok(finish(canvas, style))
}

/// The flow coloured by the Middlebury wheel in screen directions: vertex `i` gets
/// `flow_color(screen_components(u_i) / scale)`, so red moves right on the screen; with the
/// wheel legend (rim = `scale`) in the bottom-right corner.
pub fn flow_picture(
    camera: &Camera,
    surface: Surface,
    flow: &[Vector3<f64>],
    scale: f64,
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    check_count("flow vectors", surface.positions.len(), flow.len())?;
    check_positive("flow scale", scale)?;
    let colours = screen_flow_colors(camera, flow, scale);
    let mut canvas = shaded_surface(camera, surface, &colours, style)?;
    draw_wheel_legend(&mut canvas, scale);
    Ok(finish(canvas, style))
}

/// `flow_color(screen_components(u_i) / scale)` for every vector: the Middlebury colour of
/// the direction in which `camera` sees each vector move (red = right on the screen).
pub fn screen_flow_colors(camera: &Camera, flow: &[Vector3<f64>], scale: f64) -> Vec<[f64; 3]> {
    flow.iter()
        .map(|u| {
            let [x, y] = camera.screen_components(u);
            flow_color(x / scale, y / scale)
        })
        .collect()
}

/// The grey surface (as [`grey_picture`]) with arrows of the flow on visible vertices about
/// `style.arrow_spacing` pixels apart; a vector of length `scale` is `0.9 · spacing` pixels
/// long at the target's depth, as the reference arrow in the bottom-right corner shows.
pub fn arrow_picture(
    camera: &Camera,
    surface: Surface,
    intensity: &[f64],
    range: (f64, f64),
    flow: &[Vector3<f64>],
    scale: f64,
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    let canvas = arrow_canvas(camera, surface, (intensity, range), flow, scale, style)?;
    Ok(finish(canvas, style))
}

/// [`arrow_picture`] with the known displacements of tracked points drawn over it on the same
/// scale, in [`TRACK_ARROW_COLOUR`]: `tracked = (points, vectors)`, points on the surface (e.g.
/// [`crate::accuracy::TrackPoint`]'s `position` and its `truth / Δt`, the true velocity).
pub fn tracks_picture(
    camera: &Camera,
    surface: Surface,
    (intensity, range): (&[f64], (f64, f64)),
    flow: &[Vector3<f64>],
    scale: f64,
    tracked: (&[Vector3<f64>], &[Vector3<f64>]),
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    let mut canvas = arrow_canvas(camera, surface, (intensity, range), flow, scale, style)?;
    let arrows = ArrowStyle {
        colour: TRACK_ARROW_COLOUR,
        width: 2.0 * style.arrows().width,
        ..style.arrows()
    };
    draw_point_arrows(&mut canvas, camera, tracked.0, tracked.1, scale, &arrows)?;
    Ok(finish(canvas, style))
}

/// Tracked points' true displacements (red, [`TRACK_ARROW_COLOUR`]) and the flow's at the same
/// points (near-black), over the grey surface: `points` on the surface, `truth[n]` and
/// `flow[n]` the displacements at `points[n]`, drawn `0.9 ·` the arrow spacing long for a
/// length `scale`, with the reference arrow. Which cells the flow gets wrong, at a glance.
pub fn track_errors_picture(
    camera: &Camera,
    surface: Surface,
    (intensity, range): (&[f64], (f64, f64)),
    points: &[Vector3<f64>],
    (truth, flow): (&[Vector3<f64>], &[Vector3<f64>]),
    scale: f64,
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    check_positive("displacement scale", scale)?;
    let mut canvas = grey_surface(camera, surface, intensity, range, style)?;
    let computed = ArrowStyle {
        width: 2.0 * style.arrows().width,
        ..style.arrows()
    };
    let true_arrows = ArrowStyle {
        colour: TRACK_ARROW_COLOUR,
        ..computed
    };
    draw_point_arrows(&mut canvas, camera, points, truth, scale, &true_arrows)?;
    draw_point_arrows(&mut canvas, camera, points, flow, scale, &computed)?;
    draw_arrow_key(
        &mut canvas,
        scale,
        reference_arrow_length(&computed),
        &computed,
    );
    Ok(finish(canvas, style))
}

/// The colour of tracked points' arrows in [`tracks_picture`]: red, apart from the flow's
/// near-black arrows on the grey image.
pub const TRACK_ARROW_COLOUR: [f64; 3] = [0.85, 0.1, 0.1];

/// The grey surface with the flow's arrows and the reference arrow, not yet finished.
fn arrow_canvas(
    camera: &Camera,
    surface: Surface,
    (intensity, range): (&[f64], (f64, f64)),
    flow: &[Vector3<f64>],
    scale: f64,
    style: &PictureStyle,
) -> Result<Canvas, RenderError> {
    let arrows = style.arrows();
    check_count("flow vectors", surface.positions.len(), flow.len())?;
    check_positive("flow scale", scale)?;
    check_positive("arrow spacing", arrows.spacing)?;
    let mut canvas = grey_surface(camera, surface, intensity, range, style)?;
    draw_arrows(
        &mut canvas,
        camera,
        surface.positions,
        surface.faces,
        flow,
        scale,
        &arrows,
    )?;
    draw_arrow_key(&mut canvas, scale, reference_arrow_length(&arrows), &arrows);
    Ok(canvas)
}

/// The surface coloured by `values` (one per vertex, e.g. angular errors in degrees) with
/// viridis over `range`, and a colour bar labelled with the range's ends. Shading darkens the
/// colours away from the light; [`Lighting::unlit`] keeps them exactly as on the bar.
pub fn scalar_picture(
    camera: &Camera,
    surface: Surface,
    values: &[f64],
    range: (f64, f64),
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    colour_bar_picture(camera, surface, values, range, viridis, style)
}

/// The surface coloured by signed `values` (one per vertex, e.g. divergence, curl or areal
/// rate) with the [`diverging`] map over `range`: blue below its middle, white at it, red
/// above, and a colour bar labelled with the range's (negative and positive) ends. Pass
/// [`super::colormap::symmetric_range`] of the values so that white is zero.
pub fn signed_picture(
    camera: &Camera,
    surface: Surface,
    values: &[f64],
    range: (f64, f64),
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    colour_bar_picture(camera, surface, values, range, diverging, style)
}

/// The surface coloured by `colormap` over `range`, with its colour bar.
fn colour_bar_picture(
    camera: &Camera,
    surface: Surface,
    values: &[f64],
    range: (f64, f64),
    colormap: fn(f64, f64, f64) -> [f64; 3],
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    let mut canvas = mapped_surface(camera, surface, ("values", values), range, colormap, style)?;
    draw_colour_bar(&mut canvas, range, |v| colormap(v, range.0, range.1));
    Ok(finish(canvas, style))
}

/// A line chart of `series` against `x` on white, `width × height` pixels: axes with tick
/// labels, a zero line when the values span 0, series `k` in [`series_colour`]`(k)` with a
/// square at each point, the legend of names right of the plot and `title` on the top line
/// (layout and ranges: [`super::plot`]). Non-finite values are gaps in their line. Errors
/// when a side is outside [`super::plot::CHART_SIDES`] or a series has not one value per x.
pub fn series_chart(
    title: &str,
    x_label: &str,
    x: &[f64],
    series: &[Series],
    width: u32,
    height: u32,
) -> Result<RgbImage, RenderError> {
    check_chart_size(width, height)?;
    check_series_lengths(x, series)?;
    let layout = PlotLayout::new(width, height, x, series);
    let mut canvas = Canvas::new(width, height, DEFAULT_SUPERSAMPLE);
    layout.draw_axes(&mut canvas, x_label);
    for (k, s) in series.iter().enumerate() {
        layout.draw_series(&mut canvas, x, s.values, series_colour(k));
    }
    layout.draw_legend(&mut canvas, series);
    draw_title(&mut canvas, title);
    Ok(canvas.finish())
}

/// A parameter grid shown flat: vertex `r · cols + c` is the `pixel_size × pixel_size` block
/// at row `r` (row 0 at the top) and column `c`. Non-finite colours are black.
pub fn chart_picture(
    rows: usize,
    cols: usize,
    colors: &[[f64; 3]],
    pixel_size: u32,
) -> Result<RgbImage, RenderError> {
    let side = |cells: usize| {
        (cells as u64)
            .checked_mul(pixel_size as u64)
            .filter(|&pixels| (1..=MAX_IMAGE_SIDE as u64).contains(&pixels))
            .ok_or_else(|| RenderError::Size {
                reason: format!(
                    "a {rows} × {cols} chart with {pixel_size}-pixel blocks must be between 1 and {MAX_IMAGE_SIDE} pixels a side"
                ),
            })
    };
    let (width, height) = (side(cols)?, side(rows)?);
    check_count("chart colours", rows * cols, colors.len())?;
    let block = pixel_size as usize;
    Ok(RgbImage::from_fn(width as u32, height as u32, |x, y| {
        let colour = colors[(y as usize / block) * cols + x as usize / block];
        image::Rgb(if colour.iter().all(|c| c.is_finite()) {
            colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
        } else {
            [0; 3]
        })
    }))
}

/// The surface shaded in grey with the paths of moving points drawn over it
/// ([`super::glyphs::draw_paths`]: `paths[i]` starts at vertex `i`, as points on this
/// surface), coloured along time from dark to bright (viridis), one path per arrow cell.
pub fn trajectory_picture(
    camera: &Camera,
    surface: Surface,
    intensity: &[f64],
    range: (f64, f64),
    paths: &[Vec<Vector3<f64>>],
    style: &PictureStyle,
) -> Result<RgbImage, RenderError> {
    let mut canvas = grey_surface(camera, surface, intensity, range, style)?;
    super::glyphs::draw_paths(
        &mut canvas,
        camera,
        (surface.positions, surface.faces),
        paths,
        style.arrow_spacing,
        2.0,
        |t| viridis(0.25 + 0.75 * t, 0.0, 1.0),
    )?;
    Ok(finish(canvas, style))
}

/// Writes `image` as a PNG file: encoded in memory, then written atomically.
pub fn write_png(path: &Path, image: &RgbImage) -> Result<(), IoError> {
    let mut bytes = Vec::new();
    image
        .write_with_encoder(PngEncoder::new(&mut bytes))
        .map_err(|e| IoError::format(path, format!("PNG encoding failed: {e}")))?;
    write_atomically(path, |writer| writer.write_all(&bytes))
}

/// A finite range with `min ≤ max`.
fn check_range((min, max): (f64, f64)) -> Result<(), RenderError> {
    if min.is_finite() && max.is_finite() && min <= max {
        Ok(())
    } else {
        Err(RenderError::Range { min, max })
    }
}

/// The canvas with the surface drawn in grey values.
fn grey_surface(
    camera: &Camera,
    surface: Surface,
    intensity: &[f64],
    range: (f64, f64),
    style: &PictureStyle,
) -> Result<Canvas, RenderError> {
    mapped_surface(
        camera,
        surface,
        ("grey values", intensity),
        range,
        grey,
        style,
    )
}

/// The canvas with the surface drawn in the colours `colormap(value, min, max)` of the named
/// per-vertex values.
fn mapped_surface(
    camera: &Camera,
    surface: Surface,
    (what, values): (&'static str, &[f64]),
    range: (f64, f64),
    colormap: fn(f64, f64, f64) -> [f64; 3],
    style: &PictureStyle,
) -> Result<Canvas, RenderError> {
    check_range(range)?;
    check_count(what, surface.positions.len(), values.len())?;
    let colours: Vec<[f64; 3]> = values
        .iter()
        .map(|&v| colormap(v, range.0, range.1))
        .collect();
    shaded_surface(camera, surface, &colours, style)
}

/// A canvas of the camera's size with the surface drawn in the vertex colours.
fn shaded_surface(
    camera: &Camera,
    surface: Surface,
    colours: &[[f64; 3]],
    style: &PictureStyle,
) -> Result<Canvas, RenderError> {
    let mut canvas = Canvas::for_camera(camera, style.supersample);
    let masked: Option<Vec<[f64; 3]>> = style.no_data.as_ref().map(|no_data| {
        (colours.iter().enumerate())
            .map(|(i, &c)| match no_data.get(i) {
                Some(true) => NO_DATA_COLOUR,
                _ => c,
            })
            .collect()
    });
    canvas.draw_mesh(
        camera,
        surface.positions,
        surface.faces,
        masked.as_deref().unwrap_or(colours),
        &style.lighting,
    )?;
    Ok(canvas)
}

/// Writes the label line, if any, and downsamples.
fn finish(mut canvas: Canvas, style: &PictureStyle) -> RgbImage {
    if let Some(label) = &style.label {
        draw_title(&mut canvas, label);
    }
    canvas.finish()
}
