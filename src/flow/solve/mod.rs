//! Solving `A u = b` for the space-time system.
//!
//! `A` is block-tridiagonal in time: diagonal blocks `D_s` (slab `s`'s data, speed and spatial
//! smoothness, plus the diagonal parts of its time links) and links `X_s` between slabs `s`
//! and `s + 1`. The link weight is `γ / (α² h)`: a small `α` or a short frame spacing `h`
//! makes the time coupling dominate.
//!
//! - **Direct**: one sparse Cholesky of the whole system. Exact, but the factor of a
//!   space-time system grows far faster than the system; `auto` uses it up to
//!   `FlowParams::direct_limit` unknowns.
//! - **Slab-wise direct** (`α = ∞`): the slabs decouple; one factorization per slab.
//! - **PCG with slab Gauss–Seidel**: conjugate gradients preconditioned by a symmetric block
//!   Gauss–Seidel sweep in time whose blocks are exact per-slab Cholesky factors (one symbolic
//!   analysis with a METIS nested-dissection ordering, numeric factorizations in parallel,
//!   stored in single precision: half the memory and memory traffic, CG itself runs in double
//!   precision). The sweep runs in odd–even order ([`precondition::SlabSweeps`]): all even
//!   slabs at once, then all odd ones, so it is parallel in time and the same preconditioner
//!   however many cores share the work. PCG runs on the odd slabs alone, the even ones
//!   eliminated ([`reduced`]): the same spectrum as the sweep's, but each slab solved once an
//!   iteration instead of the even ones twice, in two rounds of refinement that make up for
//!   the `f32` factors' inexact elimination (paper-size frames: 19 → 20 iterations, the
//!   iterations' time 15–20 % less). The slab solves handle the spatial coupling exactly,
//!   so iteration counts stay flat under spatial refinement. The error they leave is smooth in
//!   time, and when the time coupling dominates that error dominates: 166 iterations at
//!   `α = 0.1` on the 128×95×20 torus.
//! - **PCG with multigrid in time** ([`multigrid`]): a V-cycle whose smoother is the slab
//!   sweep and whose coarse levels merge slab pairs (semi-coarsening in time) with the
//!   Galerkin operator of the transported prolongation `u_{2k+1} = T_k ũ_k`, less half the
//!   coarse links' coupling energy (a coarse slab spans twice the time step: see "Coarse levels
//!   at twice the time step" below). It represents the smooth-in-time error on the coarse
//!   levels whatever the ratio of temporal to spatial coupling. A V-cycle costs about 3
//!   Gauss–Seidel sweeps (0.17 against 0.052 s per iteration on the 128×95×20 torus: the
//!   coarse levels hold as many blocks again) and the coarse blocks need factors too.
//! - **PCG with Jacobi**: no factors; only when not even one slab factor fits the budget.
//!
//! **Factor precision** ([`crate::linalg::factor`]). Slab Gauss–Seidel solves with `f32`
//! factors while those of all slabs fit half of `FlowParams::factor_memory_limit`, and with
//! bfloat16 factors ([`crate::linalg::bfloat`]: 2 bytes an entry) beyond that, so that long
//! sequences keep one factor per slab instead of sharing one between neighbours. Both are
//! solved by meshflow's own supernodal kernels ([`crate::linalg::packed`]: 20–45 % faster than
//! faer's `f32` solve, AVX2 + FMA where the processor has them; double precision stays
//! faer's). Multigrid's levels use bfloat16 unless all their `f32`
//! factors together fit [`CACHED_LEVELS_BYTES`] (64 MiB: then they are read largely from the
//! caches, and rounding would only cost iterations): the fine factors are rounded when `auto`
//! switches, the coarse ones right after their `f32` factorization. A slab
//! solve streams its factor twice, so bfloat16 solves take 0.8–1.0 ms against `f32`'s
//! 1.3–1.5 ms (12,160-vertex grid block, one solve on each of the 2 cores; `cargo test
//! --release --lib packed::tests::timing -- --ignored --nocapture`).
//! Rounding `L` to 8 significant bits leaves multigrid's iterations as they were (the table
//! below: the same counts, one more at `α = 0.001`), because where multigrid is needed the
//! coarse levels, not the slab solves, limit its rate. Where the slab solves nearly solve the
//! system (large `α`), the rounding is what the iterations must remove: slab Gauss–Seidel at
//! `α = 10`, `γ = 1` took 7 iterations with bfloat16 against 3 with `f32`, and 21 against 19 at
//! `α = 1` (`γ = 0.01`: 5 against 2, 8 against 8), which is why it keeps `f32` while that fits.
//! Double precision remains the fallback when a block is too ill-conditioned for `f32`.
//! Measured at 200 frames × 48,450 vertices (`bench_paper_torus -- 255 190 200`, 2 cores,
//! 8.8 GB budget): one bfloat16 factor per slab instead of one `f32` factor per two slabs,
//! 7 iterations instead of 11, solve 34.1 → 28.2 s with the same peak memory (8.18 GB).
//! Where a cycle is nearly exact the rounding shows: on the zebrafish recording (2 slabs) with
//! `--large-motion --regularizer strain`, bfloat16 levels took 98 iterations in 8 solves
//! instead of 76 (3.4 s against 3.2 s; 81 once `auto` left a probe without progress early,
//! below). Its 3 factors take 29 MB in `f32`, so its levels now stay in `f32`: 54 iterations,
//! 3.3–3.7 s (bfloat16: 3.4–3.7 s); the default solve keeps 9 (4 + 5) and multigrid alone 6.
//! Bfloat16 factors also leave out the rows of `L` below a supernode whose entries are all
//! under `2⁻¹⁰` of their pivot ([`crate::linalg::bfloat::DROP_TOLERANCE`]): where the time
//! coupling dominates the blocks (small `α`, exactly where multigrid runs) `L` decays fast and
//! more than half of it drops, so a V-cycle reads about half as much, with the same iterations
//! (the iterations' time falls by 22–30 %, less than the bytes: the many one-vertex supernodes'
//! per-row work and the residual products stay).
//!
//! Every method runs with subnormal numbers flushed to zero ([`crate::subnormals`]): at
//! mid-range `α` up to 4 % of the single-precision factors' entries are subnormal otherwise
//! (`bench_solver`'s `subnormal` column with `SUBNORMALS=keep`), which made the factorization 5×
//! slower on a processor that assists every subnormal operand in microcode.
//!
//! `auto` starts slab Gauss–Seidel and, from [`PROBE_ITERATIONS`] on, projects the iterations
//! to the tolerance at the rate of the last few; once they exceed [`SWITCH_ITERATIONS`] (less
//! the probe's) it factors the coarse levels and continues with multigrid from the current
//! iterate. During the probe it leaves only when the residual has not fallen below its start
//! ([`pcg::Projection::gives_up`]): at `α ≤ 0.1` on the torus below, slab Gauss–Seidel's
//! first iteration leaves 1.5–3.6 times the starting residual, and multigrid needs as many
//! iterations after one Gauss–Seidel iteration as after four (13 → 10 at `α = 0.01`, `γ = 1`;
//! 15 → 12 at `γ = 0.01`; the warped strain solve of the zebrafish recording 98 → 81 in 8
//! solves with bfloat16 levels; its default solve, whose first iteration halves the residual,
//! keeps 9). It keeps watching after the probe because the first iterations drop faster than
//! the rest: on a 48,450-vertex torus × 40 frames with default weights (`meshflow solve` on
//! NPY arrays), slab Gauss–Seidel fell by 0.53 per iteration over iterations 1–4 (29.7
//! projected in all, within the limit) and by 0.87 over 5–8; `auto` ran it to the end, 72
//! iterations and 39.7 s. Now it leaves after iteration 5 (rate 0.71, 47 more projected) and
//! converges with multigrid: 5 + 10 iterations, 26.9 s (multigrid alone: 10, 25.7 s). The
//! torus table below, the zebrafish recording and the 100-frame torus choose as before (the
//! rule at iteration 4 is the old one). Slab factors beyond
//! `FlowParams::factor_memory_limit` are shared: runs of neighbouring slabs use the factor of
//! their mean block, so memory stays within the budget however long the sequence (at the
//! price of a weaker preconditioner). Every solution says why its method was chosen
//! ([`Solution::reason`]).
//!
//! **Warm starts** ([`WarmStart`]). The solves of a run (coarse-to-fine warping, robust
//! reweighting) start from the previous solve's flow: a start within the tolerance is the
//! solution (nothing factored), the probe does not give up during its first iterations from a
//! start (CG may raise the residual's norm first), and `auto` goes straight to multigrid where
//! the previous solve needed it. Paper size with `--large-motion`: 184 → 124 iterations in 8
//! solves; the zebrafish recording's robust run 63 → 38 in 7 (docs/scaling.md, "Warm starts
//! across a run's solves").
//!
//! **Factors handed on** ([`run`]). A run's solves recycle their `f32` factors' buffers, and a
//! warping level's next warp, whose system differs by the re-linearized data term alone, is
//! preconditioned with the last warp's factors instead of its own (slab Gauss–Seidel's sweeps
//! or all of multigrid's levels): about as many iterations, no factorization. `--large-motion`
//! on the Stanford bunny sequence 45.4 → 38.3 s (docs/scaling.md, "Factors kept for a level's
//! next warp").
//!
//! Measured on the 128×95 torus × 20 frames (`synth::paper_torus` geometry, grey values in
//! [0, 1], tolerance 1e-8, 2 cores; `cargo run --release --example bench_solver [-- 128 95 20
//! SOLVER]`): iterations, then solve seconds including factorization. Before the odd–even
//! sweeps (first line of a cell where they differ) and with them (second):
//!
//! | α | γ = 1, slab GS | γ = 1, `auto` | γ = 1, MG | γ = 0.01, `auto` | γ = 0.01, MG |
//! |---|---|---|---|---|---|
//! | ∞ | 1 (direct) | 1, 1.0 s; 1, 0.4 s (slab-wise) | – | 1, 0.9 s; 1, 0.4 s | – |
//! | 10 | 2; 3 | 4, 1.0 s; 3, 0.5 s | 3 | 3, 0.8 s; 2, 0.4 s | 2 |
//! | 1 | 12; 19 | 18, 2.4 s; 19, 1.3 s (GS) | 7; 8 | 9, 1.9 s; 8, 0.8 s (GS) | 5 |
//! | 0.1 | 87; 166 | 19, 6.1 s; 19, 3.8 s (MG) | 15; 16 | 15, 4.6 s; 16, 3.4 s (MG) | 13 |
//! | 0.01 | 804; – | 21, 7.0 s; 22, 4.1 s (MG) | 17; 17 | 21, 6.3 s; 21, 4.0 s (MG) | 17 |
//! | 0.001 | – | 19, 5.1 s; 20, 4.0 s (MG) | 15; 15 | 20, 6.4 s; 20, 3.6 s (MG) | 14 |
//!
//! Lexicographic Gauss–Seidel alone is the better preconditioner (12 against 19 iterations at
//! `α = 1`), but odd–even sweeps run both halves in parallel and cost less per iteration;
//! multigrid's iterations did not change. `t(α = 0.01) / t(α = 1)` under `auto` is 3.1 at
//! `γ = 1` and 5 at `γ = 0.01` (target 2.5: missed; `α = 1` got faster than `α = 0.01`). Default
//! weights at 30 frames per second: 145 iterations in the first release, 16 now (4 GS + 12 MG,
//! 2.9 s).
//!
//! **Real data: the zebrafish recording** (`../shared/data/zebrafish_140_142_L6`, 3 frames ×
//! 16,251 vertices, 2 slabs, 65,004 unknowns; a fluorescence image dark and flat over most of
//! the surface). With one lexicographic chunk per core the sweeps were block *Jacobi* between
//! the two slabs (two chunks on 2 cores), and in the dark regions, where only `γ L` and the
//! coupling remain (`D_s ≈ c M + γ L`, `X_s ≈ −c M`), block Jacobi maps the error alternating
//! in time, `(e, −e)`, to about `−(e, −e)`: it does not smooth it, and the coarse level
//! (constant in time) cannot represent it. Measured: multigrid 158 iterations with chunks, 6
//! with a single chunk; factors in double instead of single precision changed nothing (157,
//! 6): the cause is the ordering, not the precision.
//!
//! | `meshflow solve DIR --out OUT …` | before | now |
//! |---|---|---|
//! | defaults | PCG, MG, 166 iterations, 3.1 s | PCG, MG, 9 iterations (4 GS + 5 MG), 0.36 s |
//! | `--time-scale 0` | slab-wise direct, 0.25 s | unchanged |
//! | `--large-motion --regularizer strain` | 225 iterations, 84.5 s | 76 iterations in 8 solves (9–10 each), 3.5 s |
//! | `--solver pcg-time-multigrid` | 158 | 6 |
//! | `--solver pcg-slab-gauss-seidel` | 366 | 186 |
//!
//! The spectrum of the preconditioned operator `M⁻¹A` there, from CG's own Lanczos
//! coefficients (`FlowResult::preconditioned_spectrum`, `summary.json`; Ritz values, tested
//! against dense eigenvalues): odd–even Gauss–Seidel `[1.2e-3, 1.0]` (κ ≈ 820: the smooth,
//! time-constant error in the dark parts, which only the coarse level sees), multigrid in time
//! `[0.886, 1.000]` (κ ≈ 1.13), Jacobi `[3.2e-4, 1.83]` (κ ≈ 5,700, 507 iterations).
//!
//! Candidates measured and rejected (128×95×20, `γ = 1`, multigrid alone, iterations at
//! `α` = 0.1 / 0.01 / 0.001): over-correcting the coarse correction by 1.4 or 1.8 (worse at
//! every `α`); transported *linear* interpolation in time, `u_{2k+1} = ½ (F ũ_k + B ũ_{k+1})`,
//! with its Galerkin operator (58 / 91 / 8, and 32 at `α = 0.01` on the 64×48 torus: it grows
//! under spatial refinement); the same with symmetric Gauss–Seidel as pre- and post-smoother
//! (41 / 66 / –). The piecewise-constant prolongation stays: 15 / 17 / 15, flat in `α` and in
//! the mesh size.
//!
//! **Coarse levels at twice the time step.** The Galerkin product of the piecewise-constant
//! prolongation keeps the fine link weight `c = γ / (α² h)` between coarse slabs, where a
//! coarse slab spans `2h` and rediscretization gives `c / 2`: each level is twice too stiff
//! in time for the error between neighbouring coarse slabs, and the V-cycle compounds that
//! level by level, so iterations grew with the number of frames (the tables above, at 20
//! frames, did not show it). Now every coarse level subtracts half of its links' coupling
//! energy (`LinkMatrix::halve` in `flow::system`: positive semidefinite, and no more than the
//! true coupling, so the coarse operators stay positive definite). Multigrid alone
//! (`--solver pcg-time-multigrid`), `α = 0.01`, `γ = 1`, 64×48 torus:
//!
//! | frames | 20 | 40 | 100 | 200 |
//! |---|---|---|---|---|
//! | Galerkin levels: iterations | 17 | 25 | 42 | 58 (19.9 s) |
//! | halved coupling: iterations | 9 | 10 | 10 | 10 (4.8 s) |
//!
//! On the 128×95×20 torus, multigrid alone at `α` = 1 / 0.1 / 0.01 / 0.001: 7 / 9 / 9 / 7
//! iterations at `γ = 1` (before: – / 16 / 17 / 15), 5 / 8 / 11 / 7 at `γ = 0.01` (– / 13 /
//! 17 / 14). Under `auto` (4 Gauss–Seidel iterations, then multigrid; solve seconds with
//! factorization): `γ = 1`: 13, 2.6 s / 13, 2.6 s / 11, 2.2 s at `α` = 0.1 / 0.01 / 0.001
//! (before 19, 3.6 s / 22, 4.0 s / 20, 3.6 s); `γ = 0.01`: 11, 2.2 s / 15, 2.9 s / 11, 2.3 s
//! (before 16, 3.0 s / 21, 3.9 s / 20, 3.7 s); default weights at 30 frames per second 12,
//! 2.5 s (before 16, 3.0 s). `t(α = 0.01) / t(α = 1)`: 1.9 at `γ = 1` (1.6 with assembly;
//! target 2.5 met), 3.9 at `γ = 0.01` (3.0 with assembly; missed: at `α = 1, γ = 0.01` slab
//! Gauss–Seidel needs 8 iterations, 0.76 s, while the coarse levels' factorizations and
//! assembly alone take about 0.6 s). Real data, Khronos `Fox.glb` (83 frames, `--intensity`),
//! multigrid alone at `--time-scale` 1 / 30 / 1000: 11 / 35 / 37 → 8 / 11 / 10 iterations.
//!
//! Consistent time coupling: a lumped link's diagonal part is `c m_i I` per vertex, which the
//! link itself bounds (`|X_ii| ≤ c m_i`), but a consistent link's is a mass matrix rotated by
//! each slab's connection, which the link does not determine. Consistent links therefore carry
//! their two diagonal parts from assembly (`ConsistentLink`: three times a link's values) and
//! halve exactly. Multigrid alone, Galerkin levels → halved: the Fox at `--time-scale` 1 / 30
//! / 1000 / 10⁴, 11 / 35 / 43 / – → 8 / 11 / 17 / 18 iterations (preconditioned spectrum at
//! 10⁴: `[0.60, 1.79]`, lumped `[0.81, 1.38]`: bounded, as the halved coarse operators are no
//! softer than half the Galerkin ones); Khronos `CesiumMan.glb` (48 frames × 2,338 vertices,
//! a grey pattern fixed in space as `--intensity`) at 1 / 30 / 1000, 11 / 28 / 32 → 9 / 11 /
//! 16 (lumped: 9 / 10 / 11); the 48,450-vertex torus × 40 frames with default weights, 14 →
//! 10 iterations, 44.3 → 39.2 s end to end, peak memory 6.5 → 8.0 GB (the parts are kept from
//! assembly on, whichever solver runs). Subtracting less than half (0.9 or 0.8 of it) is
//! far worse (264 and 354 iterations at 30): the diagonal parts then no longer cancel the
//! links for fields constant in time, and at a large `c` the remainder acts as a huge mass
//! term that blocks the coarse correction.
//!
//! Measured and rejected: reduction to the even slabs on the finest level (exact odd-slab
//! solves before and after the coarse correction, `z = S r + (I − S A) P B_c Pᵀ (I − A S) r`,
//! no products with `A`, half the finest level's slab solves). On the torus at `α = 0.01` it
//! cut multigrid's time from 2.7 to 1.9 s at equal iterations, but on a sphere dark outside a
//! textured cap (`tests/solver.rs`) it doubled the iterations at `α = 0.1` (7 → 14, 8 → 16):
//! the Galerkin coarse operator is then far from the Schur complement of the odd slabs.
//! Skipping the smoothing and factors of every other coarse level (coarsening by 4): at 20
//! frames 2.8 → 2.3 s (`γ = 0.01`, `α = 0.01`, 11 iterations either way), but at 200 frames
//! (64×48) 10 → 15 iterations and slower: iterations grow with frames again.
//!
//! Measured and rejected, operator-dependent coarse levels (reduction in time with an
//! algebraic interpolation): the coarse level is the even slabs, with the Galerkin operator of
//! `u_o = −diag(D_o)⁻¹ (X_{o−1} u_{o−1} + X_oᵀ u_{o+1})` per vertex, the harmonic extension
//! into each odd slab with its block replaced by its vertex diagonal (checked against the dense
//! `P̂ᵀ A P̂` to 4e-16; its coarse links carry the odd slabs' spatial pattern). With exact
//! odd-slab solves before and after and no smoothing of the even slabs it is nearly exact on
//! an 8×6 torus (preconditioned eigenvalues in `[0.998, 1]`), but on the 128×95×20 torus it
//! took 126 / 152 / 61 iterations at `α` = 0.1 / 0.01 / 0.001 (`γ = 1`) and 51 / 66 / 33 at
//! `γ = 0.01`; as the coarse levels of the V-cycle (both sweeps), 99 / 130 / 58 and 40 / 56 /
//! 32. The vertex diagonal stands in for the odd slab's inverse only where `c m_i` dominates
//! `γ L_ii`, and `c m_i` shrinks with the square of the mesh spacing while `γ L_ii` does not:
//! it degrades under spatial refinement. The piecewise-constant transported prolongation asks
//! nothing of `D_o⁻¹`, which is why it stays flat. Weighting the halving instead (coarse links
//! `X ← (1 − θ) X` with `θ |X|` off the diagonal blocks, which keeps fields constant in time
//! free of coupling energy for any `θ`; `θ = ½` is the doubled time step): `θ` = 0.4 / 0.45 /
//! 0.55 gave 10 / 10 / 9, 9 / 9 / 8 and 9 / 10 / 8 iterations at `γ = 1`, `α` = 0.1 / 0.01 /
//! 0.001 (`θ = ½`: 9 / 9 / 7), and at `γ = 0.01`, `α = 0.01` 11 for every `θ` (12 at 0.55).
//!
//! Where the time goes at `α = 0.01`, `γ = 0.01` (multigrid alone, 2.7 s): fine factors 0.31 s,
//! building the coarse levels 0.085 s (0.063 s since they are updated in place), their factors
//! 0.3 s, 11 V-cycles of 0.165 s (85 % slab sweeps, 11 % residual products). A slab solve streams
//! its single-precision factor twice (2.18 M entries, 17.5 MB) and takes 1.75 ms on one core
//! alone and about twice that while the other core solves too: the sweeps were bound by memory
//! bandwidth (~10 GB/s) there, not arithmetic (the paper size's larger factors are bound by
//! the per-supernode work instead, [`crate::linalg::packed`]), and a V-cycle, which solves 82
//! slab blocks (both sweeps over the 20 fine and 21 coarse blocks) against a Gauss–Seidel
//! iteration's 30, costs what it reads. `t(α = 0.01) / t(α = 1) ≤ 2.5` at `γ = 0.01` (1.9 s for the solve) would need at most 7
//! V-cycles, or a cycle that reads half as much; every candidate above that reads less (reduction
//! to the even slabs, skipping levels, operator-dependent levels) loses flatness in `α`, in the
//! number of frames or in the mesh size. Bfloat16 factors are such a cycle, and they keep the
//! iterations: under `auto` (4 Gauss–Seidel iterations, then multigrid) `α = 0.01`, `γ = 0.01`
//! now takes 15 iterations and 2.47 s with the factorizations (0.79 s), about 0.13 s a V-cycle,
//! and `γ = 1` 13 iterations, 2.05–2.28 s (before: 3.44 s and 2.72 s, the same iterations).
//! `t(α = 0.01) / t(α = 1)` is 1.1–1.5 at `γ = 1` and 3.1 at `γ = 0.01` (target 2.5: still
//! missed there; `α = 1` takes 0.71–0.80 s in 8 Gauss–Seidel iterations, while the coarse levels'
//! factorizations and the probe alone take about 0.7 s at `α = 0.01`). Leaving the probe after
//! its first iteration when that made no progress takes 3 iterations off every multigrid cell
//! and about 0.16 s off the solve. `auto`'s iterations now, `α` = 10 / 1 / 0.1 / 0.01 / 0.001:
//! 3 / 19 / 10 / 10 / 9 at `γ = 1`, 2 / 8 / 11 / 12 / 8 at `γ = 0.01`, default weights at
//! 30 fps 12 (bench_solver, 2026-11-27). Since then (the post-smoother in place, the levels
//! built in parallel) the ratio was 1.25–1.36 at `γ = 1` and 2.55–2.63 at `γ = 0.01` on two
//! cores; cheaper cycles (a V(0,1) cycle under flexible CG, shared coarse factors, links'
//! residuals on bfloat16 levels) lost iterations where they saved work (docs/scaling.md,
//! "Cheaper cycles"). Dropping the bfloat16 factors' small rows (above) keeps every iteration
//! count and takes it to 1.09–1.24 at `γ = 1` and 2.21 at `γ = 0.01` (`bench_solver`'s
//! medians; 2.20 against 2.65 before in alternating runs of a quiet hour, 2.47 against 2.66 in a
//! noisy one), and to 1.14 and 2.07 on the 16-core Xeon limited to 2 cores (2.87 before, the
//! same hour; docs/scaling.md, "Small rows dropped").
//!
//! What slows slab Gauss–Seidel at `α = 1` (19 iterations at paper size) is error that the
//! slab blocks barely see and only the time coupling holds: their near-null space (global
//! fields along the texture's isophotes, eigenvalues a thousandth of the blocks' diagonal). A
//! coarse space of 64 Ritz vectors of the middle slab's block, shared by all slabs, takes the
//! paper size to 8 iterations, but making it costs what those iterations save at 20 frames;
//! aggregation spaces 15–30 times larger do not help there at all, while on the zebrafish
//! recording (2 slabs, Gauss–Seidel alone 186 iterations) only aggregation does (24); both
//! side by side serve both (docs/scaling.md, "What slows slab Gauss–Seidel at `α = 1`").
//!
//! Results agree with the direct solver to 1e-9 relative (`tests/solver.rs`), for lumped and
//! consistent coupling, Neumann and Dirichlet boundaries, even and odd slab counts.

pub mod distributed;
mod multigrid;
mod pcg;
mod precondition;
mod reduced;
mod run;

use super::system::SpaceTimeSystem;
use super::{FlowError, FlowParams, SolverChoice};
use crate::linalg::bfloat::Bf16Factor;
use crate::linalg::cholesky::{analyze, CholeskyFactor, FactorEntries};
use crate::linalg::factor::{SlabFactor, SpareValues};
use crate::linalg::packed::PackedFactor;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::Par;
use multigrid::{TimeHierarchy, TimeMultigrid};
use precondition::{Jacobi, SlabGaussSeidel, SlabSweeps};
use rayon::prelude::*;
pub(crate) use run::{FactorReuse, InRun, RunFactors};
use run::{Shape, WithLevels};
use std::sync::Arc;
use std::time::Instant;

/// The method that produced a solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverMethod {
    Direct,
    SlabwiseDirect,
    PcgSlabGaussSeidel,
    PcgTimeMultigrid,
    PcgJacobi,
}

impl SolverMethod {
    /// Whether it iterates to a tolerance (the preconditioned conjugate gradients) rather than
    /// factoring the system.
    pub fn is_iterative(&self) -> bool {
        !matches!(self, SolverMethod::Direct | SolverMethod::SlabwiseDirect)
    }
}

impl std::fmt::Display for SolverMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SolverMethod::Direct => "direct",
            SolverMethod::SlabwiseDirect => "slab-wise direct",
            SolverMethod::PcgSlabGaussSeidel => "PCG (slab Gauss-Seidel)",
            SolverMethod::PcgTimeMultigrid => "PCG (multigrid in time)",
            SolverMethod::PcgJacobi => "PCG (Jacobi)",
        })
    }
}

/// Progress reports from a running solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolveEvent {
    /// Factorizing `slabs` diagonal blocks (or the whole system when `slabs == 0`).
    Factorizing { slabs: usize },
    Iteration {
        iteration: usize,
        relative_residual: f64,
    },
    /// Coarse-to-fine warping starts linear solve `solve` of `solves` (level `level`, coarsest
    /// first, warp `warp` on it).
    Warp {
        level: usize,
        warp: usize,
        solve: usize,
        solves: usize,
    },
    /// The first linear solve's flow moves the image too far for the linear model (its
    /// linearization error `η` above `threshold`, [`crate::flow::motion`]): the flow is solved
    /// again coarse to fine.
    LargeMotion {
        linearization_error: f64,
        threshold: f64,
    },
}

/// Receives a running solve's [`SolveEvent`]s, and may stop it. Any `Fn(SolveEvent) + Sync`
/// closure is one (never stopping); the Python package's also checks for Ctrl-C.
pub trait SolveObserver: Sync {
    fn event(&self, event: SolveEvent);
    /// Asked after every event: `true` ends the solve with [`FlowError::Interrupted`]. Events
    /// come at least once per iteration, warp and factorization, so a solve stops within one
    /// iteration (a factorization in progress runs to its end).
    fn interrupted(&self) -> bool {
        false
    }
}

impl<F: Fn(SolveEvent) + Sync> SolveObserver for F {
    fn event(&self, event: SolveEvent) {
        self(event)
    }
}

impl dyn SolveObserver + '_ {
    /// Reports `event`; [`FlowError::Interrupted`] if the observer asks to stop.
    pub(crate) fn notify(&self, event: SolveEvent) -> Result<(), FlowError> {
        self.event(event);
        match self.interrupted() {
            true => Err(FlowError::Interrupted),
            false => Ok(()),
        }
    }
}

/// `u` with how it was found.
#[derive(Clone, Debug)]
pub struct Solution {
    pub u: Vec<f64>,
    pub method: SolverMethod,
    pub iterations: usize,
    /// `‖b − Au‖ / ‖b‖`, recomputed from the returned `u` (0 when `b = 0`).
    pub relative_residual: f64,
    pub factor_seconds: f64,
    /// Entries of all Cholesky factors used.
    pub factor_entries: FactorEntries,
    /// Levels of multigrid in time (1: none).
    pub time_levels: usize,
    /// Why this method: the rule `auto` applied, with the figures it compared.
    pub reason: String,
    /// `[λ_min, λ_max]` of the preconditioned operator seen by the last CG run (its Ritz
    /// values); `None` for direct solves.
    pub spectrum: Option<[f64; 2]>,
}

/// Solves the system with the method `params.solver` asks for (see the module docs), with
/// subnormal numbers flushed ([`crate::subnormals`]).
///
/// `start`, when given, is where the iterative methods start ([`WarmStart`]; the direct ones
/// ignore it). `run`, when given, holds what a run's solves hand on ([`run`]): the slab
/// factors take their buffers from its pool and give them back at the end, so that the run's
/// next solve writes into pages mapped already ([`SlabFactor::recycle`]); and where
/// [`FactorReuse`] says so, a solve keeps its factors for the next one, which preconditions
/// with them instead of factoring its own.
pub fn solve(
    system: &SpaceTimeSystem,
    params: &FlowParams,
    start: Option<&WarmStart>,
    run: Option<InRun<'_>>,
    observer: &dyn SolveObserver,
) -> Result<Solution, FlowError> {
    let solution =
        crate::subnormals::flushed(|| solve_flushed(system, params, (start, run), observer));
    // The factors are gone; what comes next (energy terms, push-forward) rebuilds slabs.
    crate::limits::release_free_memory();
    solution
}

/// Whether the solve of a system of `dimension` unknowns (`coupled`: linked in time) factors
/// its slab blocks, as [`solve_flushed`] chooses: then the blocks' symbolic analysis is made
/// beside the assembly ([`SpaceTimeSystem::slab_symbolic`]; otherwise on first use).
pub(crate) fn factors_slabs(params: &FlowParams, dimension: usize, coupled: bool) -> bool {
    match params.solver {
        SolverChoice::Auto => !coupled || dimension > params.direct_limit,
        SolverChoice::PcgSlabGaussSeidel | SolverChoice::PcgTimeMultigrid => true,
        SolverChoice::Direct | SolverChoice::PcgJacobi => false,
    }
}

/// A warm start: the previous solve of a run whose systems differ a little (warping,
/// reweighting), as [`crate::flow::FlowProblem::solve_from`] and the distributed solve take it.
///
/// PCG starts from `u` instead of zero, and a `u` that already meets the tolerance is the
/// solution, returned before anything is factored. `auto` goes straight to multigrid in time
/// where the previous solve needed it (its probe of slab Gauss–Seidel would only find that
/// again, later: from a start nearer the tolerance the projected rest of slab Gauss–Seidel
/// stays within its limit for more iterations), and otherwise probes as from zero but for the
/// first iterations' lack of progress, which from a warm start says little (CG may raise the
/// residual's norm first). Measured: docs/scaling.md, "Warm starts across a run's solves".
#[derive(Clone, Debug)]
pub struct WarmStart {
    /// The previous solution's unknowns, slab-major (`2V` per slab, two per vertex, as
    /// `SpaceTimeSystem` orders them; over ranks, this rank's slabs).
    pub u: Vec<f64>,
    /// The method that solution ended with.
    pub method: SolverMethod,
}

impl WarmStart {
    /// How `auto` preconditions a solve from `start`.
    fn auto(start: Option<&Self>) -> Preconditioning {
        match start.map(|s| s.method) {
            Some(SolverMethod::PcgTimeMultigrid) => Preconditioning::MultigridAsBefore,
            _ => Preconditioning::Adaptive,
        }
    }
}

/// Why `auto` runs multigrid from the start of a warm solve ([`WarmStart`]).
const MULTIGRID_AS_BEFORE: &str = "the run's previous solve needed multigrid in time";

fn solve_flushed(
    system: &SpaceTimeSystem,
    params: &FlowParams,
    (start, run): (Option<&WarmStart>, Option<InRun<'_>>),
    observer: &dyn SolveObserver,
) -> Result<Solution, FlowError> {
    let slab_pcg = |preconditioning| {
        let from = Starting { start, run };
        slab_pcg(system, params, preconditioning, from, observer)
    };
    let b = system.rhs();
    if b.iter().all(|&v| v == 0.0) {
        return Ok(Solution::zero(b.len()));
    }
    let mut solution = match params.solver {
        SolverChoice::Auto if !system.has_links() => {
            let why = match system.n_slabs() {
                1 => "one slab",
                _ => "α = ∞: the slabs are independent",
            };
            slabwise_direct(system, observer, why.into())?
        }
        SolverChoice::Auto if system.dimension() <= params.direct_limit => direct(
            system,
            observer,
            format!(
                "{} unknowns, within the direct solver's limit of {}",
                system.dimension(),
                params.direct_limit
            ),
        )?,
        SolverChoice::Auto => slab_pcg(WarmStart::auto(start))?,
        SolverChoice::Direct => direct(system, observer, "asked for".into())?,
        SolverChoice::PcgSlabGaussSeidel => slab_pcg(Preconditioning::GaussSeidel)?,
        SolverChoice::PcgTimeMultigrid => slab_pcg(Preconditioning::Multigrid)?,
        SolverChoice::PcgJacobi => match MetStart::of(system, system.rhs(), params, start) {
            Some(met) => met.solution(SolverMethod::PcgJacobi),
            None => {
                let x = start.map(|s| s.u.clone());
                let outcome = run_pcg(system, x, &Jacobi::new(system), params, 0, observer)?;
                Solution::iterated(outcome, SolverMethod::PcgJacobi, "asked for".into())
                    .converged(params)?
            }
        },
    };
    solution.relative_residual = relative_residual(system, system.rhs(), &solution.u);
    Ok(solution)
}

impl Solution {
    /// `u = 0` for `b = 0`, a static image: the exact minimizer (`E ≥ 0 = E(0)` minus the
    /// constant).
    fn zero(dimension: usize) -> Self {
        Self {
            iterations: 0,
            relative_residual: 0.0,
            ..Solution::exact(
                vec![0.0; dimension],
                SolverMethod::Direct,
                "the right-hand side is zero (a static image): u = 0".into(),
            )
        }
    }

    fn exact(u: Vec<f64>, method: SolverMethod, reason: String) -> Self {
        Self {
            u,
            method,
            iterations: 1,
            relative_residual: f64::NAN,
            factor_seconds: 0.0,
            factor_entries: FactorEntries::default(),
            time_levels: 1,
            reason,
            spectrum: None,
        }
    }

    fn iterated(outcome: pcg::CgOutcome, method: SolverMethod, reason: String) -> Self {
        Self {
            iterations: outcome.iterations,
            relative_residual: outcome.relative_residual,
            spectrum: outcome.spectrum,
            ..Self::exact(outcome.x, method, reason)
        }
    }

    /// `Err(NotConverged)` unless the recursive residual met the tolerance.
    fn converged(self, params: &FlowParams) -> Result<Self, FlowError> {
        match self.relative_residual <= params.tolerance {
            true => Ok(self),
            false => Err(FlowError::NotConverged {
                iterations: self.iterations,
                residual: self.relative_residual,
                tolerance: params.tolerance,
            }),
        }
    }
}

/// A [`WarmStart`] that already meets the tolerance: the solution of no iteration, found before
/// anything is factored. A run's next solve may start there when its system changed less than
/// the tolerance sees (at paper size with `--large-motion`, the coarsest level's second warp).
struct MetStart {
    u: Vec<f64>,
    relative_residual: f64,
}

impl MetStart {
    /// `start` when `‖b − A u‖ ≤ tolerance ‖b‖`.
    fn of(
        system: &dyn pcg::Operator,
        b: &[f64],
        params: &FlowParams,
        start: Option<&WarmStart>,
    ) -> Option<Self> {
        let u = &start?.u;
        let relative_residual = relative_residual(system, b, u);
        (relative_residual <= params.tolerance).then(|| MetStart {
            u: u.to_vec(),
            relative_residual,
        })
    }

    fn solution(self, method: SolverMethod) -> Solution {
        Solution {
            iterations: 0,
            relative_residual: self.relative_residual,
            spectrum: None,
            ..Solution::exact(
                self.u,
                method,
                format!(
                    "the start (the run's previous flow) already meets the tolerance: \
                     residual {:.1e}",
                    self.relative_residual
                ),
            )
        }
    }
}

/// `‖b − A u‖ / ‖b‖`.
fn relative_residual(system: &dyn pcg::Operator, b: &[f64], u: &[f64]) -> f64 {
    let mut r = vec![0.0; u.len()];
    system.apply(u, &mut r);
    r.iter_mut().zip(b).for_each(|(r, b)| *r = b - *r);
    (system.dot(&r, &r) / system.dot(b, b)).sqrt()
}

/// PCG from `x` (zero when `None`) with iterations `done` already counted.
fn run_pcg(
    system: &SpaceTimeSystem,
    x: Option<Vec<f64>>,
    preconditioner: &dyn pcg::Preconditioner,
    params: &FlowParams,
    done: usize,
    observer: &dyn SolveObserver,
) -> Result<pcg::CgOutcome, FlowError> {
    let stop = pcg::Stop {
        done,
        ..pcg::Stop::new(params.tolerance, params.max_iterations)
    };
    run_pcg_until(system, x, preconditioner, stop, observer)
}

fn run_pcg_until(
    system: &SpaceTimeSystem,
    x: Option<Vec<f64>>,
    preconditioner: &dyn pcg::Preconditioner,
    stop: pcg::Stop,
    observer: &dyn SolveObserver,
) -> Result<pcg::CgOutcome, FlowError> {
    let x = x.unwrap_or_else(|| vec![0.0; system.dimension()]);
    pcg::pcg(system, system.rhs(), x, preconditioner, stop, observer)
}

fn factorization_error(what: String) -> impl Fn(String) -> FlowError {
    move |detail| FlowError::Factorization {
        what: what.clone(),
        detail,
    }
}

/// How slab-factor PCG is preconditioned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Preconditioning {
    GaussSeidel,
    Multigrid,
    /// `auto` from a [`WarmStart`] whose solve ended with multigrid in time.
    MultigridAsBefore,
    /// Slab Gauss–Seidel for [`PROBE_ITERATIONS`]; multigrid in time if it is too slow.
    Adaptive,
}

/// Iterations of slab Gauss–Seidel from which `Adaptive` projects its convergence (at every
/// iteration, from the rate of the last `PROBE_ITERATIONS − 1`).
pub const PROBE_ITERATIONS: usize = 4;
/// Projected Gauss–Seidel iterations in all (those of the probe and the rest) above which
/// `Adaptive` builds the multigrid levels; after the probe, the projected rest is held to
/// `SWITCH_ITERATIONS − PROBE_ITERATIONS`.
/// Measured (`examples/bench_solver.rs`): a V-cycle costs about 3 Gauss–Seidel sweeps and
/// its coarse levels about one more round of factorizations; multigrid needs at most ~11
/// iterations after the probe, so it pays from about 30 Gauss–Seidel iterations on.
pub const SWITCH_ITERATIONS: f64 = 30.0;

/// `auto`'s probe: [`PROBE_ITERATIONS`], then give up on slab Gauss–Seidel above
/// [`SWITCH_ITERATIONS`] projected to `goal` (the tolerance; a round's stopping point in
/// [`reduced`]); before, without progress, unless the run starts `warm` ([`pcg::GiveUp::early`]).
fn probe_give_up(goal: f64, warm: bool) -> pcg::GiveUp {
    pcg::GiveUp {
        probe: PROBE_ITERATIONS,
        limit: SWITCH_ITERATIONS,
        goal,
        early: !warm,
    }
}

/// Why `auto` kept slab Gauss–Seidel, or left it for multigrid in time, after a run that may
/// have given up ([`pcg::Stop::give_up`]).
fn gauss_seidel_verdict(outcome: &pcg::CgOutcome) -> String {
    match outcome.gave_up {
        None => format!(
            "slab Gauss-Seidel converges fast enough (its rate never projected more than {} \
             further iterations after the first {PROBE_ITERATIONS})",
            SWITCH_ITERATIONS - PROBE_ITERATIONS as f64
        ),
        Some(projection) if projection.rate >= 1.0 => format!(
            "slab Gauss-Seidel left {:.1e} times the starting residual after {}, no progress: \
             the time coupling dominates",
            outcome.relative_residual,
            iterations(outcome.iterations)
        ),
        Some(projection) => format!(
            "slab Gauss-Seidel reached {:.1e} in {}, reducing the residual by only {:.2} per \
             iteration (about {:.0} more projected), too slow: the time coupling dominates",
            outcome.relative_residual,
            iterations(outcome.iterations),
            projection.rate,
            projection.remaining.min(1e6)
        ),
    }
}

/// "1 iteration", "4 iterations".
fn iterations(n: usize) -> String {
    match n {
        1 => "1 iteration".into(),
        n => format!("{n} iterations"),
    }
}

/// PCG preconditioned with exact slab solves: slab Gauss–Seidel, multigrid in time, or the
/// first then the second when it converges too slowly.
fn slab_pcg(
    system: &SpaceTimeSystem,
    params: &FlowParams,
    preconditioning: Preconditioning,
    Starting { start: first, run }: Starting<'_>,
    observer: &dyn SolveObserver,
) -> Result<Solution, FlowError> {
    if let Some(met) = MetStart::of(system, system.rhs(), params, first) {
        return Ok(met.solution(match preconditioning {
            Preconditioning::Multigrid | Preconditioning::MultigridAsBefore => {
                SolverMethod::PcgTimeMultigrid
            }
            _ => SolverMethod::PcgSlabGaussSeidel,
        }));
    }
    let start = Instant::now();
    let job = |plan| SlabJob {
        system,
        params,
        preconditioning,
        plan,
        start,
        first: first.map(|s| s.u.as_slice()),
        run,
        kept: false,
        observer,
    };
    let plans = Plans::new(system, params);
    let kept = |run: InRun<'_>| {
        let with = WithKept {
            job: job(&plans.single),
            plans: &plans,
        };
        run.take_kept(shape(system), with)
    };
    if let Some(solution) = run.and_then(kept) {
        return solution;
    }
    let Plans {
        single,
        compressed,
        double,
    } = &plans;
    let outcome = match single.slabs_per_factor {
        1 => slab_pcg_in::<PackedFactor<f32>>(job(single)),
        _ => slab_pcg_in::<Bf16Factor>(job(compressed)),
    };
    match outcome {
        Err(FlowError::Factorization { .. }) => slab_pcg_in::<CholeskyFactor<f64>>(job(double)),
        other => other,
    }
}

/// The [`FactorPlan`]s of a system's slab factors by precision: single precision (`f32` or
/// bfloat16) suffices for a preconditioner; double precision if a block of any level (the
/// fine slabs, or the coarse levels multigrid adds later) is too ill-conditioned for single.
struct Plans<'a> {
    single: FactorPlan<'a>,
    compressed: FactorPlan<'a>,
    double: FactorPlan<'a>,
}

impl<'a> Plans<'a> {
    fn new(system: &'a SpaceTimeSystem, params: &FlowParams) -> Self {
        let symbolic = system.slab_symbolic();
        Self {
            single: FactorPlan::new::<PackedFactor<f32>>(system, symbolic, params),
            compressed: FactorPlan::new::<Bf16Factor>(system, symbolic, params),
            double: FactorPlan::new::<CholeskyFactor<f64>>(system, symbolic, params),
        }
    }

    /// The plan for factors of type `F`.
    fn of<F: SlabFactor>(&self) -> &FactorPlan<'a> {
        match F::ENTRY_BYTES {
            8 => &self.double,
            2 => &self.compressed,
            _ => &self.single,
        }
    }
}

/// [`slab_pcg`] with factors of type `F` (or Jacobi, when not even one fits the budget).
fn slab_pcg_in<F: SlabFactor>(job: SlabJob<'_>) -> Result<Solution, FlowError> {
    let (system, params, plan) = (job.system, job.params, job.plan);
    if plan.slabs_per_factor > system.n_slabs() {
        let jacobi = Jacobi::new(system);
        let outcome = run_pcg(
            system,
            job.first_iterate(),
            &jacobi,
            params,
            0,
            job.observer,
        )?;
        return Solution::iterated(outcome, SolverMethod::PcgJacobi, plan.describe())
            .converged(params);
    }
    job.observer.notify(SolveEvent::Factorizing {
        slabs: system.n_slabs(),
    })?;
    let per_thread = SpareValues::per_thread();
    let spare = run::spare_for::<F>(job.run, &per_thread);
    let fine = plan.factor::<F>(&[system], spare)?.remove(0);
    slab_pcg_with(job, fine)
}

/// Where a solve of a run starts: the previous solve ([`WarmStart`]) and what the run's solves
/// hand on ([`solve`]'s `run`).
#[derive(Clone, Copy)]
struct Starting<'a> {
    start: Option<&'a WarmStart>,
    run: Option<InRun<'a>>,
}

/// What [`slab_pcg_with`] needs besides the factors (factored since `start`; PCG's first
/// iterate `first`, zero when `None`; the run the solve is one of; whether the factors are
/// `kept` from the run's previous solve, [`run`]).
#[derive(Clone, Copy)]
struct SlabJob<'a> {
    system: &'a SpaceTimeSystem,
    params: &'a FlowParams,
    preconditioning: Preconditioning,
    plan: &'a FactorPlan<'a>,
    start: Instant,
    first: Option<&'a [f64]>,
    run: Option<InRun<'a>>,
    kept: bool,
    observer: &'a dyn SolveObserver,
}

impl SlabJob<'_> {
    fn first_iterate(&self) -> Option<Vec<f64>> {
        self.first.map(<[f64]>::to_vec)
    }

    /// The solve's `levels` to the run: kept for the next solve, or their buffers recycled.
    fn hand_on<F: SlabFactor>(&self, levels: Vec<SlabSweeps<F>>) {
        if let Some(run) = self.run {
            run.hand_on(levels, shape(self.system));
        }
    }

    /// `reason` with where the factors came from.
    fn factors_reason(&self, reason: String) -> String {
        match self.kept {
            true => format!("{reason}; {KEPT}"),
            false => format!("{reason}; {}", self.plan.describe()),
        }
    }
}

/// Why a solve's factors are not its own ([`run`]).
const KEPT: &str = "the factors of the level's previous warp, kept (the systems differ by the \
                    re-linearized data term alone)";

/// The slabs and unknowns per slab of `system`: what kept factors must match.
fn shape(system: &SpaceTimeSystem) -> Shape {
    (system.n_slabs(), system.slab_dimension())
}

/// [`slab_pcg_with`] or multigrid in time with the levels the run's previous solve kept.
struct WithKept<'a> {
    job: SlabJob<'a>,
    plans: &'a Plans<'a>,
}

impl WithLevels for WithKept<'_> {
    type Output = Result<Solution, FlowError>;

    fn with<F: SlabFactor>(self, mut levels: Vec<SlabSweeps<F>>) -> Self::Output {
        let job = SlabJob {
            plan: self.plans.of::<F>(),
            kept: true,
            ..self.job
        };
        let fine = levels.remove(0);
        if levels.is_empty() {
            return slab_pcg_with(job, fine);
        }
        let switch = Switch {
            x: job.first_iterate(),
            done: 0,
            reason: job.factors_reason(multigrid_why(job.preconditioning).into()),
            factor_seconds: 0.0,
            coarse_start: Instant::now(),
        };
        let mut sweeps = vec![fine];
        sweeps.extend(levels);
        multigrid_pcg(job, TimeHierarchy::new(job.system), sweeps, switch)
    }
}

/// Why multigrid in time runs from the start under `preconditioning`.
fn multigrid_why(preconditioning: Preconditioning) -> &'static str {
    match preconditioning {
        Preconditioning::Multigrid => "asked for",
        _ => MULTIGRID_AS_BEFORE,
    }
}

fn slab_pcg_with<F: SlabFactor>(
    job: SlabJob<'_>,
    fine: SlabSweeps<F>,
) -> Result<Solution, FlowError> {
    let SlabJob {
        system,
        params,
        preconditioning,
        plan,
        start,
        observer,
        ..
    } = job;
    // The factorizations' workspaces, before CG's vectors.
    crate::limits::release_free_memory();
    let factor_seconds = start.elapsed().as_secs_f64();
    let factor_entries = fine.entries();
    let (x, done, reason) = match preconditioning {
        Preconditioning::Multigrid | Preconditioning::MultigridAsBefore => {
            let reason = job.factors_reason(multigrid_why(preconditioning).into());
            (job.first_iterate(), 0, reason)
        }
        _ => {
            let stop = pcg::Stop {
                give_up: (preconditioning == Preconditioning::Adaptive)
                    .then(|| probe_give_up(params.tolerance, job.first.is_some())),
                ..pcg::Stop::new(params.tolerance, params.max_iterations)
            };
            let first = job.first_iterate();
            let eliminates = !job.kept && plan.slabs_per_factor == 1;
            let outcome = gauss_seidel_pcg(system, &fine, eliminates, first, stop, observer)?;
            let verdict = gauss_seidel_verdict(&outcome);
            if outcome.gave_up.is_none() || preconditioning == Preconditioning::GaussSeidel {
                let reason = match preconditioning {
                    Preconditioning::GaussSeidel => job.factors_reason("asked for".into()),
                    _ => job.factors_reason(verdict),
                };
                let mut solution =
                    Solution::iterated(outcome, SolverMethod::PcgSlabGaussSeidel, reason);
                solution.factor_seconds = factor_seconds;
                solution.factor_entries = factor_entries;
                job.hand_on(vec![fine]);
                return solution.converged(params);
            }
            let reason = job.factors_reason(verdict);
            (Some(outcome.x), outcome.iterations, reason)
        }
    };
    let switch = Switch {
        x,
        done,
        reason,
        factor_seconds,
        coarse_start: Instant::now(),
    };
    let spare = SpareValues::per_thread();
    match levels_keep_precision::<F>(plan.symbolic, system.n_slabs()) {
        true => time_multigrid(job, fine, switch, spare),
        false => {
            let compressed = fine.compress(&spare);
            time_multigrid(job, compressed, switch, spare)
        }
    }
}

/// Slab Gauss–Seidel's PCG from `x` (zero when `None`) under `stop`: on the odd slabs alone
/// (the even ones eliminated, [`reduced`]) where the factors `eliminate` (each slab has its own
/// factor of its own block) and solve exactly enough; when a round of refinement is too slow
/// or stalls (other than `auto`'s probe giving up), PCG on the whole system goes on from where
/// the rounds left it.
fn gauss_seidel_pcg<F: SlabFactor>(
    system: &SpaceTimeSystem,
    fine: &SlabSweeps<F>,
    eliminate: bool,
    x: Option<Vec<f64>>,
    stop: pcg::Stop,
    observer: &dyn SolveObserver,
) -> Result<pcg::CgOutcome, FlowError> {
    let gauss_seidel = SlabGaussSeidel::new(system, fine);
    if !eliminate || !F::ELIMINATES || !system.has_links() {
        return run_pcg_until(system, x, &gauss_seidel, stop, observer);
    }
    let x = x.unwrap_or_else(|| vec![0.0; system.dimension()]);
    let reduced = reduced::odd_slab_pcg(system, fine, x, stop, observer)?;
    let unfinished = reduced.relative_residual > stop.tolerance
        && reduced.iterations < stop.max_iterations
        && reduced.gave_up.is_none();
    if !unfinished {
        return Ok(reduced);
    }
    let rest = pcg::Stop {
        done: reduced.iterations,
        give_up: None,
        ..stop
    };
    let outcome = run_pcg_until(system, Some(reduced.x), &gauss_seidel, rest, observer)?;
    Ok(pcg::CgOutcome {
        spectrum: reduced.spectrum,
        ..outcome
    })
}

/// Where multigrid in time starts: from `x` after `done` Gauss–Seidel iterations (`None`: from
/// zero), why, and the fine factors' seconds.
struct Switch {
    x: Option<Vec<f64>>,
    done: usize,
    reason: String,
    factor_seconds: f64,
    coarse_start: Instant,
}

/// PCG with multigrid in time whose levels have factors of type `F`, the fine ones given, the
/// coarse ones factored into `spare`'s buffers (freed before CG).
fn time_multigrid<F: SlabFactor>(
    job: SlabJob<'_>,
    fine: SlabSweeps<F>,
    switch: Switch,
    spare: SpareValues,
) -> Result<Solution, FlowError> {
    let hierarchy = TimeHierarchy::new(job.system);
    let coarse: Vec<&SpaceTimeSystem> = hierarchy.coarse_systems().iter().collect();
    job.observer.notify(SolveEvent::Factorizing {
        slabs: coarse.iter().map(|c| c.n_slabs()).sum(),
    })?;
    let mut sweeps = vec![fine];
    sweeps.extend(job.plan.factor::<F>(&coarse, &spare)?);
    drop(spare);
    multigrid_pcg(job, hierarchy, sweeps, switch)
}

/// PCG with multigrid in time over `hierarchy` with the levels' `sweeps`, finest first; the
/// sweeps handed on to the run at the end.
fn multigrid_pcg<F: SlabFactor>(
    job: SlabJob<'_>,
    hierarchy: TimeHierarchy,
    sweeps: Vec<SlabSweeps<F>>,
    switch: Switch,
) -> Result<Solution, FlowError> {
    let (system, observer) = (job.system, job.observer);
    let factor_seconds = switch.factor_seconds + switch.coarse_start.elapsed().as_secs_f64();
    let factor_entries = sweeps.iter().map(SlabSweeps::entries).sum();
    let levels = sweeps.len();
    let multigrid = TimeMultigrid::new(system, hierarchy, sweeps);
    let outcome = run_pcg(
        system,
        switch.x,
        &multigrid,
        job.params,
        switch.done,
        observer,
    )?;
    job.hand_on(multigrid.into_sweeps());
    let reason = format!("{}; the levels' factors in {}", switch.reason, F::NAME);
    let mut solution = Solution::iterated(outcome, SolverMethod::PcgTimeMultigrid, reason);
    solution.factor_seconds = factor_seconds;
    solution.factor_entries = factor_entries;
    solution.time_levels = levels;
    solution.converged(job.params)
}

/// All multigrid levels' factors together, in bytes, up to which they keep the fine factors'
/// precision (`f32`) instead of bfloat16 ([`SlabFactor::Compressed`]).
///
/// Bfloat16 pays by reading half as much memory per cycle; factors this small are read largely
/// from the processor's caches, while the rounding costs iterations where the cycle is nearly
/// exact. Measured (2 cores, 32 MB last-level cache): the zebrafish recording (2 slabs, 3
/// factors of 29 MB in all) with `--large-motion --regularizer strain` took 54 iterations in
/// 8 solves with `f32` levels against 81 with bfloat16, 3.3–3.7 s against 3.4–3.7 s; the
/// 128×95×20 torus (41 factors, 0.72 GB) keeps its iterations with bfloat16 and saves about
/// a quarter of each V-cycle.
pub const CACHED_LEVELS_BYTES: usize = 64 << 20;

/// Whether the levels over `n_slabs` fine slabs keep factors of type `F`
/// ([`CACHED_LEVELS_BYTES`]); the same on every rank of a distributed solve.
fn levels_keep_precision<F: SlabFactor>(
    symbolic: &SymbolicCholesky<usize>,
    n_slabs: usize,
) -> bool {
    let factors: usize = multigrid::level_slab_counts(n_slabs).iter().sum();
    factors * symbolic.len_val() * F::ENTRY_BYTES <= CACHED_LEVELS_BYTES
}

/// How many slab factors to keep: all of them if they fit `params.factor_memory_limit`,
/// otherwise one per run of `slabs_per_factor` neighbouring slabs (more than all slabs: not
/// even one factor fits).
struct FactorPlan<'a> {
    symbolic: &'a Arc<SymbolicCholesky<usize>>,
    slabs_per_factor: usize,
    /// Bytes of one factor of the type planned for.
    factor_bytes: usize,
    /// How that type stores its entries ([`SlabFactor::NAME`]).
    precision: &'static str,
    budget: usize,
    n_slabs: usize,
}

impl<'a> FactorPlan<'a> {
    /// The plan for factors of type `F` within `params.factor_memory_limit`: half of it for
    /// single precision (multigrid adds about as many coarse factors again, in bfloat16),
    /// all of it for double.
    fn new<F: SlabFactor>(
        system: &SpaceTimeSystem,
        symbolic: &'a Arc<SymbolicCholesky<usize>>,
        params: &FlowParams,
    ) -> Self {
        let budget = match F::ENTRY_BYTES {
            8 => params.factor_memory_limit,
            _ => params.factor_memory_limit / 2,
        };
        let factor_bytes = F::bytes_at_most(symbolic);
        let fitting = budget / factor_bytes.max(1);
        let slabs_per_factor = match fitting {
            0 => system.n_slabs() + 1,
            f => system.n_slabs().div_ceil(f).max(1),
        };
        Self {
            symbolic,
            slabs_per_factor,
            factor_bytes,
            precision: F::NAME,
            budget,
            n_slabs: system.n_slabs(),
        }
    }

    fn describe(&self) -> String {
        let gb = |b: usize| b as f64 / 1e9;
        match self.slabs_per_factor {
            1 => format!(
                "one factor per slab in {} ({:.2} GB each at most, budget {:.1} GB a level)",
                self.precision,
                gb(self.factor_bytes),
                gb(self.budget)
            ),
            n if n <= self.n_slabs => format!(
                "one slab factor in {} takes up to {:.2} GB: {n} neighbouring slabs share the \
                 factor of their mean to stay within the {:.1} GB budget a level",
                self.precision,
                gb(self.factor_bytes),
                gb(self.budget)
            ),
            _ => format!(
                "one slab factor takes up to {:.2} GB and does not fit the {:.1} GB budget: \
                 Jacobi, no factors",
                gb(self.factor_bytes),
                gb(self.budget)
            ),
        }
    }

    /// One [`SlabSweeps`] per system, all factors computed in one parallel pass (in `spare`'s
    /// buffers where it has some).
    fn factor<F: SlabFactor>(
        &self,
        levels: &[&SpaceTimeSystem],
        spare: &SpareValues,
    ) -> Result<Vec<SlabSweeps<F>>, FlowError> {
        let g = self.slabs_per_factor;
        let groups: Vec<(usize, usize)> = (0..levels.len())
            .flat_map(|l| (0..levels[l].n_slabs().div_ceil(g)).map(move |k| (l, k)))
            .collect();
        let mut factors = groups
            .par_iter()
            .map(|&(l, k)| {
                let system = levels[l];
                let slabs = k * g..((k + 1) * g).min(system.n_slabs());
                let what = match (l, g) {
                    (0, 1) => format!("slab {}", slabs.start),
                    (0, _) => format!("slabs {}..{}", slabs.start, slabs.end),
                    _ => format!("merged slab {} of time level {l}", slabs.start),
                };
                let mean = (g > 1).then(|| system.mean_block(slabs.clone()));
                let block = match &mean {
                    Some(values) => system.block_pattern().view(values),
                    None => system.block(slabs.start),
                };
                F::factor(self.symbolic, block, spare).map_err(factorization_error(what))
            })
            .collect::<Result<Vec<_>, _>>()?
            .into_iter();
        Ok(levels
            .iter()
            .map(|level| {
                let n = level.n_slabs();
                let own = factors.by_ref().take(n.div_ceil(g)).collect();
                SlabSweeps::new(own, g, n)
            })
            .collect())
    }
}

fn direct(
    system: &SpaceTimeSystem,
    observer: &dyn SolveObserver,
    reason: String,
) -> Result<Solution, FlowError> {
    observer.notify(SolveEvent::Factorizing { slabs: 0 })?;
    let start = Instant::now();
    let matrix = system.to_sparse();
    let symbolic = analyze(matrix.symbolic(), 2);
    let par = Par::rayon(rayon::current_num_threads());
    let factor = CholeskyFactor::<f64>::new(&symbolic, matrix.as_ref(), par)
        .map_err(factorization_error("the space-time system".into()))?;
    let factor_seconds = start.elapsed().as_secs_f64();
    let mut u = system.rhs().to_vec();
    factor.solve_in_place(&mut u, par);
    Ok(Solution {
        factor_seconds,
        factor_entries: factor.entries(),
        ..Solution::exact(u, SolverMethod::Direct, reason)
    })
}

fn slabwise_direct(
    system: &SpaceTimeSystem,
    observer: &dyn SolveObserver,
    reason: String,
) -> Result<Solution, FlowError> {
    observer.notify(SolveEvent::Factorizing {
        slabs: system.n_slabs(),
    })?;
    let start = Instant::now();
    let symbolic = system.slab_symbolic();
    let n = system.slab_dimension();
    let mut u = system.rhs().to_vec();
    let entries: Vec<FactorEntries> = u
        .par_chunks_mut(n)
        .enumerate()
        .map(|(s, us)| {
            let factor = CholeskyFactor::<f64>::new(symbolic, system.block(s), Par::Seq)
                .map_err(factorization_error(format!("slab {s}")))?;
            factor.solve_in_place(us, Par::Seq);
            Ok(factor.entries())
        })
        .collect::<Result<_, FlowError>>()?;
    Ok(Solution {
        factor_seconds: start.elapsed().as_secs_f64(),
        factor_entries: entries.into_iter().sum(),
        ..Solution::exact(u, SolverMethod::SlabwiseDirect, reason)
    })
}
