//! Model and solver parameters.
//!
//! # Units and scaling
//!
//! The energy `∫∫ (∂_t I + dI(u))² + β|u|² + γ|∇u|² + (γ/α²)|∇_t u|² dA dt` is not scale
//! invariant. With intensity unit `[I]`, length `[L]` and time `[T]` (u is a velocity, `L/T`):
//!
//! - `γ` has units `[I]²`: scaling all intensities by `c` needs `γ → c² γ` and `β → c² β` for
//!   the same flow;
//! - `β` has units `[I]²/[L]²`: it penalizes speed; scaling lengths by `λ` needs `β → β/λ²`;
//! - `α` is a speed `[L]/[T]`: it compares spatial to temporal variation of the flow, scaling
//!   lengths by `λ` needs `α → λ α`, and time by `κ` needs `α → α/κ`.
//!
//! The defaults (`α = 1`, `β = 0`, `γ = 0.1`) suit intensities in `[0, 1]` on surfaces of unit
//! size sampled at unit time steps: the smoothness weight `γ = 0.1` is a tenth of a squared
//! full-range contrast, so flow is driven by edges of contrast ≳ 0.3 and filled in smoothly
//! elsewhere (Horn–Schunck's α² in the same units); `α = 1` lets the flow change by about its
//! own size per unit time, and `β = 0` adds no bias towards zero speed.

use super::FlowError;

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
    /// Conjugate gradients with the diagonal as preconditioner (least memory).
    PcgJacobi,
}

/// Parameters of the energy (`α`, `β`, `γ`, boundary, coupling) and of the solver.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FlowParams {
    /// Ratio of temporal to spatial smoothness scale, a speed. `f64::INFINITY` decouples the
    /// slabs (frame-by-frame flow).
    pub alpha: f64,
    /// Weight of `|u|²` (≥ 0). Zero is allowed when the data and geometry determine `u`.
    pub beta: f64,
    /// Weight of the spatial smoothness `|∇u|²` (> 0).
    pub gamma: f64,
    pub boundary: Boundary,
    pub time_coupling: TimeCoupling,
    pub solver: SolverChoice,
    /// Stop when `‖b − Au‖ ≤ tolerance · ‖b‖`.
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Above this many unknowns `Auto` does not use the direct solver.
    pub direct_limit: usize,
    /// Bytes the per-slab Cholesky factors may take before `Auto` falls back to Jacobi.
    pub factor_memory_limit: usize,
}

impl Default for FlowParams {
    fn default() -> Self {
        Self {
            alpha: 1.0,
            beta: 0.0,
            gamma: 0.1,
            boundary: Boundary::Neumann,
            time_coupling: TimeCoupling::Lumped,
            solver: SolverChoice::Auto,
            tolerance: 1e-8,
            max_iterations: 5000,
            direct_limit: 60_000,
            factor_memory_limit: 8 << 30,
        }
    }
}

impl FlowParams {
    /// Checks every parameter; the error names the first invalid one.
    pub fn validate(&self) -> Result<(), FlowError> {
        let check = |name, value: f64, ok: bool, requirement| {
            if ok {
                Ok(())
            } else {
                Err(FlowError::InvalidParameter {
                    name,
                    value,
                    requirement,
                })
            }
        };
        check(
            "alpha",
            self.alpha,
            self.alpha > 0.0,
            "positive (or infinite for frame-by-frame flow)",
        )?;
        check(
            "beta",
            self.beta,
            self.beta >= 0.0 && self.beta.is_finite(),
            "finite and ≥ 0",
        )?;
        check(
            "gamma",
            self.gamma,
            self.gamma > 0.0 && self.gamma.is_finite(),
            "finite and > 0",
        )?;
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
        )
    }

    /// Whether the slabs are coupled in time.
    pub fn is_coupled(&self) -> bool {
        self.alpha.is_finite()
    }
}

/// Parses the lowercase names used on the command line (`neumann`, `dirichlet`, …).
macro_rules! parse_by_name {
    ($type:ty, $($name:literal => $value:expr),+) => {
        impl std::str::FromStr for $type {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($name => Ok($value),)+
                    other => Err(format!("'{other}' is not one of: {}", [$($name),+].join(", "))),
                }
            }
        }
    };
}

parse_by_name!(Boundary, "neumann" => Boundary::Neumann, "dirichlet" => Boundary::Dirichlet);
parse_by_name!(TimeCoupling, "lumped" => TimeCoupling::Lumped, "consistent" => TimeCoupling::Consistent);
parse_by_name!(
    SolverChoice,
    "auto" => SolverChoice::Auto,
    "direct" => SolverChoice::Direct,
    "pcg-slab-gauss-seidel" => SolverChoice::PcgSlabGaussSeidel,
    "pcg-jacobi" => SolverChoice::PcgJacobi
);
