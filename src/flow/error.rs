//! What can go wrong between a sequence and its flow.

use crate::geometry::GeometryError;

/// Why a flow could not be computed. Variants name the frame, vertex or parameter at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FlowError {
    /// The space-time system would not fit the memory limit ([`crate::limits`]).
    #[error(transparent)]
    OverMemoryLimit(#[from] crate::limits::OverBudget),
    #[error("a sequence needs at least 2 frames, got {0}")]
    TooFewFrames(usize),
    #[error("expected {expected} {what}, got {got}")]
    CountMismatch {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("interrupted")]
    Interrupted,
    #[error("the sequence has edge lengths only (no vertex positions): there is no surface in R^3 to place points on")]
    Intrinsic,
    #[error("point {point} has a non-finite coordinate")]
    NonFinitePoint { point: usize },
    #[error("the embedded regularizer differentiates the flow in R^3 and needs vertex positions; this sequence has edge lengths only (use the covariant or strain regularizer)")]
    NeedsEmbedding,
    #[error("frame {frame}: {source}")]
    Frame {
        frame: usize,
        #[source]
        source: GeometryError,
    },
    #[error("slab {slab} (frames {slab} and {}): {source}", slab + 1)]
    Slab {
        slab: usize,
        #[source]
        source: GeometryError,
    },
    #[error("frame {frame}: intensity at vertex {vertex}{} is {value}, not a finite number", channel.map_or(String::new(), |c| format!(", channel {c}")))]
    NonFiniteIntensity {
        frame: usize,
        vertex: usize,
        /// `None` for a grey (one-channel) image.
        channel: Option<usize>,
        value: f64,
    },
    #[error("frame {frame} has {got} image channels, frame 0 has {expected}")]
    ChannelMismatch {
        frame: usize,
        expected: usize,
        got: usize,
    },
    #[error("frame times must be finite and strictly increasing, but t[{frame}] = {value} follows t[{}] = {previous}", frame - 1)]
    NonIncreasingTimes {
        frame: usize,
        value: f64,
        previous: f64,
    },
    #[error("frame time t[{frame}] = {value} is not a finite number")]
    NonFiniteTime { frame: usize, value: f64 },
    #[error("parameter {name} = {} is invalid: it must be {requirement}", readable(*value))]
    InvalidParameter {
        name: &'static str,
        value: f64,
        requirement: &'static str,
    },
    #[error("give one of {first} and {second}, not both")]
    ConflictingOptions {
        first: &'static str,
        second: &'static str,
    },
    #[error("{option} needs {needs}")]
    OptionNeeds {
        option: &'static str,
        needs: &'static str,
    },
    #[error("the anisotropic regularizers (--anisotropic, --flow-driven anisotropic) weight the covariant |∇u|² or the strain |Sym ∇u|², not the {regularizer} regularizer (use --regularizer covariant or strain)")]
    AnisotropyUnsupported { regularizer: &'static str },
    #[error("the flow-driven anisotropic penalty (--flow-driven anisotropic) is a robust one: give its scale with --robust-smoothness EPS")]
    FlowDrivenNeedsRobust,
    #[error("{what} does not run over several ranks yet: run it in one process (or, for the solver, use auto, pcg-slab-gauss-seidel or pcg-time-multigrid)")]
    NotDistributed { what: &'static str },
    #[error("{ranks} ranks for {slabs} slabs: each rank needs at least one slab (run with at most {slabs} ranks)")]
    TooManyRanks { ranks: usize, slabs: usize },
    #[error("the grey values do not vary over the surface in any frame, so no flow can be measured; relative weights (--spread, --time-scale, --speed-penalty) need an image gradient")]
    NoImageGradient,
    #[error("the energy has no unique minimizer ({reason}); a speed penalty fixes the undetermined field: --speed-penalty 0.01 (relative to the data's scales), or β > 0 in the data's units (--beta)")]
    Singular { reason: String },
    #[error("the sparse Cholesky factorization of {what} failed ({detail}); the system is not numerically positive definite: try a speed penalty (--speed-penalty 0.01, or --beta in the data's units)")]
    Factorization { what: String, detail: String },
    #[error("the solver stopped after {iterations} iterations at relative residual {residual:.3e}, above the tolerance {tolerance:.1e}")]
    NotConverged {
        iterations: usize,
        residual: f64,
        tolerance: f64,
    },
}

/// A number as a person writes it: plainly between 10⁻⁴ and 10⁶, else in scientific notation.
fn readable(value: f64) -> String {
    match value.abs() {
        a if a == 0.0 || !a.is_finite() || (1e-4..1e6).contains(&a) => format!("{value}"),
        _ => format!("{value:e}"),
    }
}
