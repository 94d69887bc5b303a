//! **The keep-going rule**: how far the held-out gap is from its floor (far from it a round
//! confirms its best-scored candidates whatever their screening score), which passing
//! candidate is best, and why a round added nothing (the loop stops).

use super::candidate::Candidate;
use super::context::{Context, CrossValidation, kind_weight};
use super::report::CandidateStatus;

/// The held-out gap of the current model (`held`: its all-data cross-validation) over the
/// floor estimate `√(3σ₁²(1 + p/N))`: σ₁ the per-axis noise of a weight-1 row — the noise
/// reference (replicates or instruments) or, without one, the round's saturated σ̂ — `p`
/// the fitted rank and `N` the scalar residuals (the cross-validated prediction of a correct
/// model misses by the noise plus its own estimation error). Rows are weighted by kind as in
/// the fits. `None` when no σ is known.
pub(super) fn gap_over_floor(
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

/// Index of the passing candidate with the largest held-out improvement.
pub(super) fn best_passing(candidates: &[Candidate]) -> Option<usize> {
    let key = |c: &Candidate| c.refit.as_ref().map_or(f64::NEG_INFINITY, |r| r.0.heldout.mean_reduction_mm2);
    candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.status == CandidateStatus::PassedNotBest)
        .max_by(|a, b| key(a.1).total_cmp(&key(b.1)))
        .map(|(i, _)| i)
}

/// Why nothing was added, naming the best-scored candidate.
pub(super) fn nothing_added(candidates: &[Candidate], ln_threshold: f64) -> String {
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
