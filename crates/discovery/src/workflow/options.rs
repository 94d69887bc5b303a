//! The settings of [`discover`](crate::workflow::discover)(super::discover).

use std::collections::BTreeMap;

use vatcal_identification::{IdentifyOptions, KindSigmas};

use crate::noise::ReplicateTolerance;

/// Settings of [`discover`](crate::workflow::discover).
#[derive(Debug, Clone)]
pub struct DiscoverOptions {
    /// family-wise false-alarm probability of the screening over **all** rounds: round r
    /// (1-based) spends `alpha·s_r` ([`round_spending`](crate::workflow::round_spending)), split over its m scored candidates
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
    /// when no candidate passes alone and no block passes, run the **joint search**
    /// (`workflow/joint.rs`): every scored candidate's parameters fitted together (ridge toward
    /// zero with each parameter's typical scale as prior width) on the screening part, the
    /// candidates ranked by the share of the prediction they carry, the number kept chosen by
    /// cross-validation on the screening part, and the chosen ones confirmed together on the
    /// confirmation part (one more test of the round, at `confirm_alpha·s_r/(max_refits + 2)`)
    /// with the size rule and plausibility applied to each member
    pub joint_search: bool,
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
    /// [`Round::sigma_saturated_mm`](crate::workflow::Round::sigma_saturated_mm)), which holds only what no candidate can describe
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
    /// estimate ([`Round::gap_over_floor`](crate::workflow::Round::gap_over_floor)): such a round confirms its best-scored candidates
    /// even when none passes the screening threshold and waives the size rule for the ones
    /// that pass the held-out test (a model that far from the noise is missing something
    /// that matters); `f64::INFINITY` switches this off
    pub floor_gap_factor: f64,
    /// let the validation rows take part in decisions (default **off**: they only report the
    /// gap, an honest estimate because nothing was chosen on them). On, they choose among
    /// near-equivalent rivals (the one predicting them significantly better) and, with
    /// [`validation_veto`](Self::validation_veto), refuse additions that make them worse.
    /// Measured on the frozen benchmark (generator v3, seeds 8128, 21, 9001, 60606; 400
    /// cases), deciding on them named 324 instead of 334 of 347 effects with their driver and
    /// 275 instead of 288 of 308 exactly, with 378 instead of 381 cases within 1.3× the floor:
    /// a choice made on the rows "which predicts better now" favours the look-alike that also
    /// soaks up effects still missing (`docs/discovery.md`)
    pub validation_decides: bool,
    /// with [`validation_decides`](Self::validation_decides): refuse an addition that makes
    /// the validation rows' error significantly larger (paired z below
    /// `-`[`VETO_Z`](crate::workflow::VETO_Z))
    pub validation_veto: bool,
    /// when a round adds nothing, re-examine earlier additions against that round's
    /// look-alikes (including candidates the model absorbed) and swap one or two in for one
    /// or two additions when they predict the held-out points significantly better, or, with
    /// fewer parameters, no worse by more than one standard error (the swap check,
    /// `workflow/swap.rs`; `vatcal discover --no-lookalike-swap` switches it off)
    pub lookalike_swap: bool,
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
            joint_search: true,
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
            validation_decides: false,
            validation_veto: true,
            lookalike_swap: true,
            noise_floor_mm: 0.001,
        }
    }
}
