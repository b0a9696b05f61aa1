//! (in progress)
use super::IoError;
use nalgebra::Vector3;
use std::path::Path;
pub struct AnimationFrame<'a> {
    pub time: f64,
    pub positions: &'a [Vector3<f64>],
    pub colors: &'a [[f64; 3]],
}
pub fn write_glb_animation(
    path: &Path,
    _faces: &[[u32; 3]],
    _frames: &[AnimationFrame],
) -> Result<(), IoError> {
    Err(IoError::format(path, "todo"))
}
