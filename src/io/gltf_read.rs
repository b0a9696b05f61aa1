//! (in progress: replaced by the glTF reader)
use super::{FrameMesh, IoError, RawSequence};
use std::path::Path;
pub fn read_gltf_animation(path: &Path, _fps: Option<f64>) -> Result<RawSequence, IoError> {
    Err(IoError::format(path, "glTF not yet supported"))
}
pub fn read_gltf_frame(path: &Path) -> Result<FrameMesh, IoError> {
    Err(IoError::format(path, "glTF not yet supported"))
}
