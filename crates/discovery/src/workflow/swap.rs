//! **The swap check**: when the forward search stops, earlier additions are re-examined against
//! the look-alikes refused in the last round.
//!
//! Effects whose prediction changes point nearly the same way on the data (joint compliance,
//! link bending, the τ|τ| stiffness, the carriage tilt; cosine 0.92–0.99) compete for the same
//! misfit. The greedy forward search adds whichever is ahead when the misfit is first seen,
//! often by a z of 2 or so; once it is in, the true one has little left to explain and is
//! refused (held-out not lower, or the validation veto). So when a round adds nothing, every
//! refitted-but-refused candidate B of that round is tested against every earlier addition A it
//! looks like on the data — the largest cosine between a direction of B and the span of A's
//! directions, both with the rest of the model projected out, is at least [`LOOKALIKE_COSINE`]
//! — by fitting the model with **B in place of A** and cross-validating it on the confirmation
//! folds: B replaces A when it predicts the held-out points better by at least [`SWAP_Z`]
//! paired standard errors, its values are plausible and the validation rows are not
//! significantly worse. At most one swap per round (the best z); an effect swapped out never
//! comes back (no cycles). After a swap the search continues: the next round screens again.

use std::collections::BTreeMap;

use faer::Mat;
use rayon::prelude::*;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{ParamId, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::assemble_jacobian;

use super::backward::rebuild;
use super::candidate::Candidate;
use super::context::{Context, CrossValidation, columns, weigh_rows};
use super::plausible::plausibility;
use super::record::added_record;
use super::report::{AddedEffect, Ambiguity, CandidateStatus, RefitEvidence, RemovedEffect, file_value};
use super::veto::validation_worse;
use crate::DiscoveryError;
use crate::criteria::{HeldOutComparison, NestedComparison};
use crate::fit::{Fit, fit};
use crate::linear::ColumnSpace;

/// Largest cosine between a candidate's direction and an added effect's span (both with the
/// rest of the model projected out) from which the two count as look-alikes on the data.
pub const LOOKALIKE_COSINE: f64 = 0.9;

/// Paired z of the held-out improvement a look-alike needs to replace an earlier addition.
pub const SWAP_Z: f64 = 2.0;

/// One swap made by [`swap_check`].
pub(super) struct Swap {
    /// the earlier addition that left the model
    pub(super) removed: RemovedEffect,
    /// why, for the report's ambiguities
    pub(super) ambiguity: Ambiguity,
    /// the round's decision text
    pub(super) sentence: String,
}

/// The swap check of round `round`, in which nothing was added (`held0`: the confirmation CV
/// of `current`, `j0` its weighted Jacobian on all data). Replaces at most one earlier addition by a look-alike candidate of the round
/// that predicts the held-out points significantly better; `swapped_out` holds the effects
/// already swapped out (never tried again). Returns the swap made, if any.
#[allow(clippy::too_many_arguments)]
pub(super) fn swap_check(
    start: &Model,
    added: &mut [AddedEffect],
    current: &mut Fit,
    candidates: &mut [Candidate],
    (held0, j0): (&CrossValidation, &Mat<f64>),
    round: usize,
    swapped_out: &mut Vec<EffectSpec>,
    ctx: &Context<'_>,
) -> Result<Option<Swap>, DiscoveryError> {
    if added.is_empty() || held0.errors.iter().all(Option::is_none) {
        return Ok(None);
    }
    let pairs = lookalike_pairs(added, current, j0, candidates, swapped_out, ctx)?;
    let tried: Vec<(usize, usize, f64)> = pairs.into_iter().take(MAX_SWAP_TRIALS).collect();
    let outcomes: Vec<Option<(HeldOutComparison, Fit)>> = tried
        .par_iter()
        .map(|&(k, b, _)| try_swap(start, added, k, &candidates[b], current, held0, ctx))
        .collect();
    let mut best: Option<(usize, usize, f64, HeldOutComparison, Fit)> = None;
    for (&(k, b, cosine), outcome) in tried.iter().zip(outcomes) {
        let Some((h, swapped)) = outcome else { continue };
        if best.as_ref().is_none_or(|w| h.z > w.3.z) {
            best = Some((k, b, cosine, h, swapped));
        }
    }
    let Some((k, b, cosine, h, swapped)) = best else { return Ok(None) };
    record_swap(added, k, candidates, b, cosine, h, swapped, current, round, swapped_out, ctx).map(Some)
}

/// At most this many (addition, look-alike) pairs are refitted per swap check (the most
/// collinear first).
pub const MAX_SWAP_TRIALS: usize = 8;

/// Replaces `added[k]` by candidate `b` fitted as `swapped`; the record, the ambiguity and the
/// removed effect.
#[allow(clippy::too_many_arguments)]
fn record_swap(
    added: &mut [AddedEffect],
    k: usize,
    candidates: &mut [Candidate],
    b: usize,
    cosine: f64,
    h: HeldOutComparison,
    swapped: Fit,
    current: &mut Fit,
    round: usize,
    swapped_out: &mut Vec<EffectSpec>,
    ctx: &Context<'_>,
) -> Result<Swap, DiscoveryError> {
    let gap_before = added[k].gap_after.clone();
    let held_all = ctx.cross_validate(&swapped.model, &swapped.params, &ctx.all_folds);
    let gap_after = ctx.gap(&swapped.model, &held_all)?;
    let c = &candidates[b];
    let mut evidence = match c.refit.as_ref() {
        Some((e, ..)) => e.clone(),
        None => swap_evidence(c, current, &swapped, h, ctx),
    };
    evidence.heldout = h;
    evidence.values = c
        .new_params
        .iter()
        .filter_map(|p| swapped.model.param(*p).ok().map(|v| file_value(*p, v)))
        .collect::<BTreeMap<_, _>>();
    let record = added_record(c, &evidence, &swapped, round, current, &gap_before, &gap_after, ctx)?;
    let old = std::mem::replace(&mut added[k], record);
    swapped_out.push(old.spec);
    let label = c.spec.label();
    candidates[b].status = CandidateStatus::Added;
    let sentence = format!(
        "swapped {} (added in round {}) for its look-alike {} (cosine {cosine:.3} on the data): held-out RMS {:.4} -> {:.4} mm, paired z = {:.2} >= {SWAP_Z}",
        old.label, old.round, label, h.rms_before_mm, h.rms_after_mm, h.z
    );
    let ambiguity = Ambiguity {
        round,
        chosen: label,
        rivals: vec![old.label.clone()],
        basis: "swap".to_string(),
        validation_z: vec![None],
        sentence: sentence.clone(),
    };
    let removed =
        RemovedEffect { label: old.label, added_in_round: old.round, removed_in_round: round, heldout: h };
    *current = swapped;
    Ok(Swap { removed, ambiguity, sentence })
}

/// The evidence of a look-alike swapped in without a refit of its own this round: the nested
/// comparison of the swap against the current model (same parameter count), no
/// confounding list.
fn swap_evidence(
    c: &Candidate,
    current: &Fit,
    swapped: &Fit,
    heldout: HeldOutComparison,
    ctx: &Context<'_>,
) -> RefitEvidence {
    let n = 3 * ctx.measurements.len();
    let rss = |f: &Fit| f.residuals.iter().map(|r| r.norm_squared()).sum::<f64>();
    RefitEvidence {
        fitted_params: c.new_params.iter().map(|p| p.name()).collect(),
        comparison: NestedComparison::new(
            n,
            current.params.len(),
            rss(current),
            swapped.params.len(),
            rss(swapped),
        ),
        heldout,
        z_required: SWAP_Z,
        negligible_below_mm: 0.0,
        size_rule_waived_above_z: None,
        floor_below_mm: 0.0,
        size_rule_waived_far_from_floor: false,
        values: BTreeMap::new(),
        std_errors: BTreeMap::new(),
        confounding: Vec::new(),
        implausible: None,
        rival: None,
    }
}

/// Every (earlier addition `k`, candidate `b`) pair that looks alike on the data, most collinear
/// first: the largest cosine between a direction of `b` (switched on at zero in the current
/// model) and the span of `k`'s directions, both with the rest of the model projected out, at
/// least [`LOOKALIKE_COSINE`] (`j0`: the current model's weighted Jacobian on all data).
/// Candidates already swapped out, or without a score, are skipped.
fn lookalike_pairs(
    added: &[AddedEffect],
    current: &Fit,
    j0: &Mat<f64>,
    candidates: &[Candidate],
    swapped_out: &[EffectSpec],
    ctx: &Context<'_>,
) -> Result<Vec<(usize, usize, f64)>, DiscoveryError> {
    let eligible: Vec<usize> = (0..candidates.len())
        .filter(|&b| {
            let c = &candidates[b];
            c.score.is_some()
                && !c.new_params.is_empty()
                && c.status != CandidateStatus::Added
                && !swapped_out.contains(&c.spec)
                && c.refit.as_ref().is_none_or(|(e, f, _)| f.converged && e.implausible.is_none())
        })
        .collect();
    // each candidate's weighted columns at the current model (switched on at zero)
    let with_b: Vec<Option<Mat<f64>>> = eligible
        .par_iter()
        .map(|&b| {
            let c = &candidates[b];
            let mut m = current.model.clone();
            m.enable_effect(c.spec).ok()?;
            let mut j = assemble_jacobian(&m, ctx.measurements, &ParamSet(c.new_params.clone())).ok()?;
            weigh_rows(&mut j, ctx.measurements, &ctx.options.identify.weights);
            Some(j)
        })
        .collect();
    let mut pairs = Vec::new();
    for (k, a) in added.iter().enumerate() {
        let own_a: Vec<usize> = a.spec.params().iter().filter_map(|p| current.params.index_of(*p)).collect();
        if own_a.is_empty() {
            continue;
        }
        let rest: Vec<usize> = (0..current.params.len()).filter(|i| !own_a.contains(i)).collect();
        let rest_space = ColumnSpace::of(columns(j0, &rest).as_ref())?;
        let pa = rest_space.project_out(columns(j0, &own_a).as_ref());
        for (&b, jb) in eligible.iter().zip(&with_b) {
            let Some(jb) = jb else { continue };
            let pb = rest_space.project_out(jb.as_ref());
            let cosine = largest_cosine(&pa, &pb)?;
            if cosine >= LOOKALIKE_COSINE {
                pairs.push((k, b, cosine));
            }
        }
    }
    pairs.sort_by(|x, y| y.2.total_cmp(&x.2).then(x.0.cmp(&y.0)).then(x.1.cmp(&y.1)));
    Ok(pairs)
}

/// The largest cosine between a column of `b` and the span of the columns of `a` (0 when
/// either is numerically empty).
fn largest_cosine(a: &Mat<f64>, b: &Mat<f64>) -> Result<f64, DiscoveryError> {
    let scale = |m: &Mat<f64>| (0..m.ncols()).map(|c| m.col(c).norm_l2()).fold(0.0, f64::max);
    if scale(a) <= 1e-12 || scale(b) <= 1e-12 {
        return Ok(0.0);
    }
    let span = ColumnSpace::of(a.as_ref())?;
    let residual = span.project_out(b.as_ref());
    let mut best: f64 = 0.0;
    for c in 0..b.ncols() {
        let total = b.col(c).norm_l2();
        if total <= 1e-12 * scale(b) {
            continue;
        }
        let left = residual.col(c).norm_l2() / total;
        best = best.max((1.0 - left * left).max(0.0).sqrt());
    }
    Ok(best)
}

/// The model with candidate `c` in place of `added[k]` (its values from its own refit when it
/// has one, else zero): fitted on all data and cross-validated on the confirmation folds,
/// compared with `held0` (the current model's). `None` unless it predicts the held-out points
/// better by [`SWAP_Z`], is plausible and leaves the validation rows not significantly worse.
fn try_swap(
    start: &Model,
    added: &[AddedEffect],
    k: usize,
    c: &Candidate,
    current: &Fit,
    held0: &CrossValidation,
    ctx: &Context<'_>,
) -> Option<(HeldOutComparison, Fit)> {
    let gone: Vec<ParamId> = added[k].spec.params();
    let mut params: Vec<ParamId> = current.params.iter().copied().filter(|p| !gone.contains(p)).collect();
    let known = ParamSet(params.clone());
    params.extend(c.new_params.iter().copied().filter(|p| !known.0.contains(p)));
    let params = ParamSet(params);
    let mut specs: Vec<EffectSpec> =
        added.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, a)| a.spec).collect();
    specs.push(c.spec);
    let base = match c.refit.as_ref() {
        Some((_, refit, _)) => rebuild(
            start,
            &specs,
            &refit.model,
            &ParamSet(params.iter().copied().filter(|p| refit.params.index_of(*p).is_some()).collect()),
        )
        .ok()?,
        None => rebuild(start, &specs, &current.model, &known).ok()?,
    };
    let cv = ctx.cross_validate(&base, &params, &ctx.confirm_folds);
    let h = HeldOutComparison::new(&held0.errors, &cv.errors);
    if h.z < SWAP_Z {
        return None;
    }
    let swapped = fit(&base, ctx.measurements, &params, &ctx.options.identify).ok()?;
    let changes: Vec<(ParamId, f64)> =
        c.new_params.iter().filter_map(|p| swapped.model.param(*p).ok().map(|v| (*p, v))).collect();
    if plausibility(ctx, &c.spec, &changes).is_err() || validation_worse(current, &swapped, ctx) {
        return None;
    }
    Some((h, swapped))
}
