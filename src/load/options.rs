//! How a sequence is loaded: the options every loader takes.

use super::Channels;
use crate::format::gltf::AnimationOptions;
use std::path::PathBuf;

/// Choices for [`super::load_sequence`] (and [`super::load_mesh`]); `Default` is "everything from the
/// files, welded at the default tolerance, not repaired". A solve's output records them
/// (`meshflow_run.json`), so that later commands load its input the same way.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct LoadOptions {
    /// The image from this float32, float64, uint8 or uint16 `.npy` of shape (frames, file vertices), or
    /// (frames, file vertices, channels).
    pub intensity: Option<PathBuf>,
    /// Which channels of the image to use (`--channels`): all of them by default.
    pub channels: Channels,
    /// The PLY vertex property holding the grey value (instead of the colours).
    pub intensity_attribute: Option<String>,
    /// Frame times, overriding any in the files.
    pub times: Option<Vec<f64>>,
    /// Resample a glTF animation at this many frames per unit of time.
    pub fps: Option<f64>,
    /// Weld seam copies: vertices that coincide in every frame and end coincident edges, never
    /// where the surface only touches itself (`docs/io.md`).
    pub weld: bool,
    /// The animation of a glTF file to read, by name, else by index (`"2"`); `None`: the first
    /// that moves the mesh (its morph weights, skin joints or node transforms).
    pub animation: Option<String>,
    /// How close coincident vertices are, relative to the bounding-box diagonal of frame 0
    /// (0: bitwise equal).
    pub weld_tolerance: f64,
    /// Repair non-manifold edges and vertices, faces with a repeated vertex and duplicate faces
    /// (see [`crate::mesh::repair`]) instead of refusing them.
    pub repair: bool,
}

impl LoadOptions {
    /// The default [`LoadOptions::weld_tolerance`].
    pub const DEFAULT_WELD_TOLERANCE: f64 = 1e-9;

    /// What the glTF reader takes of these options: the animation and `fps`.
    pub fn animation_options(&self) -> AnimationOptions {
        AnimationOptions {
            animation: self.animation.clone(),
            fps: self.fps,
        }
    }
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            intensity: None,
            channels: Channels::Auto,
            intensity_attribute: None,
            times: None,
            fps: None,
            weld: true,
            animation: None,
            weld_tolerance: Self::DEFAULT_WELD_TOLERANCE,
            repair: false,
        }
    }
}
