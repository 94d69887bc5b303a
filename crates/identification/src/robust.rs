//! Bad rows: naming them, down-weighting them, dropping them (issue 29, item 5).
//!
//! One real posture 55–75 mm off (a motion-capture glitch) doubles a least-squares fit's error
//! on new postures. After a fit:
//!
//! * **Scale.** `σ̂_r = median_k(√w_k ‖e_k‖) / 1.5382` ([`robust_sigma_mm`]): the median
//!   residual norm of the rows (kind-weighted, `w_k` the kind weight), scaled to the σ of one
//!   coordinate of a 3-D Gaussian — the norm of a 3-D Gaussian residual of σ per axis is σ
//!   times a χ variable with 3 degrees of freedom, whose median is 1.5382
//!   ([`CHI3_MEDIAN`]). A median ignores up to half of the rows being wrong, where the
//!   least-squares σ̂ (`√(RSS/dof)`) is inflated by one bad row.
//! * **Flagged rows** ([`flag_outliers`]): residual norm beyond `k · σ̂_r` (default k = 4,
//!   [`DEFAULT_OUTLIER_K`]). A Gaussian row is beyond 4 σ with probability 0.0011
//!   (`P(χ²₃ > 16)`): about one false flag per 900 clean rows.
//! * **Down-weighting** ([`irls`], [`calibrate_robust`]): iteratively reweighted least
//!   squares. Each round computes `u_k = √w_k ‖e_k‖ / (√3 σ̂_r)` — the row's RMS coordinate
//!   residual in units of σ̂_r (`E u² = 1` for a clean row) — from the previous fit and refits
//!   from the same start with the row weights `ψ(u_k)/u_k` of an M-estimator
//!   ([`IdentifyOptions::row_weights`]): Huber `min(1, c/u)` with c = 1.345, Cauchy
//!   `1 / (1 + (u/c)²)` with c = 2.385 ([`RobustLoss`]; both constants in units of σ̂_r,
//!   the classical 95 %-efficiency tunings for one Gaussian coordinate; measured against the
//!   norm itself, `u = ‖e‖/σ̂_r`, clean rows sit near c and the Cauchy fit lost 23 % on
//!   held-out postures against 3 % with the RMS coordinate, tests below). Huber bounds the pull
//!   of a bad row (it counts as a row c σ̂ off); Cauchy's weights fall with the square of the
//!   distance, so a row thousands of σ off has no pull at all. The rounds stop when no weight
//!   changes by more than 1e-3 (at most 30 rounds).
//! * **Dropping** ([`calibrate_dropping_outliers`]): the rows beyond `K · σ̂_r` are removed
//!   and the whole calibration (initialisation, the parameter set's choice, the fit) is redone
//!   on the rows kept, until no kept row is beyond (at most [`MAX_DROP_ROUNDS`] rounds).

use std::fmt;
use std::str::FromStr;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::sets::DataDesign;

use crate::{
    Calibration, CalibrationStart, CvOptions, Identification, IdentifyError, IdentifyOptions, KindWeights,
    calibrate, identify, prepare_calibration,
};

/// Median of a χ variable with 3 degrees of freedom (`√(median of χ²₃)` = √2.36597): the median
/// norm of a 3-D residual whose coordinates are Gaussian with σ = 1.
pub const CHI3_MEDIAN: f64 = 1.538_172_254_455_052;
/// Default k of [`flag_outliers`]: rows beyond 4 σ̂_r are named.
pub const DEFAULT_OUTLIER_K: f64 = 4.0;
/// Huber's tuning constant, in units of σ̂_r.
pub const HUBER_TUNING: f64 = 1.345;
/// Cauchy's tuning constant, in units of σ̂_r.
pub const CAUCHY_TUNING: f64 = 2.385;
/// Rounds of removal and refit of [`calibrate_dropping_outliers`] (at most).
pub const MAX_DROP_ROUNDS: usize = 5;
/// The robust scale in words, for reports.
pub const SIGMA_ESTIMATOR: &str =
    "median residual norm / 1.5382 (median of chi with 3 dof; 0.6745 for a plane contact's one row)";

/// The M-estimator of a robust fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RobustLoss {
    /// Huber: quadratic within c σ̂, linear beyond; weight `min(1, c/u)`, c = 1.345.
    Huber,
    /// Cauchy (Lorentzian): weight `1 / (1 + (u/c)²)`, c = 2.385.
    Cauchy,
}

impl RobustLoss {
    /// `huber` or `cauchy`.
    pub fn name(self) -> &'static str {
        match self {
            RobustLoss::Huber => "huber",
            RobustLoss::Cauchy => "cauchy",
        }
    }

    /// The default tuning constant c in units of σ̂_r ([`HUBER_TUNING`], [`CAUCHY_TUNING`]).
    pub fn default_tuning(self) -> f64 {
        match self {
            RobustLoss::Huber => HUBER_TUNING,
            RobustLoss::Cauchy => CAUCHY_TUNING,
        }
    }

    /// The IRLS weight `ψ(u)/u` of a row whose RMS coordinate residual is `u` robust σ̂, with
    /// tuning constant `c`.
    ///
    /// # Examples
    /// ```
    /// use vatcal_identification::RobustLoss;
    ///
    /// assert_eq!(RobustLoss::Huber.weight(1.0, 1.345), 1.0);
    /// assert!((RobustLoss::Huber.weight(13.45, 1.345) - 0.1).abs() < 1e-12);
    /// assert!((RobustLoss::Cauchy.weight(2.385, 2.385) - 0.5).abs() < 1e-12);
    /// ```
    pub fn weight(self, u: f64, c: f64) -> f64 {
        let u = u.abs();
        match self {
            RobustLoss::Huber => {
                if u <= c {
                    1.0
                } else {
                    c / u
                }
            }
            RobustLoss::Cauchy => 1.0 / (1.0 + (u / c) * (u / c)),
        }
    }
}

impl fmt::Display for RobustLoss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for RobustLoss {
    type Err = String;

    /// Parses `huber` or `cauchy`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "huber" => Ok(RobustLoss::Huber),
            "cauchy" => Ok(RobustLoss::Cauchy),
            other => Err(format!("unknown robust loss `{other}` (expected huber or cauchy)")),
        }
    }
}

/// `√w_kind` of a row.
fn kind_weight(m: &Measurement, weights: &KindWeights) -> f64 {
    weights.of(&m.target)
}

/// The kind-weighted residual norms `√w_k ‖e_k‖` \[mm\].
fn weighted_norms(residuals: &[Vector3<f64>], rows: &[Measurement], weights: &KindWeights) -> Vec<f64> {
    residuals.iter().zip(rows).map(|(e, m)| kind_weight(m, weights).sqrt() * e.norm()).collect()
}

/// Median of a χ variable with `dof` degrees of freedom (1, 2 or 3: the informative rows of a
/// measurement, `Target::residual_rows`).
fn chi_median(dof: usize) -> f64 {
    match dof {
        1 => 0.674_489_750_196_081_7,
        2 => 1.177_410_022_515_474_7,
        _ => CHI3_MEDIAN,
    }
}

/// σ̂_r from the weighted norms: the median over rows of `norm_k / median(χ_{d_k})`, each row
/// scaled by the median of its own χ (a plane contact without the tool axis has one
/// informative row, a point three).
fn sigma_of_norms(norms: &[f64], rows: &[Measurement]) -> f64 {
    let scaled: Vec<f64> =
        norms.iter().zip(rows).map(|(n, m)| n / chi_median(m.target.residual_rows())).collect();
    median(&scaled)
}

fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

/// The robust σ of one coordinate of a weight-1 row: the median of the kind-weighted residual
/// norms `√w_k ‖e_k‖` over [`CHI3_MEDIAN`] \[mm\] (module docs; a plane contact without the
/// tool axis, one informative row, over the median of χ₁). `NaN` without rows.
pub fn robust_sigma_mm(residuals: &[Vector3<f64>], rows: &[Measurement], weights: &KindWeights) -> f64 {
    sigma_of_norms(&weighted_norms(residuals, rows, weights), rows)
}

/// A row whose residual is beyond `k · σ̂_r`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlaggedRow {
    /// 0-based index of the row in the rows given
    pub index: usize,
    /// its residual norm `‖e‖` \[mm\] (unweighted)
    pub residual_mm: f64,
    /// its kind-weighted residual norm in units of σ̂_r
    pub sigmas: f64,
}

/// The rows of a fit beyond `k · σ̂_r` ([`flag_outliers`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutlierScan {
    /// σ̂_r, the robust σ of one coordinate \[mm\] ([`robust_sigma_mm`])
    pub sigma_mm: f64,
    /// the k of the threshold
    pub k: f64,
    /// the rows beyond, largest first
    pub rows: Vec<FlaggedRow>,
}

/// The rows whose kind-weighted residual norm exceeds `k · σ̂_r`, largest first (module docs).
/// `residuals[i]` belongs to `rows[i]` (e.g. [`Identification::residuals`]).
///
/// # Errors
/// [`IdentifyError::InvalidOptions`] for `k` not finite and > 0 or unequal lengths.
///
/// # Examples
/// Eleven rows at the noise level and one 60 mm off: only that one is named.
/// ```
/// use nalgebra::Vector3;
/// use vatcal_core::{JointVector, Measurement};
/// use vatcal_identification::{KindWeights, flag_outliers};
///
/// let rows: Vec<Measurement> =
///     (0..12).map(|_| Measurement::tracker(1, JointVector::zeros(6), Vector3::zeros())).collect();
/// let mut residuals: Vec<Vector3<f64>> =
///     (0..12).map(|k| Vector3::new(0.01 * ((k % 3) as f64 - 1.0), 0.012, -0.008)).collect();
/// residuals[7] = Vector3::new(60.0, 0.0, 0.0);
/// let scan = flag_outliers(&residuals, &rows, &KindWeights::default(), 4.0)?;
/// assert_eq!(scan.rows.len(), 1);
/// assert_eq!(scan.rows[0].index, 7);
/// # Ok::<(), vatcal_identification::IdentifyError>(())
/// ```
pub fn flag_outliers(
    residuals: &[Vector3<f64>],
    rows: &[Measurement],
    weights: &KindWeights,
    k: f64,
) -> Result<OutlierScan, IdentifyError> {
    if !(k.is_finite() && k > 0.0) {
        return Err(IdentifyError::InvalidOptions(format!("outlier k must be finite and > 0, got {k}")));
    }
    if residuals.len() != rows.len() {
        return Err(IdentifyError::InvalidOptions(format!(
            "{} residuals for {} rows",
            residuals.len(),
            rows.len()
        )));
    }
    let norms = weighted_norms(residuals, rows, weights);
    let sigma_mm = sigma_of_norms(&norms, rows);
    let mut flagged: Vec<FlaggedRow> = if sigma_mm > 0.0 {
        norms
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > k * sigma_mm)
            .map(|(index, n)| FlaggedRow {
                index,
                residual_mm: residuals[index].norm(),
                sigmas: n / sigma_mm,
            })
            .collect()
    } else {
        Vec::new()
    };
    flagged.sort_by(|a, b| b.sigmas.total_cmp(&a.sigmas));
    Ok(OutlierScan { sigma_mm, k, rows: flagged })
}

/// Options of the robust fit ([`irls`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobustOptions {
    /// the M-estimator
    pub loss: RobustLoss,
    /// its tuning constant c in units of σ̂_r (default: [`RobustLoss::default_tuning`])
    pub tuning: f64,
    /// reweighting rounds, at most (default 30)
    pub max_rounds: usize,
    /// stop when no row weight changes by more than this (default 1e-3)
    pub weight_tolerance: f64,
}

impl RobustOptions {
    /// The defaults of `loss`.
    pub fn new(loss: RobustLoss) -> Self {
        Self { loss, tuning: loss.default_tuning(), max_rounds: 30, weight_tolerance: 1e-3 }
    }

    fn check(&self) -> Result<(), IdentifyError> {
        if !(self.tuning.is_finite() && self.tuning > 0.0) {
            return Err(IdentifyError::InvalidOptions(format!(
                "robust tuning constant must be finite and > 0, got {}",
                self.tuning
            )));
        }
        if self.max_rounds == 0 || !(self.weight_tolerance.is_finite() && self.weight_tolerance > 0.0) {
            return Err(IdentifyError::InvalidOptions(
                "robust fit: max_rounds must be >= 1 and weight_tolerance finite and > 0".into(),
            ));
        }
        Ok(())
    }
}

/// The outcome of [`irls`].
#[derive(Debug, Clone)]
pub struct RobustFit {
    /// the final, row-weighted fit
    pub fit: Identification,
    /// the row weights of that fit (same order as the rows; 1 = full weight)
    pub weights: Vec<f64>,
    /// σ̂_r of the residuals the final weights were computed from \[mm\]
    pub sigma_mm: f64,
    /// reweighted fits that were run
    pub rounds: usize,
    /// whether the weights settled (no change above the tolerance) within `max_rounds`
    pub converged: bool,
    /// the options used
    pub options: RobustOptions,
    /// RMS residual norm of the unweighted (least-squares) fit it started from \[mm\]
    pub unweighted_rms_mm: f64,
}

/// Iteratively reweighted least squares (module docs): the unweighted fit of `params` from
/// `start` (or `first`, when the caller has it already: it must be the fit of exactly these
/// arguments), then rounds of weights from its residuals and a refit from `start` with them
/// ([`IdentifyOptions::row_weights`], multiplied into the kind weights of `fit_options`).
///
/// # Errors
/// Invalid robust options; the errors of [`identify`] in any round.
pub fn irls(
    start: &Model,
    rows: &[Measurement],
    params: &ParamSet,
    fit_options: &IdentifyOptions,
    robust: &RobustOptions,
    first: Option<Identification>,
) -> Result<RobustFit, IdentifyError> {
    robust.check()?;
    let base = IdentifyOptions { row_weights: None, ..fit_options.clone() };
    let mut fit = match first {
        Some(f) => f,
        None => identify(start, rows, params, &base)?,
    };
    let unweighted_rms_mm = fit.residual_stats.rms;
    let mut weights = vec![1.0; rows.len()];
    let (mut rounds, mut converged, mut sigma_mm) = (0, false, f64::NAN);
    while rounds < robust.max_rounds {
        sigma_mm = robust_sigma_mm(&fit.residuals, rows, &fit_options.weights);
        if !(sigma_mm.is_finite() && sigma_mm > 0.0) {
            // an exact fit: nothing to weigh
            converged = true;
            break;
        }
        // u: the row's RMS coordinate residual in units of σ̂_r (module docs)
        let scale = sigma_mm * 3f64.sqrt();
        let norms = weighted_norms(&fit.residuals, rows, &fit_options.weights);
        let next: Vec<f64> = norms.iter().map(|n| robust.loss.weight(n / scale, robust.tuning)).collect();
        let change = next.iter().zip(&weights).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        if rounds > 0 && change <= robust.weight_tolerance {
            converged = true;
            break;
        }
        weights = next;
        fit = identify(
            start,
            rows,
            params,
            &IdentifyOptions { row_weights: Some(weights.clone()), ..base.clone() },
        )?;
        rounds += 1;
    }
    Ok(RobustFit { fit, weights, sigma_mm, rounds, converged, options: *robust, unweighted_rms_mm })
}

/// A robust calibration ([`calibrate_robust`]).
#[derive(Debug, Clone)]
pub struct RobustCalibration {
    /// the calibration as [`calibrate`] returns it, its `fit` the reweighted one (its weak
    /// directions judged at the robust σ̂_r)
    pub calibration: Calibration,
    /// the start, the parameter set (named, or chosen by cross-validation — again with the
    /// robust row weights after a first robust fit) and the options of the fit
    /// ([`prepare_calibration`])
    pub start: CalibrationStart,
    /// the reweighted fit (its `fit` is `calibration.fit`)
    pub robust: RobustFit,
}

/// [`prepare_calibration`] (initialisation; the parameter set, chosen by cross-validation for
/// `default` on a chain other than the canonical cell), then the robust fit [`irls`] from its
/// start with its options. A cross-validated choice is made again with the robust fit's row
/// weights (the fold fits and the scores weigh the rows as the fit does), and the robust fit
/// is redone when the choice changed.
///
/// # Errors
/// The errors of [`prepare_calibration`] and [`irls`].
pub fn calibrate_robust(
    nominal: &Model,
    rows: &[Measurement],
    spec: &str,
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
    robust: &RobustOptions,
) -> Result<RobustCalibration, IdentifyError> {
    robust.check()?;
    let options = IdentifyOptions { row_weights: None, ..options.clone() };
    let first_start = prepare_calibration(nominal, rows, spec, design, &options, cv)?;
    let first = irls(&first_start.start, rows, &first_start.params, &first_start.fit_options, robust, None)?;
    let (start, fit) = match &first_start.selection {
        // the set / prior scale was chosen by cross-validation on the unweighted rows: choose
        // again with the robust weights (scored and fitted with them), so that a bad row does
        // not decide the model; refit only when the choice changed
        Some(unweighted) => {
            let weighted = IdentifyOptions { row_weights: Some(first.weights.clone()), ..options.clone() };
            let mut again = prepare_calibration(nominal, rows, spec, design, &weighted, cv)?;
            again.fit_options.row_weights = None;
            let same =
                again.selection.as_ref().map(|s| s.chosen().label()) == Some(unweighted.chosen().label());
            if same {
                let kept = CalibrationStart { selection: again.selection, ..first_start };
                (kept, first)
            } else {
                let fit = irls(&again.start, rows, &again.params, &again.fit_options, robust, None)?;
                (again, fit)
            }
        }
        None => (first_start, first),
    };
    let calibration = start.finish(fit.fit.clone(), rows, cv, fit.sigma_mm)?;
    Ok(RobustCalibration { calibration, start, robust: fit })
}

/// A row removed by [`calibrate_dropping_outliers`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DroppedRow {
    /// 0-based index in the rows given
    pub index: usize,
    /// its residual norm in the fit it was dropped from \[mm\]
    pub residual_mm: f64,
    /// that residual in units of that fit's σ̂_r
    pub sigmas: f64,
    /// the round that dropped it (1 = the fit on all rows)
    pub round: usize,
}

/// The outcome of [`calibrate_dropping_outliers`].
#[derive(Debug, Clone)]
pub struct OutlierDrop {
    /// the calibration on the rows kept ([`calibrate`])
    pub calibration: Calibration,
    /// indices of the rows kept, in order (the rows `calibration` was fitted to)
    pub kept: Vec<usize>,
    /// the rows removed, in the order they were removed
    pub dropped: Vec<DroppedRow>,
    /// calibrations that were run (1: nothing was beyond)
    pub rounds: usize,
}

/// Calibrates ([`calibrate`]: initialisation, the set's choice, the fit), removes the rows
/// beyond `k · σ̂_r` ([`flag_outliers`]) and calibrates again on the rows kept, until no kept
/// row is beyond or after [`MAX_DROP_ROUNDS`] calibrations. `options.weights` weigh the kinds
/// as in the fit.
///
/// # Errors
/// `k` not finite and > 0; the errors of [`calibrate`] (e.g. too few rows left).
pub fn calibrate_dropping_outliers(
    nominal: &Model,
    rows: &[Measurement],
    spec: &str,
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
    k: f64,
) -> Result<OutlierDrop, IdentifyError> {
    if !(k.is_finite() && k > 0.0) {
        return Err(IdentifyError::InvalidOptions(format!(
            "--drop-outliers K must be finite and > 0, got {k}"
        )));
    }
    let mut kept: Vec<usize> = (0..rows.len()).collect();
    let mut dropped = Vec::new();
    let subset = |kept: &[usize]| -> Vec<Measurement> { kept.iter().map(|i| rows[*i]).collect() };
    let mut calibration = calibrate(nominal, rows, spec, design, options, cv)?;
    let mut rounds = 1;
    loop {
        let current = subset(&kept);
        let scan = flag_outliers(&calibration.fit.residuals, &current, &options.weights, k)?;
        if scan.rows.is_empty() || rounds >= MAX_DROP_ROUNDS {
            break;
        }
        let mut gone: Vec<usize> = scan.rows.iter().map(|f| f.index).collect();
        dropped.extend(scan.rows.iter().map(|f| DroppedRow {
            index: kept[f.index],
            residual_mm: f.residual_mm,
            sigmas: f.sigmas,
            round: rounds,
        }));
        gone.sort_unstable();
        kept = kept
            .iter()
            .enumerate()
            .filter(|(i, _)| gone.binary_search(i).is_err())
            .map(|(_, r)| *r)
            .collect();
        calibration = calibrate(nominal, &subset(&kept), spec, design, options, cv)?;
        rounds += 1;
    }
    Ok(OutlierDrop { calibration, kept, dropped, rounds })
}

/// One named row in the JSON report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BadRowReport {
    /// 0-based index of the row among the rows given to `identify` (all files, in order)
    pub row: usize,
    /// the file it was read from (when known)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// its 1-based line in that file (when known)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub line: Option<u64>,
    /// residual norm \[mm\]
    pub residual_mm: f64,
    /// kind-weighted residual norm in units of σ̂_r
    pub sigmas: f64,
    /// its weight in a robust fit (absent otherwise)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weight: Option<f64>,
    /// the round that dropped it (`--drop-outliers`; absent otherwise)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub round: Option<usize>,
}

/// The robust fit in the JSON report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobustReport {
    /// `huber` or `cauchy`
    pub loss: RobustLoss,
    /// tuning constant in units of σ̂_r
    pub tuning: f64,
    /// reweighted fits run
    pub rounds: usize,
    /// whether the weights settled
    pub converged: bool,
    /// smallest row weight
    pub min_weight: f64,
    /// rows with a weight below 0.5
    pub rows_below_half_weight: usize,
    /// RMS residual norm of the unweighted fit it started from \[mm\]
    pub unweighted_rms_mm: f64,
}

impl RobustReport {
    /// The report of a robust fit.
    pub fn from_fit(r: &RobustFit) -> Self {
        Self {
            loss: r.options.loss,
            tuning: r.options.tuning,
            rounds: r.rounds,
            converged: r.converged,
            min_weight: r.weights.iter().copied().fold(f64::INFINITY, f64::min),
            rows_below_half_weight: r.weights.iter().filter(|w| **w < 0.5).count(),
            unweighted_rms_mm: r.unweighted_rms_mm,
        }
    }
}

/// The bad-row section of the JSON report (`bad_rows`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BadRowsReport {
    /// how σ̂_r is estimated ([`SIGMA_ESTIMATOR`])
    pub sigma_estimator: String,
    /// σ̂_r of the final fit's residuals \[mm\]
    pub robust_sigma_mm: f64,
    /// k of the threshold
    pub k: f64,
    /// `k · σ̂_r` \[mm\] (kind-weighted norm)
    pub threshold_mm: f64,
    /// the final fit's rows beyond the threshold, largest first (kept in the fit unless
    /// `dropped` lists them)
    pub rows: Vec<BadRowReport>,
    /// the robust fit (`--robust`)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robust: Option<RobustReport>,
    /// the rows removed before the final fit (`--drop-outliers`)
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dropped: Vec<BadRowReport>,
    /// `K` of `--drop-outliers`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drop_k: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi3_median_is_the_median_of_a_3d_gaussian_norm() {
        // P(chi2_3 <= x) = erf(sqrt(x/2)) - sqrt(2x/pi) exp(-x/2); at x = CHI3_MEDIAN^2 it is 1/2
        let x: f64 = CHI3_MEDIAN * CHI3_MEDIAN;
        let erf = |z: f64| {
            // Abramowitz-Stegun 7.1.26 is too coarse; integrate exp(-t^2) by Simpson's rule
            let n = 2000;
            let h = z / n as f64;
            let f = |t: f64| (-t * t).exp();
            let mut s = f(0.0) + f(z);
            for i in 1..n {
                s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            s * h / 3.0 * 2.0 / std::f64::consts::PI.sqrt()
        };
        let cdf = erf((x / 2.0).sqrt()) - (2.0 * x / std::f64::consts::PI).sqrt() * (-x / 2.0).exp();
        assert!((cdf - 0.5).abs() < 1e-10, "{cdf}");
    }

    #[test]
    fn losses_parse_and_weigh() {
        assert_eq!("Cauchy".parse::<RobustLoss>(), Ok(RobustLoss::Cauchy));
        assert!("l1".parse::<RobustLoss>().is_err());
        assert_eq!(RobustLoss::Huber.weight(-0.5, 1.345), 1.0);
        assert!(RobustLoss::Cauchy.weight(3000.0, 2.385) < 1e-6);
    }
}
