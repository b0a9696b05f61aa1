//! What the solves of a run (coarse-to-fine warping, robust reweighting) hand on to each other
//! besides the flow they start from ([`super::WarmStart`]): the buffers of their `f32` slab
//! factors, and a solve's whole preconditioner where the next system differs from its own by
//! the data term's re-linearization alone.
//!
//! **Recycled buffers.** A slab factor is a large buffer (36 MB at paper size) whose pages each
//! fault on first touch; the run's pool ([`SpareValues`]) takes the `f32` factors' buffers at
//! the end of a solve and gives them to the next solve's factorizations.
//!
//! **Kept factors.** Within a warping level every warp solves `A' u = b'` whose blocks differ
//! from the last warp's `A` only in the data term `Σ_c w_c ∇I_c ∇I_cᵀ`, re-linearized at the
//! images warped by the last flow: the smoothness, the time links and their weights are the
//! same. Preconditioned by `A`'s factors (slab Gauss–Seidel sweeps or multigrid in time with
//! `A`'s levels) CG still solves `A' u = b'` (it multiplies by `A'`; the preconditioner only
//! has to be symmetric positive definite), and it needs about as many iterations as with
//! `A'`'s own, because what limits them is the time coupling and the near-null space of the
//! smoothness, which the re-linearization leaves alone. Measured on 2 cores, `--large-motion`
//! (two warps a level), the second warps' iterations with their own factors and with the first
//! warps': the Stanford bunny sequence (multigrid) 6 / 8 / 9 / 10 and the same; the paper-size
//! torus (slab Gauss–Seidel) 6 / 12 / 14 and 5 / 11 / 14; the zebrafish recording 4 / 4 / 4 / 5
//! and 4 / 4 / 5 / 8 (docs/scaling.md, "Factors kept for a level's next warp").
//!
//! Not between levels (`γ` doubles from level to level: the bunny's run went from 45 s to
//! more than 7 minutes), nor between robust reweightings (their weights change the smoothness
//! everywhere: the zebrafish recording's 5 iterations a reweighting became 17–24). Kept
//! factors are not exact blocks, so slab Gauss–Seidel runs its sweeps rather than the odd slabs'
//! elimination ([`super::reduced`]), which needs exact ones.

use super::precondition::SlabSweeps;
use crate::linalg::bfloat::Bf16Factor;
use crate::linalg::cholesky::CholeskyFactor;
use crate::linalg::factor::{SlabFactor, SpareValues};
use crate::linalg::packed::PackedFactor;
use std::any::Any;
use std::sync::{Mutex, PoisonError};

/// How a solve of a run uses the factors of the run's previous solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FactorReuse {
    /// This solve's system differs from the previous solve's by the re-linearized data term
    /// alone: it is preconditioned with the factors that solve kept.
    pub take: bool,
    /// The next solve's system will differ from this one's by that alone: this solve keeps its
    /// factors for it.
    pub keep: bool,
}

/// The factors a run's solves hand on: a pool of `f32` buffers and the last solve's
/// preconditioner when it was kept.
pub struct RunFactors {
    spare: SpareValues,
    kept: Mutex<Option<Kept>>,
}

/// A solve's levels of slab sweeps (one: slab Gauss–Seidel; more: multigrid in time, finest
/// first), as `Vec<SlabSweeps<F>>` for the factor type `F` they ended with, and the shape of
/// the system they factor.
struct Kept {
    levels: Box<dyn Any + Send>,
    shape: Shape,
}

/// Slabs and unknowns per slab of a system.
pub(super) type Shape = (usize, usize);

/// A run's solve: its [`RunFactors`] and how it uses them.
#[derive(Clone, Copy)]
pub struct InRun<'a> {
    pub factors: &'a RunFactors,
    pub reuse: FactorReuse,
}

/// What a solve does with kept levels of whatever factor type they have ([`RunFactors::take`]).
pub(super) trait WithLevels {
    type Output;
    fn with<F: SlabFactor>(self, levels: Vec<SlabSweeps<F>>) -> Self::Output;
}

impl RunFactors {
    /// A run over `n_slabs` slabs: the pool holds one factor's buffer per slab.
    pub fn new(n_slabs: usize) -> Self {
        Self {
            spare: SpareValues::with_capacity(n_slabs),
            kept: Mutex::new(None),
        }
    }

    /// The pool of `f32` buffers the run's factorizations take from.
    pub fn spare(&self) -> &SpareValues {
        &self.spare
    }

    /// Keeps `levels`, the factors of a system of `shape`, for the next solve.
    fn keep<F: SlabFactor>(&self, levels: Vec<SlabSweeps<F>>, shape: Shape) {
        let levels = Box::new(levels);
        *self.lock() = Some(Kept { levels, shape });
    }

    /// The kept levels, if they factor a system of `shape`, handed to `with`; `None` (and the
    /// levels given up) otherwise.
    fn take<W: WithLevels>(&self, shape: Shape, with: W) -> Option<W::Output> {
        let kept = self.lock().take()?;
        if kept.shape != shape {
            Self::give_up(kept.levels, &self.spare);
            return None;
        }
        with_levels(kept.levels, with)
    }

    /// Gives up the kept levels, if any, their `f32` buffers to the pool: before a solve that
    /// factors its own, so that the two never take memory at once.
    fn release(&self) {
        if let Some(kept) = self.lock().take() {
            Self::give_up(kept.levels, &self.spare);
        }
    }

    fn give_up(levels: Box<dyn Any + Send>, spare: &SpareValues) {
        struct Recycle<'a>(&'a SpareValues);
        impl WithLevels for Recycle<'_> {
            type Output = ();
            fn with<F: SlabFactor>(self, levels: Vec<SlabSweeps<F>>) {
                recycle(levels, self.0);
            }
        }
        with_levels(levels, Recycle(spare));
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Kept>> {
        self.kept.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl InRun<'_> {
    /// Where this solve takes the previous solve's factors (and they factor a system of
    /// `shape`), `with` applied to them; otherwise `None`, any kept factors given up first.
    pub(super) fn take_kept<W: WithLevels>(self, shape: Shape, with: W) -> Option<W::Output> {
        if self.reuse.take {
            if let Some(output) = self.factors.take(shape, with) {
                return Some(output);
            }
        }
        self.factors.release();
        None
    }

    /// This solve's `levels` (of a system of `shape`) kept for the next solve where
    /// [`FactorReuse::keep`] says so, otherwise given up, their `f32` buffers to the pool.
    pub(super) fn hand_on<F: SlabFactor>(self, levels: Vec<SlabSweeps<F>>, shape: Shape) {
        match self.reuse.keep {
            true => self.factors.keep(levels, shape),
            false => recycle(levels, &self.factors.spare),
        }
    }
}

/// Gives up `levels`, their `f32` buffers to `spare` ([`SlabSweeps::recycle`]).
fn recycle<F: SlabFactor>(levels: Vec<SlabSweeps<F>>, spare: &SpareValues) {
    levels.into_iter().for_each(|l| l.recycle(spare));
}

/// The pool a factorization of type `F` takes its buffers from: the run's where `F` recycles
/// them ([`SlabFactor::RECYCLES`]), otherwise `per_thread`.
pub(super) fn spare_for<'s, F: SlabFactor>(
    run: Option<InRun<'s>>,
    per_thread: &'s SpareValues,
) -> &'s SpareValues {
    match run {
        Some(run) if F::RECYCLES => run.factors.spare(),
        _ => per_thread,
    }
}

/// `with` applied to `levels`, whichever of the solver's factor types they hold (`None`, the
/// levels dropped, for any other type).
fn with_levels<W: WithLevels>(levels: Box<dyn Any + Send>, with: W) -> Option<W::Output> {
    fn of<F: SlabFactor, W: WithLevels>(
        levels: Box<dyn Any + Send>,
        with: W,
    ) -> Result<W::Output, (Box<dyn Any + Send>, W)> {
        match levels.downcast::<Vec<SlabSweeps<F>>>() {
            Ok(levels) => Ok(with.with(*levels)),
            Err(levels) => Err((levels, with)),
        }
    }
    of::<PackedFactor<f32>, W>(levels, with)
        .or_else(|(levels, with)| of::<Bf16Factor, W>(levels, with))
        .or_else(|(levels, with)| of::<CholeskyFactor<f64>, W>(levels, with))
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::solve::{solve, Solution, WarmStart};
    use crate::flow::warp::warped_slab;
    use crate::flow::{scale_pyramid, FlowParams, FlowProblem, SolverChoice, SpaceTimeSystem};
    use nalgebra::Vector2;

    /// The paper's torus and its system, and the system of the next warp: every slab's images
    /// warped halfway by a flow of a tenth of the torus's tube radius per frame.
    fn two_warps(params: &FlowParams) -> (SpaceTimeSystem, SpaceTimeSystem) {
        let sequence = crate::synth::paper_torus(12, 9, 7).unwrap();
        let first = FlowProblem::new(&sequence, params)
            .unwrap()
            .system()
            .clone();
        let images = scale_pyramid(&sequence, 1).unwrap().remove(0);
        let u = vec![Vector2::new(0.03, -0.02); sequence.mesh().n_vertices()];
        let slabs = (0..sequence.n_slabs())
            .map(|s| {
                let frames = (images.frame(s), images.frame(s + 1));
                warped_slab(&sequence, s, frames, &u, &[1.0]).unwrap()
            })
            .collect();
        let next = FlowProblem::from_slabs(&sequence, params, slabs).unwrap();
        (first, next.system().clone())
    }

    fn solve_in(
        system: &SpaceTimeSystem,
        params: &FlowParams,
        start: Option<&Solution>,
        run: Option<InRun<'_>>,
    ) -> Solution {
        let start = start.map(|s| WarmStart {
            u: s.u.clone(),
            method: s.method,
        });
        solve(system, params, start.as_ref(), run, &|_| {}).unwrap()
    }

    /// A level's second warp preconditioned with the first warp's kept factors (slab
    /// Gauss–Seidel at `α = 1`, multigrid in time asked for) converges to the flow its own
    /// factors give, in about as many iterations; the kept factors serve one solve, and a
    /// system of another shape factors its own.
    #[test]
    fn the_next_warp_converges_with_the_factors_the_last_one_kept() {
        for solver in [SolverChoice::Auto, SolverChoice::PcgTimeMultigrid] {
            let params = FlowParams {
                solver,
                direct_limit: 0,
                tolerance: 1e-10,
                ..FlowParams::paper(1.0, 0.0, 1.0)
            };
            let (first, next) = two_warps(&params);
            let factors = RunFactors::new(first.n_slabs());
            let step = |take, keep| {
                Some(InRun {
                    factors: &factors,
                    reuse: FactorReuse { take, keep },
                })
            };
            let solved = solve_in(&first, &params, None, step(false, true));
            let own = solve_in(&next, &params, Some(&solved), None);
            let kept = solve_in(&next, &params, Some(&solved), step(true, false));
            println!(
                "{solver:?}: {} iterations with its own factors, {} with the kept ones ({})",
                own.iterations, kept.iterations, kept.reason
            );
            assert!(kept.reason.contains("kept"), "{}", kept.reason);
            assert!(!own.reason.contains("kept"), "{}", own.reason);
            assert_eq!(kept.method, own.method);
            assert!(
                kept.relative_residual <= 1e-10,
                "{}",
                kept.relative_residual
            );
            assert!(kept.iterations <= own.iterations + 3, "{solver:?}");
            let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let difference: Vec<f64> = kept.u.iter().zip(&own.u).map(|(a, b)| a - b).collect();
            assert!(norm(&difference) <= 1e-7 * norm(&own.u), "{solver:?}");
            // Nothing is kept after a solve that keeps nothing.
            let again = solve_in(&next, &params, Some(&solved), step(true, false));
            assert!(!again.reason.contains("kept"), "{}", again.reason);
            // Kept factors of another shape are given up, not used.
            solve_in(&first, &params, None, step(false, true));
            let shorter = crate::synth::paper_torus(12, 9, 5).unwrap();
            let shorter = FlowProblem::new(&shorter, &params)
                .unwrap()
                .system()
                .clone();
            let fresh = solve_in(&shorter, &params, None, step(true, false));
            assert!(!fresh.reason.contains("kept"), "{}", fresh.reason);
            assert!(fresh.relative_residual <= 1e-10);
        }
    }
}
