//! Pinhole cameras: where a point of R³ lands in the picture, and how a tangent vector looks.
//!
//! A camera at `eye` looking at `target` with world direction `up` has the orthonormal frame
//!
//! ```text
//! forward f = (target − eye) / |target − eye|,   right r = f × up / |f × up|,   down d = f × r
//! ```
//!
//! (right-handed: `r × d = f`). A point `p` has camera coordinates
//! `(x, y, z) = ((p − eye)·r, (p − eye)·d, (p − eye)·f)`; `z` is its *depth*, the distance
//! along the view axis. The perspective projection onto a `W × H` picture is
//!
//! ```text
//! pixel x = W/2 + F x / z,   pixel y = H/2 + F y / z,   F = (H/2) / tan(φ/2),
//! ```
//!
//! `φ` the vertical field of view and `F` the focal length in pixels (pixels are square, so the
//! horizontal field of view is `2 atan(tan(φ/2) W/H)`). Pixel `(i, j)` covers
//! `[i, i + 1) × [j, j + 1)`, its centre is `(i + 0.5, j + 0.5)`, and **y grows downward**.
//! Points at depth `z ≤ near = 10⁻³ |eye − target|` (behind or at the eye) are not projected.
//!
//! # Views
//!
//! A [`View`] is the direction from the target to the eye, `(cos e cos a, cos e sin a, sin e)`
//! for azimuth `a` (in the xy-plane, from +x towards +y) and elevation `e` (above the
//! xy-plane). World up is +z; looking straight down or up, where +z is parallel to the view
//! axis, +y takes its place (then +x, for an arbitrary `up` given to [`Camera::look_at`]).
//!
//! # Screen components
//!
//! [`Camera::screen_components`] gives `(v·r, v·d)` for a tangent vector `v`: its direction as
//! the camera sees it, x right and y *down*. That is exactly the Middlebury `(u, v)` convention
//! of [`super::color_wheel`], so a flow coloured with
//! `flow_color(screen_components(u) / scale)` reads like a Middlebury image: moving right on
//! the screen is red, down is yellow-orange, left cyan-blue, up violet. It is the image-plane
//! part of `v`, without the perspective factor `F/z` and the term from `v`'s depth component
//! (the projected point moves with `F/z · (v·r − x/z v·f, v·d − y/z v·f)`): it encodes
//! the screen direction and the world speed, uniformly over the picture, as a legend needs.

use super::RenderError;
use nalgebra::Vector3;
use std::str::FromStr;

/// Vertical field of view of cameras made by [`Camera::framing`], degrees.
pub const DEFAULT_FOV_Y_DEGREES: f64 = 30.0;

/// Largest picture side accepted, pixels (keeps the supersampled buffers within memory).
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// Fraction of the smaller half-extent of the picture that [`Camera::framing`] gives to the
/// bounding sphere's silhouette radius: a small margin around the object.
const FRAMING_FILL: f64 = 0.88;

/// Near plane distance relative to the eye–target distance.
const NEAR_FRACTION: f64 = 1e-3;

/// The direction from the target to the eye, in degrees; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub azimuth_degrees: f64,
    pub elevation_degrees: f64,
}

impl Default for View {
    /// Azimuth −60°, elevation 30°: a three-quarter view from the front right and above
    /// (the eye towards +x, −y, +z) of something centred at the origin.
    fn default() -> Self {
        Self {
            azimuth_degrees: -60.0,
            elevation_degrees: 30.0,
        }
    }
}

impl View {
    /// Unit vector from the target to the eye: `(cos e cos a, cos e sin a, sin e)`.
    pub fn direction(&self) -> Vector3<f64> {
        let (a, e) = (
            self.azimuth_degrees.to_radians(),
            self.elevation_degrees.to_radians(),
        );
        Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
    }
}

impl FromStr for View {
    type Err = RenderError;

    /// Parses `"AZIMUTH,ELEVATION"` in degrees, e.g. `"-60,30"` (spaces allowed).
    fn from_str(text: &str) -> Result<Self, RenderError> {
        let error = |reason: &str| RenderError::View {
            text: text.to_string(),
            reason: reason.to_string(),
        };
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let [azimuth, elevation] = parts[..] else {
            return Err(error("needs exactly two numbers separated by a comma"));
        };
        let angle = |part: &str, name: &str| {
            part.parse::<f64>()
                .ok()
                .filter(|a| a.is_finite())
                .ok_or_else(|| error(&format!("{name} {part:?} is not a finite number")))
        };
        Ok(Self {
            azimuth_degrees: angle(azimuth, "azimuth")?,
            elevation_degrees: angle(elevation, "elevation")?,
        })
    }
}

/// A pinhole (perspective) camera and the size of its picture; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    eye: Vector3<f64>,
    target: Vector3<f64>,
    right: Vector3<f64>,
    down: Vector3<f64>,
    forward: Vector3<f64>,
    fov_y_degrees: f64,
    focal: f64,
    near: f64,
    width: u32,
    height: u32,
}

impl Camera {
    /// The camera at `eye` looking at `target`, `up` pointing up in the picture (only its part
    /// perpendicular to the view axis matters; a parallel `up` falls back to +y, then +x),
    /// vertical field of view `fov_y_degrees` in (0, 180), picture `width × height` pixels.
    pub fn look_at(
        eye: Vector3<f64>,
        target: Vector3<f64>,
        up: Vector3<f64>,
        fov_y_degrees: f64,
        width: u32,
        height: u32,
    ) -> Result<Self, RenderError> {
        let fail = |reason: String| Err(RenderError::Camera { reason });
        let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        if !(finite(&eye) && finite(&target) && finite(&up)) {
            return fail(format!(
                "eye {eye:?}, target {target:?} and up {up:?} must be finite"
            ));
        }
        if (target - eye).norm() == 0.0 || up.norm() == 0.0 {
            return fail("the eye must differ from the target and up must be non-zero".into());
        }
        if !(fov_y_degrees > 0.0 && fov_y_degrees < 180.0) {
            return fail(format!(
                "field of view {fov_y_degrees}° must lie strictly between 0° and 180°"
            ));
        }
        if !(1..=MAX_IMAGE_SIDE).contains(&width) || !(1..=MAX_IMAGE_SIDE).contains(&height) {
            return fail(format!(
                "picture size {width}×{height} must be between 1 and {MAX_IMAGE_SIDE} pixels a side"
            ));
        }
        Ok(Self::oriented(
            eye,
            target,
            up,
            fov_y_degrees,
            width,
            height,
        ))
    }

    /// The camera that looks at the centre of the bounding box of the finite `points` from
    /// direction `view`, with field of view [`DEFAULT_FOV_Y_DEGREES`], from the distance at
    /// which the bounding sphere (about that centre) fills 88 % of the smaller half-extent of
    /// the picture: its silhouette radius `F tan(asin(R/d))` is `0.88 F tan(φ_min/2)`, with
    /// `φ_min` the smaller of the horizontal and vertical fields of view.
    ///
    /// Never fails: no finite point frames the unit sphere, a single point a unit sphere around
    /// it, a non-finite view is replaced by the default, sizes are clamped to
    /// `1..=`[`MAX_IMAGE_SIDE`].
    pub fn framing(points: &[Vector3<f64>], view: View, width: u32, height: u32) -> Self {
        let (width, height) = (
            width.clamp(1, MAX_IMAGE_SIDE),
            height.clamp(1, MAX_IMAGE_SIDE),
        );
        let (centre, radius) = bounding_sphere(points);
        let tan_half_y = (DEFAULT_FOV_Y_DEGREES / 2.0).to_radians().tan();
        let tan_half_min = tan_half_y * (width as f64 / height as f64).min(1.0);
        let angular_radius = (FRAMING_FILL * tan_half_min).atan();
        let distance = radius / angular_radius.sin();
        let mut direction = view.direction();
        if !direction.iter().all(|x| x.is_finite()) {
            direction = View::default().direction();
        }
        Self::oriented(
            centre + distance * direction,
            centre,
            Vector3::z(),
            DEFAULT_FOV_Y_DEGREES,
            width,
            height,
        )
    }

    /// Builds the frame of valid parameters (finite, `eye ≠ target`, `up ≠ 0`).
    fn oriented(
        eye: Vector3<f64>,
        target: Vector3<f64>,
        up: Vector3<f64>,
        fov_y_degrees: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let offset = target - eye;
        let forward = offset.normalize();
        let right = right_axis(&forward, &up);
        Self {
            eye,
            target,
            right,
            down: forward.cross(&right),
            forward,
            fov_y_degrees,
            focal: height as f64 / 2.0 / (fov_y_degrees / 2.0).to_radians().tan(),
            near: NEAR_FRACTION * offset.norm(),
            width,
            height,
        }
    }

    /// Pixel x (right), pixel y (down) and depth of `p`; `None` when `p` is not in front of the
    /// near plane (or not finite). Points outside the picture are projected too.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 3]> {
        let q = p - self.eye;
        let depth = q.dot(&self.forward);
        if !(depth > self.near && depth.is_finite()) {
            return None;
        }
        let scale = self.focal / depth;
        Some([
            self.width as f64 / 2.0 + scale * q.dot(&self.right),
            self.height as f64 / 2.0 + scale * q.dot(&self.down),
            depth,
        ])
    }

    /// `(v·right, v·down)`: the tangent vector `v` as the camera sees its direction, in the
    /// Middlebury `(u, v)` convention (x right, y down); see the module documentation.
    pub fn screen_components(&self, v: &Vector3<f64>) -> [f64; 2] {
        [v.dot(&self.right), v.dot(&self.down)]
    }

    /// The world vector with camera coordinates `(x, y, z)` = (right, down, forward).
    pub fn camera_to_world(&self, [x, y, z]: [f64; 3]) -> Vector3<f64> {
        x * self.right + y * self.down + z * self.forward
    }

    /// Pixels per world length unit for a segment parallel to the picture at `depth`: `F / z`.
    pub fn pixels_per_unit(&self, depth: f64) -> f64 {
        self.focal / depth
    }

    /// Distance from the eye to the target along the view axis.
    pub fn target_depth(&self) -> f64 {
        (self.target - self.eye).norm()
    }

    pub fn eye(&self) -> Vector3<f64> {
        self.eye
    }

    pub fn target(&self) -> Vector3<f64> {
        self.target
    }

    /// Unit vector pointing right in the picture.
    pub fn right(&self) -> Vector3<f64> {
        self.right
    }

    /// Unit vector pointing down in the picture.
    pub fn down(&self) -> Vector3<f64> {
        self.down
    }

    /// Unit vector along the view axis, from the eye into the scene.
    pub fn forward(&self) -> Vector3<f64> {
        self.forward
    }

    pub fn fov_y_degrees(&self) -> f64 {
        self.fov_y_degrees
    }

    /// Focal length `F = (H/2) / tan(φ/2)`, pixels.
    pub fn focal_length(&self) -> f64 {
        self.focal
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }
}

/// `f × up`, normalized; when `up` is (nearly) parallel to `f`, +y and then +x take its place.
fn right_axis(forward: &Vector3<f64>, up: &Vector3<f64>) -> Vector3<f64> {
    [up.normalize(), Vector3::y(), Vector3::x()]
        .iter()
        .map(|candidate| forward.cross(candidate))
        .find(|right| right.norm() > 1e-6)
        .unwrap_or_else(Vector3::x)
        .normalize()
}

/// Centre of the bounding box of the finite points and the largest distance from it (the unit
/// sphere at the origin when there is no finite point, radius 1 when all points coincide).
fn bounding_sphere(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let finite: Vec<&Vector3<f64>> = points
        .iter()
        .filter(|p| p.iter().all(|x| x.is_finite()))
        .collect();
    let Some(first) = finite.first() else {
        return (Vector3::zeros(), 1.0);
    };
    let (low, high) = finite.iter().fold((**first, **first), |(low, high), p| {
        (low.inf(p), high.sup(p))
    });
    let centre = (low + high) / 2.0;
    let radius = finite
        .iter()
        .map(|p| (*p - centre).norm())
        .fold(0.0, f64::max);
    let usable = radius > 0.0 && radius.is_finite() && centre.iter().all(|x| x.is_finite());
    if usable {
        (centre, radius)
    } else {
        (centre.map(|x| if x.is_finite() { x } else { 0.0 }), 1.0)
    }
}
