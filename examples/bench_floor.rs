//! How far the paper-size solve is from what its method cannot go below on this machine: the
//! slab factorizations' arithmetic and the slab solves' memory traffic, each set against the
//! solve's own times (`bench_scipy`'s texture: the paper's torus, grey values in [0, 1],
//! `α = γ = 1`, `β = 0`).
//!
//! - **Factorizations.** One slab block's supernodal Cholesky factorization (faer's, in `f32`,
//!   as the solver's) costs `Σ_s w³/3 + w² m + w m²` flops over its supernodes (`w` columns,
//!   `m` rows below). Timed alone on one thread, it gives the rate; the `S` slab factorizations
//!   on `T` threads cannot take less than `S / T` of those (each thread at that rate).
//! - **Iterations.** Slab Gauss–Seidel's PCG on the odd slabs solves once with every slab's
//!   factor an iteration (docs/scaling.md), and a solve reads the factor twice (`L`, then `Lᵀ`),
//!   four bytes an entry. At the rate this machine streams an `f32` array on `T` threads (the
//!   fastest of five passes over 1 GB), an iteration cannot take less than those bytes' time.
//!
//! - **First touches.** The pages the solve maps on first touch (4 KB each, most of them the
//!   new factors'; faer zeroes a factor before it factors) and the system time of the solve:
//!   on this machine a fault costs 1.7–8 µs, varying between runs (docs/scaling.md, "The
//!   paper size against its floors").
//!
//! `cargo run --release --example bench_floor [-- N1 N2 FRAMES]` (default 255 190 20).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::sparse::SparseColMatRef;
use faer::{Par, Side};
use meshflow::flow::{FlowParams, FlowProblem};
use rayon::prelude::*;
use std::time::Instant;

#[path = "common/torus.rs"]
mod torus;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn main() -> Result<()> {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<std::result::Result<_, _>>()?;
    let [n1, n2, frames] = [0, 1, 2].map(|i| sizes.get(i).copied().unwrap_or([255, 190, 20][i]));
    let threads = rayon::current_num_threads();
    println!("paper torus {n1}×{n2}, {frames} frames, α = γ = 1, β = 0, {threads} threads");
    let sequence = torus::unit_grey_torus(n1, n2, frames, 1.0)?;
    let problem = FlowProblem::new(&sequence, &FlowParams::paper(1.0, 0.0, 1.0))?;
    let system = problem.system();
    let slabs = system.n_slabs();
    let cost = factor_cost(system.slab_symbolic()).ok_or("a supernodal slab factor")?;
    let block = system.block(slabs / 2);
    let (pattern, values) = block.parts();
    // As the solver factorizes: subnormal numbers flushed (`meshflow::subnormals`).
    let one_factorization = (0..5)
        .map(|_| {
            meshflow::subnormals::flushed(|| {
                time_f32_factorization(system.slab_symbolic(), pattern, values)
            })
        })
        .fold(f64::INFINITY, f64::min);
    let stream = streaming_read_rate();
    let before = Usage::now();
    let result = problem.solve(&|_| {})?;
    let touched = Usage::now().since(&before);

    let factorization_floor = slabs as f64 * one_factorization / threads as f64;
    let iteration_bytes = slabs as f64 * 2.0 * cost.entries * 4.0;
    let iteration_floor = iteration_bytes / stream;
    let iterations = result.iterations.max(1) as f64;
    let iterations_time = result.timings.solve - result.timings.factorization;
    println!("slab block          {} unknowns", system.slab_dimension());
    println!(
        "slab factor         {:.2} M entries, {} supernodes, {:.2} GFlop to factor",
        cost.entries / 1e6,
        cost.supernodes,
        cost.flops / 1e9
    );
    println!(
        "one factorization   {one_factorization:.3} s on one thread ({:.1} GFlop/s, f32)",
        cost.flops / one_factorization / 1e9
    );
    println!(
        "streaming read      {:.1} GB/s on {threads} threads",
        stream / 1e9
    );
    println!("                    floor       measured");
    println!(
        "factorizations      {factorization_floor:6.2} s    {:6.2} s  ({slabs} slabs)",
        result.timings.factorization
    );
    println!(
        "one iteration       {:6.3} s    {:6.3} s  ({:.2} GB of factor reads: {:.1} GB/s)",
        iteration_floor,
        iterations_time / iterations,
        iteration_bytes / 1e9,
        iteration_bytes * iterations / iterations_time / 1e9
    );
    println!(
        "iterations          {:6.2} s    {iterations_time:6.2} s  ({} iterations, {})",
        iteration_floor * iterations,
        result.iterations,
        result.method
    );
    println!(
        "assembly            {:>6}      {:6.2} s",
        "", result.timings.assembly
    );
    println!(
        "first touches       {:.0} k page faults in the solve ({:.2} GB), {:.2} s of system time",
        touched.minor_faults as f64 / 1e3,
        touched.minor_faults as f64 * 4096.0 / 1e9,
        touched.system_seconds
    );
    Ok(())
}

/// What the kernel did for the process so far: the pages it mapped on first touch (the new
/// factors' among them) and its CPU time doing so and the rest (`getrusage`).
struct Usage {
    minor_faults: i64,
    system_seconds: f64,
}

impl Usage {
    fn now() -> Self {
        // SAFETY: `getrusage` fills the zeroed struct it is given.
        let usage = unsafe {
            let mut usage: libc::rusage = std::mem::zeroed();
            libc::getrusage(libc::RUSAGE_SELF, &mut usage);
            usage
        };
        let time = usage.ru_stime;
        Self {
            minor_faults: usage.ru_minflt,
            system_seconds: time.tv_sec as f64 + time.tv_usec as f64 * 1e-6,
        }
    }

    fn since(&self, earlier: &Self) -> Self {
        Self {
            minor_faults: self.minor_faults - earlier.minor_faults,
            system_seconds: self.system_seconds - earlier.system_seconds,
        }
    }
}

/// A supernodal factor's size and the flops of its numeric factorization.
struct FactorCost {
    supernodes: usize,
    /// Entries of `L`: `w (w + 1) / 2 + w m` per supernode.
    entries: f64,
    /// `w³/3 + w² m + w m²` per supernode: its dense factorization, the solve of its rows below,
    /// and their update of the later columns.
    flops: f64,
}

fn factor_cost(symbolic: &SymbolicCholesky<usize>) -> Option<FactorCost> {
    let SymbolicCholeskyRaw::Supernodal(s) = symbolic.raw() else {
        return None;
    };
    let widths = s.supernode_begin().iter().zip(s.supernode_end());
    let (entries, flops) = widths
        .enumerate()
        .map(|(k, (begin, end))| {
            let (w, m) = ((end - begin) as f64, s.supernode(k).pattern().len() as f64);
            (
                w * (w + 1.0) / 2.0 + w * m,
                w * w * w / 3.0 + w * w * m + w * m * m,
            )
        })
        .fold((0.0, 0.0), |(e, f), (de, df)| (e + de, f + df));
    Some(FactorCost {
        supernodes: s.supernode_begin().len(),
        entries,
        flops,
    })
}

/// Seconds of one `f32` numeric factorization on one thread, as the solver makes each.
fn time_f32_factorization(
    symbolic: &SymbolicCholesky<usize>,
    pattern: faer::sparse::SymbolicSparseColMatRef<'_, usize>,
    values: &[f64],
) -> f64 {
    let rounded: Vec<f32> = values.iter().map(|&v| v as f32).collect();
    // Touched before the clock starts: the first write to fresh pages is not arithmetic.
    let mut factor = vec![1f32; symbolic.len_val()];
    let scratch = symbolic.factorize_numeric_llt_scratch::<f32>(Par::Seq, Default::default());
    let start = Instant::now();
    symbolic
        .factorize_numeric_llt::<f32>(
            &mut factor,
            SparseColMatRef::new(pattern, &rounded),
            Side::Lower,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(scratch)),
            Default::default(),
        )
        .expect("the slab blocks are positive definite");
    start.elapsed().as_secs_f64()
}

/// Bytes per second this machine reads an `f32` array with, on all of rayon's threads.
fn streaming_read_rate() -> f64 {
    let array = vec![1f32; 1 << 28];
    let seconds = (0..5)
        .map(|_| {
            let start = Instant::now();
            let sum: f32 = array.par_chunks(1 << 16).map(lane_sum).sum();
            std::hint::black_box(sum);
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min);
    (array.len() * 4) as f64 / seconds
}

/// The sum of `x` in 16 lanes, so that the compiler vectorizes it and the reads, not the
/// additions' latency, bound it.
fn lane_sum(x: &[f32]) -> f32 {
    let mut lanes = [0f32; 16];
    for chunk in x.chunks_exact(16) {
        lanes.iter_mut().zip(chunk).for_each(|(l, v)| *l += v);
    }
    lanes.iter().sum::<f32>() + x.chunks_exact(16).remainder().iter().sum::<f32>()
}
