#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The single composition root of a calibration run, generic over the device traits of
//! `vatcal-hardware-traits` (it depends on no driver and on no simulator). It reads top-down:
//!
//! * **the run folder** ([`folders`]): [`RunFolder`] and [`PlanFolder`] own every file name of
//!   a run (journals, CSVs, plan folders, report files);
//! * **the stages**, each a module that takes inputs and returns outputs and knows nothing of
//!   the others:
//!   1. [`plan_stage`](mod@plan_stage) (`vatcal-planning`): candidate measurement poses, Detmax selection, the
//!      time-optimal tour, written as a [`PlanFolder`];
//!   2. [`campaign_stage`](mod@campaign_stage) (`vatcal-campaign`): the planned measurements on any [`DeviceSet`]
//!      with TriCal auto-centering, the crash-safe journal and `measurements.csv` (also what
//!      `vatcal campaign` runs on the real cell);
//!   3. [`identify_stage`](mod@identify_stage) (`vatcal-identification`): the plan's parameter set (the paper's 34
//!      parameters on the canonical cell, the chain's identifiable default set otherwise) by
//!      Levenberg–Marquardt;
//!   4. [`discovery_stage`](mod@discovery_stage) (`vatcal-discovery`, optional): a second probe campaign, the
//!      missing-effect discovery and its measurement loop ([`discovery_loop`]);
//!   5. [`validation_stage`](mod@validation_stage) (`vatcal_campaign::validation`): random poses and a printing path
//!      measured with the tracker, commanded by every model; the printing path (the guide
//!      lifting the part out of the tank) exists on the canonical Meca500-on-guide cell only:
//!      any other chain is validated on the random poses alone ([`has_printing_path`]);
//!   6. [`compensation`]: the validation's two printing-path runs checked against the
//!      uncompensated and compensated targets of `vatcal-compensation` (before any motion);
//! * **the report** ([`report`]): `report.json` ([`RunReport`]) from the stages' outputs, with
//!   `summary.md`, CSVs, SVG plots and `timing.json` ([`timing`]);
//! * **the sequence** ([`calibrate()`]): runs the stages in order (resumable, each stage's
//!   state in `stages.json`); [`run`] is all of them at once.
//!
//! Progress goes to a [`Progress`] implementation (stage started/finished, step i of n with
//! the time left); nothing here draws on a terminal. `vatcal demo` is this pipeline on the
//! in-process virtual cell (`vatcal-demo`).

// the run folder and what a run is asked to do
mod devices;
mod error;
pub mod folders;
mod options;
pub mod plans;
mod progress;
mod state;
// what the stages share
pub mod budget;
mod campaign_runner;
pub mod registration;
mod two_sided;
// the stages
pub mod campaign_stage;
pub mod compensation;
pub mod discovery_loop;
pub mod discovery_stage;
pub mod identify_stage;
pub mod plan_stage;
pub mod validation_stage;
// the report of the stages' outputs
mod cell_setup;
mod files;
mod outcome;
pub mod report;
mod report_files;
mod summary;
mod summary_discovery;
mod summary_html;
pub mod timing;
// the sequence
mod book;
pub mod calibrate;
mod steps;
pub mod stop;

pub use calibrate::{
    CalibrateOptions, CalibrateOutcome, DeviceSource, STAGES_FILE, StageStatus, StagesFile, calibrate, run,
    run_with_discovery,
};
pub use campaign_stage::campaign_stage;
pub use devices::{DeviceSet, TrackerRegistrationMode};
pub use discovery_stage::{DiscoveryOutcome, DiscoveryStageOptions};
pub use error::PipelineError;
pub use folders::{PlanFolder, PlanHeader, PlanKind, RunFolder};
pub use identify_stage::identify_stage;
pub use options::{CALIBRATED, DISCOVERED, NOMINAL, RunOptions, RunSizes, TRUE_STRUCTURE, plan_options};
pub use outcome::RunOutcome;
pub use plan_stage::plan_stage;
pub use progress::{NoProgress, Progress, Stage, StageLog, StepProgress};
pub use registration::{RegistrationReport, TRACKER_REGISTRATION_FILE};
pub use report::{
    CampaignSummary, PAPER, PaperFigures, REPORT_FORMAT, ReportSetup, RunReport, ValidationSummary,
    comparison_table,
};
pub use validation_stage::{
    ValidationStage, has_printing_path, validation_options, validation_seed, validation_stage,
};
