//! What every reader produces: one frame's triangle mesh with optional grey values, and
//! a whole sequence read from a single file.

use super::{LoadWarning, VertexValues};
use nalgebra::Vector3;
use std::path::PathBuf;

/// One frame as read from one file, before any validation: vertex positions, triangles
/// (0-based, counter-clockwise seen from outside) and a grey value or colour per vertex if the
/// file carries one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameMesh {
    pub positions: Vec<Vector3<f64>>,
    pub faces: Vec<[u32; 3]>,
    pub image: Option<VertexValues>,
}

/// A sequence read from one file (a glTF animation): one connectivity, positions and
/// optional grey values or colours per frame, and the frame times when the file defines them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawSequence {
    pub faces: Vec<[u32; 3]>,
    pub positions: Vec<Vec<Vector3<f64>>>,
    pub images: Option<Vec<VertexValues>>,
    pub times: Option<Vec<f64>>,
    /// The file each frame came from, for error messages.
    pub sources: Vec<PathBuf>,
    /// What the reader noticed and worked around.
    pub warnings: Vec<LoadWarning>,
}

/// The grey value of a colour: the value itself when `r = g = b` (so grey data passes through
/// exactly, unclamped), Rec. 709 luma `0.2126 r + 0.7152 g + 0.0722 b` otherwise. Colours are
/// taken as stored (no gamma decoding): brightness constancy only needs a consistent grey scale.
pub fn grey_value([r, g, b]: [f64; 3]) -> f64 {
    if r == g && g == b {
        r
    } else {
        0.2126 * r + 0.7152 * g + 0.0722 * b
    }
}

/// [`grey_value`] of each colour.
pub fn grey_values(colors: &[[f64; 3]]) -> Vec<f64> {
    colors.iter().map(|&c| grey_value(c)).collect()
}
