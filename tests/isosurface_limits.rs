//! Finding a surface checks the memory it will hold against the process's limit before the
//! work. Alone in its test binary: it lowers the process-wide limit.

use meshflow::surface::{find_surface, IsosurfaceOptions};
use meshflow::volume::Volume;
use nalgebra::Vector3;

#[test]
fn a_volume_over_the_memory_limit_is_refused_before_the_work() {
    let values = vec![0.0f32; 40 * 40 * 40];
    let volume = Volume::new([40; 3], values, Vector3::repeat(1.0), Vector3::zeros()).unwrap();
    let limit = meshflow::limits::memory_limit();
    meshflow::limits::set_memory_limit(1 << 20);
    let error = find_surface(&volume, &IsosurfaceOptions::default());
    meshflow::limits::set_memory_limit(limit);
    let error = error.unwrap_err().to_string();
    assert!(
        error.contains("finding the surface in [40, 40, 40] voxels"),
        "{error}"
    );
}
