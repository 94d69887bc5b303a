//! The discovery loop (background.md §8.3) with a held-out decision rule.
//!
//! The measurements are split once (seeded, stratified by calibration position) into a
//! **screening** part S and a **confirmation** part C. Each round:
//! 1. the current model is fitted to all data (identification crate) and its residuals are
//!    located against every driving variable ([`crate::location`], a diagnostic);
//! 2. **screening** on S only: the current model is refitted to S and every catalog effect not
//!    yet in the model is scored there (novelty `‖P⊥Z‖/‖Z‖` and the score test). The
//!    false-alarm probability is spent over the rounds: round r screens at `α·s_r/m` (m scored
//!    candidates), so the family-wise level over **all** rounds and candidates is ≤ α;
//! 3. **confirmation** on C only (data the screening never saw): for the best screened
//!    candidates, every point of C is predicted by fits without it (K folds of C; training =
//!    S + the other folds of C), without and with the effect. The effect must lower the
//!    held-out squared error by more than `z_r` standard errors of the paired differences
//!    (`z_r` at the level `confirm_alpha·s_r/max_refits`, `s_r = 6/(π²r²)`, [`round_spending`]),
//!    its predictions must change by more than the noise (the instruments' known noise when
//!    given, else σ̂; below it the effect is reported as *detected, negligible (x µm)* and not
//!    added), and its identified values must be plausible;
//! 4. the confirmed candidate with the largest held-out improvement is added (refitted on all
//!    data); then a **backward check** removes earlier effects (those correlated with the new
//!    one) that no longer lower the held-out error by more than one standard error with the
//!    new one present;
//! 5. repeat until no candidate is confirmed.
//!
//! A cross-validation fold whose fit fails (ill-conditioned, not converged) is skipped,
//! counted and reported; it does not abort the run.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;
use vatcal_core::canonical::bounds::{ChainScale, ScaledBound, scaled_bound};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::ParamUnit;
use vatcal_core::{Measurement, ParamId, ParamSet, rad_to_deg};
use vatcal_identification::{ErrorStats, IdentifyOptions, KindSigmas, KindWeights};
use vatcal_kinematics::Model;
use vatcal_kinematics::effects::{DataAvailability, candidate_effects, missing_data};
use vatcal_observability::assemble_jacobian;

use crate::DiscoveryError;
use crate::catalog::{driver_of_in, meaning};
use crate::criteria::{HeldOutComparison, NestedComparison};
use crate::distributions::{chi2_ln_sf, normal_upper_quantile};
use crate::fit::{Fit, fit, residuals};
use crate::folds::{screening_split, stratified_folds};
use crate::linear::{ColumnSpace, EffectDirections, ScoreTest, score_test, unit_columns};
use crate::location::{DriverSummary, PoseData, locate};
use crate::noise::{NoiseReference, NoiseSource, ReplicateTolerance};
use crate::power::{DEFAULT_POWER, Detectability};

/// Settings of [`discover`].
#[derive(Debug, Clone)]
pub struct DiscoverOptions {
    /// family-wise false-alarm probability of the screening over **all** rounds: round r
    /// (1-based) spends `alpha·s_r` ([`round_spending`]), split over its m scored candidates
    pub alpha: f64,
    /// family-wise level of the held-out confirmation over all rounds: round r confirms at
    /// `confirm_alpha·s_r/max_refits` per refitted candidate (one-sided paired z-test)
    pub confirm_alpha: f64,
    /// share of the measurements (per calibration position) used for screening; the rest
    /// confirms
    pub screen_fraction: f64,
    /// an effect whose held-out predictions change by less than this many times the noise
    /// (RMS of `‖Δprediction‖` below `negligible_factor · √3 · σ̂₁`, σ̂₁ the per-axis noise
    /// estimate of the refit **with** the effect, i.e. what is left once it is modelled) is
    /// reported as "detected, negligible" and not added
    pub negligible_factor: f64,
    /// directions of a candidate whose novelty (singular value of the unit-normalised `P⊥Z`)
    /// is at or below this are treated as absorbed by the current parameters
    pub novelty_floor: f64,
    /// number of cross-validation folds (of the confirmation part, and of all data for the
    /// reported held-out gap)
    pub folds: usize,
    /// seed of the screening/confirmation split and of the folds
    pub seed: u64,
    /// how many screened candidates (best score first) are confirmed per round
    pub max_refits: usize,
    /// upper bound on the number of rounds
    pub max_rounds: usize,
    /// when no candidate passes alone, confirm the refitted candidates that each lowered the
    /// held-out error by more than one standard error **together** (one more test of the
    /// round, at `confirm_alpha·s_r/(max_refits + 1)`), then prune the block's members with
    /// the backward check: with many missing effects each one's held-out gain is masked by
    /// the others' misfit, together they are not
    pub block_step: bool,
    /// the backward check after an addition re-tests an earlier effect only when one of its
    /// parameters correlates with one of the new effect's by at least this (absolute value,
    /// in the fit with both): an effect can only be made redundant by one that shares its
    /// directions
    pub redundancy_correlation: f64,
    /// known noise σ per axis \[mm\] for the score test; when `None` σ̂ of the screening fit is used
    pub known_sigma_mm: Option<f64>,
    /// the instruments' known measurement noise per kind (σ per axis of probe and of tracker
    /// rows \[mm\], e.g. from the device specifications). When given, the size rule compares an
    /// effect's prediction change with this noise instead of σ̂ of the refit (which effects
    /// still unmodelled inflate), and probe/tracker rows are weighted by it; the score test
    /// keeps σ̂ (conservative while effects are missing). `None`: σ̂ everywhere.
    pub instrument_sigmas: Option<KindSigmas>,
    /// estimate σ of probe and of tracker residuals separately and weight the fits by them
    /// (only matters when both kinds are in the data)
    pub weight_by_kind: bool,
    /// standard deviation of the systematic CMM errors of the TCP and calibration-position
    /// coordinates \[mm\] (per coordinate), included in the reported prediction uncertainty
    pub cmm_sigma_mm: f64,
    /// options of every fit (the kind weights are replaced when `weight_by_kind`)
    pub identify: IdentifyOptions,
    /// where `instrument_sigmas` came from, for the report (e.g. "recorded in probe.csv
    /// (`# vatcal-noise:`)" or "--probe-sigma-mm"); `None`: "given by the caller"
    pub instrument_noise_origin: Option<String>,
    /// use the pure error of replicated measurements in the data as the noise reference of
    /// the size rule (preferred over `instrument_sigmas`, [`crate::noise`])
    pub use_replicates: bool,
    /// joint tolerances below which two measurements count as replicates of one pose
    pub replicate_tolerance: ReplicateTolerance,
    /// without a noise reference (no replicates, no instrument noise) the size rule compares
    /// with σ̂, which the effects still missing inflate: an effect whose held-out z is at
    /// least `strong_z_factor` times the round's `z_r` is then added whatever σ̂ says (and
    /// kept by the backward check while its z stays above `strong_z_factor`)
    pub strong_z_factor: f64,
    /// without a noise reference, compare with the lower of a refit's σ̂ and σ̂ of the round's
    /// saturated linear model (current parameters plus every scored candidate's directions;
    /// [`Round::sigma_saturated_mm`]), which holds only what no candidate can describe
    pub saturated_noise: bool,
    /// plausibility bounds set by the user, per effect (catalog name, e.g. `joint-backlash`):
    /// the largest plausible magnitude of each of its parameters in file units (deg for
    /// angles, mm for lengths, the parameter's own unit otherwise); they replace the bounds
    /// scaled to the chain ([`vatcal_core::canonical::bounds`])
    pub bound_overrides: BTreeMap<String, f64>,
    /// Catalog effects (by name, e.g. `link-out-of-plane`) that are not proposed: a researcher
    /// restricting the search to the physics they want to test (`vatcal discover
    /// --exclude-effect NAME`). Empty: the whole catalog.
    pub excluded_effects: Vec<String>,
    /// discovery keeps going while the held-out gap is more than this many times its floor
    /// estimate ([`Round::gap_over_floor`]): such a round confirms its best-scored candidates
    /// even when none passes the screening threshold and waives the size rule for the ones
    /// that pass the held-out test (a model that far from the noise is missing something
    /// that matters); `f64::INFINITY` switches this off
    pub floor_gap_factor: f64,
    /// refuse an addition that makes the validation rows' error significantly larger (paired
    /// z below `-`[`VETO_Z`], when validation rows are given): an effect is real only if it
    /// shrinks the gap on data the fit never saw
    pub validation_veto: bool,
    /// the physical floor of the noise reference, σ per axis \[mm\] (default 0.001: the
    /// resolution of the finest instrument vatcal reads, the Sylvac gauges' 1 µm; laser
    /// trackers and motion capture are coarser). Whatever the reference — replicates, a
    /// stated noise, σ̂ of a refit or of the saturated model — the size rule and the
    /// gap-over-floor ratio never compare with less: an estimate that collapses to round-off
    /// (data whose only misfit beyond the start is describable by candidates, e.g. µm fixture
    /// errors on noise-free data) would otherwise make every effect "not negligible" and the
    /// gap infinitely far from its floor. The size rule is never waived below it. `0`: off
    pub noise_floor_mm: f64,
}

impl Default for DiscoverOptions {
    fn default() -> Self {
        Self {
            alpha: 0.01,
            confirm_alpha: 0.05,
            screen_fraction: 0.5,
            negligible_factor: 1.0,
            novelty_floor: 1e-3,
            folds: 5,
            seed: 1,
            max_refits: 4,
            max_rounds: 16,
            redundancy_correlation: 0.2,
            block_step: true,
            known_sigma_mm: None,
            instrument_sigmas: None,
            weight_by_kind: true,
            cmm_sigma_mm: 0.002,
            identify: IdentifyOptions::default(),
            instrument_noise_origin: None,
            use_replicates: true,
            replicate_tolerance: ReplicateTolerance::default(),
            strong_z_factor: 1.5,
            saturated_noise: true,
            bound_overrides: BTreeMap::new(),
            excluded_effects: Vec::new(),
            floor_gap_factor: 1.5,
            validation_veto: true,
            noise_floor_mm: 0.001,
        }
    }
}

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
    /// `negligible_factor · √3 ·` [`DiscoverOptions::noise_floor_mm`] \[mm\] (never waived)
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
    /// level 0.8 : 0.2, [`GENERIC_SCREENING_SHARE`])
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
    /// [`DiscoverOptions::floor_gap_factor`] the round keeps going ([`Round::far_from_floor`])
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

/// Internal state of a candidate during a round.
struct Candidate {
    spec: EffectSpec,
    new_params: Vec<ParamId>,
    directions: Option<EffectDirections>,
    score: Option<ScoreTest>,
    status: CandidateStatus,
    refit: Option<(RefitEvidence, Fit, CrossValidation)>,
    detect: Option<Detectability>,
    /// ln of the candidate's weight in the round's screening (weighted Bonferroni,
    /// [`screening_weights`]): its p-value is compared with `weight · alpha_r / m`
    ln_weight: f64,
}

impl Candidate {
    /// The screening's ln p-value divided by the candidate's weight (compared with the
    /// round's unweighted threshold).
    fn weighted_ln_p(&self) -> Option<f64> {
        self.score.map(|s| s.ln_p_value - self.ln_weight)
    }
}

/// Share of a round's screening level spent on the catalog's **generic** effects
/// (`ErrorEffect::generic`, e.g. `link-out-of-plane`) when the round also scores physical
/// ones: a weighted Bonferroni split (weights summing to the number of candidates), so that
/// adding generic fallbacks to the catalog costs the physical effects' power little (their
/// threshold is that of a catalog without the fallbacks, times 0.8).
pub const GENERIC_SCREENING_SHARE: f64 = 0.2;

/// ln weights of the scored candidates (module docs of [`GENERIC_SCREENING_SHARE`]).
fn screening_weights(candidates: &mut [Candidate]) {
    let generic = |c: &Candidate| c.spec.effect().is_some_and(|e| e.generic());
    let scored = || candidates.iter().filter(|c| c.score.is_some());
    let m = scored().count() as f64;
    let m_generic = scored().filter(|c| generic(c)).count() as f64;
    let m_physical = m - m_generic;
    for c in candidates.iter_mut() {
        c.ln_weight = if m_generic == 0.0 || m_physical == 0.0 {
            0.0
        } else if generic(c) {
            (GENERIC_SCREENING_SHARE * m / m_generic).ln()
        } else {
            ((1.0 - GENERIC_SCREENING_SHARE) * m / m_physical).ln()
        };
    }
}

/// Held-out predictions of a cross-validation: one error per measurement (`None` = not
/// predicted: not in the evaluated part, or its fold was skipped).
struct CrossValidation {
    errors: Vec<Option<Vector3<f64>>>,
    skipped: Vec<String>,
}

impl CrossValidation {
    fn stats(&self) -> ErrorStats {
        let e: Vec<Vector3<f64>> = self.errors.iter().flatten().copied().collect();
        ErrorStats::from_errors(&e)
    }
}

/// Fixed inputs of one run.
struct Context<'a> {
    measurements: &'a [Measurement],
    validation: Option<&'a [Measurement]>,
    /// fold of every measurement over all data (reported gap)
    all_folds: Vec<Option<usize>>,
    /// fold of every confirmation measurement (`None` for screening ones)
    confirm_folds: Vec<Option<usize>>,
    /// the screening measurements
    screen: Vec<Measurement>,
    options: DiscoverOptions,
    /// σ per axis of each kind the size rule compares with (replicates or instruments);
    /// `None`: σ̂ of each fit ([`NoiseSource::Estimated`])
    reference: Option<KindSigmas>,
    /// without a reference: σ̂ of the round's saturated linear model (bits of an f64, NaN =
    /// unknown), the lower of it and a refit's σ̂ is the size rule's noise
    saturated_bits: std::sync::atomic::AtomicU64,
    /// the chain's size as the data see it (plausibility bounds)
    scale: ChainScale,
}

impl Context<'_> {
    /// Held-out residual of every measurement with `Some` fold: one fit per fold on every
    /// other measurement (a failing fold is skipped and named).
    fn cross_validate(&self, start: &Model, params: &ParamSet, folds: &[Option<usize>]) -> CrossValidation {
        let k = folds.iter().flatten().copied().max().map_or(0, |m| m + 1);
        let mut cv = CrossValidation { errors: vec![None; self.measurements.len()], skipped: Vec::new() };
        // the folds' fits are independent: run them in parallel, collect in fold order (the
        // result does not depend on the thread count)
        let per_fold: Vec<_> = (0..k)
            .into_par_iter()
            .map(|f| {
                let test: Vec<usize> = (0..folds.len()).filter(|i| folds[*i] == Some(f)).collect();
                if test.is_empty() {
                    return (test, None);
                }
                let train: Vec<Measurement> =
                    (0..folds.len()).filter(|i| folds[*i] != Some(f)).map(|i| self.measurements[i]).collect();
                let test_ms: Vec<Measurement> = test.iter().map(|i| self.measurements[*i]).collect();
                let predicted = fit(start, &train, params, &self.options.identify)
                    .and_then(|trained| residuals(&trained.model, &test_ms));
                (test, Some(predicted))
            })
            .collect();
        for (f, (test, predicted)) in per_fold.into_iter().enumerate() {
            match predicted {
                None => {}
                Some(Ok(r)) => {
                    for (i, e) in test.iter().zip(r) {
                        cv.errors[*i] = Some(e);
                    }
                }
                Some(Err(e)) => {
                    cv.skipped.push(format!("fold {} of {k} ({} measurements): {e}", f + 1, test.len()))
                }
            }
        }
        cv
    }

    /// The plausibility bound of `id`: the user's override of its effect, else the larger of
    /// the canonical bound and the one scaled to the chain.
    fn bound(&self, id: &ParamId) -> Option<ScaledBound> {
        let kind = vatcal_core::effects::kind_of_param(id)?;
        if let Some(v) = self.options.bound_overrides.get(kind.name()) {
            let (value, unit) = match id.unit() {
                ParamUnit::Rad => (v.to_radians(), "deg"),
                ParamUnit::Mm => (*v, "mm"),
                _ => (*v, ""),
            };
            return Some(ScaledBound { value, text: format!("{v} {unit} (set by the user)") });
        }
        scaled_bound(id, vatcal_core::effects::bound_of(id), &self.scale)
    }

    /// Checks the identified changes of an effect's parameters against their bounds (a
    /// compliance must also be positive). Returns why it is implausible.
    fn plausibility(&self, spec: &EffectSpec, changes: &[(ParamId, f64)]) -> Result<(), String> {
        // a profile's bound applies to its excursion, not to its coefficients
        let named: Vec<(ParamId, f64, String)> =
            spec.effect().and_then(|e| e.bounded_magnitudes(spec, changes)).unwrap_or_else(|| {
                changes
                    .iter()
                    .map(|(id, c)| (*id, *c, format!("{} of {}", id.name(), spec.label())))
                    .collect()
            });
        for (id, change, name) in &named {
            if let ParamId::Compliance(j) = id
                && *change <= 0.0
            {
                return Err(format!(
                    "c_{j} came out {change:.3e} rad/(N*m): a joint cannot stiffen under load"
                ));
            }
            if let Some(b) = self.bound(id)
                && change.abs() > b.value
            {
                let shown = if id.unit() == ParamUnit::Rad {
                    format!("{:.3e} deg", change.to_degrees())
                } else {
                    format!("{change:.3e}")
                };
                return Err(format!("{name} changed by {shown}: more than the plausible {}", b.text));
            }
        }
        Ok(())
    }

    /// The held-out z from which the size rule is waived in a test at `z_required`: only
    /// without a noise reference (module docs of [`crate::noise`]).
    fn strong_z(&self, z_required: f64) -> Option<f64> {
        self.reference.is_none().then(|| self.options.strong_z_factor * z_required.max(1.0))
    }

    fn gap(&self, model: &Model, heldout: &CrossValidation) -> Result<Gap, DiscoveryError> {
        let validation = match self.validation {
            Some(v) if !v.is_empty() => Some(ErrorStats::from_errors(&residuals(model, v)?)),
            _ => None,
        };
        Ok(Gap { heldout: heldout.stats(), skipped_folds: heldout.skipped.len(), validation })
    }

    /// Per-axis noise estimate of a weight-1 measurement from a fit with `rank` identified
    /// directions (or the known σ).
    fn sigma_hat(&self, f: &Fit, ms: &[Measurement], rank: usize) -> f64 {
        if let Some(s) = self.options.known_sigma_mm {
            return s;
        }
        let w = &self.options.identify.weights;
        let rss: f64 = ms.iter().zip(&f.residuals).map(|(m, r)| kind_weight(m, w) * r.norm_squared()).sum();
        (rss / (3 * ms.len()).saturating_sub(rank).max(1) as f64).sqrt()
    }

    /// Per-axis noise the size rule compares a prediction change with: the noise reference of
    /// a weight-1 row (probe σ when the data has probe rows, else tracker σ; from replicates
    /// or the instruments, [`crate::noise`]) when there is one, else [`Context::sigma_hat`] of
    /// the fit.
    fn noise_sigma(&self, f: &Fit, ms: &[Measurement], rank: usize) -> f64 {
        let known = self.reference.and_then(|k| {
            let has_probe = ms.iter().any(|m| matches!(m.target, vatcal_core::Target::Probe { .. }));
            if has_probe { k.probe_mm } else { k.tracker_mm }
        });
        let sigma = match known {
            Some(s) if s > 0.0 && s.is_finite() => s,
            _ => {
                let own = self.sigma_hat(f, ms, rank);
                let sat = f64::from_bits(self.saturated_bits.load(std::sync::atomic::Ordering::Relaxed));
                if sat.is_finite() && sat > 0.0 { own.min(sat) } else { own }
            }
        };
        sigma.max(self.options.noise_floor_mm)
    }
}

/// The held-out gap of the current model (`held`: its all-data cross-validation) over the
/// floor estimate `√(3σ₁²(1 + p/N))`: σ₁ the per-axis noise of a weight-1 row — the noise
/// reference (replicates or instruments) or, without one, the round's saturated σ̂ — `p`
/// the fitted rank and `N` the scalar residuals (the cross-validated prediction of a correct
/// model misses by the noise plus its own estimation error). Rows are weighted by kind as in
/// the fits. `None` when no σ is known.
fn gap_over_floor(
    held: &CrossValidation,
    sigma_saturated: Option<f64>,
    rank: usize,
    ctx: &Context<'_>,
) -> Option<f64> {
    let ms = ctx.measurements;
    let known = ctx.reference.and_then(|k| {
        let has_probe = ms.iter().any(|m| matches!(m.target, vatcal_core::Target::Probe { .. }));
        if has_probe { k.probe_mm } else { k.tracker_mm }
    });
    let sigma =
        known.or(sigma_saturated).filter(|s| s.is_finite() && *s > 0.0)?.max(ctx.options.noise_floor_mm);
    let w = &ctx.options.identify.weights;
    let (mut sum, mut count) = (0.0, 0usize);
    for (m, e) in ms.iter().zip(&held.errors) {
        if let Some(e) = e {
            sum += kind_weight(m, w) * e.norm_squared();
            count += 1;
        }
    }
    if count == 0 {
        return None;
    }
    let n = 3.0 * ms.len() as f64;
    let floor2 = 3.0 * sigma * sigma * (1.0 + rank as f64 / n);
    Some((sum / count as f64 / floor2).sqrt())
}

/// Refuses (status `Rejected`) every passing candidate whose refit predicts the validation
/// rows significantly worse than the current model (paired z of the squared errors below
/// `-`[`VETO_Z`]): an addition that makes the gap on data the fit never saw larger is not
/// kept.
fn veto_on_validation(
    candidates: &mut [Candidate],
    current: &Fit,
    ctx: &Context<'_>,
) -> Result<(), DiscoveryError> {
    let Some(v) = ctx.validation.filter(|v| !v.is_empty() && ctx.options.validation_veto) else {
        return Ok(());
    };
    let before: Vec<Option<Vector3<f64>>> = residuals(&current.model, v)?.into_iter().map(Some).collect();
    for c in candidates.iter_mut().filter(|c| c.status == CandidateStatus::PassedNotBest) {
        let Some((_, f, _)) = c.refit.as_ref() else { continue };
        let after: Vec<Option<Vector3<f64>>> = residuals(&f.model, v)?.into_iter().map(Some).collect();
        let h = HeldOutComparison::new(&before, &after);
        if h.z < -VETO_Z {
            c.status = CandidateStatus::Rejected(format!(
                "{VALIDATION_WORSE} (RMS {:.4} -> {:.4} mm over {} rows, z = {:.2})",
                h.rms_before_mm, h.rms_after_mm, h.points, h.z
            ));
        }
    }
    Ok(())
}

/// Whether `fit1` predicts the validation rows significantly worse than `current` (paired z
/// below `-`[`VETO_Z`]; false without validation rows or with the veto off).
fn validation_worse(current: &Fit, fit1: &Fit, ctx: &Context<'_>) -> bool {
    let Some(v) = ctx.validation.filter(|v| !v.is_empty() && ctx.options.validation_veto) else {
        return false;
    };
    match (residuals(&current.model, v), residuals(&fit1.model, v)) {
        (Ok(b), Ok(a)) => {
            let wrap = |r: Vec<Vector3<f64>>| r.into_iter().map(Some).collect::<Vec<_>>();
            HeldOutComparison::new(&wrap(b), &wrap(a)).z < -VETO_Z
        }
        _ => false,
    }
}

/// Paired z below `-VETO_Z` on the validation rows refuses an addition: the rows must be
/// significantly worse with it, not merely worse by chance.
pub const VETO_Z: f64 = 2.0;

/// Start of the rejection reason of a candidate refused by [`veto_on_validation`].
const VALIDATION_WORSE: &str = "the validation rows' error grows with it";

/// Share of the false-alarm probability spent in round `r` (1-based): `6/(π² r²)`, which sums
/// to 1 over all rounds, so spending `alpha · spend(r)` per round keeps the family-wise level
/// over every round below `alpha` while later rounds (needed when a cell has many missing
/// effects) stay testable (round 8 still spends 0.95 %, where `2⁻ʳ` would spend 0.39 %).
pub fn round_spending(r: usize) -> f64 {
    let r = r.max(1) as f64;
    6.0 / (std::f64::consts::PI * std::f64::consts::PI * r * r)
}

/// Weight of a measurement's kind.
fn kind_weight(m: &Measurement, w: &KindWeights) -> f64 {
    match m.target {
        vatcal_core::Target::Probe { .. } => w.probe,
        vatcal_core::Target::Tracker { .. } => w.tracker,
    }
}

/// Multiplies the row block of every measurement by `√w` of its kind.
fn weigh_rows(j: &mut faer::Mat<f64>, ms: &[Measurement], w: &KindWeights) {
    if w.probe == 1.0 && w.tracker == 1.0 {
        return;
    }
    for (k, m) in ms.iter().enumerate() {
        let s = kind_weight(m, w).sqrt();
        for c in 0..j.ncols() {
            for a in 0..3 {
                j[(3 * k + a, c)] *= s;
            }
        }
    }
}

/// The stacked residual of a fit, rows weighted by `√w`.
fn weighted_residual(f: &Fit, ms: &[Measurement], w: &KindWeights) -> Vec<f64> {
    ms.iter()
        .zip(&f.residuals)
        .flat_map(|(m, r)| {
            let s = kind_weight(m, w).sqrt();
            [s * r.x, s * r.y, s * r.z]
        })
        .collect()
}

fn summarize_fit(f: &Fit, ms: &[Measurement], rank: usize, ctx: &Context<'_>) -> FitSummary {
    let n = f.n();
    let dof = n.saturating_sub(rank).max(1);
    FitSummary {
        params: f.params.names(),
        measurements: f.residuals.len(),
        residuals: n,
        rank,
        rss_mm2: f.rss_mm2,
        sigma_hat_mm: ctx.sigma_hat(f, ms, rank),
        fit_errors: ErrorStats::from_errors(&f.residuals),
        chi2_ln_p_value: ctx.options.known_sigma_mm.map(|s| chi2_ln_sf(f.rss_mm2 / (s * s), dof)),
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

/// Highest gear harmonic [`candidates`] proposes.
pub const MAX_PROPOSED_HARMONIC: u8 = vatcal_core::effects::joint_cyclic::MAX_PROPOSED_HARMONIC;

/// The catalog's candidates plus what each effect's module adds: further candidates once an
/// instance is in the model (`ErrorEffect::follow_ups`: the next gear harmonic of a joint
/// once the model has its harmonic h ≥ 2, harmonics entering in order up to
/// [`MAX_PROPOSED_HARMONIC`]: a strain-wave gear whose error curve has a second harmonic has
/// higher ones too, and proposing them only then keeps the number of scored candidates, and
/// so the Bonferroni price, small), then candidates tested beside another
/// (`ErrorEffect::also_try`: the lower orders of the guide-angular polynomial; order 1 = a
/// linear pitch/yaw/roll, 3 parameters, is tested on its own so that a linear error does not
/// have to pay for the 3 quadratic parameters too; the order-2 candidate is then the test of
/// the quadratic terms).
pub fn candidates(model: &Model, measurements: &[Measurement]) -> Vec<EffectSpec> {
    let mut v = candidate_effects(model, measurements);
    for spec in model.effects() {
        for next in spec.effect().map(|e| e.follow_ups(spec)).unwrap_or_default() {
            if !v.contains(&next) {
                v.push(next);
            }
        }
    }
    let mut lower = Vec::new();
    for spec in &v {
        lower.extend(spec.effect().map(|e| e.also_try(spec)).unwrap_or_default());
    }
    for spec in lower {
        if !v.contains(&spec) {
            v.push(spec);
        }
    }
    v
}

/// Scores every candidate effect on the screening data (`screen_fit` = the current model
/// refitted to the screening measurements).
fn score_candidates(
    current: &Fit,
    screen_fit: &Fit,
    space: &ColumnSpace,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<Vec<Candidate>, DiscoveryError> {
    let data = DataAvailability::of(ctx.measurements);
    let mut out: Vec<Candidate> = Vec::new();
    let excluded = |spec: &EffectSpec| ctx.options.excluded_effects.iter().any(|n| n == spec.kind().name());
    for spec in candidates(&current.model, ctx.measurements).into_iter().filter(|s| !excluded(s)) {
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
        out.push(Candidate {
            spec,
            new_params,
            directions: None,
            score: None,
            status,
            refit: None,
            detect: None,
            ln_weight: 0.0,
        });
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
    let w = ctx.options.identify.weights;
    let mut zall = assemble_jacobian(&screen_fit.model, &ctx.screen, &ParamSet(all.clone()))
        .map_err(DiscoveryError::Jacobian)?;
    weigh_rows(&mut zall, &ctx.screen, &w);
    let r = weighted_residual(screen_fit, &ctx.screen, &w);
    let sigma = ctx.sigma_hat(screen_fit, &ctx.screen, space.rank());
    // columns at round-off size (e.g. the compliance of a vertical joint: no gravity torque)
    // are no direction at all, however they look after unit normalisation
    let norms: Vec<f64> = (0..zall.ncols()).map(|c| zall.col(c).norm_l2()).collect();
    let negligible = vatcal_observability::identifiability::negligible_columns(&norms, &all);
    for c in out.iter_mut().filter(|c| c.status == CandidateStatus::NotSignificant) {
        let cols: Vec<usize> = c.new_params.iter().filter_map(|p| all.iter().position(|q| q == p)).collect();
        if cols.iter().all(|k| negligible.contains(k)) {
            c.status = CandidateStatus::NotDiscoverable;
            continue;
        }
        let z = columns(&zall, &cols);
        let d = EffectDirections::new(space, z.as_ref(), ctx.options.novelty_floor)?;
        if d.dof == 0 {
            c.status = CandidateStatus::NotDiscoverable;
        } else {
            c.score = Some(score_test(space, &d, &r, sigma * sigma));
        }
        c.directions = Some(d);
    }
    Ok(out)
}

/// The thresholds of one round.
struct Thresholds {
    ln_screen: f64,
    z_required: f64,
    /// the held-out gap is well above its floor estimate ([`Round::far_from_floor`])
    far_from_floor: bool,
}

/// Refits with one candidate on all data, confirms it on the held-out confirmation data and
/// collects the evidence.
#[allow(clippy::too_many_arguments)]
fn refit_candidate(
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &CrossValidation,
    candidate: &Candidate,
    th: &Thresholds,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<(RefitEvidence, Fit, CrossValidation), String> {
    refit_effects(
        current,
        j0,
        rank0,
        held0,
        &[(candidate.spec, candidate.new_params.clone())],
        th,
        ctx,
        notes,
    )
}

/// The physical floor of the noise for the size rule of `effects` \[mm per axis\]:
/// [`DiscoverOptions::noise_floor_mm`], and for corrections of fixture coordinates (effects
/// driven by the TCP or the calibration position: a ball or socket off its CMM value) at least
/// the fixtures' stated CMM uncertainty [`DiscoverOptions::cmm_sigma_mm`] — a coordinate
/// correction within the CMM's own uncertainty is not a missing physical effect (the reported
/// prediction uncertainty already includes it, `CmmUncertainty`).
fn physical_floor_mm(effects: &[(EffectSpec, Vec<ParamId>)], opts: &DiscoverOptions) -> f64 {
    let fixture = !effects.is_empty()
        && effects.iter().all(|(s, _)| {
            matches!(
                crate::catalog::driver_of(s),
                crate::location::Driver::Tcp | crate::location::Driver::Position
            )
        });
    if fixture { opts.noise_floor_mm.max(opts.cmm_sigma_mm) } else { opts.noise_floor_mm }
}

/// Refits with several effects at once (each with its not yet fitted parameters) on all data,
/// confirms them together on the held-out confirmation data and collects the evidence.
#[allow(clippy::too_many_arguments)]
fn refit_effects(
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &CrossValidation,
    effects: &[(EffectSpec, Vec<ParamId>)],
    th: &Thresholds,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<(RefitEvidence, Fit, CrossValidation), String> {
    let opts = &ctx.options;
    let mut start = current.model.clone();
    let mut new_params: Vec<ParamId> = Vec::new();
    for (spec, params) in effects {
        start.enable_effect(*spec).map_err(|e| e.to_string())?;
        new_params.extend(params.iter().copied().filter(|p| !new_params.contains(p)).collect::<Vec<_>>());
    }
    let label = effects.iter().map(|(s, _)| s.label()).collect::<Vec<_>>().join(" + ");
    let z = assemble_jacobian(&start, ctx.measurements, &ParamSet(new_params.clone()))
        .map_err(|e| e.to_string())?;
    let (zn, _) = unit_columns(z.as_ref());
    let (jn, _) = unit_columns(j0.as_ref());
    let subset = identifiable_subset(&jn, &zn, opts.novelty_floor).map_err(|e| e.to_string())?;
    let added: Vec<ParamId> = subset.iter().map(|k| new_params[*k]).collect();
    if added.is_empty() {
        return Err("no identifiable parameter".into());
    }
    let mut params1 = current.params.clone();
    params1.0.extend(added.iter().copied());
    let (fit1, params1, added, rival) = fit_resolving_rivals(&start, current, params1, added, &label, ctx)?;
    if added.is_empty() {
        return Err("no identifiable parameter".into());
    }
    let dropped = current.params.len() + added.len() - params1.len();
    let comparison = NestedComparison::new(
        current.n(),
        rank0,
        current.rss_mm2,
        (rank0 + added.len()).saturating_sub(dropped),
        fit1.rss_mm2,
    );
    let held1 = ctx.cross_validate(&start, &params1, &ctx.confirm_folds);
    for s in &held1.skipped {
        notes.push(format!("confirmation of {label}: skipped {s}"));
    }
    let heldout = HeldOutComparison::new(&held0.errors, &held1.errors);
    let before = |p: ParamId| current.model.param(p).unwrap_or(0.0);
    let changes: Vec<(ParamId, f64)> =
        added.iter().map(|p| (*p, fit1.value(*p).unwrap_or(0.0) - before(*p))).collect();
    let implausible = effects.iter().find_map(|(spec, params)| {
        let own: Vec<(ParamId, f64)> = changes.iter().copied().filter(|(p, _)| params.contains(p)).collect();
        ctx.plausibility(spec, &own)
            .err()
            .map(|why| if effects.len() > 1 { format!("{}: {why}", spec.label()) } else { why })
    });
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
    let existing = params1.len() - added.len();
    for (a, p) in added.iter().enumerate() {
        for e in 0..existing {
            if let Some(c) = fit1.correlation(existing + a, e) {
                confounding.push(Confounding {
                    added: p.name(),
                    existing: params1.0[e].name(),
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
        heldout,
        z_required: th.z_required,
        negligible_below_mm: opts.negligible_factor
            * 3f64.sqrt()
            * ctx.noise_sigma(&fit1, ctx.measurements, rank0 + added.len()),
        size_rule_waived_above_z: ctx.strong_z(th.z_required),
        size_rule_waived_far_from_floor: th.far_from_floor,
        floor_below_mm: opts.negligible_factor * 3f64.sqrt() * physical_floor_mm(effects, opts),
        values,
        std_errors,
        confounding,
        implausible,
        rival,
    };
    Ok((evidence, fit1, held1))
}

/// |Correlation| at which an added parameter and one already in the model count as the same
/// direction on the data: near-equivalent rivals (`fit_resolving_rivals`).
pub const RIVAL_CORRELATION: f64 = 0.99;

/// Fits `params1` (the current parameters followed by the `added` ones). When the fit is
/// refused as ill-conditioned because added parameters and parameters already in the model
/// are near-equivalent on the data (|correlation| ≥ [`RIVAL_CORRELATION`]; e.g. `c_2` and
/// `carriage_tilt_y`), the data cannot tell them apart, so instead of failing it fits both
/// resolutions — **keep** the model's parameters and add only the rest of the candidate's,
/// or **swap**: the candidate's parameters replace the model's rivals — and keeps the swap
/// only when it predicts the validation rows significantly better (paired z > 2), else the
/// simpler resolution (the model as it was, plus the candidate's other directions). The
/// choice is returned as an [`Ambiguity`] (round 0: set by the caller) naming both.
fn fit_resolving_rivals(
    start: &Model,
    current: &Fit,
    params1: ParamSet,
    added: Vec<ParamId>,
    label: &str,
    ctx: &Context<'_>,
) -> Result<(Fit, ParamSet, Vec<ParamId>, Option<Ambiguity>), String> {
    let opts = &ctx.options;
    let (mut params1, mut added) = (params1, added);
    let refused = loop {
        match fit(start, ctx.measurements, &params1, &opts.identify) {
            Ok(f) => return Ok((f, params1, added, None)),
            Err(DiscoveryError::Fit(e)) => match *e {
                vatcal_identification::IdentifyError::IllConditioned(id) => break id,
                // some of the candidate's parameters are exact combinations of the model's on
                // these data (e.g. a tool-frame shift once two TCP offsets are in): fit the
                // candidate's other directions, as the screening's identifiable subset meant to
                vatcal_identification::IdentifyError::Unidentifiable { ref unidentifiable, .. }
                    if added.iter().any(|p| unidentifiable.contains(p))
                        && !added.iter().all(|p| unidentifiable.contains(p)) =>
                {
                    added.retain(|p| !unidentifiable.contains(p));
                    params1
                        .0
                        .retain(|p| !unidentifiable.contains(p) || current.params.index_of(*p).is_some());
                }
                other => return Err(format!("refit failed: {other}")),
            },
            Err(e) => return Err(format!("refit failed: {e}")),
        }
    };
    let n_old = current.params.len();
    let corr = &refused.correlation;
    let mut pairs: Vec<(ParamId, ParamId, f64)> = Vec::new();
    for (a, pa) in added.iter().enumerate() {
        for e in 0..n_old {
            let (i, k) = (n_old + a, e);
            if i < corr.nrows() && k < corr.ncols() {
                let c = corr[(i, k)];
                if c.is_finite() && c.abs() >= RIVAL_CORRELATION {
                    pairs.push((*pa, current.params.0[e], c));
                }
            }
        }
    }
    if pairs.is_empty() {
        return Err(format!(
            "refit failed: {}",
            vatcal_identification::IdentifyError::IllConditioned(refused)
        ));
    }
    let new_rivals: Vec<ParamId> =
        added.iter().copied().filter(|p| pairs.iter().any(|(a, _, _)| a == p)).collect();
    let old_rivals: Vec<ParamId> =
        current.params.iter().copied().filter(|p| pairs.iter().any(|(_, e, _)| e == p)).collect();
    // keep: the model's parameters, the candidate's other ones
    let keep_added: Vec<ParamId> = added.iter().copied().filter(|p| !new_rivals.contains(p)).collect();
    let keep_params = ParamSet(current.params.iter().copied().chain(keep_added.iter().copied()).collect());
    let keep = if keep_added.is_empty() {
        None
    } else {
        fit(start, ctx.measurements, &keep_params, &opts.identify).ok()
    };
    // swap: the candidate's parameters in place of the model's rivals
    let swap_params = ParamSet(
        current
            .params
            .iter()
            .copied()
            .filter(|p| !old_rivals.contains(p))
            .chain(added.iter().copied())
            .collect(),
    );
    let swap = fit(start, ctx.measurements, &swap_params, &opts.identify).ok();
    let names = |v: &[ParamId]| v.iter().map(|p| p.name()).collect::<Vec<_>>().join(", ");
    let shown: Vec<String> =
        pairs.iter().map(|(a, e, c)| format!("{}/{} ({c:+.4})", a.name(), e.name())).collect();
    let validation = ctx.validation.filter(|v| !v.is_empty());
    let val_errors = |f: &Fit| -> Option<Vec<Option<Vector3<f64>>>> {
        validation.and_then(|v| residuals(&f.model, v).ok()).map(|r| r.into_iter().map(Some).collect())
    };
    let swap_z = match (&keep, &swap, validation) {
        (Some(k), Some(s), Some(_)) => match (val_errors(k), val_errors(s)) {
            (Some(vk), Some(vs)) => Some(HeldOutComparison::new(&vk, &vs).z),
            _ => None,
        },
        (None, Some(s), Some(_)) => match (val_errors(current), val_errors(s)) {
            (Some(vc), Some(vs)) => Some(HeldOutComparison::new(&vc, &vs).z),
            _ => None,
        },
        _ => None,
    };
    let use_swap = swap.is_some() && (keep.is_none() || swap_z.is_some_and(|z| z > 2.0));
    let (chosen_fit, chosen_params, chosen_added, basis, chosen_name, rival_name) = if use_swap {
        let Some(f) = swap else {
            return Err("refit failed: no resolution of the rivals could be fitted".into());
        };
        let basis = if swap_z.is_some_and(|z| z > 2.0) { "validation" } else { "only-fit" };
        (f, swap_params, added.clone(), basis, format!("{label} ({})", names(&added)), names(&old_rivals))
    } else {
        let Some(f) = keep else {
            return Err(format!(
                "refit failed: {label} and the model's {} are indistinguishable on these data ({}) and neither resolution could be fitted",
                names(&old_rivals),
                shown.join(", ")
            ));
        };
        (
            f,
            keep_params,
            keep_added,
            "simpler",
            names(&old_rivals),
            format!("{label} ({})", names(&new_rivals)),
        )
    };
    let why = match basis {
        "validation" => format!(
            "{chosen_name} predicts the validation rows better (paired z = {:.2})",
            swap_z.unwrap_or(f64::NAN)
        ),
        "only-fit" => format!("{chosen_name} kept: the other resolution could not be fitted"),
        _ => format!(
            "kept {chosen_name}, already in the model{}",
            swap_z.map_or(" (no validation rows to tell them apart)".to_string(), |z| format!(
                " (the swap is not significantly better on the validation rows: z = {z:.2})"
            ))
        ),
    };
    let ambiguity = Ambiguity {
        round: 0,
        chosen: chosen_name.clone(),
        rivals: vec![rival_name.clone()],
        basis: basis.to_string(),
        validation_z: vec![swap_z],
        sentence: format!(
            "{chosen_name} or {rival_name}: indistinguishable on these data (correlation {}); {why}",
            shown.join(", ")
        ),
    };
    Ok((chosen_fit, chosen_params, chosen_added, Some(ambiguity)))
}

/// Start of the rejection reason of a candidate refused at a plausibility bound.
const IMPLAUSIBLE: &str = "implausible: ";

/// Start of the rejection reason of a candidate that failed the held-out z-test.
const HELDOUT_NOT_LOWER: &str = "held-out error not lower by more than its uncertainty";

/// The decision rule: what the evidence says about adding the effect.
fn decide(e: &RefitEvidence, fit1: &Fit) -> CandidateStatus {
    let h = &e.heldout;
    if !fit1.converged {
        return CandidateStatus::Rejected("refit did not converge".into());
    }
    if h.points < 2 {
        return CandidateStatus::Rejected("no held-out predictions (every confirmation fold failed)".into());
    }
    if h.z.is_nan() || h.z <= e.z_required {
        return CandidateStatus::Rejected(format!(
            "{HELDOUT_NOT_LOWER} (RMS {:.4} -> {:.4} mm, reduction {:.3e} +- {:.3e} mm2, z = {:.2} < {:.2})",
            h.rms_before_mm, h.rms_after_mm, h.mean_reduction_mm2, h.std_error_mm2, h.z, e.z_required
        ));
    }
    let waived = e.size_rule_waived_far_from_floor || e.size_rule_waived_above_z.is_some_and(|z| h.z >= z);
    if h.change_rms_mm < e.floor_below_mm {
        return CandidateStatus::DetectedNegligible(format!(
            "detected, negligible ({:.2} um): predictions change by less than the physical noise floor ({:.2} um = sqrt(3) x {:.2} um per axis), whatever the estimate of the noise",
            1e3 * h.change_rms_mm,
            1e3 * e.floor_below_mm,
            1e3 * e.floor_below_mm / 3f64.sqrt()
        ));
    }
    if h.change_rms_mm < e.negligible_below_mm && !waived {
        return CandidateStatus::DetectedNegligible(format!(
            "detected, negligible ({:.1} um): predictions change by less than the noise ({:.1} um){}",
            1e3 * h.change_rms_mm,
            1e3 * e.negligible_below_mm,
            e.size_rule_waived_above_z
                .map(|z| format!(
                    " estimated by sigma-hat, and the held-out z = {:.2} is below {z:.2}, at which the size rule is waived",
                    h.z
                ))
                .unwrap_or_default()
        ));
    }
    if let Some(why) = &e.implausible {
        return CandidateStatus::Rejected(format!("{IMPLAUSIBLE}{why}"));
    }
    CandidateStatus::PassedNotBest
}

fn driver_plot(
    spec: &EffectSpec,
    model: &Model,
    ms: &[Measurement],
    before: &[Vector3<f64>],
    after: &[Vector3<f64>],
) -> Result<DriverPlot, DiscoveryError> {
    let n = model.joint_count() as u8;
    let driver = driver_of_in(spec, model.guide_joint().unwrap_or(1) as u8, n);
    let pose = PoseData::of(model, ms)?;
    let joint = spec.joint().map(usize::from).filter(|j| model.is_revolute(*j));
    let y_label = match joint {
        Some(j) => format!("residual as joint-{j} angle error [urad]"),
        None => "residual norm [um]".to_string(),
    };
    let mut plot = DriverPlot {
        x_label: driver.label_for(model.joint_kinds()),
        y_label,
        x: Vec::new(),
        before: Vec::new(),
        after: Vec::new(),
    };
    for (i, m) in ms.iter().enumerate() {
        let Some(x) = driver.value(i, m, &pose) else { continue };
        let y = |r: &Vector3<f64>| match (joint, pose.joint_directions.as_ref()) {
            (Some(j), Some(dirs)) => {
                let d = dirs[i][j - 1];
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

/// Refits and confirms the screened candidates (best score first, at most `max_refits`).
#[allow(clippy::too_many_arguments)]
fn confirm_screened(
    candidates: &mut [Candidate],
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &CrossValidation,
    th: &Thresholds,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) {
    let mut chosen = Vec::new();
    for (i, c) in candidates.iter_mut().enumerate() {
        let Some(ln_p) = c.weighted_ln_p() else { continue };
        // far from the floor: the best-scored candidates are confirmed whatever their screening
        // score (the held-out test still decides)
        if ln_p.is_nan() || (ln_p >= th.ln_screen && !th.far_from_floor) {
            continue;
        }
        if chosen.len() >= ctx.options.max_refits {
            c.status = CandidateStatus::NotRefitted;
            continue;
        }
        chosen.push(i);
    }
    // the refits are independent: in parallel, applied in candidate order
    let results: Vec<_> = chosen
        .par_iter()
        .map(|&i| {
            let mut own_notes = Vec::new();
            let r = refit_candidate(current, j0, rank0, held0, &candidates[i], th, ctx, &mut own_notes);
            (own_notes, r)
        })
        .collect();
    for (&i, (own_notes, r)) in chosen.iter().zip(results) {
        notes.extend(own_notes);
        let c = &mut candidates[i];
        match r {
            Ok((evidence, fit1, held1)) => {
                c.status = decide(&evidence, &fit1);
                c.refit = Some((evidence, fit1, held1));
            }
            Err(why) => c.status = CandidateStatus::Rejected(why),
        }
    }
}

/// σ̂ per axis of the saturated linear model: the residual of the current fit with the
/// current parameters' and every scored candidate's directions projected out, over its
/// degrees of freedom (`None` when fewer than a quarter of the residuals stay free).
fn saturated_sigma(
    current: &Fit,
    candidates: &[Candidate],
    j0: &faer::Mat<f64>,
    ctx: &Context<'_>,
) -> Option<f64> {
    let mut all: Vec<ParamId> = Vec::new();
    for c in candidates.iter().filter(|c| c.score.is_some()) {
        for p in &c.new_params {
            if !all.contains(p) {
                all.push(*p);
            }
        }
    }
    let w = ctx.options.identify.weights;
    let mut z = assemble_jacobian(&current.model, ctx.measurements, &ParamSet(all)).ok()?;
    weigh_rows(&mut z, ctx.measurements, &w);
    let stacked = faer::Mat::from_fn(j0.nrows(), j0.ncols() + z.ncols(), |r, c| {
        if c < j0.ncols() { j0[(r, c)] } else { z[(r, c - j0.ncols())] }
    });
    let (unit, _) = unit_columns(stacked.as_ref());
    let space = ColumnSpace::of(unit.as_ref()).ok()?;
    let n = j0.nrows();
    let dof = n.checked_sub(space.rank())?;
    if 4 * dof < n {
        return None;
    }
    let r = weighted_residual(current, ctx.measurements, &w);
    let rss: f64 = space.project_out_vec(&r).iter().map(|v| v * v).sum();
    Some((rss / dof as f64).sqrt())
}

/// Cosine between two candidates' changes of the held-out predictions (`e0 − e_with`) over the
/// points both predict: near 1 = they correct the same thing.
fn change_cosine(base: &CrossValidation, a: &CrossValidation, b: &CrossValidation) -> f64 {
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for ((e0, ea), eb) in base.errors.iter().zip(&a.errors).zip(&b.errors) {
        if let (Some(e0), Some(ea), Some(eb)) = (e0, ea, eb) {
            let (da, db) = (e0 - ea, e0 - eb);
            ab += da.dot(&db);
            aa += da.norm_squared();
            bb += db.norm_squared();
        }
    }
    if aa > 0.0 && bb > 0.0 { ab / (aa * bb).sqrt() } else { 0.0 }
}

/// Cosine above which two candidates' held-out prediction changes count as the same
/// correction (rivals).
pub const RIVAL_COSINE: f64 = 0.8;

/// Among the passing candidate `best` (largest held-out improvement) and its rivals — refitted
/// candidates whose held-out prediction changes point the same way (cosine ≥ [`RIVAL_COSINE`])
/// and whose held-out errors are not distinguishable from `best`'s (paired |z| < 2) — choose
/// the one that predicts the validation rows significantly better (paired z > 2), else the
/// simplest passing one (fewest fitted parameters), else `best`. Returns the chosen index and
/// the ambiguity, if there were rivals.
fn choose_among_rivals(
    candidates: &mut [Candidate],
    best: usize,
    held0: &CrossValidation,
    round: usize,
    ctx: &Context<'_>,
) -> Result<(usize, Option<Ambiguity>), DiscoveryError> {
    let Some((_, _, cv_best)) = candidates[best].refit.as_ref() else { return Ok((best, None)) };
    let mut rivals: Vec<usize> = Vec::new();
    for (i, c) in candidates.iter().enumerate() {
        let Some((e, f, cv)) = c.refit.as_ref() else { continue };
        if i == best || !f.converged || e.implausible.is_some() {
            continue;
        }
        let eligible = c.status == CandidateStatus::PassedNotBest
            || matches!(&c.status, CandidateStatus::Rejected(w) if w.starts_with(HELDOUT_NOT_LOWER))
                && e.heldout.z > 1.0;
        if !eligible {
            continue;
        }
        let versus = HeldOutComparison::new(&cv.errors, &cv_best.errors);
        if versus.z.abs() < 2.0 && change_cosine(held0, cv_best, cv) >= RIVAL_COSINE {
            rivals.push(i);
        }
    }
    if rivals.is_empty() {
        return Ok((best, None));
    }
    let mut chosen = best;
    let mut basis = "held-out";
    // validation rows: the one that generalises
    let validation = ctx.validation.filter(|v| !v.is_empty());
    let val_errors = |i: usize| -> Result<Option<Vec<Option<Vector3<f64>>>>, DiscoveryError> {
        match (validation, candidates[i].refit.as_ref()) {
            (Some(v), Some((_, f, _))) => Ok(Some(residuals(&f.model, v)?.into_iter().map(Some).collect())),
            _ => Ok(None),
        }
    };
    if let Some(vb) = val_errors(best)? {
        let mut best_z = 2.0;
        for &i in &rivals {
            if let Some(vi) = val_errors(i)? {
                let z = HeldOutComparison::new(&vb, &vi).z;
                if z > best_z {
                    best_z = z;
                    chosen = i;
                    basis = "validation";
                }
            }
        }
    }
    if chosen == best {
        // the data cannot tell: the simplest passing one — among the rivals the validation
        // rows do not show significantly worse than the best one (a simpler rival that
        // predicts them worse at z > 2 is not "indistinguishable")
        let size = |i: usize| candidates[i].refit.as_ref().map_or(usize::MAX, |r| r.0.fitted_params.len());
        let vb = val_errors(best)?;
        let mut eligible = Vec::new();
        for &i in &rivals {
            let worse = match (&vb, val_errors(i)?) {
                (Some(b), Some(vi)) => HeldOutComparison::new(&vi, b).z > 2.0,
                _ => false,
            };
            if !worse {
                eligible.push(i);
            }
        }
        if let Some(&simpler) = eligible
            .iter()
            .filter(|i| candidates[**i].status == CandidateStatus::PassedNotBest)
            .filter(|i| size(**i) < size(best))
            .min_by_key(|i| size(**i))
        {
            chosen = simpler;
            basis = "simpler";
        } else if eligible.is_empty() && !rivals.is_empty() {
            // the best one predicts the validation rows significantly better than every rival
            basis = "validation";
        }
    }
    let mut group: Vec<usize> = vec![best];
    group.extend(&rivals);
    let others: Vec<usize> = group.iter().copied().filter(|i| *i != chosen).collect();
    let vc = val_errors(chosen)?;
    let mut validation_z = Vec::new();
    for &i in &others {
        validation_z.push(match (&vc, val_errors(i)?) {
            (Some(c), Some(o)) => Some(HeldOutComparison::new(&o, c).z),
            _ => None,
        });
    }
    let label = |i: usize| candidates[i].spec.label();
    let names: Vec<String> = group.iter().map(|i| label(*i)).collect();
    let why = match basis {
        "validation" => format!("{} predicts the validation rows better", label(chosen)),
        "simpler" => format!("the data cannot tell them apart, {} has fewer parameters", label(chosen)),
        _ if validation.is_some() => {
            format!(
                "neither predicts the validation rows significantly better; kept {}, the larger held-out improvement",
                label(chosen)
            )
        }
        _ => format!(
            "kept {}, the larger held-out improvement (no validation rows to tell them apart)",
            label(chosen)
        ),
    };
    let sentence = format!("{}: indistinguishable on these data; {why}", names.join(" or "));
    let ambiguity = Ambiguity {
        round,
        chosen: label(chosen),
        rivals: others.iter().map(|i| label(*i)).collect(),
        basis: basis.to_string(),
        validation_z,
        sentence,
    };
    if chosen != best {
        candidates[best].status = CandidateStatus::PassedNotBest;
    }
    Ok((chosen, Some(ambiguity)))
}

/// Attaches the minimum detectable size to every borderline candidate: scored, not added, and
/// refitted or nominally significant at 1 % alone.
fn mark_borderline(
    candidates: &mut [Candidate],
    sigma: f64,
    ln_threshold: f64,
    n_screen: usize,
    total: usize,
) {
    for c in candidates.iter_mut() {
        let (Some(score), Some(d)) = (c.score, c.directions.as_ref()) else { continue };
        let refitted = c.refit.is_some();
        if matches!(c.status, CandidateStatus::Added | CandidateStatus::PassedNotBest)
            || !(refitted || score.ln_p_value < 0.01f64.ln())
        {
            continue;
        }
        let heldout = c.refit.as_ref().map(|(e, ..)| (e.heldout.z, e.z_required));
        c.detect = Some(
            Detectability::new(d.dof, d.novelty, sigma, n_screen, ln_threshold + c.ln_weight, DEFAULT_POWER)
                .with_observed(score.statistic, heldout, total),
        );
    }
}

/// Index of the passing candidate with the largest held-out improvement.
fn best_passing(candidates: &[Candidate]) -> Option<usize> {
    let key = |c: &Candidate| c.refit.as_ref().map_or(f64::NEG_INFINITY, |r| r.0.heldout.mean_reduction_mm2);
    candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.status == CandidateStatus::PassedNotBest)
        .max_by(|a, b| key(a.1).total_cmp(&key(b.1)))
        .map(|(i, _)| i)
}

/// Why nothing was added, naming the best-scored candidate.
fn nothing_added(candidates: &[Candidate], ln_threshold: f64) -> String {
    match candidates.iter().find(|c| c.score.is_some()) {
        Some(c) => {
            let why = match &c.status {
                CandidateStatus::Rejected(why) | CandidateStatus::DetectedNegligible(why) => why.clone(),
                _ => format!(
                    "screening log10 p = {:.1} above the threshold {:.1}",
                    c.score.map_or(0.0, |s| s.ln_p_value) / std::f64::consts::LN_10,
                    (ln_threshold + c.ln_weight) / std::f64::consts::LN_10
                ),
            };
            let power = c.detect.map(|d| format!("; {}", d.sentence())).unwrap_or_default();
            format!("nothing added: best candidate {} ({why}){power}", c.spec.label())
        }
        None => "nothing added: no candidate can be tested".to_string(),
    }
}

/// The record of an added candidate (its refit must be present).
fn added_effect(
    c: &Candidate,
    round: usize,
    current: &Fit,
    gap_before: &Gap,
    ctx: &Context<'_>,
) -> Result<(AddedEffect, Fit, CrossValidation), DiscoveryError> {
    let lost = || DiscoveryError::Numerical("internal: the added candidate has no refit or score".into());
    let (evidence, fit1, _) = c.refit.as_ref().ok_or_else(lost)?;
    let held1 = ctx.cross_validate(&fit1.model, &fit1.params, &ctx.all_folds);
    let gap_after = ctx.gap(&fit1.model, &held1)?;
    let added = added_record(c, evidence, fit1, round, current, gap_before, &gap_after, ctx)?;
    Ok((added, fit1.clone(), held1))
}

/// The record of candidate `c` added with the refit `fit1` (its own or a block's) and its
/// evidence; values and standard errors restricted to `c`'s parameters.
#[allow(clippy::too_many_arguments)]
fn added_record(
    c: &Candidate,
    evidence: &RefitEvidence,
    fit1: &Fit,
    round: usize,
    current: &Fit,
    gap_before: &Gap,
    gap_after: &Gap,
    ctx: &Context<'_>,
) -> Result<AddedEffect, DiscoveryError> {
    let lost = || DiscoveryError::Numerical("internal: the added candidate has no score".into());
    let score = c.score.ok_or_else(lost)?;
    let keys: Vec<String> = c.new_params.iter().map(|p| file_value(*p, 0.0).0).collect();
    let own = |m: &BTreeMap<String, f64>| -> BTreeMap<String, f64> {
        m.iter().filter(|(k, _)| keys.contains(k)).map(|(k, v)| (k.clone(), *v)).collect()
    };
    let plot = driver_plot(&c.spec, &fit1.model, ctx.measurements, &current.residuals, &fit1.residuals)?;
    Ok(AddedEffect {
        effect: c.spec.kind().name().to_string(),
        joint: c.spec.joint(),
        label: c.spec.label(),
        meaning: meaning(c.spec.kind()).to_string(),
        spec: c.spec,
        round,
        values: own(&evidence.values),
        std_errors: own(&evidence.std_errors),
        novelty: c.directions.as_ref().map_or(0.0, |d| d.novelty),
        score,
        comparison: evidence.comparison,
        heldout: evidence.heldout,
        confounding: evidence.confounding.clone(),
        gap_before_mm: gap_before.headline_mm(),
        gap_after_mm: gap_after.headline_mm(),
        gap_before: gap_before.clone(),
        gap_after: gap_after.clone(),
        plot,
    })
}

/// Whether a refitted candidate failed **only** the held-out z-test but still lowered the
/// held-out error by more than one standard error and changed the predictions by more than
/// the noise: a member of the round's block.
fn block_member(c: &Candidate) -> bool {
    let Some((e, f, _)) = &c.refit else { return false };
    matches!(&c.status, CandidateStatus::Rejected(why) if why.starts_with(HELDOUT_NOT_LOWER))
        && f.converged
        && e.implausible.is_none()
        && e.heldout.z > 1.0
        && e.heldout.change_rms_mm >= e.negligible_below_mm.max(e.floor_below_mm)
}

/// The block step of a round in which no candidate passed alone (module docs): the refitted
/// candidates that each lowered the held-out error by more than one standard error are
/// refitted **together** and confirmed together at `z_block` (one more test of the round).
/// Returns the members' indices and the block's evidence, fit and confirmation CV when the
/// block passes the decision rule.
#[allow(clippy::too_many_arguments)]
fn block_step(
    candidates: &[Candidate],
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &CrossValidation,
    z_block: f64,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Option<(Vec<usize>, RefitEvidence, Fit, CrossValidation)> {
    let members: Vec<usize> = (0..candidates.len()).filter(|i| block_member(&candidates[*i])).collect();
    if members.len() < 2 {
        return None;
    }
    let effects: Vec<(EffectSpec, Vec<ParamId>)> =
        members.iter().map(|i| (candidates[*i].spec, candidates[*i].new_params.clone())).collect();
    let th = Thresholds { ln_screen: f64::NAN, z_required: z_block, far_from_floor: false };
    match refit_effects(current, j0, rank0, held0, &effects, &th, ctx, notes) {
        Ok((evidence, fit1, held1)) => match decide(&evidence, &fit1) {
            CandidateStatus::PassedNotBest if validation_worse(current, &fit1, ctx) => {
                notes.push(format!("block not added: {VALIDATION_WORSE}"));
                None
            }
            CandidateStatus::PassedNotBest => Some((members, evidence, fit1, held1)),
            other => {
                let label = effects.iter().map(|(s, _)| s.label()).collect::<Vec<_>>().join(" + ");
                notes.push(format!("block {label} not added: {other:?}"));
                None
            }
        },
        Err(why) => {
            notes.push(format!("block refit failed: {why}"));
            None
        }
    }
}

/// `start` with the effects `specs` switched on and every parameter of `params` set to its
/// value in `values_from` (effects not in `specs` are absent, their parameters unfitted).
fn rebuild(
    start: &Model,
    specs: &[EffectSpec],
    values_from: &Model,
    params: &ParamSet,
) -> Result<Model, String> {
    let mut m = start.clone();
    for s in specs {
        m.enable_effect(*s).map_err(|e| e.to_string())?;
    }
    for p in params.iter() {
        let v = values_from.param(*p).map_err(|e| e.to_string())?;
        m.set_param(*p, v).map_err(|e| e.to_string())?;
    }
    Ok(m)
}

/// Backward check after an addition: every earlier added effect must still lower the held-out
/// error of the confirmation data by more than one standard error (and by more than the
/// noise) given the others; the weakest one that does not is removed and the model refitted,
/// until all pass. Returns the removed effects.
#[allow(clippy::too_many_arguments)]
fn backward_check(
    start: &Model,
    added: &mut Vec<AddedEffect>,
    fresh: usize,
    current: &mut Fit,
    round: usize,
    with_current: &CrossValidation,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<Vec<RemovedEffect>, DiscoveryError> {
    let mut removed = Vec::new();
    let mut recomputed: Option<CrossValidation> = None;
    // parameters of the effect(s) just added: an earlier effect can only have become redundant
    // if its parameters are correlated with these
    let newest: Vec<usize> = added
        .iter()
        .rev()
        .take(fresh)
        .flat_map(|a| a.spec.params())
        .filter_map(|p| current.params.index_of(p))
        .collect();
    // a single new effect was just confirmed alone and is not re-tested; every member of a
    // block is (each must still lower the held-out error given the others)
    let exempt = usize::from(fresh == 1);
    while added.len() >= 2 {
        let rank = current.params.len();
        let _ = fresh;
        let negligible_below_mm =
            ctx.options.negligible_factor * 3f64.sqrt() * ctx.noise_sigma(current, ctx.measurements, rank);
        // without a noise reference an effect that still lowers the held-out error by
        // `strong_z_factor` standard errors is kept whatever σ̂ says
        let strong = ctx.strong_z(1.0);
        // never below the physical floor of the noise (`DiscoverOptions::noise_floor_mm`)
        let floor_mm = ctx.options.negligible_factor * 3f64.sqrt() * ctx.options.noise_floor_mm;
        let with = recomputed.as_ref().unwrap_or(with_current);
        let mut weakest: Option<(usize, HeldOutComparison, Fit)> = None;
        // the newest effect was just confirmed; check the earlier ones
        let checked: Vec<usize> = (0..added.len() - exempt.min(added.len()))
            .filter(|&k| {
                let own_idx: Vec<usize> =
                    added[k].spec.params().iter().filter_map(|p| current.params.index_of(*p)).collect();
                recomputed.is_some()
                    || own_idx.iter().any(|a| {
                        newest.iter().any(|b| {
                            current
                                .correlation(*a, *b)
                                .is_none_or(|c| c.abs() >= ctx.options.redundancy_correlation)
                        })
                    })
            })
            .collect();
        // each check (a cross-validation without one effect, and its refit) is independent:
        // in parallel, the weakest chosen in effect order as before
        let current_ref: &Fit = current;
        let added_ref: &[AddedEffect] = added;
        let outcomes: Vec<Option<(HeldOutComparison, Option<Fit>)>> = checked
            .par_iter()
            .map(|&k| {
                let own: Vec<ParamId> = added_ref[k].spec.params();
                let params =
                    ParamSet(current_ref.params.iter().copied().filter(|p| !own.contains(p)).collect());
                let specs: Vec<EffectSpec> =
                    added_ref.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, a)| a.spec).collect();
                let base = rebuild(start, &specs, &current_ref.model, &params).ok()?;
                let without = ctx.cross_validate(&base, &params, &ctx.confirm_folds);
                let h = HeldOutComparison::new(&without.errors, &with.errors);
                let keep = h.z > 1.0
                    && h.change_rms_mm >= floor_mm
                    && (h.change_rms_mm >= negligible_below_mm || strong.is_some_and(|z| h.z >= z));
                if keep {
                    return Some((h, None));
                }
                Some((h, fit(&base, ctx.measurements, &params, &ctx.options.identify).ok()))
            })
            .collect();
        for (&k, outcome) in checked.iter().zip(outcomes) {
            let Some((h, refit)) = outcome else { continue };
            let keep = h.z > 1.0
                && h.change_rms_mm >= floor_mm
                && (h.change_rms_mm >= negligible_below_mm || strong.is_some_and(|z| h.z >= z));
            if keep {
                continue;
            }
            let Some(refit) = refit else {
                notes.push(format!("backward check: refit without {} failed; kept", added[k].label));
                continue;
            };
            if weakest.as_ref().is_none_or(|(_, w, _)| h.z < w.z) {
                weakest = Some((k, h, refit));
            }
        }
        let Some((k, h, refit)) = weakest else { break };
        let gone = added.remove(k);
        removed.push(RemovedEffect {
            label: gone.label,
            added_in_round: gone.round,
            removed_in_round: round,
            heldout: h,
        });
        *current = refit;
        recomputed = Some(ctx.cross_validate(&current.model, &current.params, &ctx.confirm_folds));
    }
    Ok(removed)
}

/// Predicted TCP uncertainty of the final model at the validation poses (or the measurement
/// poses), without and with the systematic CMM errors.
fn predicted_uncertainty(
    model: &Model,
    params: &ParamSet,
    ctx: &Context<'_>,
) -> Result<PredictedUncertainty, String> {
    let id = vatcal_identification::identify(model, ctx.measurements, params, &ctx.options.identify)
        .map_err(|e| e.to_string())?;
    let cmm = vatcal_identification::CmmUncertainty::new(
        &id,
        ctx.measurements,
        &ctx.options.identify.weights,
        ctx.options.cmm_sigma_mm,
    )
    .map_err(|e| e.to_string())?;
    let (label, poses) = match ctx.validation {
        Some(v) if !v.is_empty() => ("validation", v),
        _ => ("measurements", ctx.measurements),
    };
    let (mut stat, mut total) = (0.0, 0.0);
    for m in poses {
        stat += id.predicted_position_sigma(&m.q, m.tcp).map_err(|e| e.to_string())?.norm();
        total += cmm.total_sigma(&id, &m.q, m.tcp).map_err(|e| e.to_string())?.norm();
    }
    let n = poses.len().max(1) as f64;
    Ok(PredictedUncertainty {
        poses: label.to_string(),
        count: poses.len(),
        statistical_mean_mm: stat / n,
        with_cmm_mean_mm: total / n,
        cmm_sigma_mm: ctx.options.cmm_sigma_mm,
    })
}

/// Runs the discovery loop from `start` with the fitted parameter set `params` on
/// `measurements`; `validation` (e.g. tracker measurements) is used only to report the gap.
///
/// # Examples
/// A hidden once-per-revolution error of joint 5 (0.02°) that the paper's 34 parameters cannot
/// describe is found and named:
/// ```
/// use vatcal_core::effects::EffectSpec;
/// use vatcal_core::params::EffectParam;
/// use vatcal_core::{CellFile, ParamId, ParamSet};
/// use vatcal_discovery::{DiscoverOptions, discover};
/// use vatcal_kinematics::Model;
/// use vatcal_sim::truth::{ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses};
/// use vatcal_sim::truth::{synthetic_probe_measurements, synthetic_tracker_measurements};
///
/// let nominal = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let mut truth = perturbed_truth(&nominal, 31, &ErrorBudget::realistic());
/// let hidden = EffectSpec::JointCyclic { joint: 5, harmonic: 1 };
/// truth.enable_effect(hidden)?;
/// let a = 0.02f64.to_radians();
/// truth.set_param(ParamId::Effect(EffectParam::CyclicSin { joint: 5, harmonic: 1 }), 0.6 * a)?;
/// truth.set_param(ParamId::Effect(EffectParam::CyclicCos { joint: 5, harmonic: 1 }), 0.8 * a)?;
/// let starts = probe_start_poses(&nominal, 180, 132);
/// let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise::default(), 233);
/// let validation = synthetic_tracker_measurements(&truth, 250, 0.005, 334);
/// let d = discover(&nominal, &probe, &ParamSet::paper34(), Some(&validation), &DiscoverOptions::default())?;
/// assert_eq!(d.added_effects.len(), 1);
/// assert_eq!(d.added_effects[0].spec, hidden);
/// assert!(d.final_gap_mm < 0.5 * d.initial_gap_mm);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`DiscoveryError::NoMeasurements`]; [`DiscoveryError::Measurement`] when the model rejects a
/// measurement (unknown TCP or calibration position, naming its index);
/// [`DiscoveryError::Fit`] when the starting fit fails (e.g. data that cannot identify `params`);
/// [`DiscoveryError::Jacobian`] / [`DiscoveryError::Numerical`] for a Jacobian that cannot be
/// assembled or a failed factorisation.
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
    let mut notes = Vec::new();
    let mut options = options.clone();
    // separate σ for probe and tracker residuals (inverse-variance weights)
    let first = fit(start, measurements, params, &options.identify)?;
    let estimated = KindSigmas::estimate(measurements, &first.residuals, params.len());
    let kinds = start.joint_kinds().to_vec();
    let pure = if options.use_replicates {
        crate::noise::pure_error(measurements, &first.residuals, &kinds, options.replicate_tolerance)
    } else {
        None
    };
    let (reference, source) = noise_reference(pure.as_ref(), options.instrument_sigmas, measurements);
    let known = reference.filter(|k| k.probe_mm.is_some() && k.tracker_mm.is_some());
    let kind_sigmas = known.unwrap_or(estimated);
    let weighted =
        options.weight_by_kind && kind_sigmas.probe_mm.is_some() && kind_sigmas.tracker_mm.is_some();
    let mut current = if weighted {
        options.identify.weights = kind_sigmas.weights();
        notes.push(format!(
            "probe and tracker residuals weighted by their {} sigma ({:.4} / {:.4} mm per axis)",
            match (known.is_some(), source) {
                (true, NoiseSource::Replicates) => "replicates'",
                (true, _) => "instruments' known",
                (false, _) => "own estimated",
            },
            kind_sigmas.probe_mm.unwrap_or(0.0),
            kind_sigmas.tracker_mm.unwrap_or(0.0)
        ));
        fit(start, measurements, params, &options.identify)?
    } else {
        first
    };
    let start_residuals = current.residuals.clone();
    let is_screen = screening_split(measurements, options.screen_fraction, options.seed);
    let screen: Vec<Measurement> =
        measurements.iter().zip(&is_screen).filter(|(_, s)| **s).map(|(m, _)| *m).collect();
    let confirm_idx: Vec<usize> = (0..measurements.len()).filter(|i| !is_screen[*i]).collect();
    let confirm_ms: Vec<Measurement> = confirm_idx.iter().map(|i| measurements[*i]).collect();
    let k = options.folds.max(2);
    let mut confirm_folds = vec![None; measurements.len()];
    for (i, f) in confirm_idx.iter().zip(stratified_folds(&confirm_ms, k, options.seed.wrapping_add(1))) {
        confirm_folds[*i] = Some(f);
    }
    let all_folds = stratified_folds(measurements, k, options.seed).into_iter().map(Some).collect();
    let split = [screen.len(), confirm_ms.len()];
    let ctx = Context {
        measurements,
        validation,
        all_folds,
        confirm_folds,
        screen,
        options,
        reference,
        saturated_bits: std::sync::atomic::AtomicU64::new(f64::NAN.to_bits()),
        scale: chain_scale(start, measurements)?,
    };
    let options = &ctx.options;
    let mut skipped_folds = 0;
    let mut held_all = ctx.cross_validate(&current.model, &current.params, &ctx.all_folds);
    skipped_folds += held_all.skipped.len();
    notes.extend(held_all.skipped.iter().map(|s| format!("held-out gap: skipped {s}")));
    let initial_gap = ctx.gap(&current.model, &held_all)?;
    let mut gap = initial_gap.clone();
    let mut rounds = Vec::new();
    let mut added_effects: Vec<AddedEffect> = Vec::new();
    let mut removed_effects = Vec::new();
    let mut negligible_effects = Vec::new();
    let mut bound_hits = Vec::new();
    let mut ambiguities = Vec::new();
    // confirmation-fold CV of the current model, when already known
    let mut confirm_cv: Option<CrossValidation> = None;
    for index in 1..=options.max_rounds.max(1) {
        let spend = round_spending(index);
        let mut j0 = assemble_jacobian(&current.model, measurements, &current.params)
            .map_err(DiscoveryError::Jacobian)?;
        weigh_rows(&mut j0, measurements, &options.identify.weights);
        let rank0 = ColumnSpace::of(j0.as_ref())?.rank();
        let location = locate(&current.model, measurements, &current.residuals)?;
        let fit_summary = summarize_fit(&current, measurements, rank0, &ctx);
        // screening on S
        let screen_fit = match fit(&current.model, &ctx.screen, &current.params, &options.identify) {
            Ok(f) => f,
            Err(e) => {
                rounds.push(Round {
                    index,
                    fit: fit_summary,
                    location,
                    ln_threshold: f64::NAN,
                    sigma_saturated_mm: None,
                    z_required: f64::NAN,
                    gap_over_floor: None,
                    far_from_floor: false,
                    candidates: Vec::new(),
                    removed: Vec::new(),
                    decision: format!(
                        "nothing added: the fit to the {} screening measurements failed ({e}); more measurements are needed",
                        ctx.screen.len()
                    ),
                });
                break;
            }
        };
        let mut js = assemble_jacobian(&screen_fit.model, &ctx.screen, &current.params)
            .map_err(DiscoveryError::Jacobian)?;
        weigh_rows(&mut js, &ctx.screen, &options.identify.weights);
        let space = ColumnSpace::of(js.as_ref())?;
        let mut candidates = score_candidates(&current, &screen_fit, &space, &ctx, &mut notes)?;
        let m = candidates.iter().filter(|c| c.score.is_some()).count().max(1);
        let sigma_saturated = if ctx.reference.is_none() && options.saturated_noise {
            saturated_sigma(&current, &candidates, &j0, &ctx)
        } else {
            None
        };
        ctx.saturated_bits
            .store(sigma_saturated.unwrap_or(f64::NAN).to_bits(), std::sync::atomic::Ordering::Relaxed);
        let gap_over_floor = gap_over_floor(&held_all, sigma_saturated, rank0, &ctx);
        let th = Thresholds {
            ln_screen: (options.alpha * spend / m as f64).ln(),
            z_required: normal_upper_quantile(
                options.confirm_alpha * spend / options.max_refits.max(1) as f64,
            ),
            far_from_floor: gap_over_floor.is_some_and(|r| r > options.floor_gap_factor),
        };
        screening_weights(&mut candidates);
        let key = |c: &Candidate| c.weighted_ln_p().unwrap_or(f64::INFINITY);
        candidates.sort_by(|a, b| key(a).total_cmp(&key(b)));
        let any_screened = candidates
            .iter()
            .any(|c| c.weighted_ln_p().is_some_and(|p| th.far_from_floor || p < th.ln_screen));
        let cached = confirm_cv.take();
        let held0 = if !any_screened {
            CrossValidation { errors: vec![None; measurements.len()], skipped: Vec::new() }
        } else if let Some(h) = cached {
            h
        } else {
            let h = ctx.cross_validate(&current.model, &current.params, &ctx.confirm_folds);
            notes.extend(
                h.skipped.iter().map(|s| format!("round {index} confirmation baseline: skipped {s}")),
            );
            h
        };
        let mut fold_notes = Vec::new();
        confirm_screened(&mut candidates, &current, &j0, rank0, &held0, &th, &ctx, &mut fold_notes);
        skipped_folds += held0.skipped.len() + fold_notes.len();
        notes.extend(fold_notes);
        let sigma_screen = ctx.sigma_hat(&screen_fit, &ctx.screen, space.rank());
        mark_borderline(&mut candidates, sigma_screen, th.ln_screen, ctx.screen.len(), measurements.len());
        for c in &candidates {
            if let (CandidateStatus::Rejected(why), Some((e, ..))) = (&c.status, &c.refit)
                && let Some(reason) = why.strip_prefix(IMPLAUSIBLE)
            {
                bound_hits.push(BoundHit {
                    round: index,
                    effect: c.spec.kind().name().to_string(),
                    label: c.spec.label(),
                    reason: reason.to_string(),
                    heldout_z: e.heldout.z,
                    otherwise_passed: true,
                });
            }
            if let (CandidateStatus::DetectedNegligible(_), Some((e, ..))) = (&c.status, &c.refit) {
                negligible_effects.push(NegligibleEffect {
                    label: c.spec.label(),
                    round: index,
                    change_um: 1e3 * e.heldout.change_rms_mm,
                    heldout: e.heldout,
                });
            }
        }
        veto_on_validation(&mut candidates, &current, &ctx)?;
        let mut block: Option<Vec<usize>> = None;
        let mut ambiguity_line: Option<String> = None;
        let mut extra_added: Vec<AddedEffect> = Vec::new();
        let next = match best_passing(&candidates) {
            None if options.block_step => {
                let z_block = normal_upper_quantile(
                    options.confirm_alpha * spend / (options.max_refits.max(1) + 1) as f64,
                );
                match block_step(&candidates, &current, &j0, rank0, &held0, z_block, &ctx, &mut notes) {
                    Some((members, evidence, fit1, held1)) => {
                        let held_gap = ctx.cross_validate(&fit1.model, &fit1.params, &ctx.all_folds);
                        let gap_after = ctx.gap(&fit1.model, &held_gap)?;
                        let mut records = Vec::new();
                        for i in &members {
                            records.push(added_record(
                                &candidates[*i],
                                &evidence,
                                &fit1,
                                index,
                                &current,
                                &gap,
                                &gap_after,
                                &ctx,
                            )?);
                            candidates[*i].status = CandidateStatus::Added;
                        }
                        confirm_cv = Some(held1);
                        block = Some(members);
                        let rest = records.split_off(1);
                        extra_added = rest;
                        records.pop().map(|first| (first, fit1, held_gap))
                    }
                    None => None,
                }
            }
            None => None,
            Some(best) => {
                let (b, rivalry) = choose_among_rivals(&mut candidates, best, &held0, index, &ctx)?;
                if let Some(a) = rivalry {
                    ambiguity_line = Some(a.sentence.clone());
                    ambiguities.push(a);
                }
                if let Some(mut a) = candidates[b].refit.as_ref().and_then(|r| r.0.rival.clone()) {
                    a.round = index;
                    ambiguity_line = Some(match ambiguity_line.take() {
                        Some(l) => format!("{l}; {}", a.sentence),
                        None => a.sentence.clone(),
                    });
                    ambiguities.push(a);
                }
                candidates[b].status = CandidateStatus::Added;
                let added = added_effect(&candidates[b], index, &current, &gap, &ctx)?;
                // the confirmation CV of the refit is that of the new current model: reused by
                // the backward check and as the next round's baseline
                confirm_cv = candidates[b].refit.as_mut().map(|r| {
                    std::mem::replace(&mut r.2, CrossValidation { errors: Vec::new(), skipped: Vec::new() })
                });
                Some(added)
            }
        };
        let mut decision = match (&next, &block) {
            (Some((added, ..)), Some(members)) => {
                let labels: Vec<String> = members.iter().map(|i| candidates[*i].spec.label()).collect();
                format!(
                    "no candidate passed alone; added together as a block ({}): held-out RMS {:.4} -> {:.4} mm, z = {:.1}, predictions change {:.1} um; gap {:.4} -> {:.4} mm",
                    labels.join(", "),
                    added.heldout.rms_before_mm,
                    added.heldout.rms_after_mm,
                    added.heldout.z,
                    1e3 * added.heldout.change_rms_mm,
                    added.gap_before_mm,
                    added.gap_after_mm
                )
            }
            (Some((added, ..)), None) => match &ambiguity_line {
                Some(a) => format!("{}; {a}", added.summary_line()),
                None => added.summary_line(),
            },
            (None, _) => nothing_added(&candidates, th.ln_screen),
        };
        let mut removed = Vec::new();
        let done = next.is_none();
        if let Some((added, fit1, held1)) = next {
            skipped_folds += held1.skipped.len();
            gap = added.gap_after.clone();
            added_effects.push(added);
            let fresh = 1 + extra_added.len();
            added_effects.append(&mut extra_added);
            current = fit1;
            held_all = held1;
            let with = match confirm_cv.take() {
                Some(cv) => cv,
                None => ctx.cross_validate(&current.model, &current.params, &ctx.confirm_folds),
            };
            removed = backward_check(
                start,
                &mut added_effects,
                fresh,
                &mut current,
                index,
                &with,
                &ctx,
                &mut notes,
            )?;
            if removed.is_empty() {
                confirm_cv = Some(with);
            } else {
                held_all = ctx.cross_validate(&current.model, &current.params, &ctx.all_folds);
                gap = ctx.gap(&current.model, &held_all)?;
                let names: Vec<&str> = removed.iter().map(|r| r.label.as_str()).collect();
                decision.push_str(&format!("; backward check removed {}", names.join(", ")));
            }
        }
        rounds.push(Round {
            index,
            fit: fit_summary,
            location,
            ln_threshold: th.ln_screen,
            sigma_saturated_mm: sigma_saturated,
            z_required: th.z_required,
            gap_over_floor,
            far_from_floor: th.far_from_floor,
            candidates: candidates.into_iter().map(candidate_score).collect(),
            removed: removed.clone(),
            decision,
        });
        removed_effects.extend(removed);
        if done {
            break;
        }
    }
    let _ = &held_all;
    if skipped_folds > 0 {
        notes.push(format!(
            "{skipped_folds} cross-validation fold(s) skipped over the run (their fit failed)"
        ));
    }
    let noise = describe_noise(source, reference, pure, &start_residuals, params.len(), &current, &ctx);
    let uncertainty = match predicted_uncertainty(&current.model, &current.params, &ctx) {
        Ok(u) => Some(u),
        Err(e) => {
            notes.push(format!("predicted uncertainty not computed: {e}"));
            None
        }
    };
    Ok(Discovery {
        model: current.model,
        params: current.params,
        added_effects,
        removed_effects,
        negligible_effects,
        bound_hits,
        ambiguities,
        rounds,
        split,
        kind_sigmas,
        noise,
        skipped_folds,
        initial_gap_mm: initial_gap.headline_mm(),
        initial_gap,
        final_gap_mm: gap.headline_mm(),
        final_gap: gap,
        uncertainty,
        notes,
    })
}

/// The chain's size as the measurements see it: each joint's largest gravity torque, bending
/// moment and lever arm over the poses (plausibility bounds, [`vatcal_core::canonical::bounds`]).
fn chain_scale(model: &Model, ms: &[Measurement]) -> Result<ChainScale, DiscoveryError> {
    let pose = PoseData::of(model, ms)?;
    let mut scale = ChainScale {
        max_torque_nm: [0.0; vatcal_core::MAX_JOINTS],
        max_lever_mm: [0.0; vatcal_core::MAX_JOINTS],
        max_bending_nm: [0.0; vatcal_core::MAX_JOINTS],
    };
    for m in ms {
        for (b, v) in scale.max_bending_nm.iter_mut().zip(model.link_bending_moments(&m.q)) {
            *b = b.max(v[0].hypot(v[1]));
        }
    }
    for t in &pose.torques {
        for (m, v) in scale.max_torque_nm.iter_mut().zip(t) {
            *m = m.max(v.abs());
        }
    }
    for d in pose.joint_directions.iter().flatten() {
        for (m, v) in scale.max_lever_mm.iter_mut().zip(d) {
            *m = m.max(v.norm());
        }
    }
    Ok(scale)
}

/// The noise reference per kind: the replicates' pure error where the data has enough of it,
/// else the instruments' stated noise; `None` unless every kind in the data has one.
fn noise_reference(
    pure: Option<&crate::noise::PureError>,
    stated: Option<KindSigmas>,
    ms: &[Measurement],
) -> (Option<KindSigmas>, NoiseSource) {
    let from_pure = pure.map(|p| p.sigmas).unwrap_or_default();
    let stated = stated.unwrap_or_default();
    let merged = KindSigmas {
        probe_mm: from_pure.probe_mm.or(stated.probe_mm),
        tracker_mm: from_pure.tracker_mm.or(stated.tracker_mm),
    };
    if !crate::noise::covers(&merged, ms) {
        return (None, NoiseSource::Estimated);
    }
    let used_pure = from_pure.probe_mm.is_some() || from_pure.tracker_mm.is_some();
    (Some(merged), if used_pure { NoiseSource::Replicates } else { NoiseSource::Instrument })
}

/// The report's account of the noise reference (lack-of-fit tests of the starting and the
/// final fit when the data has replicates).
fn describe_noise(
    source: NoiseSource,
    reference: Option<KindSigmas>,
    pure: Option<crate::noise::PureError>,
    start_residuals: &[Vector3<f64>],
    start_params: usize,
    last: &Fit,
    ctx: &Context<'_>,
) -> NoiseReference {
    use crate::noise::{lack_of_fit, lack_of_fit_sentence};
    let opts = &ctx.options;
    let ms = ctx.measurements;
    let kinds = last.model.joint_kinds().to_vec();
    let w = opts.identify.weights;
    let lof = |r: &[Vector3<f64>], p: usize| {
        lack_of_fit(ms, r, p, &kinds, opts.replicate_tolerance, |m| kind_weight(m, &w))
    };
    let lack_of_fit_start = lof(start_residuals, start_params);
    let lack_of_fit_final = lof(&last.residuals, last.params.len());
    let um = |s: Option<f64>| s.map_or("-".to_string(), |v| format!("{:.1} um", 1e3 * v));
    let sigmas = reference.unwrap_or_default();
    let per_kind = format!("probe {} / tracker {} per axis", um(sigmas.probe_mm), um(sigmas.tracker_mm));
    let mut text = match (source, &pure) {
        (NoiseSource::Replicates, Some(p)) => format!(
            "noise reference: pure error of {} replicate groups ({} measurements, {} dof): {per_kind}. It holds no model error, so the size rule (prediction change above sqrt(3) sigma) does not shrink while effects are missing.",
            p.groups, p.replicated, p.dof
        ),
        (NoiseSource::Instrument, _) | (NoiseSource::Replicates, None) => format!(
            "noise reference: the instruments' stated noise ({}): {per_kind}. The size rule compares prediction changes with sqrt(3) sigma of it; if the statement is too low, small real effects are added, if too high, they are called negligible.",
            opts.instrument_noise_origin.as_deref().unwrap_or("given by the caller")
        ),
        (NoiseSource::Estimated, _) => format!(
            "noise reference: none (no replicates in the data, no instrument noise recorded in the file or given): the size rule compares with sigma-hat, which contains the effects still missing: the lower of the refit's and that of the round's saturated linear model (every scored candidate's directions projected out, so only what no candidate describes is left in it), and the rule is waived for an effect whose held-out improvement is at least {} times the round's z. Effects that are real but only moderately significant may be called negligible; record the noise in the file (`# vatcal-noise: probe_sigma_mm=...`), repeat some poses, or pass --probe-sigma-mm / --tracker-sigma-mm.",
            opts.strong_z_factor
        ),
    };
    if let Some(p) = &pure
        && source != NoiseSource::Replicates
    {
        text.push_str(&format!(
            " ({} replicate groups with {} dof were found, too few to estimate every kind's sigma.)",
            p.groups, p.dof
        ));
    }
    if let (Some(stated), NoiseSource::Replicates) = (opts.instrument_sigmas, source) {
        text.push_str(&format!(
            " The stated instrument noise (probe {} / tracker {}) was not used: the replicates measure it on these data.",
            um(stated.probe_mm),
            um(stated.tracker_mm)
        ));
    }
    let floor = opts.noise_floor_mm;
    if floor > 0.0 {
        let below: Vec<&str> = [("probe", sigmas.probe_mm), ("tracker", sigmas.tracker_mm)]
            .into_iter()
            .filter(|(_, v)| v.is_some_and(|v| v < floor))
            .map(|(k, _)| k)
            .collect();
        text.push_str(&format!(
            " Physical floor: {:.2} um per axis (--noise-floor-mm): no reference, stated or estimated, is taken below it, and no effect whose predictions change by less than sqrt(3) times it is added{}.",
            1e3 * floor,
            if below.is_empty() {
                String::new()
            } else {
                format!(" (the {} reference is below it: the floor is used)", below.join(" and "))
            }
        ));
    }
    if let Some(l) = &lack_of_fit_start {
        text.push_str(&format!(" Starting model: {}.", lack_of_fit_sentence(l)));
    }
    if let Some(l) = &lack_of_fit_final {
        text.push_str(&format!(" Final model: {}.", lack_of_fit_sentence(l)));
    }
    NoiseReference {
        source,
        floor_mm: opts.noise_floor_mm,
        sigmas,
        pure_error: pure,
        lack_of_fit_start,
        lack_of_fit_final,
        stated: opts.instrument_sigmas,
        explanation: text,
    }
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
        detectability: c.detect,
        status: c.status,
    }
}

#[cfg(test)]
mod tests {
    use super::round_spending;

    #[test]
    fn round_spending_sums_to_at_most_one_and_decreases() {
        let total: f64 = (1..=100_000).map(round_spending).sum();
        assert!(total < 1.0 && total > 0.9999, "{total}");
        assert!((1..50).all(|r| round_spending(r + 1) < round_spending(r)));
        assert!((round_spending(1) - 6.0 / std::f64::consts::PI.powi(2)).abs() < 1e-15);
    }

    fn candidate(spec: vatcal_core::effects::EffectSpec, scored: bool) -> super::Candidate {
        super::Candidate {
            spec,
            new_params: Vec::new(),
            directions: None,
            score: scored.then_some(crate::linear::ScoreTest { statistic: 1.0, dof: 1, ln_p_value: -3.0 }),
            status: super::CandidateStatus::NotSignificant,
            refit: None,
            detect: None,
            ln_weight: f64::NAN,
        }
    }

    /// Weighted Bonferroni: the weights of the scored candidates sum to their number, the
    /// generic ones share `GENERIC_SCREENING_SHARE` of it, and a round with one class only
    /// weighs every candidate 1.
    #[test]
    fn screening_weights_split_the_level_between_physical_and_generic_effects() {
        use vatcal_core::effects::EffectSpec;
        use vatcal_core::effects::link_out_of_plane::{Component, spec};
        let mut cs = vec![
            candidate(EffectSpec::JointScale { joint: 3 }, true),
            candidate(EffectSpec::ToolFrame, true),
            candidate(EffectSpec::JointBacklash { joint: 2 }, true),
            candidate(spec(4, Component::Axial), true),
            candidate(spec(5, Component::TiltX), false),
        ];
        super::screening_weights(&mut cs);
        let w: Vec<f64> = cs.iter().filter(|c| c.score.is_some()).map(|c| c.ln_weight.exp()).collect();
        assert!((w.iter().sum::<f64>() - 4.0).abs() < 1e-12, "{w:?}");
        assert!((w[3] - super::GENERIC_SCREENING_SHARE * 4.0).abs() < 1e-12, "{w:?}");
        assert!((w[0] - (1.0 - super::GENERIC_SCREENING_SHARE) * 4.0 / 3.0).abs() < 1e-12, "{w:?}");
        let mut physical =
            vec![candidate(EffectSpec::ToolFrame, true), candidate(EffectSpec::GuideScale, true)];
        super::screening_weights(&mut physical);
        assert!(physical.iter().all(|c| c.ln_weight == 0.0));
    }
}
