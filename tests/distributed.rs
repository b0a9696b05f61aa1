//! The solve over time windows held by separate ranks (`meshflow::flow::distributed`), with
//! threads standing in for the ranks: for 1 to 4 ranks the solution equals the single
//! process's (`pcg-slab-gauss-seidel`, the same odd–even preconditioner) to 1e-10 and takes the
//! same number of iterations, with lumped and consistent coupling and Dirichlet boundaries.
//! Each rank assembles only its window, from its frames, with the scales summed over ranks.

use meshflow::flow::distributed::{solve_window, TimeRanks};
use meshflow::flow::window::{TimeWindow, WindowSlabs};
use meshflow::flow::{FlowParams, FlowProblem, MeshSequence, ScaleSums, SolverChoice};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Barrier, Mutex};

mod common;

/// What the threads share for sums: a barrier and one slot per rank.
struct Shared {
    barrier: Barrier,
    sums: Mutex<Vec<Vec<f64>>>,
}

/// A rank played by a thread: sums through `Shared`, messages through one channel per
/// ordered pair of ranks (unbounded: sends never block, unlike MPI's, so the tests of message
/// order are the `mpirun` ones in `tests/mpi.rs`).
struct ThreadRank {
    rank: usize,
    size: usize,
    shared: Arc<Shared>,
    to: Vec<Sender<Vec<f64>>>,
    from: Vec<Receiver<Vec<f64>>>,
}

/// `size` ranks wired to each other.
fn thread_ranks(size: usize) -> Vec<ThreadRank> {
    let shared = Arc::new(Shared {
        barrier: Barrier::new(size),
        sums: Mutex::new(vec![Vec::new(); size]),
    });
    let mut senders: Vec<Vec<Sender<Vec<f64>>>> = (0..size).map(|_| Vec::new()).collect();
    let mut receivers: Vec<Vec<Receiver<Vec<f64>>>> = (0..size).map(|_| Vec::new()).collect();
    for to_all in senders.iter_mut() {
        for inbox in receivers.iter_mut() {
            let (sender, receiver) = channel();
            to_all.push(sender);
            inbox.push(receiver);
        }
    }
    (senders.into_iter().zip(receivers).enumerate())
        .map(|(rank, (to, from))| ThreadRank {
            rank,
            size,
            shared: shared.clone(),
            to,
            from,
        })
        .collect()
}

impl TimeRanks for ThreadRank {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn sum(&self, values: &mut [f64]) {
        self.shared.sums.lock().unwrap()[self.rank] = values.to_vec();
        self.shared.barrier.wait();
        let all = self.shared.sums.lock().unwrap().clone();
        self.shared.barrier.wait();
        for (k, v) in values.iter_mut().enumerate() {
            *v = all.iter().map(|rank| rank[k]).sum();
        }
    }

    fn send(&self, to: usize, values: &[f64]) {
        self.to[to].send(values.to_vec()).unwrap();
    }

    fn receive(&self, from: usize) -> Vec<f64> {
        self.from[from].recv().unwrap()
    }
}

/// Rank `rank` of `size`: its window's slabs `[a, b)` from its frames alone, the scales summed
/// over ranks, the solve; returns its unknowns and the iterations.
fn rank_solve(
    sequence: &MeshSequence,
    params: &FlowParams,
    rank: ThreadRank,
    window: TimeWindow,
) -> (Vec<f64>, usize) {
    let frames = window.frames();
    let local = sequence.frames(frames.clone()).unwrap();
    let slabs = WindowSlabs::new(&local, frames.start, window, params).unwrap();
    let mut sums = slabs.scale_sums(&local).to_array();
    rank.sum(&mut sums);
    let scales = ScaleSums::from_array(sums).scales();
    let system = slabs.assemble(&local, params, &scales).unwrap();
    let solution = solve_window(&system, &rank, params, &|_| {}).unwrap();
    (solution.u, solution.iterations)
}

/// Solves with `solver` in one process and over 1 to 8 ranks (at most one per slab): the same
/// solution to 1e-10 and the same iterations (±1, the dot products summed in another order).
fn check(name: &str, sequence: &MeshSequence, params: &FlowParams, solver: SolverChoice) {
    let params = FlowParams {
        solver,
        tolerance: 1e-12,
        direct_limit: 0,
        ..params.clone()
    };
    let single = FlowProblem::new(sequence, &params)
        .unwrap()
        .solve(&|_| {})
        .unwrap();
    let expected: Vec<f64> = (single.intrinsic.iter().flatten())
        .flat_map(|v| [v.x, v.y])
        .collect();
    let n_slabs = sequence.n_slabs();
    for size in 1..=n_slabs.min(8) {
        let results: Vec<(Vec<f64>, usize)> = std::thread::scope(|scope| {
            let handles: Vec<_> = (thread_ranks(size).into_iter())
                .map(|me| {
                    let window = TimeWindow::of_rank(me.rank, size, n_slabs);
                    let params = &params;
                    scope.spawn(move || rank_solve(sequence, params, me, window))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let u: Vec<f64> = results.iter().flat_map(|(u, _)| u.clone()).collect();
        let norm = expected.iter().map(|x| x * x).sum::<f64>().sqrt();
        let difference = (u.iter().zip(&expected))
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt()
            / norm;
        let iterations: Vec<usize> = results.iter().map(|(_, i)| *i).collect();
        println!(
            "{name}, {solver:?}, {size} ranks: iterations {iterations:?} (one process {}, {}), \
             difference {difference:.1e}",
            single.iterations, single.method
        );
        assert!(difference < 1e-10, "{name}, {size} ranks: {difference:e}");
        assert!(iterations.iter().all(|&i| i == iterations[0]), "{name}");
        assert!(
            iterations[0].abs_diff(single.iterations) <= 1,
            "{name}, {size} ranks"
        );
    }
}

#[test]
fn ranks_sweep_as_one_process_does() {
    for (name, sequence, params) in common::window_cases() {
        check(&name, &sequence, &params, SolverChoice::PcgSlabGaussSeidel);
    }
}

/// The coarse levels pair slabs across windows and gather onto fewer ranks; the V-cycle is
/// the single process's, so are the iterations.
#[test]
fn ranks_run_the_multigrid_in_time_as_one_process_does() {
    for (name, sequence, params) in common::window_cases() {
        check(&name, &sequence, &params, SolverChoice::PcgTimeMultigrid);
    }
}
