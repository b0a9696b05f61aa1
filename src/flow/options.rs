//! The flow's parameters as a user states them, one setting per flag: the CLI's `solve` flags
//! and the Python keywords of `compute_flow` fill a [`FlowOptions`], and
//! [`FlowOptions::params`] checks the settings together and makes the [`FlowParams`]. So both
//! front ends combine their settings by one rule:
//!
//! - each weight is a value (`alpha`, `beta`, `gamma`: the paper's) or relative to its
//!   natural scale (`time_scale`, `speed_penalty`, `spread`; see [`Weight`]), not both;
//! - `anisotropic_sigma` and `anisotropic_in_time` refine `anisotropic` and need it;
//! - `dirichlet_mix` refines the strain regularizer ([`Regularizer::with_mix`]);
//! - `levels`, `warps` and `large_motion` make one [`Warping`].

use super::{Anisotropy, Boundary, FlowDriven, FlowError, FlowParams, Regularizer, Scale};
use super::{SolverChoice, TimeCoupling, Warping, Weight};

/// One setting per flag of `meshflow solve` (see the module documentation); `Default` is no
/// flag given.
#[derive(Clone, Debug, PartialEq)]
pub struct FlowOptions {
    pub alpha: Option<f64>,
    pub time_scale: Option<f64>,
    pub beta: Option<f64>,
    pub speed_penalty: Option<f64>,
    pub gamma: Option<f64>,
    pub spread: Option<f64>,
    pub regularizer: Regularizer,
    pub dirichlet_mix: Option<f64>,
    pub anisotropic: Option<Scale>,
    pub anisotropic_sigma: Option<f64>,
    pub anisotropic_in_time: bool,
    pub robust_smoothness: Option<Scale>,
    pub flow_driven: FlowDriven,
    pub robust_data: Option<Scale>,
    pub median_filter: bool,
    pub local_integration: Option<f64>,
    /// `false`: `--no-large-motion`.
    pub detect_large_motion: bool,
    pub channel_weights: Option<Vec<f64>>,
    pub boundary: Boundary,
    pub time_coupling: TimeCoupling,
    pub solver: SolverChoice,
    pub tolerance: f64,
    pub levels: Option<usize>,
    pub warps: Option<usize>,
    pub large_motion: bool,
}

impl Default for FlowOptions {
    fn default() -> Self {
        let defaults = FlowParams::default();
        Self {
            alpha: None,
            time_scale: None,
            beta: None,
            speed_penalty: None,
            gamma: None,
            spread: None,
            regularizer: defaults.regularizer,
            dirichlet_mix: None,
            anisotropic: None,
            anisotropic_sigma: None,
            anisotropic_in_time: false,
            robust_smoothness: defaults.robust_smoothness,
            flow_driven: defaults.flow_driven,
            robust_data: defaults.robust_data,
            median_filter: defaults.median_filter,
            local_integration: defaults.local_integration,
            detect_large_motion: defaults.detect_large_motion,
            channel_weights: defaults.channel_weights,
            boundary: defaults.boundary,
            time_coupling: defaults.time_coupling,
            solver: defaults.solver,
            tolerance: defaults.tolerance,
            levels: None,
            warps: None,
            large_motion: false,
        }
    }
}

impl FlowOptions {
    /// The parameters these settings make, checked ([`FlowParams::validate`]); the error names
    /// the first setting at fault, by its flag.
    pub fn params(&self) -> Result<FlowParams, FlowError> {
        let defaults = FlowParams::default();
        let params = FlowParams {
            alpha: weight(
                (self.alpha, "--alpha"),
                (self.time_scale, "--time-scale"),
                defaults.alpha,
            )?,
            beta: weight(
                (self.beta, "--beta"),
                (self.speed_penalty, "--speed-penalty"),
                defaults.beta,
            )?,
            gamma: weight(
                (self.gamma, "--gamma"),
                (self.spread, "--spread"),
                defaults.gamma,
            )?,
            regularizer: Regularizer::with_mix(self.regularizer, self.dirichlet_mix)?,
            anisotropy: self.anisotropy()?,
            robust_smoothness: self.robust_smoothness,
            flow_driven: self.flow_driven,
            robust_data: self.robust_data,
            median_filter: self.median_filter,
            local_integration: self.local_integration,
            detect_large_motion: self.detect_large_motion,
            channel_weights: self.channel_weights.clone(),
            boundary: self.boundary,
            time_coupling: self.time_coupling,
            solver: self.solver,
            tolerance: self.tolerance,
            warping: Warping::from_options(self.levels, self.warps, self.large_motion),
            ..defaults
        };
        params.validate()?;
        Ok(params)
    }

    /// `anisotropic` with `anisotropic_sigma` and `anisotropic_in_time`.
    fn anisotropy(&self) -> Result<Option<Anisotropy>, FlowError> {
        let Some(lambda) = self.anisotropic else {
            let refinement = match (self.anisotropic_sigma, self.anisotropic_in_time) {
                (Some(_), _) => Some("--anisotropic-sigma"),
                (None, true) => Some("--anisotropic-in-time"),
                (None, false) => None,
            };
            return match refinement {
                Some(option) => Err(FlowError::OptionNeeds {
                    option,
                    needs: "--anisotropic",
                }),
                None => Ok(None),
            };
        };
        Ok(Some(Anisotropy {
            sigma: self.anisotropic_sigma,
            in_time: self.anisotropic_in_time,
            ..Anisotropy::with(lambda)
        }))
    }
}

/// A weight given as a value or relative to its scale (each with its flag), not both;
/// `default` when neither.
fn weight(
    (value, value_flag): (Option<f64>, &'static str),
    (relative, relative_flag): (Option<f64>, &'static str),
    default: Weight,
) -> Result<Weight, FlowError> {
    match (value, relative) {
        (Some(_), Some(_)) => Err(FlowError::ConflictingOptions {
            first: value_flag,
            second: relative_flag,
        }),
        (Some(v), None) => Ok(Weight::Value(v)),
        (None, Some(r)) => Ok(Weight::Relative(r)),
        (None, None) => Ok(default),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_setting_gives_the_default_parameters() {
        assert_eq!(
            FlowOptions::default().params().unwrap(),
            FlowParams::default()
        );
    }

    #[test]
    fn each_setting_reaches_its_parameter() {
        let options = FlowOptions {
            alpha: Some(0.5),
            speed_penalty: Some(0.01),
            spread: Some(2.0),
            regularizer: Regularizer::Strain { dirichlet: 0.0 },
            dirichlet_mix: Some(0.25),
            anisotropic: Some(Scale::Value(0.3)),
            anisotropic_sigma: Some(0.0),
            anisotropic_in_time: true,
            large_motion: true,
            ..FlowOptions::default()
        };
        let params = options.params().unwrap();
        assert_eq!(params.alpha, Weight::Value(0.5));
        assert_eq!(params.beta, Weight::Relative(0.01));
        assert_eq!(params.gamma, Weight::Relative(2.0));
        assert_eq!(params.regularizer, Regularizer::Strain { dirichlet: 0.25 });
        let anisotropy = params.anisotropy.unwrap();
        assert_eq!(anisotropy.lambda, Scale::Value(0.3));
        assert_eq!((anisotropy.sigma, anisotropy.in_time), (Some(0.0), true));
        assert_eq!(params.warping, Warping::LARGE_MOTION);
    }

    #[test]
    fn conflicting_and_incomplete_settings_are_named() {
        let both = FlowOptions {
            gamma: Some(1e-3),
            spread: Some(0.5),
            ..FlowOptions::default()
        };
        let error = both.params().unwrap_err().to_string();
        assert_eq!(error, "give one of --gamma and --spread, not both");
        let sigma_alone = FlowOptions {
            anisotropic_sigma: Some(1.0),
            ..FlowOptions::default()
        };
        let error = sigma_alone.params().unwrap_err().to_string();
        assert_eq!(error, "--anisotropic-sigma needs --anisotropic");
        let invalid = FlowOptions {
            tolerance: 0.0,
            ..FlowOptions::default()
        };
        assert!(invalid
            .params()
            .unwrap_err()
            .to_string()
            .contains("tolerance"));
    }
}
