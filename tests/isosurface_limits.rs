//! Reading and finding surfaces in volumes against the process's memory limit. The tests lower
//! the process-wide limit, so they are alone in this binary and take turns ([`LIMIT`]).

use meshflow::surface::{find_surface, IsosurfaceOptions};
use meshflow::volume::Volume;
use nalgebra::Vector3;

/// Held while a test changes the memory limit.
static LIMIT: std::sync::Mutex<()> = std::sync::Mutex::new(());

#[test]
fn a_volume_over_the_memory_limit_is_refused_before_the_work() {
    let _turn = LIMIT.lock().unwrap_or_else(|e| e.into_inner());
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

/// A recording longer than memory streams: `read_volumes` refuses to hold all of a
/// (4, 40, 40, 40) float64 stack under a limit that one frame fits, while `VolumeStream`
/// reads it frame by frame, each frame equal to what `read_volumes` reads without the limit.
#[test]
fn a_recording_longer_than_memory_streams_frame_by_frame() {
    use meshflow::volume::{read_volumes, VolumeOptions, VolumeStream};
    let _turn = LIMIT.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("stack.npy");
    let values: Vec<f64> = (0..4 * 64_000).map(|i| (i % 997) as f64 * 0.5).collect();
    meshflow::format::write_npy(&file, &[4, 40, 40, 40], &values).unwrap();
    let options = VolumeOptions::default();
    let whole = read_volumes(&file, &options).unwrap();
    let limit = meshflow::limits::memory_limit();
    meshflow::limits::set_memory_limit(1_500_000);
    let refused = read_volumes(&file, &options)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    let streamed: Result<Vec<_>, _> = VolumeStream::open(&file, &options).unwrap().collect();
    meshflow::limits::set_memory_limit(limit);
    assert!(
        refused.contains("4 volume frames of 40 × 40 × 40 voxels"),
        "{refused}"
    );
    let streamed = streamed.unwrap();
    assert_eq!(streamed.len(), 4);
    for ((volume, from), expected) in streamed.iter().zip(&whole.volumes) {
        assert_eq!(volume, expected);
        assert_eq!(from, &file);
    }
}
