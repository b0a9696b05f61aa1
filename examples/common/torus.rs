//! The benchmarks' test sequence: `synth::paper_torus` with grey values in [0, 1].

use meshflow::flow::MeshSequence;
use meshflow::synth::paper_torus;

/// The paper's torus `n1 × n2 × frames`, grey values divided by their maximum, `fps` frames
/// per time unit.
pub fn unit_grey_torus(
    n1: usize,
    n2: usize,
    frames: usize,
    fps: f64,
) -> Result<MeshSequence, meshflow::Error> {
    let sequence = paper_torus(n1, n2, frames)?;
    let max = (0..frames)
        .flat_map(|k| sequence.intensities(k).iter().copied())
        .fold(0.0, f64::max);
    let positions = (0..frames)
        .map(|k| sequence.positions(k).expect("embedded").to_vec())
        .collect();
    let intensities = (0..frames)
        .map(|k| sequence.intensities(k).iter().map(|v| v / max).collect())
        .collect();
    let times = (0..frames).map(|k| k as f64 / fps).collect();
    Ok(MeshSequence::new(
        sequence.mesh().clone(),
        positions,
        intensities,
        Some(times),
    )?)
}
