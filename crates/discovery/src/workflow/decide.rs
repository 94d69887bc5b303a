//! **The decision rule** of a refitted candidate (module docs of [`super`], step 3): held-out
//! z, the size rule, plausibility.

use super::report::{CandidateStatus, RefitEvidence};
use crate::fit::Fit;

/// Start of the rejection reason of a candidate refused at a plausibility bound.
pub(super) const IMPLAUSIBLE: &str = "implausible: ";

/// Start of the rejection reason of a candidate that failed the held-out z-test.
pub(super) const HELDOUT_NOT_LOWER: &str = "held-out error not lower by more than its uncertainty";

/// The decision rule: what the evidence says about adding the effect.
pub(super) fn decide(e: &RefitEvidence, fit1: &Fit) -> CandidateStatus {
    let h = &e.heldout;
    if !fit1.converged {
        return CandidateStatus::Rejected("refit did not converge".into());
    }
    if h.points < 2 {
        return CandidateStatus::Rejected("no held-out predictions (every confirmation fold failed)".into());
    }
    if h.z.is_nan() || h.z <= e.z_required {
        return CandidateStatus::Rejected(format!(
            "{HELDOUT_NOT_LOWER} (RMS {:.4} -> {:.4} mm, reduction {:.3e} +- {:.3e} mm2, z = {:.2} < {:.2})",
            h.rms_before_mm, h.rms_after_mm, h.mean_reduction_mm2, h.std_error_mm2, h.z, e.z_required
        ));
    }
    let waived = e.size_rule_waived_far_from_floor || e.size_rule_waived_above_z.is_some_and(|z| h.z >= z);
    if h.change_rms_mm < e.floor_below_mm {
        return CandidateStatus::DetectedNegligible(format!(
            "detected, negligible ({:.2} um): predictions change by less than the physical noise floor ({:.2} um = sqrt(3) x {:.2} um per axis), whatever the estimate of the noise",
            1e3 * h.change_rms_mm,
            1e3 * e.floor_below_mm,
            1e3 * e.floor_below_mm / 3f64.sqrt()
        ));
    }
    if h.change_rms_mm < e.negligible_below_mm && !waived {
        return CandidateStatus::DetectedNegligible(format!(
            "detected, negligible ({:.1} um): predictions change by less than the noise ({:.1} um){}",
            1e3 * h.change_rms_mm,
            1e3 * e.negligible_below_mm,
            e.size_rule_waived_above_z
                .map(|z| format!(
                    " estimated by sigma-hat, and the held-out z = {:.2} is below {z:.2}, at which the size rule is waived",
                    h.z
                ))
                .unwrap_or_default()
        ));
    }
    if let Some(why) = &e.implausible {
        return CandidateStatus::Rejected(format!("{IMPLAUSIBLE}{why}"));
    }
    CandidateStatus::PassedNotBest
}
