//! The JSON report of a fit (serde), with parameter values in **file units**.

use std::path::Path;

use serde::{Deserialize, Serialize};
use vatcal_core::ParamId;
use vatcal_core::params::ParamUnit;

use crate::{ErrorStats, Identification, IdentifyError, IterationLog, Method, Termination};

/// Unit of a parameter in the cell file and the reports: angles in degrees, lengths in mm.
pub fn file_unit_label(id: ParamId) -> &'static str {
    match id.unit() {
        ParamUnit::Rad => "deg",
        other => other.label(),
    }
}

/// Converts an internal value (or difference, or standard deviation) of `id` to file units.
pub fn to_file_units(id: ParamId, internal: f64) -> f64 {
    if id.unit() == ParamUnit::Rad { internal.to_degrees() } else { internal }
}

/// One parameter in the report. Every number is in the file unit named by `unit`
/// (degrees for angles, mm for lengths, rad/(N·m) for compliances).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterReport {
    /// stable parameter name (e.g. `theta_offset_2`)
    pub name: String,
    /// file unit of the values below
    pub unit: String,
    /// value of the starting (nominal) model
    pub nominal_file_units: f64,
    /// identified value
    pub identified_file_units: f64,
    /// identified − nominal
    pub delta_file_units: f64,
    /// standard deviation of the identified value (posterior, with priors)
    pub sigma_file_units: f64,
    /// the kind of prior the parameter had (`theta_offset`, `length`, ...; absent without
    /// priors)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_kind: Option<String>,
    /// the prior standard deviation (absent without priors; null for a free parameter)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_sigma_file_units: Option<f64>,
    /// posterior σ / prior σ: near 1, the data did not move what the prior knew; near 0, the
    /// data determine the parameter (absent without priors or for a free parameter)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posterior_over_prior: Option<f64>,
}

/// A strongly correlated parameter pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CorrelationReport {
    /// first parameter
    pub a: String,
    /// second parameter
    pub b: String,
    /// correlation coefficient
    pub correlation: f64,
}

/// The JSON report written by `vatcal identify --report`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentificationReport {
    /// report format marker
    pub format: String,
    /// estimation method
    pub method: Method,
    /// whether a convergence criterion fired
    pub converged: bool,
    /// why the iteration stopped
    pub termination: Termination,
    /// number of measurements (probe + tracker)
    pub n_measurements: usize,
    /// probe measurements
    pub n_probe: usize,
    /// tracker measurements
    pub n_tracker: usize,
    /// number of identified parameters
    pub n_parameters: usize,
    /// degrees of freedom 3n − L
    pub dof: usize,
    /// weighted residual sum of squares \[mm²\]
    pub rss_mm2: f64,
    /// estimated noise of one coordinate of a weight-1 measurement \[mm\]
    pub sigma_hat_mm: f64,
    /// condition number of the weighted, column-normalised Jacobian at the solution
    pub condition_number: f64,
    /// its singular values, descending
    pub singular_values: Vec<f64>,
    /// the parameters, in file units
    pub parameters: Vec<ParameterReport>,
    /// per-iteration log (iteration 0 = start)
    pub iterations: Vec<IterationLog>,
    /// residuals at the solution
    pub residual_stats: ErrorStats,
    /// |correlation| threshold
    pub correlation_threshold: f64,
    /// pairs above the threshold, strongest first
    pub strong_correlations: Vec<CorrelationReport>,
    /// the closed-form initialisation, when one ran ([`crate::calibrate`])
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initialisation: Option<InitialisationReport>,
    /// the cross-validated choice of the parameter set, when `default` chose one
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection: Option<SelectionReport>,
    /// the directions the data excite less than the priors do (or than the realistic widths,
    /// without priors), weakest first ([`crate::weak_directions`])
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub weak_directions: Vec<crate::WeakDirection>,
    /// the rows beyond k robust σ̂, named with file and line, and what was done about them
    /// (`vatcal identify`; issue 29)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bad_rows: Option<crate::BadRowsReport>,
    /// per-joint minimum and maximum over the rows the fit used, file units (mm / deg); the
    /// calibrated cell file's `[training_range]`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training_range: Option<vatcal_core::training_range::TrainingRange>,
    /// σ per measurement kind fitted from the residuals and the orientation weight of pose
    /// rows (`vatcal identify` with orientation rows; issue 31)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_scatter: Option<crate::FittedScatter>,
}

/// What the initialisation did ([`crate::initialise`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InitialisationReport {
    /// RMS residual norm of the nominal model \[mm\]
    pub rms_before_mm: f64,
    /// RMS residual norm after the initialisation \[mm\]
    pub rms_after_mm: f64,
    /// rounds of registration + linear solve
    pub rounds: usize,
    /// whether the base pose was registered
    pub registered: bool,
}

/// One candidate of the cross-validated choice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateReport {
    /// set name (`registration`, `joint-offsets`, `kinematic`, `kinematic+compliance`)
    pub set: String,
    /// the scale of its priors toward nominal (null: none)
    pub prior_scale: Option<f64>,
    /// its identifiable parameters on these data
    pub n_parameters: usize,
    /// RMS held-out residual norm over the folds \[mm\] (null when rejected)
    pub cv_rms_mm: Option<f64>,
    /// standard error of the fold mean squared residuals \[mm²\]
    pub cv_se_mm2: Option<f64>,
    /// RMS held-out residual norm of each fold \[mm\]
    pub fold_rms_mm: Vec<f64>,
    /// RMS residual norm of the fit on all rows \[mm\]
    pub train_rms_mm: Option<f64>,
    /// condition number of the fit on all rows
    pub condition_number: Option<f64>,
    /// why the candidate was not scored
    pub rejected: Option<String>,
    /// fold fits that reached the (scaled) iteration cap and were scored at their last iterate
    #[serde(default)]
    pub capped_fits: usize,
}

/// The cross-validated choice ([`crate::cross_validate_sets`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SelectionReport {
    /// folds and posture groups
    pub folds: usize,
    /// posture groups dealt into the folds
    pub groups: usize,
    /// shuffle seed
    pub seed: u64,
    /// repetitions of the K-fold split (1: leave-one-posture-out or a single split)
    #[serde(default = "one")]
    pub repeats: usize,
    /// every candidate, smallest first
    pub candidates: Vec<CandidateReport>,
    /// the chosen set
    pub chosen: String,
    /// why it won
    pub reason: String,
}

fn one() -> usize {
    1
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

impl SelectionReport {
    /// The report of a selection.
    pub fn from_selection(sel: &crate::CvSelection) -> Self {
        Self {
            folds: sel.folds,
            groups: sel.groups,
            seed: sel.seed,
            repeats: sel.repeats,
            candidates: sel
                .candidates
                .iter()
                .map(|c| CandidateReport {
                    set: c.set.name().to_string(),
                    prior_scale: c.prior_scale,
                    n_parameters: c.params.len(),
                    cv_rms_mm: finite(c.cv_rms_mm),
                    cv_se_mm2: finite(c.cv_se_mm2),
                    fold_rms_mm: c.fold_rms_mm.clone(),
                    train_rms_mm: finite(c.train_rms_mm),
                    condition_number: finite(c.condition_number),
                    rejected: c.rejected.clone(),
                    capped_fits: c.capped_fits,
                })
                .collect(),
            chosen: sel.chosen().label(),
            reason: sel.reason.clone(),
        }
    }
}

/// Value of [`IdentificationReport::format`].
pub const REPORT_FORMAT: &str = "vatcal-identification-report/1";

impl IdentificationReport {
    /// Builds the report of a fit.
    pub fn from_identification(id: &Identification) -> Self {
        let parameters = id
            .params
            .iter()
            .enumerate()
            .map(|(k, p)| ParameterReport {
                name: p.name(),
                unit: file_unit_label(*p).to_string(),
                nominal_file_units: to_file_units(*p, id.start_values[k]),
                identified_file_units: to_file_units(*p, id.values[k]),
                delta_file_units: to_file_units(*p, id.values[k] - id.start_values[k]),
                sigma_file_units: to_file_units(*p, id.sigma[k]),
                prior_kind: None,
                prior_sigma_file_units: None,
                posterior_over_prior: None,
            })
            .collect();
        Self {
            format: REPORT_FORMAT.to_string(),
            method: id.method,
            converged: id.converged,
            termination: id.termination,
            n_measurements: id.n_probe + id.n_tracker,
            n_probe: id.n_probe,
            n_tracker: id.n_tracker,
            n_parameters: id.params.len(),
            dof: id.dof,
            rss_mm2: id.rss,
            sigma_hat_mm: id.sigma_hat_mm,
            condition_number: id.condition_number,
            singular_values: id.singular_values.clone(),
            parameters,
            iterations: id.iterations.clone(),
            residual_stats: id.residual_stats.clone(),
            correlation_threshold: id.correlation_threshold,
            strong_correlations: id
                .strong_correlations
                .iter()
                .map(|(a, b, c)| CorrelationReport { a: a.name(), b: b.name(), correlation: *c })
                .collect(),
            initialisation: None,
            selection: None,
            weak_directions: Vec::new(),
            bad_rows: None,
            training_range: None,
            fitted_scatter: None,
        }
    }

    /// The report of a [`crate::calibrate`] run: the fit, its initialisation and the
    /// cross-validated choice.
    pub fn from_calibration(cal: &crate::Calibration) -> Self {
        let mut r = Self::from_identification(&cal.fit);
        r.initialisation = cal.init.as_ref().map(|i| InitialisationReport {
            rms_before_mm: i.rms_before_mm,
            rms_after_mm: i.rms_after_mm,
            rounds: i.rounds,
            registered: i.registered,
        });
        r.selection = cal.selection.as_ref().map(SelectionReport::from_selection);
        if cal.prior_sigmas.len() == cal.fit.params.len() {
            for ((entry, p), (prior, post)) in r
                .parameters
                .iter_mut()
                .zip(cal.fit.params.iter())
                .zip(cal.prior_sigmas.iter().zip(&cal.fit.sigma))
            {
                entry.prior_kind = Some(crate::PriorKind::of(*p, &cal.fit.model).name().to_string());
                entry.prior_sigma_file_units = prior.is_finite().then(|| to_file_units(*p, *prior));
                entry.posterior_over_prior = prior.is_finite().then(|| post / prior);
            }
        }
        r.weak_directions = cal.weak_directions.clone();
        r
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> Result<String, IdentifyError> {
        serde_json::to_string_pretty(self)
            .map_err(|e| IdentifyError::Numerical(format!("cannot serialise the report: {e}")))
    }

    /// Parses a report.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, IdentifyError> {
        serde_json::from_str(text).map_err(|e| IdentifyError::File { path: origin.into(), source: e.into() })
    }

    /// Writes the report as JSON.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), IdentifyError> {
        let path = path.as_ref();
        std::fs::write(path, self.to_json()?)
            .map_err(|e| IdentifyError::File { path: path.to_path_buf(), source: e.into() })
    }

    /// Reads a report written by [`Self::save`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self, IdentifyError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| IdentifyError::File { path: path.to_path_buf(), source: e.into() })?;
        Self::from_json(&text, &path.display().to_string())
    }

    /// The entry of parameter `name`.
    pub fn parameter(&self, name: &str) -> Option<&ParameterReport> {
        self.parameters.iter().find(|p| p.name == name)
    }
}
