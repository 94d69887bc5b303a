//! # vatcal-demo
//!
//! The whole calibration of the paper, simulated end to end in one call ([`run_demo`]; the
//! `vatcal demo` command):
//!
//! 1. **plan** (`vatcal-planning`): candidate measurement poses (IK, limits, singularities,
//!    collisions), Detmax selection of 40, the time-optimal tour with collision-free paths;
//! 2. **measurement campaign** (`vatcal-campaign`) on the virtual cell (`vatcal-sim`) whose
//!    hidden truth is chosen by [`DemoOptions::truth`] (default `paper-like`: the paper's 34
//!    parameters' errors plus the physics they miss, `docs/virtual-cell.md`; `ideal`: only the
//!    34 parameters' errors) — the robot controller believes the nominal model, the devices
//!    have the paper's noise budget —
//!    with TriCal auto-centering and the crash-safe journal;
//! 3. **identification** (`vatcal-identification`): the paper's 34 parameters by
//!    Levenberg–Marquardt;
//! 4. **validation** with the simulated laser tracker (`vatcal_campaign::validation`): random
//!    poses (paper: 573) and a 300-slice six-dimensional printing path commanded by the nominal
//!    and by the calibrated model;
//! 5. **report folder**: `report.json` (everything measured), `summary.md`, SVG plots, the
//!    calibrated cell file, the plan files, the journals and every measurement as CSV.
//!
//! Everything is seeded: the same options give the same numbers (`report.json` is identical
//! byte for byte; only the wall-clock times in `summary.md` change).

mod error;
mod output;

use std::path::{Path, PathBuf};
use std::time::Instant;

use vatcal_campaign::validation::{
    ModelValidation, PrintingPathOptions, RandomPoseOptions, ValidationPlan, ValidationPlanOptions,
    ValidationRecords, build_validation_plan, evaluate,
};
use vatcal_campaign::{Campaign, CampaignConfig, CampaignPlan, CampaignReport, CellDevices};
use vatcal_core::{CellFile, JointVector, ParamSet};
use vatcal_hardware_traits::{Clock, TriCal, VirtualClock};
use vatcal_identification::{Identification, IdentifyOptions, identify};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::{PlanSummary, write_plan};
use vatcal_planning::plan::{PlanOptions, plan_campaign};
pub use vatcal_sim::truth::TruthSpec;
use vatcal_sim::{SimArm, SimGauge, SimGuide, SimOperator, SimTracker, VirtualCell};

pub use error::DemoError;
pub use output::{
    CampaignSummary, DemoReport, DemoSetup, PAPER, PaperFigures, REPORT_FORMAT, ValidationSummary,
};

/// The canonical nominal cell (`fixtures/meca500-zaber.toml`), built into the binary so that
/// the demo runs from any directory.
pub const BUILT_IN_CELL: &str = include_str!("../../../fixtures/meca500-zaber.toml");

/// Name of the built-in cell in messages and in the report.
pub const BUILT_IN_CELL_NAME: &str = "fixtures/meca500-zaber.toml (built in)";

/// Sizes of the simulated calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoSizes {
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

impl DemoSizes {
    /// Checks every size; errors name the option.
    pub fn check(&self) -> Result<(), DemoError> {
        let at_least = |option: &str, value: usize, min: usize| {
            if value < min {
                return Err(DemoError::Option {
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
}

impl Default for DemoSizes {
    /// The paper's sizes: 500 orientations, 10 guide steps, 40 measurements, 573 random
    /// validation poses, 300 slices.
    fn default() -> Self {
        Self { orientations: 500, guide_steps: 10, count: 40, random_poses: 573, slices: 300 }
    }
}

/// Options of [`run_demo`].
#[derive(Debug, Clone)]
pub struct DemoOptions {
    /// master seed: hidden truth, device noise, planning, validation poses
    pub seed: u64,
    /// the nominal cell (what the robot controller believes)
    pub nominal: CellFile,
    /// where the nominal cell comes from (for the report)
    pub nominal_source: String,
    /// sizes of every stage
    pub sizes: DemoSizes,
    /// draw progress bars (planning and campaigns, on stderr)
    pub show_progress: bool,
    /// the hidden truth of the virtual cell (default: paper-like)
    pub truth: TruthSpec,
}

impl DemoOptions {
    /// The paper's sizes on the built-in cell, seed `seed`, no progress bars.
    ///
    /// # Errors
    /// Only if the built-in cell does not parse (a build defect).
    pub fn new(seed: u64) -> Result<Self, DemoError> {
        let nominal = CellFile::from_toml_str(BUILT_IN_CELL, BUILT_IN_CELL_NAME)?;
        Ok(Self {
            seed,
            nominal,
            nominal_source: BUILT_IN_CELL_NAME.into(),
            sizes: DemoSizes::default(),
            show_progress: false,
            truth: TruthSpec::PaperLike,
        })
    }
}

/// What a demo produced.
#[derive(Debug, Clone)]
pub struct DemoOutcome {
    /// the report (also written as `report.json`)
    pub report: DemoReport,
    /// the identification (calibrated model, statistics)
    pub identification: Identification,
    /// the hidden true model of the virtual cell (oracle: a real cell has none)
    pub truth: Model,
    /// wall-clock seconds of every stage
    pub stage_seconds: Vec<(String, f64)>,
    /// the files written, relative to the output directory
    pub files: Vec<PathBuf>,
}

impl DemoOutcome {
    /// The validation of the model labelled `label` (`nominal` or `calibrated`).
    pub fn validation(&self, label: &str) -> Option<&ModelValidation> {
        self.report.validation.models.iter().find(|m| m.label == label)
    }

    /// The short before/after table printed by `vatcal demo`.
    pub fn comparison_table(&self) -> String {
        output::comparison_table(&self.report)
    }
}

/// Labels of the two models compared by the validation.
const NOMINAL: &str = "nominal";
const CALIBRATED: &str = "calibrated";

/// Journals written by the demo; removed before a run so that it always starts afresh.
const JOURNALS: [&str; 2] = ["campaign.journal", "validation.journal"];

/// Owned simulated devices of one virtual cell, lent to campaigns as trait objects.
struct SimDevices {
    arm: SimArm,
    guide: SimGuide,
    probe: TriCal<SimGauge>,
    tracker: SimTracker,
    operator: SimOperator,
    clock: VirtualClock,
}

impl SimDevices {
    fn of(cell: &VirtualCell) -> Result<Self, DemoError> {
        Ok(Self {
            arm: cell.arm(),
            guide: cell.guide(),
            probe: cell.probe()?,
            tracker: cell.tracker(),
            operator: cell.operator(),
            clock: cell.clock(),
        })
    }

    fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: &mut self.guide,
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
        }
    }
}

/// Wall-clock stopwatch of the stages.
struct Stages {
    start: Instant,
    done: Vec<(String, f64)>,
}

impl Stages {
    fn new() -> Self {
        Self { start: Instant::now(), done: Vec::new() }
    }

    /// Ends the current stage; returns its duration [s].
    fn lap(&mut self, name: &str) -> f64 {
        let s = self.start.elapsed().as_secs_f64();
        self.start = Instant::now();
        self.done.push((name.to_string(), s));
        s
    }
}

/// Runs the whole simulated calibration and writes the report folder `out` (created if
/// missing; the demo's own files in it are replaced, its journals removed first so the run
/// starts afresh). `log` receives one line per finished stage.
///
/// # Errors
/// Invalid sizes (checked before anything runs), any stage's error ([`DemoError`]), or a file
/// that cannot be written.
pub fn run_demo(opts: &DemoOptions, out: &Path, log: &mut dyn FnMut(&str)) -> Result<DemoOutcome, DemoError> {
    let mut stages = Stages::new();
    opts.sizes.check()?;
    prepare_output(out)?;
    let nominal = Model::from_cell(&opts.nominal)?;
    let geometry = CellGeometry::from_cell(&opts.nominal)?;
    let mut files = output::Files::new(out);
    files.cell("nominal.toml", &opts.nominal)?;

    let (candidates, plan) = plan_stage(opts, &nominal, &geometry, out, &mut files)?;
    let s = stages.lap("plan");
    log(&format!(
        "plan: {candidates} candidates, {} measurements selected, tour of {} steps ({s:.1} s)",
        plan.selected, plan.tour_steps
    ));

    let cell = opts
        .truth
        .virtual_cell(nominal.clone(), opts.seed)
        .map_err(|e| DemoError::Option { option: "truth".into(), reason: e.to_string() })?;
    let mut devices = SimDevices::of(&cell)?;
    let campaign = campaign_stage(opts, &nominal, out, &mut devices, &mut files)?;
    let campaign_time_s = devices.clock.now_s();
    let s = stages.lap("measurement campaign");
    log(&format!(
        "campaign: {} probe measurements ({} skipped), {:.0} min of virtual time ({s:.1} s)",
        campaign.measurements.len(),
        campaign.skipped,
        campaign_time_s / 60.0
    ));

    let fit = identify(&nominal, &campaign.measurements, &ParamSet::paper34(), &IdentifyOptions::default())?;
    files.cell("calibrated.toml", &fit.model.to_cell())?;
    let s = stages.lap("identification");
    log(&format!(
        "identification: {} parameters, {} iterations, residual mean {:.4} mm ({s:.1} s)",
        fit.params.len(),
        fit.iterations.len().saturating_sub(1),
        fit.residual_stats.mean
    ));

    let start = campaign.records.last().map(|r| r.state.joints);
    let validation = validation_stage(opts, &nominal, &geometry, &fit.model, start, out, &mut devices)?;
    let validation_time_s = devices.clock.now_s() - campaign_time_s;
    let s = stages.lap("validation");
    log(&format!(
        "validation: {} random poses, {} slices × {} models, {} tracker measurements ({s:.1} s)",
        validation.records.random.len(),
        validation.plan.slices.len(),
        validation.plan.path_runs.len(),
        validation.plan.measurement_count()
    ));

    files.note(JOURNALS[1]);
    files.validation_csvs(&validation.records, &validation.plan.slices, &validation.results)?;
    files.plots(&fit, &validation.plan.slices, &validation.results)?;
    let report = output::build_report(output::ReportInputs {
        opts,
        plan,
        campaign: &campaign,
        campaign_time_s,
        fit: &fit,
        validation_plan: &validation.plan,
        validation_options: &validation.options,
        validation_time_s,
        results: validation.results,
    });
    files.json("report.json", &report)?;
    stages.lap("report");
    files.note("summary.md");
    let outcome = DemoOutcome {
        report,
        identification: fit,
        truth: cell.truth(),
        stage_seconds: stages.done,
        files: files.written().to_vec(),
    };
    files.summary("summary.md", &outcome)?;
    Ok(outcome)
}

/// Plans the campaign on the nominal cell and writes `plan/`; returns the number of candidates
/// and the plan summary.
fn plan_stage(
    opts: &DemoOptions,
    nominal: &Model,
    geometry: &CellGeometry,
    out: &Path,
    files: &mut output::Files,
) -> Result<(usize, PlanSummary), DemoError> {
    let plan = plan_campaign(nominal, geometry, &plan_options(opts))?;
    let summary = write_plan(&plan, &out.join("plan"))?;
    files.record_plan();
    Ok((plan.candidates.candidates.len(), summary))
}

/// Runs the planned tour (read back from `plan/tour.csv`, as a user would) on the virtual cell;
/// writes the journal and `measurements.csv`.
fn campaign_stage(
    opts: &DemoOptions,
    nominal: &Model,
    out: &Path,
    devices: &mut SimDevices,
    files: &mut output::Files,
) -> Result<CampaignReport, DemoError> {
    let tour = CampaignPlan::read_tour(out.join("plan").join("tour.csv"))?;
    let report = Campaign::new(devices.devices(), nominal, campaign_config(opts))
        .run(&tour, out.join(JOURNALS[0]))
        .map_err(DemoError::from)?;
    files.note(JOURNALS[0]);
    files.measurements("measurements.csv", &report.measurements)?;
    Ok(report)
}

/// What the validation stage produced.
struct ValidationStage {
    options: ValidationPlanOptions,
    plan: ValidationPlan,
    records: ValidationRecords,
    results: Vec<ModelValidation>,
}

/// Plans and runs the tracker validation of the nominal and the calibrated model on the same
/// virtual cell (the session continues: same clock, same tool-changer offset), from the pose
/// where the calibration campaign left the arm.
fn validation_stage(
    opts: &DemoOptions,
    nominal: &Model,
    geometry: &CellGeometry,
    calibrated: &Model,
    start: Option<JointVector>,
    out: &Path,
    devices: &mut SimDevices,
) -> Result<ValidationStage, DemoError> {
    let options = validation_options(opts, start);
    let models: [(&str, &Model); 2] = [(NOMINAL, nominal), (CALIBRATED, calibrated)];
    let plan = build_validation_plan(nominal, geometry, &models, &options)?;
    let mut campaign = Campaign::new(devices.devices(), nominal, campaign_config(opts));
    let records = plan.run(&mut campaign, out.join(JOURNALS[1]))?;
    let smrs: Vec<_> =
        nominal.tcp_ids().into_iter().filter_map(|id| nominal.tcp(id).map(|t| (id, t))).collect();
    let results = evaluate(&records, &plan.slices, &models, &smrs)?;
    Ok(ValidationStage { options, plan, records, results })
}

/// Creates `out` and removes the demo's journals from an earlier run.
fn prepare_output(out: &Path) -> Result<(), DemoError> {
    std::fs::create_dir_all(out).map_err(|source| DemoError::Io { path: out.to_path_buf(), source })?;
    for name in JOURNALS {
        let path = out.join(name);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|source| DemoError::Io { path, source })?;
        }
    }
    Ok(())
}

fn plan_options(opts: &DemoOptions) -> PlanOptions {
    PlanOptions {
        candidates: CandidateOptions {
            orientations: opts.sizes.orientations,
            guide_steps: opts.sizes.guide_steps,
            progress: opts.show_progress,
            ..CandidateOptions::default()
        },
        count: opts.sizes.count,
        motion: opts.nominal.motion_limits(),
        seed: opts.seed,
        ..PlanOptions::default()
    }
}

/// The campaign settings of the demo: a measurement whose auto-centering is refused is skipped
/// (and counted) instead of stopping the run; the journal is written record by record but
/// synced once at the end (the virtual cell's steps take microseconds).
fn campaign_config(opts: &DemoOptions) -> CampaignConfig {
    CampaignConfig {
        skip_failed_measurements: true,
        show_progress: opts.show_progress,
        sync_journal_each_step: false,
        note: format!("vatcal demo, seed {}", opts.seed),
        ..CampaignConfig::default()
    }
}

/// Seed of the validation stage, independent of the planning seed.
fn validation_seed(seed: u64) -> u64 {
    seed ^ 0x5eed_7a11_da7e_0001
}

fn validation_options(opts: &DemoOptions, start: Option<JointVector>) -> ValidationPlanOptions {
    ValidationPlanOptions {
        random: RandomPoseOptions { count: opts.sizes.random_poses, ..RandomPoseOptions::default() },
        printing: PrintingPathOptions { slices: opts.sizes.slices, ..PrintingPathOptions::default() },
        motion: opts.nominal.motion_limits(),
        start,
        seed: validation_seed(opts.seed),
        ..ValidationPlanOptions::default()
    }
}
