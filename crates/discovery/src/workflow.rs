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
//! 5. when no candidate passes alone (nor, with the block step, the block of those that each
//!    helped), the **joint search**: every scored candidate considered together by a
//!    cross-validated forward path of ridge fits on the screening part (`joint`), the chosen
//!    set refitted and confirmed together on the confirmation part, each member held to the
//!    size rule and the plausibility bounds on its own (`joint_add`); the backward check then
//!    re-tests every effect;
//! 6. repeat until nothing is added.
//!
//! A cross-validation fold whose fit fails (ill-conditioned, not converged) is skipped,
//! counted and reported; it does not abort the run.
//!
//! One file per decision: `screen` (candidates, scores, levels),
//! `confirm` (refits on the held-out confirmation data), `decide` (the decision rule),
//! `size` (the noise reference and the size rule), `plausible` (bounds), `rivals`
//! (look-alikes), `veto` (the validation rows), `block` (the block step), `joint` and
//! `joint_add` (the joint search's selection and confirmation), `backward` (the
//! backward check), `stop` (the keep-going rule), `borderline` (the glue to
//! [`crate::propose`]), `record` (an added effect's record); this file only sequences them.

mod backward;
mod block;
mod borderline;
mod candidate;
mod confirm;
mod context;
mod decide;
mod joint;
mod joint_add;
mod options;
mod plausible;
mod record;
mod report;
mod rivals;
mod screen;
mod setup;
mod size;
mod stop;
mod swap;
mod veto;

pub use options::DiscoverOptions;
pub use report::{
    AddedEffect, Ambiguity, BoundHit, CandidateScore, CandidateStatus, Confounding, Discovery, DriverPlot,
    FitSummary, Gap, NegligibleEffect, PredictedUncertainty, RefitEvidence, RemovedEffect, Round, file_value,
};
pub use rivals::{RIVAL_CORRELATION, RIVAL_COSINE};
pub use screen::{GENERIC_SCREENING_SHARE, MAX_PROPOSED_HARMONIC, candidates, round_spending};
pub use veto::VETO_Z;

use vatcal_core::effects::EffectSpec;
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::assemble_jacobian;

use self::backward::backward_check;
use self::block::add_block;
use self::borderline::mark_borderline;
use self::candidate::{Candidate, candidate_score};
use self::confirm::confirm_screened;
use self::context::{Context, CrossValidation, summarize_fit, weigh_rows};
use self::joint_add::add_joint;
use self::record::{
    Addition, added_effect, decision, findings, predicted_uncertainty, push_with_prerequisites,
};
use self::rivals::choose_among_rivals;
use self::screen::{Thresholds, rank_candidates, score_candidates};
use self::setup::{Setup, prepare};
use self::size::{describe_noise, saturated_sigma};
use self::stop::{best_passing, gap_over_floor};
use self::swap::{SwapCheck, swap_check};
use self::veto::veto_on_validation;
use crate::DiscoveryError;
use crate::fit::{Fit, fit};
use crate::linear::ColumnSpace;
use crate::location::{DriverSummary, locate};

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
    let setup = prepare(start, measurements, params, validation, options)?;
    let mut run = Run::new(&setup)?;
    for index in 1..=setup.ctx.options.max_rounds.max(1) {
        if !run.round(index, start, &setup.ctx)? {
            break;
        }
    }
    Ok(run.finish(setup, params))
}

/// What the loop has found so far.
struct Run {
    /// the current model's fit to all data
    current: Fit,
    /// its all-data cross-validation
    held_all: CrossValidation,
    initial_gap: Gap,
    gap: Gap,
    rounds: Vec<Round>,
    added: Vec<AddedEffect>,
    removed: Vec<RemovedEffect>,
    negligible: Vec<NegligibleEffect>,
    bound_hits: Vec<BoundHit>,
    ambiguities: Vec<Ambiguity>,
    /// confirmation-fold CV of the current model, when already known
    confirm_cv: Option<CrossValidation>,
    /// effects a look-alike replaced (never tried again)
    swapped_out: Vec<EffectSpec>,
    skipped_folds: usize,
    notes: Vec<String>,
}

/// The current model at the start of a round: its weighted Jacobian on all data and rank,
/// the location of its residuals and the summary of its fit.
struct Base {
    j0: faer::Mat<f64>,
    rank0: usize,
    location: Vec<DriverSummary>,
    fit: FitSummary,
}

/// The screening of a round: the candidates (best score first) and the round's thresholds.
struct Screened {
    candidates: Vec<Candidate>,
    th: Thresholds,
    sigma_saturated: Option<f64>,
    gap_over_floor: Option<f64>,
    /// σ̂ of the screening fit
    sigma_screen: f64,
}

impl Run {
    /// The starting model's all-data cross-validation and gap.
    fn new(setup: &Setup<'_>) -> Result<Self, DiscoveryError> {
        let ctx = &setup.ctx;
        let current = setup.current.clone();
        let mut notes = setup.notes.clone();
        let held_all = ctx.cross_validate(&current.model, &current.params, &ctx.all_folds);
        notes.extend(held_all.skipped.iter().map(|s| format!("held-out gap: skipped {s}")));
        let initial_gap = ctx.gap(&current.model, &held_all)?;
        Ok(Self {
            skipped_folds: held_all.skipped.len(),
            current,
            held_all,
            gap: initial_gap.clone(),
            initial_gap,
            rounds: Vec::new(),
            added: Vec::new(),
            removed: Vec::new(),
            negligible: Vec::new(),
            bound_hits: Vec::new(),
            ambiguities: Vec::new(),
            confirm_cv: None,
            swapped_out: Vec::new(),
            notes,
        })
    }

    /// One round: screen, confirm, choose, add, check backward. Returns whether the loop
    /// goes on (something was added).
    fn round(&mut self, index: usize, start: &Model, ctx: &Context<'_>) -> Result<bool, DiscoveryError> {
        let base = self.base(ctx)?;
        let screen_fit =
            match fit(&self.current.model, &ctx.screen, &self.current.params, &ctx.options.identify) {
                Ok(f) => f,
                Err(e) => {
                    self.rounds.push(failed_round(index, base, &e, ctx));
                    return Ok(false);
                }
            };
        let mut s = self.screen(index, &screen_fit, &base, ctx)?;
        let mut held0 = self.confirmation_baseline(index, &s, ctx);
        self.confirm(index, &mut s, &base, &held0, ctx)?;
        let next = self.choose(index, &mut s.candidates, &base, &mut held0, ctx)?;
        let mut decision = decision(next.as_ref(), &s.candidates, s.th.ln_screen);
        let mut done = next.is_none();
        let mut removed = match next {
            Some(next) => self.apply(next, index, start, ctx, &mut decision)?,
            None => Vec::new(),
        };
        if done && ctx.options.lookalike_swap {
            let swap = self.swap(index, start, &mut s.candidates, (&mut held0, &base.j0), ctx)?;
            if let Some((sentence, gone)) = swap {
                decision = sentence;
                removed.extend(gone);
                done = false;
            }
        }
        self.rounds.push(Round {
            index,
            fit: base.fit,
            location: base.location,
            ln_threshold: s.th.ln_screen,
            sigma_saturated_mm: s.sigma_saturated,
            z_required: s.th.z_required,
            gap_over_floor: s.gap_over_floor,
            far_from_floor: s.th.far_from_floor,
            candidates: s.candidates.into_iter().map(candidate_score).collect(),
            removed: removed.clone(),
            decision,
        });
        self.removed.extend(removed);
        Ok(!done)
    }

    /// The current model's weighted Jacobian, rank, residual location and fit summary.
    fn base(&self, ctx: &Context<'_>) -> Result<Base, DiscoveryError> {
        let (current, measurements) = (&self.current, ctx.measurements);
        let mut j0 = assemble_jacobian(&current.model, measurements, &current.params)
            .map_err(DiscoveryError::Jacobian)?;
        weigh_rows(&mut j0, measurements, &ctx.options.identify.weights);
        let rank0 = ColumnSpace::of(j0.as_ref())?.rank();
        let location = locate(&current.model, measurements, &current.residuals)?;
        let fit = summarize_fit(current, measurements, rank0, ctx);
        Ok(Base { j0, rank0, location, fit })
    }

    /// Screening on S: every candidate scored, the saturated σ̂, the gap over its floor, the
    /// round's thresholds; candidates sorted best first.
    fn screen(
        &mut self,
        index: usize,
        screen_fit: &Fit,
        base: &Base,
        ctx: &Context<'_>,
    ) -> Result<Screened, DiscoveryError> {
        let options = &ctx.options;
        let mut js = assemble_jacobian(&screen_fit.model, &ctx.screen, &self.current.params)
            .map_err(DiscoveryError::Jacobian)?;
        weigh_rows(&mut js, &ctx.screen, &options.identify.weights);
        let space = ColumnSpace::of(js.as_ref())?;
        let mut candidates = score_candidates(&self.current, screen_fit, &space, ctx, &mut self.notes)?;
        let m = candidates.iter().filter(|c| c.score.is_some()).count().max(1);
        let sigma_saturated = if ctx.reference.is_none() && options.saturated_noise {
            saturated_sigma(&self.current, &candidates, &base.j0, ctx)
        } else {
            None
        };
        ctx.saturated_bits
            .store(sigma_saturated.unwrap_or(f64::NAN).to_bits(), std::sync::atomic::Ordering::Relaxed);
        let gap_over_floor = gap_over_floor(&self.held_all, sigma_saturated, base.rank0, ctx);
        let th = Thresholds::new(options, round_spending(index), m, gap_over_floor);
        rank_candidates(&mut candidates);
        let sigma_screen = ctx.sigma_hat(screen_fit, &ctx.screen, space.rank());
        Ok(Screened { candidates, th, sigma_saturated, gap_over_floor, sigma_screen })
    }

    /// The current model's confirmation-fold cross-validation (cached from the last round when
    /// known; empty when no candidate is to be confirmed).
    fn confirmation_baseline(&mut self, index: usize, s: &Screened, ctx: &Context<'_>) -> CrossValidation {
        let cached = self.confirm_cv.take();
        if !s.th.any_screened(&s.candidates) {
            return CrossValidation { errors: vec![None; ctx.measurements.len()], skipped: Vec::new() };
        }
        if let Some(h) = cached {
            return h;
        }
        let h = ctx.cross_validate(&self.current.model, &self.current.params, &ctx.confirm_folds);
        self.notes
            .extend(h.skipped.iter().map(|s| format!("round {index} confirmation baseline: skipped {s}")));
        h
    }

    /// Confirmation on C of the screened candidates, the borderline ones' detectability, the
    /// round's bound hits and negligible effects, and the validation veto.
    fn confirm(
        &mut self,
        index: usize,
        s: &mut Screened,
        base: &Base,
        held0: &CrossValidation,
        ctx: &Context<'_>,
    ) -> Result<(), DiscoveryError> {
        let candidates = &mut s.candidates;
        let mut fold_notes = Vec::new();
        confirm_screened(candidates, &self.current, &base.j0, base.rank0, held0, &s.th, ctx, &mut fold_notes);
        self.skipped_folds += held0.skipped.len() + fold_notes.len();
        self.notes.extend(fold_notes);
        let (n_screen, total) = (ctx.screen.len(), ctx.measurements.len());
        mark_borderline(candidates, s.sigma_screen, s.th.ln_screen, n_screen, total);
        let (bound_hits, negligible) = findings(candidates, index);
        self.bound_hits.extend(bound_hits);
        self.negligible.extend(negligible);
        veto_on_validation(candidates, &self.current, ctx)
    }

    /// The round's addition: the best passing candidate (or a look-alike of it), else, with
    /// the block step on, the block of candidates that helped, else, with the joint search on,
    /// the set the joint search chose; `None` when nothing passes.
    fn choose(
        &mut self,
        index: usize,
        candidates: &mut [Candidate],
        base: &Base,
        held0: &mut CrossValidation,
        ctx: &Context<'_>,
    ) -> Result<Option<Addition>, DiscoveryError> {
        if let Some(best) = best_passing(candidates) {
            return self.add_best(index, best, candidates, held0, ctx).map(Some);
        }
        let (current, spend) = (&self.current, round_spending(index));
        let (j0, rank0) = (&base.j0, base.rank0);
        let mut found = None;
        if ctx.options.block_step {
            let at = (index, spend);
            found = add_block(candidates, current, j0, rank0, held0, at, &self.gap, ctx, &mut self.notes)?;
        }
        if found.is_none() && ctx.options.joint_search {
            let at = (index, spend);
            found = add_joint(candidates, current, (j0, rank0), held0, at, &self.gap, ctx, &mut self.notes)?;
        }
        Ok(found.map(|(addition, held1)| {
            self.confirm_cv = Some(held1);
            addition
        }))
    }

    /// Adds the passing candidate `best` or the look-alike chosen among its rivals.
    fn add_best(
        &mut self,
        index: usize,
        best: usize,
        candidates: &mut [Candidate],
        held0: &CrossValidation,
        ctx: &Context<'_>,
    ) -> Result<Addition, DiscoveryError> {
        let (b, rivalry) = choose_among_rivals(candidates, best, held0, index, ctx)?;
        let mut ambiguity_line = None;
        if let Some(a) = rivalry {
            ambiguity_line = Some(a.sentence.clone());
            self.ambiguities.push(a);
        }
        if let Some(mut a) = candidates[b].refit.as_ref().and_then(|r| r.0.rival.clone()) {
            a.round = index;
            ambiguity_line = Some(match ambiguity_line.take() {
                Some(l) => format!("{l}; {}", a.sentence),
                None => a.sentence.clone(),
            });
            self.ambiguities.push(a);
        }
        candidates[b].status = CandidateStatus::Added;
        let (added, fit1, held_all) = added_effect(&candidates[b], index, &self.current, &self.gap, ctx)?;
        // the confirmation CV of the refit is that of the new current model: reused by the
        // backward check and as the next round's baseline
        self.confirm_cv = candidates[b].refit.as_mut().map(|r| {
            std::mem::replace(&mut r.2, CrossValidation { errors: Vec::new(), skipped: Vec::new() })
        });
        let mut records = Vec::new();
        push_with_prerequisites(&mut records, added, &candidates[b], &fit1);
        let added = records.remove(0);
        Ok(Addition {
            added,
            extra: records,
            fit: fit1,
            held_all,
            block: None,
            ambiguity_line,
            joint_line: None,
        })
    }

    /// Makes `next` the current model and runs the backward check; returns the effects it
    /// removed (named in `decision`).
    fn apply(
        &mut self,
        next: Addition,
        index: usize,
        start: &Model,
        ctx: &Context<'_>,
        decision: &mut String,
    ) -> Result<Vec<RemovedEffect>, DiscoveryError> {
        self.skipped_folds += next.held_all.skipped.len();
        self.gap = next.added.gap_after.clone();
        self.added.push(next.added);
        let fresh = 1 + next.extra.len();
        self.added.extend(next.extra);
        self.current = next.fit;
        self.held_all = next.held_all;
        let with = match self.confirm_cv.take() {
            Some(cv) => cv,
            None => ctx.cross_validate(&self.current.model, &self.current.params, &ctx.confirm_folds),
        };
        let (added, current, notes) = (&mut self.added, &mut self.current, &mut self.notes);
        let removed = backward_check(start, added, fresh, current, index, &with, ctx, notes)?;
        if removed.is_empty() {
            self.confirm_cv = Some(with);
        } else {
            self.held_all = ctx.cross_validate(&self.current.model, &self.current.params, &ctx.all_folds);
            self.gap = ctx.gap(&self.current.model, &self.held_all)?;
            let names: Vec<&str> = removed.iter().map(|r| r.label.as_str()).collect();
            decision.push_str(&format!("; backward check removed {}", names.join(", ")));
        }
        Ok(removed)
    }

    /// The swap check of a round that added nothing (`baseline`: the current model's
    /// confirmation CV and weighted Jacobian): an earlier addition replaced by a look-alike
    /// that predicts the held-out points significantly better. Returns the round's
    /// decision and the effect swapped out.
    fn swap(
        &mut self,
        index: usize,
        start: &Model,
        candidates: &mut [Candidate],
        baseline: (&mut CrossValidation, &faer::Mat<f64>),
        ctx: &Context<'_>,
    ) -> Result<Option<(String, Vec<RemovedEffect>)>, DiscoveryError> {
        let (added, current, out) = (&mut self.added, &mut self.current, &mut self.swapped_out);
        let swap = match swap_check(start, added, current, candidates, baseline, index, out, ctx)? {
            SwapCheck::Made(swap) => swap,
            SwapCheck::Kept(kept) => {
                // the search ends here: say why each look-alike tried did not replace its rival
                self.notes.extend(kept.into_iter().map(|k| format!("round {index}, swap check: {k}")));
                return Ok(None);
            }
        };
        self.held_all = ctx.cross_validate(&self.current.model, &self.current.params, &ctx.all_folds);
        self.gap = ctx.gap(&self.current.model, &self.held_all)?;
        self.confirm_cv = None;
        self.ambiguities.push(swap.ambiguity);
        Ok(Some((swap.sentence, swap.removed)))
    }

    /// The report: the noise reference's account, the final model's predicted uncertainty.
    fn finish(mut self, setup: Setup<'_>, params: &ParamSet) -> Discovery {
        let ctx = &setup.ctx;
        if self.skipped_folds > 0 {
            self.notes.push(format!(
                "{} cross-validation fold(s) skipped over the run (their fit failed)",
                self.skipped_folds
            ));
        }
        let (current, start_residuals) = (&self.current, &setup.start_residuals);
        let noise = describe_noise(
            setup.source,
            ctx.reference,
            setup.pure,
            start_residuals,
            params.len(),
            current,
            ctx,
        );
        let uncertainty = match predicted_uncertainty(&current.model, &current.params, ctx) {
            Ok(u) => Some(u),
            Err(e) => {
                self.notes.push(format!("predicted uncertainty not computed: {e}"));
                None
            }
        };
        Discovery {
            model: self.current.model,
            params: self.current.params,
            added_effects: self.added,
            removed_effects: self.removed,
            negligible_effects: self.negligible,
            bound_hits: self.bound_hits,
            ambiguities: self.ambiguities,
            rounds: self.rounds,
            split: setup.split,
            kind_sigmas: setup.kind_sigmas,
            noise,
            skipped_folds: self.skipped_folds,
            initial_gap_mm: self.initial_gap.headline_mm(),
            initial_gap: self.initial_gap,
            final_gap_mm: self.gap.headline_mm(),
            final_gap: self.gap,
            uncertainty,
            notes: self.notes,
        }
    }
}

/// The record of a round whose fit to the screening measurements failed (the loop stops).
fn failed_round(index: usize, base: Base, e: &DiscoveryError, ctx: &Context<'_>) -> Round {
    Round {
        index,
        fit: base.fit,
        location: base.location,
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
    }
}
