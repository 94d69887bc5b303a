//! **The validation veto**: an addition that makes the validation rows' error significantly
//! larger is refused.

use nalgebra::Vector3;

use super::candidate::Candidate;
use super::context::Context;
use super::report::CandidateStatus;
use crate::DiscoveryError;
use crate::criteria::HeldOutComparison;
use crate::fit::{Fit, residuals};

/// Refuses (status `Rejected`) every passing candidate whose refit predicts the validation
/// rows significantly worse than the current model (paired z of the squared errors below
/// `-`[`VETO_Z`]): an addition that makes the gap on data the fit never saw larger is not
/// kept.
pub(super) fn veto_on_validation(
    candidates: &mut [Candidate],
    current: &Fit,
    ctx: &Context<'_>,
) -> Result<(), DiscoveryError> {
    let Some(v) = ctx.deciding_validation().filter(|_| ctx.options.validation_veto) else {
        return Ok(());
    };
    let before: Vec<Option<Vector3<f64>>> = residuals(&current.model, v)?.into_iter().map(Some).collect();
    for c in candidates.iter_mut().filter(|c| c.status == CandidateStatus::PassedNotBest) {
        let Some((_, f, _)) = c.refit.as_ref() else { continue };
        let after: Vec<Option<Vector3<f64>>> = residuals(&f.model, v)?.into_iter().map(Some).collect();
        let h = HeldOutComparison::new(&before, &after);
        if h.z < -VETO_Z {
            c.status = CandidateStatus::Rejected(format!(
                "{VALIDATION_WORSE} (RMS {:.4} -> {:.4} mm over {} rows, z = {:.2})",
                h.rms_before_mm, h.rms_after_mm, h.points, h.z
            ));
        }
    }
    Ok(())
}

/// Whether `fit1` predicts the validation rows significantly worse than `current` (paired z
/// below `-`[`VETO_Z`]; false without validation rows, when they do not decide, or with the
/// veto off).
pub(super) fn validation_worse(current: &Fit, fit1: &Fit, ctx: &Context<'_>) -> bool {
    let Some(v) = ctx.deciding_validation().filter(|_| ctx.options.validation_veto) else {
        return false;
    };
    match (residuals(&current.model, v), residuals(&fit1.model, v)) {
        (Ok(b), Ok(a)) => {
            let wrap = |r: Vec<Vector3<f64>>| r.into_iter().map(Some).collect::<Vec<_>>();
            HeldOutComparison::new(&wrap(b), &wrap(a)).z < -VETO_Z
        }
        _ => false,
    }
}

/// Paired z below `-VETO_Z` on the validation rows refuses an addition: the rows must be
/// significantly worse with it, not merely worse by chance.
pub const VETO_Z: f64 = 2.0;

/// Start of the rejection reason of a candidate refused by [`veto_on_validation`].
pub(super) const VALIDATION_WORSE: &str = "the validation rows' error grows with it";
