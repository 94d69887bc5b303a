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
//!
//! One file per decision: [`screen`](self::screen) (candidates, scores, levels),
//! `confirm` (refits on the held-out confirmation data), `decide` (the decision rule),
//! `size` (the noise reference and the size rule), `plausible` (bounds), `rivals`
//! (look-alikes), `veto` (the validation rows), `block` (the block step), `backward` (the
//! backward check), `stop` (the keep-going rule), `borderline` (the glue to
//! [`crate::propose`]), `record` (an added effect's record); this file only sequences them.

mod backward;
mod block;
mod borderline;
mod candidate;
mod confirm;
mod context;
mod decide;
mod options;
mod plausible;
mod record;
mod report;
mod rivals;
mod screen;
mod size;
mod stop;
mod veto;

pub use options::DiscoverOptions;
pub use report::{
    AddedEffect, Ambiguity, BoundHit, CandidateScore, CandidateStatus, Confounding, Discovery, DriverPlot,
    FitSummary, Gap, NegligibleEffect, PredictedUncertainty, RefitEvidence, RemovedEffect, Round, file_value,
};
pub use rivals::{RIVAL_CORRELATION, RIVAL_COSINE};
pub use screen::{GENERIC_SCREENING_SHARE, MAX_PROPOSED_HARMONIC, candidates, round_spending};
pub use veto::VETO_Z;

use vatcal_core::{Measurement, ParamSet};
use vatcal_identification::KindSigmas;
use vatcal_kinematics::Model;
use vatcal_observability::assemble_jacobian;

use self::backward::backward_check;
use self::block::block_step;
use self::borderline::mark_borderline;
use self::candidate::{Candidate, candidate_score};
use self::confirm::confirm_screened;
use self::context::{Context, CrossValidation, chain_scale, summarize_fit, weigh_rows};
use self::decide::IMPLAUSIBLE;
use self::record::{added_effect, added_record, predicted_uncertainty};
use self::rivals::choose_among_rivals;
use self::screen::{Thresholds, score_candidates, screening_weights};
use self::size::{describe_noise, noise_reference, saturated_sigma};
use self::stop::{best_passing, gap_over_floor, nothing_added};
use self::veto::veto_on_validation;
use crate::DiscoveryError;
use crate::distributions::normal_upper_quantile;
use crate::fit::fit;
use crate::folds::{screening_split, stratified_folds};
use crate::linear::ColumnSpace;
use crate::location::locate;
use crate::noise::NoiseSource;

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
