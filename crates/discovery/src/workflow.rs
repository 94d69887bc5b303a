//! The discovery loop (background.md §8.3).
//!
//! Each round:
//! 1. the current model is fitted (identification crate);
//! 2. its residuals are located against every driving variable ([`crate::location`]);
//! 3. every catalog effect not yet in the model is scored: novelty `‖P⊥Z‖/‖Z‖` (≈ 0: not
//!    discoverable with this data) and the score test with σ̂ from the current fit; the
//!    candidates that pass a Bonferroni threshold `α/m` are refitted and must also pass the
//!    F-test (same threshold), lower BIC and AICc, a significantly lower stratified K-fold
//!    cross-validated prediction error (paired one-sided z-test), and a plausibility check of
//!    the identified values;
//! 4. the passing candidate with the lowest BIC is added (`enable_effect` + its identifiable
//!    parameters join the fitted set), and the gap — held-out and validation error — before
//!    and after is recorded;
//! 5. repeat until no candidate passes.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::Serialize;
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::ParamUnit;
use vatcal_core::{Measurement, ParamId, ParamSet, rad_to_deg};
use vatcal_identification::{ErrorStats, IdentifyOptions, validate};
use vatcal_kinematics::Model;
use vatcal_kinematics::effects::{DataAvailability, candidate_effects, missing_data};
use vatcal_observability::assemble_jacobian;

use crate::DiscoveryError;
use crate::catalog::{driver_of, meaning, plausibility};
use crate::criteria::{NestedComparison, PairedImprovement};
use crate::distributions::chi2_ln_sf;
use crate::fit::{Fit, fit, residuals};
use crate::folds::{split, stratified_folds};
use crate::linear::{ColumnSpace, EffectDirections, ScoreTest, score_test, unit_columns};
use crate::location::{DriverSummary, PoseData, locate};

/// Settings of [`discover`].
#[derive(Debug, Clone)]
pub struct DiscoverOptions {
    /// family-wise false-alarm probability of one round; each of the m scored candidates is
    /// tested at `alpha / m` (Bonferroni)
    pub alpha: f64,
    /// directions of a candidate whose novelty (singular value of the unit-normalised `P⊥Z`)
    /// is at or below this are treated as absorbed by the current parameters
    pub novelty_floor: f64,
    /// number of cross-validation folds
    pub folds: usize,
    /// seed of the fold assignment
    pub seed: u64,
    /// how many screened candidates (best score first) are refitted per round
    pub max_refits: usize,
    /// upper bound on the number of effects added
    pub max_rounds: usize,
    /// one-sided level of the paired test that the cross-validated (held-out) errors improve
    /// with the effect; confirmation of a screened candidate, so not divided by m
    pub cv_alpha: f64,
    /// known noise σ per axis [mm]; when `None` the score test uses σ̂ of the current fit
    pub known_sigma_mm: Option<f64>,
    /// options of every fit
    pub identify: IdentifyOptions,
}

impl Default for DiscoverOptions {
    fn default() -> Self {
        Self {
            alpha: 0.01,
            novelty_floor: 1e-3,
            folds: 5,
            seed: 1,
            max_refits: 4,
            max_rounds: 8,
            cv_alpha: 0.05,
            known_sigma_mm: None,
            identify: IdentifyOptions::default(),
        }
    }
}

/// Mean squared residual norm [mm²] of error statistics.
fn mse_mm2(s: &ErrorStats) -> f64 {
    s.rms * s.rms
}

/// How far the model is from the data it did not see.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Gap {
    /// errors of K-fold cross-validation (each measurement predicted by a fit without it)
    pub heldout: ErrorStats,
    /// errors on the independent validation set, when given
    pub validation: Option<ErrorStats>,
}

impl Gap {
    /// The headline number: the mean validation error when a validation set is given, else the
    /// mean held-out error [mm].
    pub fn headline_mm(&self) -> f64 {
        self.validation.as_ref().map_or(self.heldout.mean, |v| v.mean)
    }

    /// What [`Gap::headline_mm`] measures, for people.
    pub fn headline_name(&self) -> &'static str {
        if self.validation.is_some() { "mean validation error" } else { "mean cross-validated error" }
    }
}

/// Summary of one fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitSummary {
    /// fitted parameter names
    pub params: Vec<String>,
    /// number of measurements
    pub measurements: usize,
    /// number of scalar residuals N
    pub residuals: usize,
    /// numerical rank of the fitted Jacobian (identified directions)
    pub rank: usize,
    /// residual sum of squares [mm²]
    pub rss_mm2: f64,
    /// σ̂ = sqrt(RSS / (N − rank)) per axis [mm]
    pub sigma_hat_mm: f64,
    /// mean / RMS / max residual norm of the fit [mm]
    pub fit_errors: ErrorStats,
    /// with a known σ: `ln P(χ²_{N−rank} > RSS/σ²)` (very negative = something is missing)
    pub chi2_ln_p_value: Option<f64>,
    /// solver iterations
    pub iterations: usize,
    /// whether the solver converged
    pub converged: bool,
}

/// Where a candidate ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "status", content = "reason", rename_all = "kebab-case")]
pub enum CandidateStatus {
    /// the data lacks a column the effect needs
    MissingData(String),
    /// all its parameters are already fitted
    AlreadyInModel,
    /// its columns are absorbed by the current parameters (novelty ≈ 0)
    NotDiscoverable,
    /// the score test did not pass the screening threshold
    NotSignificant,
    /// screened, but not among the candidates refitted this round
    NotRefitted,
    /// refitted and rejected (the reason names the failed check)
    Rejected(String),
    /// passed every check, but another candidate was better (lower BIC)
    PassedNotBest,
    /// added to the model this round
    Added,
}

/// Correlation of an added parameter with an existing one after the refit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Confounding {
    /// the added parameter
    pub added: String,
    /// the existing parameter
    pub existing: String,
    /// their correlation coefficient
    pub correlation: f64,
}

/// Evidence from refitting with a candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefitEvidence {
    /// the parameters that joined the fitted set (the identifiable ones of the effect)
    pub fitted_params: Vec<String>,
    /// F-test, ΔAICc, ΔBIC
    pub comparison: NestedComparison,
    /// cross-validated prediction errors without / with the effect
    pub cv_before: ErrorStats,
    /// cross-validated prediction errors with the effect
    pub cv_after: ErrorStats,
    /// paired test of the held-out errors (without − with the effect)
    pub cv_improvement: PairedImprovement,
    /// identified values in file units (angles in degrees), keyed by parameter name with unit
    pub values: BTreeMap<String, f64>,
    /// their standard deviations in the same units
    pub std_errors: BTreeMap<String, f64>,
    /// largest correlations of the added parameters with existing ones
    pub confounding: Vec<Confounding>,
    /// `None` if plausible, else why not
    pub implausible: Option<String>,
}

/// Every candidate's scores in one round.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateScore {
    /// catalog name
    pub effect: String,
    /// human label (with joint, harmonic, ...)
    pub label: String,
    /// cell joint 1..7 for per-joint effects
    pub joint: Option<u8>,
    /// the effect's parameters that are not fitted yet
    pub params: Vec<String>,
    /// overall novelty ‖P⊥Ẑ‖/‖Ẑ‖ (None when not computed)
    pub novelty: Option<f64>,
    /// score test (None when not computed)
    pub score: Option<ScoreTest>,
    /// result of the refit (screened candidates only)
    pub refit: Option<RefitEvidence>,
    /// outcome
    #[serde(flatten)]
    pub status: CandidateStatus,
}

/// One round of the loop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Round {
    /// 1-based
    pub index: usize,
    /// the fit of the current model
    pub fit: FitSummary,
    /// residuals against every driving variable, most significant first
    pub location: Vec<DriverSummary>,
    /// Bonferroni screening threshold `ln(alpha/m)`
    pub ln_threshold: f64,
    /// every candidate, best score first
    pub candidates: Vec<CandidateScore>,
    /// what was decided, in one sentence
    pub decision: String,
}

/// Data for a plot of the residual against the effect's driving variable: for effects of a
/// revolute joint j the residual expressed as an angle error of joint j (its component along
/// `∂p/∂θ_j` divided by the lever arm) [µrad], otherwise the residual norm [µm].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriverPlot {
    /// x-axis label with unit
    pub x_label: String,
    /// y-axis label with unit
    pub y_label: String,
    /// driver value per measurement
    pub x: Vec<f64>,
    /// residual per measurement before adding the effect
    pub before: Vec<f64>,
    /// residual per measurement after adding the effect
    pub after: Vec<f64>,
}

/// An effect the loop added.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AddedEffect {
    /// catalog name
    pub effect: String,
    /// cell joint 1..7 for per-joint effects
    pub joint: Option<u8>,
    /// human label
    pub label: String,
    /// what it means physically
    pub meaning: String,
    /// the catalog instance
    pub spec: EffectSpec,
    /// identified values in file units, keyed by parameter name with unit
    pub values: BTreeMap<String, f64>,
    /// their standard deviations
    pub std_errors: BTreeMap<String, f64>,
    /// novelty of the effect before it was added
    pub novelty: f64,
    /// the score test
    pub score: ScoreTest,
    /// F-test and information criteria of the refit
    pub comparison: NestedComparison,
    /// largest correlations with existing parameters
    pub confounding: Vec<Confounding>,
    /// headline gap before adding it [mm]
    pub gap_before_mm: f64,
    /// headline gap after adding it [mm]
    pub gap_after_mm: f64,
    /// held-out and validation errors before
    pub gap_before: Gap,
    /// held-out and validation errors after
    pub gap_after: Gap,
    /// residual against the driving variable, before and after (for the plots; not in JSON)
    #[serde(skip)]
    pub plot: DriverPlot,
}

impl AddedEffect {
    /// One line for people: what was found and how much the gap shrank.
    pub fn summary_line(&self) -> String {
        let shrink = 100.0 * (1.0 - self.gap_after_mm / self.gap_before_mm.max(f64::MIN_POSITIVE));
        format!(
            "added {} (LM = {:.1} on {} dof, log10 p = {:.1}; F = {:.1}; dBIC = {:.1}; novelty {:.2}): gap {:.4} -> {:.4} mm ({shrink:.0} % smaller)",
            self.label,
            self.score.statistic,
            self.score.dof,
            self.score.ln_p_value / std::f64::consts::LN_10,
            self.comparison.f,
            self.comparison.delta_bic,
            self.novelty,
            self.gap_before_mm,
            self.gap_after_mm,
        )
    }
}

/// Everything the loop found.
#[derive(Debug, Clone, Serialize)]
pub struct Discovery {
    /// the final model (not serialised; write it with `to_cell`)
    #[serde(skip)]
    pub model: Model,
    /// the final fitted parameter set
    #[serde(serialize_with = "serialize_param_names")]
    pub params: ParamSet,
    /// the effects added, in order
    pub added_effects: Vec<AddedEffect>,
    /// every round
    pub rounds: Vec<Round>,
    /// gap of the starting parameter set
    pub initial_gap: Gap,
    /// gap of the final model
    pub final_gap: Gap,
    /// headline gap of the starting parameter set [mm]
    pub initial_gap_mm: f64,
    /// headline final gap [mm]
    pub final_gap_mm: f64,
    /// remarks (skipped candidates, data limits)
    pub notes: Vec<String>,
}

fn serialize_param_names<S: serde::Serializer>(p: &ParamSet, s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(p.iter().map(|x| x.name()))
}

/// Key and value of a parameter in file units (angles in degrees).
pub fn file_value(id: ParamId, v: f64) -> (String, f64) {
    match id.unit() {
        ParamUnit::Rad => (format!("{}_deg", id.name()), rad_to_deg(v)),
        ParamUnit::Mm => (format!("{}_mm", id.name()), v),
        _ => (id.name(), v),
    }
}

/// Internal state of a candidate during a round.
struct Candidate {
    spec: EffectSpec,
    new_params: Vec<ParamId>,
    directions: Option<EffectDirections>,
    score: Option<ScoreTest>,
    status: CandidateStatus,
    refit: Option<(RefitEvidence, Fit, Vec<Vector3<f64>>)>,
}

/// Fixed inputs of one run.
struct Context<'a> {
    measurements: &'a [Measurement],
    validation: Option<&'a [Measurement]>,
    folds: Vec<usize>,
    options: &'a DiscoverOptions,
}

impl Context<'_> {
    /// Held-out residual of every measurement: K fits, each without one fold.
    fn cross_validate(&self, start: &Model, params: &ParamSet) -> Result<Vec<Vector3<f64>>, DiscoveryError> {
        let k = self.folds.iter().copied().max().map_or(1, |m| m + 1);
        let mut held = vec![Vector3::zeros(); self.measurements.len()];
        for f in 0..k {
            let (train, test) = split(&self.folds, f);
            let train_ms: Vec<Measurement> = train.iter().map(|i| self.measurements[*i]).collect();
            let test_ms: Vec<Measurement> = test.iter().map(|i| self.measurements[*i]).collect();
            let trained = fit(start, &train_ms, params, &self.options.identify)?;
            for (i, r) in test.iter().zip(residuals(&trained.model, &test_ms)?) {
                held[*i] = r;
            }
        }
        Ok(held)
    }

    fn gap(&self, model: &Model, heldout: &[Vector3<f64>]) -> Result<Gap, DiscoveryError> {
        let validation = match self.validation {
            Some(v) if !v.is_empty() => {
                Some(validate(model, v).map_err(|e| DiscoveryError::Fit(e.to_string()))?.stats)
            }
            _ => None,
        };
        Ok(Gap { heldout: ErrorStats::from_errors(heldout), validation })
    }
}

fn summarize_fit(f: &Fit, rank: usize, known_sigma_mm: Option<f64>) -> FitSummary {
    let n = f.n();
    let dof = n.saturating_sub(rank).max(1);
    FitSummary {
        params: f.params.names(),
        measurements: f.residuals.len(),
        residuals: n,
        rank,
        rss_mm2: f.rss_mm2,
        sigma_hat_mm: (f.rss_mm2 / dof as f64).sqrt(),
        fit_errors: ErrorStats::from_errors(&f.residuals),
        chi2_ln_p_value: known_sigma_mm.map(|s| chi2_ln_sf(f.rss_mm2 / (s * s), dof)),
        iterations: f.iterations,
        converged: f.converged,
    }
}

/// The columns `cols` of `j` as a new matrix.
fn columns(j: &faer::Mat<f64>, cols: &[usize]) -> faer::Mat<f64> {
    faer::Mat::from_fn(j.nrows(), cols.len(), |r, c| j[(r, cols[c])])
}

/// The effect parameters (indices into `z`'s columns) that add an identifiable direction, chosen
/// greedily in catalog order.
fn identifiable_subset(
    j: &faer::Mat<f64>,
    z: &faer::Mat<f64>,
    novelty_floor: f64,
) -> Result<Vec<usize>, DiscoveryError> {
    let mut kept: Vec<usize> = Vec::new();
    for c in 0..z.ncols() {
        let base = faer::Mat::from_fn(j.nrows(), j.ncols() + kept.len(), |r, k| {
            if k < j.ncols() { j[(r, k)] } else { z[(r, kept[k - j.ncols()])] }
        });
        let space = ColumnSpace::of(base.as_ref())?;
        let col = columns(z, &[c]);
        let d = EffectDirections::new(&space, col.as_ref(), novelty_floor)?;
        if d.dof == 1 {
            kept.push(c);
        }
    }
    Ok(kept)
}

/// The catalog's candidates plus the lower orders of the guide-angular polynomial (order 1 =
/// a linear pitch/yaw/roll, 3 parameters, is tested on its own so that a linear error does not
/// have to pay for the 3 quadratic parameters too; the order-2 candidate is then the test of
/// the quadratic terms).
pub fn candidates(model: &Model, measurements: &[Measurement]) -> Vec<EffectSpec> {
    let mut v = candidate_effects(model, measurements);
    let mut lower = Vec::new();
    for spec in &v {
        if let EffectSpec::GuideAngular { order } = *spec {
            lower.extend((1..order).map(|o| EffectSpec::GuideAngular { order: o }));
        }
    }
    for spec in lower {
        if !v.contains(&spec) {
            v.push(spec);
        }
    }
    v
}

/// Scores every candidate effect against the current fit.
fn score_candidates(
    current: &Fit,
    space: &ColumnSpace,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<Vec<Candidate>, DiscoveryError> {
    let data = DataAvailability::of(ctx.measurements);
    let mut out: Vec<Candidate> = Vec::new();
    for spec in candidates(&current.model, ctx.measurements) {
        let new_params: Vec<ParamId> =
            spec.params().into_iter().filter(|p| current.params.index_of(*p).is_none()).collect();
        let status = if let Some(why) = missing_data(&spec, &data) {
            let what = match spec.joint() {
                Some(_) => format!("{} (every joint)", spec.kind()),
                None => spec.label(),
            };
            let note = format!("{what} not tested: {why}");
            if !notes.contains(&note) {
                notes.push(note);
            }
            CandidateStatus::MissingData(why.to_string())
        } else if new_params.is_empty() {
            CandidateStatus::AlreadyInModel
        } else {
            CandidateStatus::NotSignificant
        };
        out.push(Candidate { spec, new_params, directions: None, score: None, status, refit: None });
    }
    // one Jacobian for the parameters of every live candidate
    let mut all: Vec<ParamId> = Vec::new();
    for c in out.iter().filter(|c| c.status == CandidateStatus::NotSignificant) {
        for p in &c.new_params {
            if !all.contains(p) {
                all.push(*p);
            }
        }
    }
    if all.is_empty() {
        return Ok(out);
    }
    let zall = assemble_jacobian(&current.model, ctx.measurements, &ParamSet(all.clone()))
        .map_err(|e| DiscoveryError::Jacobian(e.to_string()))?;
    let r = current.stacked_residual();
    let n = r.len();
    let sigma2 = match ctx.options.known_sigma_mm {
        Some(s) => s * s,
        None => current.rss_mm2 / n.saturating_sub(space.rank()).max(1) as f64,
    };
    for c in out.iter_mut().filter(|c| c.status == CandidateStatus::NotSignificant) {
        let cols: Vec<usize> = c.new_params.iter().filter_map(|p| all.iter().position(|q| q == p)).collect();
        let z = columns(&zall, &cols);
        let d = EffectDirections::new(space, z.as_ref(), ctx.options.novelty_floor)?;
        if d.dof == 0 {
            c.status = CandidateStatus::NotDiscoverable;
        } else {
            c.score = Some(score_test(space, &d, &r, sigma2));
        }
        c.directions = Some(d);
    }
    Ok(out)
}

/// Refits with one candidate and collects the evidence.
fn refit_candidate(
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &[Vector3<f64>],
    candidate: &Candidate,
    ctx: &Context<'_>,
) -> Result<(RefitEvidence, Fit, Vec<Vector3<f64>>), String> {
    let opts = ctx.options;
    let mut start = current.model.clone();
    start.enable_effect(candidate.spec).map_err(|e| e.to_string())?;
    let z = assemble_jacobian(&start, ctx.measurements, &ParamSet(candidate.new_params.clone()))
        .map_err(|e| e.to_string())?;
    let (zn, _) = unit_columns(z.as_ref());
    let (jn, _) = unit_columns(j0.as_ref());
    let subset = identifiable_subset(&jn, &zn, opts.novelty_floor).map_err(|e| e.to_string())?;
    let added: Vec<ParamId> = subset.iter().map(|k| candidate.new_params[*k]).collect();
    if added.is_empty() {
        return Err("no identifiable parameter".into());
    }
    let mut params1 = current.params.clone();
    params1.0.extend(added.iter().copied());
    let fit1 =
        fit(&start, ctx.measurements, &params1, &opts.identify).map_err(|e| format!("refit failed: {e}"))?;
    let comparison =
        NestedComparison::new(current.n(), rank0, current.rss_mm2, rank0 + added.len(), fit1.rss_mm2);
    let held1 =
        ctx.cross_validate(&fit1.model, &params1).map_err(|e| format!("cross-validation failed: {e}"))?;
    let cv_after = ErrorStats::from_errors(&held1);
    let cv_improvement = PairedImprovement::new(held0, &held1);
    let before = |p: ParamId| current.model.param(p).unwrap_or(0.0);
    let changes: Vec<(ParamId, f64)> =
        added.iter().map(|p| (*p, fit1.value(*p).unwrap_or(0.0) - before(*p))).collect();
    let implausible = plausibility(&candidate.spec, &changes).err();
    let mut values = BTreeMap::new();
    let mut std_errors = BTreeMap::new();
    for p in &added {
        let (key, v) = file_value(*p, fit1.value(*p).unwrap_or(0.0));
        values.insert(key.clone(), v);
        if let Some(s) = params1.index_of(*p).and_then(|i| fit1.sigma.get(i)) {
            std_errors.insert(key, file_value(*p, *s).1);
        }
    }
    let mut confounding = Vec::new();
    let existing = current.params.len();
    for (a, p) in added.iter().enumerate() {
        for e in 0..existing {
            if let Some(c) = fit1.correlation(existing + a, e) {
                confounding.push(Confounding {
                    added: p.name(),
                    existing: current.params.0[e].name(),
                    correlation: c,
                });
            }
        }
    }
    confounding.sort_by(|x, y| y.correlation.abs().total_cmp(&x.correlation.abs()));
    confounding.truncate(3);
    let evidence = RefitEvidence {
        fitted_params: added.iter().map(|p| p.name()).collect(),
        comparison,
        cv_before: ErrorStats::from_errors(held0),
        cv_after,
        cv_improvement,
        values,
        std_errors,
        confounding,
        implausible,
    };
    Ok((evidence, fit1, held1))
}

/// Why refit evidence does not support adding the effect (`None` = it does).
fn rejection(e: &RefitEvidence, fit1: &Fit, ln_threshold: f64, cv_alpha: f64) -> Option<String> {
    let c = &e.comparison;
    if !fit1.converged {
        return Some("refit did not converge".into());
    }
    let significant = c.f_ln_p_value < ln_threshold;
    let bic_drops = c.delta_bic < 0.0;
    let aicc_drops = c.delta_aicc < 0.0;
    let cv_improves =
        mse_mm2(&e.cv_after) < mse_mm2(&e.cv_before) && e.cv_improvement.ln_p_value < cv_alpha.ln();
    if !significant {
        return Some(format!(
            "F-test not significant (log10 p = {:.1})",
            c.f_ln_p_value / std::f64::consts::LN_10
        ));
    }
    if !bic_drops {
        return Some(format!("BIC does not drop ({:+.1})", c.delta_bic));
    }
    if !aicc_drops {
        return Some(format!("AICc does not drop ({:+.1})", c.delta_aicc));
    }
    if !cv_improves {
        return Some(format!(
            "cross-validated error does not improve significantly (RMS {:.4} -> {:.4} mm, paired z = {:.2})",
            e.cv_before.rms, e.cv_after.rms, e.cv_improvement.z
        ));
    }
    e.implausible.as_ref().map(|why| format!("implausible: {why}"))
}

fn driver_plot(
    spec: &EffectSpec,
    model: &Model,
    ms: &[Measurement],
    before: &[Vector3<f64>],
    after: &[Vector3<f64>],
) -> Result<DriverPlot, DiscoveryError> {
    let driver = driver_of(spec);
    let pose = PoseData::of(model, ms)?;
    let joint = spec.joint().filter(|j| *j >= 2).map(usize::from);
    let y_label = match joint {
        Some(j) => format!("residual as joint-{j} angle error [urad]"),
        None => "residual norm [um]".to_string(),
    };
    let mut plot =
        DriverPlot { x_label: driver.label(), y_label, x: Vec::new(), before: Vec::new(), after: Vec::new() };
    for (i, m) in ms.iter().enumerate() {
        let Some(x) = driver.value(i, m, &pose.torques[i]) else { continue };
        let y = |r: &Vector3<f64>| match (joint, pose.joint_directions.as_ref()) {
            (Some(j), Some(dirs)) => {
                let d = dirs[i][j - 2];
                let l2 = d.norm_squared();
                if l2 > 0.0 { 1e6 * r.dot(&d) / l2 } else { 0.0 }
            }
            _ => 1e3 * r.norm(),
        };
        plot.x.push(x);
        plot.before.push(y(&before[i]));
        plot.after.push(y(&after[i]));
    }
    Ok(plot)
}

/// Refits the screened candidates (best score first, at most `max_refits`) and marks each as
/// rejected or passed.
fn confirm_screened(
    candidates: &mut [Candidate],
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &[Vector3<f64>],
    ln_threshold: f64,
    ctx: &Context<'_>,
) {
    let mut refits = 0;
    for c in candidates.iter_mut() {
        let Some(score) = c.score else { continue };
        let screened = score.ln_p_value < ln_threshold;
        if !screened {
            continue;
        }
        if refits >= ctx.options.max_refits {
            c.status = CandidateStatus::NotRefitted;
            continue;
        }
        refits += 1;
        match refit_candidate(current, j0, rank0, held0, c, ctx) {
            Ok((evidence, fit1, held1)) => {
                c.status = match rejection(&evidence, &fit1, ln_threshold, ctx.options.cv_alpha) {
                    Some(why) => CandidateStatus::Rejected(why),
                    None => CandidateStatus::PassedNotBest,
                };
                c.refit = Some((evidence, fit1, held1));
            }
            Err(why) => c.status = CandidateStatus::Rejected(why),
        }
    }
}

/// Index of the passing candidate with the lowest BIC.
fn best_passing(candidates: &[Candidate]) -> Option<usize> {
    let key = |c: &Candidate| c.refit.as_ref().map_or(f64::INFINITY, |r| r.0.comparison.delta_bic);
    candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.status == CandidateStatus::PassedNotBest)
        .min_by(|a, b| key(a.1).total_cmp(&key(b.1)))
        .map(|(i, _)| i)
}

/// Why nothing was added, naming the best-scored candidate.
fn nothing_added(candidates: &[Candidate], ln_threshold: f64) -> String {
    match candidates.iter().find(|c| c.score.is_some()) {
        Some(c) => {
            let why = match &c.status {
                CandidateStatus::Rejected(why) => why.clone(),
                _ => format!(
                    "score test log10 p = {:.1} above the threshold {:.1}",
                    c.score.map_or(0.0, |s| s.ln_p_value) / std::f64::consts::LN_10,
                    ln_threshold / std::f64::consts::LN_10
                ),
            };
            format!("nothing added: best candidate {} ({why})", c.spec.label())
        }
        None => "nothing added: no candidate can be tested".to_string(),
    }
}

/// The record of an added candidate (its refit must be present).
fn added_effect(
    c: &Candidate,
    current: &Fit,
    gap_before: &Gap,
    ctx: &Context<'_>,
) -> Result<(AddedEffect, Fit, Vec<Vector3<f64>>), DiscoveryError> {
    let lost = || DiscoveryError::Numerical("internal: the added candidate has no refit or score".into());
    let (evidence, fit1, held1) = c.refit.clone().ok_or_else(lost)?;
    let score = c.score.ok_or_else(lost)?;
    let gap_after = ctx.gap(&fit1.model, &held1)?;
    let plot = driver_plot(&c.spec, &fit1.model, ctx.measurements, &current.residuals, &fit1.residuals)?;
    let added = AddedEffect {
        effect: c.spec.kind().name().to_string(),
        joint: c.spec.joint(),
        label: c.spec.label(),
        meaning: meaning(c.spec.kind()).to_string(),
        spec: c.spec,
        values: evidence.values,
        std_errors: evidence.std_errors,
        novelty: c.directions.as_ref().map_or(0.0, |d| d.novelty),
        score,
        comparison: evidence.comparison,
        confounding: evidence.confounding,
        gap_before_mm: gap_before.headline_mm(),
        gap_after_mm: gap_after.headline_mm(),
        gap_before: gap_before.clone(),
        gap_after,
        plot,
    };
    Ok((added, fit1, held1))
}

/// Runs the discovery loop from `start` with the fitted parameter set `params` on
/// `measurements`; `validation` (e.g. tracker measurements) is used only to report the gap.
pub fn discover(
    start: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    validation: Option<&[Measurement]>,
    options: &DiscoverOptions,
) -> Result<Discovery, DiscoveryError> {
    if measurements.is_empty() {
        return Err(DiscoveryError::NoMeasurements);
    }
    let ctx = Context {
        measurements,
        validation,
        folds: stratified_folds(measurements, options.folds.max(2), options.seed),
        options,
    };
    let mut notes = Vec::new();
    let mut current = fit(start, measurements, params, &options.identify)?;
    let mut held0 = ctx.cross_validate(&current.model, &current.params)?;
    let initial_gap = ctx.gap(&current.model, &held0)?;
    let mut gap = initial_gap.clone();
    let mut rounds = Vec::new();
    let mut added_effects = Vec::new();
    for index in 1..=options.max_rounds.max(1) {
        let j0 = assemble_jacobian(&current.model, measurements, &current.params)
            .map_err(|e| DiscoveryError::Jacobian(e.to_string()))?;
        let space = ColumnSpace::of(j0.as_ref())?;
        let rank0 = space.rank();
        let location = locate(&current.model, measurements, &current.residuals)?;
        let mut candidates = score_candidates(&current, &space, &ctx, &mut notes)?;
        let m = candidates.iter().filter(|c| c.score.is_some()).count().max(1);
        let ln_threshold = (options.alpha / m as f64).ln();
        let key = |c: &Candidate| c.score.map_or(f64::INFINITY, |s| s.ln_p_value);
        candidates.sort_by(|a, b| key(a).total_cmp(&key(b)));
        confirm_screened(&mut candidates, &current, &j0, rank0, &held0, ln_threshold, &ctx);
        let fit_summary = summarize_fit(&current, rank0, options.known_sigma_mm);
        let next = match best_passing(&candidates) {
            Some(b) => {
                candidates[b].status = CandidateStatus::Added;
                Some(added_effect(&candidates[b], &current, &gap, &ctx)?)
            }
            None => None,
        };
        let decision = match &next {
            Some((added, ..)) => added.summary_line(),
            None => nothing_added(&candidates, ln_threshold),
        };
        rounds.push(Round {
            index,
            fit: fit_summary,
            location,
            ln_threshold,
            candidates: candidates.into_iter().map(candidate_score).collect(),
            decision,
        });
        let Some((added, fit1, held1)) = next else { break };
        gap = added.gap_after.clone();
        added_effects.push(added);
        current = fit1;
        held0 = held1;
    }
    Ok(Discovery {
        model: current.model,
        params: current.params,
        added_effects,
        rounds,
        initial_gap_mm: initial_gap.headline_mm(),
        initial_gap,
        final_gap_mm: gap.headline_mm(),
        final_gap: gap,
        notes,
    })
}

fn candidate_score(c: Candidate) -> CandidateScore {
    CandidateScore {
        effect: c.spec.kind().name().to_string(),
        label: c.spec.label(),
        joint: c.spec.joint(),
        params: c.new_params.iter().map(|p| p.name()).collect(),
        novelty: c.directions.as_ref().map(|d| d.novelty),
        score: c.score,
        refit: c.refit.map(|r| r.0),
        status: c.status,
    }
}
