//! The record of an added effect: its values, evidence, gap before and after, the plot of the
//! residual against its driver; and the final model's predicted uncertainty.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;

use super::candidate::Candidate;
use super::context::{Context, CrossValidation};
use super::decide::IMPLAUSIBLE;
use super::report::{
    AddedEffect, BoundHit, CandidateStatus, DriverPlot, Gap, NegligibleEffect, PredictedUncertainty,
    RefitEvidence, file_value,
};
use super::stop::nothing_added;
use crate::DiscoveryError;
use crate::catalog::{driver_of_in, meaning};
use crate::fit::Fit;
use crate::location::PoseData;

pub(super) fn driver_plot(
    spec: &EffectSpec,
    model: &Model,
    ms: &[Measurement],
    before: &[Vector3<f64>],
    after: &[Vector3<f64>],
) -> Result<DriverPlot, DiscoveryError> {
    let n = model.joint_count() as u8;
    let driver = driver_of_in(spec, model.guide_joint().unwrap_or(1) as u8, n);
    let pose = PoseData::of(model, ms)?;
    let joint = spec.joint().map(usize::from).filter(|j| model.is_revolute(*j));
    let y_label = match joint {
        Some(j) => format!("residual as joint-{j} angle error [urad]"),
        None => "residual norm [um]".to_string(),
    };
    let mut plot = DriverPlot {
        x_label: driver.label_for(model.joint_kinds()),
        y_label,
        x: Vec::new(),
        before: Vec::new(),
        after: Vec::new(),
    };
    for (i, m) in ms.iter().enumerate() {
        let Some(x) = driver.value(i, m, &pose) else { continue };
        let y = |r: &Vector3<f64>| match (joint, pose.joint_directions.as_ref()) {
            (Some(j), Some(dirs)) => {
                let d = dirs[i][j - 1];
                let l2 = d.norm_squared();
                if l2 > 0.0 { 1e6 * r.dot(&d) / l2 } else { 0.0 }
            }
            _ => 1e3 * r.norm(),
        };
        plot.x.push(x);
        plot.before.push(y(&before[i]));
        plot.after.push(y(&after[i]));
    }
    Ok(plot)
}

/// The record of an added candidate (its refit must be present).
pub(super) fn added_effect(
    c: &Candidate,
    round: usize,
    current: &Fit,
    gap_before: &Gap,
    ctx: &Context<'_>,
) -> Result<(AddedEffect, Fit, CrossValidation), DiscoveryError> {
    let lost = || DiscoveryError::Numerical("internal: the added candidate has no refit or score".into());
    let (evidence, fit1, _) = c.refit.as_ref().ok_or_else(lost)?;
    let held1 = ctx.cross_validate(&fit1.model, &fit1.params, &ctx.all_folds);
    let gap_after = ctx.gap(&fit1.model, &held1)?;
    let added = added_record(c, evidence, fit1, round, current, gap_before, &gap_after, ctx)?;
    Ok((added, fit1.clone(), held1))
}

/// The record of candidate `c` added with the refit `fit1` (its own or a block's) and its
/// evidence; values and standard errors restricted to `c`'s parameters.
#[allow(clippy::too_many_arguments)]
pub(super) fn added_record(
    c: &Candidate,
    evidence: &RefitEvidence,
    fit1: &Fit,
    round: usize,
    current: &Fit,
    gap_before: &Gap,
    gap_after: &Gap,
    ctx: &Context<'_>,
) -> Result<AddedEffect, DiscoveryError> {
    let lost = || DiscoveryError::Numerical("internal: the added candidate has no score".into());
    let score = c.score.ok_or_else(lost)?;
    let keys: Vec<String> = c.new_params.iter().map(|p| file_value(*p, 0.0).0).collect();
    let own = |m: &BTreeMap<String, f64>| -> BTreeMap<String, f64> {
        m.iter().filter(|(k, _)| keys.contains(k)).map(|(k, v)| (k.clone(), *v)).collect()
    };
    let plot = driver_plot(&c.spec, &fit1.model, ctx.measurements, &current.residuals, &fit1.residuals)?;
    Ok(AddedEffect {
        effect: c.spec.kind().name().to_string(),
        joint: c.spec.joint(),
        label: c.spec.label(),
        meaning: meaning(c.spec.kind()).to_string(),
        spec: c.spec,
        round,
        how: format!(
            "forward search: passed alone (held-out z = {:.1} > {:.2})",
            evidence.heldout.z, evidence.z_required
        ),
        values: own(&evidence.values),
        std_errors: own(&evidence.std_errors),
        novelty: c.directions.as_ref().map_or(0.0, |d| d.novelty),
        score,
        comparison: evidence.comparison,
        heldout: evidence.heldout,
        confounding: evidence.confounding.clone(),
        gap_before_mm: gap_before.headline_mm(),
        gap_after_mm: gap_after.headline_mm(),
        gap_before: gap_before.clone(),
        gap_after: gap_after.clone(),
        plot,
    })
}

/// Appends to `records` the record `r` of candidate `c`, then one record per lower-order effect
/// it was proposed with ([`super::screen::missing_prerequisites`]: the linear compliance fitted
/// with a `τ|τ|` term), each with its own parameters' values and the same evidence; `r` keeps
/// only the values of `c`'s own parameters. An effect already in `records` (a lower-order
/// effect that was a candidate of the same group too) is not recorded twice.
pub(super) fn push_with_prerequisites(
    records: &mut Vec<AddedEffect>,
    mut r: AddedEffect,
    c: &Candidate,
    fit1: &Fit,
) {
    // only those it was proposed with and that the fit holds (a refit resolving rivals may
    // have kept a look-alike already in the model in their place)
    let lower: Vec<EffectSpec> = c
        .spec
        .prerequisites()
        .into_iter()
        .filter(|e| {
            let params = e.params();
            params.iter().any(|p| c.new_params.contains(p))
                && params.iter().all(|p| fit1.params.index_of(*p).is_some())
        })
        .collect();
    let mut push = |rec: AddedEffect| {
        if !records.iter().any(|x| x.spec == rec.spec) {
            records.push(rec);
        }
    };
    if lower.is_empty() {
        return push(r);
    }
    let keys =
        |spec: &EffectSpec| -> Vec<String> { spec.params().iter().map(|p| file_value(*p, 0.0).0).collect() };
    let only = |m: &BTreeMap<String, f64>, k: &[String]| -> BTreeMap<String, f64> {
        m.iter().filter(|(name, _)| k.contains(name)).map(|(name, v)| (name.clone(), *v)).collect()
    };
    let mut lower_records = Vec::with_capacity(lower.len());
    for spec in lower {
        let k = keys(&spec);
        let mut p = r.clone();
        p.effect = spec.kind().name().to_string();
        p.joint = spec.joint();
        p.label = spec.label();
        p.meaning = meaning(spec.kind()).to_string();
        p.spec = spec;
        p.how = format!("{}; the first-order term of {}, fitted with it", r.how, r.label);
        p.values = only(&r.values, &k);
        p.std_errors = only(&r.std_errors, &k);
        lower_records.push(p);
    }
    let own = keys(&c.spec);
    r.values = only(&r.values, &own);
    r.std_errors = only(&r.std_errors, &own);
    push(r);
    lower_records.into_iter().for_each(push);
}

/// Predicted TCP uncertainty of the final model at the validation poses (or the measurement
/// poses), without and with the systematic CMM errors.
pub(super) fn predicted_uncertainty(
    model: &Model,
    params: &ParamSet,
    ctx: &Context<'_>,
) -> Result<PredictedUncertainty, String> {
    let id = vatcal_identification::identify(model, ctx.measurements, params, &ctx.options.identify)
        .map_err(|e| e.to_string())?;
    let cmm = vatcal_identification::CmmUncertainty::new(
        &id,
        ctx.measurements,
        &ctx.options.identify.weights,
        ctx.options.cmm_sigma_mm,
    )
    .map_err(|e| e.to_string())?;
    let (label, poses) = match ctx.validation {
        Some(v) if !v.is_empty() => ("validation", v),
        _ => ("measurements", ctx.measurements),
    };
    let (mut stat, mut total) = (0.0, 0.0);
    for m in poses {
        stat += id.predicted_position_sigma(&m.q, m.tcp).map_err(|e| e.to_string())?.norm();
        total += cmm.total_sigma(&id, &m.q, m.tcp).map_err(|e| e.to_string())?.norm();
    }
    let n = poses.len().max(1) as f64;
    Ok(PredictedUncertainty {
        poses: label.to_string(),
        count: poses.len(),
        statistical_mean_mm: stat / n,
        with_cmm_mean_mm: total / n,
        cmm_sigma_mm: ctx.options.cmm_sigma_mm,
    })
}

/// An addition of a round: the effect added (the first member of a block), the block's other
/// members, the new current fit and its all-data cross-validation.
pub(super) struct Addition {
    /// the effect added (a block's first member)
    pub(super) added: AddedEffect,
    /// a block's other members
    pub(super) extra: Vec<AddedEffect>,
    /// the fit with the addition
    pub(super) fit: Fit,
    /// its all-data cross-validation (the reported gap)
    pub(super) held_all: CrossValidation,
    /// the block's members (indices into the round's candidates), when a block was added
    pub(super) block: Option<Vec<usize>>,
    /// the look-alikes among which the added one was chosen, in one sentence
    pub(super) ambiguity_line: Option<String>,
    /// the joint search's account of the set it added, in one sentence
    pub(super) joint_line: Option<String>,
}

/// How a group of candidates was added: the block step's members, or the joint search's set
/// with its account in one sentence.
pub(super) enum GroupOrigin {
    /// the block step (the members' indices)
    Block(Vec<usize>),
    /// the joint search (its account)
    JointSearch(String),
}

/// How each member of a group entered the model, from the number of other members and the
/// group's evidence (the `how` of its record).
pub(super) type HowAdded<'a> = &'a dyn Fn(usize, &RefitEvidence) -> String;

/// Marks a group's members added and records them (the first as the addition, the others as
/// its extra members) with the group's evidence; `how(other members, evidence)` says how each
/// entered. Returns the addition and the group's confirmation cross-validation.
pub(super) fn record_group(
    candidates: &mut [Candidate],
    members: &[usize],
    (evidence, fit1, held1): (&RefitEvidence, Fit, CrossValidation),
    (round, current, gap): (usize, &Fit, &Gap),
    (origin, how): (GroupOrigin, HowAdded<'_>),
    ctx: &Context<'_>,
) -> Result<Option<(Addition, CrossValidation)>, DiscoveryError> {
    let held_gap = ctx.cross_validate(&fit1.model, &fit1.params, &ctx.all_folds);
    let gap_after = ctx.gap(&fit1.model, &held_gap)?;
    let mut records = Vec::new();
    for i in members {
        let mut r = added_record(&candidates[*i], evidence, &fit1, round, current, gap, &gap_after, ctx)?;
        r.how = how(members.len() - 1, evidence);
        push_with_prerequisites(&mut records, r, &candidates[*i], &fit1);
        candidates[*i].status = CandidateStatus::Added;
    }
    let extra = records.split_off(1);
    let Some(added) = records.pop() else { return Ok(None) };
    let (block, joint_line) = match origin {
        GroupOrigin::Block(m) => (Some(m), None),
        GroupOrigin::JointSearch(line) => (None, Some(line)),
    };
    let addition =
        Addition { added, extra, fit: fit1, held_all: held_gap, block, ambiguity_line: None, joint_line };
    Ok(Some((addition, held1)))
}

/// The round's bound hits and negligible effects (refitted candidates refused at a
/// plausibility bound / detected but negligible).
pub(super) fn findings(candidates: &[Candidate], round: usize) -> (Vec<BoundHit>, Vec<NegligibleEffect>) {
    let mut bound_hits = Vec::new();
    let mut negligible = Vec::new();
    for c in candidates {
        if let (CandidateStatus::Rejected(why), Some((e, ..))) = (&c.status, &c.refit)
            && let Some(reason) = why.strip_prefix(IMPLAUSIBLE)
        {
            bound_hits.push(BoundHit {
                round,
                effect: c.spec.kind().name().to_string(),
                label: c.spec.label(),
                reason: reason.to_string(),
                heldout_z: e.heldout.z,
                otherwise_passed: true,
            });
        }
        if let (CandidateStatus::DetectedNegligible(_), Some((e, ..))) = (&c.status, &c.refit) {
            negligible.push(NegligibleEffect {
                label: c.spec.label(),
                round,
                change_um: 1e3 * e.heldout.change_rms_mm,
                heldout: e.heldout,
            });
        }
    }
    (bound_hits, negligible)
}

/// What the round decided, in one sentence (before the backward check).
pub(super) fn decision(next: Option<&Addition>, candidates: &[Candidate], ln_screen: f64) -> String {
    let Some(next) = next else { return nothing_added(candidates, ln_screen) };
    let added = &next.added;
    if let Some(line) = &next.joint_line {
        return format!(
            "no candidate passed alone and no block passed; {line}; gap {:.4} -> {:.4} mm",
            added.gap_before_mm, added.gap_after_mm
        );
    }
    match (&next.block, &next.ambiguity_line) {
        (Some(members), _) => {
            let labels: Vec<String> = members.iter().map(|i| candidates[*i].spec.label()).collect();
            format!(
                "no candidate passed alone; added together as a block ({}): held-out RMS {:.4} -> {:.4} mm, z = {:.1}, predictions change {:.1} um; gap {:.4} -> {:.4} mm",
                labels.join(", "),
                added.heldout.rms_before_mm,
                added.heldout.rms_after_mm,
                added.heldout.z,
                1e3 * added.heldout.change_rms_mm,
                added.gap_before_mm,
                added.gap_after_mm
            )
        }
        (None, Some(a)) => format!("{}; {a}", added.summary_line()),
        (None, None) => added.summary_line(),
    }
}
