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
//! directions, both with the rest of the model projected out, is at least [`LOOKALIKE_COSINE`].
//!
//! The replacements tried ([`trials`]): **B in place of A**; **two look-alikes of A** in its
//! place when together they have no more parameters than A (a two-parameter link bending
//! standing in for two one-parameter compliances); and **a look-alike of each of two
//! additions** in place of both, when they have fewer parameters together. Each is fitted
//! and cross-validated on the confirmation folds, and decided by a stated rule:
//! - with as many parameters as what it replaces, it must predict the held-out points better
//!   by at least [`SWAP_Z`] paired standard errors;
//! - with **fewer** parameters, simplicity decides: it is taken unless it predicts them worse
//!   by more than one paired standard error ([`SIMPLER_SWAP_Z`], the one-standard-error rule);
//! - either way its values must be plausible and the validation rows not significantly worse.
//!
//! At most one swap per round: of the replacements that pass, those within one paired standard
//! error of the best z, and of those the one leaving the fewest parameters ([`choose`]); an
//! effect swapped out never comes back (no
//! cycles), and a replacement of more than one effect never has more parameters than what it
//! replaces. After a swap the search continues: the next round screens again.

use std::collections::BTreeMap;

use faer::Mat;
use rayon::prelude::*;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{ParamId, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::assemble_jacobian;

use super::backward::rebuild;
use super::candidate::Candidate;
use super::context::{Context, CrossValidation, columns, weigh_rows, weighted_residual};
use super::plausible::plausibility;
use super::record::{added_record, push_with_prerequisites};
use super::report::{AddedEffect, Ambiguity, CandidateStatus, RefitEvidence, RemovedEffect, file_value};
use super::veto::validation_worse;
use crate::DiscoveryError;
use crate::criteria::{HeldOutComparison, NestedComparison};
use crate::fit::{Fit, fit};
use crate::linear::{ColumnSpace, EffectDirections, ScoreTest, score_test};

/// Largest cosine between a candidate's direction and an added effect's span (both with the
/// rest of the model projected out) from which the two count as look-alikes on the data.
pub const LOOKALIKE_COSINE: f64 = 0.9;

/// Paired z of the held-out improvement a look-alike needs to replace an earlier addition.
pub const SWAP_Z: f64 = 2.0;

/// One swap made by [`swap_check`].
pub(super) struct Swap {
    /// the earlier additions that left the model
    pub(super) removed: Vec<RemovedEffect>,
    /// why, for the report's ambiguities
    pub(super) ambiguity: Ambiguity,
    /// the round's decision text
    pub(super) sentence: String,
}

/// One replacement tried by the swap check: earlier additions `outs` out, candidates `ins`
/// in, each a look-alike of one of the `outs`; `cosine` is the smallest of their look-alike
/// cosines.
#[derive(Clone, Debug)]
struct Trial {
    outs: Vec<usize>,
    ins: Vec<usize>,
    cosine: f64,
    /// the parameters the `ins` add and the `outs` take away
    n_in: usize,
    n_out: usize,
}

impl Trial {
    /// The paired held-out z the replacement needs: [`SWAP_Z`], or [`SIMPLER_SWAP_Z`] when it
    /// has fewer parameters than what it replaces.
    fn z_required(&self) -> f64 {
        if self.n_in < self.n_out { SIMPLER_SWAP_Z } else { SWAP_Z }
    }
}

/// The swap check of round `round`, in which nothing was added (`held0`: the confirmation CV
/// of `current`, `j0` its weighted Jacobian on all data). Replaces at most one earlier
/// addition by one look-alike candidate of the round, or by two look-alikes with no more
/// parameters together than it has, that predict the held-out points significantly better;
/// `swapped_out` holds the effects already swapped out (never tried again). Returns the swap
/// made, or why each replacement tried was refused.
#[allow(clippy::too_many_arguments)]
pub(super) fn swap_check(
    start: &Model,
    added: &mut Vec<AddedEffect>,
    current: &mut Fit,
    candidates: &mut [Candidate],
    (held0, j0): (&mut CrossValidation, &Mat<f64>),
    round: usize,
    swapped_out: &mut Vec<EffectSpec>,
    ctx: &Context<'_>,
) -> Result<SwapCheck, DiscoveryError> {
    if added.is_empty() {
        return Ok(SwapCheck::Kept(Vec::new()));
    }
    let pairs = lookalike_pairs(added, current, j0, candidates, swapped_out, ctx)?;
    let tried = trials(&pairs, added, candidates);
    if tried.is_empty() {
        return Ok(SwapCheck::Kept(Vec::new()));
    }
    // a round whose screening passed nothing has no confirmation baseline yet: the search
    // stops there all the same, so the check needs one
    ctx.ensure_confirmation_baseline(held0, current);
    let held0 = &*held0;
    let outcomes: Vec<Result<Outcome, String>> =
        tried.par_iter().map(|t| try_swap(start, added, t, candidates, current, held0, ctx)).collect();
    let mut passed = Vec::new();
    let mut kept = Vec::new();
    for (t, outcome) in tried.into_iter().zip(outcomes) {
        match outcome {
            Ok(o) => passed.push((t, o)),
            Err(why) => kept.push(kept_sentence(&t, &why, added, candidates)),
        }
    }
    let Some((t, o)) = choose(passed) else { return Ok(SwapCheck::Kept(kept)) };
    for (b, score) in o.scores {
        candidates[b].score = Some(score);
    }
    record_swap(added, &t, candidates, o.heldout, o.swapped, current, round, swapped_out, ctx)
        .map(SwapCheck::Made)
}

/// What a swap check did: one swap, or none, with why each replacement tried was refused.
pub(super) enum SwapCheck {
    /// a swap was made
    Made(Swap),
    /// nothing was swapped: for every replacement tried, the earlier addition kept and why
    Kept(Vec<String>),
}

/// The report's sentence for a replacement refused (`why`): which addition was kept over which
/// look-alike, their cosine and parameter counts.
fn kept_sentence(t: &Trial, why: &str, added: &[AddedEffect], candidates: &[Candidate]) -> String {
    let outs: Vec<String> = t.outs.iter().map(|&k| added[k].label.clone()).collect();
    let ins: Vec<String> = t.ins.iter().map(|&b| candidates[b].spec.label()).collect();
    format!(
        "kept {} over the look-alike{} {} (cosine {:.3}; {} parameter(s) for {}): {why}",
        outs.join(" and "),
        if ins.len() == 1 { "" } else { "s" },
        ins.join(" and "),
        t.cosine,
        t.n_in,
        t.n_out,
    )
}

/// The replacement to make among those that passed (`passed`), by the one-standard-error
/// rule that decides each of them: of the replacements within one paired standard error of
/// the best one's held-out z, the one that leaves the **fewest parameters** in the model, then
/// the larger z. (Two stand-ins swapped for two simpler effects at z = 2.75 beat one of those
/// swaps alone at z = 3.04: the data cannot tell the two apart, the first model is smaller.)
fn choose(passed: Vec<(Trial, Outcome)>) -> Option<(Trial, Outcome)> {
    let best_z = passed.iter().map(|(_, o)| o.heldout.z).fold(f64::NEG_INFINITY, f64::max);
    // the change in the model's parameter count (negative: smaller)
    let change = |t: &Trial| t.n_in as i64 - t.n_out as i64;
    passed
        .into_iter()
        .filter(|(_, o)| o.heldout.z >= best_z - 1.0)
        .min_by(|(ta, oa), (tb, ob)| change(ta).cmp(&change(tb)).then(ob.heldout.z.total_cmp(&oa.heldout.z)))
}

/// At most this many (addition, look-alike) pairs are refitted per swap check (the most
/// collinear first).
pub const MAX_SWAP_TRIALS: usize = 8;

/// At most this many replacements of more than one effect (two look-alikes for one addition,
/// or for two) are refitted per swap check (the most collinear first), besides the
/// [`MAX_SWAP_TRIALS`] single ones.
pub const MAX_MULTI_SWAP_TRIALS: usize = 8;

/// Paired z of the held-out improvement a replacement with **fewer** parameters than the
/// effects it replaces needs: −1, the one-standard-error rule — the simpler model is taken
/// unless it predicts the held-out points worse by more than one standard error of the
/// paired difference. Look-alikes the data cannot tell apart are decided by simplicity: a
/// two-parameter link bending or carriage tilt standing in for a one-parameter compliance
/// gives way to it. The validation veto and the plausibility bounds still apply.
pub const SIMPLER_SWAP_Z: f64 = -1.0;

/// The replacements to try, from the look-alike `pairs` (most collinear first):
/// - each pair as a one-for-one swap;
/// - every two look-alikes of one addition whose parameters together are no more than the
///   addition's (one two-parameter effect standing in for two one-parameter ones);
/// - for every two additions, a look-alike of each, with **fewer** parameters together (two
///   stand-ins for two simpler effects; with as many, the one-for-one swaps cover it).
fn trials(pairs: &[(usize, usize, f64)], added: &[AddedEffect], candidates: &[Candidate]) -> Vec<Trial> {
    let n_out = |outs: &[usize]| outs.iter().map(|&k| added[k].spec.params().len()).sum::<usize>();
    let trial = |outs: Vec<usize>, ins: Vec<usize>, cosine: f64| {
        let (n_in, n_out) = (params_of(&ins, candidates), n_out(&outs));
        Trial { outs, ins, cosine, n_in, n_out }
    };
    let mut out: Vec<Trial> =
        pairs.iter().take(MAX_SWAP_TRIALS).map(|&(k, b, cosine)| trial(vec![k], vec![b], cosine)).collect();
    let mut multi = Vec::new();
    for (i, &(k1, b1, c1)) in pairs.iter().enumerate() {
        for &(k2, b2, c2) in &pairs[i + 1..] {
            let (ins, n_in) = (vec![b1, b2], params_of(&[b1, b2], candidates));
            let admissible =
                b1 != b2 && if k1 == k2 { n_in <= n_out(&[k1]) } else { n_in < n_out(&[k1, k2]) };
            if admissible {
                let outs = if k1 == k2 { vec![k1] } else { vec![k1.min(k2), k1.max(k2)] };
                multi.push(trial(outs, ins, c1.min(c2)));
            }
        }
    }
    multi.sort_by(|x, y| y.cosine.total_cmp(&x.cosine).then(x.outs.cmp(&y.outs)).then(x.ins.cmp(&y.ins)));
    out.extend(multi.into_iter().take(MAX_MULTI_SWAP_TRIALS));
    out
}

/// Replaces the additions `t.outs` by the candidates `t.ins` fitted as `swapped`; the
/// records, the ambiguity and the removed effects.
#[allow(clippy::too_many_arguments)]
fn record_swap(
    added: &mut Vec<AddedEffect>,
    t: &Trial,
    candidates: &mut [Candidate],
    h: HeldOutComparison,
    swapped: Fit,
    current: &mut Fit,
    round: usize,
    swapped_out: &mut Vec<EffectSpec>,
    ctx: &Context<'_>,
) -> Result<Swap, DiscoveryError> {
    let gap_before = added[t.outs[0]].gap_after.clone();
    let held_all = ctx.cross_validate(&swapped.model, &swapped.params, &ctx.all_folds);
    let gap_after = ctx.gap(&swapped.model, &held_all)?;
    let mut records = Vec::with_capacity(t.ins.len());
    for &b in &t.ins {
        let c = &candidates[b];
        let mut evidence = match c.refit.as_ref() {
            Some((e, ..)) => e.clone(),
            None => swap_evidence(c, current, &swapped, (h, t.z_required()), ctx),
        };
        evidence.heldout = h;
        evidence.values = c
            .new_params
            .iter()
            .filter_map(|p| swapped.model.param(*p).ok().map(|v| file_value(*p, v)))
            .collect::<BTreeMap<_, _>>();
        let r = added_record(c, &evidence, &swapped, round, current, &gap_before, &gap_after, ctx)?;
        push_with_prerequisites(&mut records, r, c, &swapped);
    }
    let mut olds: Vec<AddedEffect> = Vec::new();
    for &k in t.outs.iter().rev() {
        olds.insert(0, added.remove(k));
    }
    // every effect that enters, the lower-order ones proposed with a candidate included
    let labels: Vec<String> = records.iter().map(|r| r.label.clone()).collect();
    added.extend(records);
    swapped_out.extend(olds.iter().map(|o| o.spec));
    let old_labels: Vec<String> =
        olds.iter().map(|o| format!("{} (added in round {})", o.label, o.round)).collect();
    for &b in &t.ins {
        candidates[b].status = CandidateStatus::Added;
    }
    let (n_in, n_out) = (t.n_in, t.n_out);
    let why = if n_in < n_out {
        format!(
            "fewer parameters ({n_in} for {n_out}) and the held-out points predicted no worse: paired z = {:.2} >= {:.1}",
            h.z,
            t.z_required()
        )
    } else {
        format!("paired z = {:.2} >= {:.1}", h.z, t.z_required())
    };
    let sentence = format!(
        "swapped {} for {} {} (look-alikes on the data, cosine {:.3}): held-out RMS {:.4} -> {:.4} mm, {why}",
        old_labels.join(" and "),
        if labels.len() == 1 { "its look-alike" } else { "the look-alikes" },
        labels.join(" and "),
        t.cosine,
        h.rms_before_mm,
        h.rms_after_mm,
    );
    let ambiguity = Ambiguity {
        round,
        chosen: labels.join(" + "),
        rivals: olds.iter().map(|o| o.label.clone()).collect(),
        basis: "swap".to_string(),
        validation_z: vec![None; olds.len()],
        sentence: sentence.clone(),
    };
    let removed = olds
        .into_iter()
        .map(|o| RemovedEffect {
            label: o.label,
            added_in_round: o.round,
            removed_in_round: round,
            heldout: h,
        })
        .collect();
    *current = swapped;
    Ok(Swap { removed, ambiguity, sentence })
}

/// The parameters the candidates `ins` add.
fn params_of(ins: &[usize], candidates: &[Candidate]) -> usize {
    ins.iter().map(|&b| candidates[b].new_params.len()).sum()
}

/// The evidence of a look-alike swapped in without a refit of its own this round: the nested
/// comparison of the swap against the current model, no confounding list.
fn swap_evidence(
    c: &Candidate,
    current: &Fit,
    swapped: &Fit,
    (heldout, z_required): (HeldOutComparison, f64),
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
        z_required,
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
/// Candidates already swapped out are skipped, and so are those the round could not score,
/// except the ones the current model **absorbed** (no direction outside its span): those are
/// exactly the effects an addition may be standing in for.
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
            (c.score.is_some() || c.directions.as_ref().is_some_and(|d| d.dof == 0))
                && !c.new_params.is_empty()
                && c.status != CandidateStatus::Added
                && !swapped_out.contains(&c.spec)
                && c.refit.as_ref().is_none_or(|(e, f, _)| f.converged && e.implausible.is_none())
        })
        .collect();
    // each candidate's weighted columns at the current model (switched on at zero)
    let with_b: Vec<Option<Mat<f64>>> =
        eligible.par_iter().map(|&b| weighted_columns(&current.model, &candidates[b], ctx)).collect();
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

/// Candidate `c`'s columns on all data, weighted, at `model` with its effect switched on at
/// zero (`None` when it cannot be switched on or evaluated).
fn weighted_columns(model: &Model, c: &Candidate, ctx: &Context<'_>) -> Option<Mat<f64>> {
    let mut with_c = model.clone();
    with_c.enable_effect(c.spec).ok()?;
    let mut j = assemble_jacobian(&with_c, ctx.measurements, &ParamSet(c.new_params.clone())).ok()?;
    weigh_rows(&mut j, ctx.measurements, &ctx.options.identify.weights);
    Some(j)
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

/// A replacement that passed: its held-out comparison with the current model, its fit, and
/// the scores of the candidates swapped in that the round could not score.
struct Outcome {
    heldout: HeldOutComparison,
    swapped: Fit,
    scores: Vec<(usize, ScoreTest)>,
}

/// The model with the candidates `t.ins` in place of the additions `t.outs` (a single candidate's
/// values from its own refit when it has one, else zero): fitted on all data and
/// cross-validated on the confirmation folds, compared with `held0` (the current model's).
/// Refused, with the reason, unless it predicts the held-out points better by
/// `t.z_required()`, every candidate's values are plausible and the validation rows are not
/// significantly worse.
fn try_swap(
    start: &Model,
    added: &[AddedEffect],
    t: &Trial,
    candidates: &[Candidate],
    current: &Fit,
    held0: &CrossValidation,
    ctx: &Context<'_>,
) -> Result<Outcome, String> {
    const UNFITTED: &str = "the replacement could not be fitted";
    let (known, mut specs) = without(added, &t.outs, current);
    let mut params = known.0.clone();
    let ins: Vec<&Candidate> = t.ins.iter().map(|&b| &candidates[b]).collect();
    for c in &ins {
        params.extend(c.new_params.iter().copied().filter(|p| !params.contains(p)).collect::<Vec<_>>());
    }
    let params = ParamSet(params);
    specs.extend(ins.iter().map(|c| c.spec));
    let base = match (ins.as_slice(), ins.first().and_then(|c| c.refit.as_ref())) {
        ([_], Some((_, refit, _))) => rebuild(
            start,
            &specs,
            &refit.model,
            &ParamSet(params.iter().copied().filter(|p| refit.params.index_of(*p).is_some()).collect()),
        )
        .map_err(|_| UNFITTED.to_string())?,
        _ => rebuild(start, &specs, &current.model, &known).map_err(|_| UNFITTED.to_string())?,
    };
    let cv = ctx.cross_validate(&base, &params, &ctx.confirm_folds);
    let h = HeldOutComparison::new(&held0.errors, &cv.errors);
    if h.z.is_nan() || h.z < t.z_required() {
        return Err(format!(
            "with it the held-out points are predicted {} (RMS {:.4} -> {:.4} mm, paired z = {:.2} < {:.1})",
            if h.z < 0.0 { "worse" } else { "not enough better" },
            h.rms_before_mm,
            h.rms_after_mm,
            h.z,
            t.z_required()
        ));
    }
    let swapped =
        fit(&base, ctx.measurements, &params, &ctx.options.identify).map_err(|_| UNFITTED.to_string())?;
    for c in &ins {
        let changes: Vec<(ParamId, f64)> =
            c.new_params.iter().filter_map(|p| swapped.model.param(*p).ok().map(|v| (*p, v))).collect();
        if let Err(why) = plausibility(ctx, &c.spec, &changes) {
            return Err(format!("{}: {why}", c.spec.label()));
        }
    }
    if validation_worse(current, &swapped, ctx) {
        return Err("the validation rows are predicted significantly worse".to_string());
    }
    let unscored: Vec<usize> = t.ins.iter().copied().filter(|&b| candidates[b].score.is_none()).collect();
    let scores = if unscored.is_empty() {
        Vec::new()
    } else {
        scores_without(start, added, t, &unscored, candidates, current, ctx).ok_or_else(|| {
            "its score at the model without the replaced effects could not be computed".to_string()
        })?
    };
    Ok(Outcome { heldout: h, swapped, scores })
}

/// The parameters and switched-on effects of the current model without the additions `outs`.
fn without(added: &[AddedEffect], outs: &[usize], current: &Fit) -> (ParamSet, Vec<EffectSpec>) {
    let gone: Vec<ParamId> = outs.iter().flat_map(|&k| added[k].spec.params()).collect();
    let params = ParamSet(current.params.iter().copied().filter(|p| !gone.contains(p)).collect());
    let specs = added.iter().enumerate().filter(|(i, _)| !outs.contains(i)).map(|(_, a)| a.spec).collect();
    (params, specs)
}

/// The score tests of the candidates `unscored` (of `t.ins`) at the model without the
/// additions `t.outs`, refitted once on all data: the screening evidence of candidates the
/// replaced effects absorbed (in the round's screening their directions lay in the model's
/// span, so they had no score). `None` when one cannot be computed or has no direction of its
/// own there either.
#[allow(clippy::too_many_arguments)]
fn scores_without(
    start: &Model,
    added: &[AddedEffect],
    t: &Trial,
    unscored: &[usize],
    candidates: &[Candidate],
    current: &Fit,
    ctx: &Context<'_>,
) -> Option<Vec<(usize, ScoreTest)>> {
    let (params, specs) = without(added, &t.outs, current);
    let base = rebuild(start, &specs, &current.model, &params).ok()?;
    let reduced = fit(&base, ctx.measurements, &params, &ctx.options.identify).ok()?;
    let weights = &ctx.options.identify.weights;
    let mut j = assemble_jacobian(&reduced.model, ctx.measurements, &params).ok()?;
    weigh_rows(&mut j, ctx.measurements, weights);
    let space = ColumnSpace::of(j.as_ref()).ok()?;
    let residual = weighted_residual(&reduced, ctx.measurements, weights);
    let sigma = ctx.sigma_hat(&reduced, ctx.measurements, space.rank());
    unscored
        .iter()
        .map(|&b| {
            let z = weighted_columns(&reduced.model, &candidates[b], ctx)?;
            let directions = EffectDirections::new(&space, z.as_ref(), ctx.options.novelty_floor).ok()?;
            (directions.dof > 0).then(|| (b, score_test(&space, &directions, &residual, sigma * sigma)))
        })
        .collect()
}
