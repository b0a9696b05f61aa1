//! Benchmark at the size of the paper's Experiment I: the 255×190 periodic torus grid, 20
//! frames (19 slabs, 1.84 M unknowns), α = γ = 1, β = 0. Prints assembly and solve times,
//! iterations, residual and peak memory, and the cost of analysing the flow
//! (`meshflow::analysis`: divergence, curl, Hodge parts, strain rate) against the solve's.
//!
//! `cargo run --release --example bench_paper_torus [-- N1 N2 FRAMES [solver]]
//! [--anisotropic LAMBDA|auto] [--robust-data EPS|auto] [--check-motion]` (the image-driven
//! anisotropic regularizer, the robust data term, the default's check of the linear model
//! (`flow::motion`): their cost against the paper's quadratic solve's).

use meshflow::flow::{Anisotropy, FlowParams, FlowProblem, Scale, SolveEvent};
use meshflow::synth::paper_torus;
use std::time::Instant;

#[path = "common/memory.rs"]
mod memory;
use memory::peak_memory_bytes;

fn main() -> Result<(), meshflow::Error> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let anisotropy = scale_flag(&mut args, "--anisotropic").map(Anisotropy::with);
    let robust_data = scale_flag(&mut args, "--robust-data");
    let detect_large_motion = match args.iter().position(|a| a == "--check-motion") {
        Some(at) => {
            args.remove(at);
            true
        }
        None => false,
    };
    let number = |i: usize, default: usize| {
        args.get(i)
            .map_or(default, |a| a.parse().expect("a whole number"))
    };
    let (n1, n2, frames) = (number(0, 255), number(1, 190), number(2, 20));
    let solver = args
        .get(3)
        .map_or(Ok(Default::default()), |s| s.parse())
        .expect("a solver name");
    let params = FlowParams {
        solver,
        anisotropy,
        robust_data,
        detect_large_motion,
        ..FlowParams::paper(1.0, 0.0, 1.0)
    };
    println!(
        "paper torus {n1}×{n2}, {frames} frames, α = 1, β = 0, γ = 1, {} threads",
        rayon::current_num_threads()
    );

    let start = Instant::now();
    let sequence = paper_torus(n1, n2, frames)?;
    let generate = start.elapsed().as_secs_f64();
    let problem = FlowProblem::new(&sequence, &params)?;
    let assembled = start.elapsed().as_secs_f64();
    let report = |event: SolveEvent| {
        if let SolveEvent::Iteration {
            iteration,
            relative_residual,
        } = event
        {
            if iteration % 10 == 0 {
                eprintln!("  iteration {iteration:4}: residual {relative_residual:.2e}");
            }
        }
    };
    let result = problem.solve(&report)?;
    let total = start.elapsed().as_secs_f64();
    let solve_peak = peak_memory_bytes();
    let unknowns = problem.system().dimension();
    // The analysis reads the flow, not the system.
    drop(problem);
    let analysis_start = Instant::now();
    let analysed = meshflow::analysis::analyze_flow(&sequence, &result.intrinsic)?;
    let analysis = analysis_start.elapsed().as_secs_f64();

    println!("unknowns            {unknowns}");
    println!("generate sequence   {generate:8.2} s");
    println!("assembly            {:8.2} s", assembled - generate);
    println!(
        "factorization       {:8.2} s  ({:.1} M factor entries)",
        result.timings.factorization,
        result.factor_entries as f64 / 1e6
    );
    println!("solve (incl. fact.) {:8.2} s", result.timings.solve);
    println!("end to end          {total:8.2} s");
    println!(
        "analysis            {analysis:8.2} s  ({:.0} % of assembly + solve; {} slabs)",
        100.0 * analysis / (total - generate),
        analysed.len()
    );
    println!("solver              {}", result.method);
    println!(
        "iterations          {} ({} in all; {} reweightings)",
        result.iterations,
        result.iterations_in_all(),
        result.reweightings
    );
    if let Some(check) = &result.motion_check {
        println!(
            "motion check        η = {:.3} ({})",
            check.linearization_error,
            if check.warped { "warped" } else { "linear" }
        );
    }
    for step in &result.timings.steps {
        println!(
            "  {:<17} {:8.2} s  ({} iterations)",
            step.label, step.seconds, step.iterations
        );
    }
    println!("relative residual   {:.2e}", result.relative_residual);
    println!(
        "energy              {:.6e} (zero flow {:.6e})",
        result.energy, result.energy_at_zero
    );
    println!(
        "peak memory         {:.2} GB ({:.2} GB with the analysis)",
        solve_peak as f64 / 1e9,
        peak_memory_bytes() as f64 / 1e9
    );
    Ok(())
}

/// The scale after `flag` (`auto` or a number), taken out of `args`; `None` without the flag.
fn scale_flag(args: &mut Vec<String>, flag: &str) -> Option<Scale> {
    let at = args.iter().position(|a| a == flag)?;
    let value = args.get(at + 1).map(|l| l.parse::<Scale>());
    args.drain(at..(at + 2).min(args.len()));
    let value = value.unwrap_or_else(|| panic!("a scale after {flag}"));
    Some(value.expect("auto or a number"))
}
