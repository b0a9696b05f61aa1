//! `mpirun -n R meshflow solve …` (the `mpi` feature): each rank reads and solves one time
//! window of the sequence (`meshflow::flow::window`); rank 0 reports progress and writes the
//! outputs, exactly those of one process, the other ranks streaming their slabs to it
//! (`meshflow::run::write_flow_over_ranks`; for `flow.glb`, pictures and ground-truth scores
//! rank 0 reads all frames and gathers the whole flow instead). Any rank that fails prints its error in
//! one line naming the rank and ends the whole job (`MPI_Abort`), so no rank is left waiting;
//! a panic does the same through a panic hook.

use crate::{solve, SolveArgs};
use meshflow::flow::distributed::{abort_job_on_panic, MpiRanks};
use meshflow::Error;
use mpi::traits::*;

/// `meshflow solve`, over the ranks `mpirun` started (one process without `mpirun`). A lone
/// process does not start MPI: Open MPI's singleton start spawns its daemon, 0.5 s of a
/// 9 s paper-size solve on 2 cores.
pub fn solve(args: &SolveArgs) -> Result<(), Error> {
    if !launched_as_one_of_several() {
        return solve::solve(args, None);
    }
    let Some(universe) = mpi::initialize() else {
        return solve::solve(args, None);
    };
    let world = universe.world();
    if world.size() == 1 {
        return solve::solve(args, None);
    }
    abort_job_on_panic();
    let ranks = MpiRanks {
        communicator: &world,
    };
    let result = match world.rank() {
        0 => solve::solve(args, Some(&ranks)),
        _ => solve::solve_on_rank(args, &ranks),
    };
    if let Err(error) = result {
        stderr_line!("meshflow (rank {}): error: {error}", world.rank());
        world.abort(1);
    }
    Ok(())
}

/// Whether this process is one of several that `mpirun` (Open MPI, MPICH) or `srun` started.
pub fn launched_as_one_of_several() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "SLURM_NTASKS"]
        .iter()
        .filter_map(|name| std::env::var(name).ok()?.parse::<usize>().ok())
        .any(|size| size > 1)
}
