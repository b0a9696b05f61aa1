//! Solver robustness benchmark: iterations, seconds and peak memory of the space-time solve
//! over `α ∈ {∞, 10, 1, 0.1, 0.01, 0.001} × γ ∈ {1, 0.01}` on the paper's torus (grey values in
//! [0, 1]), plus the default weights at 30 frames per second. Each cell runs in its own
//! process so that its peak memory is its own.
//!
//! `cargo run --release --example bench_solver [-- N1 N2 FRAMES [SOLVER]]` (default 128 95 20
//! auto). It ends with the time ratio `t(α = 0.01) / t(α = 1)` per `γ` (solve seconds, with
//! the factorization): subnormal numbers in the single-precision slab factors slow mid-range
//! `α` on some processors ([`meshflow::subnormals`]). With `SUBNORMALS=keep` in the
//! environment the solver runs without flushing them, to measure what they cost; the column
//! `subnormal` is the share of the factors' entries that are subnormal.

use meshflow::flow::{FlowParams, FlowProblem, SolverChoice};
use std::time::Instant;

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
    let size: Vec<String> = ["128", "95", "20"]
        .iter()
        .enumerate()
        .map(|(i, d)| args.get(i).cloned().unwrap_or(d.to_string()))
        .collect();
    let solver = args.get(3).cloned().unwrap_or("auto".into());
    println!(
        "paper torus {}×{}, {} frames, grey values in [0, 1], solver {solver}, {} threads, \
         tolerance 1e-8",
        size[0],
        size[1],
        size[2],
        rayon::current_num_threads()
    );
    println!("subnormals {}", subnormal_mode());
    println!(
        "{:>8} {:>6} {:>6} {:>11} {:>9} {:>9} {:>8} {:>10}  method",
        "α", "γ", "fps", "iterations", "factor s", "solve s", "peak GB", "subnormal"
    );
    let mut cells: Vec<[&str; 3]> = Vec::new();
    for gamma in ["1", "0.01"] {
        for alpha in ["inf", "10", "1", "0.1", "0.01", "0.001"] {
            cells.push([alpha, gamma, "1"]);
        }
    }
    cells.push(["default", "default", "30"]);
    let mut seconds = std::collections::HashMap::new();
    for [alpha, gamma, fps] in cells {
        let (n1, n2, frames) = (&size[0], &size[1], &size[2]);
        match run_cell_process(&[n1, n2, frames, &solver, alpha, gamma, fps])? {
            Ok(line) => {
                print!("{line}");
                let columns: Vec<&str> = line.split_whitespace().collect();
                let number = |k: usize| columns.get(k).and_then(|c| c.parse::<f64>().ok());
                if let (Some(factor), Some(solve)) = (number(4), number(5)) {
                    seconds.insert((alpha, gamma), (factor, solve));
                }
            }
            Err(error) => println!(
                "{alpha:>8} {gamma:>6} {fps:>6}  failed: {}",
                error.replace('\n', " ")
            ),
        }
    }
    for gamma in ["1", "0.01"] {
        if let (Some(mid), Some(one)) = (seconds.get(&("0.01", gamma)), seconds.get(&("1", gamma)))
        {
            println!(
                "γ = {gamma}: t(α = 0.01) / t(α = 1) = {:.2} (solve {:.2} / {:.2} s, \
                 factorization {:.2} / {:.2} s)",
                mid.1 / one.1,
                mid.1,
                one.1,
                mid.0,
                one.0
            );
        }
    }
    Ok(())
}

/// `SUBNORMALS=keep`: the solver leaves subnormal numbers as they are.
fn subnormal_mode() -> &'static str {
    match std::env::var("SUBNORMALS").as_deref() {
        Ok("keep") => {
            meshflow::subnormals::set_enabled(false);
            "kept (SUBNORMALS=keep)"
        }
        _ => "flushed to zero while the solver runs",
    }
}

/// `--cell N1 N2 FRAMES SOLVER ALPHA GAMMA FPS`: one solve, one line.
fn run_cell(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let [n1, n2, frames]: [usize; 3] = std::array::from_fn(|i| args[i].parse().expect("a size"));
    let solver: SolverChoice = args[3].parse()?;
    let (alpha, gamma, fps) = (&args[4], &args[5], args[6].parse::<f64>()?);
    let params = match (alpha.as_str(), gamma.as_str()) {
        ("default", _) => FlowParams::default(),
        (a, g) => FlowParams::paper(a.parse()?, 0.0, g.parse()?),
    };
    let params = FlowParams { solver, ..params };
    subnormal_mode();
    let sequence = unit_grey_torus(n1, n2, frames, fps)?;
    let start = Instant::now();
    let problem = FlowProblem::new(&sequence, &params)?;
    let result = problem.solve(&|_| {})?;
    let total = start.elapsed().as_secs_f64();
    println!(
        "{alpha:>8} {gamma:>6} {fps:>6} {:>11} {:>9.2} {:>9.2} {:>8.2} {:>10.1e}  {}, {} levels ({:.1} s with assembly)",
        result.iterations,
        result.timings.factorization,
        result.timings.solve,
        peak_memory_bytes() as f64 / 1e9,
        result.subnormal_factor_entries as f64 / result.factor_entries.max(1) as f64,
        result.method,
        result.time_levels,
        total
    );
    Ok(())
}
