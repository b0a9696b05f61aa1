//! The solve over time windows held by separate ranks (`meshflow::flow::distributed`), with
//! threads standing in for the ranks: for 1 to 4 ranks the solution equals the single
//! process's (`pcg-slab-gauss-seidel`, the same odd–even preconditioner) to 1e-10 and takes the
//! same number of iterations, with lumped and consistent coupling and Dirichlet boundaries.
//! Each rank assembles only its window, from its frames, with the scales summed over ranks.

use meshflow::flow::distributed::{solve_window, TimeRanks};
use meshflow::flow::window::{rank_slabs, window_frames, WindowSlabs};
use meshflow::flow::{FlowParams, FlowProblem, MeshSequence, ScaleSums, SolverChoice};
use std::sync::{Arc, Barrier, Mutex};

mod common;

/// What the threads share: a barrier and one mailbox per rank.
struct Shared {
    barrier: Barrier,
    sums: Mutex<Vec<Vec<f64>>>,
    boundaries: Mutex<Vec<(Vec<f64>, Vec<f64>)>>,
}

struct ThreadRank {
    rank: usize,
    size: usize,
    first_slab: usize,
    shared: Arc<Shared>,
}

impl TimeRanks for ThreadRank {
    fn first_slab(&self) -> usize {
        self.first_slab
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

    fn exchange(&self, first: &[f64], last: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        self.shared.boundaries.lock().unwrap()[self.rank] = (first.to_vec(), last.to_vec());
        self.shared.barrier.wait();
        let all = self.shared.boundaries.lock().unwrap().clone();
        self.shared.barrier.wait();
        let before = (self.rank > 0).then(|| all[self.rank - 1].1.clone());
        let after = (self.rank + 1 < self.size).then(|| all[self.rank + 1].0.clone());
        (before, after)
    }
}

/// Rank `rank` of `size`: its window's slabs `[a, b)` from its frames alone, the scales summed
/// over ranks, the solve; returns its unknowns and the iterations.
fn rank_solve(
    sequence: &MeshSequence,
    params: &FlowParams,
    rank: ThreadRank,
    window: std::ops::Range<usize>,
) -> (Vec<f64>, usize) {
    let frames = window_frames(&window, sequence.n_frames());
    let local = sequence.frames(frames.clone()).unwrap();
    let slabs = WindowSlabs::new(&local, frames.start, window, params).unwrap();
    let mut sums = slabs.scale_sums(&local).to_array();
    rank.sum(&mut sums);
    let scales = ScaleSums::from_array(sums).scales();
    let system = slabs.assemble(&local, params, &scales).unwrap();
    let solution = solve_window(&system, &rank, params).unwrap();
    (solution.u, solution.iterations)
}

fn check(name: &str, sequence: &MeshSequence, params: &FlowParams) {
    let params = FlowParams {
        solver: SolverChoice::PcgSlabGaussSeidel,
        tolerance: 1e-12,
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
    for size in 1..=4 {
        let shared = Arc::new(Shared {
            barrier: Barrier::new(size),
            sums: Mutex::new(vec![Vec::new(); size]),
            boundaries: Mutex::new(vec![(Vec::new(), Vec::new()); size]),
        });
        let results: Vec<(Vec<f64>, usize)> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..size)
                .map(|rank| {
                    let window = rank_slabs(rank, size, n_slabs);
                    let me = ThreadRank {
                        rank,
                        size,
                        first_slab: window.start,
                        shared: shared.clone(),
                    };
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
            "{name}, {size} ranks: iterations {iterations:?} (one process {}), difference {difference:.1e}",
            single.iterations
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
fn ranks_solve_the_whole_system_as_one_process_does() {
    for (name, sequence, params) in common::window_cases() {
        check(&name, &sequence, &params);
    }
}
