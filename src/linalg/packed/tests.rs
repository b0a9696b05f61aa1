//! Tests of the packed factors' solves, and the test blocks the bfloat16 tests share.

use super::*;
use crate::linalg::bfloat::{Bf16Factor, DROP_TOLERANCE};
use crate::linalg::cholesky::analyze;
use crate::linalg::factor::SlabFactor;
use faer::sparse::{SparseColMat, Triplet};
use faer::Par;
use rayon::prelude::*;

/// A connection Laplacian plus mass on an `n1 × n2` periodic grid (two DOFs per vertex,
/// each edge's block a rotation, as for tangent fields), `diagonal` on the diagonal
/// (`4 + mass`): symmetric positive definite.
pub(crate) fn grid_block(n1: usize, n2: usize, diagonal: f64) -> SparseColMat<usize, f64> {
    let vertex = |i: usize, j: usize| (i % n1) * n2 + j % n2;
    let mut triplets = Vec::new();
    for i in 0..n1 {
        for j in 0..n2 {
            let v = vertex(i, j);
            for d in 0..2 {
                triplets.push(Triplet::new(2 * v + d, 2 * v + d, diagonal));
            }
            for (k, w) in [vertex(i + 1, j), vertex(i, j + 1)].into_iter().enumerate() {
                let angle = 0.3 * (v + k) as f64;
                let (c, s) = (angle.cos(), angle.sin());
                for (a, b, x) in [(0, 0, c), (0, 1, -s), (1, 0, s), (1, 1, c)] {
                    triplets.push(Triplet::new(2 * v + a, 2 * w + b, -x));
                    triplets.push(Triplet::new(2 * w + b, 2 * v + a, -x));
                }
            }
        }
    }
    SparseColMat::try_new_from_triplets(2 * n1 * n2, 2 * n1 * n2, &triplets).unwrap()
}

/// The `f32` factor of [`grid_block`] with a small mass (diagonal 4.1): `L` decays slowly.
pub(crate) fn grid_factor(n1: usize, n2: usize) -> CholeskyFactor<f32> {
    mass_factor(n1, n2, 4.1)
}

/// The `f32` factor of [`grid_block`].
pub(crate) fn mass_factor(n1: usize, n2: usize, diagonal: f64) -> CholeskyFactor<f32> {
    let block = grid_block(n1, n2, diagonal);
    let symbolic = analyze(block.symbolic(), 2);
    CholeskyFactor::<f32>::new(&symbolic, block.as_ref(), Par::Seq).unwrap()
}

/// `sin(0.37 (i + shift))` for `i < n`: a right-hand side with every column's share.
pub(crate) fn sines(n: usize, shift: usize) -> Vec<f64> {
    (0..n).map(|i| (0.37 * (i + shift) as f64).sin()).collect()
}

/// `‖x − y‖ / ‖y‖`.
pub(crate) fn relative_difference(x: &[f64], y: &[f64]) -> f64 {
    let squared: f64 = x.iter().zip(y).map(|(x, y)| (x - y) * (x - y)).sum();
    (squared / y.iter().map(|y| y * y).sum::<f64>()).sqrt()
}

/// `factor`'s values widened to `f64`: the reference solves with the same `L`.
fn widened(factor: &CholeskyFactor<f32>) -> CholeskyFactor<f64> {
    let values = factor.values().iter().map(|&v| f64::from(v)).collect();
    CholeskyFactor::from_parts(factor.symbolic().clone(), values)
}

/// The width of each supernode of a factor (none for the simplicial layout).
fn widths_of(factor: &CholeskyFactor<f32>) -> impl Iterator<Item = usize> + '_ {
    let supernodal = match factor.symbolic().raw() {
        SymbolicCholeskyRaw::Supernodal(s) => Some(s),
        SymbolicCholeskyRaw::Simplicial(_) => None,
    };
    (supernodal.into_iter())
        .flat_map(|s| (s.supernode_begin().iter().zip(s.supernode_end())).map(|(b, e)| e - b))
}

/// The supernode widths of a factor.
fn widths(factor: &CholeskyFactor<f32>) -> std::collections::BTreeSet<usize> {
    widths_of(factor).collect()
}

/// The packed `f32` solve equals the double-precision solve with the same `L`, up to `f32`
/// rounding, with the portable kernels and with the processor's, the tree split over two
/// threads and not: on a grid block whose
/// supernodes take every path (one to four columns, wider ones with a remainder after the
/// blocks of four), and on a small simplicial one.
#[test]
fn f32_solves_as_the_same_factor_in_double_precision() {
    for (n1, n2) in [(64, 48), (8, 6)] {
        let factor = grid_factor(n1, n2);
        let shapes = widths(&factor);
        if n1 > 8 {
            let remainder = shapes.iter().any(|&w| w > 4 && w % 4 != 0);
            assert!(
                (1..=5).all(|w| shapes.contains(&w)) && remainder,
                "widths {shapes:?}"
            );
        } else {
            assert!(shapes.is_empty(), "a simplicial factor");
        }
        let reference = widened(&factor);
        let b = sines(factor.symbolic().nrows(), 0);
        let mut expected = b.clone();
        reference.solve_in_place(&mut expected, Par::Seq);
        for kernels in [Kernels::Portable, Kernels::detect()] {
            let packed = PackedFactor {
                kernels,
                ..PackedFactor::new(factor.clone())
            };
            for halves in [Halves::Parallel, Halves::Sequential] {
                let mut x = b.clone();
                packed.solve_in_place(&mut x, &mut Vec::new(), halves);
                let relative = relative_difference(&x, &expected);
                let case = format!("{n1}×{n2}, {kernels:?}, {halves:?}");
                assert!(relative < 1e-5, "{case}: {relative:e}");
            }
        }
    }
}

/// Bytes `factor` holds (its entries and which rows it keeps).
fn held_bytes<E: Entry>(factor: &PackedFactor<E>) -> usize {
    let kept = factor.kept.as_ref().map_or(0, |k| {
        8 * (k.bits.len() + k.word_start.len() + k.value_start.len()) + 4 * k.rows.len()
    });
    E::BYTES * factor.values.len() + kept
}

/// The entries faer stores in the upper halves of the wide supernodes' triangles, which the
/// blocked layout leaves out ([`layout`]).
fn unused_upper_halves(factor: &CholeskyFactor<f32>) -> usize {
    widths_of(factor)
        .filter(|&w| layout::is_wide(w))
        .map(|w| w * w - layout::triangle_entries(w))
        .sum()
}

/// A factor's bytes stay within [`PackedFactor::bytes_at_most`], the memory budget's count:
/// in bfloat16 with nothing dropped and in `f32` (every entry but the triangles' unused upper
/// halves stored), and in bfloat16 with most rows dropped (about half of it).
#[test]
fn bytes_stay_within_the_budget_count() {
    for (diagonal, tolerance) in [(4.1, 0.0), (40.0, DROP_TOLERANCE)] {
        let factor = mass_factor(64, 48, diagonal);
        let bound = Bf16Factor::bytes_at_most(factor.symbolic());
        let packed = Bf16Factor::packing(factor.symbolic(), factor.values(), tolerance);
        let bytes = held_bytes(&packed);
        match tolerance == 0.0 {
            true => {
                let stored = factor.values().len() - unused_upper_halves(&factor);
                assert_eq!(packed.values.len(), stored, "diagonal {diagonal}");
                assert!(bytes <= bound, "diagonal {diagonal}: {bytes} of {bound}");
            }
            false => assert!(
                3 * bytes < 2 * bound,
                "diagonal {diagonal}: {bytes} of {bound}"
            ),
        }
    }
    let factor = grid_factor(64, 48);
    let bound = PackedFactor::<f32>::bytes_at_most(factor.symbolic());
    let packed = PackedFactor::new(factor.clone());
    let stored = factor.values().len() - unused_upper_halves(&factor);
    assert_eq!(packed.values.len(), stored);
    assert!(held_bytes(&packed) <= bound);
}

/// On a nested-dissection order the elimination tree splits into two subtrees of at least
/// a tenth of the entries each, and the solve over them on two threads equals the
/// sequential one up to `f32` rounding (the subtrees' sums on the top's columns are added
/// in another order).
#[test]
fn two_subtrees_solve_as_one() {
    let factor = grid_factor(64, 48);
    let split = PackedFactor::new(factor.clone());
    let parts = split.split.clone().expect("a grid's tree splits in two");
    let entries = |r: &Range<usize>| match factor.symbolic().raw() {
        SymbolicCholeskyRaw::Supernodal(s) => {
            s.col_ptr_for_val()[r.end] - s.col_ptr_for_val()[r.start]
        }
        _ => unreachable!(),
    };
    let all = split.values.len();
    for part in [&parts.first, &parts.second] {
        assert!(10 * entries(part) >= all, "{part:?} holds too few of {all}");
    }
    let b = sines(factor.symbolic().nrows(), 0);
    let (mut x, mut y) = (b.clone(), b);
    split.solve_in_place(&mut x, &mut Vec::new(), Halves::Parallel);
    split.solve_in_place(&mut y, &mut Vec::new(), Halves::Sequential);
    let largest = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let difference = (x.iter().zip(&y)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        difference <= 1e-5 * largest,
        "differs by {difference:e} of {largest:e}"
    );
}

/// Slab solves from a parallel loop, each splitting its tree over two threads
/// (`rayon::join`): a thread waiting for its other half runs another slab's solve, which
/// must not find the thread's scratch buffer borrowed ("RefCell already borrowed" on 16
/// threads before the buffer was taken out for the solve). Each result equals the lone
/// solve's exactly.
#[test]
fn nested_solves_on_one_thread_share_no_scratch() {
    let grid = grid_factor(64, 48);
    let factor = Bf16Factor::rounding(grid.symbolic(), grid.values());
    assert!(factor.split.is_some(), "the solve splits its tree");
    let n = factor.symbolic.nrows();
    let lone: Vec<Vec<f64>> = (0..64)
        .map(|k| {
            let mut x = sines(n, k);
            factor.solve_in_place(&mut x, &mut Vec::new(), Halves::Parallel);
            x
        })
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(8)
        .build()
        .unwrap();
    for _ in 0..20 {
        let solved: Vec<Vec<f64>> = pool.install(|| {
            (0..64)
                .into_par_iter()
                .map(|k| {
                    let mut x = sines(n, k);
                    SlabFactor::solve(&factor, &mut x, Halves::Parallel);
                    x
                })
                .collect()
        });
        assert_eq!(solved, lone);
    }
}

/// Timing of slab solves: faer's `f32` solve against the packed `f32` factor's (the
/// processor's kernels with the tree split and without, the portable kernels) and the bfloat16
/// factor's (split and not), on the paper-size slab block (255×190 torus, `α = γ = 1`), on the
/// 128×95 torus's block at `α = γ = 0.01` (the blocks of multigrid's levels, whose bfloat16
/// factors keep a third of their entries) and on grid blocks whose `L` decays slowly (diagonal
/// 4.1: little drops) and fast (40). Copies of each factor (more than the last-level cache
/// holds) are solved in turn on each of two threads, each thread half the copies ahead of the
/// other; the fastest of 12 interleaved rounds
/// (`cargo test --release --lib packed::tests::timing -- --ignored --nocapture`).
///
/// As the solver runs them: factored and solved with subnormal numbers flushed
/// ([`crate::subnormals`]), each solve from the same right-hand side. Unflushed, on a
/// processor that takes a microcode assist per subnormal operand (2026-11-29), the small
/// blocks' `f32` factors, whose `L` decays into that range, solved 2–2.5 times slower (128×95
/// torus at `α = γ = 0.01` 5.57 against 2.28 ms, grid with diagonal 4.1 2.98 against 1.61 ms).
#[test]
#[ignore]
fn timing() {
    crate::subnormals::flushed(timed_factors)
}

fn timed_factors() {
    let paper = torus_slab_factor(255, 190, crate::flow::FlowParams::paper(1.0, 0.0, 1.0));
    time_solves("paper-size slab", &paper, 8);
    // The coarse levels' kind of block: multigrid streams 41 such factors per cycle.
    let small = torus_slab_factor(128, 95, crate::flow::FlowParams::paper(0.01, 0.0, 0.01));
    time_solves("128×95 torus slab, α = γ = 0.01, 40 copies", &small, 40);
    for diagonal in [4.1, 40.0] {
        let name = format!("128×95 grid, diagonal {diagonal}");
        time_solves(&name, &mass_factor(128, 95, diagonal), 40);
    }
}

/// The `f32` factor of the second slab block of the paper's torus (`n1 × n2`, three frames).
fn torus_slab_factor(n1: usize, n2: usize, params: crate::flow::FlowParams) -> CholeskyFactor<f32> {
    let sequence = crate::synth::paper_torus(n1, n2, 3).unwrap();
    let problem = crate::flow::FlowProblem::new(&sequence, &params).unwrap();
    let system = problem.system();
    CholeskyFactor::<f32>::new(system.slab_symbolic(), system.block(1), Par::Seq).unwrap()
}

/// A timed solve: with copy `k` of a factor, on `x`, with `work`.
type Solve<'a> = dyn Fn(usize, &mut [f64], &mut Vec<f32>) + Sync + 'a;

fn time_solves(name: &str, factor: &CholeskyFactor<f32>, copies: usize) {
    let n = factor.symbolic().nrows();
    let faer: Vec<CholeskyFactor<f32>> = vec![factor.clone(); copies];
    let packed: Vec<PackedFactor<f32>> = faer.iter().cloned().map(PackedFactor::new).collect();
    let portable: Vec<PackedFactor<f32>> = (faer.iter().cloned())
        .map(|f| PackedFactor {
            kernels: Kernels::Portable,
            ..PackedFactor::new(f)
        })
        .collect();
    let bf16: Vec<Bf16Factor> = packed
        .iter()
        .map(|f| Bf16Factor::rounding(f.symbolic(), &f.column_major_values()))
        .collect();
    let time = |solve: &Solve<'_>| {
        let start = std::time::Instant::now();
        // Half the copies apart: two threads reading one factor at once would share the
        // last-level cache and read it from memory once.
        (0..2).into_par_iter().for_each(|thread| {
            // Each solve from the same right-hand side: solving on the last solve's result
            // would scale it by up to the block's inverse eigenvalues each time, into
            // subnormal or infinite numbers whose arithmetic costs differently.
            let (b, mut x, mut work) = (sines(n, 0), vec![0.0; n], Vec::new());
            let first = thread * copies / 2;
            (0..2 * copies).for_each(|k| {
                x.copy_from_slice(&b);
                solve((first + k) % copies, &mut x, &mut work)
            });
        });
        start.elapsed().as_secs_f64() * 1e3 / (2 * copies) as f64
    };
    use Halves::{Parallel, Sequential};
    let solves: [(&str, &Solve<'_>); 6] = [
        ("faer f32", &|k, x, _| faer[k].solve_in_place(x, Par::Seq)),
        ("packed f32", &|k, x, w| {
            packed[k].solve_in_place(x, w, Sequential)
        }),
        ("split", &|k, x, w| packed[k].solve_in_place(x, w, Parallel)),
        ("portable", &|k, x, w| {
            portable[k].solve_in_place(x, w, Sequential)
        }),
        ("bfloat16", &|k, x, w| {
            bf16[k].solve_in_place(x, w, Sequential)
        }),
        ("split", &|k, x, w| bf16[k].solve_in_place(x, w, Parallel)),
    ];
    let mut fastest = [f64::INFINITY; 6];
    for _ in 0..12 {
        for (fastest, (_, solve)) in fastest.iter_mut().zip(&solves) {
            *fastest = fastest.min(time(solve));
        }
    }
    let times: Vec<String> = (solves.iter().zip(fastest))
        .map(|((name, _), ms)| format!("{name} {ms:.2}"))
        .collect();
    println!(
        "{name}: {} entries ({} in bfloat16), {:?}; ms per solve on each of 2 threads: {}",
        packed[0].values.len(),
        bf16[0].values.len(),
        Kernels::detect(),
        times.join(", ")
    );
}
