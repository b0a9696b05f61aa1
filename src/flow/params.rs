//! Model and solver parameters.
//!
//! # Units, and weights that have none
//!
//! The energy `∫∫ (∂_t I + dI(u))² + β|u|² + γ|∇u|² + (γ/α²)|∇_t u|² dA dt` is not scale
//! invariant. With intensity unit `[I]`, length `[L]` and time `[T]` (u is a velocity, `L/T`):
//!
//! - `γ` has units `[I]²`: scaling all intensities by `c` needs `γ → c² γ` for the same flow;
//! - `β` has units `[I]²/[L]²`: scaling intensities by `c` needs `β → c² β`, lengths by `λ`
//!   needs `β → β/λ²`;
//! - `α` is a speed `[L]/[T]`: scaling lengths by `λ` needs `α → λ α`, time by `κ` needs
//!   `α → α/κ`.
//!
//! So no fixed number suits both grey values in `[0, 1]` and in `[0, 255]`, a unit sphere and a
//! scan in millimetres, frames at unit steps and at 1/30 s. Each weight is therefore a
//! [`Weight`]: the paper's value as given ([`Weight::Value`]), or a unit-free scale
//! ([`Weight::Relative`]) that [`FlowParams::weights`] turns into a value with the data's own
//! scales ([`DataScales`]: the image's gradient scale `S`, the mean edge length `h̄` and the
//! mean frame spacing `Δt̄`):
//!
//! ```text
//! γ = (λ h̄ S)²              λ: the spread, in mean edge lengths
//! α = √γ / (S n Δt̄)         n: the time scale, in frames (n = 0: α = ∞, frame by frame)
//! β = b S²                  b: the speed penalty, relative
//! ```
//!
//! Each reads as a balance against the data term `S² |u|²`: the flow changing by its own size
//! over `λ` edge lengths costs as much smoothness as a data mismatch of that size, and likewise
//! over `n` frames. The relative weights give the same flow (in mesh edge lengths per frame)
//! whatever the units of grey values, lengths and times.
//!
//! The defaults, `λ = 0.5`, `n = 1`, `β = 0`, were chosen on textures turning on spheres
//! (`examples/default_parameters.rs`): a dense texture and sparse blobs, at 642 and 2562
//! vertices, all have their best spread between 0.4 and 0.6 edge lengths in these units. The
//! gradient scale `S² = ∫|∇I|⁴ / ∫|∇I|²` is the root mean square gradient *where the gradient
//! energy is*, which is what makes one spread fit dense textures and sparse features alike
//! (the plain root mean square is diluted by empty background and gave best spreads 2.5 times
//! apart).

use super::{Anisotropy, DataScales, FlowDriven, FlowError, Regularizer};

/// Boundary condition in space (time always has natural conditions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Boundary {
    /// Natural: no condition on boundary vertices.
    #[default]
    Neumann,
    /// `u = 0` at boundary vertices.
    Dirichlet,
}

/// Discretization of the temporal smoothness term (`docs/discretization.md` §7).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeCoupling {
    /// Vertex-lumped mid-slab areas: couples each vertex only with itself.
    #[default]
    Lumped,
    /// Consistent P1 mass with mid-slab areas.
    Consistent,
}

/// How the linear system is solved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverChoice {
    /// Direct for small systems, one factorization per slab when `α = ∞`, otherwise PCG with
    /// slab Gauss–Seidel (Jacobi when the slab factors exceed the memory budget).
    #[default]
    Auto,
    /// Sparse Cholesky of the whole space-time system (small problems).
    Direct,
    /// Conjugate gradients, symmetric block Gauss–Seidel in time with per-slab Cholesky factors.
    PcgSlabGaussSeidel,
    /// Conjugate gradients preconditioned by a V-cycle of multigrid in time (slab sweeps as
    /// smoother, slab pairs merged per level).
    PcgTimeMultigrid,
    /// Conjugate gradients with the diagonal as preconditioner (least memory).
    PcgJacobi,
}

/// One of the weights `α`, `β`, `γ`: the value itself in the data's units (the paper's), or a
/// unit-free scale from which [`FlowParams::weights`] derives the value (see the module docs
/// for what each field's relative scale means).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Weight {
    /// The weight itself, in the units of the data.
    Value(f64),
    /// A unit-free scale: the spread (γ), the time scale in frames (α), the relative speed
    /// penalty (β).
    Relative(f64),
}

impl serde::Serialize for Weight {
    /// `{"value": x}` or `{"relative": x}`; an infinite value as the string `"inf"`.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let (key, x) = match *self {
            Weight::Value(x) => ("value", x),
            Weight::Relative(x) => ("relative", x),
        };
        let mut map = serializer.serialize_map(Some(1))?;
        match x.is_finite() {
            true => map.serialize_entry(key, &x)?,
            false => map.serialize_entry(key, "inf")?,
        }
        map.end()
    }
}

/// The weights `α`, `β`, `γ` of the energy as numbers, in the data's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Weights {
    /// `f64::INFINITY` decouples the slabs.
    pub alpha: f64,
    pub beta: f64,
    pub gamma: f64,
}

impl Weights {
    /// Whether the slabs are coupled in time.
    pub fn is_coupled(&self) -> bool {
        self.alpha.is_finite()
    }
}

impl serde::Serialize for Weights {
    /// `alpha` infinite is written as the string `"inf"` (JSON has no infinity).
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut out = serializer.serialize_struct("Weights", 3)?;
        match self.alpha.is_finite() {
            true => out.serialize_field("alpha", &self.alpha)?,
            false => out.serialize_field("alpha", "inf")?,
        }
        out.serialize_field("beta", &self.beta)?;
        out.serialize_field("gamma", &self.gamma)?;
        out.end()
    }
}

/// A scale of the model given as a value, or `auto`: chosen from the data ([`Anisotropy`]'s
/// contrast `λ`, [`FlowParams::robust_smoothness`]'s `ε`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scale {
    Value(f64),
    Auto,
}

impl serde::Serialize for Scale {
    /// The number, or `"auto"`.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Scale::Value(value) => serializer.serialize_f64(*value),
            Scale::Auto => serializer.serialize_str("auto"),
        }
    }
}

impl std::str::FromStr for Scale {
    type Err = String;

    /// `auto` or a number (checked by [`FlowParams::validate`]).
    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "auto" => Ok(Scale::Auto),
            number => (number.parse().map(Scale::Value))
                .map_err(|_| format!("'{number}' is neither auto nor a number")),
        }
    }
}

/// Parameters of the energy (`α`, `β`, `γ`, boundary, coupling) and of the solver.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FlowParams {
    /// Time regularity. `Value`: the paper's `α`, a speed (`f64::INFINITY`: frame by frame).
    /// `Relative(n)`: the time scale in frames, `α = √γ / (S n Δt̄)` (`n = 0`: frame by frame).
    pub alpha: Weight,
    /// Speed penalty `|u|²`. `Value`: the paper's `β ≥ 0`. `Relative(b)`: `β = b S²`. Zero is
    /// allowed when the data and geometry determine `u`.
    pub beta: Weight,
    /// Spatial smoothness `|∇u|²`. `Value`: the paper's `γ > 0`. `Relative(λ)`: the spread in
    /// mean edge lengths, `γ = (λ h̄ S)²`.
    pub gamma: Weight,
    /// What `γ` weighs: the paper's covariant `|∇u|²` or the strain `|Sym ∇u|²`
    /// ([`super::regularizer`]).
    pub regularizer: Regularizer,
    /// `Some`: the image-driven anisotropic regularizer `tr(∇u D ∇uᵀ)` in place of `|∇u|²`
    /// ([`super::anisotropy`]; covariant and strain regularizers). `None`: the isotropic one.
    pub anisotropy: Option<Anisotropy>,
    /// `Some(ε)`: robust (Charbonnier) spatial smoothness `2ε(√(r(u) + ε²) − ε)` in place of
    /// the quadratic `r(u)` of the regularizer, by reweighted solves ([`super::robust`]);
    /// `ε` in the units of `|∇u|` (1/time), or `auto`: per slab, twice the median `|∇u|` of
    /// the first (quadratic) solve. `None`: the quadratic model.
    pub robust_smoothness: Option<Scale>,
    /// How the robust penalty sees the flow's gradient: `ψ` of its size (isotropic, the
    /// default) or of each principal direction (anisotropic; [`super::robust`]). Only with
    /// `robust_smoothness`.
    pub flow_driven: FlowDriven,
    /// `Some(ε)`: the robust (Charbonnier) data term `2ε(√(d(u) + ε²) − ε)` of the face's mean
    /// squared residual `d = ⨍ (∂_t I + dI(u))²` in place of `d`, by reweighted solves
    /// ([`super::robust`], "The data term"); `ε` in the residual's units (grey value per
    /// time), or `auto`: [`super::robust::AUTO_DATA_SCALE`] `· S h̄ / Δt̄`, the residual a
    /// flow wrong by a tenth of an edge length per frame leaves at the image's gradient scale
    /// `S`. `None`: the paper's quadratic data term.
    pub robust_data: Option<Scale>,
    /// Between the warps of coarse-to-fine warping, replace the flow the next warp is
    /// linearized around by its weighted median over each vertex's star
    /// ([`super::median`]; Sun, Roth & Black 2010). Only with warping.
    pub median_filter: bool,
    /// `Some(ρ)`: the combined local-global data term ([`super::local`]; Bruhn, Weickert &
    /// Schnörr 2005), the motion tensor averaged over a Gaussian of standard deviation `ρ` (a
    /// length) on the surface, lumped; `None`: the paper's data term.
    pub local_integration: Option<f64>,
    /// When [`Self::warping`] is [`Warping::NONE`]: after the first linear solve, measure how
    /// far the linear model is from the images warped by its flow ([`super::motion`]) and, if
    /// the motion is too large for it, solve again coarse to fine with
    /// [`Warping::LARGE_MOTION`]. `false`: the paper's single linear solve, always.
    pub detect_large_motion: bool,
    /// The weight `w_c` of each image channel in the data term `Σ_c w_c (∂_t I_c + dI_c(u))²`,
    /// one per channel of the sequence; `None`: 1 for every channel.
    pub channel_weights: Option<Vec<f64>>,
    pub boundary: Boundary,
    pub time_coupling: TimeCoupling,
    pub solver: SolverChoice,
    /// Stop when `‖b − Au‖ ≤ tolerance · ‖b‖`.
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Above this many unknowns `Auto` does not use the direct solver.
    pub direct_limit: usize,
    /// Bytes the per-slab Cholesky factors may take before `Auto` falls back to Jacobi
    /// [default: [`crate::limits::factor_budget`], 35 % of the memory limit].
    pub factor_memory_limit: usize,
    /// Coarse-to-fine warping for large motions ([`Warping::NONE`]: the paper's single linear
    /// solve).
    pub warping: Warping,
}

/// Coarse-to-fine warping (`flow::warp`): `levels` image scales, coarsest first, with `warps`
/// re-linearizations (each one solve of the whole sequence) per level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Warping {
    pub levels: usize,
    pub warps: usize,
}

impl Warping {
    /// One level, no warp: the paper's linear model, solved once.
    pub const NONE: Warping = Warping {
        levels: 1,
        warps: 0,
    };
    /// `--large-motion`: 4 levels, 2 warps each (8 solves). Measured in `examples/large_motion`.
    pub const LARGE_MOTION: Warping = Warping {
        levels: 4,
        warps: 2,
    };

    /// The most warps per level [`FlowParams::validate`] accepts.
    pub const MAX_WARPS: usize = 20;

    /// The CLI's `--levels`, `--warps` and `--large-motion` (and the Python keywords) as one
    /// setting: the preset's values unless given; without the preset, one warp per level once
    /// there are several levels.
    pub fn from_options(levels: Option<usize>, warps: Option<usize>, large_motion: bool) -> Self {
        let preset = match large_motion {
            true => Self::LARGE_MOTION,
            false => Self::NONE,
        };
        let levels = levels.unwrap_or(preset.levels);
        let default_warps = match (large_motion, levels) {
            (true, _) => preset.warps,
            (false, 1) => 0,
            (false, _) => 1,
        };
        Self {
            levels,
            warps: warps.unwrap_or(default_warps),
        }
    }

    /// Whether anything is warped.
    pub fn is_active(&self) -> bool {
        self.warps > 0
    }

    /// The linear solves it takes.
    pub fn solves(&self) -> usize {
        self.levels * self.warps.max(1)
    }
}

impl Default for Warping {
    fn default() -> Self {
        Self::NONE
    }
}

/// The default spread `λ`, in mean edge lengths.
pub const DEFAULT_SPREAD: f64 = 0.5;
/// The default time scale `n`, in frames.
pub const DEFAULT_TIME_SCALE: f64 = 1.0;

impl Default for FlowParams {
    /// Unit-free weights: spread 0.5 edge lengths, time scale 1 frame, no speed penalty.
    fn default() -> Self {
        Self {
            alpha: Weight::Relative(DEFAULT_TIME_SCALE),
            beta: Weight::Value(0.0),
            gamma: Weight::Relative(DEFAULT_SPREAD),
            regularizer: Regularizer::Covariant,
            anisotropy: None,
            robust_smoothness: None,
            flow_driven: FlowDriven::Isotropic,
            robust_data: None,
            median_filter: false,
            local_integration: None,
            detect_large_motion: true,
            channel_weights: None,
            boundary: Boundary::Neumann,
            time_coupling: TimeCoupling::Lumped,
            solver: SolverChoice::Auto,
            tolerance: 1e-8,
            max_iterations: 5000,
            direct_limit: 60_000,
            factor_memory_limit: crate::limits::factor_budget(),
            warping: Warping::NONE,
        }
    }
}

impl FlowParams {
    /// The paper's model with its weights as given (in the data's units): one linear solve,
    /// never switched to warping ([`Self::detect_large_motion`] off); other settings at their
    /// defaults.
    pub fn paper(alpha: f64, beta: f64, gamma: f64) -> Self {
        Self {
            alpha: Weight::Value(alpha),
            beta: Weight::Value(beta),
            gamma: Weight::Value(gamma),
            detect_large_motion: false,
            ..Self::default()
        }
    }

    /// Whether a robust penalty (smoothness or data) makes the minimization a run of
    /// reweighted solves.
    pub fn is_robust(&self) -> bool {
        self.robust_smoothness.is_some() || self.robust_data.is_some()
    }

    /// Checks every parameter; the error names the first invalid one.
    pub fn validate(&self) -> Result<(), FlowError> {
        use Weight::{Relative, Value};
        let (alpha_ok, alpha_requirement) = match self.alpha {
            Value(a) => (a > 0.0, "positive (or infinite for frame-by-frame flow)"),
            Relative(n) => (
                n >= 0.0 && n.is_finite(),
                "a time scale in frames, finite and ≥ 0 (0: frame by frame)",
            ),
        };
        let (beta_ok, gamma_ok) = match (self.beta, self.gamma) {
            (Value(b) | Relative(b), Value(g) | Relative(g)) => {
                (b >= 0.0 && b.is_finite(), g > 0.0 && g.is_finite())
            }
        };
        let gamma_requirement = match self.gamma {
            Value(_) => "finite and > 0",
            Relative(_) => "a spread in edge lengths, finite and > 0",
        };
        check(
            weight_name("alpha", self.alpha),
            number(self.alpha),
            alpha_ok,
            alpha_requirement,
        )?;
        check(
            weight_name("beta", self.beta),
            number(self.beta),
            beta_ok,
            "finite and ≥ 0",
        )?;
        check(
            weight_name("gamma", self.gamma),
            number(self.gamma),
            gamma_ok,
            gamma_requirement,
        )?;
        if let Some(Scale::Value(epsilon)) = self.robust_smoothness {
            check(
                "robust_smoothness",
                epsilon,
                epsilon > 0.0 && epsilon.is_finite(),
                "a positive number (the |∇u| where the penalty turns from quadratic to linear), or auto",
            )?;
        }
        if let Some(Scale::Value(epsilon)) = self.robust_data {
            check(
                "robust_data",
                epsilon,
                epsilon > 0.0 && epsilon.is_finite(),
                "a positive number (the residual ∂_t I + dI(u) where the penalty turns from quadratic to linear), or auto",
            )?;
        }
        if let Some(rho) = self.local_integration {
            check(
                "local_integration",
                rho,
                rho >= 0.0 && rho.is_finite(),
                "a length ≥ 0 (the standard deviation of the motion tensor's average)",
            )?;
        }
        if self.flow_driven == FlowDriven::Anisotropic {
            self.check_flow_driven_anisotropic()?;
        }
        if let Some(weights) = &self.channel_weights {
            if let Some(&w) = weights.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
                check(
                    "channel_weights",
                    w,
                    false,
                    "finite and ≥ 0 for every channel",
                )?;
            }
            check(
                "channel_weights (their sum)",
                weights.iter().sum(),
                weights.iter().any(|&w| w > 0.0),
                "positive: some channel must count",
            )?;
        }
        if let Regularizer::Strain { dirichlet } = self.regularizer {
            check(
                "dirichlet (the covariant part of the strain regularizer)",
                dirichlet,
                dirichlet >= 0.0 && dirichlet.is_finite(),
                "finite and ≥ 0",
            )?;
        }
        if let Some(anisotropy) = &self.anisotropy {
            anisotropy.validate(self.regularizer)?;
        }
        check(
            "tolerance",
            self.tolerance,
            self.tolerance > 0.0 && self.tolerance < 1.0,
            "in (0, 1)",
        )?;
        check(
            "max_iterations",
            self.max_iterations as f64,
            self.max_iterations > 0,
            "at least 1",
        )?;
        check(
            "levels",
            self.warping.levels as f64,
            (1..=12).contains(&self.warping.levels),
            "from 1 to 12",
        )?;
        check(
            "warps",
            self.warping.warps as f64,
            self.warping.warps > 0 || self.warping.levels == 1,
            "at least 1 with more than one level (coarse levels are only used by warping)",
        )?;
        check(
            "warps",
            self.warping.warps as f64,
            self.warping.warps <= Warping::MAX_WARPS,
            "at most 20 per level (each warp is a whole solve)",
        )
    }

    /// The flow-driven anisotropic penalty needs the robust scale `ε` and a regularizer that
    /// takes a tensor.
    fn check_flow_driven_anisotropic(&self) -> Result<(), FlowError> {
        if self.robust_smoothness.is_none() {
            return Err(FlowError::FlowDrivenNeedsRobust);
        }
        match self.regularizer {
            Regularizer::Embedded => Err(FlowError::AnisotropyUnsupported {
                regularizer: "embedded",
            }),
            Regularizer::Covariant | Regularizer::Strain { .. } => Ok(()),
        }
    }

    /// The weight of each of `n_channels` image channels: [`Self::channel_weights`], or 1 each.
    pub fn channel_weights_for(&self, n_channels: usize) -> Result<Vec<f64>, FlowError> {
        match &self.channel_weights {
            None => Ok(vec![1.0; n_channels]),
            Some(w) if w.len() == n_channels => Ok(w.clone()),
            Some(w) => Err(FlowError::CountMismatch {
                what: "channel weights (one per image channel)",
                expected: n_channels,
                got: w.len(),
            }),
        }
    }

    /// The weights as numbers for data with the given scales (relative weights resolved as in
    /// the module docs). Errors: invalid parameters; a relative weight for an image whose
    /// gradient scale is zero.
    pub fn weights(&self, scales: &DataScales) -> Result<Weights, FlowError> {
        self.validate()?;
        let needs_gradient = matches!(self.gamma, Weight::Relative(_))
            || matches!(self.alpha, Weight::Relative(n) if n > 0.0)
            || matches!(self.beta, Weight::Relative(b) if b > 0.0);
        if needs_gradient && !(scales.gradient > 0.0 && scales.gradient.is_finite()) {
            return Err(FlowError::NoImageGradient);
        }
        let s = scales.gradient;
        let gamma = match self.gamma {
            Weight::Value(g) => g,
            Weight::Relative(spread) => (spread * scales.edge_length * s).powi(2),
        };
        let alpha = match self.alpha {
            Weight::Value(a) => a,
            Weight::Relative(0.0) => f64::INFINITY,
            Weight::Relative(n) => gamma.sqrt() / (s * n * scales.frame_spacing),
        };
        let beta = match self.beta {
            Weight::Value(b) => b,
            Weight::Relative(b) => b * s * s,
        };
        check(
            "gamma",
            gamma,
            gamma > 0.0 && gamma.is_finite(),
            "finite and > 0 once derived from the data's scales",
        )?;
        // α as a time scale in frames, n = √γ / (α s Δt): beyond [`MAX_TIME_SCALE`] the
        // coupling of neighbouring frames, γ/α², swamps the rest of the system.
        let frames = gamma.sqrt() / (alpha * s * scales.frame_spacing);
        let measurable = s > 0.0 && scales.frame_spacing > 0.0;
        check(
            weight_name("alpha", self.alpha),
            number(self.alpha),
            alpha.is_infinite() || !measurable || frames <= MAX_TIME_SCALE,
            "a coupling in time no stronger than --time-scale 10⁴ (frames) gives, with --alpha \
             a value not that small: stronger coupling leaves the system numerically singular",
        )?;
        let penalty = beta / gamma;
        check(
            weight_name("beta", self.beta),
            number(self.beta),
            penalty.is_finite(),
            "such that β/γ is a finite number: a smaller --speed-penalty or --beta",
        )?;
        Ok(Weights { alpha, beta, gamma })
    }
}

/// The strongest coupling in time the solvers compute reliably, as a time scale in frames: on
/// the shipped rotating sphere the direct solve's residual is 10⁻⁷ at 10⁴ frames, 10⁻³ at 10⁶,
/// and its Cholesky factorization fails at 10⁸.
pub const MAX_TIME_SCALE: f64 = 1e4;

/// The name of a weight as the command line spells it: the paper's name for a value, the
/// relative name (`spread`, `time-scale`, `speed-penalty`) for a relative scale.
fn weight_name(paper: &'static str, weight: Weight) -> &'static str {
    match (paper, weight) {
        (_, Weight::Value(_)) => paper,
        ("alpha", _) => "time-scale",
        ("beta", _) => "speed-penalty",
        _ => "spread",
    }
}

fn number(weight: Weight) -> f64 {
    match weight {
        Weight::Value(x) | Weight::Relative(x) => x,
    }
}

pub(super) fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    requirement: &'static str,
) -> Result<(), FlowError> {
    match ok {
        true => Ok(()),
        false => Err(FlowError::InvalidParameter {
            name,
            value,
            requirement,
        }),
    }
}

parse_by_name!(Boundary, "neumann" => Boundary::Neumann, "dirichlet" => Boundary::Dirichlet);
parse_by_name!(TimeCoupling, "lumped" => TimeCoupling::Lumped, "consistent" => TimeCoupling::Consistent);
parse_by_name!(
    SolverChoice,
    "auto" => SolverChoice::Auto,
    "direct" => SolverChoice::Direct,
    "pcg-slab-gauss-seidel" => SolverChoice::PcgSlabGaussSeidel,
    "pcg-time-multigrid" => SolverChoice::PcgTimeMultigrid,
    "pcg-jacobi" => SolverChoice::PcgJacobi
);
