#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The single composition root of a calibration run, generic over the device traits of
//! `vatcal-hardware-traits` (it depends on no driver and on no simulator):
//!
//! 1. [`Stage::Plan`] (`vatcal-planning`): candidate measurement poses, Detmax selection, the
//!    time-optimal tour, written as a [`PlanFolder`];
//! 2. [`Stage::Campaign`] (`vatcal-campaign`): the planned measurements on any
//!    [`DeviceSet`] with TriCal auto-centering, the crash-safe journal and `measurements.csv`
//!    ([`campaign_stage`], also what `vatcal campaign` runs on the real cell);
//! 3. [`Stage::Identify`] (`vatcal-identification`): the plan's parameter set (the paper's 34
//!    parameters on the canonical cell, the chain's identifiable default set otherwise) by
//!    Levenberg–Marquardt;
//! 4. [`Stage::Validate`] (`vatcal_campaign::validation`): random poses and a printing path
//!    measured with the tracker, commanded by the nominal and by the calibrated model; the
//!    two printing-path runs are the uncompensated and compensated targets of
//!    `vatcal-compensation` (checked before any motion, [`compensation`]). The printing path
//!    (the guide lifting the part out of the tank) exists on the canonical Meca500-on-guide
//!    cell only: any other chain is validated on the random poses alone ([`has_printing_path`]);
//! 5. [`Stage::Report`]: `report.json` ([`RunReport`]), `summary.md`, CSVs and SVG plots.
//!
//! [`run`] executes all of them in order. Progress goes to a [`Progress`] implementation
//! (stage started/finished, step i of n with the time left); nothing here draws on a terminal.
//! `vatcal demo` is this pipeline on the in-process virtual cell (`vatcal-demo`).

pub mod calibrate;
pub mod compensation;
pub mod discovery_loop;
pub mod discovery_stage;
mod error;
pub mod folders;
pub mod plans;
mod progress;
pub mod registration;
pub mod report;
pub mod stop;
pub mod timing;

use std::path::{Path, PathBuf};

use vatcal_campaign::validation::{
    ModelValidation, PrintingPathOptions, RandomPoseOptions, ValidationPlan, ValidationPlanOptions,
    ValidationRecords, evaluate,
};
use vatcal_campaign::{
    Campaign, CampaignConfig, CampaignPlan, CampaignReport, CellDevices, Journal, StepRecord,
};
use vatcal_core::{CellFile, JointVector, ParamSet};
use vatcal_identification::{Identification, IdentifyOptions, identify};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::PlanSummary;
use vatcal_planning::plan::{PlanOptions, plan_campaign};

pub use calibrate::{
    CalibrateOptions, CalibrateOutcome, DeviceSource, STAGES_FILE, StageStatus, StagesFile, calibrate,
};
pub use discovery_stage::{DISCOVERED, DiscoveryOutcome, DiscoveryStageOptions, TRUE_STRUCTURE};
pub use error::PipelineError;
pub use folders::{PlanFolder, RunFolder};
pub use plans::{PlanHeader, PlanKind};
pub use progress::{NoProgress, Progress, Stage, StageLog, StepProgress};
pub use registration::{RegistrationReport, TRACKER_REGISTRATION_FILE};
pub use report::{
    CampaignSummary, PAPER, PaperFigures, REPORT_FORMAT, ReportSetup, RunReport, ValidationSummary,
    comparison_table,
};

use progress::StepCounter;

/// Labels of the two models compared by the validation.
pub const NOMINAL: &str = "nominal";
/// Label of the calibrated model in the validation.
pub const CALIBRATED: &str = "calibrated";

/// Anything that can lend the devices of one cell to a campaign, as often as needed (the
/// measurement campaign, then the validation on the same session).
pub trait DeviceSet {
    /// The devices, borrowed for one campaign.
    fn devices(&mut self) -> CellDevices<'_>;

    /// How the validation stage brings the tracker's readings into the tank frame (default
    /// [`TrackerRegistrationMode::Skip`]: an in-process tracker that reports in the tank frame).
    fn tracker_registration(&self) -> TrackerRegistrationMode {
        TrackerRegistrationMode::Skip
    }
}

/// How the validation stage relates the tracker's frame to the tank frame, before its first
/// tracker measurement (`vatcal_campaign::validation::register_tracker`, paper §5: the SMR
/// seated in the probe's nest at each calibration position).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackerRegistrationMode {
    /// the tracker reports in its own frame: register it (measure the nest at every
    /// calibration position, fit `tank ← tracker`) and map every validation reading through the
    /// fit
    Register,
    /// the tracker reports in the tank frame already (its software is registered): measure the
    /// nest at every calibration position and report how far the readings are from the known
    /// positions, readings used as they are
    Check,
    /// no registration measurement (the in-process virtual tracker of `vatcal demo`, which
    /// reports in the tank frame with its simulated registration error)
    Skip,
}

/// Sizes of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunSizes {
    /// random tool orientations per TCP × calibration position (paper: 500)
    pub orientations: usize,
    /// guide positions of the candidates (paper: 10)
    pub guide_steps: usize,
    /// measurements selected by Detmax (paper: 40)
    pub count: usize,
    /// random validation poses (paper: 573)
    pub random_poses: usize,
    /// slices of the printing path (paper: 300)
    pub slices: usize,
}

impl RunSizes {
    /// Checks every size; errors name the option.
    ///
    /// # Errors
    /// A size below its minimum.
    pub fn check(&self) -> Result<(), PipelineError> {
        let at_least = |option: &str, value: usize, min: usize| {
            if value < min {
                return Err(PipelineError::Option {
                    option: option.into(),
                    reason: format!("must be at least {min}, got {value}"),
                });
            }
            Ok(())
        };
        at_least("orientations", self.orientations, 1)?;
        at_least("guide_steps", self.guide_steps, 1)?;
        at_least("count", self.count, 1)?;
        at_least("random_poses", self.random_poses, 1)?;
        at_least("slices", self.slices, 2)
    }

    /// The small sizes of a quick look (`--quick`): 20 orientations, 3 guide steps, 40
    /// measurements, 200 random validation poses; the slices are kept.
    pub fn quick(self) -> Self {
        Self { orientations: 20, guide_steps: 3, count: 40, random_poses: 200, ..self }
    }
}

impl Default for RunSizes {
    /// The paper's sizes: 500 orientations, 10 guide steps, 40 measurements, 573 random
    /// validation poses, 300 slices.
    fn default() -> Self {
        Self { orientations: 500, guide_steps: 10, count: 40, random_poses: 573, slices: 300 }
    }
}

/// Options of a whole run ([`run`]).
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// master seed: planning and validation poses
    pub seed: u64,
    /// the nominal cell (what the robot controller believes)
    pub nominal: CellFile,
    /// sizes of every stage
    pub sizes: RunSizes,
    /// settings of the measurement and validation campaigns
    pub campaign: CampaignConfig,
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunOutcome<S> {
    /// the report (also written as `report.json`)
    pub report: RunReport<S>,
    /// the identification (calibrated model, statistics)
    pub identification: Identification,
    /// wall-clock seconds of every stage
    pub stage_seconds: Vec<(String, f64)>,
    /// the files written, relative to the output directory
    pub files: Vec<PathBuf>,
    /// the discovery stage, when it ran ([`run_with_discovery`])
    pub discovery: Option<DiscoveryOutcome>,
    /// time on the devices: stages, and every kind of step measured against the planner's
    /// estimate (`timing.json`)
    pub timing: Option<timing::RunTiming>,
}

impl<S> RunOutcome<S> {
    /// The validation of the model labelled `label` ([`NOMINAL`] or [`CALIBRATED`]).
    pub fn validation(&self, label: &str) -> Option<&ModelValidation> {
        self.report.model(label)
    }
}

/// Runs the whole calibration — plan, measurement campaign, identification, validation,
/// report — on `devices`, writing the report folder `out` (created if missing; its journals
/// are removed first so the run starts afresh). `setup` describes the cell for the report,
/// from the identification.
///
/// # Errors
/// Invalid sizes (checked before anything runs), any stage's error, or a file that cannot be
/// written.
pub fn run<S: ReportSetup>(
    opts: &RunOptions,
    devices: &mut dyn DeviceSet,
    setup: impl FnOnce(&Identification) -> S,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<RunOutcome<S>, PipelineError> {
    run_with_discovery(opts, None, devices, setup, out, progress)
}

/// [`run`] with, when `discovery` is given, the discovery stage
/// ([`discovery_stage::discovery_stage`]) between the identification and the validation: the
/// discovered model (and the true-structure model, when the oracle is given) are validated
/// beside the nominal and the calibrated one, `report.json` gains a `discovery` object and the
/// summary a discovery section.
///
/// # Errors
/// As [`run`], and the discovery stage's errors.
pub fn run_with_discovery<S: ReportSetup>(
    opts: &RunOptions,
    discovery: Option<&DiscoveryStageOptions>,
    devices: &mut dyn DeviceSet,
    setup: impl FnOnce(&Identification) -> S,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<RunOutcome<S>, PipelineError> {
    let mut source = calibrate::Lent(devices);
    let outcome =
        calibrate(opts, discovery, &CalibrateOptions::default(), &mut source, setup, out, progress)?;
    outcome.run.ok_or_else(|| PipelineError::Option {
        option: "stages".into(),
        reason: "the run stopped before the report".into(),
    })
}

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

/// Whether the validation of `nominal` has the printing path: the guide lifts the part out of
/// the tank like a printer's z axis, so only the canonical Meca500-on-guide cell has it (its
/// IK and tank geometry); any other chain is validated on random poses only.
pub fn has_printing_path(nominal: &Model) -> bool {
    nominal.is_meca500_on_guide()
}

/// Runs `tour` on `devices`, journaling into the run folder's `campaign.journal` (a journal
/// of the same plan is resumed where it stopped: nothing lost, nothing repeated), reporting
/// the start of [`Stage::Campaign`] and every step to `progress`, and writes
/// `measurements.csv` at the end.
///
/// # Errors
/// The campaign's error (the journal keeps every completed step: run again to resume).
pub fn campaign_stage(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    tour: &CampaignPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<CampaignReport, PipelineError> {
    progress.stage_started(Stage::Campaign, Some(tour.steps.len()));
    let journal = folder.journal();
    let report = run_campaign(devices, nominal, tour, &journal, config, Stage::Campaign, None, progress)?;
    folder.write_measurements(&report.measurements, nominal.joint_kinds())?;
    Ok(report)
}

/// Runs a campaign plan with progress reporting (steps, measurements, time left); with
/// `tank_from_tracker` (a tracker registration) every tracker reading is mapped into the tank
/// frame before it is journaled.
#[allow(clippy::too_many_arguments)] // the campaign's inputs
fn run_campaign(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    plan: &CampaignPlan,
    journal: &Path,
    config: CampaignConfig,
    stage: Stage,
    tank_from_tracker: Option<&vatcal_core::Frame>,
    progress: &mut dyn Progress,
) -> Result<CampaignReport, PipelineError> {
    let mut counter = StepCounter::new(plan.steps.len(), plan.measurement_count());
    if journal.exists()
        && let Ok(j) = Journal::open(journal)
    {
        counter.resumed(j.next_step(), j.measurements().len());
    }
    let observer = |record: &StepRecord| {
        let p = counter.record(record.step, record.measurement().is_some());
        progress.step_done(stage, p);
    };
    let mut cell = devices.devices();
    let mut registered = match (tank_from_tracker, cell.tracker.take()) {
        (Some(frame), Some(t)) => Some(vatcal_hardware_traits::RegisteredTracker::new(t, *frame)),
        (_, t) => {
            cell.tracker = t;
            None
        }
    };
    if let Some(r) = registered.as_mut() {
        cell.tracker = Some(r);
    }
    let report = Campaign::new(cell, nominal, config).on_record(observer).run(plan, journal)?;
    Ok(report)
}

/// Identifies `params` (the plan's set: the paper's 34 on the canonical cell) from the probe
/// measurements (Levenberg–Marquardt).
///
/// # Errors
/// The identification fails (too few measurements, divergence).
pub fn identify_stage(
    nominal: &Model,
    measurements: &[vatcal_core::Measurement],
    params: &ParamSet,
) -> Result<Identification, PipelineError> {
    Ok(identify(nominal, measurements, params, &IdentifyOptions::default())?)
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
/// continues): the tracker registration and the campaign ([`plans::tracker_campaign_stage`],
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
        plans::tracker_campaign_stage(devices, nominal, &plan.campaign, folder, config, progress)?;
    let records = plan.collect(&report.records)?;
    let smrs: Vec<_> =
        nominal.tcp_ids().into_iter().filter_map(|id| nominal.tcp(id).map(|t| (id, t))).collect();
    let results = evaluate(&records, &plan.slices, models, &smrs)?;
    Ok((ValidationStage { plan, records, results }, registration))
}

/// The planning options of a run.
pub fn plan_options(opts: &RunOptions) -> PlanOptions {
    PlanOptions {
        candidates: CandidateOptions {
            orientations: opts.sizes.orientations,
            guide_steps: opts.sizes.guide_steps,
            progress: false,
            ..CandidateOptions::default()
        },
        count: opts.sizes.count,
        // empty: the chain's default set (the paper's 34 on the canonical cell)
        params: ParamSet(Vec::new()),
        motion: opts.nominal.motion_limits(),
        seed: opts.seed,
        ..PlanOptions::default()
    }
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
