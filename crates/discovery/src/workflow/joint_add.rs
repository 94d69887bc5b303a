//! **The joint search, confirmation**: the candidates [`super::joint`] chose on the screening
//! part are refitted together with the nonlinear model on all data and confirmed together on
//! the held-out confirmation part (one more test of the round, at
//! `confirm_alpha·s_r/(max_refits + 2)`). Every member must pass the size rule on its own (its
//! own prediction change, linearised at the joint fit, above the noise reference and its
//! physical floor) and be plausible; members that fail are dropped and the rest refitted (at
//! most [`MAX_ATTEMPTS`] refits). The whole set is then decided like one candidate (held-out
//! z, size, plausibility) and vetoed by the validation rows like one. The backward check of
//! the round then re-tests earlier effects against the new ones.

use vatcal_core::effects::EffectSpec;
use vatcal_core::{ParamId, ParamSet};
use vatcal_observability::assemble_jacobian;

use super::candidate::Candidate;
use super::confirm::refit_effects;
use super::context::{Context, CrossValidation};
use super::decide::decide;
use super::joint::{JointPath, joint_path};
use super::plausible::plausibility;
use super::record::{Addition, GroupOrigin, record_group};
use super::report::{CandidateStatus, Gap, RefitEvidence};
use super::screen::Thresholds;
use super::size::physical_floor_mm;
use super::veto::{VALIDATION_WORSE, validation_worse};
use crate::DiscoveryError;
use crate::distributions::normal_upper_quantile;
use crate::fit::Fit;

/// Refits of the chosen set at most (members failing the size rule or plausibility are
/// dropped between them).
pub(super) const MAX_ATTEMPTS: usize = 3;

/// z the joint set must exceed in a round that spends `spend`: one more test of the round, at
/// `confirm_alpha·spend/(max_refits + 2)` (the block step is the `+ 1`).
pub(super) fn joint_z(confirm_alpha: f64, max_refits: usize, spend: f64) -> f64 {
    normal_upper_quantile(confirm_alpha * spend / (max_refits.max(1) + 2) as f64)
}

/// The joint search of a round in which nothing passed alone and no block passed (module
/// docs of [`super::joint`] and of this module). Returns the addition and its confirmation
/// cross-validation when the chosen set passes.
#[allow(clippy::too_many_arguments)]
pub(super) fn add_joint(
    candidates: &mut [Candidate],
    current: &Fit,
    (j0, rank0): (&faer::Mat<f64>, usize),
    held0: &mut CrossValidation,
    (round, spend): (usize, f64),
    gap: &Gap,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<Option<(Addition, CrossValidation)>, DiscoveryError> {
    let Some(path) = joint_path(candidates, current, j0, ctx)? else { return Ok(None) };
    if path.chosen == 0 {
        notes.push(format!("round {round}: {}", path_sentence(&path, candidates)));
        return Ok(None);
    }
    ctx.ensure_confirmation_baseline(held0, current);
    let held0 = &*held0;
    let th = Thresholds {
        ln_screen: f64::NAN,
        z_required: joint_z(ctx.options.confirm_alpha, ctx.options.max_refits, spend),
        far_from_floor: false,
    };
    let mut members = path.members().to_vec();
    let mut dropped: Vec<String> = Vec::new();
    for _ in 0..MAX_ATTEMPTS {
        if members.is_empty() {
            break;
        }
        let effects: Vec<(EffectSpec, Vec<ParamId>)> =
            members.iter().map(|i| (candidates[*i].spec, candidates[*i].new_params.clone())).collect();
        let (evidence, fit1, held1) =
            match refit_effects(current, j0, rank0, held0, &effects, &th, ctx, notes) {
                Ok(r) => r,
                Err(why) => {
                    notes.push(format!("round {round}: joint search refit failed: {why}"));
                    return Ok(None);
                }
            };
        let weak = weak_members(&effects, &evidence, current, &fit1, ctx)?;
        if !weak.is_empty() {
            for (k, why) in weak.iter().rev() {
                dropped.push(format!("{} ({why})", candidates[members[*k]].spec.label()));
                members.remove(*k);
            }
            continue;
        }
        let labels = || members.iter().map(|i| candidates[*i].spec.label()).collect::<Vec<_>>().join(", ");
        match decide(&evidence, &fit1) {
            CandidateStatus::PassedNotBest if validation_worse(current, &fit1, ctx) => {
                notes.push(format!(
                    "round {round}: joint search set ({}) not added: {VALIDATION_WORSE}",
                    labels()
                ));
                return Ok(None);
            }
            CandidateStatus::PassedNotBest => {
                let line = format!(
                    "{}{}; added together ({}): held-out RMS {:.4} -> {:.4} mm on the confirmation part, z = {:.1} > {:.2}",
                    path_sentence(&path, candidates),
                    if dropped.is_empty() {
                        String::new()
                    } else {
                        format!("; dropped {}", dropped.join(", "))
                    },
                    labels(),
                    evidence.heldout.rms_before_mm,
                    evidence.heldout.rms_after_mm,
                    evidence.heldout.z,
                    th.z_required,
                );
                return record_group(
                    candidates,
                    &members,
                    (&evidence, fit1, held1),
                    (round, current, gap),
                    (GroupOrigin::JointSearch(line), &joint_how),
                    ctx,
                );
            }
            other => {
                notes.push(format!("round {round}: joint search set ({}) not added: {other:?}", labels()));
                return Ok(None);
            }
        }
    }
    notes.push(format!(
        "round {round}: joint search added nothing: {}; dropped {}",
        path_sentence(&path, candidates),
        dropped.join(", ")
    ));
    Ok(None)
}

/// The members (indices into `effects`) that fail alone: their own prediction change
/// (linearised at `fit1`) below the size rule's noise or their physical floor, or an
/// implausible value; with the reason.
fn weak_members(
    effects: &[(EffectSpec, Vec<ParamId>)],
    evidence: &RefitEvidence,
    current: &Fit,
    fit1: &Fit,
    ctx: &Context<'_>,
) -> Result<Vec<(usize, String)>, DiscoveryError> {
    let ms = ctx.measurements;
    let opts = &ctx.options;
    let mut weak = Vec::new();
    for (k, (spec, params)) in effects.iter().enumerate() {
        let own: Vec<ParamId> =
            params.iter().copied().filter(|p| fit1.params.index_of(*p).is_some()).collect();
        if own.is_empty() {
            weak.push((k, "no parameter kept".to_string()));
            continue;
        }
        let changes: Vec<(ParamId, f64)> = own
            .iter()
            .map(|p| (*p, fit1.value(*p).unwrap_or(0.0) - current.model.param(*p).unwrap_or(0.0)))
            .collect();
        let j =
            assemble_jacobian(&fit1.model, ms, &ParamSet(own.clone())).map_err(DiscoveryError::Jacobian)?;
        let mut ss = 0.0;
        for r in 0..j.nrows() {
            let v: f64 = changes.iter().enumerate().map(|(c, (_, d))| j[(r, c)] * d).sum();
            ss += v * v;
        }
        let change_mm = (ss / ms.len().max(1) as f64).sqrt();
        let floor =
            opts.negligible_factor * 3f64.sqrt() * physical_floor_mm(&[(*spec, params.clone())], opts);
        let noise = evidence.negligible_below_mm.max(floor);
        if change_mm < noise {
            weak.push((
                k,
                format!("its predictions change by {:.1} um < {:.1} um", 1e3 * change_mm, 1e3 * noise),
            ));
        } else if let Err(why) = plausibility(ctx, spec, &changes) {
            weak.push((k, format!("implausible: {why}")));
        }
    }
    Ok(weak)
}

/// The path in one sentence: how many candidates, the order, how many kept, the held-out
/// error.
fn path_sentence(path: &JointPath, candidates: &[Candidate]) -> String {
    let shown = path.chosen.max(3).min(path.order.len());
    let first: Vec<String> = path.order[..shown]
        .iter()
        .zip(&path.heldout_rms_mm[1..])
        .map(|(i, e)| format!("{} ({:.4})", candidates[*i].spec.label(), e))
        .collect();
    format!(
        "joint search over {} candidates (forward path by cross-validation on the {} screening measurements, held-out RMS mm after each: {}{}): the one-standard-error rule keeps {} (held-out RMS {:.4} -> {:.4} mm)",
        path.live,
        path.measurements,
        first.join(", "),
        if path.order.len() > shown { ", ..." } else { "" },
        path.chosen,
        path.heldout_rms_mm[0],
        path.heldout_rms_mm[path.chosen],
    )
}

/// How a member of the joint search's set entered the model.
fn joint_how(others: usize, e: &RefitEvidence) -> String {
    format!(
        "joint search: nothing passed alone; chosen with the {others} other member(s) by the cross-validated forward path over every candidate, confirmed together (held-out z = {:.1} > {:.2}), its own prediction change above the noise",
        e.heldout.z, e.z_required
    )
}
