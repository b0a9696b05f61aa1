//! `meshflow::subnormals`: the solver's kernels run with subnormal numbers flushed on the
//! calling thread and on every rayon worker, and each thread's own mode comes back afterwards,
//! also when several threads hold scopes at once or a kernel panics. One test function: the
//! mode is per thread but the pool and the switch are shared by the whole binary.

use meshflow::flow::{compute_flow, FlowParams};
use meshflow::subnormals::{flushed, flushing_on_this_thread, set_enabled};
use std::hint::black_box;

/// Half the smallest normal `f32`: a subnormal, or 0 under flush-to-zero.
fn half_smallest_normal() -> f32 {
    black_box(f32::MIN_POSITIVE) * black_box(0.5)
}

/// `(caller, every pool thread)`: is flush-to-zero on, and does arithmetic flush?
fn modes() -> (bool, Vec<bool>) {
    let this = |_| flushing_on_this_thread() && half_smallest_normal() == 0.0;
    (this(()), rayon::broadcast(|_| this(())))
}

fn assert_default(when: &str) {
    let (caller, pool) = modes();
    assert!(
        !caller && pool.iter().all(|&on| !on),
        "{when}: {caller} {pool:?}"
    );
    assert!(half_smallest_normal() > 0.0, "{when}: gradual underflow");
}

#[test]
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
fn kernels_flush_subnormals_and_give_each_thread_its_mode_back() {
    assert_default("before");
    let (caller, pool) = flushed(modes);
    assert!(
        caller && pool.iter().all(|&on| on),
        "inside: {caller} {pool:?}"
    );
    assert_default("after");

    // Nested, and from several threads at once (ranks played by threads): a pool thread keeps
    // the modes while any scope holds it and gets its own back when the last one ends.
    let inner = flushed(|| flushed(modes));
    assert!(inner.0 && inner.1.iter().all(|&on| on), "nested: {inner:?}");
    let barrier = std::sync::Barrier::new(4);
    std::thread::scope(|scope| {
        for k in 0..4 {
            let barrier = &barrier;
            scope.spawn(move || {
                flushed(|| {
                    barrier.wait();
                    std::thread::sleep(std::time::Duration::from_millis(5 * k));
                    let (caller, pool) = modes();
                    assert!(caller && pool.iter().all(|&on| on), "thread {k}");
                });
            });
        }
    });
    assert_default("after concurrent scopes");

    // A panicking kernel leaves no thread flushed.
    let panicked = std::panic::catch_unwind(|| flushed(|| panic!("kernel")));
    assert!(panicked.is_err());
    assert_default("after a panic");

    // Switched off, kernels run in the caller's mode; the solve is the same either way on
    // a problem without subnormals.
    let sample = meshflow::synth::rotating_sphere(2, 3, 1.0, 0.1)
        .unwrap()
        .sequence;
    let with = compute_flow(&sample, &FlowParams::default()).unwrap();
    set_enabled(false);
    let (caller, _) = flushed(modes);
    assert!(!caller, "switched off");
    let without = compute_flow(&sample, &FlowParams::default()).unwrap();
    set_enabled(true);
    assert_eq!(with.intrinsic, without.intrinsic);
    assert_default("after solves");

    // Where subnormals arise: the single-precision slab factors of multigrid in time at a
    // mid-range α (3.7 % of the entries on the 128 × 95 × 20 torus, `bench_solver`). Kept,
    // the factors hold some; flushed, none, and the solve takes the same iterations to a
    // solution within its tolerance.
    let torus = meshflow::synth::paper_torus(32, 24, 8).unwrap();
    let params = FlowParams {
        solver: meshflow::flow::SolverChoice::PcgTimeMultigrid,
        ..FlowParams::paper(0.01, 0.0, 1.0)
    };
    let flushed_solve = compute_flow(&torus, &params).unwrap();
    set_enabled(false);
    let kept_solve = compute_flow(&torus, &params).unwrap();
    set_enabled(true);
    assert_eq!(flushed_solve.subnormal_factor_entries, 0);
    assert!(
        kept_solve.subnormal_factor_entries > 0,
        "{} entries",
        kept_solve.factor_entries
    );
    assert_eq!(flushed_solve.iterations, kept_solve.iterations);
    let difference = (flushed_solve.intrinsic.iter().flatten())
        .zip(kept_solve.intrinsic.iter().flatten())
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    let scale = (kept_solve.intrinsic.iter().flatten())
        .map(|v| v.norm())
        .fold(0.0, f64::max);
    assert!(difference < 1e-6 * scale, "{difference:e} of {scale:e}");
}
