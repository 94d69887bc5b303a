//! The `plan` stage: candidate measurement poses, Detmax selection and the time-optimal tour on
//! the nominal cell, written as a plan folder (`plan/`).
//!
//! Input: the run's options and the nominal model; output: the plan's summary and the parameter
//! set it was selected for. Deterministic: a run folder whose plan is done recomputes the same
//! plan ([`plan_recompute`]).

use vatcal_core::ParamSet;
use vatcal_kinematics::Model;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::PlanSummary;
use vatcal_planning::plan::plan_campaign;

use crate::folders::PlanFolder;
use crate::{PipelineError, RunOptions, plan_options};

/// Plans the campaign on the nominal cell and writes the plan folder; returns the number of
/// candidates, the plan summary and the parameter set the plan was selected for (the paper's
/// 34 on the canonical cell, the chain's identifiable default set otherwise).
///
/// # Errors
/// Planning fails or the folder cannot be written.
pub fn plan_stage(
    opts: &RunOptions,
    nominal: &Model,
    geometry: &CellGeometry,
    folder: &PlanFolder,
) -> Result<(usize, PlanSummary, ParamSet), PipelineError> {
    let plan = plan_campaign(nominal, geometry, &plan_options(opts))?;
    let summary = folder.write(&plan)?;
    Ok((plan.candidates.candidates.len(), summary, plan.params))
}

/// The plan of [`plan_stage`] computed again without writing it (deterministic: the plan the
/// folder holds): its summary and parameter set.
///
/// # Errors
/// Planning fails.
pub fn plan_recompute(
    opts: &RunOptions,
    nominal: &Model,
    geometry: &CellGeometry,
) -> Result<(PlanSummary, ParamSet), PipelineError> {
    let plan = plan_campaign(nominal, geometry, &plan_options(opts))?;
    Ok((PlanSummary::of(&plan), plan.params))
}
