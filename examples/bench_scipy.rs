//! meshflow against a SciPy pipeline, measured in the same run: the paper's Experiment I at
//! full size (255×190 torus, 20 frames, 1.84 M unknowns, α = γ = 1, β = 0, grey values in
//! [0, 1]), OBJ frames in and all outputs written, end to end.
//!
//! - meshflow: `meshflow solve FRAMES --intensity intensity.npy …` (the release binary:
//!   NPY, VTU and glTF outputs).
//! - SciPy: `examples/scipy/flow_pipeline.py`, an independent NumPy/SciPy implementation of
//!   `docs/discretization.md` (vectorized assembly, per-slab SuperLU factors, SciPy's CG),
//!   which also checks meshflow's numbers: the two flows must agree to the solvers' tolerance.
//!
//! `cargo build --release && cargo run --release --example bench_scipy [-- N1 N2 FRAMES]
//! [--work DIR]` (needs `python3` with NumPy and SciPy; `--work` keeps the frames and both
//! outputs in `DIR` instead of a temporary directory).

use meshflow::format::{read_npy_float, write_npy, write_obj};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[path = "common/torus.rs"]
mod torus;
use torus::unit_grey_torus;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn main() -> Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let kept = match args.iter().position(|a| a == "--work") {
        Some(i) => Some(PathBuf::from(
            args.drain(i..i + 2).nth(1).ok_or("--work DIR")?,
        )),
        None => None,
    };
    let sizes: Vec<usize> = args
        .iter()
        .map(|a| a.parse())
        .collect::<std::result::Result<_, _>>()?;
    let [n1, n2, frames] = [0, 1, 2].map(|i| sizes.get(i).copied().unwrap_or([255, 190, 20][i]));
    let meshflow = meshflow_binary()?;
    let pipeline = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scipy/flow_pipeline.py");
    let temporary = tempfile::tempdir()?;
    let work = kept.as_deref().unwrap_or(temporary.path());
    let input = work.join("frames");
    write_frames(&input, n1, n2, frames)?;
    println!(
        "paper torus {n1}×{n2}, {frames} frames as OBJ + intensity.npy, α = γ = 1, β = 0, \
         tolerance 1e-8"
    );

    let weights = ["--alpha", "1", "--beta", "0", "--gamma", "1"];
    let ours = work.join("meshflow");
    let meshflow_seconds = timed(
        Command::new(&meshflow)
            .arg("solve")
            .arg(&input)
            .arg("--intensity")
            .arg(input.join("intensity.npy"))
            .args(weights)
            .arg("--out")
            .arg(&ours),
    )?;
    let theirs = work.join("scipy");
    let scipy_seconds = timed(
        Command::new("python3")
            .arg(&pipeline)
            .arg(&input)
            .arg("--intensity")
            .arg(input.join("intensity.npy"))
            .args(weights)
            .arg("--out")
            .arg(&theirs),
    )?;

    println!("meshflow solve (npy, vtu, glb)  {meshflow_seconds:8.2} s");
    println!("SciPy pipeline (npy)            {scipy_seconds:8.2} s");
    println!(
        "ratio                           {:8.3}",
        meshflow_seconds / scipy_seconds
    );
    let difference = relative_difference(
        &ours.join("flow_intrinsic.npy"),
        &theirs.join("flow_intrinsic.npy"),
    )?;
    println!("flows differ by {difference:.1e} (max abs difference / max |u|)");
    Ok(())
}

/// The release `meshflow` binary beside this example's directory.
fn meshflow_binary() -> Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let binary = exe
        .parent()
        .and_then(Path::parent)
        .map(|dir| dir.join("meshflow"))
        .filter(|b| b.exists());
    binary
        .ok_or_else(|| "no meshflow binary beside the examples: run `cargo build --release`".into())
}

/// `frame_KKKK.obj` and `intensity.npy` (frames × vertices) in `dir`.
fn write_frames(dir: &Path, n1: usize, n2: usize, frames: usize) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    let sequence = unit_grey_torus(n1, n2, frames, 1.0)?;
    let faces = sequence.mesh().faces();
    for k in 0..frames {
        let positions = sequence.positions(k).expect("embedded");
        write_obj(
            &dir.join(format!("frame_{k:04}.obj")),
            positions,
            faces,
            None,
        )?;
    }
    let grey: Vec<f64> = (0..frames)
        .flat_map(|k| sequence.intensities(k).to_vec())
        .collect();
    let shape = [frames as u64, sequence.mesh().n_vertices() as u64];
    write_npy(&dir.join("intensity.npy"), &shape, &grey)?;
    Ok(())
}

/// Wall-clock seconds of a command that must succeed (its output is passed through).
fn timed(command: &mut Command) -> Result<f64> {
    let start = Instant::now();
    let status = command.status()?;
    let seconds = start.elapsed().as_secs_f64();
    match status.success() {
        true => Ok(seconds),
        false => Err(format!("{command:?} failed: {status}").into()),
    }
}

/// `max |a − b| / max |b|` of two `.npy` arrays of the same shape.
fn relative_difference(a: &Path, b: &Path) -> Result<f64> {
    let (a, b) = (read_npy_float(a)?, read_npy_float(b)?);
    if a.shape != b.shape {
        return Err(format!("shapes differ: {:?} and {:?}", a.shape, b.shape).into());
    }
    let max = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0, f64::max);
    let difference = max(&mut a.data.iter().zip(&b.data).map(|(x, y)| (x - y).abs()));
    Ok(difference / max(&mut b.data.iter().map(|y| y.abs())))
}
