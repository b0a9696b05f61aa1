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

use super::params::check;
use super::pyramid::heat_smoothed;
use super::slab::structure_tensor;
use super::{FlowError, Regularizer, Slab};
use crate::mesh::Mesh;
use nalgebra::Matrix2;

/// Implicit heat steps of the presmoothing.
pub const HEAT_STEPS: usize = 4;

/// `λ` as a value, or `auto`: per slab, the median over faces of the presmoothed image's
/// contrast `√tr J` (`|g|` for one channel), so that half the faces count as edges. Scaling
/// the grey values by `c` scales it by `c` and leaves `D` unchanged, like a given `λ` scaled
/// with them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Contrast {
    Value(f64),
    Auto,
}

impl serde::Serialize for Contrast {
    /// The number, or `"auto"`.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Contrast::Value(lambda) => serializer.serialize_f64(*lambda),
            Contrast::Auto => serializer.serialize_str("auto"),
        }
    }
}

impl std::str::FromStr for Contrast {
    type Err = String;

    /// `auto` or a number (checked by [`Anisotropy::validate`]).
    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "auto" => Ok(Contrast::Auto),
            number => (number.parse().map(Contrast::Value))
                .map_err(|_| format!("'{number}' is neither auto nor a number")),
        }
    }
}

/// `λ` and the presmoothing width `σ` of the anisotropic regularizer (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Anisotropy {
    /// The contrast (grey value per length) at which smoothing across an edge is reduced to
    /// two thirds of its isotropic value (`2λ²/(|g|² + 2λ²)` at `|g| = λ`); `> 0`.
    pub lambda: Contrast,
    /// The presmoothing width (a length); `None`: the slab's mean edge length, `0`: none.
    pub sigma: Option<f64>,
}

impl Anisotropy {
    /// `λ` with the default presmoothing.
    pub fn new(lambda: f64) -> Self {
        Self::with(Contrast::Value(lambda))
    }

    /// `λ` given or `auto`, with the default presmoothing.
    pub fn with(lambda: Contrast) -> Self {
        Self {
            lambda,
            sigma: None,
        }
    }

    /// `λ > 0` finite, `σ ≥ 0` finite, and a regularizer that takes a tensor (covariant or
    /// strain).
    pub fn validate(&self, regularizer: Regularizer) -> Result<(), FlowError> {
        if let Contrast::Value(lambda) = self.lambda {
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

    /// The tensor of every face of `slab` (on `mesh`), from its presmoothed channels, and the
    /// contrast `λ` it used (`auto` resolved).
    pub fn face_tensors(
        &self,
        mesh: &Mesh,
        slab: &Slab,
    ) -> Result<(Vec<Matrix2<f64>>, f64), FlowError> {
        let sigma = self
            .sigma
            .unwrap_or_else(|| slab.geometry.mean_edge_length());
        let mids: Vec<&[f64]> = slab.channels.iter().map(|c| c.mid.as_slice()).collect();
        let what = || "the presmoothing of the anisotropic regularizer's image".to_string();
        let smoothed = heat_smoothed(
            mesh,
            &slab.geometry,
            &mids,
            0.5 * sigma * sigma,
            HEAT_STEPS,
            what,
        )?;
        let weights = slab.channels.iter().map(|c| c.weight);
        let structures: Vec<Matrix2<f64>> = (mesh.faces().iter().enumerate())
            .map(|(f, face)| {
                let channels = weights.clone().zip(smoothed.iter().map(Vec::as_slice));
                structure_tensor(slab.geometry.triangle(f), face, channels)
            })
            .collect();
        let lambda = match self.lambda {
            Contrast::Value(lambda) => lambda,
            Contrast::Auto => median_contrast(&structures),
        };
        Ok((
            structures.iter().map(|j| tensor(j, lambda)).collect(),
            lambda,
        ))
    }
}

/// `D` of the structure `J = Σ_c w_c g_c g_cᵀ` at contrast `λ`:
/// `2 (tr(J) Id − J + λ² Id) / (tr J + 2λ²)`.
pub fn tensor(structure: &Matrix2<f64>, lambda: f64) -> Matrix2<f64> {
    let (trace, l2) = (structure.trace(), lambda * lambda);
    (Matrix2::identity() * (trace + l2) - structure) * (2.0 / (trace + 2.0 * l2))
}

/// The median of `√tr J` over the faces with contrast (1 where the image is flat: then
/// `J = 0` and `D = Id` whatever `λ`).
fn median_contrast(structures: &[Matrix2<f64>]) -> f64 {
    let mut contrasts: Vec<f64> = (structures.iter())
        .map(|j| j.trace().max(0.0).sqrt())
        .filter(|&c| c > 0.0)
        .collect();
    if contrasts.is_empty() {
        return 1.0;
    }
    let middle = contrasts.len() / 2;
    *contrasts.select_nth_unstable_by(middle, f64::total_cmp).1
}
