//! Things a loader noticed and worked around without failing: the caller decides how to show
//! them (the CLI prints each as one `meshflow: warning: …` line).

use super::gltf_read::{clip_list, AnimationClip};
use std::path::PathBuf;

/// A remark about an input that was read successfully but not exactly as written.
///
/// Every variant names the file it is about; `Display` gives one line for a user.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LoadWarning {
    /// File vertices that are shared by no face were left out of the mesh.
    #[error("{}: dropped {count} vertices that no face uses (e.g. file vertex {first}); outputs keep the file's numbering", file.display())]
    UnusedVertices {
        file: PathBuf,
        count: usize,
        first: usize,
    },
    /// A glTF file holds several animations and none was chosen: `chosen`, the first that
    /// moves the mesh, was read.
    #[error("{}: {} animations ({}); read {chosen}, the first that moves the mesh; choose one with --animation NAME|INDEX", file.display(), clips.len(), clip_list(clips))]
    SeveralAnimations {
        file: PathBuf,
        clips: Vec<AnimationClip>,
        chosen: AnimationClip,
    },
    /// The grey values of every frame equal those of frame 0 (to [`STATIC_IMAGE_TOLERANCE`]
    /// of their range) while the surface moves: the image moves with the surface (a texture
    /// fixed to the mesh, say), so the flow along the surface is zero.
    #[error("{}: the grey values are the same in all {frames} frames while the surface moves: the image moves with the surface (e.g. a texture fixed to the mesh), so the flow is zero", file.display())]
    StaticImage { file: PathBuf, frames: usize },
}

/// Grey values closer than this fraction of their range count as equal for
/// [`LoadWarning::StaticImage`]: round-off, and far below any change that carries a flow.
pub const STATIC_IMAGE_TOLERANCE: f64 = 1e-6;
