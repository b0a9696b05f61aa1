//! The spatial regularizer: which quadratic form of `∇u` the weight `γ` multiplies.
//!
//! ```text
//! covariant (the paper's):  γ ∫ |∇u|²                       (Bochner / connection Laplacian)
//! strain:                   γ ∫ |Sym ∇u|² + δ γ ∫ |∇u|²      (Sym ∇u = (∇u + ∇uᵀ)/2)
//! ```
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
//! [`super::uniqueness`] for what is detected before solving).
//! The temporal term is the same for both.
//!
//! A new regularizer is one more variant here with its element matrix; assembly, energy and
//! solvers take the element from [`Regularizer::element`].

use super::FlowError;
use crate::fem::element::{cotan_stiffness, strain_element, vector_element};
use crate::geometry::Triangle;
use nalgebra::{Matrix2, Matrix6};

/// The spatial smoothness term of the energy (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum Regularizer {
    /// `|∇u|²`, the paper's.
    #[default]
    Covariant,
    /// `|Sym ∇u|² + δ |∇u|²`.
    Strain { dirichlet: f64 },
}

impl Regularizer {
    /// The 6×6 element matrix of one face (vertex-frame DOFs of its corners, `rotations` the
    /// vertex → face rotations), before the weight `γ Δt`.
    pub fn element(&self, triangle: &Triangle, rotations: &[Matrix2<f64>; 3]) -> Matrix6<f64> {
        let covariant = || vector_element(&cotan_stiffness(triangle), rotations);
        match *self {
            Regularizer::Covariant => covariant(),
            Regularizer::Strain { dirichlet: 0.0 } => strain_element(triangle, rotations),
            Regularizer::Strain { dirichlet } => {
                strain_element(triangle, rotations) + covariant() * dirichlet
            }
        }
    }

    /// `base` (parsed from its name) with the covariant share `dirichlet` of the strain
    /// regularizer, as the CLI's `--dirichlet-mix` and the Python keyword give it.
    pub fn with_mix(base: Regularizer, dirichlet: Option<f64>) -> Result<Self, FlowError> {
        match (base, dirichlet) {
            (base, None) => Ok(base),
            (Regularizer::Strain { .. }, Some(dirichlet)) => Ok(Regularizer::Strain { dirichlet }),
            (Regularizer::Covariant, Some(_)) => Err(FlowError::InvalidParameter {
                name: "dirichlet_mix",
                value: dirichlet.unwrap_or_default(),
                requirement:
                    "only with the strain regularizer (the covariant one is all Dirichlet)",
            }),
        }
    }
}

impl std::str::FromStr for Regularizer {
    type Err = String;

    /// `covariant` or `strain` (pure strain; set `dirichlet` afterwards for a mix).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "covariant" => Ok(Regularizer::Covariant),
            "strain" => Ok(Regularizer::Strain { dirichlet: 0.0 }),
            other => Err(format!("'{other}' is not one of: covariant, strain")),
        }
    }
}
