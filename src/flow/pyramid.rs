//! The images at coarser scales, for coarse-to-fine warping: heat diffusion on each frame's
//! own surface, by implicit steps that share one factorization per frame (and one ordering
//! for all frames).
//!
//! ```text
//! (M + τ L) I^{n+1} = M I^n        (M: P1 mass, L: cotan Laplacian of frame k)
//! ```
//!
//! `n` steps of `τ` smooth to heat time `t = n τ`. Level `ℓ = 0` is the image itself; level
//! `ℓ ≥ 1` has `t_ℓ = τ 4^{ℓ−1}` with the coarsest `t_{L−1} = 0.15 ρ²`, `ρ = √(A / 4π)` the
//! radius of the sphere with the surface's area `A`: heat time `t` blurs over a distance of
//! about `√(4t)`, so the coarsest level still sees a feature displaced by about `ρ` (a
//! displacement `d` needs `t ≈ 0.15 d²`, Brox et al.'s rule of thumb carried to surfaces).
//! Scales come from the surface's size, not from the data's units.

use super::{FlowError, Images, MeshSequence};
use crate::fem::{cotan_laplacian, scalar_mass, MassKind, SparseMatrix};
use crate::geometry::IntrinsicGeometry;
use crate::linalg::cholesky::{analyze, CholeskyFactor};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::Par;
use rayon::prelude::*;
use std::sync::Arc;

/// `t_max / ρ²`: the coarsest heat time relative to the surface's radius squared.
pub const COARSEST_HEAT_TIME: f64 = 0.15;

/// Heat times `[0, t_1, …, t_{L−1}]` of `levels` levels for a surface of area `area`.
pub fn heat_times(levels: usize, area: f64) -> Vec<f64> {
    let t_max = COARSEST_HEAT_TIME * area / (4.0 * std::f64::consts::PI);
    (0..levels)
        .map(|l| match l {
            0 => 0.0,
            l => t_max * 4f64.powi(l as i32 - (levels as i32 - 1)),
        })
        .collect()
}

/// `pyramid[ℓ]`: the sequence's images (every channel) smoothed to level `ℓ` (`pyramid[0]` the
/// originals).
pub fn scale_pyramid(sequence: &MeshSequence, levels: usize) -> Result<Vec<Images>, FlowError> {
    let mesh = sequence.mesh();
    let geometry = |k: usize| {
        IntrinsicGeometry::new(mesh, sequence.edge_lengths(k).to_vec())
            .map_err(|source| FlowError::Frame { frame: k, source })
    };
    // Every frame's `M + τL` has the mesh's pattern: one ordering serves them all.
    let symbolic = match levels {
        0 | 1 => None,
        _ => Some(heat_symbolic(sequence)?),
    };
    // per_frame[k][ℓ][c]
    let per_frame: Vec<Vec<Vec<Vec<f64>>>> = (0..sequence.n_frames())
        .into_par_iter()
        .map(|k| {
            let geometry = geometry(k)?;
            let times = heat_times(levels, geometry.total_area());
            let channels = sequence.channels(k);
            match &symbolic {
                Some(symbolic) => heat_levels(mesh, &geometry, symbolic, channels, &times, k),
                None => Ok(vec![channels.to_vec()]),
            }
        })
        .collect::<Result<_, _>>()?;
    Ok((0..levels)
        .map(|l| Images::from_channels(per_frame.iter().map(|frame| frame[l].clone()).collect()))
        .collect())
}

/// The ordering and symbolic analysis of every frame's `M + τL` (the mesh's pattern: vertex
/// adjacency and diagonal), computed once per sequence and shared by the scale pyramid and the
/// anisotropic regularizer's presmoothing of every slab.
pub(super) fn heat_symbolic(
    sequence: &MeshSequence,
) -> Result<Arc<SymbolicCholesky<usize>>, FlowError> {
    let cache = sequence.heat_symbolic_cache();
    if let Some(symbolic) = cache.get() {
        return Ok(symbolic.clone());
    }
    let mesh = sequence.mesh();
    let geometry = IntrinsicGeometry::new(mesh, sequence.edge_lengths(0).to_vec())
        .map_err(|source| FlowError::Frame { frame: 0, source })?;
    let symbolic = analyze(heat_operator(mesh, &geometry, 1.0).1.symbolic(), 1);
    Ok(cache.get_or_init(|| symbolic).clone())
}

/// The consistent mass `M` and the heat step's operator `M + τL`.
fn heat_operator(
    mesh: &crate::mesh::Mesh,
    geometry: &IntrinsicGeometry,
    step: f64,
) -> (SparseMatrix, SparseMatrix) {
    let mass = scalar_mass(mesh, geometry, MassKind::Consistent);
    let operator = sum_of(&mass, &cotan_laplacian(mesh, geometry), step);
    (mass, operator)
}

/// One frame's channels at the heat times `times` (`times[ℓ] = τ 4^{ℓ−1}`, `τ = times[1]`; at
/// least two levels), factorized once on the shared ordering `symbolic`: `levels[ℓ][c]`.
fn heat_levels(
    mesh: &crate::mesh::Mesh,
    geometry: &IntrinsicGeometry,
    symbolic: &Arc<SymbolicCholesky<usize>>,
    channels: &[Vec<f64>],
    times: &[f64],
    frame: usize,
) -> Result<Vec<Vec<Vec<f64>>>, FlowError> {
    let step = times[1];
    let heat = HeatStep::new(mesh, geometry, symbolic, step, || {
        format!("the heat step of frame {frame}")
    })?;
    let mut levels = vec![channels.to_vec()];
    let mut current = channels.to_vec();
    let mut steps_done = 0;
    for &t in &times[1..] {
        let steps = (t / step).round() as usize;
        for channel in &mut current {
            for _ in steps_done..steps {
                heat.apply(channel);
            }
        }
        steps_done = steps;
        levels.push(current.clone());
    }
    Ok(levels)
}

/// `values` (one per vertex) smoothed to heat time `time` by `steps` implicit steps of
/// `time / steps` on `geometry` (a geometry of `sequence`'s mesh; the sequence's shared
/// ordering, [`heat_symbolic`]): about a Gaussian of width `√(2 time)`.
pub(super) fn heat_smoothed(
    sequence: &MeshSequence,
    geometry: &IntrinsicGeometry,
    values: &[&[f64]],
    time: f64,
    steps: usize,
    what: impl Fn() -> String,
) -> Result<Vec<Vec<f64>>, FlowError> {
    let mut out: Vec<Vec<f64>> = values.iter().map(|v| v.to_vec()).collect();
    if time <= 0.0 || steps == 0 {
        return Ok(out);
    }
    let step = time / steps as f64;
    let symbolic = heat_symbolic(sequence)?;
    let heat = HeatStep::new(sequence.mesh(), geometry, &symbolic, step, what)?;
    for channel in &mut out {
        (0..steps).for_each(|_| heat.apply(channel));
    }
    Ok(out)
}

/// Steps of [`smoothed_over_length`]: implicit Euler with this many steps is within a few
/// per cent of the heat kernel's width.
const LENGTH_STEPS: usize = 4;

/// `values` (each one per vertex) smoothed on frame `frame`'s surface over the length `length`
/// (physical units): heat flow to time `t = length² / 2`, about a Gaussian of standard
/// deviation `length` along the surface, in a few implicit steps (`LENGTH_STEPS`). Mass is
/// kept: the mean over the surface does not change. `length = 0` returns the values.
pub fn smoothed_over_length(
    sequence: &MeshSequence,
    frame: usize,
    values: &[&[f64]],
    length: f64,
) -> Result<Vec<Vec<f64>>, FlowError> {
    let geometry = IntrinsicGeometry::new(sequence.mesh(), sequence.edge_lengths(frame).to_vec())
        .map_err(|source| FlowError::Frame { frame, source })?;
    let what = || format!("the smoothing of frame {frame} over {length}");
    heat_smoothed(
        sequence,
        &geometry,
        values,
        0.5 * length * length,
        LENGTH_STEPS,
        what,
    )
}

/// One implicit heat step `I ← (M + τL)⁻¹ M I`, factorized.
struct HeatStep {
    mass: SparseMatrix,
    factor: CholeskyFactor<f64>,
}

impl HeatStep {
    /// The step `τ = step` on `geometry`, factorized on `symbolic`; `what` names it in errors.
    fn new(
        mesh: &crate::mesh::Mesh,
        geometry: &IntrinsicGeometry,
        symbolic: &Arc<SymbolicCholesky<usize>>,
        step: f64,
        what: impl Fn() -> String,
    ) -> Result<Self, FlowError> {
        let (mass, operator) = heat_operator(mesh, geometry, step);
        let factor = CholeskyFactor::<f64>::new(symbolic, operator.as_ref(), Par::Seq).map_err(
            |detail| FlowError::Factorization {
                what: what(),
                detail,
            },
        )?;
        Ok(Self { mass, factor })
    }

    fn apply(&self, values: &mut Vec<f64>) {
        *values = mass_times(&self.mass, values);
        self.factor.solve_in_place(values, Par::Seq);
    }
}

/// `a + s b` for two matrices (any patterns).
fn sum_of(a: &SparseMatrix, b: &SparseMatrix, s: f64) -> SparseMatrix {
    let mut triplets = Vec::with_capacity(a.compute_nnz() + b.compute_nnz());
    for (m, scale) in [(a, 1.0), (b, s)] {
        super::system::for_each_column(m.as_ref(), |j, rows, values| {
            for (&i, &v) in rows.iter().zip(values) {
                triplets.push(faer::sparse::Triplet::new(i, j, scale * v));
            }
        });
    }
    SparseMatrix::try_new_from_triplets(a.nrows(), a.ncols(), &triplets)
        .expect("both matrices have the same shape")
}

fn mass_times(mass: &SparseMatrix, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    super::system::for_each_column(mass.as_ref(), |j, rows, values| {
        for (&i, &v) in rows.iter().zip(values) {
            y[i] += v * x[j];
        }
    });
    y
}
