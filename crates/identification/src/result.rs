//! What a fit returns: the calibrated model, the iteration log and the statistics.

use nalgebra::{DMatrix, Vector3};
use serde::{Deserialize, Serialize};
use vatcal_core::{ParamId, ParamSet};
use vatcal_kinematics::Model;

use crate::{ErrorStats, Method};

/// One line of the iteration log. Iteration 0 is the starting point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IterationLog {
    /// iteration number (0 = start)
    pub iteration: usize,
    /// mean residual magnitude over the point measurements (probe, tracker) \[mm\]
    pub mean_mm: f64,
    /// RMS residual magnitude of the point measurements \[mm\]
    pub rms_mm: f64,
    /// largest residual magnitude of the point measurements \[mm\]
    pub max_mm: f64,
    /// RMS rotation-vector residual of the orientation rows \[mrad\] (`None`: no orientation
    /// rows)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation_rms_mrad: Option<f64>,
    /// weighted cost `Σ w_k ‖r_k‖²` plus the prior terms \[mm²\]
    pub cost: f64,
    /// damping λ of the accepted step (0 for Gauss–Newton and the paper-literal method)
    pub lambda: f64,
    /// largest parameter change of the step in units of the parameter's typical a-priori
    /// standard deviation (0 at iteration 0)
    pub step_norm: f64,
}

/// Why the iteration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Termination {
    /// the step fell below `step_tolerance` (converged)
    StepTolerance,
    /// the residual is orthogonal to every Jacobian column within `gradient_tolerance`
    /// (converged)
    GradientTolerance,
    /// the relative cost reduction fell below `cost_tolerance` (converged)
    CostTolerance,
    /// the paper's stop rule: the mean residual changed by less than 1e-6 mm (converged;
    /// paper-literal method only)
    ErrorChange,
    /// the iteration cap was reached
    MaxIterations,
    /// the mean residual grew beyond `divergence_factor` × its starting value
    Diverged,
    /// a parameter, residual or step became NaN or infinite
    NonFinite,
    /// Levenberg–Marquardt could not reduce the cost even with a huge damping
    Stalled,
}

impl Termination {
    /// True for the stopping reasons that mean convergence.
    pub fn is_converged(self) -> bool {
        matches!(
            self,
            Termination::StepTolerance
                | Termination::GradientTolerance
                | Termination::CostTolerance
                | Termination::ErrorChange
        )
    }

    /// A short human-readable explanation.
    pub fn describe(self) -> &'static str {
        match self {
            Termination::StepTolerance => "converged: the parameter step fell below the step tolerance",
            Termination::GradientTolerance => {
                "converged: the residual is orthogonal to every Jacobian column"
            }
            Termination::CostTolerance => {
                "converged: the relative cost reduction fell below the cost tolerance"
            }
            Termination::ErrorChange => {
                "converged: the mean residual changed by less than 1e-6 mm (paper's rule)"
            }
            Termination::MaxIterations => "the iteration cap was reached",
            Termination::Diverged => "diverged: the mean residual grew beyond the divergence factor",
            Termination::NonFinite => "a parameter, residual or step became NaN or infinite",
            Termination::Stalled => "stalled: no cost reduction even with a very large damping",
        }
    }
}

/// The result of [`identify`](crate::identify).
///
/// Parameter values, σ and covariance are in **internal units** (mm, rad, rad/(N·m)); the JSON
/// report ([`IdentificationReport`](crate::IdentificationReport)) converts to file units.
#[derive(Debug, Clone)]
pub struct Identification {
    /// method that was run
    pub method: Method,
    /// the calibrated model (start model with the identified values)
    pub model: Model,
    /// the identified parameters, in order
    pub params: ParamSet,
    /// starting values
    pub start_values: Vec<f64>,
    /// identified values
    pub values: Vec<f64>,
    /// standard deviations √Cov_jj
    pub sigma: Vec<f64>,
    /// covariance `σ̂² (JᵀWJ [+ prior information])⁻¹` (L × L)
    pub covariance: DMatrix<f64>,
    /// correlation matrix `S⁻¹ Cov S⁻¹`
    pub correlation: DMatrix<f64>,
    /// pairs with |correlation| above the threshold, strongest first
    pub strong_correlations: Vec<(ParamId, ParamId, f64)>,
    /// |correlation| threshold used for `strong_correlations`
    pub correlation_threshold: f64,
    /// per-iteration log (iteration 0 = start)
    pub iterations: Vec<IterationLog>,
    /// residuals `target − FK` of every measurement at the solution \[mm\] (unweighted)
    pub residuals: Vec<Vector3<f64>>,
    /// statistics of `residuals`
    pub residual_stats: ErrorStats,
    /// weighted residual sum of squares of the measurements at the solution \[mm²\]
    pub rss: f64,
    /// σ̂ = √(RSS / dof): estimated noise of one coordinate of a weight-1 measurement \[mm\]
    pub sigma_hat_mm: f64,
    /// degrees of freedom 3n − L
    pub dof: usize,
    /// condition number of the weighted, column-normalised measurement Jacobian at the solution
    pub condition_number: f64,
    /// singular values of that matrix, descending
    pub singular_values: Vec<f64>,
    /// whether a convergence criterion fired (false only with `accept_iteration_cap`)
    pub converged: bool,
    /// why the iteration stopped
    pub termination: Termination,
    /// number of probe measurements used
    pub n_probe: usize,
    /// number of tracker measurements used
    pub n_tracker: usize,
}

impl Identification {
    /// Identified value of `id` (internal units), if it was estimated.
    pub fn value_of(&self, id: ParamId) -> Option<f64> {
        self.params.index_of(id).map(|k| self.values[k])
    }

    /// Standard deviation of `id` (internal units), if it was estimated.
    pub fn sigma_of(&self, id: ParamId) -> Option<f64> {
        self.params.index_of(id).map(|k| self.sigma[k])
    }
}
