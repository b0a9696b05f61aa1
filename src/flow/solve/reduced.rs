//! Slab Gauss–Seidel's iterations on the odd slabs alone: the even slabs eliminated.
//!
//! With the slabs in odd–even order, `A = [D_E Cᵀ; C D_O]` (`D_E`, `D_O` the even and odd slab
//! blocks, `C` the links' terms from even to odd slabs). The symmetric sweep of
//! [`SlabSweeps`], `M = (D + L) D⁻¹ (D + U)`, differs from `A` in the odd block alone,
//! `M − A = diag(0, C D_E⁻¹ Cᵀ)`, so apart from the eigenvalue 1 the spectrum of `M⁻¹A` is that
//! of `D_O⁻¹ S` for the even slabs' Schur complement
//!
//! ```text
//! S = D_O − C D_E⁻¹ Cᵀ,   A d = r  ⇔  S d_O = r_O − C D_E⁻¹ r_E,   d_E = D_E⁻¹ (r_E − Cᵀ d_O).
//! ```
//!
//! PCG on `S` preconditioned by `D_O` therefore converges as slab Gauss–Seidel's PCG does, but
//! an iteration solves each slab once (`D_E⁻¹` in the product with `S`, `D_O⁻¹` in the
//! preconditioner) where the symmetric sweep solves the even slabs twice, and its vectors are
//! the odd slabs' (the reduced system of a red–black ordering: Saad, *Iterative Methods for
//! Sparse Linear Systems*, 2nd ed., 2003, §4.3).
//!
//! The factors are single precision, so the `S` the iterations see is that of the factors'
//! `D̃_E`: on the paper-size frames an elimination leaves about `10⁻⁴` of the residual it
//! starts from. Hence rounds of iterative refinement (Higham, *Accuracy and Stability of
//! Numerical Algorithms*, 2nd ed., 2002, ch. 12): each solves the reduced system for the
//! correction of the whole system's true residual, to [`ROUND_REDUCTION`] of it or to the
//! tolerance, two rounds for the default tolerance. A round's restart would lose what CG had
//! learnt of the spectrum (3 iterations of 19 there), so later rounds start deflated by the
//! first round's directions ([`Directions`]), and lose one. Each round also costs two half
//! sweeps of the even slabs (the right-hand side and the correction's even slabs) and one of
//! the odd ones (its first preconditioning): about three iterations' worth of the solves an
//! iteration saves, so it pays from about ten iterations on.
//!
//! Measured against slab Gauss–Seidel's PCG on the whole system: docs/scaling.md, "Slab
//! Gauss–Seidel on the odd slabs alone".

use super::multigrid::residual;
use super::pcg::{self, CgOutcome, Directions, Operator, Preconditioner, Recycling, Stop};
use super::precondition::{subtract, Parity, SlabSweeps, Whole};
use super::{probe_give_up, SolveObserver};
use crate::flow::system::{dot, SpaceTimeSystem};
use crate::flow::FlowError;
use crate::linalg::factor::SlabFactor;
use rayon::prelude::*;
use std::cell::RefCell;

/// How far a round of refinement reduces the whole residual when the tolerance lies further:
/// its CG stops at this share of the residual the round starts from. The elimination's
/// rounding leaves about `10⁻⁴` of it, so this share brings `10⁻⁸` within two rounds.
pub const ROUND_REDUCTION: f64 = 3e-5;

/// The share of the tolerance the last round's CG aims at, below the tolerance by what the
/// elimination's rounding adds to the whole residual.
pub const LAST_ROUND_MARGIN: f64 = 0.5;

/// Solves `A x = b` (the system's right-hand side) from `x` as slab Gauss–Seidel's PCG does
/// under `stop`, on the odd slabs' reduced system in rounds of refinement (module docs). The
/// first round probes with `stop.give_up` when given, and its Lanczos spectrum is the run's.
/// Returns when the tolerance is reached, the iterations are spent, the probe gives up
/// (`gave_up` set), or a round is too slow (as `auto`'s probe judges it) or fails to halve the
/// residual (`gave_up` not set: the caller goes on with the whole system). `relative_residual`
/// is the true one, `‖b − A x‖ / ‖b‖`, and `x` the whole system's.
pub fn odd_slab_pcg<F: SlabFactor>(
    system: &SpaceTimeSystem,
    sweeps: &SlabSweeps<F>,
    mut x: Vec<f64>,
    stop: Stop,
    observer: &dyn SolveObserver,
) -> Result<CgOutcome, FlowError> {
    let b = system.rhs();
    let b_norm = dot(b, b).sqrt();
    let odd = OddSlabs::new(system, sweeps);
    let mut r = match x.par_iter().any(|x| *x != 0.0) {
        true => residual(system, b, &x),
        false => b.to_vec(),
    };
    let mut outcome = CgOutcome {
        x: Vec::new(),
        iterations: stop.done,
        relative_residual: if b_norm > 0.0 {
            dot(&r, &r).sqrt() / b_norm
        } else {
            0.0
        },
        gave_up: None,
        spectrum: None,
    };
    let mut first_round = Directions::default();
    let mut spectrum = None;
    for round in 0.. {
        let started = outcome.relative_residual;
        if started <= stop.tolerance || outcome.iterations >= stop.max_iterations {
            break;
        }
        let goal = round_tolerance(started, stop.tolerance);
        // A round too slow for its stopping point, as `auto`'s probe judges slab Gauss–Seidel:
        // where the even slabs are far better conditioned than the reduced system (a time
        // coupling that nearly cancels `D_O`, small `α`), the elimination's rounding leaves `S`
        // too inexact for CG, and the whole system's PCG goes on from the rounds' iterate.
        let round_stop = Stop {
            tolerance: goal,
            done: outcome.iterations,
            give_up: Some(match (round, stop.give_up) {
                (0, Some(probe)) => probe,
                _ => probe_give_up(goal, false),
            }),
            reference: Some(b_norm),
            ..stop
        };
        let g = odd.schur_rhs(&r);
        let recycling = match round {
            0 => Recycling::Keep(&mut first_round),
            _ => Recycling::StartFrom(&first_round),
        };
        let (zero, cg) = (vec![0.0; g.len()], (round_stop, observer));
        outcome = pcg::pcg_recycling(&odd, &g, zero, &odd, cg, recycling)?;
        spectrum = spectrum.or(outcome.spectrum);
        let correction = odd.whole_correction(&r, &outcome.x);
        r = add_correction(system, b, &correction, &mut x);
        outcome.relative_residual = dot(&r, &r).sqrt() / b_norm;
        let probed = round == 0 && stop.give_up.is_some();
        let halved = outcome.relative_residual <= 0.5 * started;
        if outcome.gave_up.is_some() || !halved {
            outcome.gave_up = outcome.gave_up.filter(|_| probed);
            break;
        }
    }
    outcome.x = x;
    outcome.spectrum = spectrum;
    Ok(outcome)
}

/// Where a round that starts at the whole residual `started` stops its CG: at
/// [`ROUND_REDUCTION`] of it, or at [`LAST_ROUND_MARGIN`] of the tolerance where that is as far.
fn round_tolerance(started: f64, tolerance: f64) -> f64 {
    match ROUND_REDUCTION * started > tolerance {
        true => ROUND_REDUCTION * started,
        false => LAST_ROUND_MARGIN * tolerance,
    }
}

/// `x += d`, then `b − A x`.
fn add_correction(system: &SpaceTimeSystem, b: &[f64], d: &[f64], x: &mut [f64]) -> Vec<f64> {
    x.par_iter_mut().zip(d).for_each(|(x, d)| *x += d);
    residual(system, b, x)
}

/// The reduced system on the odd slabs of a whole system: its vectors hold the odd slabs
/// packed (slab `2k + 1` as block `k`); the operator is `S`, the preconditioner `D_O⁻¹`.
struct OddSlabs<'a, F: SlabFactor> {
    system: &'a SpaceTimeSystem,
    sweeps: &'a SlabSweeps<F>,
    /// Two whole-system vectors for the products with `S`.
    scratch: RefCell<[Vec<f64>; 2]>,
}

impl<'a, F: SlabFactor> OddSlabs<'a, F> {
    fn new(system: &'a SpaceTimeSystem, sweeps: &'a SlabSweeps<F>) -> Self {
        let whole = || vec![0.0; system.dimension()];
        Self {
            system,
            sweeps,
            scratch: RefCell::new([whole(), whole()]),
        }
    }

    /// The odd slabs of the whole-system vector `whole`, packed.
    fn pack(&self, whole: &[f64], packed: &mut [f64]) {
        let n = self.system.slab_dimension();
        (packed.par_chunks_mut(n))
            .zip(whole.par_chunks(n).skip(1).step_by(2))
            .for_each(|(p, w)| p.copy_from_slice(w));
    }

    /// `whole`'s odd slabs from `packed`; its even slabs are left alone.
    fn unpack(&self, packed: &[f64], whole: &mut [f64]) {
        let n = self.system.slab_dimension();
        (whole.par_chunks_mut(n).skip(1).step_by(2))
            .zip(packed.par_chunks(n))
            .for_each(|(w, p)| w.copy_from_slice(p));
    }

    /// `g = r_O − C D_E⁻¹ r_E`, packed: the reduced right-hand side of `A d = r`.
    fn schur_rhs(&self, r: &[f64]) -> Vec<f64> {
        let (system, n) = (self.system, self.system.slab_dimension());
        let mut even = r.to_vec();
        self.sweeps
            .half_sweep(system, &mut even, Parity::Even, false, &Whole);
        let coupling = self
            .sweeps
            .neighbour_terms(system, &even, Parity::Odd, &Whole);
        let mut g = vec![0.0; system.n_slabs() / 2 * n];
        self.pack(r, &mut g);
        (g.par_chunks_mut(n))
            .zip(coupling)
            .for_each(|(gs, c)| subtract(gs, &c));
        g
    }

    /// The whole system's `d` with odd slabs `d_O` (packed) and even slabs
    /// `d_E = D_E⁻¹ (r_E − Cᵀ d_O)`.
    fn whole_correction(&self, r: &[f64], d_odd: &[f64]) -> Vec<f64> {
        let mut d = r.to_vec();
        self.unpack(d_odd, &mut d);
        self.sweeps
            .half_sweep(self.system, &mut d, Parity::Even, true, &Whole);
        d
    }
}

impl<F: SlabFactor> Operator for OddSlabs<'_, F> {
    /// `y = S x = D_O x − C D_E⁻¹ Cᵀ x`: the odd rows of `A z` for `z = (−D_E⁻¹ Cᵀ x, x)`.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let [z, az] = &mut *self.scratch.borrow_mut();
        let n = self.system.slab_dimension();
        (z.par_chunks_mut(n).step_by(2)).for_each(|zs| zs.fill(0.0));
        self.unpack(x, z);
        self.sweeps
            .half_sweep(self.system, z, Parity::Even, true, &Whole);
        let odd = |s: usize| s % 2 == Parity::Odd as usize;
        self.system.apply_rows(z, az, odd);
        self.pack(az, y);
    }

    fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        dot(x, y)
    }
}

impl<F: SlabFactor> Preconditioner for OddSlabs<'_, F> {
    /// `z = D_O⁻¹ r`.
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        let n = self.system.slab_dimension();
        let slabs = z.chunks_mut(n).enumerate();
        let odd = slabs.map(|(k, zs)| (2 * k + 1, zs)).collect();
        self.sweeps.solve_slabs(odd, None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::solve::precondition::SlabGaussSeidel;
    use crate::flow::system::for_each_column;
    use crate::flow::{FlowParams, FlowProblem, TimeCoupling};
    use crate::linalg::cholesky::CholeskyFactor;
    use crate::linalg::factor::SpareValues;
    use crate::linalg::packed::PackedFactor;
    use nalgebra::{DMatrix, DVector};

    /// A torus with a time coupling that matters (`α = 1`), for an even and an odd slab count
    /// and both couplings.
    fn systems() -> Vec<SpaceTimeSystem> {
        [(6, TimeCoupling::Lumped), (7, TimeCoupling::Consistent)]
            .into_iter()
            .map(|(frames, coupling)| {
                let sequence = crate::synth::paper_torus(8, 6, frames).unwrap();
                let params = FlowParams {
                    time_coupling: coupling,
                    ..FlowParams::paper(1.0, 0.0, 1.0)
                };
                FlowProblem::new(&sequence, &params)
                    .unwrap()
                    .system()
                    .clone()
            })
            .collect()
    }

    fn sweeps<F: SlabFactor>(system: &SpaceTimeSystem) -> SlabSweeps<F> {
        let symbolic = system.slab_symbolic();
        let factors = (0..system.n_slabs())
            .map(|s| F::factor(symbolic, system.block(s), &SpareValues::per_thread()).unwrap())
            .collect();
        SlabSweeps::new(factors, 1, system.n_slabs())
    }

    fn dense(system: &SpaceTimeSystem) -> DMatrix<f64> {
        let n = system.dimension();
        let mut a = DMatrix::<f64>::zeros(n, n);
        for_each_column(system.to_sparse().as_ref(), |j, rows, values| {
            rows.iter().zip(values).for_each(|(&i, &v)| a[(i, j)] += v);
        });
        a
    }

    /// The whole-system indices of the slabs of parity `odd`.
    fn indices(system: &SpaceTimeSystem, odd: usize) -> Vec<usize> {
        let n = system.slab_dimension();
        (0..system.dimension())
            .filter(|i| (i / n) % 2 == odd)
            .collect()
    }

    fn wave(n: usize, k: f64) -> Vec<f64> {
        (0..n).map(|i| (k * i as f64).cos()).collect()
    }

    /// With exact factors the product is the dense Schur complement `A_OO − A_OE A_EE⁻¹ A_EO`,
    /// and the reduced right-hand side, solved densely and completed on the even slabs, gives
    /// `A⁻¹ r`.
    #[test]
    fn the_reduced_system_is_the_schur_complement_and_solves_the_whole() {
        for system in systems() {
            let exact = sweeps::<CholeskyFactor<f64>>(&system);
            let odd = OddSlabs::new(&system, &exact);
            let a = dense(&system);
            let (e, o) = (indices(&system, 0), indices(&system, 1));
            let block = |rows: &[usize], cols: &[usize]| a.select_rows(rows).select_columns(cols);
            let a_ee_inverse = block(&e, &e).try_inverse().unwrap();
            let schur = block(&o, &o) - block(&o, &e) * a_ee_inverse * block(&e, &o);
            let x = wave(o.len(), 0.37);
            let mut y = vec![0.0; o.len()];
            Operator::apply(&odd, &x, &mut y);
            let want = &schur * DVector::from_column_slice(&x);
            let error = (DVector::from_vec(y) - &want).amax();
            assert!(error < 1e-10 * want.amax(), "S x: {error:e}");

            let r = wave(system.dimension(), 0.71);
            let g = odd.schur_rhs(&r);
            let d_odd = schur.clone().lu().solve(&DVector::from_vec(g)).unwrap();
            let d = odd.whole_correction(&r, d_odd.as_slice());
            let want = a.clone().lu().solve(&DVector::from_vec(r)).unwrap();
            let error = (DVector::from_vec(d) - &want).amax();
            assert!(error < 1e-9 * want.amax(), "A⁻¹ r: {error:e}");
        }
    }

    /// With single-precision factors the rounds reach the tolerance in the true residual, the
    /// solution is the whole system's PCG's, and the iterations are at most one more than
    /// slab Gauss–Seidel's on the whole system (the rounds' cost; the first round's directions
    /// win back the restart).
    #[test]
    fn rounds_reach_the_tolerance_with_single_precision_factors() {
        for system in systems() {
            let sweeps = sweeps::<PackedFactor<f32>>(&system);
            let stop = Stop::new(1e-8, 500);
            let reduced = odd_slab_pcg(
                &system,
                &sweeps,
                vec![0.0; system.dimension()],
                stop,
                &|_| {},
            )
            .unwrap();
            let whole = SlabGaussSeidel::new(&system, &sweeps);
            let zero = vec![0.0; system.dimension()];
            let b = system.rhs();
            let reference = pcg::pcg(&system, b, zero, &whole, stop, &|_| {}).unwrap();
            let true_residual = crate::flow::solve::relative_residual(&system, b, &reduced.x);
            println!(
                "{} slabs: {} iterations (whole system {}), residual {true_residual:.2e}",
                system.n_slabs(),
                reduced.iterations,
                reference.iterations
            );
            assert!(true_residual <= 1e-8, "{true_residual:e}");
            assert!((reduced.relative_residual - true_residual).abs() < 1e-3 * true_residual);
            assert!(reduced.iterations <= reference.iterations + 1);
            let difference = reduced.x.iter().zip(&reference.x);
            let error = difference.fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            let scale = reference.x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(error < 1e-6 * scale, "{error:e} of {scale:e}");
        }
    }
}
