//! **The backward check** after an addition: earlier effects that no longer lower the held-out
//! error given the new one are removed.

use rayon::prelude::*;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{ParamId, ParamSet};
use vatcal_kinematics::Model;

use super::context::{Context, CrossValidation};
use super::report::{AddedEffect, RemovedEffect};
use super::size::{noise_sigma, strong_z};
use crate::DiscoveryError;
use crate::criteria::HeldOutComparison;
use crate::fit::{Fit, fit};

/// `start` with the effects `specs` switched on and every parameter of `params` set to its
/// value in `values_from` (effects not in `specs` are absent, their parameters unfitted).
pub(super) fn rebuild(
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
/// noise) given the others; the weakest one that does not is removed — together with the
/// failing ones unrelated to it ([`independent_failures`]) — and the model refitted, and the
/// effects related to the removed ones ([`related_to`]) are checked again, until all pass.
/// Returns the removed effects.
#[allow(clippy::too_many_arguments)]
pub(super) fn backward_check(
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
    // after a removal: the effects whose standing it can have changed (a parameter correlated
    // with one of the removed effects' in the fit before the removal); the others are not
    // re-tested
    let mut affected: Option<Vec<EffectSpec>> = None;
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
            ctx.options.negligible_factor * 3f64.sqrt() * noise_sigma(ctx, current, ctx.measurements, rank);
        // without a noise reference an effect that still lowers the held-out error by
        // `strong_z_factor` standard errors is kept whatever σ̂ says
        let strong = strong_z(ctx, 1.0);
        // never below the physical floor of the noise (`DiscoverOptions::noise_floor_mm`)
        let floor_mm = ctx.options.negligible_factor * 3f64.sqrt() * ctx.options.noise_floor_mm;
        let with = recomputed.as_ref().unwrap_or(with_current);
        // the newest effect was just confirmed; check the earlier ones
        let checked: Vec<usize> = (0..added.len() - exempt.min(added.len()))
            .filter(|&k| {
                let own_idx: Vec<usize> =
                    added[k].spec.params().iter().filter_map(|p| current.params.index_of(*p)).collect();
                match &affected {
                    Some(specs) => specs.contains(&added[k].spec),
                    None => own_idx.iter().any(|a| {
                        newest.iter().any(|b| {
                            current
                                .correlation(*a, *b)
                                .is_none_or(|c| c.abs() >= ctx.options.redundancy_correlation)
                        })
                    }),
                }
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
        let mut failing: Vec<(usize, HeldOutComparison, Fit)> = Vec::new();
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
            failing.push((k, h, refit));
        }
        if failing.is_empty() {
            break;
        }
        let refit = remove_failing(start, added, current, failing, round, ctx, &mut removed, &mut affected);
        *current = refit;
        recomputed = Some(ctx.cross_validate(&current.model, &current.params, &ctx.confirm_folds));
    }
    Ok(removed)
}

/// The failing effects (sorted weakest first) that are removed in the same pass: the weakest,
/// and each further one none of whose parameters correlates (by at least `limit`, or unknown)
/// with a parameter of one already taken — look-alikes are removed one at a time (each may
/// carry what the other loses), unrelated failures together.
fn independent_failures(
    failing: &[(usize, HeldOutComparison, Fit)],
    added: &[AddedEffect],
    current: &Fit,
    limit: f64,
) -> Vec<usize> {
    let idx = |k: usize| -> Vec<usize> {
        added[k].spec.params().iter().filter_map(|p| current.params.index_of(*p)).collect()
    };
    let mut taken: Vec<usize> = Vec::new();
    let mut taken_idx: Vec<usize> = Vec::new();
    for (k, ..) in failing {
        let own = idx(*k);
        let related = own
            .iter()
            .any(|a| taken_idx.iter().any(|b| current.correlation(*a, *b).is_none_or(|c| c.abs() >= limit)));
        if !related {
            taken.push(*k);
            taken_idx.extend(own);
        }
    }
    taken
}

/// The model refitted without the effects `ks` (indices into `added`); `None` when only one
/// is removed (its own refit is used) or the refit fails.
fn remove_together(
    start: &Model,
    added: &[AddedEffect],
    current: &Fit,
    ks: &[usize],
    ctx: &Context<'_>,
) -> Option<Fit> {
    if ks.len() < 2 {
        return None;
    }
    let own: Vec<ParamId> = ks.iter().flat_map(|k| added[*k].spec.params()).collect();
    let params = ParamSet(current.params.iter().copied().filter(|p| !own.contains(p)).collect());
    let specs: Vec<EffectSpec> =
        added.iter().enumerate().filter(|(i, _)| !ks.contains(i)).map(|(_, a)| a.spec).collect();
    let base = rebuild(start, &specs, &current.model, &params).ok()?;
    fit(&base, ctx.measurements, &params, &ctx.options.identify).ok()
}

/// The effects other than `ks` (indices into `added`) with a parameter correlated (by at least
/// `limit`, or unknown) with a parameter of one of `ks` in `current`.
fn related_to(ks: &[usize], added: &[AddedEffect], current: &Fit, limit: f64) -> Vec<EffectSpec> {
    let idx = |a: &AddedEffect| -> Vec<usize> {
        a.spec.params().iter().filter_map(|p| current.params.index_of(*p)).collect()
    };
    let gone: Vec<usize> = ks.iter().flat_map(|k| idx(&added[*k])).collect();
    added
        .iter()
        .enumerate()
        .filter(|(i, a)| {
            !ks.contains(i)
                && idx(a).iter().any(|x| {
                    gone.iter().any(|g| current.correlation(*x, *g).is_none_or(|c| c.abs() >= limit))
                })
        })
        .map(|(_, a)| a.spec)
        .collect()
}

/// Removes the weakest failing effect and those unrelated to it ([`independent_failures`]),
/// records them in `removed`, sets `affected` to the effects their removal concerns
/// ([`related_to`]) and returns the refit without them.
#[allow(clippy::too_many_arguments)]
fn remove_failing(
    start: &Model,
    added: &mut Vec<AddedEffect>,
    current: &Fit,
    mut failing: Vec<(usize, HeldOutComparison, Fit)>,
    round: usize,
    ctx: &Context<'_>,
    removed: &mut Vec<RemovedEffect>,
    affected: &mut Option<Vec<EffectSpec>>,
) -> Fit {
    failing.sort_by(|x, y| x.1.z.total_cmp(&y.1.z));
    let together = independent_failures(&failing, added, current, ctx.options.redundancy_correlation);
    let zs: Vec<(usize, HeldOutComparison)> = failing.iter().map(|(k, h, _)| (*k, *h)).collect();
    let (mut ks, refit) = match remove_together(start, added, current, &together, ctx) {
        Some(refit) => (together, refit),
        None => {
            let (k, _, refit) = failing.swap_remove(0);
            (vec![k], refit)
        }
    };
    *affected = Some(related_to(&ks, added, current, ctx.options.redundancy_correlation));
    ks.sort_unstable_by(|a, b| b.cmp(a));
    for k in ks {
        let Some((_, h)) = zs.iter().find(|(j, _)| *j == k) else { continue };
        let gone = added.remove(k);
        removed.push(RemovedEffect {
            label: gone.label,
            added_in_round: gone.round,
            removed_in_round: round,
            heldout: *h,
        });
    }
    refit
}
