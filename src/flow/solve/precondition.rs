//! Preconditioners for the block-tridiagonal space-time system.

use super::pcg::Preconditioner;
use crate::flow::system::SpaceTimeSystem;
use crate::linalg::cholesky::FactorEntries;
use crate::linalg::factor::{SlabFactor, SpareValues};
use crate::linalg::packed::Halves;
use rayon::prelude::*;

/// `z = r / diag(A)`: no setup, no memory, iteration counts grow with refinement.
pub struct Jacobi {
    inverse_diagonal: Vec<f64>,
}

impl Jacobi {
    pub fn new(system: &SpaceTimeSystem) -> Self {
        Self {
            inverse_diagonal: system.diagonal().iter().map(|d| 1.0 / d).collect(),
        }
    }
}

impl Preconditioner for Jacobi {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.par_iter_mut()
            .zip(r)
            .zip(&self.inverse_diagonal)
            .for_each(|((z, r), d)| *z = r * d);
    }
}

/// Exact slab solves swept through time in odd–even order: with `D` the slab blocks
/// (Cholesky factors) and the slabs ordered even first, then odd, `L` the links below the
/// diagonal in that order (odd rows, even columns) and `U = Lᵀ`, the forward sweep applies
/// `(D + L)⁻¹`,
///
/// ```text
/// z_s = D_s⁻¹ r_s (s even),      z_s = D_s⁻¹ (r_s − X_{s−1} z_{s−1} − X_sᵀ z_{s+1}) (s odd),
/// ```
///
/// and the backward sweep `(D + U)⁻¹` the same with the parities exchanged. The slabs of one
/// parity do not touch each other, so each half sweep solves them all in parallel: the sweep
/// is parallel in time however few cores or however many ranks share the slabs, and stays an
/// exact block Gauss–Seidel sweep (of the reordered system).
///
/// Why not the lexicographic sweep split into one contiguous chunk per core (the first
/// release's choice): between chunks it is block *Jacobi*, and where the time coupling
/// dominates the slab blocks (`D_s ≈ c M`, `X_s ≈ −c M` in the dark, textureless parts of a
/// fluorescence recording, where only `γ L` and the coupling remain) block Jacobi maps the
/// error that alternates in time, `(e, −e)`, to about `−(e, −e)`: it does not smooth it, and
/// the coarse levels (constant in time) cannot see it. On the zebrafish recording (2 slabs on
/// 2 cores: one chunk per slab) multigrid in time took 158 iterations with chunks and 6
/// without.
///
/// When the factors of all slabs would not fit in memory, runs of `slabs_per_factor`
/// neighbouring slabs share the factor of their mean block: `D_s` is then replaced by a
/// neighbour average, still symmetric positive definite, so the sweeps remain a valid
/// preconditioner (a weaker one, as the slabs differ).
pub struct SlabSweeps<F: SlabFactor> {
    factors: Vec<F>,
    slabs_per_factor: usize,
}

/// Which slabs a half sweep solves.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Parity {
    Even = 0,
    Odd = 1,
}

impl<F: SlabFactor> SlabSweeps<F> {
    /// `factors[g]` must factor the mean of blocks `g·slabs_per_factor ..` (up to
    /// `slabs_per_factor` of them) of the `n_slabs` slabs of the system the sweeps are applied
    /// to.
    pub fn new(factors: Vec<F>, slabs_per_factor: usize, n_slabs: usize) -> Self {
        assert_eq!(
            factors.len(),
            n_slabs.div_ceil(slabs_per_factor),
            "one factor per group"
        );
        Self {
            factors,
            slabs_per_factor,
        }
    }

    fn factor(&self, slab: usize) -> &F {
        &self.factors[slab / self.slabs_per_factor]
    }

    /// The same sweeps with the factors multigrid's levels use ([`SlabFactor::Compressed`]),
    /// the buffers given up left in `spare` for the levels' factorizations.
    pub fn compress(self, spare: &SpareValues) -> SlabSweeps<F::Compressed> {
        SlabSweeps {
            factors: (self.factors.into_par_iter())
                .map(|factor| factor.compress(spare))
                .collect(),
            slabs_per_factor: self.slabs_per_factor,
        }
    }

    /// Gives up the factors, their `f32` buffers to `spare` ([`SlabFactor::recycle`]).
    pub fn recycle(self, spare: &SpareValues) {
        self.factors.into_iter().for_each(|f| f.recycle(spare));
    }

    /// Entries of all factors.
    pub fn entries(&self) -> FactorEntries {
        self.factors.iter().map(F::entries).sum()
    }

    /// `z ← (D + L)⁻¹ z`: even slabs, then odd slabs with their even neighbours' values.
    pub fn forward(&self, system: &SpaceTimeSystem, z: &mut [f64], around: &dyn Surroundings) {
        self.half_sweep(system, z, Parity::Even, false, around);
        self.half_sweep(system, z, Parity::Odd, true, around);
    }

    /// `r − A z` for `z = (D + L)⁻¹ r`, the forward sweep's result: `(D + L) z = r` leaves
    /// `−U z`, which is `−(X_{s−1} z_{s−1} + X_sᵀ z_{s+1})` on the even slabs and zero on the
    /// odd ones. The links alone, no block products: half a product with `A` (the same
    /// identity [`Self::symmetric`] rests on; exact up to the factors' rounding).
    pub fn forward_residual(
        &self,
        system: &SpaceTimeSystem,
        z: &[f64],
        around: &dyn Surroundings,
    ) -> Vec<f64> {
        let mut residual = vec![0.0; z.len()];
        if !around.coupled(system) {
            return residual;
        }
        let coupled = self.neighbour_terms(system, z, Parity::Even, around);
        let n = system.slab_dimension();
        let slabs = slabs_of(&mut residual, n, Parity::Even, around.first_slab());
        (slabs.into_par_iter())
            .zip(coupled)
            .for_each(|((_, rs), c)| subtract(rs, &c));
        residual
    }

    /// `z ← (D + U)⁻¹ z`: odd slabs, then even slabs with their odd neighbours' values.
    pub fn backward(&self, system: &SpaceTimeSystem, z: &mut [f64], around: &dyn Surroundings) {
        self.half_sweep(system, z, Parity::Odd, false, around);
        self.half_sweep(system, z, Parity::Even, true, around);
    }

    /// `z ← z + (D + U)⁻¹ (r − A z)`, the backward sweep on the residual, without a product
    /// with `A`: the odd slabs become `D_s⁻¹ (r_s − (X z)_s)` from the even ones, then the even
    /// slabs the same from the new odd ones (the slab blocks cancel: exact up to the factors'
    /// rounding, as [`Self::forward_residual`]).
    pub fn backward_from(
        &self,
        system: &SpaceTimeSystem,
        r: &[f64],
        z: &mut [f64],
        around: &dyn Surroundings,
    ) {
        let (n, first) = (system.slab_dimension(), around.first_slab());
        for parity in [Parity::Odd, Parity::Even] {
            let rhs = r.chunks(n).enumerate();
            (z.chunks_mut(n).zip(rhs))
                .filter(|(_, (s, _))| (first + s) % 2 == parity as usize)
                .for_each(|(zs, (_, rs))| zs.copy_from_slice(rs));
            self.half_sweep(system, z, parity, true, around);
        }
    }

    /// `z ← (D + U)⁻¹ D (D + L)⁻¹ z`, the symmetric Gauss–Seidel sweep: the forward sweep, then
    /// `z_s ← z_s − D_s⁻¹ (X z)_s` for the even slabs (the odd ones keep their values).
    pub fn symmetric(&self, system: &SpaceTimeSystem, z: &mut [f64], around: &dyn Surroundings) {
        self.forward(system, z, around);
        if !around.coupled(system) {
            return;
        }
        let coupled = self.neighbour_terms(system, z, Parity::Even, around);
        let slabs = slabs_of(
            z,
            system.slab_dimension(),
            Parity::Even,
            around.first_slab(),
        );
        let halves = Halves::for_solves(slabs.len());
        (slabs.into_par_iter())
            .zip(coupled)
            .for_each(|((s, zs), mut c)| {
                self.factor(s).solve(&mut c, halves);
                subtract(zs, &c);
            });
    }

    /// Solves the slabs of `parity` in place, after subtracting their neighbours' coupling
    /// when `coupled`.
    pub(super) fn half_sweep(
        &self,
        system: &SpaceTimeSystem,
        z: &mut [f64],
        parity: Parity,
        coupled: bool,
        around: &dyn Surroundings,
    ) {
        let terms = (coupled && around.coupled(system))
            .then(|| self.neighbour_terms(system, z, parity, around));
        let slabs = slabs_of(z, system.slab_dimension(), parity, around.first_slab());
        self.solve_slabs(slabs, terms.as_deref());
    }

    /// `z_s ← D_s⁻¹ (z_s − less_k)` for the `k`-th of the given slabs `(s, z_s)` (`less_k = 0`
    /// without `less`), in parallel: each task subtracts, then solves, while its slab is warm.
    pub(super) fn solve_slabs(&self, slabs: Vec<(usize, &mut [f64])>, less: Option<&[Vec<f64>]>) {
        let halves = Halves::for_solves(slabs.len());
        slabs.into_par_iter().enumerate().for_each(|(k, (s, zs))| {
            if let Some(less) = less {
                subtract(zs, &less[k]);
            }
            self.factor(s).solve(zs, halves);
        });
    }

    /// `X_{s−1} z_{s−1} + X_sᵀ z_{s+1}` for each slab `s` of `parity`, in order; beyond the
    /// system's ends the coupling `around` gives.
    pub(super) fn neighbour_terms(
        &self,
        system: &SpaceTimeSystem,
        z: &[f64],
        parity: Parity,
        around: &dyn Surroundings,
    ) -> Vec<Vec<f64>> {
        let (before, after) = around.beyond(z);
        let (n, slabs, first) = (
            system.slab_dimension(),
            system.n_slabs(),
            around.first_slab(),
        );
        (0..slabs)
            .into_par_iter()
            .filter(|s| (first + s) % 2 == parity as usize)
            .map(|s| {
                let mut c = vec![0.0; n];
                match (s > 0, &before) {
                    (true, _) => system.link_mul(s - 1, &z[(s - 1) * n..s * n], &mut c),
                    (false, Some(term)) => add(&mut c, term),
                    (false, None) => {}
                }
                match (s + 1 < slabs, &after) {
                    (true, _) => system.link_transpose_mul(s, &z[(s + 1) * n..(s + 2) * n], &mut c),
                    (false, Some(term)) => add(&mut c, term),
                    (false, None) => {}
                }
                c
            })
            .collect()
    }
}

/// Where a system's slabs sit in the whole sequence and what couples them to slabs beyond its
/// ends: nothing for a whole system ([`Whole`]); a rank's window adds its neighbouring ranks'
/// slabs through its boundary links ([`super::distributed`]).
pub trait Surroundings {
    /// The index of the system's slab 0 in the whole sequence (the sweeps' parities are the
    /// sequence's).
    fn first_slab(&self) -> usize;
    /// Whether the slabs are coupled in time (the same answer on every rank).
    fn coupled(&self, system: &SpaceTimeSystem) -> bool;
    /// `(X_{a−1} z_{a−1}, X_{b−1}ᵀ z_b)`: the coupling of the system's first and last slab to
    /// the slabs beyond, for its values `z` (for a window, an exchange with the other ranks).
    fn beyond(&self, z: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>);
}

/// A whole system: slab 0 is the sequence's first, nothing lies beyond.
pub struct Whole;

impl Surroundings for Whole {
    fn first_slab(&self) -> usize {
        0
    }

    fn coupled(&self, system: &SpaceTimeSystem) -> bool {
        system.has_links()
    }

    fn beyond(&self, _: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        (None, None)
    }
}

/// The slabs of `parity` (counted from `first` in the sequence) as `(slab, values)`.
fn slabs_of(z: &mut [f64], n: usize, parity: Parity, first: usize) -> Vec<(usize, &mut [f64])> {
    (z.chunks_mut(n).enumerate())
        .filter(|(s, _)| (first + s) % 2 == parity as usize)
        .collect()
}

/// `z += c`.
pub(super) fn add(z: &mut [f64], c: &[f64]) {
    z.iter_mut().zip(c).for_each(|(z, c)| *z += c);
}

/// `z −= c`.
pub(super) fn subtract(z: &mut [f64], c: &[f64]) {
    z.iter_mut().zip(c).for_each(|(z, c)| *z -= c);
}

/// Symmetric block Gauss–Seidel in time, `P = (D + L) D⁻¹ (D + Lᵀ)`: one [`SlabSweeps`]
/// forward and back.
pub struct SlabGaussSeidel<'a, F: SlabFactor> {
    system: &'a SpaceTimeSystem,
    sweeps: &'a SlabSweeps<F>,
}

impl<'a, F: SlabFactor> SlabGaussSeidel<'a, F> {
    pub fn new(system: &'a SpaceTimeSystem, sweeps: &'a SlabSweeps<F>) -> Self {
        Self { system, sweeps }
    }
}

impl<F: SlabFactor> Preconditioner for SlabGaussSeidel<'_, F> {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        self.sweeps.symmetric(self.system, z, &Whole);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::{FlowParams, FlowProblem, TimeCoupling};
    use crate::linalg::cholesky::CholeskyFactor;

    /// Calls `check` with the system and exact (double-precision) slab sweeps of a small torus,
    /// for even and odd slab counts and lumped and consistent coupling.
    fn with_exact_sweeps(check: impl Fn(&SpaceTimeSystem, &SlabSweeps<CholeskyFactor<f64>>)) {
        for (frames, coupling) in [(5, TimeCoupling::Lumped), (6, TimeCoupling::Consistent)] {
            let sequence = crate::synth::paper_torus(8, 6, frames).unwrap();
            let params = FlowParams {
                time_coupling: coupling,
                ..FlowParams::paper(0.3, 0.0, 1.0)
            };
            let problem = FlowProblem::new(&sequence, &params).unwrap();
            let system = problem.system();
            let symbolic = system.slab_symbolic();
            let factors = (0..system.n_slabs())
                .map(|s| {
                    CholeskyFactor::<f64>::new(symbolic, system.block(s), faer::Par::Seq).unwrap()
                })
                .collect();
            check(system, &SlabSweeps::new(factors, 1, system.n_slabs()));
        }
    }

    /// `cos(k i)` for `i < n`.
    fn wave(n: usize, k: f64) -> Vec<f64> {
        (0..n).map(|i| (k * i as f64).cos()).collect()
    }

    /// `r − A z`.
    fn full_residual(system: &SpaceTimeSystem, r: &[f64], z: &[f64]) -> Vec<f64> {
        let mut residual = vec![0.0; r.len()];
        system.apply(z, &mut residual);
        residual.iter_mut().zip(r).for_each(|(e, r)| *e = r - *e);
        residual
    }

    /// `max |a − b|`.
    fn max_difference(a: &[f64], b: &[f64]) -> f64 {
        (a.iter().zip(b)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
    }

    /// `max |v|`.
    fn max_abs(v: &[f64]) -> f64 {
        v.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    /// After the forward sweep with exact slab factors, the links alone give `r − A z`: zero on
    /// the odd slabs, equal to the full product on the even ones.
    #[test]
    fn forward_residual_is_the_full_residual_after_the_forward_sweep() {
        with_exact_sweeps(|system, sweeps| {
            let r = wave(system.dimension(), 0.7);
            let mut z = r.clone();
            sweeps.forward(system, &mut z, &Whole);
            let expected = full_residual(system, &r, &z);
            let residual = sweeps.forward_residual(system, &z, &Whole);
            let scale = max_abs(&expected);
            assert!(scale > 1e-3, "a residual to compare: {scale:e}");
            let n = system.slab_dimension();
            let slabs = residual.chunks(n).zip(expected.chunks(n));
            for (s, (got, want)) in slabs.enumerate() {
                let error = max_difference(got, want);
                assert!(error < 1e-12 * scale, "slab {s}: {error:e}");
                if s % 2 == 1 {
                    assert!(got.iter().all(|&g| g == 0.0), "odd slab {s} not zero");
                }
            }
        });
    }

    /// The backward sweep in place from the links alone equals the backward sweep on the full
    /// residual, `z + (D + U)⁻¹ (r − A z)`, for a `z` that is no sweep's result.
    #[test]
    fn backward_from_is_the_backward_sweep_on_the_residual() {
        with_exact_sweeps(|system, sweeps| {
            let r = wave(system.dimension(), 0.7);
            let z = wave(system.dimension(), 0.31);
            let mut expected = full_residual(system, &r, &z);
            sweeps.backward(system, &mut expected, &Whole);
            add(&mut expected, &z);
            let mut got = z.clone();
            sweeps.backward_from(system, &r, &mut got, &Whole);
            let (error, scale) = (max_difference(&got, &expected), max_abs(&expected));
            assert!(error < 1e-11 * scale, "{error:e} of {scale:e}");
            let change = max_difference(&z, &expected);
            assert!(change > 0.1 * scale, "the sweep changes z: {change:e}");
        });
    }
}
