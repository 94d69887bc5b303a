//! The one place where discovery calls the identification crate: a fit of a parameter set and
//! the quantities the tests need from it (residual vectors, RSS, the identified rank, the
//! parameter covariance), plus prediction errors on other measurements.

use nalgebra::Vector3;
use vatcal_core::{Measurement, ParamId, ParamSet};
use vatcal_identification::{ErrorStats, IdentifyOptions, identify};
use vatcal_kinematics::Model;

use crate::DiscoveryError;

/// A converged (or capped) least-squares fit of `params` to a set of measurements.
#[derive(Debug, Clone)]
pub struct Fit {
    /// the identified model
    pub model: Model,
    /// the fitted parameters
    pub params: ParamSet,
    /// residual vector of every measurement \[mm\] (`target − FK`)
    pub residuals: Vec<Vector3<f64>>,
    /// residual sum of squares \[mm²\]
    pub rss_mm2: f64,
    /// Gauss–Newton / LM iterations used
    pub iterations: usize,
    /// whether the solver's stop rule was met
    pub converged: bool,
    /// parameter correlation matrix (params order)
    pub correlation: nalgebra::DMatrix<f64>,
    /// standard deviation of every parameter (params order, internal units)
    pub sigma: Vec<f64>,
}

impl Fit {
    /// Number of scalar residuals (3 per measurement).
    pub fn n(&self) -> usize {
        3 * self.residuals.len()
    }

    /// The residuals stacked as one vector (x, y, z of measurement 0, then 1, ...).
    pub fn stacked_residual(&self) -> Vec<f64> {
        self.residuals.iter().flat_map(|r| [r.x, r.y, r.z]).collect()
    }

    /// Identified value of `id` (internal units).
    pub fn value(&self, id: ParamId) -> Option<f64> {
        self.model.param(id).ok()
    }

    /// Correlation of parameters `a` and `b` (indices into `params`), if known.
    pub fn correlation(&self, a: usize, b: usize) -> Option<f64> {
        let l = self.correlation.nrows();
        (a < l && b < l && self.correlation.ncols() == l)
            .then(|| self.correlation[(a, b)])
            .filter(|c| c.is_finite())
    }
}

/// Residual vectors of `measurements` under `model` \[mm\] (against the observed target: the
/// recorded centring offset of a probe measurement included).
pub fn residuals(model: &Model, measurements: &[Measurement]) -> Result<Vec<Vector3<f64>>, DiscoveryError> {
    measurements
        .iter()
        .enumerate()
        .map(|(i, m)| {
            model
                .residual(m)
                .map(|r| r + m.target_offset_mm())
                .map_err(|source| DiscoveryError::Measurement { index: i, source })
        })
        .collect()
}

/// Fits `params` of `start` to `measurements` with the identification crate.
pub fn fit(
    start: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    options: &IdentifyOptions,
) -> Result<Fit, DiscoveryError> {
    let id = identify(start, measurements, params, options).map_err(|e| DiscoveryError::Fit(Box::new(e)))?;
    let rss_mm2 = id.residuals.iter().map(|r| r.norm_squared()).sum();
    Ok(Fit {
        model: id.model,
        params: params.clone(),
        residuals: id.residuals,
        rss_mm2,
        iterations: id.iterations.len().saturating_sub(1),
        converged: id.converged,
        correlation: id.correlation,
        sigma: id.sigma,
    })
}

/// Error statistics of `model` on `measurements` (mean, RMS, max of the residual norms).
pub fn error_stats(model: &Model, measurements: &[Measurement]) -> Result<ErrorStats, DiscoveryError> {
    Ok(ErrorStats::from_errors(&residuals(model, measurements)?))
}
