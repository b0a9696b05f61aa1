//! Preconditioned conjugate gradients on the space-time system, with a rayon matvec.

use super::{SolveEvent, SolveObserver};
use crate::flow::system::{dot, SpaceTimeSystem};
use crate::flow::FlowError;
use rayon::prelude::*;

/// `z ≈ A⁻¹ r` for a symmetric positive definite approximation of `A⁻¹`.
pub trait Preconditioner {
    fn apply(&self, r: &[f64], z: &mut [f64]);
}

/// What CG needs of `A` and of the space its vectors live in: the whole system in one
/// process, or one rank's window of it with dot products summed over the ranks
/// ([`super::distributed`]).
pub trait Operator {
    /// `y = A x`.
    fn apply(&self, x: &[f64], y: &mut [f64]);
    /// `x · y` over the whole system.
    fn dot(&self, x: &[f64], y: &[f64]) -> f64;
}

impl Operator for SpaceTimeSystem {
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        SpaceTimeSystem::apply(self, x, y);
    }

    fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        dot(x, y)
    }
}

/// When CG stops, and how its iterations are numbered in the reports.
#[derive(Clone, Copy, Debug)]
pub struct Stop {
    /// Stop when `‖b − Ax‖ ≤ tolerance · ‖b‖`.
    pub tolerance: f64,
    /// Iterations counted so far (by an earlier run this one continues); reported numbers
    /// continue from here, and `max_iterations` counts them too.
    pub done: usize,
    pub max_iterations: usize,
    /// `Some((k, n))`: give up when this run, after `k` iterations or any later one, is too
    /// slow: when the rate of its last `k − 1` iterations projects more than `n − k` further
    /// iterations to the tolerance; before, only when it makes no progress at all
    /// ([`Projection::gives_up`]).
    pub give_up: Option<(usize, f64)>,
}

/// Result of a CG run: iterate, iterations (including `Stop::done`), the last recursive
/// residual `‖r‖/‖b‖`.
pub struct CgOutcome {
    pub x: Vec<f64>,
    pub iterations: usize,
    pub relative_residual: f64,
    /// Why the run gave up ([`Stop::give_up`]); `None` when it did not.
    pub gave_up: Option<Projection>,
    /// `[λ_min, λ_max]` of the preconditioned operator `M⁻¹A` as this run's Lanczos process saw
    /// them ([`ritz_extremes`]; `None` for a run of no iteration).
    pub spectrum: Option<[f64; 2]>,
}

/// Where a run's recent rate leads: the mean residual reduction per iteration over its last
/// iterations, and the further iterations that rate needs to reach the tolerance (`∞` without
/// progress).
#[derive(Clone, Copy, Debug)]
pub struct Projection {
    pub rate: f64,
    pub remaining: f64,
}

impl Projection {
    /// From the residuals `window` of consecutive iterations (oldest first, at least two).
    ///
    /// Why the recent iterations and not the whole run: CG's first iterations remove the error
    /// the preconditioner handles well and drop fast; the rate then settles. On the 48,450-vertex
    /// torus × 40 frames with default weights, slab Gauss–Seidel fell by 0.53 per iteration over
    /// iterations 1–4 (29.7 projected in all) and then by 0.87 over 5–8: it took 72.
    fn of(window: &[f64], tolerance: f64) -> Self {
        let (first, last) = (window[0], window[window.len() - 1]);
        let rate = (last / first).powf(1.0 / (window.len() - 1) as f64);
        let remaining = match rate < 1.0 {
            true => ((tolerance / last).ln() / rate.ln()).max(0.0),
            false => f64::INFINITY,
        };
        Self { rate, remaining }
    }

    /// Whether a run that probes for `probe` iterations gives up after `ran` of them, with
    /// `residuals` its residuals so far (its start first) and `limit` the iterations it may
    /// take in all.
    ///
    /// After the probe, when the rate of its last `probe − 1` iterations projects more than
    /// `limit − probe` further iterations. During the probe only when the residual has not
    /// fallen below its start: the first iterations' rate says little either way (CG may need
    /// a few to remove the components `b` weighs most), but a preconditioner under which CG
    /// cannot even reduce the residual is far off. On the torus at `α ≤ 0.1` slab
    /// Gauss–Seidel's first iteration leaves 1.5–3.6 times the starting residual, and multigrid
    /// needs no more iterations from there than from the fourth.
    fn gives_up(residuals: &[f64], ran: usize, probe: usize, limit: f64, tol: f64) -> Option<Self> {
        let window = probe.max(2);
        let (projection, allowed) = match ran >= window {
            true => (
                Self::of(&residuals[ran + 1 - window..=ran], tol),
                limit - probe as f64,
            ),
            false => (Self::of(&residuals[..=ran], tol), f64::MAX),
        };
        (projection.remaining > allowed).then_some(projection)
    }
}

/// Solves `A x = b` from `x` (CG restarted there) until the tolerance or the iteration limit
/// ([`FlowError::Interrupted`] when the observer stops it).
pub fn pcg(
    system: &dyn Operator,
    b: &[f64],
    mut x: Vec<f64>,
    preconditioner: &dyn Preconditioner,
    stop: Stop,
    observer: &dyn SolveObserver,
) -> Result<CgOutcome, FlowError> {
    let n = b.len();
    let b_norm = system.dot(b, b).sqrt();
    let mut r = vec![0.0; n];
    system.apply(&x, &mut r);
    r.par_iter_mut().zip(b).for_each(|(r, b)| *r = b - *r);
    let mut relative = system.dot(&r, &r).sqrt() / b_norm;
    let mut z = vec![0.0; n];
    preconditioner.apply(&r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = system.dot(&r, &z);
    let mut iteration = stop.done;
    let mut residuals = vec![relative];
    let mut gave_up = None;
    let mut lanczos = Lanczos::default();
    while relative > stop.tolerance && relative.is_finite() && iteration < stop.max_iterations {
        iteration += 1;
        system.apply(&p, &mut ap);
        let step = rz / system.dot(&p, &ap);
        lanczos.steps.push(step);
        axpy(step, &p, &mut x);
        axpy(-step, &ap, &mut r);
        relative = system.dot(&r, &r).sqrt() / b_norm;
        residuals.push(relative);
        observer.notify(SolveEvent::Iteration {
            iteration,
            relative_residual: relative,
        })?;
        if relative <= stop.tolerance {
            break;
        }
        if let Some((probe, limit)) = stop.give_up {
            let ran = iteration - stop.done;
            gave_up = Projection::gives_up(&residuals, ran, probe, limit, stop.tolerance);
            if gave_up.is_some() {
                break;
            }
        }
        preconditioner.apply(&r, &mut z);
        let rz_next = system.dot(&r, &z);
        let beta = rz_next / rz;
        lanczos.betas.push(beta);
        rz = rz_next;
        p.par_iter_mut()
            .zip(&z)
            .for_each(|(p, z)| *p = z + beta * *p);
    }
    Ok(CgOutcome {
        x,
        iterations: iteration,
        relative_residual: relative,
        gave_up,
        spectrum: ritz_extremes(&lanczos),
    })
}

/// CG's step lengths `α_k` and ratios `β_k = (r_{k+1}, z_{k+1}) / (r_k, z_k)`: the Lanczos
/// process of `M⁻¹A` in disguise.
#[derive(Default)]
struct Lanczos {
    steps: Vec<f64>,
    betas: Vec<f64>,
}

/// The extreme eigenvalues of the Lanczos matrix of a CG run (Golub & Van Loan, *Matrix
/// Computations*, §11.3.5): `T_kk = 1/α_k + β_{k−1}/α_{k−1}`, `T_{k,k+1} = √β_k / α_k`. Its
/// extreme eigenvalues (Ritz values) approach those of `M⁻¹A` from inside as CG proceeds, so
/// `λ_max / λ_min` estimates the condition number that governs the iterations.
fn ritz_extremes(lanczos: &Lanczos) -> Option<[f64; 2]> {
    let m = lanczos.steps.len();
    if m == 0 {
        return None;
    }
    let (a, b) = (&lanczos.steps, &lanczos.betas);
    let t = nalgebra::DMatrix::from_fn(m, m, |i, j| match (i, j) {
        _ if i == j => 1.0 / a[i] + if i > 0 { b[i - 1] / a[i - 1] } else { 0.0 },
        _ if j == i + 1 => b[i].sqrt() / a[i],
        _ if i == j + 1 => b[j].sqrt() / a[j],
        _ => 0.0,
    });
    let values = t.symmetric_eigenvalues();
    Some([values.min(), values.max()])
}

/// `y += a x`.
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.par_iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::solve::precondition::Jacobi;
    use crate::flow::system::for_each_column;
    use crate::flow::{FlowParams, FlowProblem};
    use nalgebra::DMatrix;

    /// `A = diag(values)`, CG without preconditioning: a spectrum whose error CG removes fast
    /// at first and slowly after.
    struct Diagonal(Vec<f64>);

    impl Operator for Diagonal {
        fn apply(&self, x: &[f64], y: &mut [f64]) {
            y.iter_mut()
                .zip(x.iter().zip(&self.0))
                .for_each(|(y, (x, d))| *y = d * x);
        }
        fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
            dot(x, y)
        }
    }

    struct Identity;

    impl Preconditioner for Identity {
        fn apply(&self, r: &[f64], z: &mut [f64]) {
            z.copy_from_slice(r);
        }
    }

    /// A run gives up when its rate slows down after the probe, not only when the probe's first
    /// iterations are slow: `b` weighs three well-separated eigenvalues heavily (CG removes
    /// them in the first iterations) and 400 eigenvalues spread over `[1, 10⁶]` lightly. Over
    /// iterations 1–4 the projection stays within the limit; later it does not. A
    /// well-conditioned system never gives up.
    #[test]
    fn cg_gives_up_when_its_rate_slows_after_the_probe() {
        let slow: Vec<f64> = (0..400)
            .map(|i| 10f64.powf(6.0 * i as f64 / 399.0))
            .collect();
        let values: Vec<f64> = [1e5, 3e5, 9e5].into_iter().chain(slow).collect();
        let b: Vec<f64> = (0..values.len())
            .map(|i| if i < 3 { 1.0 } else { 3e-3 })
            .collect();
        let stop = Stop {
            tolerance: 1e-8,
            done: 0,
            max_iterations: 1000,
            give_up: Some((4, 30.0)),
        };
        let run = |values: &[f64]| {
            let system = Diagonal(values.to_vec());
            let x = vec![0.0; values.len()];
            pcg(&system, &b, x, &Identity, stop, &|_| {}).unwrap()
        };
        let outcome = run(&values);
        let projection = outcome.gave_up.expect("the slow run gives up");
        println!(
            "gave up after {} iterations: rate {:.3}, {:.0} more projected",
            outcome.iterations, projection.rate, projection.remaining
        );
        assert!(outcome.iterations > 4, "{} iterations", outcome.iterations);
        assert!(projection.remaining > 26.0 && projection.rate > 0.7);
        let well_conditioned: Vec<f64> = (0..values.len())
            .map(|i| 1.0 + (i % 7) as f64 * 0.1)
            .collect();
        let outcome = run(&well_conditioned);
        assert!(outcome.gave_up.is_none() && outcome.relative_residual <= 1e-8);
    }

    /// During the probe a run gives up only without progress: on `diag(1, 100)` with
    /// `b = (10, 1)` CG's first step leaves `‖r₁‖ ≈ 4.9 ‖r₀‖`, and the run stops there, while
    /// the slow start of the run above (rate 0.785 in its first iteration) goes on.
    #[test]
    fn cg_gives_up_during_the_probe_only_when_the_residual_grows() {
        let system = Diagonal(vec![1.0, 100.0]);
        let stop = Stop {
            tolerance: 1e-8,
            done: 0,
            max_iterations: 10,
            give_up: Some((4, 30.0)),
        };
        let outcome = pcg(
            &system,
            &[10.0, 1.0],
            vec![0.0; 2],
            &Identity,
            stop,
            &|_| {},
        )
        .unwrap();
        let projection = outcome.gave_up.expect("no progress");
        assert_eq!(outcome.iterations, 1);
        assert!(
            (outcome.relative_residual - 4.95).abs() < 0.01,
            "{}",
            outcome.relative_residual
        );
        assert!(projection.rate > 1.0 && projection.remaining.is_infinite());
    }

    /// Run to convergence, CG's Ritz values reach the extreme eigenvalues of `M⁻¹A`, computed
    /// densely as those of `D^{-1/2} A D^{-1/2}` for the Jacobi preconditioner `M = D`.
    #[test]
    fn ritz_values_find_the_extreme_eigenvalues_of_the_preconditioned_operator() {
        let sequence = crate::synth::paper_torus(8, 6, 3).unwrap();
        let problem = FlowProblem::new(&sequence, &FlowParams::paper(0.3, 0.0, 1.0)).unwrap();
        let system = problem.system();
        let n = system.dimension();
        let mut a = DMatrix::<f64>::zeros(n, n);
        for_each_column(system.to_sparse().as_ref(), |j, rows, values| {
            rows.iter().zip(values).for_each(|(&i, &v)| a[(i, j)] += v);
        });
        let scale = DMatrix::from_diagonal(&a.diagonal().map(|d: f64| 1.0 / d.sqrt()));
        let exact = (&scale * &a * &scale).symmetric_eigenvalues();
        let stop = Stop {
            tolerance: 1e-15,
            done: 0,
            max_iterations: 4 * n,
            give_up: None,
        };
        let x = vec![0.0; n];
        let outcome = pcg(system, system.rhs(), x, &Jacobi::new(system), stop, &|_| {}).unwrap();
        let [low, high] = outcome.spectrum.unwrap();
        println!(
            "{} iterations: Ritz [{low:.6e}, {high:.6e}], exact [{:.6e}, {:.6e}]",
            outcome.iterations,
            exact.min(),
            exact.max()
        );
        assert!((high - exact.max()).abs() < 1e-8 * exact.max());
        assert!((low - exact.min()).abs() < 1e-6 * exact.min());
    }
}
