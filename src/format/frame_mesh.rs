//! What every reader produces: one frame's triangle mesh with optional grey values or colours
//! ([`VertexValues`]), and a whole sequence read from a single file.

use super::gltf::ImplicitClip;
use crate::statistics::channel_mean;
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
    /// The animation read when the file holds several and none was named: the loader turns it
    /// into a warning.
    pub implicit_clip: Option<ImplicitClip>,
}

/// One frame's image as a reader (or caller) gives it, one entry per file vertex.
#[derive(Clone, Debug, PartialEq)]
pub enum VertexValues {
    /// A grey value per vertex.
    Grey(Vec<f64>),
    /// An RGB colour per vertex.
    Colors(Vec<[f64; 3]>),
    /// `C` channels: `values[c][i]`.
    Channels(Vec<Vec<f64>>),
}

impl VertexValues {
    /// The number of values of a channel that does not have `n` (one per vertex), if any: the
    /// channels of a [`VertexValues::Channels`] may differ in length when a caller builds them.
    pub fn wrong_length(&self, n: usize) -> Option<usize> {
        let lengths: Vec<usize> = match self {
            VertexValues::Grey(v) => vec![v.len()],
            VertexValues::Colors(v) => vec![v.len()],
            VertexValues::Channels(c) => c.iter().map(Vec::len).collect(),
        };
        lengths.into_iter().find(|&length| length != n)
    }

    /// One grey value per vertex: itself, the luma of a colour, the mean of several channels
    /// (what tracking and pictures use).
    pub fn to_grey(&self) -> Vec<f64> {
        match self {
            VertexValues::Grey(v) => v.clone(),
            VertexValues::Colors(v) => v.iter().map(|&c| grey_value(c)).collect(),
            VertexValues::Channels(c) => channel_mean(c),
        }
    }

    /// Row-major values of the vertices: one grey value each (`channels` = `None`), or
    /// `channels` values each (an `(V, C)` array row by row).
    pub fn from_rows(values: Vec<f64>, channels: Option<usize>) -> Self {
        match channels {
            None => VertexValues::Grey(values),
            Some(c) => VertexValues::Channels(
                (0..c)
                    .map(|j| values.iter().skip(j).step_by(c).copied().collect())
                    .collect(),
            ),
        }
    }

    /// The values as channels `[c][i]`.
    pub(crate) fn into_channels(self) -> Vec<Vec<f64>> {
        match self {
            VertexValues::Grey(v) => vec![v],
            VertexValues::Colors(v) => (0..3).map(|c| v.iter().map(|x| x[c]).collect()).collect(),
            VertexValues::Channels(c) => c,
        }
    }

    /// 1 for grey values, 3 for colours, `C` for channels.
    pub(crate) fn n_channels(&self) -> usize {
        match self {
            VertexValues::Grey(_) => 1,
            VertexValues::Colors(_) => 3,
            VertexValues::Channels(c) => c.len(),
        }
    }
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
