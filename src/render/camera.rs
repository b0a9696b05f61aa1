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
//! A [`View`] is the direction from the target to the eye, given by azimuth `a` and elevation
//! `e` relative to a world *up axis* `u` (an [`UpAxis`]: ±x, ±y or ±z), and a roll `ρ`. With
//! the horizontal axes `(h₁, h₂)` of `u` from the table below,
//!
//! ```text
//! direction = cos e (cos a h₁ + sin a h₂) + sin e u
//! ```
//!
//! so azimuth turns from `h₁` towards `h₂` (counter-clockwise seen from above, i.e. from `+u`)
//! and elevation rises towards `u`. `(h₁, h₂, u)` is right-handed: it is the image of
//! `(x, y, z)` under the smallest rotation that takes `+z` to `u` (for `−z`, the half turn
//! about `x`). For `u = +z` this is the plain convention (azimuth from +x towards +y,
//! elevation above the xy-plane); for `u = +y`, the glTF convention, it is the rotation that
//! z-up modelling tools apply when they export to glTF (`(x, y, z) ↦ (x, z, −y)`), so a model
//! looks the same from the same view angles before and after the export: azimuth −60°,
//! elevation 30° sees it from the front right and above in both.
//!
//! | up `u` | `h₁` (azimuth 0°) | `h₂` (azimuth 90°) |
//! |---|---|---|
//! | `+z` | `+x` | `+y` |
//! | `+y` | `+x` | `−z` |
//! | `+x` | `−z` | `+y` |
//! | `−z` | `+x` | `−y` |
//! | `−y` | `+x` | `+z` |
//! | `−x` | `+z` | `+y` |
//!
//! The camera's world up is `u`, so `u` points up in the picture. Looking straight along `u`
//! (elevation ±90°) it falls back to `h₂`, then `h₁` (for an arbitrary `up` given to
//! [`Camera::look_at`]: +y, then +x). Finally the roll `ρ` turns the picture about its centre,
//! counter-clockwise for `ρ > 0`: the screen axes become
//! `r' = cos ρ r + sin ρ d`, `d' = cos ρ d − sin ρ r`, and at `ρ = 90°` the up axis points left.
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

/// A signed coordinate axis that points up in pictures; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum UpAxis {
    X,
    Y,
    #[default]
    Z,
    NegX,
    NegY,
    NegZ,
}

impl UpAxis {
    pub const ALL: [UpAxis; 6] = [
        Self::X,
        Self::Y,
        Self::Z,
        Self::NegX,
        Self::NegY,
        Self::NegZ,
    ];

    /// The unit vector of the axis.
    pub fn vector(self) -> Vector3<f64> {
        let [_, _, up] = self.frame();
        up
    }

    /// `[h₁, h₂, u]`: the horizontal axes at azimuth 0° and 90° and the up axis, a
    /// right-handed orthonormal frame (the table of the module documentation).
    pub fn frame(self) -> [Vector3<f64>; 3] {
        let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
        match self {
            Self::Z => [x, y, z],
            Self::Y => [x, -z, y],
            Self::X => [-z, y, x],
            Self::NegZ => [x, -y, -z],
            Self::NegY => [x, z, -y],
            Self::NegX => [z, y, -x],
        }
    }

    /// `x`, `y`, `z`, `-x`, `-y` or `-z`.
    pub fn name(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
            Self::NegX => "-x",
            Self::NegY => "-y",
            Self::NegZ => "-z",
        }
    }
}

impl std::fmt::Display for UpAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for UpAxis {
    type Err = RenderError;

    /// Parses `x`, `y`, `z`, `-x`, `-y`, `-z` (also `+x`, upper case).
    fn from_str(text: &str) -> Result<Self, RenderError> {
        let wanted = text.trim().to_ascii_lowercase();
        let wanted = wanted.strip_prefix('+').unwrap_or(&wanted);
        Self::ALL
            .into_iter()
            .find(|axis| axis.name() == wanted)
            .ok_or_else(|| RenderError::UpAxis {
                text: text.to_string(),
            })
    }
}

impl From<UpAxis> for String {
    fn from(axis: UpAxis) -> String {
        axis.name().to_string()
    }
}

impl TryFrom<String> for UpAxis {
    type Error = RenderError;

    fn try_from(text: String) -> Result<Self, RenderError> {
        text.parse()
    }
}

/// The direction from the target to the eye relative to an up axis, and the picture's roll,
/// in degrees; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct View {
    pub azimuth_degrees: f64,
    pub elevation_degrees: f64,
    /// Counter-clockwise turn of the picture.
    pub roll_degrees: f64,
    pub up: UpAxis,
}

impl Default for View {
    /// Azimuth −60°, elevation 30°, no roll, +z up: a three-quarter view from the front right
    /// and above (the eye towards +x, −y, +z) of something centred at the origin.
    fn default() -> Self {
        Self::new(-60.0, 30.0)
    }
}

impl View {
    /// The view from azimuth and elevation in degrees, +z up, no roll.
    pub fn new(azimuth_degrees: f64, elevation_degrees: f64) -> Self {
        Self {
            azimuth_degrees,
            elevation_degrees,
            roll_degrees: 0.0,
            up: UpAxis::Z,
        }
    }

    /// The same angles relative to another up axis.
    pub fn with_up(self, up: UpAxis) -> Self {
        Self { up, ..self }
    }

    /// Unit vector from the target to the eye: `cos e (cos a h₁ + sin a h₂) + sin e u`.
    pub fn direction(&self) -> Vector3<f64> {
        let (a, e) = (
            self.azimuth_degrees.to_radians(),
            self.elevation_degrees.to_radians(),
        );
        let [h1, h2, up] = self.up.frame();
        (h1 * a.cos() + h2 * a.sin()) * e.cos() + up * e.sin()
    }
}

impl FromStr for View {
    type Err = RenderError;

    /// Parses `"AZIMUTH,ELEVATION[,ROLL]"` in degrees, e.g. `"-60,30"` or `"0,10,90"` (spaces
    /// allowed); the up axis is +z (see [`View::with_up`]).
    fn from_str(text: &str) -> Result<Self, RenderError> {
        let error = |reason: &str| RenderError::View {
            text: text.to_string(),
            reason: reason.to_string(),
        };
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let (azimuth, elevation, roll) = match parts[..] {
            [azimuth, elevation] => (azimuth, elevation, None),
            [azimuth, elevation, roll] => (azimuth, elevation, Some(roll)),
            _ => return Err(error("needs two or three numbers separated by commas")),
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
            roll_degrees: roll.map(|r| angle(r, "roll")).transpose()?.unwrap_or(0.0),
            up: UpAxis::Z,
        })
    }
}

/// A pinhole (perspective) camera and the size of its picture; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    frame: Frame,
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
        let frame = Frame::oriented(eye, target, [up, Vector3::y(), Vector3::x()], 0.0);
        Ok(Self::new(frame, fov_y_degrees, width, height))
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
        let mut roll = view.roll_degrees.to_radians();
        if !(direction.iter().all(|x| x.is_finite()) && roll.is_finite()) {
            direction = View::default().direction();
            roll = 0.0;
        }
        let [h1, h2, up] = view.up.frame();
        let frame = Frame::oriented(centre + distance * direction, centre, [up, h2, h1], roll);
        Self::new(frame, DEFAULT_FOV_Y_DEGREES, width, height)
    }

    fn new(frame: Frame, fov_y_degrees: f64, width: u32, height: u32) -> Self {
        Self {
            near: NEAR_FRACTION * (frame.target - frame.eye).norm(),
            frame,
            fov_y_degrees,
            focal: height as f64 / 2.0 / (fov_y_degrees / 2.0).to_radians().tan(),
            width,
            height,
        }
    }

    /// Pixel x (right), pixel y (down) and depth of `p`; `None` when `p` is not in front of the
    /// near plane (or not finite). Points outside the picture are projected too.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 3]> {
        let q = p - self.frame.eye;
        let depth = q.dot(&self.frame.forward);
        if !(depth > self.near && depth.is_finite()) {
            return None;
        }
        let scale = self.focal / depth;
        Some([
            self.width as f64 / 2.0 + scale * q.dot(&self.frame.right),
            self.height as f64 / 2.0 + scale * q.dot(&self.frame.down),
            depth,
        ])
    }

    /// `(v·right, v·down)`: the tangent vector `v` as the camera sees its direction, in the
    /// Middlebury `(u, v)` convention (x right, y down); see the module documentation.
    pub fn screen_components(&self, v: &Vector3<f64>) -> [f64; 2] {
        [v.dot(&self.frame.right), v.dot(&self.frame.down)]
    }

    /// The world vector with camera coordinates `(x, y, z)` = (right, down, forward).
    pub fn camera_to_world(&self, [x, y, z]: [f64; 3]) -> Vector3<f64> {
        x * self.frame.right + y * self.frame.down + z * self.frame.forward
    }

    /// Pixels per world length unit for a segment parallel to the picture at `depth`: `F / z`.
    pub fn pixels_per_unit(&self, depth: f64) -> f64 {
        self.focal / depth
    }

    /// Distance from the eye to the target along the view axis.
    pub fn target_depth(&self) -> f64 {
        (self.frame.target - self.frame.eye).norm()
    }

    pub fn eye(&self) -> Vector3<f64> {
        self.frame.eye
    }

    pub fn target(&self) -> Vector3<f64> {
        self.frame.target
    }

    /// Unit vector pointing right in the picture.
    pub fn right(&self) -> Vector3<f64> {
        self.frame.right
    }

    /// Unit vector pointing down in the picture.
    pub fn down(&self) -> Vector3<f64> {
        self.frame.down
    }

    /// Unit vector along the view axis, from the eye into the scene.
    pub fn forward(&self) -> Vector3<f64> {
        self.frame.forward
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

/// A camera's position and orthonormal axes.
#[derive(Clone, Debug, PartialEq)]
struct Frame {
    eye: Vector3<f64>,
    target: Vector3<f64>,
    right: Vector3<f64>,
    down: Vector3<f64>,
    forward: Vector3<f64>,
}

impl Frame {
    /// The frame of valid parameters (finite, `eye ≠ target`, `ups[0] ≠ 0`): right is
    /// `f × up` for the first of `ups` not (nearly) parallel to the view axis, then the axes
    /// are turned by `roll` radians (counter-clockwise on the screen).
    fn oriented(
        eye: Vector3<f64>,
        target: Vector3<f64>,
        ups: [Vector3<f64>; 3],
        roll: f64,
    ) -> Self {
        let forward = (target - eye).normalize();
        let right = ups
            .iter()
            .map(|candidate| forward.cross(&candidate.normalize()))
            .find(|right| right.norm() > 1e-6)
            .unwrap_or_else(Vector3::x)
            .normalize();
        let down = forward.cross(&right);
        // No roll leaves the axes bit for bit as they were.
        let (right, down) = if roll == 0.0 {
            (right, down)
        } else {
            let (sin, cos) = roll.sin_cos();
            (cos * right + sin * down, cos * down - sin * right)
        };
        Self {
            eye,
            target,
            right,
            down,
            forward,
        }
    }
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
