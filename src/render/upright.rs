//! The up axis that a surface's shape suggests, for files whose format does not say.
//!
//! # Spreads
//!
//! A surface's *spreads* `σ₀ ≤ σ₁ ≤ σ₂` are the standard deviations, along its principal axes
//! `e₀, e₁, e₂`, of a point spread uniformly over its area: the square roots of the
//! eigenvalues of the area-weighted covariance
//!
//! ```text
//! C = (1/A) Σ_t A_t M_t − m mᵀ,   M_t = (a aᵀ + b bᵀ + c cᵀ + s sᵀ) / 12,
//! m = (1/A) Σ_t A_t s / 3,        s = a + b + c,
//! ```
//!
//! `M_t` the exact second moment of the uniform distribution on triangle `abc`, `A_t` its area
//! and `A` the total. Being moments of the area, they do not depend on how finely or evenly the
//! surface is meshed.
//!
//! # The rule
//!
//! | shape | spreads | its axis |
//! |---|---|---|
//! | sheet | `σ₀ ≤ 0.1 σ₁` | the normal `e₀` |
//! | disk: a cap, a dome, a ring | `σ₀ ≤ σ₁/2` and `σ₁ ≥ 0.8 σ₂` | the normal `e₀` |
//! | rod | `σ₁ ≤ σ₂/2` and `σ₀ ≥ 0.8 σ₁` | the length `e₂` |
//! | ball: no direction stands out | `σ₀ ≥ 0.8 σ₂` | none |
//! | anything else: a figure, an animal, a bust, a vehicle | | none |
//!
//! A sheet, disk or rod whose axis lies within 25° of y or z has that axis up (sheets and disks
//! lie flat, rods stand); a ball keeps z; everything else gets y.
//!
//! Why: OBJ, PLY and NPY files do not say which way is up, and two conventions meet in them.
//! Scanned models and exports of modelling and animation tools are y up (the Stanford bunny,
//! Spot, igea); microscopy and many scanners write z up, the stack axis, and their surfaces are
//! mostly caps, domes and sheets seen from above. Second moments cannot tell a model's y from
//! its z: a y-up cow has the spreads of a z-up bust with y and z swapped. So a shape without
//! an axis of its own gets the models' convention. Measured: the bunny (spreads
//! 0.55 : 0.70 : 1) and Spot (0.43 : 0.54 : 1, its long axis 42° from z) are neither disks nor
//! rods and get y, as do characters that are flat but taller than wide (about 0.3 : 0.75 : 1);
//! a zebrafish endoderm cap (0.38 : 0.95 : 1, normal 17° from z) and a meristem dome
//! (0.19 : 0.84 : 1) are disks and get z. Where the rule guesses wrong, `--up` decides.
//!
//! # Caps and sheets: seen along their axis
//!
//! A surface with a boundary whose area faces mostly one way is a cap or a sheet: the yolk
//! surface of an embryo under a microscope, an epithelium, a height field. Its *facing* is
//!
//! ```text
//! f = |Σ_t A_t n_t| / Σ_t A_t   ∈ [0, 1]      (n_t the unit normal of triangle t)
//! ```
//!
//! 1 for a flat sheet, `(1 + cos θ)/2` for a spherical cap of half-angle `θ` (0.5 for a
//! hemisphere), 0 for a closed surface. With a boundary and `f ≥ 0.25` ([`CAP_FACING`]), the
//! pictures look along the mean normal `m = Σ_t A_t n_t` from the side it points to: the
//! outside of a cap (outward normals, counter-clockwise faces), the side a microscope imaged
//! it from, with every part of it in view. The up axis is the signed axis nearest `m`, and
//! the view's elevation and azimuth turn the eye onto `m` exactly ([`CapView`]). Measured on
//! the zebrafish cap of `meshflow surface` (65k vertices): facing 0.44, `m` 18° from −z, where
//! the spread rule's oblique view into the bowl left a third of the picture black.

use super::{UpAxis, View};
use crate::load::{FrameFormat, LoadedSequence, SequenceSource};
use nalgebra::{Matrix3, Vector3};

/// A sheet is thinner than this fraction of its narrower side.
const SHEET_THICKNESS: f64 = 0.1;
/// A disk's thickness, and a rod's width, is at most this fraction of the next spread up.
const FLAT: f64 = 0.5;
/// A disk's two sides, a rod's two widths and a ball's three spreads agree to this fraction.
const ROUND: f64 = 0.8;
/// How far a shape's axis may lie from y or z for that axis to be up.
const MAX_TILT_DEGREES: f64 = 25.0;
/// The least facing `f` of a surface with a boundary that is seen along its axis (module
/// documentation): a spherical cap of half-angle up to 120°.
pub const CAP_FACING: f64 = 0.25;

/// What the spreads say about a surface; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Sheet,
    Disk,
    Rod,
    Ball,
    Other,
}

impl Shape {
    /// The class of spreads `σ₀ ≤ σ₁ ≤ σ₂`.
    fn of_spreads([s0, s1, s2]: [f64; 3]) -> Self {
        if s0 <= SHEET_THICKNESS * s1 {
            Self::Sheet
        } else if s0 <= FLAT * s1 && s1 >= ROUND * s2 {
            Self::Disk
        } else if s1 <= FLAT * s2 && s0 >= ROUND * s1 {
            Self::Rod
        } else if s0 >= ROUND * s2 {
            Self::Ball
        } else {
            Self::Other
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Sheet => "a sheet",
            Self::Disk => "a disk",
            Self::Rod => "a rod",
            Self::Ball => "a ball",
            Self::Other => "a shape without an axis of its own",
        }
    }
}

/// The up axis that a surface's shape suggests, and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeUp {
    pub axis: UpAxis,
    pub shape: Shape,
    /// `σ₀/σ₂, σ₁/σ₂, 1`.
    pub spreads: [f64; 3],
    /// For a sheet, disk or rod: the angle between its axis and the nearer of y and z.
    pub tilt_degrees: Option<f64>,
    /// That nearer axis.
    pub nearest: Option<UpAxis>,
}

impl ShapeUp {
    /// The up axis of the surface `faces` over `positions` (see the module documentation);
    /// `None` when it has no area to go by (no faces, all degenerate, or a non-finite
    /// coordinate on one).
    pub fn of_surface(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Option<Self> {
        let covariance = area_covariance(positions, faces)?;
        let eigen = covariance.symmetric_eigen();
        let mut order = [0, 1, 2];
        order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
        let spread = |i: usize| eigen.eigenvalues[order[i]].max(0.0).sqrt();
        let largest = spread(2);
        let spreads = [spread(0) / largest, spread(1) / largest, 1.0];
        let shape = Shape::of_spreads(spreads);
        let shape_axis = match shape {
            Shape::Sheet | Shape::Disk => Some(eigen.eigenvectors.column(order[0]).into_owned()),
            Shape::Rod => Some(eigen.eigenvectors.column(order[2]).into_owned()),
            Shape::Ball | Shape::Other => None,
        };
        let nearest = shape_axis.map(|e| nearer_of_y_and_z(&e));
        let axis = match (shape, nearest) {
            (_, Some((axis, tilt))) if tilt <= MAX_TILT_DEGREES => axis,
            (Shape::Ball, _) => UpAxis::Z,
            _ => UpAxis::Y,
        };
        Some(Self {
            axis,
            shape,
            spreads,
            tilt_degrees: nearest.map(|(_, tilt)| tilt),
            nearest: nearest.map(|(axis, _)| axis),
        })
    }
}

impl std::fmt::Display for ShapeUp {
    /// E.g. "a disk, spreads 0.38 : 0.95 : 1, its axis 17° from z".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [s0, s1, _] = self.spreads;
        write!(f, "{}, spreads {s0:.2} : {s1:.2} : 1", self.shape.name())?;
        match (self.nearest, self.tilt_degrees) {
            (Some(nearest), Some(tilt)) if nearest == self.axis => {
                write!(f, ", its axis {tilt:.0}° from {nearest}")
            }
            (Some(nearest), Some(tilt)) => write!(
                f,
                ", its axis {tilt:.0}° from {nearest}, too far to stand on: {} as for models",
                self.axis
            ),
            _ if self.shape == Shape::Ball => write!(f, ": no direction stands out, z"),
            _ => write!(f, ": {} as for scanned and exported models", self.axis),
        }
    }
}

/// `(y or z, angle in degrees)`: the one of the two axes nearer to the line along `axis`.
fn nearer_of_y_and_z(axis: &Vector3<f64>) -> (UpAxis, f64) {
    let tilt = |candidate: UpAxis| {
        let cosine = axis.normalize().dot(&candidate.vector()).abs();
        cosine.min(1.0).acos().to_degrees()
    };
    let (y, z) = (tilt(UpAxis::Y), tilt(UpAxis::Z));
    match y < z {
        true => (UpAxis::Y, y),
        false => (UpAxis::Z, z),
    }
}

/// The area-weighted covariance of the surface (module documentation); `None` without area.
fn area_covariance(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Option<Matrix3<f64>> {
    let mut area = 0.0;
    let mut first = Vector3::zeros();
    let mut second = Matrix3::zeros();
    for face in faces {
        let Some([a, b, c]) = corners(positions, face) else {
            continue;
        };
        let weight = 0.5 * (b - a).cross(&(c - a)).norm();
        if !weight.is_finite() {
            continue;
        }
        let sum = a + b + c;
        area += weight;
        first += weight * sum / 3.0;
        second += weight / 12.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose());
        second += weight / 12.0 * sum * sum.transpose();
    }
    if !(area > 0.0 && area.is_finite()) {
        return None;
    }
    let mean = first / area;
    Some(second / area - mean * mean.transpose())
}

/// The corners of `face`, `None` if one of them is not a vertex.
fn corners(positions: &[Vector3<f64>], face: &[u32; 3]) -> Option<[Vector3<f64>; 3]> {
    let corner = |i: u32| positions.get(i as usize).copied();
    Some([corner(face[0])?, corner(face[1])?, corner(face[2])?])
}

/// A cap or sheet seen along its mean normal (module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CapView {
    /// Up: the signed axis nearest the mean normal; the eye on the mean normal.
    pub view: View,
    /// `f`, the share of the area facing along the mean normal.
    pub facing: f64,
    /// The angle between the mean normal and the up axis.
    pub tilt_degrees: f64,
}

impl CapView {
    /// The view along the axis of a surface with a boundary that faces mostly one way; `None`
    /// for a closed surface, one without area, or one facing several ways (`f < 0.25`).
    pub fn of_surface(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Option<Self> {
        if !has_boundary(faces) {
            return None;
        }
        let (mut sum, mut area) = (Vector3::zeros(), 0.0);
        for [a, b, c] in faces.iter().filter_map(|face| corners(positions, face)) {
            let twice = (b - a).cross(&(c - a));
            if twice.iter().all(|x| x.is_finite()) {
                sum += 0.5 * twice;
                area += 0.5 * twice.norm();
            }
        }
        let facing = sum.norm() / area;
        if !(area > 0.0 && facing >= CAP_FACING) {
            return None;
        }
        let axis = sum / sum.norm();
        let up = (UpAxis::ALL.into_iter())
            .max_by(|p, q| axis.dot(&p.vector()).total_cmp(&axis.dot(&q.vector())))
            .expect("six axes");
        let [h1, h2, u] = up.frame();
        let elevation = axis.dot(&u).clamp(-1.0, 1.0).asin().to_degrees();
        let azimuth = axis.dot(&h2).atan2(axis.dot(&h1)).to_degrees();
        Some(Self {
            view: View::new(azimuth, elevation).with_up(up),
            facing,
            tilt_degrees: 90.0 - elevation,
        })
    }
}

impl std::fmt::Display for CapView {
    /// E.g. "a cap or sheet seen along its axis from outside (facing 0.71, axis 17° from -z)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "a cap or sheet seen along its axis from outside (facing {:.2}, axis {:.0}° from {})",
            self.facing, self.tilt_degrees, self.view.up
        )
    }
}

/// Whether some edge of `faces` belongs to one face only.
fn has_boundary(faces: &[[u32; 3]]) -> bool {
    let mut edges: Vec<(u32, u32)> = (faces.iter())
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    let mut runs = edges.chunk_by(|p, q| p == q);
    runs.any(|run| run.len() == 1)
}

/// Why a view has the up axis it has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UpReason {
    /// The input format's convention (glTF is y up).
    Convention { format: &'static str },
    /// Frame 0's shape (the file does not say).
    Shape(ShapeUp),
    /// Frame 0 is a cap or sheet, seen along its axis.
    Cap(CapView),
    /// Neither a convention nor a surface with area: the old default, z.
    NoShape,
}

/// The axis that is up by the input format's convention, and the format: +y for glTF (its
/// specification says so); `None` for OBJ, PLY and NPY, which do not say (see the module
/// documentation for what the data then suggests).
pub fn up_convention(source: &SequenceSource) -> Option<(UpAxis, &'static str)> {
    match source {
        SequenceSource::Frames {
            format: FrameFormat::Gltf,
            ..
        }
        | SequenceSource::GltfAnimation(_) => Some((UpAxis::Y, FrameFormat::Gltf.name())),
        SequenceSource::Frames { .. } | SequenceSource::Npy(_) | SequenceSource::Arrays => None,
    }
}

/// The up axis a sequence gets when `--up` is not given, and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpChoice {
    pub axis: UpAxis,
    pub reason: UpReason,
}

impl UpChoice {
    /// The axis that `format` prescribes.
    pub fn by_convention(axis: UpAxis, format: &'static str) -> Self {
        let reason = UpReason::Convention { format };
        Self { axis, reason }
    }

    /// The view of a cap or sheet ([`CapView::of_surface`]), else the axis the surface's shape
    /// suggests ([`ShapeUp::of_surface`]), z without area.
    pub fn from_shape(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Self {
        if let Some(cap) = CapView::of_surface(positions, faces) {
            return Self {
                axis: cap.view.up,
                reason: UpReason::Cap(cap),
            };
        }
        match ShapeUp::of_surface(positions, faces) {
            Some(shape) => Self {
                axis: shape.axis,
                reason: UpReason::Shape(shape),
            },
            None => Self::without_shape(),
        }
    }

    /// The up axis of a loaded sequence's pictures when `--up` is not given: its format's
    /// convention ([`up_convention`]), else what frame 0's shape suggests, z for an intrinsic
    /// sequence.
    pub fn of_sequence(loaded: &LoadedSequence) -> Self {
        if let Some((axis, format)) = up_convention(&loaded.source) {
            return Self::by_convention(axis, format);
        }
        let sequence = &loaded.sequence;
        match sequence.positions(0) {
            Some(positions) => Self::from_shape(positions, sequence.mesh().faces()),
            None => Self::without_shape(),
        }
    }

    /// The default view of pictures: along a cap's axis ([`CapView`]), else the default angles
    /// about the chosen axis.
    pub fn view(&self) -> View {
        match self.reason {
            UpReason::Cap(cap) => cap.view,
            _ => View::default().with_up(self.axis),
        }
    }

    /// z, for a sequence without positions to go by.
    pub fn without_shape() -> Self {
        let reason = UpReason::NoShape;
        Self {
            axis: UpAxis::Z,
            reason,
        }
    }

    /// The other usual choice, to suggest: z for y, y for anything else.
    pub fn alternative(&self) -> UpAxis {
        match self.axis {
            UpAxis::Y => UpAxis::Z,
            _ => UpAxis::Y,
        }
    }
}

impl std::fmt::Display for UpReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Convention { format } => write!(f, "the {format} convention"),
            Self::Shape(shape) => write!(f, "chosen from the data: {shape}"),
            Self::Cap(cap) => write!(f, "chosen from the data: {cap}"),
            Self::NoShape => write!(f, "no surface to go by"),
        }
    }
}
