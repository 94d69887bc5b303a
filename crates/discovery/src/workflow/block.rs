//! **The block step**: when no candidate passes alone, the ones that each helped by more than
//! one standard error are refitted and confirmed together.

use vatcal_core::ParamId;
use vatcal_core::effects::EffectSpec;

use super::candidate::Candidate;
use super::confirm::refit_effects;
use super::context::{Context, CrossValidation};
use super::decide::{HELDOUT_NOT_LOWER, decide};
use super::options::DiscoverOptions;
use super::record::{Addition, GroupOrigin, record_group};
use super::report::{CandidateStatus, Gap, RefitEvidence};
use super::screen::Thresholds;
use super::veto::{VALIDATION_WORSE, validation_worse};
use crate::DiscoveryError;
use crate::distributions::normal_upper_quantile;
use crate::fit::Fit;

/// z the block must exceed in a round that spends `spend` ([`super::round_spending`]): one more
/// test of the round, at `confirm_alpha·spend/(max_refits + 1)`.
pub(super) fn block_z(options: &DiscoverOptions, spend: f64) -> f64 {
    normal_upper_quantile(options.confirm_alpha * spend / (options.max_refits.max(1) + 1) as f64)
}

/// Whether a refitted candidate failed **only** the held-out z-test but still lowered the
/// held-out error by more than one standard error and changed the predictions by more than
/// the noise, or passed everything but was refused **only** by the validation veto (alone it
/// made the validation rows worse — e.g. one of two large look-alikes missing together): a
/// member of the round's block, which is confirmed and vetoed as a whole.
pub(super) fn block_member(c: &Candidate) -> bool {
    let Some((e, f, _)) = &c.refit else { return false };
    matches!(&c.status, CandidateStatus::Rejected(why)
        if why.starts_with(HELDOUT_NOT_LOWER) || why.starts_with(VALIDATION_WORSE))
        && f.converged
        && e.implausible.is_none()
        && e.heldout.z > 1.0
        && e.heldout.change_rms_mm >= e.negligible_below_mm.max(e.floor_below_mm)
}

/// The block step of a round in which no candidate passed alone (module docs): the refitted
/// candidates that each lowered the held-out error by more than one standard error are
/// refitted **together** and confirmed together at `z_block` (one more test of the round).
/// Returns the members' indices and the block's evidence, fit and confirmation CV when the
/// block passes the decision rule.
#[allow(clippy::too_many_arguments)]
pub(super) fn block_step(
    candidates: &[Candidate],
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &CrossValidation,
    z_block: f64,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Option<(Vec<usize>, RefitEvidence, Fit, CrossValidation)> {
    let members: Vec<usize> = (0..candidates.len()).filter(|i| block_member(&candidates[*i])).collect();
    if members.len() < 2 {
        return None;
    }
    let effects: Vec<(EffectSpec, Vec<ParamId>)> =
        members.iter().map(|i| (candidates[*i].spec, candidates[*i].new_params.clone())).collect();
    let th = Thresholds { ln_screen: f64::NAN, z_required: z_block, far_from_floor: false };
    match refit_effects(current, j0, rank0, held0, &effects, &th, ctx, notes) {
        Ok((evidence, fit1, held1)) => match decide(&evidence, &fit1) {
            CandidateStatus::PassedNotBest if validation_worse(current, &fit1, ctx) => {
                notes.push(format!("block not added: {VALIDATION_WORSE}"));
                None
            }
            CandidateStatus::PassedNotBest => Some((members, evidence, fit1, held1)),
            other => {
                let label = effects.iter().map(|(s, _)| s.label()).collect::<Vec<_>>().join(" + ");
                notes.push(format!("block {label} not added: {other:?}"));
                None
            }
        },
        Err(why) => {
            notes.push(format!("block refit failed: {why}"));
            None
        }
    }
}

/// The block step of a round in which no candidate passed alone and the block step is on:
/// when the block passes, its members are marked added and recorded (the first as the
/// addition, the others as its extra members). Returns the addition and the block's
/// confirmation cross-validation (that of the new current model).
#[allow(clippy::too_many_arguments)]
pub(super) fn add_block(
    candidates: &mut [Candidate],
    current: &Fit,
    j0: &faer::Mat<f64>,
    rank0: usize,
    held0: &CrossValidation,
    (round, spend): (usize, f64),
    gap: &Gap,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<Option<(Addition, CrossValidation)>, DiscoveryError> {
    let z_block = block_z(&ctx.options, spend);
    let Some((members, evidence, fit1, held1)) =
        block_step(candidates, current, j0, rank0, held0, z_block, ctx, notes)
    else {
        return Ok(None);
    };
    let how = |others: usize, e: &RefitEvidence| {
        format!(
            "block step: none passed alone; confirmed together with the {others} other member(s) (held-out z = {:.1} > {:.2})",
            e.heldout.z, e.z_required
        )
    };
    record_group(
        candidates,
        &members.clone(),
        (&evidence, fit1, held1),
        (round, current, gap),
        (GroupOrigin::Block(members), &how),
        ctx,
    )
}
