//! The error type of this crate.

use std::path::PathBuf;

use vatcal_core::{ParamId, ParamSet};
use vatcal_kinematics::ModelError;
use vatcal_observability::ObservabilityError;

use crate::{Identification, IterationLog, Method, Termination};

/// What a failed fit leaves behind: why it stopped, the full iteration log and the last
/// parameter values.
#[derive(Debug, Clone, PartialEq)]
pub struct FailureReport {
    /// method that was run
    pub method: Method,
    /// why it stopped
    pub termination: Termination,
    /// the per-iteration log, iteration 0 = the start
    pub iterations: Vec<IterationLog>,
    /// the parameters that were estimated
    pub params: ParamSet,
    /// starting values (internal units)
    pub start_values: Vec<f64>,
    /// values when the fit stopped (the last finite iterate; internal units)
    pub last_values: Vec<f64>,
}

impl FailureReport {
    /// One paragraph: method, reason, and the residual at the start and at the end.
    pub fn summary(&self) -> String {
        let first = self.iterations.first();
        let last = self.iterations.last();
        let evolution = match (first, last) {
            (Some(a), Some(b)) => format!(
                "; mean residual {:.4} mm at the start, {:.4} mm after {} iteration(s)",
                a.mean_mm, b.mean_mm, b.iteration
            ),
            _ => String::new(),
        };
        format!("{} did not converge: {}{}", self.method, self.termination.describe(), evolution)
    }
}

/// Everything that can go wrong in identification and validation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifyError {
    /// The model rejected a measurement (unknown TCP or calibration position) or produced a
    /// non-finite prediction for it.
    #[error("measurement {index}: {source}")]
    Measurement {
        /// 0-based index of the measurement
        index: usize,
        /// the model's error
        #[source]
        source: ModelError,
    },
    /// The model rejected a parameter (not part of the model, non-finite value).
    #[error("{0}")]
    Model(#[from] ModelError),
    /// No measurements were given.
    #[error("no measurements given")]
    NoMeasurements,
    /// The parameter set is empty.
    #[error("the parameter set is empty")]
    NoParameters,
    /// Not more equations than unknowns: the noise level (and hence the uncertainties) cannot
    /// be estimated.
    #[error("{equations} equations (3 per point measurement, 1 per plane contact) for {params} parameters: need more than {params} equations, i.e. at least {} point measurements", params / 3 + 1)]
    TooFewMeasurements {
        /// the informative residual rows (`vatcal_core::informative_rows`)
        equations: usize,
        /// number of parameters
        params: usize,
    },
    /// The measurements cannot identify the parameter set; the message names the parameters.
    #[error("rank-deficient data: {message}")]
    Unidentifiable {
        /// numerical rank found
        rank: usize,
        /// number of parameters
        needed: usize,
        /// the parameters that cannot be identified together with the others
        unidentifiable: Vec<ParamId>,
        /// explanation from the identifiability analysis
        message: String,
    },
    /// A contact plane's rows do not fix it: fewer than three contacts, or all on a line.
    #[error(
        "plane {id}: its {rows} plane row(s) do not fix a plane (needs at least three contacts not on one line)"
    )]
    UndeterminedPlane {
        /// plane id
        id: u32,
        /// number of its plane rows
        rows: usize,
    },
    /// The identifiability analysis itself failed.
    #[error("identifiability check failed: {0}")]
    Observability(#[source] ObservabilityError),
    /// An option is invalid; the message names it.
    #[error("invalid identification options: {0}")]
    InvalidOptions(String),
    /// The fit diverged, produced non-finite values, stalled or hit the iteration cap. The
    /// report carries the iteration log.
    #[error("{}", .0.summary())]
    NotConverged(Box<FailureReport>),
    /// The fit converged but the data barely determine some parameter combinations: the
    /// condition number at the solution exceeds `max_condition_number`. The fit is attached
    /// for inspection; the message names the strongly correlated parameters.
    #[error("{}", ill_conditioned_message(.0))]
    IllConditioned(Box<Identification>),
    /// A factorisation failed or the information matrix is singular.
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// A report file could not be read or written.
    #[error("{path}: {source}")]
    File {
        /// file
        path: PathBuf,
        /// the I/O or JSON error (a JSON error names the line and column)
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

impl IdentifyError {
    /// The failure report of a fit that did not converge, if that is what this error is.
    pub fn failure(&self) -> Option<&FailureReport> {
        match self {
            IdentifyError::NotConverged(r) => Some(r),
            _ => None,
        }
    }
}

impl From<ObservabilityError> for IdentifyError {
    fn from(e: ObservabilityError) -> Self {
        match e {
            ObservabilityError::RankDeficient { rank, needed, unidentifiable, message } => {
                IdentifyError::Unidentifiable { rank, needed, unidentifiable, message }
            }
            ObservabilityError::NoMeasurements => IdentifyError::NoMeasurements,
            ObservabilityError::NoParameters => IdentifyError::NoParameters,
            ObservabilityError::Model { index, source } => IdentifyError::Measurement { index, source },
            other => IdentifyError::Observability(other),
        }
    }
}

fn ill_conditioned_message(fit: &Identification) -> String {
    let pairs: Vec<String> =
        fit.strong_correlations.iter().take(8).map(|(a, b, c)| format!("{a}/{b} ({c:+.4})")).collect();
    let correlated =
        if pairs.is_empty() { String::new() } else { format!("; strongly correlated: {}", pairs.join(", ")) };
    format!(
        "ill-conditioned data: the condition number of the column-normalised Jacobian at the solution is {:.3e} (healthy designs: ~30){correlated}. These parameters cannot be separated by the measurements: {}",
        fit.condition_number,
        vatcal_core::canonical::conditioning_hint(fit.model.joint_kinds())
    )
}
