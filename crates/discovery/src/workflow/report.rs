//! What [`discover`](super::discover) reports: the gap, every round and candidate, the effects
//! added, removed and found negligible.

use std::collections::BTreeMap;

use serde::Serialize;
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::ParamUnit;
use vatcal_core::{ParamId, ParamSet, rad_to_deg};
use vatcal_identification::{ErrorStats, KindSigmas};
use vatcal_kinematics::Model;

use crate::criteria::{HeldOutComparison, NestedComparison};
use crate::linear::ScoreTest;
use crate::location::DriverSummary;
use crate::noise::NoiseReference;
use crate::power::Detectability;

/// How far the model is from the data it did not see.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Gap {
    /// errors of K-fold cross-validation over all measurements (each predicted by a fit without
    /// it); measurements of skipped folds are left out
    pub heldout: ErrorStats,
    /// folds whose fit failed and were skipped
    pub skipped_folds: usize,
    /// errors on the independent validation set, when given
    pub validation: Option<ErrorStats>,
}

impl Gap {
    /// The headline number: the mean validation error when a validation set is given, else the
    /// mean held-out error \[mm\].
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
    /// residual sum of squares \[mm²\] (unweighted)
    pub rss_mm2: f64,
    /// σ̂ = sqrt(weighted RSS / (N − rank)) per axis of a weight-1 (probe) measurement \[mm\]
    pub sigma_hat_mm: f64,
    /// mean / RMS / max residual norm of the fit \[mm\]
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
    /// its columns are absorbed by the current parameters (novelty ≈ 0), or are of round-off
    /// size (no effect at all: e.g. the compliance of a joint without gravity load)
    NotDiscoverable,
    /// the score test on the screening data did not pass the threshold
    NotSignificant,
    /// screened, but not among the candidates confirmed this round
    NotRefitted,
    /// refitted and rejected (the reason names the failed check)
    Rejected(String),
    /// real (lowers the held-out error significantly) but changes the predictions by less
    /// than the noise: not added (the reason gives the size)
    DetectedNegligible(String),
    /// passed every check, but another candidate improved the held-out error more
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
    /// F-test, ΔAICc, ΔBIC of the refit on all data (reported, not decisive)
    pub comparison: NestedComparison,
    /// held-out comparison on the confirmation data (decisive)
    pub heldout: HeldOutComparison,
    /// z the held-out improvement had to exceed this round
    pub z_required: f64,
    /// prediction change below which the effect counts as negligible \[mm\]
    pub negligible_below_mm: f64,
    /// without a noise reference (σ̂ in the size rule): the held-out z from which the size
    /// rule is waived (`strong_z_factor · z_r`); `None` when the noise is known
    pub size_rule_waived_above_z: Option<f64>,
    /// prediction change below which the effect is negligible whatever the noise estimate:
    /// `negligible_factor · √3 ·` [`DiscoverOptions::noise_floor_mm`](crate::workflow::DiscoverOptions::noise_floor_mm) \[mm\] (never waived)
    pub floor_below_mm: f64,
    /// the round's held-out gap was far above its floor ([`Round::far_from_floor`]): the size
    /// rule is waived for a candidate that passes the held-out test
    pub size_rule_waived_far_from_floor: bool,
    /// identified values in file units (angles in degrees), keyed by parameter name with unit
    pub values: BTreeMap<String, f64>,
    /// their standard deviations in the same units
    pub std_errors: BTreeMap<String, f64>,
    /// largest correlations of the added parameters with existing ones
    pub confounding: Vec<Confounding>,
    /// `None` if plausible, else why not
    pub implausible: Option<String>,
    /// when the candidate's parameters and some already in the model were indistinguishable
    /// on the data (the plain refit was ill-conditioned): how that was resolved
    pub rival: Option<Ambiguity>,
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
    /// overall novelty ‖P⊥Ẑ‖/‖Ẑ‖ on the screening data (None when not computed)
    pub novelty: Option<f64>,
    /// score test on the screening data (None when not computed)
    pub score: Option<ScoreTest>,
    /// result of the refit and confirmation (screened candidates only)
    pub refit: Option<RefitEvidence>,
    /// for a borderline candidate (not added, but refitted or nominally significant at 1 %
    /// alone): the minimum detectable size with these data and the measurements that would
    /// decide it ([`crate::power`])
    pub detectability: Option<Detectability>,
    /// outcome
    #[serde(flatten)]
    pub status: CandidateStatus,
}

/// An effect removed by the backward check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RemovedEffect {
    /// human label
    pub label: String,
    /// round in which it was added
    pub added_in_round: usize,
    /// round in which it was removed
    pub removed_in_round: usize,
    /// why: the held-out comparison without / with it, given the later effects
    pub heldout: HeldOutComparison,
}

/// Near-equivalent candidates of one round (their held-out predictions change alike and
/// improve alike on the confirmation data) and how one was chosen.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ambiguity {
    /// round
    pub round: usize,
    /// the candidate added
    pub chosen: String,
    /// the near-equivalent ones not added
    pub rivals: Vec<String>,
    /// `validation` (the chosen one predicts the validation rows better, significantly),
    /// `simpler` (fewer parameters; the data cannot tell), or `held-out` (same size: the
    /// larger held-out improvement)
    pub basis: String,
    /// per rival: paired z of the chosen one's improvement over the rival's on the validation
    /// rows (positive: the chosen one predicts better), when validation rows are given
    pub validation_z: Vec<Option<f64>>,
    /// one sentence for people, e.g. "joint-compliance (joint 2) or guide-carriage-tilt:
    /// indistinguishable on these data; ..."
    pub sentence: String,
}

/// A candidate refused because an identified value exceeded its plausibility bound (reported,
/// never silently dropped: the bound may be wrong for this robot).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoundHit {
    /// round
    pub round: usize,
    /// catalog name (the key of a `--bound NAME=VALUE` override)
    pub effect: String,
    /// human label
    pub label: String,
    /// which value exceeded which bound, and where the bound comes from
    pub reason: String,
    /// the held-out z of the refit that was refused (how strongly the data ask for it)
    pub heldout_z: f64,
    /// whether it had passed every other check (significant, above the noise)
    pub otherwise_passed: bool,
}

/// An effect that is real but too small to matter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NegligibleEffect {
    /// human label
    pub label: String,
    /// round
    pub round: usize,
    /// RMS change of the held-out predictions it would make \[µm\]
    pub change_um: f64,
    /// the held-out comparison
    pub heldout: HeldOutComparison,
}

/// One round of the loop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Round {
    /// 1-based
    pub index: usize,
    /// the fit of the current model to all data
    pub fit: FitSummary,
    /// residuals against every driving variable, most significant first
    pub location: Vec<DriverSummary>,
    /// screening threshold `ln(alpha·s_r/m)` of a candidate of weight 1; each candidate's own
    /// threshold adds the ln of its weight (physical effects and generic fallbacks share the
    /// level 0.8 : 0.2, [`GENERIC_SCREENING_SHARE`](crate::workflow::GENERIC_SCREENING_SHARE))
    pub ln_threshold: f64,
    /// without a noise reference: σ̂ per axis of the saturated linear model (the current
    /// parameters plus every scored candidate's, on all data) \[mm\], an upper bound of the
    /// noise that holds only the physics no candidate can describe; the size rule uses the
    /// lower of it and the refit's σ̂
    pub sigma_saturated_mm: Option<f64>,
    /// z the held-out improvement of a candidate had to exceed
    pub z_required: f64,
    /// held-out gap of the current model (all-data cross-validation, rows weighted by kind)
    /// over its floor estimate `√(3σ²(1 + p/N))`, σ the noise reference (replicates or
    /// instruments) or, without one, the saturated σ̂; `None` when no σ is known. Above
    /// [`DiscoverOptions::floor_gap_factor`](crate::workflow::DiscoverOptions::floor_gap_factor) the round keeps going ([`Round::far_from_floor`])
    pub gap_over_floor: Option<f64>,
    /// whether the gap was well above its floor: the round then confirms the best-scored
    /// candidates even when none passes the screening threshold, and waives the size rule for
    /// those that pass the held-out test
    pub far_from_floor: bool,
    /// every candidate, best screening score first
    pub candidates: Vec<CandidateScore>,
    /// effects removed by the backward check after this round's addition
    pub removed: Vec<RemovedEffect>,
    /// what was decided, in one sentence
    pub decision: String,
}

/// Data for a plot of the residual against the effect's driving variable: for effects of a
/// revolute joint j the residual expressed as an angle error of joint j (its component along
/// `∂p/∂θ_j` divided by the lever arm) \[µrad\], otherwise the residual norm \[µm\].
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
    /// round in which it was added
    pub round: usize,
    /// how it was added: alone by the forward search, in the round's block, or in the set of
    /// the joint search, in one sentence
    pub how: String,
    /// identified values in file units, keyed by parameter name with unit
    pub values: BTreeMap<String, f64>,
    /// their standard deviations
    pub std_errors: BTreeMap<String, f64>,
    /// novelty of the effect before it was added (screening data)
    pub novelty: f64,
    /// the score test (screening data)
    pub score: ScoreTest,
    /// F-test and information criteria of the refit (all data)
    pub comparison: NestedComparison,
    /// the held-out comparison on the confirmation data that admitted it
    pub heldout: HeldOutComparison,
    /// largest correlations with existing parameters
    pub confounding: Vec<Confounding>,
    /// headline gap before adding it \[mm\]
    pub gap_before_mm: f64,
    /// headline gap after adding it \[mm\]
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
            "added {} (screening LM = {:.1} on {} dof, log10 p = {:.1}; held-out RMS {:.4} -> {:.4} mm, z = {:.1}, predictions change {:.1} um): gap {:.4} -> {:.4} mm ({shrink:.0} % smaller)",
            self.label,
            self.score.statistic,
            self.score.dof,
            self.score.ln_p_value / std::f64::consts::LN_10,
            self.heldout.rms_before_mm,
            self.heldout.rms_after_mm,
            self.heldout.z,
            1e3 * self.heldout.change_rms_mm,
            self.gap_before_mm,
            self.gap_after_mm,
        )
    }
}

/// Predicted TCP position uncertainty of the final model, averaged over poses.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictedUncertainty {
    /// what the poses are (`validation` or `measurements`)
    pub poses: String,
    /// number of poses
    pub count: usize,
    /// mean of `‖σ‖` (per-axis σ as a vector) from the parameter covariance alone \[mm\]
    pub statistical_mean_mm: f64,
    /// the same with the systematic CMM errors of TCP and position coordinates \[mm\]
    pub with_cmm_mean_mm: f64,
    /// the CMM standard deviation per coordinate used \[mm\]
    pub cmm_sigma_mm: f64,
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
    /// the effects in the final model, in the order added
    pub added_effects: Vec<AddedEffect>,
    /// effects added and later removed by the backward check
    pub removed_effects: Vec<RemovedEffect>,
    /// effects detected but too small to matter (not added)
    pub negligible_effects: Vec<NegligibleEffect>,
    /// candidates refused at a plausibility bound
    pub bound_hits: Vec<BoundHit>,
    /// rounds in which near-equivalent candidates competed, and how one was chosen
    pub ambiguities: Vec<Ambiguity>,
    /// every round
    pub rounds: Vec<Round>,
    /// measurements used for screening / for confirmation
    pub split: [usize; 2],
    /// σ of probe and tracker residuals of the initial fit (used as weights when both exist)
    pub kind_sigmas: KindSigmas,
    /// the noise the size rule compared with, where it came from and what follows from it
    pub noise: NoiseReference,
    /// cross-validation folds skipped over the whole run (their fit failed)
    pub skipped_folds: usize,
    /// gap of the starting parameter set
    pub initial_gap: Gap,
    /// gap of the final model
    pub final_gap: Gap,
    /// headline gap of the starting parameter set \[mm\]
    pub initial_gap_mm: f64,
    /// headline final gap \[mm\]
    pub final_gap_mm: f64,
    /// predicted uncertainty of the final model (statistical, and with CMM errors)
    pub uncertainty: Option<PredictedUncertainty>,
    /// remarks (skipped candidates, skipped folds, data limits)
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
