//! The iterative solvers against the direct one, on small problems: multigrid in time,
//! slab Gauss–Seidel, shared slab factors, and the `auto` choice with its stated reason.

use meshflow::flow::{
    compute_flow, Boundary, FlowParams, FlowProblem, FlowResult, MeshSequence, SolverChoice,
    SolverMethod, TimeCoupling,
};
use meshflow::synth::{deforming_sphere, rotating_sphere};

mod common;
use common::{assert_same_intrinsic_flow, still_sequence};

/// A sphere stretching while its texture turns: the transport between slabs is not the
/// identity, so the coarse levels' rotations matter.
fn stretching_sphere(n_frames: usize) -> MeshSequence {
    deforming_sphere(2, n_frames, 1.0, 0.05, 0.3)
        .unwrap()
        .sequence
}

fn solve(sequence: &MeshSequence, params: FlowParams) -> FlowResult {
    compute_flow(sequence, &params).unwrap()
}

#[test]
fn multigrid_in_time_agrees_with_the_direct_solver() {
    // Even and odd slab counts (the odd last slab stays alone on the coarse levels), both time
    // couplings, both boundary conditions (a hemisphere-free sphere has no boundary, so the
    // Dirichlet case uses the stripes below), strong and weak time coupling.
    for n_frames in [6, 9] {
        let sequence = stretching_sphere(n_frames);
        for coupling in [TimeCoupling::Lumped, TimeCoupling::Consistent] {
            for alpha in [1.0, 1e-3] {
                let params = |solver| FlowParams {
                    solver,
                    time_coupling: coupling,
                    tolerance: 1e-12,
                    ..FlowParams::paper(alpha, 0.0, 0.1)
                };
                let direct = solve(&sequence, params(SolverChoice::Direct));
                let multigrid = solve(&sequence, params(SolverChoice::PcgTimeMultigrid));
                assert_eq!(multigrid.method, SolverMethod::PcgTimeMultigrid);
                // A few MB of factors in all: the levels keep single precision.
                assert!(
                    (multigrid.solver_reason).ends_with("the levels' factors in single precision"),
                    "{}",
                    multigrid.solver_reason
                );
                // 5 slabs: 5, 3, 2, 1; 8 slabs: 8, 4, 2, 1.
                assert_eq!(multigrid.time_levels, 4, "{n_frames} frames");
                assert!(
                    multigrid.relative_residual <= 1e-10,
                    "{:e}",
                    multigrid.relative_residual
                );
                assert_same_intrinsic_flow(&direct, &multigrid);
            }
        }
    }
}

#[test]
fn multigrid_with_dirichlet_boundary_agrees_with_the_direct_solver() {
    let sequence = still_sequence(&meshflow::shapes::grid(9, 8, 1.0, 1.0), 7, |p, k| {
        let t = k as f64;
        (5.0 * p.x - 0.2 * t).sin() * (3.0 * p.y + 0.1 * t).cos()
    });
    let params = |solver| FlowParams {
        solver,
        boundary: Boundary::Dirichlet,
        tolerance: 1e-12,
        ..FlowParams::paper(0.01, 0.0, 0.05)
    };
    let direct = solve(&sequence, params(SolverChoice::Direct));
    let multigrid = solve(&sequence, params(SolverChoice::PcgTimeMultigrid));
    assert_same_intrinsic_flow(&direct, &multigrid);
}

#[test]
fn multigrid_iterations_stay_flat_where_gauss_seidel_degrades() {
    // 16 slabs; α from balanced to a time coupling 10⁶ times stronger.
    let sequence = rotating_sphere(3, 17, 1.0, 0.05).unwrap().sequence;
    let iterations = |solver, alpha| {
        let params = FlowParams {
            solver,
            ..FlowParams::paper(alpha, 0.0, 0.1)
        };
        solve(&sequence, params).iterations
    };
    let multigrid: Vec<usize> = [1.0, 0.1, 0.01, 1e-3]
        .iter()
        .map(|&a| iterations(SolverChoice::PcgTimeMultigrid, a))
        .collect();
    let gauss_seidel = [1.0, 1e-3].map(|a| iterations(SolverChoice::PcgSlabGaussSeidel, a));
    println!("multigrid {multigrid:?}, slab Gauss-Seidel {gauss_seidel:?}");
    assert!(multigrid.iter().all(|&n| n <= 20), "{multigrid:?}");
    // The test problem does exercise the weak spot.
    assert!(gauss_seidel[1] > 3 * gauss_seidel[0], "{gauss_seidel:?}");
    assert!(
        gauss_seidel[1] > 3 * multigrid[3],
        "{gauss_seidel:?} vs {multigrid:?}"
    );
}

#[test]
fn auto_adds_time_levels_only_when_gauss_seidel_is_slow() {
    let sequence = rotating_sphere(3, 17, 1.0, 0.05).unwrap().sequence;
    let auto = |alpha| {
        // No direct solve, so that `auto` has to choose a preconditioner.
        let params = FlowParams {
            direct_limit: 0,
            ..FlowParams::paper(alpha, 0.0, 0.1)
        };
        solve(&sequence, params)
    };
    let weak = auto(10.0);
    assert_eq!(
        weak.method,
        SolverMethod::PcgSlabGaussSeidel,
        "{}",
        weak.solver_reason
    );
    assert!(
        weak.solver_reason.contains("fast enough"),
        "{}",
        weak.solver_reason
    );
    let strong = auto(1e-3);
    assert_eq!(
        strong.method,
        SolverMethod::PcgTimeMultigrid,
        "{}",
        strong.solver_reason
    );
    assert_eq!(strong.time_levels, 5);
    assert!(
        strong.solver_reason.contains("the time coupling dominates"),
        "{}",
        strong.solver_reason
    );
    let direct = solve(
        &sequence,
        FlowParams {
            solver: SolverChoice::Direct,
            ..FlowParams::paper(1e-3, 0.0, 0.1)
        },
    );
    assert!(strong.relative_residual <= 1e-8);
    let difference = flow_difference(&direct, &strong);
    assert!(difference < 1e-6, "relative difference {difference:e}");
}

/// `‖u_a − u_b‖ / ‖u_a‖` over all slabs and vertices.
fn flow_difference(a: &FlowResult, b: &FlowResult) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for (sa, sb) in a.intrinsic.iter().zip(&b.intrinsic) {
        for (va, vb) in sa.iter().zip(sb) {
            diff += (va - vb).norm_squared();
            norm += va.norm_squared();
        }
    }
    (diff / norm).sqrt()
}

#[test]
fn slabs_share_factors_beyond_the_memory_budget() {
    let sequence = stretching_sphere(9);
    let with_budget = |bytes, solver| {
        let params = FlowParams {
            solver,
            direct_limit: 0,
            factor_memory_limit: bytes,
            tolerance: 1e-12,
            ..FlowParams::paper(0.1, 0.0, 0.1)
        };
        solve(&sequence, params)
    };
    let direct = with_budget(usize::MAX, SolverChoice::Direct);
    let all = with_budget(usize::MAX, SolverChoice::PcgSlabGaussSeidel);
    assert!(
        all.solver_reason
            .contains("one factor per slab in single precision"),
        "{}",
        all.solver_reason
    );
    // The fine level gets half the budget. Single-precision factors (4 bytes per entry) of
    // all 8 slabs need more than that, bfloat16 ones (2 bytes) fit: one factor per slab.
    let one_factor = all.factor_entries / 8;
    let compressed = with_budget(2 * 8 * 3 * one_factor, SolverChoice::PcgSlabGaussSeidel);
    assert!(
        compressed
            .solver_reason
            .contains("one factor per slab in bfloat16"),
        "{}",
        compressed.solver_reason
    );
    assert_eq!(compressed.factor_entries, all.factor_entries);
    assert_same_intrinsic_flow(&direct, &compressed);
    // Multigrid over bfloat16 fine factors keeps its levels in bfloat16.
    let levels = with_budget(2 * 8 * 3 * one_factor, SolverChoice::PcgTimeMultigrid);
    assert!(
        levels
            .solver_reason
            .ends_with("the levels' factors in bfloat16"),
        "{}",
        levels.solver_reason
    );
    assert_same_intrinsic_flow(&direct, &levels);
    // 3.5 bfloat16 factors in half the budget: runs of 3 slabs share one.
    let shared = with_budget(2 * 7 * one_factor, SolverChoice::PcgSlabGaussSeidel);
    assert!(
        shared.solver_reason.contains("3 neighbouring slabs share"),
        "{}",
        shared.solver_reason
    );
    assert_same_intrinsic_flow(&direct, &shared);
    // Not even one factor fits: Jacobi, and it says why.
    let none = with_budget(1000, SolverChoice::Auto);
    assert_eq!(none.method, SolverMethod::PcgJacobi);
    assert!(
        none.solver_reason.contains("does not fit"),
        "{}",
        none.solver_reason
    );
    assert_same_intrinsic_flow(&direct, &none);
}

#[test]
fn forced_iterative_solvers_on_uncoupled_slabs_are_exact_slab_solves() {
    let sequence = stretching_sphere(5);
    let params = |solver| FlowParams {
        solver,
        tolerance: 1e-12,
        ..FlowParams::paper(f64::INFINITY, 0.0, 0.1)
    };
    let slabwise = solve(&sequence, params(SolverChoice::Auto));
    assert_eq!(slabwise.method, SolverMethod::SlabwiseDirect);
    // Factors this small keep single precision on every level (bfloat16 levels, which solve a
    // slab to about 2⁻⁹, took up to 6 iterations here): single-precision slab solves, refined
    // to 1e-12 in a few iterations.
    for (solver, most) in [
        (SolverChoice::PcgTimeMultigrid, 3),
        (SolverChoice::PcgSlabGaussSeidel, 3),
    ] {
        let iterative = solve(&sequence, params(solver));
        assert!(
            iterative.iterations <= most,
            "{solver:?}: {}",
            iterative.iterations
        );
        assert_same_intrinsic_flow(&slabwise, &iterative);
    }
}

/// An observer that asks to stop ends the solve with `FlowError::Interrupted` right after the
/// event it was asked at; a closure observer never stops.
#[test]
fn an_observer_can_interrupt_the_solve() {
    use meshflow::flow::{FlowError, FlowProblem, SolveEvent, SolveObserver};
    use std::sync::atomic::{AtomicUsize, Ordering};

    struct StopAfter(usize, AtomicUsize);
    impl SolveObserver for StopAfter {
        fn event(&self, event: SolveEvent) {
            if let SolveEvent::Iteration { .. } = event {
                self.1.fetch_add(1, Ordering::SeqCst);
            }
        }
        fn interrupted(&self) -> bool {
            self.1.load(Ordering::SeqCst) >= self.0
        }
    }
    let sequence = rotating_sphere(3, 4, 1.0, 0.05).unwrap().sequence;
    let params = FlowParams {
        solver: SolverChoice::PcgJacobi,
        tolerance: 1e-12,
        ..FlowParams::paper(1.0, 0.0, 1e-4)
    };
    let problem = FlowProblem::new(&sequence, &params).unwrap();
    let observer = StopAfter(3, AtomicUsize::new(0));
    assert_eq!(
        problem.solve(&observer).unwrap_err(),
        FlowError::Interrupted
    );
    assert_eq!(observer.1.load(Ordering::SeqCst), 3);
    let finished = problem.solve(&|_| {}).unwrap();
    assert!(finished.iterations > 3 && finished.relative_residual <= 1e-12);
}

/// A recording that is dark over most of the surface (texture only on a cap, as in a
/// fluorescence recording): there only `γ L` and the time coupling remain, and the coupling
/// dominates. Multigrid in time still converges in a few iterations, for two slabs (which the
/// first release's chunked sweeps turned into block Jacobi on 2 cores: the zebrafish
/// recording took 158 iterations) and for four, and agrees with the direct solver.
#[test]
fn multigrid_converges_where_the_image_is_dark() {
    let surface = meshflow::shapes::icosphere(3);
    for frames in [3, 5] {
        let sequence = still_sequence(&surface, frames, |p, k| {
            let t = 0.05 * k as f64;
            match p.z > 0.6 {
                true => (p.z - 0.6) * (9.0 * (p.x + t)).sin() * (7.0 * p.y).cos(),
                false => 0.0,
            }
        });
        for alpha in [0.1, 0.01] {
            let params = |solver| FlowParams {
                solver,
                tolerance: 1e-12,
                ..FlowParams::paper(alpha, 0.0, 0.01)
            };
            let direct = solve(&sequence, params(SolverChoice::Direct));
            let multigrid = solve(&sequence, params(SolverChoice::PcgTimeMultigrid));
            println!(
                "{frames} frames, α = {alpha}: {} iterations",
                multigrid.iterations
            );
            assert!(
                multigrid.iterations <= 12,
                "{frames} frames, α = {alpha}: {} iterations",
                multigrid.iterations
            );
            assert_same_intrinsic_flow(&direct, &multigrid);
        }
    }
}

/// Where the time coupling dominates, slab Gauss–Seidel's first iteration leaves more than
/// the starting residual (the paper's torus, grey values in [0, 1], `α = 0.01`: about 4×):
/// `auto` leaves it there instead of probing 3 more, and multigrid from that iterate needs at
/// most one iteration more than multigrid alone.
#[test]
fn auto_leaves_gauss_seidel_after_an_iteration_without_progress() {
    let (n1, n2, frames) = (32, 24, 6);
    let raw = meshflow::synth::paper_torus(n1, n2, frames).unwrap();
    let max = (0..frames)
        .flat_map(|k| raw.intensities(k).iter().copied())
        .fold(0.0, f64::max);
    let sequence = MeshSequence::new(
        raw.mesh().clone(),
        (0..frames)
            .map(|k| raw.positions(k).unwrap().to_vec())
            .collect(),
        (0..frames)
            .map(|k| raw.intensities(k).iter().map(|v| v / max).collect())
            .collect(),
        None,
    )
    .unwrap();
    let params = |solver| FlowParams {
        solver,
        direct_limit: 0,
        ..FlowParams::paper(0.01, 0.0, 1.0)
    };
    let auto = solve(&sequence, params(SolverChoice::Auto));
    let multigrid = solve(&sequence, params(SolverChoice::PcgTimeMultigrid));
    let direct = solve(&sequence, params(SolverChoice::Direct));
    assert_eq!(auto.method, SolverMethod::PcgTimeMultigrid);
    assert!(
        auto.solver_reason
            .contains("times the starting residual after 1 iteration, no progress"),
        "{}",
        auto.solver_reason
    );
    println!(
        "auto {} iterations (1 of Gauss-Seidel), multigrid alone {}",
        auto.iterations, multigrid.iterations
    );
    assert!(auto.iterations <= multigrid.iterations + 1);
    let difference = flow_difference(&direct, &auto);
    assert!(difference < 1e-6, "relative difference {difference:e}");
}

/// The flow of `params` on `sequence` from zero, and warm-started from it 1 % off (as the next
/// solve of a warping run starts), with both runs' iterations printed.
fn cold_and_warm(sequence: &MeshSequence, params: &FlowParams) -> (FlowResult, FlowResult) {
    let problem = FlowProblem::new(sequence, params).unwrap();
    let cold = problem.solve(&|_| {}).unwrap();
    let mut nearby = cold.clone();
    (nearby.intrinsic.iter_mut().flatten()).for_each(|u| *u *= 1.01);
    let warm = problem.solve_from(Some(&nearby), &|_| {}).unwrap();
    println!(
        "{} iterations from zero ({}), {} from 1 % off ({})",
        cold.iterations, cold.solver_reason, warm.iterations, warm.solver_reason
    );
    (cold, warm)
}

/// A warm start ([`FlowProblem::solve_from`]): from the solution itself the solve returns it
/// without an iteration (nothing factored); from a nearby flow it converges to the same flow in
/// fewer iterations than from zero, and `auto`'s probe does not read the start's slower rate as
/// a reason to leave slab Gauss–Seidel. Multigrid in time starts there too.
#[test]
fn a_warm_start_converges_to_the_same_flow_in_fewer_iterations() {
    let sequence = rotating_sphere(3, 9, 1.0, 0.05).unwrap().sequence;
    for solver in [SolverChoice::Auto, SolverChoice::PcgTimeMultigrid] {
        let params = FlowParams {
            solver,
            direct_limit: 0,
            tolerance: 1e-10,
            ..FlowParams::paper(1.0, 0.0, 0.1)
        };
        let (cold, warm) = cold_and_warm(&sequence, &params);
        assert_eq!(warm.method, cold.method, "{}", warm.solver_reason);
        assert!(warm.relative_residual <= 1e-10);
        assert!(warm.iterations < cold.iterations, "{solver:?}");
        assert_same_intrinsic_flow(&cold, &warm);
        let problem = FlowProblem::new(&sequence, &params).unwrap();
        let solved = problem.solve_from(Some(&cold), &|_| {}).unwrap();
        assert_eq!(solved.iterations, 0, "{solver:?}");
        assert_eq!(solved.intrinsic, cold.intrinsic);
        assert_eq!(solved.factor_entries, 0, "nothing factored");
        assert!(solved.relative_residual <= 1e-10);
        let reason = &solved.solver_reason;
        assert!(reason.contains("already meets the tolerance"), "{reason}");
    }
}

/// Where the previous solve needed multigrid in time, `auto` starts the next one with it
/// instead of probing slab Gauss–Seidel again (the probe's iterations would be spent to find
/// the same): the strong time coupling of `auto_adds_time_levels_only_when_gauss_seidel_is_slow`.
#[test]
fn auto_goes_straight_to_multigrid_after_a_solve_that_needed_it() {
    let sequence = rotating_sphere(3, 17, 1.0, 0.05).unwrap().sequence;
    let params = FlowParams {
        direct_limit: 0,
        ..FlowParams::paper(1e-3, 0.0, 0.1)
    };
    let (cold, warm) = cold_and_warm(&sequence, &params);
    assert_eq!(cold.method, SolverMethod::PcgTimeMultigrid);
    assert!(cold.solver_reason.contains("slab Gauss-Seidel"));
    assert_eq!(warm.method, SolverMethod::PcgTimeMultigrid);
    let reason = &warm.solver_reason;
    assert!(reason.starts_with("the run's previous solve needed multigrid in time"));
    assert!(warm.iterations < cold.iterations);
    assert!(warm.relative_residual <= params.tolerance);
    let difference = flow_difference(&cold, &warm);
    assert!(difference < 1e-6, "relative difference {difference:e}");
}
