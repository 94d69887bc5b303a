//! What a whole run produced ([`RunOutcome`]): the report, the identification, the stage
//! times, the files written, the discovery and the time on the devices.

use std::path::PathBuf;

use vatcal_campaign::validation::ModelValidation;
use vatcal_identification::Identification;

use crate::discovery_stage::DiscoveryOutcome;
use crate::progress::Stage;
use crate::report::RunReport;
use crate::state::StagesFile;
use crate::timing::RunTiming;

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
    /// the discovery stage, when it ran ([`crate::run_with_discovery`])
    pub discovery: Option<DiscoveryOutcome>,
    /// time on the devices: stages, and every kind of step measured against the planner's
    /// estimate (`timing.json`)
    pub timing: Option<RunTiming>,
}

impl<S> RunOutcome<S> {
    /// The validation of the model labelled `label` ([`crate::NOMINAL`] or [`crate::CALIBRATED`]).
    pub fn validation(&self, label: &str) -> Option<&ModelValidation> {
        self.report.model(label)
    }
}

/// What [`crate::calibrate()`] did.
#[derive(Debug, Clone)]
pub struct CalibrateOutcome<S> {
    /// the report, when the `compensation` stage ran (it needs every stage before it)
    pub run: Option<RunOutcome<S>>,
    /// the identification, when any stage from `identify` on ran or was recomputed
    pub identification: Option<Identification>,
    /// the stages run by this call
    pub ran: Vec<Stage>,
    /// the stages found done and recomputed from the folder
    pub recomputed: Vec<Stage>,
    /// the stage state after the call
    pub state: StagesFile,
}
