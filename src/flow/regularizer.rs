//! The spatial regularizer: which quadratic form of `∇u` the weight `γ` multiplies.
//!
//! ```text
//! covariant (the paper's):  γ ∫ |∇u|²                       (Bochner / connection Laplacian)
//! strain:                   γ ∫ |Sym ∇u|² + δ γ ∫ |∇u|²      (Sym ∇u = (∇u + ∇uᵀ)/2)
//! embedded (KLS):           γ ∫ |∇^{R³} u|² = γ ∫ |∇u|² + |II(u, ·)|²
//! ```
//!
//! The embedded regularizer of Kirisits, Lang & Scherzer (2013) differentiates the flow as an
//! R³-valued field: its normal part adds the second fundamental form term. Discretely, with
//! `P_a` the orthonormal R³ frame of corner `a` (`docs/discretization.md` §8) and `S` the
//! cotan stiffness, the P1 interpolant of the R³ vectors `P_a u_a` has the element block
//! `(a, b) = S_ab P_aᵀ P_b`; on a flat mesh `P_aᵀ P_b = R_aᵀ R_b` and it equals the covariant
//! element to round-off. It needs the embedding (vertex positions), not only edge lengths.
//!
//! The covariant Dirichlet energy is not zero on a rigid rotation of a surface: a Killing field
//! has `∫|∇u|² = ∫ K |u|²` (Bochner), so on a sphere it pulls a turning texture's flow towards
//! zero wherever the image leaves room (along isophotes, in flat patches). The strain energy,
//! the deformation energy of a membrane, vanishes exactly on Killing fields and charges only
//! deformation; the Weitzenböck identity relates the two on a closed surface:
//!
//! ```text
//! ∫ |Sym ∇u|² = ½ ∫ |∇u|² + ½ ∫ (div u)² − ½ ∫ K |u|²
//! ```
//!
//! `δ ≥ 0` mixes the covariant term back in (δ = 0: pure strain). Where the data leaves a
//! Killing field free (stripes leave their translation free on a flat patch, a pattern
//! symmetric about an axis its rotation) the energy has a kernel; `β > 0` removes it (see
//! `flow::uniqueness` for what is detected before solving).
//! The temporal term is the same for both.
//!
//! With [`super::FlowParams::anisotropy`] the covariant and strain densities are weighted by a
//! per-face tensor `D` of the image ([`super::anisotropy`]): `tr(∇u D ∇uᵀ)` and
//! `tr(Sym∇u D Sym∇uᵀ)`, the same forms for `D = Id`.
//!
//! A new regularizer is one more variant here with its element matrix; assembly, energy and
//! solvers take the element from [`Regularizer::element`].

use super::FlowError;
use crate::fem::element::{
    anisotropic_stiffness, anisotropic_strain_element, cotan_stiffness, from_blocks, vector_element,
};
use crate::geometry::Triangle;
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Matrix6};

/// The spatial smoothness term of the energy (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum Regularizer {
    /// `|∇u|²`, the paper's.
    #[default]
    Covariant,
    /// `|Sym ∇u|² + δ |∇u|²`.
    Strain { dirichlet: f64 },
    /// `|∇^{R³} u|²` (Kirisits, Lang & Scherzer).
    Embedded,
}

impl Regularizer {
    /// The 6×6 element matrix of one face (vertex-frame DOFs of its corners, `rotations` the
    /// vertex → face rotations, `frames` the corners' R³ frames, which only
    /// [`Regularizer::Embedded`] uses and [`super::Slab`] provides for embedded sequences,
    /// `tensor` the face's anisotropic tensor `D`, [`super::anisotropy`], `None` for `Id`:
    /// `tr(∇u D ∇uᵀ)` and `tr(Sym∇u D Sym∇uᵀ)`; the embedded kind takes none, as
    /// [`super::FlowParams::validate`] checks), before the weight `γ Δt`.
    pub fn element(
        &self,
        triangle: &Triangle,
        rotations: &[Matrix2<f64>; 3],
        frames: Option<[&Matrix3x2<f64>; 3]>,
        tensor: Option<&Matrix2<f64>>,
    ) -> Matrix6<f64> {
        let identity = Matrix2::identity();
        let d = tensor.unwrap_or(&identity);
        let covariant = || match tensor {
            Some(d) => vector_element(&anisotropic_stiffness(triangle, d), rotations),
            None => vector_element(&cotan_stiffness(triangle), rotations),
        };
        match *self {
            Regularizer::Covariant => covariant(),
            Regularizer::Embedded => {
                let frames = frames.expect("embedded regularizer checked for positions");
                embedded_element(&cotan_stiffness(triangle), frames)
            }
            Regularizer::Strain { dirichlet: 0.0 } => {
                anisotropic_strain_element(triangle, rotations, d)
            }
            Regularizer::Strain { dirichlet } => {
                anisotropic_strain_element(triangle, rotations, d) + covariant() * dirichlet
            }
        }
    }

    /// Whether its element needs the slabs' R³ frames (`Slab::embed`).
    pub fn needs_embedding(&self) -> bool {
        *self == Regularizer::Embedded
    }

    /// `base` (parsed from its name) with the covariant share `dirichlet` of the strain
    /// regularizer, as the CLI's `--dirichlet-mix` and the Python keyword give it.
    pub fn with_mix(base: Regularizer, dirichlet: Option<f64>) -> Result<Self, FlowError> {
        match (base, dirichlet) {
            (base, None) => Ok(base),
            (Regularizer::Strain { .. }, Some(dirichlet)) => Ok(Regularizer::Strain { dirichlet }),
            (_, Some(_)) => Err(FlowError::InvalidParameter {
                name: "dirichlet_mix",
                value: dirichlet.unwrap_or_default(),
                requirement:
                    "only with the strain regularizer (the covariant one is all Dirichlet)",
            }),
        }
    }
}

/// Block `(a, b) = S_ab P_aᵀ P_b`: the cotan form of the R³ vectors `P_a u_a`.
fn embedded_element(stiffness: &Matrix3<f64>, frames: [&Matrix3x2<f64>; 3]) -> Matrix6<f64> {
    from_blocks(|a, b| frames[a].transpose() * frames[b] * stiffness[(a, b)])
}

impl std::str::FromStr for Regularizer {
    type Err = String;

    /// `covariant`, `strain` (pure strain; see [`Regularizer::with_mix`]) or `embedded`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "covariant" => Ok(Regularizer::Covariant),
            "strain" => Ok(Regularizer::Strain { dirichlet: 0.0 }),
            "embedded" => Ok(Regularizer::Embedded),
            other => Err(format!(
                "'{other}' is not one of: covariant, strain, embedded"
            )),
        }
    }
}
