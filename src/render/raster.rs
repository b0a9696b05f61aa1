//! Z-buffer rasterization of triangle meshes onto a supersampled canvas.
//!
//! # Why a z-buffer
//!
//! A [`Canvas`] keeps a colour and a depth per *sample*, `s × s` samples per output pixel
//! (`s` = supersample, default 3). Each triangle is projected once and scanned over the samples
//! of its screen bounding box; a sample is overwritten only by a strictly nearer surface. That
//! costs O(samples + triangles) with exact per-sample visibility and no acceleration structure,
//! where ray casting would need a BVH (O(samples · log triangles) per picture and a build per
//! frame of a deforming mesh) for the same picture. Overlays (arrows, legends, text) are drawn
//! into the same samples, so [`Canvas::finish`]'s box filter antialiases everything alike.
//!
//! # Coverage: fixed point and the top-left rule
//!
//! Sample `(i, j)` has its centre at `(i + ½, j + ½)` in sample units (output pixel
//! `(i + ½)/s`). Vertices are snapped to 1/256 of a sample and edge functions
//! `E_ab(p) = (b − a) × (p − a)` are evaluated in exact integer arithmetic. With the triangle
//! ordered so that `E_ab(c) > 0`, a sample is covered when `E ≥ 0` on every edge, with
//! `E = 0` counting only on *top* edges (horizontal, `dx > 0`) and *left* edges (`dy < 0`; y
//! points down). An edge shared by two triangles runs in opposite directions in them, so
//! exactly one owns the samples on it: no cracks and no double hits between neighbours.
//! Triangles with a vertex behind the near plane, with a non-finite or far off-screen
//! (beyond ±2²¹ samples) vertex, or with zero screen area are skipped.
//!
//! # Perspective-correct interpolation and shading
//!
//! With screen barycentric coordinates `λ_i` (ratios of edge functions) and vertex depths
//! `w_i`, `1/w` is affine on the screen, so a sample has depth `w = 1 / Σ λ_i / w_i` and an
//! attribute interpolates as
//!
//! ```text
//! a = Σ λ_i a_i / w_i  /  Σ λ_i / w_i,
//! ```
//!
//! the world-space barycentric interpolation. Colours and (unit) vertex normals interpolate
//! so; the normal is renormalized and shaded with [`Lighting`] (two-sided Lambert).
//! Non-finite vertex colours are black.
//!
//! # Parallelism
//!
//! The sample rows are cut into bands of 16; each triangle is binned into the bands its
//! bounding box meets and the bands are filled in parallel, each drawing its triangles in
//! index order. The result does not depend on the number of threads: ties in depth keep the
//! first triangle in index order.

use super::camera::{Camera, MAX_IMAGE_SIDE};
use super::error::check_count;
use super::shading::{face_normal, vertex_normals, Lighting};
use super::RenderError;
use crate::mesh::check_index_range;
use image::RgbImage;
use nalgebra::Vector3;
use rayon::prelude::*;

/// Samples per output pixel along each axis used unless asked otherwise.
pub const DEFAULT_SUPERSAMPLE: u32 = 3;

/// Largest supersampling factor accepted (larger requests are clamped).
pub const MAX_SUPERSAMPLE: u32 = 8;

/// Most samples a canvas holds (16 bytes each); the supersampling of huge pictures is lowered.
pub const MAX_SAMPLES: usize = 1 << 28;

/// Sub-sample precision of snapped vertex coordinates.
const SUBPIXEL: i64 = 256;

/// Vertices further off the canvas than this (in samples) skip their triangle: keeps every
/// edge-function product within i64.
const GUARD_SAMPLES: f64 = (1u64 << 21) as f64;

/// Sample rows per parallel band.
const BAND_ROWS: usize = 16;

/// Background colour: white.
const BACKGROUND: [f32; 3] = [1.0; 3];

/// A supersampled colour and depth buffer; see the module documentation.
#[derive(Clone, Debug)]
pub struct Canvas {
    width: u32,
    height: u32,
    supersample: u32,
    colour: Vec<[f32; 3]>,
    depth: Vec<f32>,
}

impl Canvas {
    /// A white canvas for a `width × height` picture with `supersample²` samples per pixel.
    /// Sizes are clamped to `1..=`[`MAX_IMAGE_SIDE`], the factor to `1..=`[`MAX_SUPERSAMPLE`]
    /// and lowered where needed to keep within [`MAX_SAMPLES`] (a 4.3 GB buffer).
    pub fn new(width: u32, height: u32, supersample: u32) -> Self {
        let width = width.clamp(1, MAX_IMAGE_SIDE);
        let height = height.clamp(1, MAX_IMAGE_SIDE);
        let pixels = width as usize * height as usize;
        let supersample = (1..=supersample.clamp(1, MAX_SUPERSAMPLE))
            .rev()
            .find(|&s| pixels * (s * s) as usize <= MAX_SAMPLES)
            .unwrap_or(1);
        let samples = (width * supersample) as usize * (height * supersample) as usize;
        Self {
            width,
            height,
            supersample,
            colour: vec![BACKGROUND; samples],
            depth: vec![f32::INFINITY; samples],
        }
    }

    /// A canvas of the camera's picture size.
    pub fn for_camera(camera: &Camera, supersample: u32) -> Self {
        Self::new(camera.width(), camera.height(), supersample)
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn supersample(&self) -> u32 {
        self.supersample
    }

    fn sample_width(&self) -> usize {
        (self.width * self.supersample) as usize
    }

    fn sample_height(&self) -> usize {
        (self.height * self.supersample) as usize
    }

    /// Draws the triangles `faces` (indices into `positions`) with per-vertex colours (RGB in
    /// [0, 1]), depth-tested against what is already drawn and shaded with `lighting`.
    /// Errors when the camera's picture size is not the canvas's, when `vertex_colors` does not
    /// have one entry per position, or when a face names a missing vertex.
    pub fn draw_mesh(
        &mut self,
        camera: &Camera,
        positions: &[Vector3<f64>],
        faces: &[[u32; 3]],
        vertex_colors: &[[f64; 3]],
        lighting: &Lighting,
    ) -> Result<(), RenderError> {
        self.check_camera(camera)?;
        check_count("vertex colours", positions.len(), vertex_colors.len())?;
        check_index_range(faces, positions.len())?;
        let normals = unit_vertex_normals(positions, faces);
        let s = self.supersample as f64;
        let screen: Vec<Option<[f64; 3]>> = positions
            .par_iter()
            .map(|p| camera.project(p).map(|[x, y, z]| [x * s, y * s, z]))
            .collect();
        let vertices = Vertices {
            positions,
            screen: &screen,
            normals: &normals,
            colours: vertex_colors,
        };
        let size = [self.sample_width(), self.sample_height()];
        let triangles: Vec<ScreenTriangle> = faces
            .par_iter()
            .filter_map(|face| ScreenTriangle::new(face, &vertices, size))
            .collect();
        let bins = bin_by_band(&triangles, size[1].div_ceil(BAND_ROWS));
        let shader = Shader {
            lighting: *lighting,
            towards_light: light_direction(camera, lighting),
        };
        let band_len = BAND_ROWS * size[0];
        self.colour
            .par_chunks_mut(band_len)
            .zip(self.depth.par_chunks_mut(band_len))
            .zip(bins.par_iter())
            .enumerate()
            .for_each(|(band, ((colour, depth), bin))| {
                let mut target = Band {
                    first_row: band * BAND_ROWS,
                    width: size[0],
                    colour,
                    depth,
                };
                for &t in bin {
                    triangles[t as usize].rasterize(&mut target, &shader);
                }
            });
        Ok(())
    }

    fn check_camera(&self, camera: &Camera) -> Result<(), RenderError> {
        if (camera.width(), camera.height()) == (self.width, self.height) {
            Ok(())
        } else {
            Err(RenderError::Size {
                reason: format!(
                    "the camera's picture is {}×{} pixels but the canvas is {}×{}",
                    camera.width(),
                    camera.height(),
                    self.width,
                    self.height
                ),
            })
        }
    }

    /// The smallest depth drawn within `radius` samples (in each direction) of the sample that
    /// contains the output-pixel position `at`; +∞ where nothing was drawn or off the canvas.
    pub fn nearest_depth(&self, at: [f64; 2], radius: usize) -> f64 {
        let s = self.supersample as f64;
        let (sx, sy) = ((at[0] * s).floor(), (at[1] * s).floor());
        let inside = |v: f64, n: usize| v.is_finite() && v >= 0.0 && v < n as f64;
        if !inside(sx, self.sample_width()) || !inside(sy, self.sample_height()) {
            return f64::INFINITY;
        }
        let (sx, sy) = (sx as usize, sy as usize);
        let columns = sx.saturating_sub(radius)..=(sx + radius).min(self.sample_width() - 1);
        let rows = sy.saturating_sub(radius)..=(sy + radius).min(self.sample_height() - 1);
        rows.flat_map(|y| columns.clone().map(move |x| (x, y)))
            .map(|(x, y)| self.depth[y * self.sample_width() + x] as f64)
            .fold(f64::INFINITY, f64::min)
    }

    /// Overwrites every sample whose centre (in output-pixel coordinates) lies in the box
    /// `[x0, x1] × [y0, y1]` and gets `Some` colour from `shade`. Depths are not touched:
    /// overlays do not hide anything from later depth queries.
    pub fn paint(
        &mut self,
        [x0, y0, x1, y1]: [f64; 4],
        shade: impl Fn([f64; 2]) -> Option<[f64; 3]>,
    ) {
        let s = self.supersample as f64;
        let (Some(columns), Some(rows)) = (
            sample_range(x0, x1, s, self.sample_width()),
            sample_range(y0, y1, s, self.sample_height()),
        ) else {
            return;
        };
        let width = self.sample_width();
        for y in rows {
            for x in columns.clone() {
                let centre = [(x as f64 + 0.5) / s, (y as f64 + 0.5) / s];
                if let Some(colour) = shade(centre) {
                    self.colour[y * width + x] = colour.map(|c| c.clamp(0.0, 1.0) as f32);
                }
            }
        }
    }

    /// Fills the box `[x0, x1] × [y0, y1]` (output pixels) with `colour`.
    pub fn fill_rect(&mut self, region: [f64; 4], colour: [f64; 3]) {
        self.paint(region, |_| Some(colour));
    }

    /// Fills the convex polygon with the given corners (output pixels, either orientation).
    pub fn fill_convex(&mut self, polygon: &[[f64; 2]], colour: [f64; 3]) {
        if polygon.len() < 3 {
            return;
        }
        let bounds = polygon.iter().fold(
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
            |b, p| {
                [
                    b[0].min(p[0]),
                    b[1].min(p[1]),
                    b[2].max(p[0]),
                    b[3].max(p[1]),
                ]
            },
        );
        let orientation = signed_area(polygon);
        if orientation == 0.0 || !orientation.is_finite() {
            return;
        }
        let edges: Vec<([f64; 2], [f64; 2])> = (0..polygon.len())
            .map(|k| (polygon[k], polygon[(k + 1) % polygon.len()]))
            .collect();
        let cross = |(a, b): &([f64; 2], [f64; 2]), p: [f64; 2]| {
            (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        };
        self.paint(bounds, |p| {
            edges
                .iter()
                .all(|e| orientation.signum() * cross(e, p) >= 0.0)
                .then_some(colour)
        });
    }

    /// The picture: each output pixel the mean of its `s × s` samples, rounded to 8 bits.
    pub fn finish(self) -> RgbImage {
        let (width, s) = (self.width as usize, self.supersample as usize);
        let sample_width = self.sample_width();
        let mut image = RgbImage::new(self.width, self.height);
        let weight = 1.0 / (s * s) as f32;
        image
            .par_chunks_mut(3 * width)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, pixel) in row.chunks_mut(3).enumerate() {
                    let mut sum = [0.0f32; 3];
                    for sy in y * s..(y + 1) * s {
                        for sample in &self.colour[sy * sample_width + x * s..][..s] {
                            (0..3).for_each(|c| sum[c] += sample[c]);
                        }
                    }
                    for c in 0..3 {
                        pixel[c] = (sum[c] * weight * 255.0).round().clamp(0.0, 255.0) as u8;
                    }
                }
            });
        image
    }
}

/// Twice the signed area of a polygon (shoelace formula).
fn signed_area(polygon: &[[f64; 2]]) -> f64 {
    (0..polygon.len())
        .map(|k| {
            let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
            a[0] * b[1] - a[1] * b[0]
        })
        .sum()
}

/// Indices of the samples whose centres `(i + ½)/s` lie in `[low, high]`, clipped to `0..n`.
fn sample_range(low: f64, high: f64, s: f64, n: usize) -> Option<std::ops::RangeInclusive<usize>> {
    let first = (low * s - 0.5).ceil().max(0.0);
    let last = (high * s - 0.5).floor().min(n as f64 - 1.0);
    (first <= last).then_some(first as usize..=last as usize)
}

/// Unit area-weighted vertex normals (zero where there is none).
fn unit_vertex_normals(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Vec<Vector3<f64>> {
    vertex_normals(positions, faces)
        .into_iter()
        .map(|n| n.try_normalize(0.0).unwrap_or_else(Vector3::zeros))
        .collect()
}

/// The unit world direction towards the light (a headlight if the given one is unusable).
fn light_direction(camera: &Camera, lighting: &Lighting) -> Vector3<f64> {
    camera
        .camera_to_world(lighting.towards_light)
        .try_normalize(0.0)
        .filter(|l| l.iter().all(|x| x.is_finite()))
        .unwrap_or_else(|| -camera.forward())
}

/// Triangle indices per band of [`BAND_ROWS`] sample rows, in index order.
fn bin_by_band(triangles: &[ScreenTriangle], n_bands: usize) -> Vec<Vec<u32>> {
    let mut bins = vec![Vec::new(); n_bands];
    for (t, triangle) in triangles.iter().enumerate() {
        let (first, last) = triangle.rows;
        for bin in &mut bins[first / BAND_ROWS..=last / BAND_ROWS] {
            bin.push(t as u32);
        }
    }
    bins
}

/// Per-vertex inputs of [`Canvas::draw_mesh`]; `screen` in sample units.
struct Vertices<'a> {
    positions: &'a [Vector3<f64>],
    screen: &'a [Option<[f64; 3]>],
    normals: &'a [Vector3<f64>],
    colours: &'a [[f64; 3]],
}

/// Lighting with its direction in world coordinates.
struct Shader {
    lighting: Lighting,
    towards_light: Vector3<f64>,
}

/// The rows `first_row..` of the sample buffers that one parallel task fills.
struct Band<'a> {
    first_row: usize,
    width: usize,
    colour: &'a mut [[f32; 3]],
    depth: &'a mut [f32],
}

/// The edge function of `a → b` in fixed point, stepped along sample rows.
#[derive(Clone, Copy)]
struct Edge {
    a: [i64; 2],
    delta: [i64; 2],
    /// 0 when the edge owns samples exactly on it (top or left edge), 1 otherwise.
    threshold: i64,
}

impl Edge {
    fn new(a: [i64; 2], b: [i64; 2]) -> Self {
        let delta = [b[0] - a[0], b[1] - a[1]];
        let top_or_left = delta[1] < 0 || (delta[1] == 0 && delta[0] > 0);
        Self {
            a,
            delta,
            threshold: if top_or_left { 0 } else { 1 },
        }
    }

    /// `E(p) = (b − a) × (p − a)`.
    fn at(&self, p: [i64; 2]) -> i64 {
        self.delta[0] * (p[1] - self.a[1]) - self.delta[1] * (p[0] - self.a[0])
    }

    /// Change of `E` from one sample to the next along a row.
    fn step(&self) -> i64 {
        -self.delta[1] * SUBPIXEL
    }
}

/// A projected, snapped triangle with positive orientation (`E_ab(c) > 0`) and its vertex
/// attributes.
struct ScreenTriangle {
    corners: [[i64; 2]; 3],
    inverse_depth: [f64; 3],
    colours: [Vector3<f64>; 3],
    normals: [Vector3<f64>; 3],
    /// `E_ab(c)`: twice the screen area in fixed-point units squared.
    area: i64,
    /// Inclusive sample rows and columns of the (clipped) bounding box.
    rows: (usize, usize),
    columns: (usize, usize),
}

impl ScreenTriangle {
    /// `None` when the triangle cannot or need not be drawn (see the module documentation).
    fn new(face: &[u32; 3], vertices: &Vertices, size: [usize; 2]) -> Option<Self> {
        let mut order = *face;
        let [p, q, r] = order.map(|v| vertices.screen[v as usize]);
        let mut points = [p?, q?, r?];
        let mut corners = [snap(points[0])?, snap(points[1])?, snap(points[2])?];
        let mut area = Edge::new(corners[0], corners[1]).at(corners[2]);
        if area == 0 {
            return None;
        }
        if area < 0 {
            order.swap(1, 2);
            points.swap(1, 2);
            corners.swap(1, 2);
            area = -area;
        }
        let columns = covered_samples(corners.map(|c| c[0]), size[0])?;
        let rows = covered_samples(corners.map(|c| c[1]), size[1])?;
        let [a, b, c] = order.map(|v| &vertices.positions[v as usize]);
        let flat = face_normal(a, b, c)
            .try_normalize(0.0)
            .unwrap_or_else(Vector3::zeros);
        let normal = |v: u32| Some(vertices.normals[v as usize]).filter(|n| *n != Vector3::zeros());
        Some(Self {
            corners,
            inverse_depth: points.map(|p| 1.0 / p[2]),
            colours: order.map(|v| finite_or_black(vertices.colours[v as usize])),
            normals: order.map(|v| normal(v).unwrap_or(flat)),
            area,
            rows,
            columns,
        })
    }

    /// Covers the samples of `band` inside the triangle that it is nearest at.
    fn rasterize(&self, band: &mut Band, shader: &Shader) {
        let band_rows = band.colour.len() / band.width;
        let first = self.rows.0.max(band.first_row);
        let last = self.rows.1.min(band.first_row + band_rows - 1);
        let [a, b, c] = self.corners;
        // Edge k is opposite corner k: its edge function is that corner's barycentric weight.
        let edges = [Edge::new(b, c), Edge::new(c, a), Edge::new(a, b)];
        let start_x = self.columns.0 as i64 * SUBPIXEL + SUBPIXEL / 2;
        let n_columns = (self.columns.1 - self.columns.0) as i64 + 1;
        for row in first..=last {
            let y = row as i64 * SUBPIXEL + SUBPIXEL / 2;
            let at_start = edges.map(|e| e.at([start_x, y]));
            let Some((skip, end)) = covered_span(&edges, &at_start, n_columns) else {
                continue;
            };
            let mut weights = [0, 1, 2].map(|k| at_start[k] + skip * edges[k].step());
            let offset = (row - band.first_row) * band.width + self.columns.0;
            for column in skip..=end {
                debug_assert!((0..3).all(|k| weights[k] >= edges[k].threshold));
                self.shade_sample(weights, offset + column as usize, band, shader);
                for k in 0..3 {
                    weights[k] += edges[k].step();
                }
            }
        }
    }

    /// Depth test and shading of one covered sample with (unnormalized) screen barycentric
    /// weights `weights`.
    fn shade_sample(&self, weights: [i64; 3], index: usize, band: &mut Band, shader: &Shader) {
        let w = std::array::from_fn::<f64, 3, _>(|k| weights[k] as f64 * self.inverse_depth[k]);
        let sum = w[0] + w[1] + w[2];
        let depth = (self.area as f64 / sum) as f32;
        // Strictly nearer only (NaN never is): ties keep the earlier triangle.
        if depth.partial_cmp(&band.depth[index]) != Some(std::cmp::Ordering::Less) {
            return;
        }
        let interpolate = |a: &[Vector3<f64>; 3]| (w[0] * a[0] + w[1] * a[1] + w[2] * a[2]) / sum;
        let normal = interpolate(&self.normals)
            .try_normalize(0.0)
            .unwrap_or_else(Vector3::zeros);
        let intensity = shader.lighting.intensity(&normal, &shader.towards_light);
        let colour = interpolate(&self.colours) * intensity;
        band.depth[index] = depth;
        band.colour[index] = [0, 1, 2].map(|c| colour[c].clamp(0.0, 1.0) as f32);
    }
}

/// The inclusive range of steps `k` in `0..n` along a row at which every edge function,
/// `at_start[e] + k · step_e`, reaches its threshold; `None` when there is none. Solving the
/// three linear inequalities exactly avoids testing the samples of the bounding box that the
/// triangle misses (most of it, for slivers).
fn covered_span(edges: &[Edge; 3], at_start: &[i64; 3], n: i64) -> Option<(i64, i64)> {
    let (mut low, mut high) = (0, n - 1);
    for (edge, &start) in edges.iter().zip(at_start) {
        let (step, margin) = (edge.step(), start - edge.threshold);
        match step.signum() {
            // start + k·step ≥ threshold  ⇔  k ≥ ⌈−margin / step⌉
            1 => low = low.max((-margin + step - 1).div_euclid(step)),
            // ⇔  k ≤ ⌊margin / −step⌋
            -1 => high = high.min(margin.div_euclid(-step)),
            _ if margin < 0 => return None,
            _ => {}
        }
    }
    (low <= high).then_some((low, high))
}

/// A screen point (sample units) snapped to fixed point; `None` when not finite or beyond the
/// guard band.
fn snap([x, y, _]: [f64; 3]) -> Option<[i64; 2]> {
    let usable = |c: f64| c.is_finite() && c.abs() < GUARD_SAMPLES;
    let fixed = |c: f64| (c * SUBPIXEL as f64).round() as i64;
    (usable(x) && usable(y)).then(|| [fixed(x), fixed(y)])
}

/// The colour as a vector, black when a channel is not finite.
fn finite_or_black(colour: [f64; 3]) -> Vector3<f64> {
    let colour = Vector3::from(colour);
    if colour.iter().all(|c| c.is_finite()) {
        colour
    } else {
        Vector3::zeros()
    }
}

/// Inclusive range of samples `i < n` whose centres `(i + ½)` lie between the smallest and
/// largest of the fixed-point coordinates; `None` when there is none.
fn covered_samples(coordinates: [i64; 3], n: usize) -> Option<(usize, usize)> {
    let low = *coordinates.iter().min().expect("three coordinates");
    let high = *coordinates.iter().max().expect("three coordinates");
    // Centre of sample i is i·SUBPIXEL + SUBPIXEL/2: first = ⌈(low − ½)/S⌉, last = ⌊(high − ½)/S⌋.
    let first = (low - SUBPIXEL / 2 + SUBPIXEL - 1).div_euclid(SUBPIXEL);
    let last = (high - SUBPIXEL / 2).div_euclid(SUBPIXEL);
    let (first, last) = (first.max(0), last.min(n as i64 - 1));
    (first <= last).then_some((first as usize, last as usize))
}
