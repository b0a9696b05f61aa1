//! The flow over MPI ranks, each holding one time window (`--features mpi`), and the
//! benchmark of the MPI solve:
//!
//! ```sh
//! cargo build --release --features mpi --example mpi_solve
//! mpirun -n 4 target/release/examples/mpi_solve [INPUT | --torus N1 N2 FRAMES] [--check]
//! ```
//!
//! INPUT is anything `meshflow solve` reads (default: a deforming icosphere of 642 vertices,
//! 9 frames, solved with `pcg-slab-gauss-seidel`); `--torus` is the paper's torus
//! (`synth::paper_torus`, `FlowParams::paper(1, 0, 1)`, solver `auto`), e.g. `--torus 255 190
//! 200` for 200 frames × 48,450 vertices. Rank `r` of `R` owns the slabs
//! `[r S / R, (r + 1) S / R)` and computes its share with `flow::window::flow_over_ranks`
//! (windows, scales summed over ranks, CG with the odd–even sweeps or multigrid in time across
//! ranks). Rank 0 prints iterations, seconds and every rank's peak memory; `--check` also
//! solves in one process (rank 0) and prints the largest difference.
//!
//! Every rank builds (`--torus`) or reads (INPUT, `meshflow::load::load_frames`) its window's
//! frames only; the default sphere is built whole on every rank, which keeps its window's. A rank that
//! fails prints one line with its rank and ends the job (MPI_Abort); a panic does the same
//! through a panic hook, so no rank is left waiting. `meshflow solve` under `mpirun` does the
//! same with every option of the CLI.

use meshflow::flow::distributed::{abort_job_on_panic, gather_to_first, MpiRanks, TimeRanks};
use meshflow::flow::window::{flow_over_ranks, TimeWindow};
use meshflow::flow::{FlowParams, FlowProblem, FlowResult, MeshSequence, SolverChoice};
use meshflow::load::{count_frames, load_frames, load_sequence};
use meshflow::synth::paper_torus_frames;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::error::Error;
use std::ops::Range;
use std::path::PathBuf;
use std::time::Instant;

#[path = "common/memory.rs"]
mod memory;
use memory::peak_memory_bytes;

fn main() {
    let universe = mpi::initialize().expect("MPI initializes once");
    let world = universe.world();
    abort_job_on_panic();
    if let Err(error) = run(&world) {
        eprintln!("meshflow (rank {}): {error}", world.rank());
        world.abort(1);
    }
}

/// The problem the command line asks for.
enum Problem {
    /// The paper's torus `n1 × n2`, `frames` frames: each rank builds its window's frames only.
    Torus { n1: usize, n2: usize, frames: usize },
    /// A sequence on disk: each rank reads its window's frames only.
    File(PathBuf),
    /// A deforming sphere, built whole on every rank.
    Sphere(Box<MeshSequence>),
}

impl Problem {
    fn n_slabs(&self) -> Result<usize, Box<dyn Error>> {
        Ok(match self {
            Problem::Torus { frames, .. } => frames - 1,
            Problem::File(path) => count_frames(path, &Default::default())?.saturating_sub(1),
            Problem::Sphere(sequence) => sequence.n_slabs(),
        })
    }

    /// Frames `frames` of the sequence (readers of a file weld alike through `ranks`).
    fn frames(
        &self,
        frames: Range<usize>,
        ranks: &dyn TimeRanks,
    ) -> Result<MeshSequence, Box<dyn Error>> {
        Ok(match self {
            &Problem::Torus { n1, n2, frames: n } => paper_torus_frames(n1, n2, n, frames)?,
            Problem::File(path) => {
                let sum = |v: &mut [f64]| ranks.sum(v);
                load_frames(path, &Default::default(), Some(frames), &sum)?.sequence
            }
            Problem::Sphere(sequence) => sequence.frames(frames)?,
        })
    }

    /// The whole sequence, in this process alone.
    fn whole(&self) -> Result<MeshSequence, Box<dyn Error>> {
        Ok(match self {
            &Problem::Torus { n1, n2, frames } => paper_torus_frames(n1, n2, frames, 0..frames)?,
            Problem::File(path) => load_sequence(path, &Default::default())?.sequence,
            Problem::Sphere(sequence) => (**sequence).clone(),
        })
    }
}

/// The sequence and parameters the command line asks for.
fn problem(args: &[String]) -> Result<(Problem, FlowParams), Box<dyn Error>> {
    if let Some(k) = args.iter().position(|a| a == "--torus") {
        let size = |i: usize| -> Result<usize, Box<dyn Error>> {
            let text = args.get(k + i).ok_or("--torus N1 N2 FRAMES")?;
            Ok(text.parse()?)
        };
        let torus = Problem::Torus {
            n1: size(1)?,
            n2: size(2)?,
            frames: size(3)?,
        };
        return Ok((torus, FlowParams::paper(1.0, 0.0, 1.0)));
    }
    let params = FlowParams {
        solver: SolverChoice::PcgSlabGaussSeidel,
        tolerance: 1e-10,
        ..FlowParams::default()
    };
    let problem = match args.iter().find(|a| !a.starts_with("--")) {
        Some(path) => Problem::File(PathBuf::from(path)),
        None => Problem::Sphere(Box::new(
            meshflow::synth::deforming_sphere(3, 9, 1.0, 0.05, 0.3)?.sequence,
        )),
    };
    Ok((problem, params))
}

fn run(world: &SimpleCommunicator) -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let check = args.iter().any(|a| a == "--check");
    let (problem, params) = problem(&args)?;
    let ranks = MpiRanks {
        communicator: world,
    };
    let n_slabs = problem.n_slabs()?;
    if ranks.size() > n_slabs {
        return Err(format!("{} ranks for {n_slabs} slabs", ranks.size()).into());
    }
    let window = TimeWindow::of_rank(ranks.rank(), ranks.size(), n_slabs);
    let frames = problem.frames(window.frames(), &ranks)?;
    let start = Instant::now();
    let result = flow_over_ranks(&frames, &window, &ranks, &params, &|_| {})?;
    let seconds = start.elapsed().as_secs_f64();
    let peaks = gather_to_first(&ranks, &[peak_memory_bytes() as f64 / 1e9]);
    if let (Some(result), Some(peaks)) = (result, peaks) {
        let peaks: Vec<f64> = peaks.concat();
        println!(
            "{} ranks, {n_slabs} slabs x {} vertices: {} iterations ({}, {} time levels), \
             residual {:.2e}, {seconds:.2} s (assembly {:.2}, factorization {:.2}), \
             peak memory per rank (GB) {peaks:.3?}",
            ranks.size(),
            frames.mesh().n_vertices(),
            result.iterations,
            result.method,
            result.time_levels,
            result.relative_residual,
            result.timings.assembly,
            result.timings.factorization,
        );
        if check {
            compare(&problem.whole()?, &params, &result)?;
        }
    }
    Ok(())
}

/// The single process's solve and the largest difference, relative to the largest value.
fn compare(
    sequence: &MeshSequence,
    params: &FlowParams,
    result: &FlowResult,
) -> Result<(), Box<dyn Error>> {
    let single = FlowProblem::new(sequence, params)?.solve(&|_| {})?;
    let flat = |r: &FlowResult| -> Vec<f64> {
        (r.intrinsic.iter().flatten())
            .flat_map(|v| [v.x, v.y])
            .collect()
    };
    let (expected, got) = (flat(&single), flat(result));
    let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let difference =
        (got.iter().zip(&expected)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
    println!(
        "one process: {} iterations; largest difference {difference:.1e}",
        single.iterations
    );
    Ok(())
}
