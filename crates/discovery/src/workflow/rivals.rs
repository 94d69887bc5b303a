//! **Look-alikes**: parameters of a candidate near-equivalent to the model's on the data (keep
//! or swap, [`RIVAL_CORRELATION`]), and candidates whose held-out corrections are the same
//! ([`RIVAL_COSINE`]): which one is chosen and why.

use nalgebra::Vector3;
use vatcal_core::{ParamId, ParamSet};
use vatcal_kinematics::Model;

use super::candidate::Candidate;
use super::context::{Context, CrossValidation};
use super::decide::HELDOUT_NOT_LOWER;
use super::report::{Ambiguity, CandidateStatus};
use crate::DiscoveryError;
use crate::criteria::HeldOutComparison;
use crate::fit::{Fit, fit, residuals};

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
pub(super) fn fit_resolving_rivals(
    start: &Model,
    current: &Fit,
    params1: ParamSet,
    added: Vec<ParamId>,
    label: &str,
    ctx: &Context<'_>,
) -> Result<(Fit, ParamSet, Vec<ParamId>, Option<Ambiguity>), String> {
    let (refused, added) = match plain_fit(start, current, params1, added, ctx)? {
        PlainFit::Fitted(f, params1, added) => return Ok((*f, params1, added, None)),
        PlainFit::Refused(id, added) => (id, added),
    };
    let pairs = rival_pairs(&added, current, &refused.correlation);
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
    let opts = &ctx.options;
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
    let shown: Vec<String> =
        pairs.iter().map(|(a, e, c)| format!("{}/{} ({c:+.4})", a.name(), e.name())).collect();
    let swap_z = swap_z(keep.as_ref(), swap.as_ref(), current, ctx);
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
    let ambiguity = resolution(basis, chosen_name, rival_name, swap_z, &shown);
    Ok((chosen_fit, chosen_params, chosen_added, Some(ambiguity)))
}

/// The outcome of the plain refit.
enum PlainFit {
    /// fitted: the fit, its parameters, the candidate's parameters in it
    Fitted(Box<Fit>, ParamSet, Vec<ParamId>),
    /// refused as ill-conditioned (its correlations name the rivals), with the candidate's
    /// parameters that were fitted
    Refused(Box<vatcal_identification::Identification>, Vec<ParamId>),
}

/// Fits `params1`; when some of the candidate's parameters are exact combinations of the
/// model's on these data (e.g. a tool-frame shift once two TCP offsets are in) they are
/// dropped and the candidate's other directions fitted, as the screening's identifiable subset
/// meant to.
fn plain_fit(
    start: &Model,
    current: &Fit,
    params1: ParamSet,
    added: Vec<ParamId>,
    ctx: &Context<'_>,
) -> Result<PlainFit, String> {
    let (mut params1, mut added) = (params1, added);
    loop {
        match fit(start, ctx.measurements, &params1, &ctx.options.identify) {
            Ok(f) => return Ok(PlainFit::Fitted(Box::new(f), params1, added)),
            Err(DiscoveryError::Fit(e)) => match *e {
                vatcal_identification::IdentifyError::IllConditioned(id) => {
                    return Ok(PlainFit::Refused(id, added));
                }
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
    }
}

/// The (added, existing) parameter pairs whose |correlation| in the refused fit (parameters:
/// the current ones followed by `added`) is at least [`RIVAL_CORRELATION`].
fn rival_pairs(
    added: &[ParamId],
    current: &Fit,
    corr: &nalgebra::DMatrix<f64>,
) -> Vec<(ParamId, ParamId, f64)> {
    let n_old = current.params.len();
    let mut pairs = Vec::new();
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
    pairs
}

/// Parameter names, comma separated.
fn names(v: &[ParamId]) -> String {
    v.iter().map(|p| p.name()).collect::<Vec<_>>().join(", ")
}

/// Paired z of the swap's improvement on the validation rows over the keep resolution (or over
/// the current model when keep could not be fitted); `None` without validation rows.
fn swap_z(keep: Option<&Fit>, swap: Option<&Fit>, current: &Fit, ctx: &Context<'_>) -> Option<f64> {
    let validation = ctx.deciding_validation()?;
    let swap = swap?;
    let val_errors = |f: &Fit| -> Option<Vec<Option<Vector3<f64>>>> {
        residuals(&f.model, validation).ok().map(|r| r.into_iter().map(Some).collect())
    };
    let baseline = keep.unwrap_or(current);
    match (val_errors(baseline), val_errors(swap)) {
        (Some(vb), Some(vs)) => Some(HeldOutComparison::new(&vb, &vs).z),
        _ => None,
    }
}

/// The ambiguity of a keep-or-swap resolution (round 0: set by the caller).
fn resolution(
    basis: &str,
    chosen_name: String,
    rival_name: String,
    swap_z: Option<f64>,
    shown: &[String],
) -> Ambiguity {
    let why = match basis {
        "validation" => format!(
            "{chosen_name} predicts the validation rows better (paired z = {:.2})",
            swap_z.unwrap_or(f64::NAN)
        ),
        "only-fit" => format!("{chosen_name} kept: the other resolution could not be fitted"),
        _ => format!(
            "kept {chosen_name}, already in the model{}",
            swap_z.map_or(" (the data cannot tell them apart)".to_string(), |z| format!(
                " (the swap is not significantly better on the validation rows: z = {z:.2})"
            ))
        ),
    };
    Ambiguity {
        round: 0,
        sentence: format!(
            "{chosen_name} or {rival_name}: indistinguishable on these data (correlation {}); {why}",
            shown.join(", ")
        ),
        chosen: chosen_name,
        rivals: vec![rival_name],
        basis: basis.to_string(),
        validation_z: vec![swap_z],
    }
}

/// Cosine between two candidates' changes of the held-out predictions (`e0 − e_with`) over the
/// points both predict: near 1 = they correct the same thing.
pub(super) fn change_cosine(base: &CrossValidation, a: &CrossValidation, b: &CrossValidation) -> f64 {
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
pub(super) fn choose_among_rivals(
    candidates: &mut [Candidate],
    best: usize,
    held0: &CrossValidation,
    round: usize,
    ctx: &Context<'_>,
) -> Result<(usize, Option<Ambiguity>), DiscoveryError> {
    let rivals = rivals_of(candidates, best, held0);
    if rivals.is_empty() {
        return Ok((best, None));
    }
    let (chosen, basis) = match by_validation(candidates, best, &rivals, ctx)? {
        Some(chosen) => (chosen, "validation"),
        None => simplest(candidates, best, &rivals, ctx)?,
    };
    let ambiguity = rivalry(candidates, best, &rivals, (chosen, basis), round, ctx)?;
    if chosen != best {
        candidates[best].status = CandidateStatus::PassedNotBest;
    }
    Ok((chosen, Some(ambiguity)))
}

/// The refitted candidates whose held-out prediction changes point the same way as `best`'s
/// (cosine ≥ [`RIVAL_COSINE`]) and whose held-out errors are not distinguishable from its
/// (paired |z| < 2): passing ones, or ones that failed only the held-out test at z > 1.
fn rivals_of(candidates: &[Candidate], best: usize, held0: &CrossValidation) -> Vec<usize> {
    let Some((_, _, cv_best)) = candidates[best].refit.as_ref() else { return Vec::new() };
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
    rivals
}

/// Errors of candidate `i`'s refit on the validation rows (`None` without validation rows or
/// refit).
fn validation_errors(
    candidates: &[Candidate],
    i: usize,
    ctx: &Context<'_>,
) -> Result<Option<Vec<Option<Vector3<f64>>>>, DiscoveryError> {
    match (ctx.deciding_validation(), candidates[i].refit.as_ref()) {
        (Some(v), Some((_, f, _))) => Ok(Some(residuals(&f.model, v)?.into_iter().map(Some).collect())),
        _ => Ok(None),
    }
}

/// The rival that predicts the validation rows significantly better than `best` (the largest
/// paired z above 2), if any: the one that generalises.
fn by_validation(
    candidates: &[Candidate],
    best: usize,
    rivals: &[usize],
    ctx: &Context<'_>,
) -> Result<Option<usize>, DiscoveryError> {
    let Some(vb) = validation_errors(candidates, best, ctx)? else { return Ok(None) };
    let (mut chosen, mut best_z) = (None, 2.0);
    for &i in rivals {
        if let Some(vi) = validation_errors(candidates, i, ctx)? {
            let z = HeldOutComparison::new(&vb, &vi).z;
            if z > best_z {
                best_z = z;
                chosen = Some(i);
            }
        }
    }
    Ok(chosen)
}

/// When the validation rows do not prefer a rival: the simplest passing one (fewer fitted
/// parameters than `best`) among the rivals the validation rows do not show significantly
/// worse than `best` (a simpler rival that predicts them worse at z > 2 is not
/// "indistinguishable"), basis `simpler`; else `best`, basis `validation` when it predicts the
/// validation rows significantly better than every rival, `held-out` otherwise.
fn simplest(
    candidates: &[Candidate],
    best: usize,
    rivals: &[usize],
    ctx: &Context<'_>,
) -> Result<(usize, &'static str), DiscoveryError> {
    let size = |i: usize| candidates[i].refit.as_ref().map_or(usize::MAX, |r| r.0.fitted_params.len());
    let vb = validation_errors(candidates, best, ctx)?;
    let mut eligible = Vec::new();
    for &i in rivals {
        let worse = match (&vb, validation_errors(candidates, i, ctx)?) {
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
        return Ok((simpler, "simpler"));
    }
    Ok((best, if eligible.is_empty() && !rivals.is_empty() { "validation" } else { "held-out" }))
}

/// The ambiguity of round `round`: `best` and its `rivals`, the one `chosen` and why.
fn rivalry(
    candidates: &[Candidate],
    best: usize,
    rivals: &[usize],
    (chosen, basis): (usize, &str),
    round: usize,
    ctx: &Context<'_>,
) -> Result<Ambiguity, DiscoveryError> {
    let mut group: Vec<usize> = vec![best];
    group.extend(rivals);
    let others: Vec<usize> = group.iter().copied().filter(|i| *i != chosen).collect();
    let vc = validation_errors(candidates, chosen, ctx)?;
    let mut validation_z = Vec::new();
    for &i in &others {
        validation_z.push(match (&vc, validation_errors(candidates, i, ctx)?) {
            (Some(c), Some(o)) => Some(HeldOutComparison::new(&o, c).z),
            _ => None,
        });
    }
    let label = |i: usize| candidates[i].spec.label();
    let names: Vec<String> = group.iter().map(|i| label(*i)).collect();
    let why = match basis {
        "validation" => format!("{} predicts the validation rows better", label(chosen)),
        "simpler" => format!("the data cannot tell them apart, {} has fewer parameters", label(chosen)),
        _ if ctx.deciding_validation().is_some() => {
            format!(
                "neither predicts the validation rows significantly better; kept {}, the larger held-out improvement",
                label(chosen)
            )
        }
        _ => format!("kept {}, the larger held-out improvement", label(chosen)),
    };
    let sentence = format!("{}: indistinguishable on these data; {why}", names.join(" or "));
    Ok(Ambiguity {
        round,
        chosen: label(chosen),
        rivals: others.iter().map(|i| label(*i)).collect(),
        basis: basis.to_string(),
        validation_z,
        sentence,
    })
}
