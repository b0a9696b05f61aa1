//! The space-time solve over MPI ranks, each holding one time window (`--features mpi`):
//!
//! ```sh
//! cargo build --release --features mpi --example mpi_solve
//! mpirun -n 4 target/release/examples/mpi_solve [INPUT] [--check]
//! ```
//!
//! INPUT is anything `meshflow solve` reads (default: a deforming icosphere of 642 vertices,
//! 9 frames). Rank `r` of `R` owns the slabs `[r S / R, (r + 1) S / R)`, assembles and factors
//! only those, from frames `a − 1 … b + 1` (`flow::window`), the scales summed over ranks; the
//! ranks then solve together (`flow::distributed`: CG with the odd–even slab sweeps, sums by
//! all-reduce, one slab vector to each neighbour per exchange). Rank 0 gathers the flow and
//! prints iterations, residual, seconds and every rank's peak memory; `--check` also solves in
//! one process (rank 0) and prints the largest difference.
//!
//! Not yet: each rank still *reads* the whole input (windowed reading needs a frame range in
//! `io::LoadOptions`), and multigrid in time does not run across ranks (small `α` needs many
//! iterations). A rank that fails prints one line with its rank and ends the job (MPI_Abort);
//! a panic does the same through a panic hook, so no rank is left waiting.

use meshflow::flow::distributed::{solve_window, MpiRanks, TimeRanks};
use meshflow::flow::window::{TimeWindow, WindowSlabs};
use meshflow::flow::{FlowParams, FlowProblem, MeshSequence, ScaleSums, SolverChoice};
use mpi::datatype::PartitionMut;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::error::Error;
use std::path::Path;
use std::time::Instant;

#[path = "common/memory.rs"]
mod memory;
use memory::peak_memory_bytes;

fn main() {
    let universe = mpi::initialize().expect("MPI initializes once");
    let world = universe.world();
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        hook(info);
        SimpleCommunicator::world().abort(101);
    }));
    if let Err(error) = run(&world) {
        eprintln!("meshflow (rank {}): {error}", world.rank());
        world.abort(1);
    }
}

fn run(world: &SimpleCommunicator) -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let check = args.iter().any(|a| a == "--check");
    let sequence = match args.iter().find(|a| !a.starts_with("--")) {
        Some(path) => meshflow::io::load_sequence(Path::new(path), &Default::default())?.sequence,
        None => meshflow::synth::deforming_sphere(3, 9, 1.0, 0.05, 0.3)?.sequence,
    };
    let params = FlowParams {
        solver: SolverChoice::PcgSlabGaussSeidel,
        tolerance: 1e-10,
        ..FlowParams::default()
    };
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let n_slabs = sequence.n_slabs();
    if size > n_slabs {
        return Err(format!("{size} ranks for {n_slabs} slabs: at most one rank per slab").into());
    }
    let window = TimeWindow::of_rank(rank, size, n_slabs);
    let start = Instant::now();
    let ranks = MpiRanks {
        communicator: world,
    };
    let frames = window.frames();
    let local = sequence.frames(frames.clone())?;
    let slabs = WindowSlabs::new(&local, frames.start, window, &params)?;
    let mut sums = slabs.scale_sums(&local).to_array();
    ranks.sum(&mut sums);
    let system = slabs.assemble(&local, &params, &ScaleSums::from_array(sums).scales())?;
    let solution = solve_window(&system, &ranks, &params, &|_| {})?;
    let seconds = start.elapsed().as_secs_f64();
    let flow = gather(world, &solution.u);
    let peaks = gather(world, &[peak_memory_bytes() as f64 / 1e9]);
    if rank == 0 {
        println!(
            "{size} ranks, {n_slabs} slabs: {} iterations, residual {:.2e}, {seconds:.2} s, \
             peak memory per rank (GB) {peaks:.3?}",
            solution.iterations, solution.relative_residual
        );
        if check {
            compare(&sequence, &params, &flow)?;
        }
    }
    Ok(())
}

/// Every rank's `values`, concatenated in rank order, on rank 0 (empty elsewhere).
fn gather(world: &SimpleCommunicator, values: &[f64]) -> Vec<f64> {
    let root = world.process_at_rank(0);
    let count = values.len() as Count;
    if world.rank() != 0 {
        root.gather_into(&count);
        root.gather_varcount_into(values);
        return Vec::new();
    }
    let mut counts = vec![0 as Count; world.size() as usize];
    root.gather_into_root(&count, &mut counts[..]);
    let offsets: Vec<Count> = (counts.iter())
        .scan(0, |sum, &c| {
            let offset = *sum;
            *sum += c;
            Some(offset)
        })
        .collect();
    let mut all = vec![0.0; counts.iter().sum::<Count>() as usize];
    let mut partition = PartitionMut::new(&mut all[..], &counts[..], &offsets[..]);
    root.gather_varcount_into_root(values, &mut partition);
    all
}

/// The single process's solve and the largest difference, relative to the largest value.
fn compare(
    sequence: &MeshSequence,
    params: &FlowParams,
    flow: &[f64],
) -> Result<(), Box<dyn Error>> {
    let single = FlowProblem::new(sequence, params)?.solve(&|_| {})?;
    let expected: Vec<f64> = (single.intrinsic.iter().flatten())
        .flat_map(|v| [v.x, v.y])
        .collect();
    let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let difference =
        (flow.iter().zip(&expected)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
    println!(
        "one process: {} iterations; largest difference {difference:.1e}",
        single.iterations
    );
    Ok(())
}
