//! The `validation` stage: random poses and a printing path measured with the laser tracker,
//! commanded by every model of the run (nominal, calibrated, discovered, …); the two
//! printing-path runs of the nominal and the calibrated model are the uncompensated and
//! compensated targets of `vatcal-compensation` (checked before any motion by the
//! `compensation` module). The printing path (the guide lifting the part out of the tank)
//! exists on the canonical Meca500-on-guide cell only: any other chain is validated on the
//! random poses alone ([`has_printing_path`]).
//!
//! Input: the devices, the models, where the last campaign left the arm; output:
//! [`ValidationStage`] (the plan, the tracker records, each model's errors) and the tracker
//! registration (`tracker-registration.json`, unless the devices skip it).

use serde::{Deserialize, Serialize};
use vatcal_campaign::validation::{
    ModelValidation, PrintingPathOptions, RandomPoseOptions, ValidationPlan, ValidationPlanOptions,
    ValidationRecords, build_validation_plan, evaluate,
};
use vatcal_campaign::{CampaignConfig, CampaignPlan, CampaignReport, Journal};
use vatcal_core::JointVector;
use vatcal_kinematics::Model;
use vatcal_planning::geometry::CellGeometry;

use crate::campaign_runner::run_campaign;
use crate::folders::{PlanFolder, PlanKind, RunFolder, VALIDATION_JOURNAL};
use crate::registration::{RegistrationReport, registration_step};
use crate::{DeviceSet, PipelineError, Progress, RunOptions, Stage};

/// Whether the validation of `nominal` has the printing path: the guide lifts the part out of
/// the tank like a printer's z axis, so only the canonical Meca500-on-guide cell has it (its
/// IK and tank geometry); any other chain is validated on random poses only.
pub fn has_printing_path(nominal: &Model) -> bool {
    nominal.is_meca500_on_guide()
}

/// Seed of the validation stage, independent of the planning seed.
pub fn validation_seed(seed: u64) -> u64 {
    seed ^ 0x5eed_7a11_da7e_0001
}

/// The validation options of a run, starting where the calibration campaign left the arm.
pub fn validation_options(opts: &RunOptions, start: Option<JointVector>) -> ValidationPlanOptions {
    ValidationPlanOptions {
        random: RandomPoseOptions { count: opts.sizes.random_poses, ..RandomPoseOptions::default() },
        printing: PrintingPathOptions { slices: opts.sizes.slices, ..PrintingPathOptions::default() },
        motion: opts.nominal.motion_limits(),
        start,
        seed: validation_seed(opts.seed),
        ..ValidationPlanOptions::default()
    }
}

/// The validation campaign of a run — random poses and the printing path commanded by each of
/// `commanding` (the nominal model first) — as the `validation` stage of `vatcal calibrate`
/// plans it ([`validation_options`] of `opts`, starting at `start`; a chain without the
/// printing path is validated on random poses within one turn per joint), and its options.
///
/// # Errors
/// The plan cannot be built (too few collision-free poses, a path no model can command, …).
pub fn validation_plan(
    opts: &RunOptions,
    nominal: &Model,
    geometry: &CellGeometry,
    commanding: &[(&str, &Model)],
    start: Option<JointVector>,
) -> Result<(ValidationPlan, ValidationPlanOptions), PipelineError> {
    let mut options = validation_options(opts, start);
    if !has_printing_path(nominal) {
        options.printing.slices = 0;
        // one turn per joint: the path planner connects the random poses of a ±360° arm
        options.random.revolute_range_deg = Some(360.0);
    }
    let plan = build_validation_plan(nominal, geometry, commanding, &options)?;
    Ok((plan, options))
}

/// `summary.json` of a validation plan folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationPlanSummary {
    /// `validation`
    pub kind: PlanKind,
    /// the master seed (the validation's own seed is derived from it, [`validation_seed`])
    pub seed: u64,
    /// random poses (visited first)
    pub random_poses: usize,
    /// slices of the printing path (0 on a chain without it)
    pub slices: usize,
    /// the models commanding a run of the printing path, in execution order
    pub path_runs: Vec<String>,
    /// SMRs measured at every slice
    pub slice_targets: Vec<u32>,
    /// tracker measurements in all
    pub tracker_measurements: usize,
    /// campaign steps
    pub steps: usize,
    /// legs between random poses that needed RRT-Connect
    pub rrt_legs: usize,
}

/// Writes a validation plan folder: `tour.csv` (`track` rows) and `summary.json`
/// ([`ValidationPlanSummary`]); returns the summary.
///
/// # Errors
/// A file that cannot be written.
pub fn write_validation_plan(
    plan: &ValidationPlan,
    nominal: &Model,
    seed: u64,
    folder: &PlanFolder,
) -> Result<ValidationPlanSummary, PipelineError> {
    std::fs::create_dir_all(folder.dir())
        .map_err(|source| PipelineError::Io { path: folder.dir().to_path_buf(), source })?;
    plan.campaign.write_tour_for(folder.path("tour.csv"), nominal.joint_kinds())?;
    let summary = ValidationPlanSummary {
        kind: PlanKind::Validation,
        seed,
        random_poses: plan.random_poses.len(),
        slices: plan.slices.len(),
        path_runs: plan.path_runs.iter().map(|r| r.label.clone()).collect(),
        slice_targets: plan.slice_targets.clone(),
        tracker_measurements: plan.measurement_count(),
        steps: plan.campaign.steps.len(),
        rrt_legs: plan.rrt_legs,
    };
    let path = folder.path("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .map_err(|source| PipelineError::Io { path, source })?;
    Ok(summary)
}

/// Runs a tracker campaign `tour` (a validation plan's) on `devices` into the run folder's
/// `validation.journal` (resumed when present): first the tracker registration
/// ([`registration_step`]: the folder's when there is one), then every
/// step, each tracker reading mapped into the tank frame by the registration.
///
/// # Errors
/// The devices have no tracker (before anything moves), the registration or the campaign
/// fails.
pub fn tracker_campaign_stage(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    tour: &CampaignPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<(CampaignReport, Option<RegistrationReport>), PipelineError> {
    if devices.devices().tracker.is_none() {
        return Err(PipelineError::Option {
            option: "devices".into(),
            reason: "the validation measures with a laser tracker and the devices have none (add a `tracker` entry \
                     to the devices file)"
                .into(),
        });
    }
    let registration = registration_step(devices, nominal, folder.dir(), config.tracker_retries)?;
    let frame = registration.as_ref().and_then(|r| r.tank_from_tracker());
    let journal = folder.path(VALIDATION_JOURNAL);
    let report =
        run_campaign(devices, nominal, tour, &journal, config, Stage::Validate, frame.as_ref(), progress)?;
    Ok((report, registration))
}

/// What the validation stage produced.
#[derive(Debug)]
pub struct ValidationStage {
    /// the planned validation campaign
    pub plan: ValidationPlan,
    /// the tracker measurements
    pub records: ValidationRecords,
    /// the errors of each model
    pub results: Vec<ModelValidation>,
}

/// Runs the tracker validation `plan` of `models` on the same devices (the session
/// continues): the tracker registration and the campaign ([`tracker_campaign_stage`],
/// journal `validation.journal`), then the evaluation of every model; returns the stage and
/// the registration (`None` when the devices skip it).
///
/// # Errors
/// The devices have no tracker, the registration, the campaign or the evaluation fails.
pub fn validation_stage(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    models: &[(&str, &Model)],
    plan: ValidationPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<(ValidationStage, Option<RegistrationReport>), PipelineError> {
    let (report, registration) =
        tracker_campaign_stage(devices, nominal, &plan.campaign, folder, config, progress)?;
    let records = plan.collect(&report.records)?;
    let results = evaluate(&records, &plan.slices, models, &smrs(nominal))?;
    Ok((ValidationStage { plan, records, results }, registration))
}

/// The validation of a run folder whose validation stage is done, recomputed from its
/// `validation.journal` (deterministic: the same evaluation as the run that measured it).
///
/// # Errors
/// A missing or damaged journal, or records that do not fit `plan`.
pub fn validation_recompute(
    nominal: &Model,
    models: &[(&str, &Model)],
    plan: ValidationPlan,
    folder: &RunFolder,
) -> Result<ValidationStage, PipelineError> {
    let journal = Journal::open(folder.path(VALIDATION_JOURNAL))?;
    let records: ValidationRecords = plan.collect(journal.records())?;
    let results = evaluate(&records, &plan.slices, models, &smrs(nominal))?;
    Ok(ValidationStage { plan, records, results })
}

/// The SMRs of the nominal cell (every TCP with a tool), which the evaluation reads.
fn smrs(nominal: &Model) -> Vec<(u32, nalgebra::Vector3<f64>)> {
    nominal.tcp_ids().into_iter().filter_map(|id| nominal.tcp(id).map(|t| (id, t))).collect()
}
