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
    /// When to give up on a run that is too slow; `None`: never.
    pub give_up: Option<GiveUp>,
    /// The norm residuals are measured against, `‖b‖` when `None`: a run that solves for a
    /// correction of a whole system's iterate ([`super::reduced`]) reports and stops on the
    /// whole system's scale.
    pub reference: Option<f64>,
}

impl Stop {
    /// Until `tolerance` or `max_iterations`, never giving up, residuals relative to `‖b‖`.
    pub fn new(tolerance: f64, max_iterations: usize) -> Self {
        Self {
            tolerance,
            done: 0,
            max_iterations,
            give_up: None,
            reference: None,
        }
    }
}

/// Give up when a run, after `probe` iterations or any later one, is too slow: when the rate
/// of its last `probe − 1` iterations projects more than `limit − probe` further iterations to
/// `goal` (a relative residual: the solve's tolerance for `auto`'s probe, a round's stopping
/// point in [`super::reduced`]); before, only when it makes no progress at all
/// ([`Projection::gives_up`]) and `early` allows it.
#[derive(Clone, Copy, Debug)]
pub struct GiveUp {
    pub probe: usize,
    pub limit: f64,
    pub goal: f64,
    /// Whether it may give up during the probe. Not from a warm start: its error is what the
    /// preconditioner handles worst (the fast components are gone), and CG, which minimizes
    /// the error's energy norm, may raise the residual's norm in its first iterations. At paper
    /// size with `--large-motion`, the second warp of a level started at 6.7e-5 and its first
    /// iteration left 1.1e-4, where slab Gauss–Seidel went on to converge in 6 iterations.
    pub early: bool,
}

/// Result of a CG run: iterate, iterations (including `Stop::done`), the last recursive
/// residual `‖r‖/‖b‖` (the true one after rounds of refinement, [`super::reduced`]).
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
    /// take in all (`give_up`'s fields).
    ///
    /// After the probe, when the rate of its last `probe − 1` iterations projects more than
    /// `limit − probe` further iterations. During the probe only when the residual has not
    /// fallen below its start: the first iterations' rate says little either way (CG may need
    /// a few to remove the components `b` weighs most), but a preconditioner under which CG
    /// cannot even reduce the residual is far off. On the torus at `α ≤ 0.1` slab
    /// Gauss–Seidel's first iteration leaves 1.5–3.6 times the starting residual, and multigrid
    /// needs no more iterations from there than from the fourth.
    fn gives_up(residuals: &[f64], ran: usize, give_up: GiveUp) -> Option<Self> {
        let GiveUp {
            probe,
            limit,
            goal,
            early,
        } = give_up;
        let window = probe.max(2);
        let (projection, allowed) = match ran >= window {
            true => (
                Self::of(&residuals[ran + 1 - window..=ran], goal),
                limit - probe as f64,
            ),
            false if early => (Self::of(&residuals[..=ran], goal), f64::MAX),
            false => return None,
        };
        (projection.remaining > allowed).then_some(projection)
    }
}

/// Solves `A x = b` from `x` (CG restarted there) until the tolerance or the iteration limit
/// ([`FlowError::Interrupted`] when the observer stops it).
pub fn pcg(
    system: &dyn Operator,
    b: &[f64],
    x: Vec<f64>,
    preconditioner: &dyn Preconditioner,
    stop: Stop,
    observer: &dyn SolveObserver,
) -> Result<CgOutcome, FlowError> {
    let cg = (stop, observer);
    pcg_recycling(system, b, x, preconditioner, cg, Recycling::None)
}

/// A CG run's search directions `p_j`, their products `A p_j` and curvatures `p_jᵀ A p_j`: an
/// `A`-conjugate basis of its Krylov space. A later run on the same operator starts deflated
/// by them, from the `A`-orthogonal projection of its solution onto them and with a first
/// direction `A`-orthogonal to them, and so does not find again what the first run found
/// (Saad, Yeung, Erhel & Guyomarc'h, "A deflated version of the conjugate gradient
/// algorithm", SIAM J. Sci. Comput. 21, 2000; only the start, as init-CG, since further
/// projections gained no iteration on the paper-size frames). Kept in `f32`: they only need
/// to span the space.
#[derive(Default)]
pub struct Directions {
    kept: Vec<Kept>,
}

struct Kept {
    p: Vec<f32>,
    ap: Vec<f32>,
    curvature: f64,
}

/// What a CG run does with [`Directions`].
pub enum Recycling<'a> {
    None,
    /// Keep the run's own directions.
    Keep(&'a mut Directions),
    /// Start deflated by earlier directions.
    StartFrom(&'a Directions),
}

impl Directions {
    /// `x += c_j p_j`, `r −= c_j A p_j` with `c_j = p_jᵀ r / p_jᵀ A p_j` for each kept direction
    /// in turn: the start projected onto them, leaving `r` orthogonal to them (each `c_j` from
    /// the `r` the earlier ones left, as modified Gram–Schmidt, so that directions that lost
    /// some conjugacy still leave `r` nearly orthogonal).
    fn project_start(&self, x: &mut [f64], r: &mut [f64]) {
        for k in &self.kept {
            let c = dot_f32(r, &k.p) / k.curvature;
            axpy_f32(c, &k.p, x);
            axpy_f32(-c, &k.ap, r);
        }
    }

    /// `p −= (pᵀ A p_j / p_jᵀ A p_j) p_j` for each kept direction in turn: `p` made
    /// `A`-orthogonal to them.
    fn deflate(&self, p: &mut [f64]) {
        for k in &self.kept {
            let c = dot_f32(p, &k.ap) / k.curvature;
            axpy_f32(-c, &k.p, p);
        }
    }

    fn keep(&mut self, p: &[f64], ap: &[f64], curvature: f64) {
        let narrowed = |v: &[f64]| v.par_iter().map(|v| *v as f32).collect();
        self.kept.push(Kept {
            p: narrowed(p),
            ap: narrowed(ap),
            curvature,
        });
    }
}

/// `yᵀ x` for `f32` `x` (in one process: directions are kept for a whole system only).
fn dot_f32(y: &[f64], x: &[f32]) -> f64 {
    (y.par_iter().zip(x)).map(|(y, x)| y * *x as f64).sum()
}

/// `y += a x` for `f32` `x`.
fn axpy_f32(a: f64, x: &[f32], y: &mut [f64]) {
    y.par_iter_mut()
        .zip(x)
        .for_each(|(y, x)| *y += a * *x as f64);
}

/// [`pcg`], keeping the run's search directions or starting deflated by earlier ones.
pub fn pcg_recycling(
    system: &dyn Operator,
    b: &[f64],
    mut x: Vec<f64>,
    preconditioner: &dyn Preconditioner,
    (stop, observer): (Stop, &dyn SolveObserver),
    mut recycling: Recycling<'_>,
) -> Result<CgOutcome, FlowError> {
    let n = b.len();
    let b_norm = stop.reference.unwrap_or_else(|| system.dot(b, b).sqrt());
    let mut r = b.to_vec();
    if x.par_iter().any(|x| *x != 0.0) {
        let mut ax = vec![0.0; n];
        system.apply(&x, &mut ax);
        r.par_iter_mut().zip(ax).for_each(|(r, ax)| *r -= ax);
    }
    if let Recycling::StartFrom(directions) = &recycling {
        directions.project_start(&mut x, &mut r);
    }
    let mut relative = system.dot(&r, &r).sqrt() / b_norm;
    let mut z = vec![0.0; n];
    preconditioner.apply(&r, &mut z);
    let mut p = z.clone();
    if let Recycling::StartFrom(directions) = &recycling {
        directions.deflate(&mut p);
    }
    let mut ap = vec![0.0; n];
    let mut rz = system.dot(&r, &z);
    let mut iteration = stop.done;
    let mut residuals = vec![relative];
    let mut gave_up = None;
    let mut lanczos = Lanczos::default();
    while relative > stop.tolerance && relative.is_finite() && iteration < stop.max_iterations {
        iteration += 1;
        system.apply(&p, &mut ap);
        let curvature = system.dot(&p, &ap);
        if let Recycling::Keep(directions) = &mut recycling {
            directions.keep(&p, &ap, curvature);
        }
        let step = rz / curvature;
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
        if let Some(give_up) = stop.give_up {
            let ran = iteration - stop.done;
            gave_up = Projection::gives_up(&residuals, ran, give_up);
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
            give_up: Some(GiveUp {
                probe: 4,
                limit: 30.0,
                goal: 1e-8,
                early: true,
            }),
            ..Stop::new(1e-8, 1000)
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
    /// the slow start of the run above (rate 0.785 in its first iteration) goes on. A run that
    /// may not give up early (a warm start) goes on and converges in its second iteration.
    #[test]
    fn cg_gives_up_during_the_probe_only_when_the_residual_grows() {
        let system = Diagonal(vec![1.0, 100.0]);
        let run = |early| {
            let give_up = GiveUp {
                probe: 4,
                limit: 30.0,
                goal: 1e-8,
                early,
            };
            let stop = Stop {
                give_up: Some(give_up),
                ..Stop::new(1e-8, 10)
            };
            pcg(
                &system,
                &[10.0, 1.0],
                vec![0.0; 2],
                &Identity,
                stop,
                &|_| {},
            )
            .unwrap()
        };
        let outcome = run(true);
        let projection = outcome.gave_up.expect("no progress");
        assert_eq!(outcome.iterations, 1);
        assert!(
            (outcome.relative_residual - 4.95).abs() < 0.01,
            "{}",
            outcome.relative_residual
        );
        assert!(projection.rate > 1.0 && projection.remaining.is_infinite());
        let patient = run(false);
        assert!(patient.gave_up.is_none());
        assert_eq!(patient.iterations, 2);
        assert!(patient.relative_residual <= 1e-8);
    }

    /// A run started deflated by an earlier run's directions on the same operator needs fewer
    /// iterations than one from zero, and finds the same solution: `diag` with 400 eigenvalues
    /// spread over `[1, 100]`, both runs to `10⁻⁴` (as rounds of refinement), the second for a
    /// right-hand side that shares the first's components.
    #[test]
    fn a_run_deflated_by_earlier_directions_needs_fewer_iterations() {
        let n = 400;
        let values: Vec<f64> = (0..n)
            .map(|i| 10f64.powf(2.0 * i as f64 / (n - 1) as f64))
            .collect();
        let system = Diagonal(values.clone());
        let wave = |k: f64| (0..n).map(move |i| (k * i as f64).cos());
        let first: Vec<f64> = wave(0.3).collect();
        let second: Vec<f64> = wave(0.3).zip(wave(0.7)).map(|(a, b)| a + 0.1 * b).collect();
        let quiet: &dyn SolveObserver = &|_| {};
        let cg = (Stop::new(1e-4, 1000), quiet);
        let mut directions = Directions::default();
        let keep = Recycling::Keep(&mut directions);
        pcg_recycling(&system, &first, vec![0.0; n], &Identity, cg, keep).unwrap();
        let run =
            |recycling| pcg_recycling(&system, &second, vec![0.0; n], &Identity, cg, recycling);
        let plain = run(Recycling::None).unwrap();
        let deflated = run(Recycling::StartFrom(&directions)).unwrap();
        println!(
            "{} directions kept; {} iterations from zero, {} deflated",
            directions.kept.len(),
            plain.iterations,
            deflated.iterations
        );
        assert!(deflated.iterations + 5 <= plain.iterations);
        let exact = second.iter().zip(&values).map(|(b, d)| b / d);
        let error = (deflated.x.iter().zip(exact)).fold(0.0f64, |m, (x, e)| m.max((x - e).abs()));
        assert!(error < 1e-3, "{error:e}");
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
        let stop = Stop::new(1e-15, 4 * n);
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
