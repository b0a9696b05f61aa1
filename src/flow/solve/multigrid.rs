//! Multigrid in time: slab sweeps as smoother, semi-coarsening in time, coarse levels at twice
//! the time step.
//!
//! Level 0 is the space-time system; level `l + 1` merges the slabs of level `l` in pairs with
//! the transported prolongation `u_{2k} = ũ_k`, `u_{2k+1} = T_k ũ_k` and has the operator
//! `Pᵀ A P − E` ([`SpaceTimeSystem::merge_slab_pairs`]), down to a single slab: `E` is half the
//! coupling energy of its links, so that the coarse time coupling is that of the doubled time
//! step (`c / 2`) rather than the fine one (see `LinkMatrix::halve`). One application is
//! a V-cycle: forward sweep `(D + L)⁻¹`, restrict the residual (which the sweep leaves on the
//! links alone over single- or double-precision factors: [`SlabSweeps::forward_residual`]), cycle
//! on the coarse level, prolong and add, backward sweep `(D + Lᵀ)⁻¹` on the new residual (over
//! single- or double-precision factors in place, again from the links alone:
//! [`SlabSweeps::backward_from`]). Pre- and post-smoother
//! are transposes of each other, so the cycle is a symmetric positive definite preconditioner
//! for CG (up to the factors' rounding, which the links' residual leaves out).
//!
//! Why it is robust: the slab solves are exact in space, so whatever error a sweep leaves is
//! smooth in time ("plane relaxation"); semi-coarsening in time represents exactly that error
//! on the coarse levels, whatever the ratio of temporal to spatial coupling (the classical
//! pairing of plane smoothers with semi-coarsening for anisotropic problems; Trottenberg,
//! Oosterlee & Schüller, *Multigrid*, 2001, §5.2).

use super::pcg::{Operator, Preconditioner};
use super::precondition::{add, SlabSweeps, Surroundings, Whole};
use crate::flow::system::SpaceTimeSystem;
use crate::linalg::factor::SlabFactor;
use nalgebra::{Matrix2, Vector2};
use rayon::prelude::*;

/// The coarse levels of a space-time system, before any factorization.
pub struct TimeHierarchy {
    /// `coarse[l]` is level `l + 1`.
    coarse: Vec<SpaceTimeSystem>,
    /// `transports[l][k][i]`: `T_k` at vertex `i` between levels `l` and `l + 1`.
    transports: Vec<Vec<Vec<Matrix2<f64>>>>,
}

impl TimeHierarchy {
    /// Halves the number of slabs until one is left (no coarse levels for uncoupled slabs:
    /// the slab solves are then exact).
    pub fn new(fine: &SpaceTimeSystem) -> Self {
        let mut hierarchy = Self {
            coarse: Vec::new(),
            transports: Vec::new(),
        };
        while fine.has_links() && hierarchy.coarsest(fine).n_slabs() > 1 {
            let current = hierarchy.coarsest(fine);
            let transports = current.pair_transports();
            let next = current.merge_slab_pairs(&transports);
            hierarchy.transports.push(transports);
            hierarchy.coarse.push(next);
        }
        hierarchy
    }

    fn coarsest<'a>(&'a self, fine: &'a SpaceTimeSystem) -> &'a SpaceTimeSystem {
        self.coarse.last().unwrap_or(fine)
    }

    /// The coarse systems, level 1 first.
    pub fn coarse_systems(&self) -> &[SpaceTimeSystem] {
        &self.coarse
    }
}

/// Slabs per level over `n` fine slabs coupled in time, finest first: halved, rounded up, until
/// one is left, as [`TimeHierarchy::new`] and a distributed solve's levels build them.
pub fn level_slab_counts(n: usize) -> Vec<usize> {
    let mut counts = vec![n];
    while counts[counts.len() - 1] > 1 {
        counts.push(counts[counts.len() - 1].div_ceil(2));
    }
    counts
}

/// The V-cycle preconditioner over a [`TimeHierarchy`] with one [`SlabSweeps`] per level.
pub struct TimeMultigrid<'a, F: SlabFactor> {
    fine: &'a SpaceTimeSystem,
    hierarchy: TimeHierarchy,
    /// `sweeps[l]` factors the blocks of level `l`.
    sweeps: Vec<SlabSweeps<F>>,
}

impl<'a, F: SlabFactor> TimeMultigrid<'a, F> {
    pub fn new(
        fine: &'a SpaceTimeSystem,
        hierarchy: TimeHierarchy,
        sweeps: Vec<SlabSweeps<F>>,
    ) -> Self {
        assert_eq!(
            sweeps.len(),
            hierarchy.coarse.len() + 1,
            "one smoother per level"
        );
        Self {
            fine,
            hierarchy,
            sweeps,
        }
    }

    /// The levels' sweeps, finest first, given back.
    pub fn into_sweeps(self) -> Vec<SlabSweeps<F>> {
        self.sweeps
    }
}

/// What a V-cycle needs of its levels: level `l`'s system, sweeps and surroundings, and the
/// transfers between levels `l` and `l + 1`. A whole hierarchy in one process is one
/// ([`TimeMultigrid`]); a rank's windows of it, whose pairs may straddle two ranks, the other
/// (`super::distributed`).
pub(super) trait CycleLevels<F: SlabFactor> {
    /// Levels of the whole hierarchy (the last has one slab).
    fn n_levels(&self) -> usize;
    /// Whether this process holds level `l` (a rank falls idle below its last).
    fn holds(&self, l: usize) -> bool;
    fn system(&self, l: usize) -> &SpaceTimeSystem;
    fn sweeps(&self, l: usize) -> &SlabSweeps<F>;
    /// Calls `f` with level `l` as an operator (for residuals) and as the sweeps' surroundings.
    fn with_view<R>(&self, l: usize, f: impl FnOnce(&dyn Operator, &dyn Surroundings) -> R) -> R;
    /// `Pᵀ r` from level `l` to `l + 1`.
    fn restrict(&self, l: usize, r: &[f64]) -> Vec<f64>;
    /// `z += P zc` from level `l + 1` to `l`.
    fn prolong_add(&self, l: usize, coarse: &[f64], z: &mut [f64]);
}

/// `z ≈ A_l⁻¹ r` by one V-cycle from level `l`: forward sweep, coarse correction, backward
/// sweep on the residual.
pub(super) fn v_cycle<F: SlabFactor>(
    levels: &impl CycleLevels<F>,
    l: usize,
    r: &[f64],
    z: &mut [f64],
) {
    levels.with_view(l, |operator, around| {
        let (system, sweeps) = (levels.system(l), levels.sweeps(l));
        z.copy_from_slice(r);
        sweeps.forward(system, z, around);
        if l + 1 == levels.n_levels() {
            // One slab: the forward sweep was an exact solve.
            return;
        }
        let after_sweep = match links_give_the_residual::<F>() {
            true => sweeps.forward_residual(system, z, around),
            false => residual(operator, r, z),
        };
        let coarse_r = levels.restrict(l, &after_sweep);
        let mut coarse_z = vec![0.0; coarse_r.len()];
        if levels.holds(l + 1) {
            v_cycle(levels, l + 1, &coarse_r, &mut coarse_z);
        }
        levels.prolong_add(l, &coarse_z, z);
        match links_give_the_residual::<F>() {
            true => sweeps.backward_from(system, r, z, around),
            false => {
                let mut correction = residual(operator, r, z);
                sweeps.backward(system, &mut correction, around);
                add(z, &correction);
            }
        }
    })
}

impl<F: SlabFactor> CycleLevels<F> for TimeMultigrid<'_, F> {
    fn n_levels(&self) -> usize {
        self.sweeps.len()
    }

    fn holds(&self, _: usize) -> bool {
        true
    }

    fn system(&self, l: usize) -> &SpaceTimeSystem {
        match l {
            0 => self.fine,
            l => &self.hierarchy.coarse[l - 1],
        }
    }

    fn sweeps(&self, l: usize) -> &SlabSweeps<F> {
        &self.sweeps[l]
    }

    fn with_view<R>(&self, l: usize, f: impl FnOnce(&dyn Operator, &dyn Surroundings) -> R) -> R {
        f(self.system(l), &Whole)
    }

    fn restrict(&self, l: usize, r: &[f64]) -> Vec<f64> {
        restrict(
            &self.hierarchy.transports[l],
            r,
            self.system(l).slab_dimension(),
        )
    }

    fn prolong_add(&self, l: usize, coarse: &[f64], z: &mut [f64]) {
        let n = self.system(l).slab_dimension();
        prolong_add(&self.hierarchy.transports[l], coarse, z, n);
    }
}

impl<F: SlabFactor> Preconditioner for TimeMultigrid<'_, F> {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        v_cycle(self, 0, r, z);
    }
}

/// Whether the V-cycle takes the residual after its forward sweep from the links alone
/// ([`SlabSweeps::forward_residual`]) and sweeps back in place ([`SlabSweeps::backward_from`])
/// instead of forming `r − A z` twice, which holds up to the slab factors' rounding: with
/// single or double precision factors. Bfloat16's rounding (2⁻⁹) is not negligible where the
/// time coupling dominates the blocks (`D ≈ 2cM`, `X ≈ −cM`, the residual a small difference of
/// large terms): on the 128×95×20 torus at `α = 0.001` it cost one iteration (9 → 10 at
/// `γ = 1`), with `f32` levels none at any `α`.
fn links_give_the_residual<F: SlabFactor>() -> bool {
    F::ENTRY_BYTES >= 4
}

/// `r − A z` (for a rank's window, `A z` on its slabs).
pub(super) fn residual(system: &dyn Operator, r: &[f64], z: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; r.len()];
    system.apply(z, &mut out);
    out.par_iter_mut().zip(r).for_each(|(o, r)| *o = r - *o);
    out
}

/// `Pᵀ r`: coarse slab `k` gets `r_{2k} + T_kᵀ r_{2k+1}`.
pub(super) fn restrict(transports: &[Vec<Matrix2<f64>>], r: &[f64], n: usize) -> Vec<f64> {
    let n_coarse = (r.len() / n).div_ceil(2);
    let mut coarse = vec![0.0; n_coarse * n];
    coarse.par_chunks_mut(n).enumerate().for_each(|(k, ck)| {
        ck.copy_from_slice(&r[2 * k * n..(2 * k + 1) * n]);
        if let Some(t) = transports.get(k) {
            let odd = &r[(2 * k + 1) * n..(2 * k + 2) * n];
            for (i, t) in t.iter().enumerate() {
                let v = t.transpose() * Vector2::new(odd[2 * i], odd[2 * i + 1]);
                ck[2 * i] += v.x;
                ck[2 * i + 1] += v.y;
            }
        }
    });
    coarse
}

/// `z += P zc`: fine slab `2k` gets `zc_k`, slab `2k + 1` gets `T_k zc_k`.
pub(super) fn prolong_add(
    transports: &[Vec<Matrix2<f64>>],
    coarse: &[f64],
    z: &mut [f64],
    n: usize,
) {
    z.par_chunks_mut(2 * n)
        .zip(coarse.par_chunks(n))
        .enumerate()
        .for_each(|(k, (pair, ck))| {
            let (even, odd) = pair.split_at_mut(n);
            even.iter_mut().zip(ck).for_each(|(z, c)| *z += c);
            if let Some(t) = transports.get(k) {
                for (i, t) in t.iter().enumerate() {
                    let v = t * Vector2::new(ck[2 * i], ck[2 * i + 1]);
                    odd[2 * i] += v.x;
                    odd[2 * i + 1] += v.y;
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::system::for_each_column;
    use crate::flow::{FlowParams, FlowProblem, LinkMatrix, TimeCoupling};
    use nalgebra::DMatrix;

    fn dense(system: &SpaceTimeSystem) -> DMatrix<f64> {
        dense_values(system.to_sparse().as_ref())
    }

    fn dense_values(a: crate::fem::SparseMatrixRef<'_>) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(a.nrows(), a.ncols());
        for_each_column(a, |j, rows, values| {
            rows.iter().zip(values).for_each(|(&i, &v)| m[(i, j)] += v);
        });
        m
    }

    /// `P` column by column, from `prolong_add` on unit vectors.
    fn prolongation(transports: &[Vec<Matrix2<f64>>], fine: usize, coarse: usize) -> DMatrix<f64> {
        let n = 2 * transports[0].len();
        let mut p = DMatrix::zeros(fine * n, coarse * n);
        for j in 0..coarse * n {
            let mut unit = vec![0.0; coarse * n];
            unit[j] = 1.0;
            let mut column = vec![0.0; fine * n];
            prolong_add(transports, &unit, &mut column, n);
            p.column_mut(j).copy_from_slice(&column);
        }
        p
    }

    /// The counts a distributed solve and the factor precision rule plan with are the slabs of
    /// the hierarchy built: 1, 2, 3, 5 and 6 fine slabs.
    #[test]
    fn level_slab_counts_are_those_of_the_hierarchy() {
        for frames in [2, 3, 4, 6, 7] {
            let sequence = crate::synth::paper_torus(8, 6, frames).unwrap();
            let problem = FlowProblem::new(&sequence, &FlowParams::paper(0.3, 0.0, 1.0)).unwrap();
            let fine = problem.system();
            let hierarchy = TimeHierarchy::new(fine);
            let built: Vec<usize> = std::iter::once(fine.n_slabs())
                .chain(hierarchy.coarse_systems().iter().map(|c| c.n_slabs()))
                .collect();
            assert_eq!(level_slab_counts(fine.n_slabs()), built, "{frames} frames");
        }
        assert_eq!(level_slab_counts(20), [20, 10, 5, 3, 2, 1]);
    }

    /// Every level of the hierarchy is `Pᵀ A P` of the one above, formed densely, less the
    /// halved coupling energy `E` of its links (formed densely, with eigenvalue square roots
    /// for lumped links; positive semidefinite), and `restrict` is `Pᵀ`: even and odd slab
    /// counts, lumped and consistent coupling.
    #[test]
    fn coarse_levels_are_the_galerkin_products_with_halved_time_coupling() {
        for (frames, coupling) in [(6, TimeCoupling::Lumped), (5, TimeCoupling::Consistent)] {
            let sequence = crate::synth::paper_torus(8, 6, frames).unwrap();
            let params = FlowParams {
                time_coupling: coupling,
                ..FlowParams::paper(0.3, 0.0, 1.0)
            };
            let problem = FlowProblem::new(&sequence, &params).unwrap();
            let mut fine = problem.system().clone();
            while fine.n_slabs() > 1 {
                let transports = fine.pair_transports();
                let coarse = fine.merge_slab_pairs(&transports);
                let p = prolongation(&transports, fine.n_slabs(), coarse.n_slabs());
                let energy = halved_coupling_energy(&coarse);
                let min_energy = energy.clone().symmetric_eigen().eigenvalues.min();
                assert!(
                    min_energy > -1e-12 * energy.amax().max(1.0),
                    "E not PSD: {min_energy:e}"
                );
                let expected = p.transpose() * dense(&fine) * &p - energy;
                let error = (dense(&coarse) - &expected).amax() / expected.amax();
                assert!(
                    error < 1e-13,
                    "{frames} frames: coarse level error {error:e}"
                );
                let r: Vec<f64> = (0..fine.dimension()).map(|i| (i as f64).sin()).collect();
                let restricted = restrict(&transports, &r, fine.slab_dimension());
                let expected = p.transpose() * DMatrix::from_column_slice(r.len(), 1, &r);
                let error = (DMatrix::from_column_slice(restricted.len(), 1, &restricted)
                    - expected)
                    .amax();
                assert!(error < 1e-12, "restriction differs from Pᵀ by {error:e}");
                fine = coarse;
            }
        }
    }

    /// The energy a coarse level's links take off `Pᵀ A P`: for each link `X` (halved)
    /// between coarse slabs `k` and `k + 1`, `X` below and above the diagonal, and on blocks
    /// `k` and `k + 1` `|X|` and `|Xᵀ|` (lumped) or the link's parts `B` and `A` (consistent).
    fn halved_coupling_energy(coarse: &SpaceTimeSystem) -> DMatrix<f64> {
        let n = coarse.slab_dimension();
        let mut e = DMatrix::zeros(coarse.dimension(), coarse.dimension());
        let sqrt = |m: Matrix2<f64>| {
            let eigen = m.symmetric_eigen();
            let roots = eigen.eigenvalues.map(|l| l.max(0.0).sqrt());
            eigen.eigenvectors * Matrix2::from_diagonal(&roots) * eigen.eigenvectors.transpose()
        };
        for k in 0..coarse.n_slabs() - 1 {
            let (a, b) = (k * n, (k + 1) * n);
            let mut put = |r: usize, c: usize, m: DMatrix<f64>| {
                let mut view = e.view_mut((r, c), m.shape());
                view += m;
            };
            match coarse.link(k) {
                LinkMatrix::Lumped(blocks) => {
                    for (i, x) in blocks.iter().enumerate() {
                        let dense =
                            |m: Matrix2<f64>| DMatrix::from_column_slice(2, 2, m.as_slice());
                        let (a, b) = (a + 2 * i, b + 2 * i);
                        put(a, a, dense(sqrt(x.transpose() * x)));
                        put(b, b, dense(sqrt(x * x.transpose())));
                        put(b, a, dense(*x));
                        put(a, b, dense(x.transpose()));
                    }
                }
                LinkMatrix::Consistent(link) => {
                    let dense = |values: &[f64]| dense_values(coarse.pattern().view(values));
                    put(a, a, dense(&link.before));
                    put(b, b, dense(&link.after));
                    put(b, a, dense(&link.cross));
                    put(a, b, dense(&link.cross).transpose());
                }
            }
        }
        e
    }

    /// A coarse level is the space-time system of every other frame, to first order in the
    /// frame spacing: its links (a consistent one with its diagonal parts) agree with the links
    /// assembled on frames `0, 2, 4, …` (time step `2h`, weight `c / 2`); the Galerkin product
    /// alone keeps `c`, twice as stiff.
    #[test]
    fn coarse_links_are_those_of_every_other_frame() {
        for coupling in [TimeCoupling::Lumped, TimeCoupling::Consistent] {
            coarse_links_are_those_of_every_other_frame_with(coupling);
        }
    }

    fn coarse_links_are_those_of_every_other_frame_with(coupling: TimeCoupling) {
        let params = FlowParams {
            time_coupling: coupling,
            ..FlowParams::paper(0.3, 0.0, 1.0)
        };
        let frames = 9;
        let sequence = crate::synth::paper_torus(16, 12, frames).unwrap();
        let fine = FlowProblem::new(&sequence, &params)
            .unwrap()
            .system()
            .clone();
        let coarse = fine.merge_slab_pairs(&fine.pair_transports());
        let every_other = {
            let positions = (0..frames)
                .step_by(2)
                .map(|k| sequence.positions(k).unwrap().to_vec());
            let grey = (0..frames)
                .step_by(2)
                .map(|k| sequence.intensities(k).to_vec());
            let times = (0..frames)
                .step_by(2)
                .map(|k| sequence.times()[k])
                .collect();
            let subsampled = crate::flow::MeshSequence::new(
                sequence.mesh().clone(),
                positions.collect(),
                grey.collect(),
                Some(times),
            )
            .unwrap();
            FlowProblem::new(&subsampled, &params)
                .unwrap()
                .system()
                .clone()
        };
        assert_eq!(coarse.n_slabs(), every_other.n_slabs());
        let values = |link: &LinkMatrix| match link {
            LinkMatrix::Lumped(blocks) => blocks.iter().flat_map(|b| b.iter().copied()).collect(),
            LinkMatrix::Consistent(link) => [&link.cross[..], &link.before, &link.after].concat(),
        };
        for k in 0..coarse.n_slabs() - 1 {
            let (x, y): (Vec<f64>, Vec<f64>) =
                (values(coarse.link(k)), values(every_other.link(k)));
            assert_eq!(x.len(), y.len(), "{coupling:?}: link kinds differ");
            let norm = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
            let difference: Vec<f64> = x.iter().zip(&y).map(|(x, y)| x - y).collect();
            let relative = norm(&difference) / norm(&y);
            assert!(
                relative < 0.01,
                "{coupling:?}, link {k}: relative difference {relative:.3}"
            );
        }
    }
}
