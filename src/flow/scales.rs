//! The data's own scales: what turns the unit-free weights of [`FlowParams`] into numbers.
//!
//! ```text
//! S²  = Σ_s Δt_s Σ_T A_T |∇I_T|⁴ / Σ_s Δt_s Σ_T A_T |∇I_T|²     (∇I_T: P1 gradient of I_mid on T)
//! |∇I_T|² = Σ_c w_c |∇I_{c,T}|²                                     (several channels)
//! h̄   = mean over slabs of the mean edge length of the slab geometry
//! Δt̄  = (t_{K−1} − t_0) / (K − 1)
//! ```
//!
//! `S` is the root mean square of `|∇I|` weighted by the gradient energy `|∇I|² dA dt`: the
//! typical gradient of the image's features, unaffected by how much empty background surrounds
//! them (see [`crate::flow::FlowParams`] for why that matters). An image whose mid-slab grey
//! values are all equal, to `1e-12` of their magnitude, in every slab has `S = 0` (its P1
//! gradient is round-off).
//!
//! With the image-driven anisotropic regularizer ([`super::anisotropy`]), `|∇I_T|²` is replaced
//! by the gradient energy its tensor smooths across, `tr(J_T D_λ(J_T))` with `J_T` the structure
//! below and `λ` the slab's contrast: a strong edge, which the tensor does not smooth across,
//! counts like a feature of contrast `√2 λ` instead of setting the smoothing of the whole
//! surface. `λ → ∞` gives `|∇I_T|²` back.
//!
//! With several channels `|∇I|²` is the trace of the data term's structure tensor
//! `Σ_c w_c ∇I_c ∇I_cᵀ`, so `C` equal channels have `S² = C S²_grey`, the relative weights grow
//! with the data term, and the flow is the grey image's.

//!
//! [`FlowParams`]: super::FlowParams

use super::{anisotropy, Slab};
use crate::mesh::Mesh;

/// Grey values closer than this, relative to their magnitude, count as equal.
const EQUAL_GREY: f64 = 1e-12;

/// The data's own scales (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DataScales {
    /// `S`, grey values per unit length; 0 for an image without spatial variation.
    pub gradient: f64,
    /// `h̄`: the mean edge length of the slab geometries.
    pub edge_length: f64,
    /// `Δt̄`: the mean frame spacing.
    pub frame_spacing: f64,
}

impl DataScales {
    /// The scales of the slabs of a sequence of `mesh`.
    pub fn measure(mesh: &Mesh, slabs: &[Slab]) -> Self {
        ScaleSums::measure(mesh, slabs).scales()
    }
}

/// The sums behind [`DataScales`] over some of a sequence's slabs: the scales of all slabs are
/// those of the added (`+`) sums of any split of them (the time windows of a
/// distributed solve complete them with one all-reduce of [`ScaleSums::to_array`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScaleSums {
    /// `Σ Δt A |∇I|²` and `Σ Δt A |∇I|⁴`.
    pub second: f64,
    pub fourth: f64,
    /// Sums over slabs of the mean edge length and of `Δt`, and the number of slabs.
    pub edge_length: f64,
    pub duration: f64,
    pub slabs: f64,
    /// 1 when some slab's image varies, else 0 (its sum over splits counts such windows).
    pub varying: f64,
}

impl ScaleSums {
    pub fn measure(mesh: &Mesh, slabs: &[Slab]) -> Self {
        let (mut second, mut fourth) = (0.0, 0.0);
        for slab in slabs {
            for (f, (face, triangle)) in mesh
                .faces()
                .iter()
                .zip(slab.geometry.triangles())
                .enumerate()
            {
                let structure = slab.structure_tensor(face, f);
                let squared = match slab.contrast {
                    Some(lambda) => (structure * anisotropy::tensor(&structure, lambda)).trace(),
                    None => structure.trace(),
                };
                second += slab.dt * triangle.area * squared;
                fourth += slab.dt * triangle.area * squared * squared;
            }
        }
        let varying = (slabs.iter())
            .flat_map(|slab| &slab.channels)
            .any(|channel| channel.weight != 0.0 && !is_constant(&channel.mid));
        ScaleSums {
            second,
            fourth,
            edge_length: slabs.iter().map(|s| s.geometry.mean_edge_length()).sum(),
            duration: slabs.iter().map(|slab| slab.dt).sum(),
            slabs: slabs.len() as f64,
            varying: f64::from(u8::from(varying)),
        }
    }

    /// `[second, fourth, edge_length, duration, slabs, varying]`.
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.second,
            self.fourth,
            self.edge_length,
            self.duration,
            self.slabs,
            self.varying,
        ]
    }

    pub fn from_array(values: [f64; 6]) -> Self {
        let [second, fourth, edge_length, duration, slabs, varying] = values;
        ScaleSums {
            second,
            fourth,
            edge_length,
            duration,
            slabs,
            varying,
        }
    }

    /// `S = √(Σ|∇I|⁴ / Σ|∇I|²)` (0 when no slab's image varies), `h̄`, `Δt̄`.
    pub fn scales(&self) -> DataScales {
        DataScales {
            gradient: match self.varying > 0.0 {
                true => (self.fourth / self.second).sqrt(),
                false => 0.0,
            },
            edge_length: self.edge_length / self.slabs,
            frame_spacing: self.duration / self.slabs,
        }
    }
}

/// The sums over both splits.
impl std::ops::Add for ScaleSums {
    type Output = Self;

    fn add(self, other: Self) -> Self {
        let [a, b] = [self.to_array(), other.to_array()];
        Self::from_array(std::array::from_fn(|k| a[k] + b[k]))
    }
}

/// Whether all `values` agree to [`EQUAL_GREY`] of their largest magnitude.
fn is_constant(values: &[f64]) -> bool {
    let (low, high) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    high - low <= EQUAL_GREY * low.abs().max(high.abs())
}
