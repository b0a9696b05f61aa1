//! Per-slab costs of the space-time solve at growing mesh sizes: the measured inputs of the
//! scale model in `docs/scaling.md` (memory per rank, bytes sent per iteration and time of a
//! solve distributed over time windows).
//!
//! For each `n1 × n2` torus grid (`synth::paper_torus` geometry, grey values in [0, 1]),
//! `FRAMES` frames, one process per cell so that peak memory is its own:
//! - slab Gauss–Seidel at `α = 1` (the fine slab factors only): factor entries per slab,
//!   factorization CPU-seconds per slab, CPU-seconds per slab and iteration;
//! - multigrid in time at `α = 0.01`: iterations, CPU-seconds per fine slab and iteration,
//!   factor entries of all levels, peak memory per unknown.
//!
//! CPU-seconds are wall seconds × threads (the slabs are processed in parallel).
//!
//! `cargo run --release --example bench_scale [-- FRAMES N1xN2 ...]` (default 9 frames,
//! 64x48 128x95 255x190 510x380).

use meshflow::flow::{FlowParams, FlowProblem, SolverChoice};

#[path = "common/cells.rs"]
mod cells;
use cells::{cell_args, run_cell_process};
#[path = "common/memory.rs"]
mod memory;
use memory::peak_memory_bytes;
#[path = "common/torus.rs"]
mod torus;
use torus::unit_grey_torus;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(cell) = cell_args(&args) {
        return run_cell(cell);
    }
    let frames = args.first().cloned().unwrap_or("9".into());
    let default_sizes = ["64x48", "128x95", "255x190", "510x380"].map(String::from);
    let sizes: Vec<String> = match args.len() > 1 {
        true => args[1..].to_vec(),
        false => default_sizes.to_vec(),
    };
    println!(
        "paper torus, {frames} frames, grey values in [0, 1], {} threads; per slab: factor MB \
         (f32), factorization CPU s, CPU s per iteration (GS at α = 1, MG at α = 0.01)",
        rayon::current_num_threads()
    );
    println!(
        "{:>9} {:>9} {:>10} {:>9} {:>8} {:>9} {:>6} {:>9} {:>10} {:>9}",
        "vertices",
        "unknowns",
        "factor MB",
        "factor s",
        "GS s/it",
        "GS iters",
        "MG it",
        "MG s/it",
        "MG fact MB",
        "B/unknown"
    );
    for size in sizes {
        let (n1, n2) = size.split_once('x').ok_or("sizes are N1xN2")?;
        let cell = |solver: &str| -> Result<Vec<f64>, Box<dyn std::error::Error>> {
            let line = run_cell_process(&[n1, n2, &frames, solver])??;
            Ok(line
                .split_whitespace()
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect())
        };
        // [vertices, slabs, unknowns, iterations, factor entries, factor s, solve s, peak bytes]
        let gs = cell("pcg-slab-gauss-seidel")?;
        let mg = cell("pcg-time-multigrid")?;
        let threads = rayon::current_num_threads() as f64;
        let slabs = gs[1];
        let per_iteration = |c: &[f64]| (c[6] - c[5]) * threads / (c[3] * slabs);
        println!(
            "{:>9} {:>9} {:>10.1} {:>9.3} {:>8.4} {:>9} {:>6} {:>9.4} {:>10.1} {:>9.0}",
            gs[0],
            gs[2],
            gs[4] * 4.0 / slabs / 1e6,
            gs[5] * threads / slabs,
            per_iteration(&gs),
            gs[3],
            mg[3],
            per_iteration(&mg),
            mg[4] * 4.0 / slabs / 1e6,
            mg[7] / mg[2],
        );
    }
    Ok(())
}

/// `--cell N1 N2 FRAMES SOLVER`: one solve; prints vertices, slabs, unknowns, iterations,
/// factor entries, factorization and solve seconds, peak bytes.
fn run_cell(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let [n1, n2, frames]: [usize; 3] = std::array::from_fn(|i| args[i].parse().expect("a size"));
    let solver: SolverChoice = args[3].parse()?;
    let alpha = match solver {
        SolverChoice::PcgTimeMultigrid => 0.01,
        _ => 1.0,
    };
    let params = FlowParams {
        solver,
        ..FlowParams::paper(alpha, 0.0, 1.0)
    };
    let sequence = unit_grey_torus(n1, n2, frames, 1.0)?;
    let problem = FlowProblem::new(&sequence, &params)?;
    let result = problem.solve(&|_| {})?;
    println!(
        "{} {} {} {} {} {} {} {}",
        sequence.mesh().n_vertices(),
        sequence.n_slabs(),
        problem.system().dimension(),
        result.iterations,
        result.factor_entries,
        result.timings.factorization,
        result.timings.solve,
        peak_memory_bytes()
    );
    Ok(())
}
