//! Arrow glyphs for tangent vector fields, on a subsample of the vertices chosen evenly on the
//! screen.
//!
//! # Which vertices
//!
//! A vertex takes part when it projects into the picture, *faces the camera* — its unit
//! area-weighted normal `n` has `|n · e| ≥ 0.15` with `e` the unit vector to the eye (either
//! side, as surfaces are drawn two-sided; grazing vertices would give arrows squashed into the
//! silhouette) — and is *visible*: its depth is at most `1.01 ×` the nearest depth drawn within
//! one sample of its position, so vertices hidden behind other parts of the surface (e.g. on
//! the far side of a sphere) get no arrow. The picture is cut into square cells of `spacing`
//! pixels and each cell keeps the taking-part vertex nearest to its centre (the lower index on
//! ties): arrows come about `spacing` apart wherever the surface is seen, independent of how
//! finely it is meshed.
//!
//! # Arrows
//!
//! The arrow of vertex `p` with vector `u` runs from the projection of `p` to the projection of
//! `p + k u`, one factor
//!
//! ```text
//! k = 0.9 · spacing / (scale · F / z_target)
//! ```
//!
//! for all vertices (`F / z_target` pixels per unit length at the target's depth), so a vector
//! of length `scale` parallel to the picture at the target's depth is `0.9 · spacing` pixels
//! long, lengths are proportional to `|u|`, and arrows are foreshortened like the surface they
//! lie on. Arrows shorter than half a pixel are skipped. Each is a shaft of `width` pixels and
//! a filled head (length `min(0.35 L, 4 · width)`, half as wide as long plus the shaft), drawn
//! into the supersampled canvas after the surface, so the downsampling antialiases it.

use super::camera::Camera;
use super::error::{check_count, check_positive};
use super::raster::Canvas;
use super::shading::vertex_normals;
use super::RenderError;
use crate::mesh::check_index_range;
use nalgebra::Vector3;

/// Arrow length, as a fraction of the spacing, of a vector of length `scale`.
const ARROW_FILL: f64 = 0.9;

/// Smallest `|n · e|` of a vertex that gets an arrow.
const MIN_FACING: f64 = 0.15;

/// Relative depth tolerance of the visibility test.
const DEPTH_TOLERANCE: f64 = 0.01;

/// Arrows shorter than this (output pixels) are not drawn.
const MIN_ARROW_PIXELS: f64 = 0.5;

/// Spacing, width and colour of arrows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArrowStyle {
    /// Side of the screen cells that get one arrow each, output pixels.
    pub spacing: f64,
    /// Shaft width, output pixels.
    pub width: f64,
    pub colour: [f64; 3],
    /// Colour of an outline drawn under every arrow, [`HALO_WIDTH`] pixels wider, so arrows
    /// read on dark and bright surfaces alike; `None`: no outline.
    pub halo: Option<[f64; 3]>,
}

/// Extra width of the halo around arrows, output pixels.
pub const HALO_WIDTH: f64 = 2.0;

impl Default for ArrowStyle {
    /// 28-pixel cells, 1.5-pixel near-black shafts with a white halo.
    fn default() -> Self {
        Self {
            spacing: 28.0,
            width: 1.5,
            colour: [0.05, 0.05, 0.08],
            halo: Some([1.0; 3]),
        }
    }
}

/// Length in output pixels of the arrow of a vector of length `scale` parallel to the picture
/// at the target's depth: `0.9 · spacing`.
pub fn reference_arrow_length(style: &ArrowStyle) -> f64 {
    ARROW_FILL * style.spacing
}

/// Draws the arrows of `flow` (one vector per position) over the surface already drawn on
/// `canvas` with the same camera, and returns how many were drawn. `scale` (positive) is the
/// vector length drawn `0.9 · spacing` pixels long. Non-finite vectors and positions are
/// skipped.
pub fn draw_arrows(
    canvas: &mut Canvas,
    camera: &Camera,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    flow: &[Vector3<f64>],
    scale: f64,
    style: &ArrowStyle,
) -> Result<usize, RenderError> {
    check_count("flow vectors", positions.len(), flow.len())?;
    check_index_range(faces, positions.len())?;
    check_positive("flow scale", scale)?;
    check_positive("arrow spacing", style.spacing)?;
    let k = reference_arrow_length(style) / (scale * camera.pixels_per_unit(camera.target_depth()));
    let segments: Vec<[[f64; 2]; 2]> =
        glyph_vertices(canvas, camera, positions, faces, style.spacing)
            .into_iter()
            .filter_map(|vertex| {
                let (p, u) = (&positions[vertex], &flow[vertex]);
                let ends = camera.project(p).zip(camera.project(&(p + k * u)));
                ends.map(|([x0, y0, _], [x1, y1, _])| [[x0, y0], [x1, y1]])
            })
            .collect();
    // All halos first, so that no halo covers a neighbouring arrow.
    if let Some(halo) = style.halo {
        for &[from, to] in &segments {
            draw_arrow(canvas, from, to, style.width + HALO_WIDTH, halo);
        }
    }
    Ok(segments
        .iter()
        .filter(|&&[from, to]| draw_arrow(canvas, from, to, style.width, style.colour))
        .count())
}

/// Draws the arrow of `scale`-relative length of `vectors[n]` from `points[n]` (points on the
/// surface already drawn on `canvas`, e.g. tracked cells and their displacements), where the
/// camera sees the point: its depth within the tolerance of the nearest surface there. Lengths
/// as in [`draw_arrows`]; non-finite points and vectors are skipped. Returns how many were
/// drawn.
pub fn draw_point_arrows(
    canvas: &mut Canvas,
    camera: &Camera,
    points: &[Vector3<f64>],
    vectors: &[Vector3<f64>],
    scale: f64,
    style: &ArrowStyle,
) -> Result<usize, RenderError> {
    check_count("point vectors", points.len(), vectors.len())?;
    check_positive("flow scale", scale)?;
    let k = reference_arrow_length(style) / (scale * camera.pixels_per_unit(camera.target_depth()));
    let visible = |[x, y, depth]: [f64; 3]| {
        let on_canvas =
            x >= 0.0 && y >= 0.0 && x < canvas.width() as f64 && y < canvas.height() as f64;
        on_canvas && depth <= canvas.nearest_depth([x, y], 1) * (1.0 + DEPTH_TOLERANCE)
    };
    let segments: Vec<[[f64; 2]; 2]> = points
        .iter()
        .zip(vectors)
        .filter_map(|(p, v)| camera.project(p).zip(camera.project(&(p + k * v))))
        .filter(|&(from, _)| visible(from))
        .map(|([x0, y0, _], [x1, y1, _])| [[x0, y0], [x1, y1]])
        .collect();
    if let Some(halo) = style.halo {
        for &[from, to] in &segments {
            draw_arrow(canvas, from, to, style.width + HALO_WIDTH, halo);
        }
    }
    Ok(segments
        .iter()
        .filter(|&&[from, to]| draw_arrow(canvas, from, to, style.width, style.colour))
        .count())
}

/// The vertices that get arrows, by screen cell in row-major order; see the module
/// documentation. `faces` must index `positions`.
pub fn glyph_vertices(
    canvas: &Canvas,
    camera: &Camera,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    spacing: f64,
) -> Vec<usize> {
    let normals = vertex_normals(positions, faces);
    let columns = (canvas.width() as f64 / spacing).ceil() as usize;
    let rows = (canvas.height() as f64 / spacing).ceil() as usize;
    // Per cell: (squared distance to the cell centre, vertex).
    let mut best: Vec<Option<(f64, usize)>> = vec![None; columns * rows];
    for (vertex, p) in positions.iter().enumerate() {
        let Some([x, y, depth]) = camera.project(p) else {
            continue;
        };
        let on_canvas =
            x >= 0.0 && y >= 0.0 && x < canvas.width() as f64 && y < canvas.height() as f64;
        if !on_canvas || !faces_camera(&normals[vertex], &(camera.eye() - p)) {
            continue;
        }
        if depth > canvas.nearest_depth([x, y], 1) * (1.0 + DEPTH_TOLERANCE) {
            continue;
        }
        let (cx, cy) = ((x / spacing) as usize, (y / spacing) as usize);
        let centre = [(cx as f64 + 0.5) * spacing, (cy as f64 + 0.5) * spacing];
        let distance = (x - centre[0]).powi(2) + (y - centre[1]).powi(2);
        let cell = &mut best[cy * columns + cx];
        if cell.is_none_or(|(nearest, _)| distance < nearest) {
            *cell = Some((distance, vertex));
        }
    }
    best.into_iter()
        .flatten()
        .map(|(_, vertex)| vertex)
        .collect()
}

/// `|n̂ · ê| ≥ MIN_FACING` for the normal `n` and the vector `to_eye` from the vertex to the eye.
fn faces_camera(normal: &Vector3<f64>, to_eye: &Vector3<f64>) -> bool {
    match (normal.try_normalize(0.0), to_eye.try_normalize(0.0)) {
        (Some(n), Some(e)) => n.dot(&e).abs() >= MIN_FACING,
        _ => false,
    }
}

/// Draws an arrow from `from` to `to` (output pixels) with a shaft `width` pixels wide and a
/// filled head; returns `false` (drawing nothing) when it is shorter than half a pixel or not
/// finite.
pub fn draw_arrow(
    canvas: &mut Canvas,
    from: [f64; 2],
    to: [f64; 2],
    width: f64,
    colour: [f64; 3],
) -> bool {
    let delta = [to[0] - from[0], to[1] - from[1]];
    let length = delta[0].hypot(delta[1]);
    if !(length >= MIN_ARROW_PIXELS && length.is_finite()) {
        return false;
    }
    let along = [delta[0] / length, delta[1] / length];
    let across = [-along[1], along[0]];
    let at = |base: [f64; 2], forward: f64, side: f64| {
        [
            base[0] + forward * along[0] + side * across[0],
            base[1] + forward * along[1] + side * across[1],
        ]
    };
    let head_length = (0.35 * length).min(4.0 * width);
    let head_half_width = 0.5 * head_length + 0.5 * width;
    // The shaft reaches halfway into the head, so the two overlap instead of leaving a seam.
    let shaft_end = length - 0.5 * head_length;
    let half = 0.5 * width;
    canvas.fill_convex(
        &[
            at(from, 0.0, -half),
            at(from, shaft_end, -half),
            at(from, shaft_end, half),
            at(from, 0.0, half),
        ],
        colour,
    );
    let base = length - head_length;
    canvas.fill_convex(
        &[
            to,
            at(from, base, head_half_width),
            at(from, base, -head_half_width),
        ],
        colour,
    );
    true
}

/// Draws the paths of the seeds that start at the vertices chosen as for arrows (one per
/// `spacing` screen cell, visible, facing the camera) over the surface already drawn on
/// `canvas`: `paths[i]` is the path of the seed that started at vertex `i`, as points on the
/// drawn surface, oldest first. Segments are `width` pixels wide and coloured along time by
/// `colour(fraction)`, fraction 0 at the start and 1 at the end, where a dot marks the seed's
/// last place; hidden segments are left out. Returns how many paths were drawn.
pub fn draw_paths(
    canvas: &mut Canvas,
    camera: &Camera,
    surface: (&[Vector3<f64>], &[[u32; 3]]),
    paths: &[Vec<Vector3<f64>>],
    spacing: f64,
    width: f64,
    colour: impl Fn(f64) -> [f64; 3],
) -> Result<usize, RenderError> {
    let (positions, faces) = surface;
    check_count("paths", positions.len(), paths.len())?;
    check_index_range(faces, positions.len())?;
    check_positive("path spacing", spacing)?;
    let visible = |p: &Vector3<f64>, canvas: &Canvas| {
        let [x, y, depth] = camera.project(p)?;
        (depth <= canvas.nearest_depth([x, y], 1) * (1.0 + DEPTH_TOLERANCE)).then_some([x, y])
    };
    let mut drawn = 0;
    for vertex in glyph_vertices(canvas, camera, positions, faces, spacing) {
        let points: Vec<Option<[f64; 2]>> =
            paths[vertex].iter().map(|p| visible(p, canvas)).collect();
        let last = points.len().saturating_sub(1).max(1) as f64;
        for (k, pair) in points.windows(2).enumerate() {
            if let [Some(from), Some(to)] = pair {
                draw_segment(canvas, *from, *to, width, colour((k + 1) as f64 / last));
            }
        }
        if let Some(Some(end)) = points.last() {
            let r = width;
            canvas.fill_convex(
                &[
                    [end[0] - r, end[1]],
                    [end[0], end[1] - r],
                    [end[0] + r, end[1]],
                    [end[0], end[1] + r],
                ],
                colour(1.0),
            );
            drawn += 1;
        }
    }
    Ok(drawn)
}

/// A segment `width` pixels wide (a quad).
pub(crate) fn draw_segment(
    canvas: &mut Canvas,
    from: [f64; 2],
    to: [f64; 2],
    width: f64,
    colour: [f64; 3],
) {
    let delta = [to[0] - from[0], to[1] - from[1]];
    let length = delta[0].hypot(delta[1]);
    if !(length > 0.0 && length.is_finite()) {
        return;
    }
    let across = [
        -0.5 * width * delta[1] / length,
        0.5 * width * delta[0] / length,
    ];
    canvas.fill_convex(
        &[
            [from[0] + across[0], from[1] + across[1]],
            [to[0] + across[0], to[1] + across[1]],
            [to[0] - across[0], to[1] - across[1]],
            [from[0] - across[0], from[1] - across[1]],
        ],
        colour,
    );
}
