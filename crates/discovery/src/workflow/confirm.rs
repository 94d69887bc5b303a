//! **Confirmation** (module docs of [`super`], step 3): the screened candidates refitted on all
//! data and compared on the held-out confirmation data, and the evidence collected.

use std::collections::BTreeMap;

use rayon::prelude::*;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{ParamId, ParamSet};
use vatcal_observability::assemble_jacobian;

use super::candidate::Candidate;
use super::context::{Context, CrossValidation, columns};
use super::decide::decide;
use super::plausible::plausibility;
use super::report::{CandidateStatus, Confounding, RefitEvidence, file_value};
use super::rivals::fit_resolving_rivals;
use super::screen::Thresholds;
use super::size::{noise_sigma, physical_floor_mm, strong_z};
use crate::DiscoveryError;
use crate::criteria::{HeldOutComparison, NestedComparison};
use crate::fit::Fit;
use crate::linear::{ColumnSpace, EffectDirections, unit_columns};

/// The effect parameters (indices into `z`'s columns) that add an identifiable direction, chosen
/// greedily in catalog order.
pub(super) fn identifiable_subset(
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

/// Refits with one candidate on all data, confirms it on the held-out confirmation data and
/// collects the evidence.
#[allow(clippy::too_many_arguments)]
pub(super) fn refit_candidate(
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

/// Refits with several effects at once (each with its not yet fitted parameters) on all data,
/// confirms them together on the held-out confirmation data and collects the evidence.
#[allow(clippy::too_many_arguments)]
pub(super) fn refit_effects(
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
        plausibility(ctx, spec, &own)
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
            * noise_sigma(ctx, &fit1, ctx.measurements, rank0 + added.len()),
        size_rule_waived_above_z: strong_z(ctx, th.z_required),
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

/// Refits and confirms the screened candidates (best score first, at most `max_refits`).
#[allow(clippy::too_many_arguments)]
pub(super) fn confirm_screened(
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
