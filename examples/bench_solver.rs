//! Solver robustness benchmark: iterations, seconds and peak memory of the space-time solve
//! over `α ∈ {∞, 10, 1, 0.1, 0.01, 0.001} × γ ∈ {1, 0.01}` on the paper's torus (grey values in
//! [0, 1]), plus the default weights at 30 frames per second. Each cell runs in its own
//! process so that its peak memory is its own.
//!
//! `cargo run --release --example bench_solver [-- N1 N2 FRAMES [SOLVER]]` (default 128 95 20
//! auto). It ends with the time ratio `t(α = 0.01) / t(α = 1)` per `γ` (solve seconds, with
//! the factorization; also end to end, with assembly), of the medians of the table's run and
//! two more alternating runs of each of its cells: subnormal numbers in the single-precision
//! slab factors slow mid-range `α` on some processors ([`meshflow::subnormals`]). With
//! `SUBNORMALS=keep` in the environment the solver runs without flushing them, to measure what
//! they cost; the column `subnormal` is the share of the factors' entries that are subnormal.

use meshflow::flow::{FlowParams, FlowProblem, SolverChoice};
use std::collections::HashMap;
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

fn main() -> Result<()> {
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
    let mut seconds: HashMap<(&str, &str), Vec<CellSeconds>> = HashMap::new();
    let mut run = |[alpha, gamma, fps]: [&'static str; 3], print_line: bool| -> Result<()> {
        let (n1, n2, frames) = (&size[0], &size[1], &size[2]);
        match run_cell_process(&[n1, n2, frames, &solver, alpha, gamma, fps])? {
            Ok(line) => {
                if print_line {
                    print!("{line}");
                }
                if let Some(cell) = CellSeconds::of(&line) {
                    seconds.entry((alpha, gamma)).or_default().push(cell);
                }
            }
            Err(error) => println!(
                "{alpha:>8} {gamma:>6} {fps:>6}  failed: {}",
                error.replace('\n', " ")
            ),
        }
        Ok(())
    };
    for cell in cells {
        run(cell, true)?;
    }
    for _ in 0..RATIO_REPEATS {
        for gamma in ["1", "0.01"] {
            for alpha in ["1", "0.01"] {
                run([alpha, gamma, "1"], false)?;
            }
        }
    }
    println!(
        "t(α = 0.01) / t(α = 1), medians of {} alternating runs of each cell:",
        RATIO_REPEATS + 1
    );
    for gamma in ["1", "0.01"] {
        let median = |alpha| {
            seconds
                .get(&(alpha, gamma))
                .map(|runs| CellSeconds::median(runs))
        };
        if let (Some(mid), Some(one)) = (median("0.01"), median("1")) {
            println!(
                "γ = {gamma}: {:.2} (solve {:.2} / {:.2} s, factorization {:.2} / {:.2} s); \
                 with assembly {:.2} ({:.2} / {:.2} s)",
                mid.solve / one.solve,
                mid.solve,
                one.solve,
                mid.factor,
                one.factor,
                mid.total / one.total,
                mid.total,
                one.total
            );
        }
    }
    Ok(())
}

/// Further runs of the ratio's four cells after the table, alternating, so that each ratio
/// is of medians rather than of single runs on a machine whose timings vary by 10–30 %.
const RATIO_REPEATS: usize = 2;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// A cell's seconds: factorization, solve (with it) and end to end (with assembly).
#[derive(Clone, Copy)]
struct CellSeconds {
    factor: f64,
    solve: f64,
    total: f64,
}

impl CellSeconds {
    /// From a cell's line ([`run_cell`]).
    fn of(line: &str) -> Option<Self> {
        let columns: Vec<&str> = line.split_whitespace().collect();
        let number = |k: usize| columns.get(k)?.trim_start_matches('(').parse::<f64>().ok();
        let total = columns.iter().position(|c| *c == "with")?.checked_sub(2)?;
        Some(Self {
            factor: number(4)?,
            solve: number(5)?,
            total: number(total)?,
        })
    }

    /// Each field's median over `runs` (the upper one of an even count).
    fn median(runs: &[Self]) -> Self {
        let median = |field: fn(&Self) -> f64| {
            let mut values: Vec<f64> = runs.iter().map(field).collect();
            values.sort_by(f64::total_cmp);
            values[values.len() / 2]
        };
        Self {
            factor: median(|c| c.factor),
            solve: median(|c| c.solve),
            total: median(|c| c.total),
        }
    }
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
fn run_cell(args: &[String]) -> Result<()> {
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
        "{alpha:>8} {gamma:>6} {fps:>6} {:>11} {:>9.2} {:>9.2} {:>8.2} {:>10.1e}  {}, {} levels ({:.2} s with assembly)",
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
