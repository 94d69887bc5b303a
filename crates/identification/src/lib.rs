#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Least-squares identification of the cell's parameters from probe and/or tracker
//! measurements, the statistics of the result, and validation on independent data
//! (background.md §6).
//!
//! * [`identify`] — Levenberg–Marquardt (default) or Gauss–Newton on the **stacked** Jacobian
//!   of all measurements, column-scaled, every step solved by faer QR of the (augmented)
//!   scaled Jacobian — never by the normal equations. Gravity torques are recomputed from the
//!   current estimate at every iteration. Optional weights per measurement kind and Gaussian
//!   priors toward the starting values (MAP / ridge). Rank-deficient data is refused before
//!   solving, naming the unidentifiable parameters (vatcal-observability). The paper's
//!   Table 7 read literally is available as [`Method::PaperLiteral`], for comparison only.
//! * [`Identification`] — calibrated model, values, σ, covariance, correlations, iteration
//!   log, residual statistics, σ̂, condition number, predicted TCP uncertainty at any pose.
//! * [`initialise`] — closed-form start for a nominal model whose world frame, measured TCP or
//!   fixed points are unknown (Kabsch registration + linear least squares);
//!   [`cross_validate_sets`] — the model size chosen by K-fold cross-validation over posture
//!   groups (the default on other chains: a MAP fit of the richest set with realistic priors
//!   [`PriorWidths`], the prior scale by the lowest CV score); [`weak_directions`] — the
//!   combinations the data excite less than the priors; [`calibrate`] — initialise, choose, fit in one call (what
//!   `vatcal identify` runs); [`prepare_calibration`] — the same without the final fit (the
//!   start and the set `vatcal discover` begins from);
//! * [`flag_outliers`], [`irls`], [`calibrate_robust`], [`calibrate_dropping_outliers`] — bad
//!   rows: named beyond k robust σ̂, down-weighted (Huber / Cauchy IRLS through
//!   [`IdentifyOptions::row_weights`]) or dropped and the calibration redone.
//! * [`IdentificationReport`] — the JSON report (file units).
//! * [`KindSigmas`] — σ of probe and tracker residuals estimated separately (inverse-variance
//!   weights); [`fit_with_fitted_scatter`] refits pose rows with the orientation weight their
//!   [`FittedScatter`] calls for; [`CmmUncertainty`] — systematic CMM errors of the TCP and calibration-position
//!   coordinates propagated into the predicted TCP uncertainty. The residual of a probe
//!   measurement is taken against `position + recorded centring offset` when the offset is known.
//! * [`validate`], [`compare_models`] — position errors of one or two models on a validation
//!   set; [`ErrorStats`] — mean / RMS / median / 95th percentile / max / per-axis statistics,
//!   shared by every crate that reports position errors.
//!
//! Units: internal (mm, rad, rad/(N·m)) in every Rust API; the JSON report and the cell file
//! use degrees for angles.

mod cv;
mod dense;
mod error;
mod error_stats;
mod fit_statistics;
mod fixed_points;
mod init;
mod literal;
mod method;
mod options;
mod planes;
mod prediction;
mod priors;
mod problem;
mod report;
mod result;
mod robust;
mod scatter;
mod solver;
mod uncertainty;
mod validation;
mod weak;

use vatcal_core::{Measurement, ParamId, ParamSet, Target};
use vatcal_kinematics::Model;
use vatcal_observability::ObservabilityError;

pub use cv::{
    CV_MIN_ITERATIONS, Calibration, CalibrationStart, CandidateScore, CvOptions, CvSelection, calibrate,
    cross_validate_sets, cv_iteration_cap, posture_folds, prepare_calibration,
};
pub use error::{FailureReport, IdentifyError};
pub use error_stats::ErrorStats;
pub use fixed_points::{DistanceCheck, FixedPointEvaluation, FixedPointStats, evaluate_fixed_points};
pub use init::{InitOptions, Initialisation, initialise};
pub use literal::PAPER_ERROR_CHANGE_MM;
pub use method::Method;
pub use options::{IdentifyOptions, KindWeights, Scaling};
pub use planes::{estimate_planes, plane_of_rows, plane_through};
pub use priors::{COMPLIANCE_TORQUE_FLOOR, PriorKind, PriorOverride, PriorSpec, PriorWidths};
pub use problem::residual_vector;
pub use report::{
    CandidateReport, CorrelationReport, IdentificationReport, InitialisationReport, ParameterReport,
    REPORT_FORMAT, SelectionReport, file_unit_label, to_file_units,
};
pub use result::{Identification, IterationLog, Termination};
pub use robust::{
    BadRowReport, BadRowsReport, CAUCHY_TUNING, CHI3_MEDIAN, DEFAULT_OUTLIER_K, DroppedRow, FlaggedRow,
    HUBER_TUNING, MAX_DROP_ROUNDS, OutlierDrop, OutlierScan, RobustCalibration, RobustFit, RobustLoss,
    RobustOptions, RobustReport, SIGMA_ESTIMATOR, calibrate_dropping_outliers, calibrate_robust,
    flag_outliers, irls, robust_sigma_mm,
};
pub use scatter::{FittedScatter, SCATTER_MAX_FITS, SCATTER_SETTLED, fit_with_fitted_scatter};
pub use uncertainty::{CmmUncertainty, KindSigmas};
pub use validation::{ModelComparison, ValidationReport, compare_models, validate};
pub use weak::{WeakDirection, weak_directions};

use problem::Problem;

/// Identifies `params` from `measurements`, starting from `start`.
///
/// Steps: check the inputs and options; refuse data that cannot identify `params`
/// (`vatcal_observability::check_identifiable`, unless `options.check_identifiability` is off
/// or finite priors cover every unidentifiable parameter); iterate with `options.method`;
/// compute the statistics at the solution.
///
/// # Errors
/// * [`IdentifyError::NoMeasurements`], [`IdentifyError::NoParameters`],
///   [`IdentifyError::TooFewMeasurements`] (3n ≤ L), [`IdentifyError::InvalidOptions`];
/// * [`IdentifyError::Model`] — a parameter that is not in the model (e.g. an effect that is
///   not switched on); [`IdentifyError::Measurement`] — an unknown TCP / position id;
/// * [`IdentifyError::Unidentifiable`] — rank-deficient data, naming the parameters;
/// * [`IdentifyError::IllConditioned`] — the condition number at the solution exceeds
///   `options.max_condition_number` (without priors), naming the correlated parameters;
/// * [`IdentifyError::NotConverged`] — divergence, non-finite values, a stall, or the
///   iteration cap (unless `accept_iteration_cap`), with the full iteration log;
/// * [`IdentifyError::Numerical`] — a singular information matrix at the solution.
///
/// # Examples
/// The 34 parameters from 40 simulated probe measurements (2 µm noise) of a hidden true cell;
/// the calibrated model predicts 150 validation poses of the truth at the noise floor:
/// ```
/// use vatcal_core::{CellFile, ParamSet};
/// use vatcal_identification::{IdentifyOptions, identify, validate};
/// use vatcal_kinematics::Model;
/// use vatcal_sim::truth::{ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses};
/// use vatcal_sim::truth::{synthetic_probe_measurements, synthetic_tracker_measurements};
///
/// let nominal = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let truth = perturbed_truth(&nominal, 2, &ErrorBudget::realistic());
/// let starts = probe_start_poses(&nominal, 40, 102);
/// let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.002 }, 202);
/// let fit = identify(&nominal, &probe, &ParamSet::paper34(), &IdentifyOptions::default())?;
/// assert!(fit.converged);
/// let poses = synthetic_tracker_measurements(&truth, 150, 0.0, 302);
/// let before = validate(&nominal, &poses)?.stats.mean;
/// let after = validate(&fit.model, &poses)?.stats.mean;
/// assert!(before > 0.5 && after < 0.01, "{before} mm -> {after} mm");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn identify(
    start: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    options: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let mut fit = identify_once(start, measurements, params, options)?;
    let has_priors = options.priors.as_ref().is_some_and(|p| p.iter().any(|s| s.is_finite()));
    let reweight = (options.distance_sigma_from_fit
        && !(options.point_distances.is_empty() && options.plane_distances.is_empty()))
        || (options.prior_sigma_from_fit && has_priors);
    if !reweight {
        return Ok(fit);
    }
    // The known distances (and priors) are weighed against the data's own scatter
    // (`IdentifyOptions::distance_sigma_from_fit`, `prior_sigma_from_fit`): refit from `start`
    // with the data σ̂ of the previous fit until it settles.
    let mut data_sigma_mm = options.measurement_sigma_mm;
    for _ in 0..DISTANCE_REWEIGHT_ROUNDS {
        let estimated =
            data_sigma_hat_mm(&fit, measurements, &options.weights, options.row_weights.as_deref());
        if !(estimated.is_finite() && estimated > 0.0)
            || (estimated / data_sigma_mm - 1.0).abs() <= DISTANCE_REWEIGHT_TOLERANCE
        {
            break;
        }
        data_sigma_mm = estimated;
        let reweighted = IdentifyOptions { distance_data_sigma_mm: Some(data_sigma_mm), ..options.clone() };
        fit = identify_once(start, measurements, params, &reweighted)?;
    }
    Ok(fit)
}

/// Refits of [`identify`] that re-weigh the known distances by the data's σ̂ (at most).
const DISTANCE_REWEIGHT_ROUNDS: usize = 5;
/// The re-weighting stops when σ̂ changes by less than this fraction.
const DISTANCE_REWEIGHT_TOLERANCE: f64 = 0.05;

/// σ̂ of one coordinate of a weight-1 measurement row from a fit's data residuals alone:
/// `√(Σ_k w_k ‖e_k‖² / (3n − L))` (the distance and prior rows left out) \[mm\]; with row
/// weights, the robust σ̂ of the rows ([`robust_sigma_mm`]).
fn data_sigma_hat_mm(
    fit: &Identification,
    measurements: &[Measurement],
    weights: &KindWeights,
    row_weights: Option<&[f64]>,
) -> f64 {
    if row_weights.is_some() {
        // a row-weighted (robust) fit: a down-weighted bad row still dominates Σ w‖e‖² (Huber
        // keeps its pull linear), so the data's scale is the robust one of the rows
        return robust_sigma_mm(&fit.residuals, measurements, weights);
    }
    let rss: f64 = fit
        .residuals
        .iter()
        .zip(measurements)
        .enumerate()
        .map(|(k, (e, m))| {
            let w = weights.of(&m.target);
            w * row_weights.map_or(1.0, |r| r[k]) * e.norm_squared()
        })
        .sum();
    let dof = vatcal_core::informative_rows(measurements).saturating_sub(fit.params.len()).max(1);
    (rss / dof as f64).sqrt()
}

/// One fit with the weights of `options` as given (no re-weighting of the distances).
fn identify_once(
    start: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    options: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    if measurements.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    if params.is_empty() {
        return Err(IdentifyError::NoParameters);
    }
    if let Some(dup) = first_duplicate(params) {
        return Err(IdentifyError::InvalidOptions(format!("parameter `{dup}` is listed twice")));
    }
    options.check(params)?;
    if let Some(w) = &options.row_weights
        && w.len() != measurements.len()
    {
        return Err(IdentifyError::InvalidOptions(format!(
            "row_weights: {} weights for {} measurements",
            w.len(),
            measurements.len()
        )));
    }
    let start_values = start.params(params)?;
    let equations = vatcal_core::informative_rows(measurements);
    if equations <= params.len() {
        return Err(IdentifyError::TooFewMeasurements { equations, params: params.len() });
    }
    let problem = Problem::new(measurements, params, start_values.clone(), options);
    let full_check = || check_rank(start, measurements, params, options);
    // Fast path: without prior rows the solver's first QR factor has the singular values of
    // the stacked Jacobian, so the (cheap) rank test runs on it and the full analysis, which
    // names the parameters, only when the rank is deficient.
    let fast_check =
        options.check_identifiability && problem.priors.is_empty() && options.method != Method::PaperLiteral;
    if options.check_identifiability && !fast_check {
        full_check()?;
    }
    let outcome = match options.method {
        Method::LevenbergMarquardt | Method::GaussNewton => {
            let check: &dyn Fn() -> Result<(), IdentifyError> = &full_check;
            solver::least_squares(&problem, start, options, fast_check.then_some(check))?
        }
        Method::PaperLiteral => literal::paper_literal(&problem, start, options)?,
    };
    let converged = outcome.termination.is_converged();
    let accepted_cap = outcome.termination == Termination::MaxIterations && options.accept_iteration_cap;
    if !converged && !accepted_cap {
        return Err(IdentifyError::NotConverged(Box::new(FailureReport {
            method: options.method,
            termination: outcome.termination,
            iterations: outcome.log,
            params: params.clone(),
            start_values,
            last_values: outcome.values,
        })));
    }
    let lin = match outcome.linearisation {
        Some(lin) => lin,
        None => fit_statistics::Linearisation::evaluate(&problem, &outcome.model, &outcome.values)?,
    };
    let s = fit_statistics::statistics(&problem, lin, options.correlation_threshold)?;
    let n_probe = measurements.iter().filter(|m| matches!(m.target, Target::Probe { .. })).count();
    let fit = Identification {
        method: options.method,
        model: outcome.model,
        params: params.clone(),
        start_values,
        values: outcome.values,
        sigma: s.sigma,
        covariance: s.covariance,
        correlation: s.correlation,
        strong_correlations: s.strong_correlations,
        correlation_threshold: options.correlation_threshold,
        iterations: outcome.log,
        residuals: s.residuals,
        residual_stats: s.residual_stats,
        rss: s.rss,
        sigma_hat_mm: s.sigma_hat_mm,
        dof: s.dof,
        condition_number: s.condition_number,
        singular_values: s.singular_values,
        converged,
        termination: outcome.termination,
        n_probe,
        n_tracker: measurements.len() - n_probe,
    };
    if problem.priors.is_empty()
        && (fit.condition_number.is_nan() || fit.condition_number > options.max_condition_number)
    {
        return Err(IdentifyError::IllConditioned(Box::new(fit)));
    }
    Ok(fit)
}

fn first_duplicate(params: &ParamSet) -> Option<ParamId> {
    params.iter().enumerate().find(|(k, p)| params.0[..*k].contains(p)).map(|(_, p)| *p)
}

/// Refuses rank-deficient data unless finite priors cover every unidentifiable parameter.
fn check_rank(
    start: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    options: &IdentifyOptions,
) -> Result<(), IdentifyError> {
    let design = vatcal_observability::sets::DataDesign {
        distances: options.point_distances.clone(),
        plane_distances: options.plane_distances.clone(),
        ..Default::default()
    };
    let checked =
        vatcal_observability::sets::analyze_design(start, measurements, &design, params).and_then(|r| {
            if r.is_full_rank() {
                Ok(r)
            } else {
                Err(vatcal_observability::identifiability::rank_deficient_error_for(&r, start.joint_kinds()))
            }
        });
    match checked {
        Ok(_) => Ok(()),
        Err(ObservabilityError::RankDeficient { unidentifiable, .. })
            if priors_cover(params, options.priors.as_deref(), &unidentifiable) =>
        {
            Ok(())
        }
        Err(e) => Err(e.into()),
    }
}

fn priors_cover(params: &ParamSet, priors: Option<&[f64]>, unidentifiable: &[ParamId]) -> bool {
    let Some(priors) = priors else { return false };
    unidentifiable.iter().all(|p| params.index_of(*p).is_some_and(|k| priors[k].is_finite()))
}
