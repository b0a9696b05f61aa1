//! Pictures of surfaces and flows, drawn headless into PNG images.
//!
//! # The math
//!
//! *Projection* ([`camera`]): a pinhole camera with frame right `r`, down `d`, forward `f`
//! maps a point with camera coordinates `(x, y, z)` to pixel `(W/2 + F x/z, H/2 + F y/z)`,
//! `F = (H/2)/tan(φ/2)` for the vertical field of view `φ`; `z` is the depth.
//!
//! *Visibility* ([`raster`]): a z-buffer rasterizer. Every triangle is scanned over the samples
//! its projection covers (exact integer edge functions, top-left fill rule), and a sample keeps
//! the nearest surface. O(samples + triangles), exact per-sample depth, no acceleration
//! structure to build per frame of a deforming mesh, which is why it is used rather than ray
//! casting.
//!
//! *Interpolation*: with screen barycentric coordinates `λ_i` and vertex depths `w_i`, vertex
//! attributes (colours, normals) are interpolated perspective-correctly,
//! `attr = Σ λ_i a_i / w_i / Σ λ_i / w_i`, the same as interpolating over the triangle in R³.
//!
//! *Shading* ([`shading`]): Lambert with a light fixed to the camera,
//! `colour · (ambient + diffuse · |n · l|)`, two-sided, with area-weighted vertex normals.
//!
//! *Up axis* ([`upright`]): without `--up`, glTF input is y up by its convention and other
//! input gets the axis its frame-0 shape suggests from the area-weighted principal spreads:
//! sheets and disks lie flat and rods stand when their axis is near y or z, balls keep z,
//! everything else gets y, the convention of scanned and exported models.
//!
//! *Signed values* ([`signed_picture`]): the [`colormap::diverging`] map over a range
//! symmetric about zero ([`colormap::symmetric_range`]) makes the sign the hue: blue
//! negative, white zero, red positive, as for divergence, curl and areal growth rate.
//!
//! *Charts* ([`plot`], [`series_chart`]): a point `(x, y)` of a series maps affinely into the
//! plot area, `px = x₀ + (x − lo)/(hi − lo) · (x₁ − x₀)` and likewise upward for `y`, over
//! the finite data's ranges padded by 5 %; non-finite values are gaps in the line.
//!
//! *Antialiasing*: everything, surface and overlays alike, is drawn at `s × s` samples per
//! pixel (`s = 3` by default) and box-filtered down.
//!
//! # Conventions
//!
//! - Pixel `(i, j)` has its centre at `(i + ½, j + ½)`; x grows to the right, **y downward**.
//! - [`Camera::screen_components`] of a tangent vector `v` is `(v · right, v · down)`, exactly
//!   the Middlebury `(u, v)` of [`color_wheel`]: on a flow picture red moves right on the
//!   screen, yellow-orange down, cyan-blue left, violet up, and the legend disc's rim is the
//!   flow scale.
//! - Colours are RGB in `[0, 1]`, written without gamma; the background is white;
//!   non-finite values are drawn black.
//!
//! # Example
//!
//! ```
//! use meshflow::render::{flow_picture, Camera, PictureStyle, Surface, View};
//! use nalgebra::Vector3;
//!
//! let sphere = meshflow::shapes::icosphere(3);
//! // Turning about +z: u = ẑ × x.
//! let flow: Vec<Vector3<f64>> = sphere.positions.iter().map(|p| Vector3::z().cross(p)).collect();
//! let camera = Camera::framing(&sphere.positions, View::default(), 320, 240);
//! let surface = Surface::from(&sphere);
//! let style = PictureStyle { label: Some("t = 0".into()), ..PictureStyle::default() };
//! let image = flow_picture(&camera, surface, &flow, 1.0, &style)?;
//! assert_eq!(image.dimensions(), (320, 240));
//! // meshflow::render::write_png(std::path::Path::new("flow.png"), &image)?;
//! # Ok::<(), meshflow::Error>(())
//! ```

pub mod camera;
pub mod color_wheel;
pub mod colormap;
mod error;
pub mod figure;
pub mod glyphs;
pub mod legend;
pub mod plot;
pub mod raster;
pub mod shading;
pub mod slabs;
pub mod text;
pub mod upright;

pub use camera::{Camera, UpAxis, View};
pub use error::RenderError;
pub use figure::{
    arrow_picture, chart_picture, flow_picture, grey_picture, mosaic_picture, mosaic_values,
    scalar_picture, screen_flow_colors, series_chart, signed_picture, track_errors_picture,
    tracks_picture, trajectory_picture, write_png, PictureStyle, Series, Surface, NO_DATA_COLOUR,
    TRACK_ARROW_COLOUR,
};
pub use raster::Canvas;
pub use shading::Lighting;
pub use slabs::{
    result_views, sequence_views, write_chosen_slab_pictures, write_slab_pictures,
    write_track_error_pictures, FigureOptions, SlabSelection, SlabView,
};
pub use upright::{up_convention, CapView, Shape, ShapeUp, UpChoice, UpReason, CAP_FACING};
