//! The Rust side of the Python package's overhead benchmark (`python/benchmarks/overhead.py`
//! runs this, then times the same solve from Python).
//!
//! `cargo run --release --example bench_python -- DIR [RUNS]` writes the level-5 rotating
//! sphere (10,242 vertices, 6 frames, 0.05 rad per frame) as an NPY sequence into DIR, then
//! times what `meshflow.compute_flow` does, from arrays in memory: the sequence built by
//! `io::sequence_from_arrays` (welding, validation) and the solve with the default weights.
//! Prints one JSON line: the median and all run times in seconds.

use meshflow::flow::{compute_flow, FlowParams};
use meshflow::format::{write_npy_sequence, VertexValues};
use meshflow::load::{sequence_from_arrays, LoadOptions};
use meshflow::synth::rotating_sphere;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), meshflow::Error> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().unwrap_or_else(|| "out/bench_python".into()));
    let runs: usize = args
        .next()
        .map_or(5, |r| r.parse().expect("RUNS is a count"));
    let scene = rotating_sphere(5, 6, 1.0, 0.05)?;
    let sequence = &scene.sequence;
    let frames = 0..sequence.n_frames();
    let positions: Vec<_> = frames
        .clone()
        .map(|k| sequence.positions(k).expect("embedded").to_vec())
        .collect();
    let grey: Vec<_> = frames.map(|k| sequence.intensities(k).to_vec()).collect();
    let faces = sequence.mesh().faces().to_vec();
    std::fs::create_dir_all(&dir).map_err(|e| meshflow::format::IoError::file(&dir, e))?;
    write_npy_sequence(&dir, &positions, &faces, Some(&grey), sequence.times())?;
    let mut seconds: Vec<f64> = (0..runs)
        .map(|_| -> Result<f64, meshflow::Error> {
            let (faces, positions, grey) = (faces.clone(), positions.clone(), grey.clone());
            let start = Instant::now();
            let times = Some(sequence.times().to_vec());
            let grey = grey.into_iter().map(VertexValues::Grey).collect();
            let loaded =
                sequence_from_arrays(faces, positions, grey, times, &LoadOptions::default())?;
            let result = compute_flow(&loaded.sequence, &FlowParams::default())?;
            std::hint::black_box(result);
            Ok(start.elapsed().as_secs_f64())
        })
        .collect::<Result<_, _>>()?;
    let all = seconds.clone();
    seconds.sort_by(f64::total_cmp);
    println!(
        "{{\"median\": {}, \"runs\": {all:?}, \"vertices\": {}, \"frames\": {}}}",
        seconds[runs / 2],
        sequence.mesh().n_vertices(),
        sequence.n_frames()
    );
    Ok(())
}
