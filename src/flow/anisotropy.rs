//! Image-driven anisotropic smoothness (Nagel–Enkelmann; Weickert & Schnörr, "A theoretical
//! framework for convex regularizers in PDE-based computation of image motion", IJCV 45(3),
//! 2001): the quadratic regularizer smooths the flow across motion boundaries, which mostly
//! are image edges; this one smooths along image edges and less across them.
//!
//! The covariant density `|∇u|² = tr(∇u ∇uᵀ)` becomes `tr(∇u D ∇uᵀ)` with, per face, the
//! symmetric positive definite 2×2 tensor (in the face's own frame, the frame of
//! [`crate::fem::element::face_gradient`]; `∇u` has the flow's components as rows and the
//! derivative directions as columns, so `D` acts on the derivative directions)
//!
//! ```text
//! D = 2 (g^⊥ g^⊥ᵀ + λ² Id) / (|g|² + 2λ²),        g = ∇I_σ on the face
//! ```
//!
//! with eigenvalues `2λ² / (|g|² + 2λ²)` along `g` (across the edge) and
//! `2(|g|² + λ²) / (|g|² + 2λ²)` along `g^⊥` (along the edge); `tr D = 2` everywhere, so
//! `γ` keeps its meaning, and `λ → ∞` (or `g = 0`) gives `D = Id`, the paper's term. `λ` is in
//! the image's units per length (grey value per length): scaling the grey values by `c` and
//! `λ` by `c` leaves `D` unchanged. `D` is positive definite for `λ > 0`, so the kernel of the
//! regularizer (covariantly constant fields) and with it the uniqueness check
//! (`flow::uniqueness`) are unchanged.
//!
//! For P1 fields `∇u|_T = Σ_a v_a ∇φ_aᵀ` (`v_a = R_a u_a`, face frame), so
//! `∫_T tr(∇u D ∇uᵀ) = Σ_ab (v_a·v_b) A ∇φ_aᵀ D ∇φ_b`: the covariant element
//! `vector_element(S, R)` with the cotan stiffness `S` replaced by the anisotropic stiffness
//! [`crate::fem::element::anisotropic_stiffness`] `K^D_ab = A ∇φ_aᵀ D ∇φ_b` (`D = Id`: `S`).
//!
//! **The image.** `g` is the face gradient of the slab's mid image `I_mid = ½(I_s + I_{s+1})`
//! (warped when warping, `docs/discretization.md` §3) on the slab's geometry, presmoothed on
//! the surface to heat time `t = σ²/2` (a Gaussian of width `σ`) by [`HEAT_STEPS`] implicit
//! steps `(M + t/n L)⁻¹ M` ([`super::pyramid`]); `σ` defaults to the slab's mean edge length.
//! Several channels sum their structure with the data term's channel weights,
//! `J = Σ_c w_c g_c g_cᵀ`, and `g^⊥ g^⊥ᵀ` and `|g|²` generalize to `tr(J) Id − J` and `tr J`
//! (equal for one channel of weight 1): an edge in any channel steers the smoothing, and
//! `tr D = 2` still holds.
//!
//! **`auto`** takes, per slab, `λ` = [`AUTO_CONTRAST`] times the contrast-weighted median of
//! the presmoothed contrast `c_T = √tr J_T` (the `c` below which half of `Σ_T A_T c_T` lies):
//! scale-aware (grey-value scaling leaves `D` unchanged), not lowered by a dark, flat
//! background as the median over faces is (sparse cells in a fluorescence recording would all
//! count as edges), and not raised to the edges' own contrast where a few strong edges hold
//! most of the gradient energy, as its energy-weighted median is.
//!
//! **The data scale.** The relative weights ([`super::FlowParams`]) set `γ` from the image's
//! gradient scale `S`, the root mean square of `|∇I|` weighted by the gradient energy. One strong
//! edge then dominates `S` (`|∇I|⁴` weighting) and with it the smoothing everywhere: a cap
//! brighter by 0.3 on the textured sphere of `examples/motion_boundaries` raises `S` from 0.65
//! to 4.5 and `γ` 50-fold, and the cap's flow falls to a fifth of its speed. Under the tensor
//! that edge is not smoothed across, so `S` is measured on the gradient energy the tensor lets
//! through, `|∇I|²_λ = tr(J D_λ(J)) = 2λ²|∇I|² / (|∇I|² + 2λ²)` per face (raw image, `λ` the
//! slab's): `|∇I|²` for contrasts well below `λ`, at most `2λ²` on edges, and `|∇I|²` again as
//! `λ → ∞` (module `flow::scales`).
//!
//! **In time** ([`Anisotropy::in_time`], `--anisotropic-in-time`). Weickert & Schnörr's
//! spatio-temporal regularizers (§5) put time into the tensor: in the product metric
//! `diag(α², g)` the image's space-time gradient is `(∇I, ∂_t I/α)` and the 3×3
//! Nagel–Enkelmann tensor, normalized to trace 3 like `D` to trace 2, is
//! `D₃ = 3((|∇₃I|² + λ²) Id − ∇₃I ∇₃Iᵀ) / (2|∇₃I|² + 3λ²)`. Its mixed space-time entries
//! would couple a slab's spatial gradient with the links' differences in time, which this
//! discretization keeps in separate elements (slabs and links, `docs/discretization.md` §5–6);
//! without them the spatial block would turn isotropic wherever the image moves
//! (`∂_t I ≠ 0`), undoing `D`. So the spatial term keeps `D`, and the coupling in time of face
//! `T` between slabs `s` and `s + 1` takes the time entry
//!
//! ```text
//! D_tt = 3 (c + λ²) / (2 (c + r/α²) + 3λ²),    c = tr J,  r = Σ_c w_c (∂_t I_c)²
//! ```
//!
//! with `c`, `r` and `λ` the two slabs' means, `∂_t I_c` the face mean of the presmoothed rate
//! `τ_c` ([`time_entries`]). It is below 1 where the image changes in time faster than its
//! edges explain, up to 3/2 on still edges, and 1 for `λ → ∞` or a flat image; positive, so
//! the uniqueness check holds. Measured (`examples/motion_boundaries`, a cap that stops
//! half-way, and the zebrafish over three frames): within 1 % of the coupling without it
//! everywhere, also where `D_tt` falls to 0.23; it is an option, not part of `auto`.
//!
//! **Design.** The tensor is a parameter of the energy next to the regularizer's kind
//! ([`super::FlowParams::anisotropy`]), not a variant of [`super::Regularizer`]: it is a
//! per-face weight of *any* quadratic form of `∇u` (the kind says which form, the tensor
//! where it is weighted), it needs the images, which the regularizer's element never sees, and
//! it is data of the slab like the robust weights: [`super::Slab::diffusion_tensors`], set
//! once per slab, read by every place that takes the regularizer's element from the slab
//! (assembly, energy, robust reweighting, windows).
//!
//! **Strain.** The strain regularizer weighs its density the same way,
//! `tr(Sym∇u D Sym∇uᵀ) = |Sym∇u D^½|²` ([`crate::fem::element::anisotropic_strain_element`]),
//! still zero exactly on Killing fields; with `--dirichlet-mix δ` the covariant share is
//! `δ tr(∇u D ∇uᵀ)`. The embedded regularizer (an R³ field's gradient) takes no tensor.

use super::params::{check, Scale};
use super::pyramid::heat_smoothed;
use super::slab::structure_tensor;
use super::{FlowError, MeshSequence, Regularizer, Slab};
use crate::statistics::weighted_median;
use nalgebra::Matrix2;

/// Implicit heat steps of the presmoothing.
pub const HEAT_STEPS: usize = 4;

/// `auto`'s `λ` in multiples of the contrast-weighted median (module docs): a face of that
/// contrast is smoothed across at 9/11 of the isotropic weight, an edge of ten times it at 4 %.
/// Measured on `examples/motion_boundaries` (two boundaries, a smooth rotation, the shipped
/// sample) and the zebrafish recording: 2 gained less at the boundaries, 1 cost more on the
/// smooth rotation. The median over faces made the zebrafish flows 30–50 % worse (its
/// background of noise set `λ`); the energy-weighted median left the equator's boundary at
/// 0.81× the defaults' error instead of 0.61× (the edge held most of the energy and set `λ`).
pub const AUTO_CONTRAST: f64 = 1.5;

/// `λ` and the presmoothing width `σ` of the anisotropic regularizer (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Anisotropy {
    /// The contrast (grey value per length) at which smoothing across an edge is reduced to
    /// two thirds of its isotropic value (`2λ²/(|g|² + 2λ²)` at `|g| = λ`); `> 0`.
    pub lambda: Scale,
    /// The presmoothing width (a length); `None`: the slab's mean edge length, `0`: none.
    pub sigma: Option<f64>,
    /// Weigh the coupling in time by the space-time tensor's time entry (module docs, "In
    /// time"); `false`: the time term is the paper's.
    pub in_time: bool,
}

impl Anisotropy {
    /// `λ` with the default presmoothing.
    pub fn new(lambda: f64) -> Self {
        Self::with(Scale::Value(lambda))
    }

    /// `λ` given or `auto`, with the default presmoothing.
    pub fn with(lambda: Scale) -> Self {
        Self {
            lambda,
            sigma: None,
            in_time: false,
        }
    }

    /// `λ > 0` finite, `σ ≥ 0` finite, and a regularizer that takes a tensor (covariant or
    /// strain).
    pub fn validate(&self, regularizer: Regularizer) -> Result<(), FlowError> {
        if let Scale::Value(lambda) = self.lambda {
            check(
                "anisotropy lambda",
                lambda,
                lambda > 0.0 && lambda.is_finite(),
                "a positive contrast (grey value per length), or auto",
            )?;
        }
        if let Some(sigma) = self.sigma {
            check(
                "anisotropy sigma",
                sigma,
                sigma >= 0.0 && sigma.is_finite(),
                "a length, finite and ≥ 0",
            )?;
        }
        match regularizer {
            Regularizer::Embedded => Err(FlowError::AnisotropyUnsupported {
                regularizer: "embedded",
            }),
            Regularizer::Covariant | Regularizer::Strain { .. } => Ok(()),
        }
    }

    /// The tensor of every face of `slab` (of `sequence`), from its presmoothed channels, the
    /// contrast `λ` it used (`auto` resolved) and, [`Self::in_time`], each face's space-time
    /// structure.
    pub fn face_tensors(
        &self,
        sequence: &MeshSequence,
        slab: &Slab,
    ) -> Result<SlabTensors, FlowError> {
        let mesh = sequence.mesh();
        let sigma = self
            .sigma
            .unwrap_or_else(|| slab.geometry.mean_edge_length());
        let mids = slab.channels.iter().map(|c| c.mid.as_slice());
        let rates = slab.channels.iter().map(|c| c.rate.as_slice());
        let images: Vec<&[f64]> = match self.in_time {
            true => mids.chain(rates).collect(),
            false => mids.collect(),
        };
        let what = || "the presmoothing of the anisotropic regularizer's image".to_string();
        let smoothed = heat_smoothed(
            sequence,
            &slab.geometry,
            &images,
            0.5 * sigma * sigma,
            HEAT_STEPS,
            what,
        )?;
        let (mids, rates) = smoothed.split_at(slab.channels.len());
        let weights = || slab.channels.iter().map(|c| c.weight);
        let structures: Vec<Matrix2<f64>> = (mesh.faces().iter().enumerate())
            .map(|(f, face)| {
                let channels = weights().zip(mids.iter().map(Vec::as_slice));
                structure_tensor(slab.geometry.triangle(f), face, channels)
            })
            .collect();
        let contrast = match self.lambda {
            Scale::Value(lambda) => lambda,
            Scale::Auto => AUTO_CONTRAST * contrast_median(&structures, slab),
        };
        let space_time = self.in_time.then(|| {
            (mesh.faces().iter().zip(&structures))
                .map(|(face, j)| SpaceTimeStructure {
                    contrast: j.trace(),
                    rate: (weights().zip(rates))
                        .map(|(w, r)| {
                            w * (face.iter().map(|&v| r[v as usize]).sum::<f64>() / 3.0).powi(2)
                        })
                        .sum(),
                })
                .collect()
        });
        Ok(SlabTensors {
            tensors: structures.iter().map(|j| tensor(j, contrast)).collect(),
            contrast,
            space_time,
        })
    }
}

/// What [`Anisotropy::face_tensors`] gives a slab.
pub struct SlabTensors {
    /// Per face, `D` in the face frame.
    pub tensors: Vec<Matrix2<f64>>,
    /// `λ`, `auto` resolved.
    pub contrast: f64,
    /// Per face, with [`Anisotropy::in_time`].
    pub space_time: Option<Vec<SpaceTimeStructure>>,
}

/// The presmoothed image's space-time gradient on one face of a slab, in squares:
/// `contrast = tr J = Σ_c w_c |∇I_c|²` (grey value per length, squared) and
/// `rate = Σ_c w_c (∂_t I_c)²` (grey value per time, squared; `∂_t I_c` the face mean of the
/// slab's rate `τ_c`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpaceTimeStructure {
    pub contrast: f64,
    pub rate: f64,
}

/// The time entry of the space-time tensor at the link of slabs `before` and `after`, per
/// face (module docs, "In time"): `3 (c + λ²) / (2 (c + r / α²) + 3 λ²)` with `c`, `r` and `λ`
/// the two slabs' means. `None` unless both slabs carry their space-time structure.
pub fn time_entries(before: &Slab, after: &Slab, alpha: f64) -> Option<Vec<f64>> {
    let (b, a) = (before.space_time.as_ref()?, after.space_time.as_ref()?);
    let lambda = 0.5 * (before.contrast? + after.contrast?);
    let l2 = lambda * lambda;
    let entries = b.iter().zip(a).map(|(b, a)| {
        let contrast = 0.5 * (b.contrast + a.contrast);
        let rate = 0.5 * (b.rate + a.rate) / (alpha * alpha);
        3.0 * (contrast + l2) / (2.0 * (contrast + rate) + 3.0 * l2)
    });
    Some(entries.collect())
}

/// `D` of the structure `J = Σ_c w_c g_c g_cᵀ` at contrast `λ`:
/// `2 (tr(J) Id − J + λ² Id) / (tr J + 2λ²)`.
pub fn tensor(structure: &Matrix2<f64>, lambda: f64) -> Matrix2<f64> {
    let (trace, l2) = (structure.trace(), lambda * lambda);
    (Matrix2::identity() * (trace + l2) - structure) * (2.0 / (trace + 2.0 * l2))
}

/// The contrast `c` below which half of the slab's total contrast `Σ_T A_T c_T` lies
/// (`c_T = √tr J_T`), the contrast-weighted median; 1 for a flat image (then `J = 0` and
/// `D = Id` whatever `λ`). A flat or dark background counts in proportion to its small
/// contrast, unlike in the median over faces; a few strong edges count in proportion to their
/// contrast, not its square as in the gradient energy.
fn contrast_median(structures: &[Matrix2<f64>], slab: &Slab) -> f64 {
    let faces = (structures.iter().zip(slab.geometry.triangles()))
        .map(|(j, t)| {
            let c = j.trace().max(0.0).sqrt();
            (t.area * c, c)
        })
        .collect();
    Some(weighted_median(faces))
        .filter(|&c| c > 0.0)
        .unwrap_or(1.0)
}
