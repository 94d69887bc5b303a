//! The glue to [`crate::propose`]: the minimum detectable size of every borderline candidate
//! (what a further campaign would need to decide it).

use super::candidate::Candidate;
use super::report::CandidateStatus;
use crate::power::{DEFAULT_POWER, Detectability};

/// Attaches the minimum detectable size to every borderline candidate: scored, not added, and
/// refitted or nominally significant at 1 % alone.
pub(super) fn mark_borderline(
    candidates: &mut [Candidate],
    sigma: f64,
    ln_threshold: f64,
    n_screen: usize,
    total: usize,
) {
    for c in candidates.iter_mut() {
        let (Some(score), Some(d)) = (c.score, c.directions.as_ref()) else { continue };
        let refitted = c.refit.is_some();
        if matches!(c.status, CandidateStatus::Added | CandidateStatus::PassedNotBest)
            || !(refitted || score.ln_p_value < 0.01f64.ln())
        {
            continue;
        }
        let heldout = c.refit.as_ref().map(|(e, ..)| (e.heldout.z, e.z_required));
        c.detect = Some(
            Detectability::new(d.dof, d.novelty, sigma, n_screen, ln_threshold + c.ln_weight, DEFAULT_POWER)
                .with_observed(score.statistic, heldout, total),
        );
    }
}
