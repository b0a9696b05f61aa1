//! What can go wrong when drawing a picture: bad camera or view parameters, per-vertex arrays
//! that do not match the surface, faces that name missing vertices, unusable scales and ranges.
//! Rendering never panics on bad input; non-finite *values* are not errors (they render black
//! or are skipped), only inconsistent *shapes* and parameters are.

use crate::mesh::ConnectivityError;

/// Why a picture could not be drawn. Variants name the parameter, array or face at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error(
        "view {text:?}: {reason} (expected \"AZIMUTH,ELEVATION[,ROLL]\" in degrees, e.g. \"-60,30\")"
    )]
    View { text: String, reason: String },
    #[error("up axis {text:?} is not one of x, y, z, -x, -y, -z")]
    UpAxis { text: String },
    /// A slab list that does not parse or names a slab that does not exist.
    #[error("slab list {text:?}: {reason}")]
    Slabs { text: String, reason: String },
    #[error("camera: {reason}")]
    Camera { reason: String },
    #[error("expected {expected} {what} (one per vertex), got {got}")]
    CountMismatch {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error(transparent)]
    Faces(#[from] ConnectivityError),
    #[error("{name} = {value} is invalid: it must be {requirement}")]
    InvalidParameter {
        name: &'static str,
        value: f64,
        requirement: &'static str,
    },
    #[error("value range ({min}, {max}) is not a finite interval with min <= max")]
    Range { min: f64, max: f64 },
    #[error("image size: {reason}")]
    Size { reason: String },
    /// A chart's series without one value per x value.
    #[error("series {name:?} has {got} values but x has {expected}: one value per x is needed")]
    SeriesLength {
        name: String,
        expected: usize,
        got: usize,
    },
    #[error("an intrinsic sequence (edge lengths, no positions) cannot be drawn")]
    Intrinsic,
}

/// Checks that a per-vertex array has one entry per vertex.
pub(crate) fn check_count(
    what: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), RenderError> {
    if expected == got {
        Ok(())
    } else {
        Err(RenderError::CountMismatch {
            what,
            expected,
            got,
        })
    }
}

/// Checks that a parameter is a positive finite number.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<(), RenderError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(RenderError::InvalidParameter {
            name,
            value,
            requirement: "a positive finite number",
        })
    }
}
