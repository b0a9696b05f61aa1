//! Writes the space-time system `A u = b` of `bench_solver`'s torus for experiments outside
//! meshflow (`examples/scipy/time_multigrid.py` prototypes coarsenings in time on it):
//! `A.mtx` (MatrixMarket, both triangles, slab-major unknowns), `b.npy` and
//! `slab_dimension.txt` (`2V`, unknowns per slab) in `OUT_DIR`.
//!
//! `cargo run --release --example space_time_system -- N1 N2 FRAMES ALPHA GAMMA OUT_DIR`
//! (the `N1 × N2` periodic torus grid, grey values in [0, 1], one frame per second, `β = 0`),
//! or `-- --read SEQUENCE INTENSITY.npy ALPHA GAMMA OUT_DIR` for a sequence read from files
//! (e.g. the paper-size frames of `bench_scipy`).

use meshflow::flow::MeshSequence;
use meshflow::flow::{FlowParams, FlowProblem};
use meshflow::format::{write_matrix_market, write_npy};
use meshflow::load::{load_sequence, LoadOptions};
use std::path::PathBuf;

#[path = "common/torus.rs"]
mod torus;

const USAGE: &str = "usage: space_time_system (N1 N2 FRAMES | --read SEQUENCE INTENSITY.npy) \
                     ALPHA GAMMA OUT_DIR";

fn rest_arguments(rest: &[String]) -> Result<[&String; 3], Box<dyn std::error::Error>> {
    match rest {
        [alpha, gamma, out] => Ok([alpha, gamma, out]),
        _ => Err(USAGE.into()),
    }
}

fn read_sequence(path: &str, intensity: &str) -> Result<MeshSequence, Box<dyn std::error::Error>> {
    let options = LoadOptions {
        intensity: Some(intensity.into()),
        ..LoadOptions::default()
    };
    Ok(load_sequence(path.as_ref(), &options)?.sequence)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (sequence, [alpha, gamma, out]) = match args.as_slice() {
        [read, path, intensity, rest @ ..] if read == "--read" => {
            (read_sequence(path, intensity)?, rest_arguments(rest)?)
        }
        [n1, n2, frames, rest @ ..] => (
            torus::unit_grey_torus(n1.parse()?, n2.parse()?, frames.parse()?, 1.0)?,
            rest_arguments(rest)?,
        ),
        _ => return Err(USAGE.into()),
    };
    let params = FlowParams::paper(alpha.parse()?, 0.0, gamma.parse()?);
    let problem = FlowProblem::new(&sequence, &params)?;
    let system = problem.system();
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out)?;
    write_matrix_market(&out.join("A.mtx"), &system.to_sparse())?;
    write_npy(
        &out.join("b.npy"),
        &[system.dimension() as u64],
        system.rhs(),
    )?;
    std::fs::write(
        out.join("slab_dimension.txt"),
        system.slab_dimension().to_string(),
    )?;
    println!(
        "{}: {} slabs × {} unknowns",
        out.display(),
        system.n_slabs(),
        system.slab_dimension()
    );
    Ok(())
}
