//! The run as resumable stages (`vatcal calibrate`, and `vatcal demo` on the virtual cell).
//!
//! [`calibrate`] executes the stages of [`Stage::ALL`] — `plan`, `campaign`, `identify`,
//! `discovery`, `validation`, `compensation` — on any [`DeviceSource`], writing one run
//! folder. Every stage's state is kept in the folder's [`STAGES_FILE`] (`stages.json`:
//! `running` or `done`, attempts, wall time and device-clock time), and every stage reads its
//! inputs from the folder:
//!
//! | stage | reads | writes |
//! |---|---|---|
//! | `plan` | the nominal cell | `plan/` (`tour.csv`, …) |
//! | `campaign` | `plan/tour.csv` | `campaign.journal`, `measurements.csv` |
//! | `identify` | `campaign.journal` | `calibrated.toml` |
//! | `discovery` | `campaign.journal`, the calibrated model | `discovery_plan/`, `discovery.journal`, `discovery_measurements.csv`, effect plots |
//! | `validation` | the models (nominal, calibrated, discovered), where the last campaign left the arm | `tracker-registration.json` ([`crate::registration`], unless the devices skip it), `validation.journal` |
//! | `compensation` | `validation.journal`, the compensated printing path | `report.json`, `summary.md` (and `.html`), CSVs, SVG plots, `timing.json` |
//!
//! The journals are the only measured data; everything derived from them (the plan, the
//! identification, the discovery loop, the validation's evaluation) is deterministic and is
//! recomputed, bit for bit, when a later stage needs it and its stage is already `done`.
//!
//! * **Fresh run** (the `plan` stage selected, no resume): the folder's journals and stage
//!   state are removed first.
//! * **Resume** ([`CalibrateOptions::resume`]): `done` stages are skipped (their results
//!   recomputed from the folder), a stage left `running` by a crash continues its journal — the
//!   campaign runner restores the cell into the last recorded state and goes on with the next
//!   step, so nothing is lost or measured twice.
//! * **A stage on its own** (a subset of stages, no resume): each selected stage is run again
//!   (its journal removed first: it measures afresh), every later stage's `done` is cleared,
//!   and every earlier stage must be `done` (the error names it). `discovery` is optional: when
//!   it is neither selected nor done, the validation measures the nominal and the calibrated
//!   model only.

use std::path::Path;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use vatcal_campaign::validation::{ValidationRecords, evaluate};
use vatcal_campaign::{CampaignReport, Journal};
use vatcal_identification::Identification;
use vatcal_kinematics::Model;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::PlanSummary;
use vatcal_planning::plan::plan_campaign;

use crate::discovery_stage::{self, DiscoveryOutcome, DiscoveryStageOptions};
use crate::folders::{self, PlanFolder, RunFolder};
use crate::report::{self, ReportSetup};
use crate::timing;
use crate::{
    CALIBRATED, DISCOVERED, DeviceSet, NOMINAL, PipelineError, Progress, RunOptions, RunOutcome, RunSizes,
    Stage, TRUE_STRUCTURE, ValidationStage, compensation,
};

/// The stage state file of a run folder.
pub const STAGES_FILE: &str = "stages.json";
/// `format` of [`STAGES_FILE`].
pub const STAGES_FORMAT: &str = "vatcal-calibrate-stages";

/// Where the devices of a run come from: connected only when a stage that moves them runs
/// ([`Stage::uses_devices`]), so a run that only recomputes offline stages needs no cell.
/// Every [`DeviceSet`] is one (already connected).
pub trait DeviceSource {
    /// The connected devices.
    ///
    /// # Errors
    /// The devices cannot be connected.
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError>;
}

impl<T: DeviceSet> DeviceSource for T {
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError> {
        Ok(self)
    }
}

/// Devices lent by a caller that holds them as a trait object.
pub struct Lent<'a>(pub &'a mut dyn DeviceSet);

impl std::fmt::Debug for Lent<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Lent")
    }
}

impl DeviceSource for Lent<'_> {
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError> {
        Ok(&mut *self.0)
    }
}

/// Which stages [`calibrate`] runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CalibrateOptions {
    /// the selected stages (any order; run in [`Stage::ALL`] order)
    pub stages: Vec<Stage>,
    /// continue the run folder: skip `done` stages, continue an interrupted one
    pub resume: bool,
}

impl Default for CalibrateOptions {
    /// Every stage, a fresh run.
    fn default() -> Self {
        Self { stages: Stage::ALL.to_vec(), resume: false }
    }
}

impl CalibrateOptions {
    /// Parses a comma list of stage keys ([`Stage::key`]), e.g. `plan,campaign,identify`.
    ///
    /// # Errors
    /// An unknown or empty key, naming the valid ones.
    pub fn parse_stages(text: &str) -> Result<Vec<Stage>, PipelineError> {
        let mut stages = Vec::new();
        for key in text.split(',') {
            let stage = Stage::from_key(key).ok_or_else(|| PipelineError::Option {
                option: "stages".into(),
                reason: format!(
                    "unknown stage `{}` (the stages are {})",
                    key.trim(),
                    Stage::ALL.map(Stage::key).join(", ")
                ),
            })?;
            if !stages.contains(&stage) {
                stages.push(stage);
            }
        }
        stages.sort();
        Ok(stages)
    }
}

/// Whether a stage is running (started, not finished: a crash or a fault stopped it) or done.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StageStatus {
    /// started and not finished
    Running,
    /// finished; its outputs are in the run folder
    Done,
}

/// One stage in [`STAGES_FILE`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageEntry {
    /// [`Stage::key`]
    pub stage: String,
    /// running or done
    pub status: StageStatus,
    /// how often it was started (a resume after a crash is one more)
    pub attempts: u32,
    /// wall-clock seconds of the attempt that finished it
    pub wall_s: Option<f64>,
    /// seconds of the devices' clock the stage took (its campaign journal's span; `None` for
    /// offline stages)
    pub device_s: Option<f64>,
}

/// The stage state of a run folder ([`STAGES_FILE`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StagesFile {
    /// [`STAGES_FORMAT`]
    pub format: String,
    /// 1
    pub version: u32,
    /// the run's master seed (a resume with another seed is refused)
    pub seed: u64,
    /// the run's sizes (a resume with other sizes is refused)
    pub sizes: RunSizes,
    /// extra probe measurements of the discovery stage, `None` without it
    pub discovery_count: Option<usize>,
    /// the stages started so far, in order
    pub stages: Vec<StageEntry>,
}

impl StagesFile {
    fn new(opts: &RunOptions, discovery: Option<&DiscoveryStageOptions>) -> Self {
        Self {
            format: STAGES_FORMAT.into(),
            version: 1,
            seed: opts.seed,
            sizes: opts.sizes.clone(),
            discovery_count: discovery.map(|d| d.count),
            stages: Vec::new(),
        }
    }

    /// Reads the stage state of the run folder `out`; `Ok(None)` when there is none.
    ///
    /// # Errors
    /// An unreadable or invalid file.
    pub fn load(out: &Path) -> Result<Option<Self>, PipelineError> {
        let path = out.join(STAGES_FILE);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path)
            .map_err(|source| PipelineError::Io { path: path.clone(), source })?;
        let file: Self = serde_json::from_str(&text)
            .map_err(|e| PipelineError::Folder { path: path.clone(), reason: e.to_string() })?;
        if file.format != STAGES_FORMAT || file.version != 1 {
            return Err(PipelineError::Folder {
                path,
                reason: format!(
                    "format `{}` version {} (expected `{STAGES_FORMAT}` version 1)",
                    file.format, file.version
                ),
            });
        }
        Ok(Some(file))
    }

    fn save(&self, out: &Path) -> Result<(), PipelineError> {
        let path = out.join(STAGES_FILE);
        let tmp = out.join(format!("{STAGES_FILE}.tmp"));
        let text = serde_json::to_string_pretty(self)?;
        std::fs::write(&tmp, text).map_err(|source| PipelineError::Io { path: tmp.clone(), source })?;
        std::fs::rename(&tmp, &path).map_err(|source| PipelineError::Io { path, source })
    }

    /// The entry of `stage`, if it was started.
    pub fn entry(&self, stage: Stage) -> Option<&StageEntry> {
        self.stages.iter().find(|e| e.stage == stage.key())
    }

    /// Whether `stage` is done.
    pub fn is_done(&self, stage: Stage) -> bool {
        self.entry(stage).is_some_and(|e| e.status == StageStatus::Done)
    }

    fn entry_mut(&mut self, stage: Stage) -> &mut StageEntry {
        if let Some(k) = self.stages.iter().position(|e| e.stage == stage.key()) {
            return &mut self.stages[k];
        }
        self.stages.push(StageEntry {
            stage: stage.key().into(),
            status: StageStatus::Running,
            attempts: 0,
            wall_s: None,
            device_s: None,
        });
        let last = self.stages.len() - 1;
        &mut self.stages[last]
    }

    /// The run's options must be the folder's (a resume or a single stage continues the same
    /// run).
    fn check(
        &self,
        opts: &RunOptions,
        discovery: Option<&DiscoveryStageOptions>,
        out: &Path,
    ) -> Result<(), PipelineError> {
        let differ = |what: String| PipelineError::Folder {
            path: out.join(STAGES_FILE),
            reason: format!(
                "the run folder was made with {what}: continue it with the same options, or start a new run \
                 (all stages, without --resume)"
            ),
        };
        if self.seed != opts.seed {
            return Err(differ(format!("seed {} (this run: {})", self.seed, opts.seed)));
        }
        if self.sizes != opts.sizes {
            return Err(differ(format!("sizes {:?} (this run: {:?})", self.sizes, opts.sizes)));
        }
        let count = discovery.map(|d| d.count);
        if self.discovery_count.is_some() && count.is_some() && self.discovery_count != count {
            return Err(differ(format!(
                "{:?} discovery measurements (this run: {:?})",
                self.discovery_count, count
            )));
        }
        Ok(())
    }
}

/// What [`calibrate`] did.
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

/// Stage bookkeeping: the stage state file, wall clock, progress.
struct Book<'p> {
    out: &'p Path,
    state: StagesFile,
    progress: &'p mut dyn Progress,
    start: Instant,
    seconds: Vec<(String, f64)>,
    ran: Vec<Stage>,
    recomputed: Vec<Stage>,
    /// the stages run in this call from their start (not resumed): the device-clock arithmetic
    /// of the report may use this process's clock readings
    fresh: Vec<Stage>,
}

impl<'p> Book<'p> {
    /// `stage` starts running (progress, state `running`, later stages no longer done).
    fn begin(&mut self, stage: Stage, steps: Option<usize>) -> Result<(), PipelineError> {
        self.start = Instant::now();
        self.progress.stage_started(stage, steps);
        self.mark_running(stage)
    }

    fn mark_running(&mut self, stage: Stage) -> Result<(), PipelineError> {
        let e = self.state.entry_mut(stage);
        if e.status == StageStatus::Done {
            e.attempts = 0;
        }
        e.status = StageStatus::Running;
        e.attempts += 1;
        e.wall_s = None;
        e.device_s = None;
        self.state.stages.retain(|e| Stage::from_key(&e.stage).is_none_or(|s| s <= stage));
        self.state.save(self.out)
    }

    /// `stage` is done: `line` receives its wall time and returns the summary line.
    fn finish(
        &mut self,
        stage: Stage,
        device_s: Option<f64>,
        line: impl FnOnce(f64) -> Option<String>,
    ) -> Result<f64, PipelineError> {
        let s = self.start.elapsed().as_secs_f64();
        self.start = Instant::now();
        self.seconds.push((stage.name().to_string(), s));
        let e = self.state.entry_mut(stage);
        e.status = StageStatus::Done;
        e.wall_s = Some(s);
        e.device_s = device_s;
        self.state.save(self.out)?;
        self.ran.push(stage);
        let summary = line(s).unwrap_or_default();
        self.progress.stage_finished(stage, &summary, s);
        Ok(s)
    }

    /// `stage` is done from an earlier call: its results are recomputed from the folder.
    fn recompute(&mut self, stage: Stage) -> Result<(), PipelineError> {
        if !self.state.is_done(stage) {
            return Err(PipelineError::Option {
                option: "stages".into(),
                reason: format!(
                    "stage `{}` is needed but not done in {} (run it first: --stages {}, or --resume)",
                    stage.key(),
                    self.out.display(),
                    stage.key()
                ),
            });
        }
        let wall = self.state.entry(stage).and_then(|e| e.wall_s).unwrap_or(0.0);
        self.seconds.push((stage.name().to_string(), wall));
        self.recomputed.push(stage);
        self.start = Instant::now();
        Ok(())
    }

    fn device_s(&self, stage: Stage) -> f64 {
        self.state.entry(stage).and_then(|e| e.device_s).unwrap_or(0.0)
    }
}

/// The devices' clock span of a campaign: this process's clock readings for a campaign run
/// from its start, else the journal's last record (its time since the journal began,
/// continued across restarts).
fn device_span(report: &CampaignReport, clock_delta_s: f64) -> f64 {
    match report.resumed_at_step {
        None => clock_delta_s,
        Some(_) => report.records.last().map_or(clock_delta_s, |r| r.time_s),
    }
}

/// Runs the selected stages of a calibration on the devices of `devices` into the run
/// folder `out` (module docs: fresh run, resume, single stages). `discovery`, when given,
/// enables the discovery stage. `setup` describes the cell for the report.
///
/// # Errors
/// Invalid sizes or stages (checked before anything runs), a needed stage not done, a run
/// folder of other options, any stage's error (the stage stays `running`: run again with
/// `resume`).
pub fn calibrate<S: ReportSetup>(
    opts: &RunOptions,
    discovery: Option<&DiscoveryStageOptions>,
    cal: &CalibrateOptions,
    devices: &mut dyn DeviceSource,
    setup: impl FnOnce(&Identification) -> S,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<CalibrateOutcome<S>, PipelineError> {
    opts.sizes.check()?;
    let Some(&last) = cal.stages.iter().max() else {
        return Err(PipelineError::Option { option: "stages".into(), reason: "no stage selected".into() });
    };
    let folder = RunFolder::new(out);
    folder.create()?;
    let fresh = !cal.resume && cal.stages.contains(&Stage::Plan);
    let state = if fresh {
        folder.remove_journals()?;
        folder.remove(STAGES_FILE)?;
        StagesFile::new(opts, discovery)
    } else {
        match StagesFile::load(out)? {
            Some(s) => {
                s.check(opts, discovery, out)?;
                s
            }
            None if cal.resume => {
                return Err(PipelineError::Folder {
                    path: out.join(STAGES_FILE),
                    reason: "no stage state: nothing to resume (start the run without --resume)".into(),
                });
            }
            None => StagesFile::new(opts, discovery),
        }
    };
    let mut book = Book {
        out,
        state,
        progress,
        start: Instant::now(),
        seconds: Vec::new(),
        ran: Vec::new(),
        recomputed: Vec::new(),
        fresh: Vec::new(),
    };
    // run: selected, and not already done when resuming
    let run = |book: &Book<'_>, s: Stage| cal.stages.contains(&s) && !(cal.resume && book.state.is_done(s));
    // a stage run again on its own measures afresh; a resumed one continues its journal
    let restart = |book: &Book<'_>, s: Stage| !cal.resume || book.state.entry(s).is_none();
    book.state.save(out)?;

    let nominal = Model::from_cell(&opts.nominal)?;
    let geometry = CellGeometry::from_cell(&opts.nominal)?;
    let mut files = report::Files::new(out, nominal.joint_kinds());
    files.cell("nominal.toml", &opts.nominal)?;

    // 1. plan
    let plan_folder = PlanFolder::new(out.join("plan"));
    let (plan, params) = if run(&book, Stage::Plan) {
        book.begin(Stage::Plan, None)?;
        let (candidates, plan, params) = crate::plan_stage(opts, &nominal, &geometry, &plan_folder)?;
        book.finish(Stage::Plan, None, |s| {
            Some(format!(
                "plan: {candidates} candidates, {} measurements selected, tour of {} steps ({s:.1} s)",
                plan.selected, plan.tour_steps
            ))
        })?;
        (plan, params)
    } else {
        book.recompute(Stage::Plan)?;
        // deterministic: the same plan as the one written
        let plan = plan_campaign(&nominal, &geometry, &crate::plan_options(opts))?;
        (PlanSummary::of(&plan), plan.params)
    };
    files.record_plan();
    let done = |book: Book<'_>, files: report::Files| finish_early(book, files, None);
    if last == Stage::Plan {
        return done(book, files);
    }

    // 2. measurement campaign
    let tour = plan_folder.read_tour(nominal.joint_kinds())?;
    let mut clock_start_s = None;
    let (campaign, campaign_time_s) = if run(&book, Stage::Campaign) {
        let fresh_journal = restart(&book, Stage::Campaign);
        if fresh_journal {
            folder.remove(folders::CAMPAIGN_JOURNAL)?;
        }
        book.mark_running(Stage::Campaign)?;
        book.start = Instant::now();
        let dev = devices.open()?;
        let start_s = dev.devices().clock.now_s();
        let campaign =
            crate::campaign_stage(dev, &nominal, &tour, &folder, opts.campaign.clone(), &mut *book.progress)?;
        let t = device_span(&campaign, dev.devices().clock.now_s() - start_s);
        if campaign.resumed_at_step.is_none() {
            clock_start_s = Some(start_s);
            book.fresh.push(Stage::Campaign);
        }
        book.finish(Stage::Campaign, Some(t), |s| {
            Some(format!(
                "campaign: {} probe measurements ({} skipped), {:.0} min of virtual time ({s:.1} s)",
                campaign.measurements.len(),
                campaign.skipped,
                t / 60.0
            ))
        })?;
        (campaign, t)
    } else {
        book.recompute(Stage::Campaign)?;
        (folder.journal_report(folders::CAMPAIGN_JOURNAL)?, book.device_s(Stage::Campaign))
    };
    files.note(folders::CAMPAIGN_JOURNAL);
    files.note(folders::MEASUREMENTS_CSV);
    if last == Stage::Campaign {
        return done(book, files);
    }

    // 3. identification (deterministic: recomputed from the journal when done)
    let fit = if run(&book, Stage::Identify) {
        book.begin(Stage::Identify, None)?;
        let fit = crate::identify_stage(&nominal, &campaign.measurements, &params)?;
        // the calibrated cell records the joints' training range: `compensate` and `validate`
        // warn about postures outside it
        let mut calibrated = fit.model.to_cell();
        calibrated.training_range = vatcal_core::training_range::TrainingRange::from_postures(
            fit.model.joint_kinds(),
            campaign.measurements.iter().map(|m| &m.q),
        );
        files.cell(folders::CALIBRATED_CELL, &calibrated)?;
        book.finish(Stage::Identify, None, |s| {
            Some(format!(
                "identification: {} parameters, {} iterations, residual mean {:.4} mm ({s:.1} s)",
                fit.params.len(),
                fit.iterations.len().saturating_sub(1),
                fit.residual_stats.mean
            ))
        })?;
        fit
    } else {
        book.recompute(Stage::Identify)?;
        files.note(folders::CALIBRATED_CELL);
        crate::identify_stage(&nominal, &campaign.measurements, &params)?
    };
    if last == Stage::Identify {
        return finish_early(book, files, Some(fit));
    }

    // 4. discovery (optional)
    let mut start = campaign.records.last().map(|r| r.state.joints);
    let wanted =
        discovery.is_some() && (cal.stages.contains(&Stage::Discover) || book.state.is_done(Stage::Discover));
    let discovered: Option<DiscoveryOutcome> = match discovery.filter(|_| wanted) {
        Some(stage) if run(&book, Stage::Discover) => {
            if restart(&book, Stage::Discover) {
                folder.remove(discovery_stage::DISCOVERY_JOURNAL)?;
            }
            book.mark_running(Stage::Discover)?;
            book.start = Instant::now();
            let dev = devices.open()?;
            let start_s = dev.devices().clock.now_s();
            let resumed = folder.path(discovery_stage::DISCOVERY_JOURNAL).exists();
            let d = discovery_stage::discovery_stage(
                opts,
                stage,
                dev,
                &nominal,
                &fit.model,
                &fit.params,
                &campaign.measurements,
                start,
                out,
                opts.campaign.clone(),
                &mut *book.progress,
            )?;
            let clock_delta = dev.devices().clock.now_s() - start_s;
            let t = if resumed {
                folder
                    .journal_report(discovery_stage::DISCOVERY_JOURNAL)?
                    .records
                    .last()
                    .map_or(clock_delta, |r| r.time_s)
            } else {
                book.fresh.push(Stage::Discover);
                clock_delta
            };
            files.note(discovery_stage::DISCOVERY_JOURNAL);
            files.note(discovery_stage::DISCOVERY_MEASUREMENTS_CSV);
            discovery_stage::note_loop_files(&d, &mut files);
            for p in &d.plots {
                files.svg(&p.file, &p.svg)?;
            }
            book.finish(Stage::Discover, Some(t), |s| {
                let names: Vec<&str> = d.discovery.added_effects.iter().map(|a| a.label.as_str()).collect();
                Some(format!(
                    "discovery: {} extra probe measurements, {} effect(s) added ({}), held-out gap {:.4} -> {:.4} mm ({s:.1} s)",
                    d.extra_measurements,
                    names.len(),
                    names.join(", "),
                    d.discovery.initial_gap_mm,
                    d.discovery.final_gap_mm
                ))
            })?;
            Some(d)
        }
        Some(stage) => {
            book.recompute(Stage::Discover)?;
            let d = discovery_stage::discovery_recompute(
                opts,
                stage,
                &nominal,
                &fit.model,
                &fit.params,
                &campaign.measurements,
                out,
            )?;
            files.note(discovery_stage::DISCOVERY_JOURNAL);
            files.note(discovery_stage::DISCOVERY_MEASUREMENTS_CSV);
            discovery_stage::note_loop_files(&d, &mut files);
            for p in &d.plots {
                files.note(&p.file);
            }
            Some(d)
        }
        None => None,
    };
    if let Some(d) = &discovered {
        start = d.last_joints.or(start);
    }
    if last == Stage::Discover {
        return finish_early(book, files, Some(fit));
    }

    // 5. validation
    let mut models: Vec<(&str, &Model)> = vec![(NOMINAL, &nominal), (CALIBRATED, &fit.model)];
    if let Some(d) = &discovered {
        models.push((DISCOVERED, &d.discovery.model));
        if let Some(t) = &d.true_structure {
            models.push((TRUE_STRUCTURE, t));
        }
    }
    let (validation_plan, options) =
        crate::plans::validation_plan(opts, &nominal, &geometry, &models, start)?;
    let printing_targets = if validation_plan.slices.is_empty() {
        None
    } else {
        Some(compensation::check_printing_path(&nominal, &fit.model, &validation_plan)?)
    };
    let (validation, validation_time_s) = if run(&book, Stage::Validate) {
        if restart(&book, Stage::Validate) {
            folder.remove(folders::VALIDATION_JOURNAL)?;
            folder.remove_registration()?;
        }
        let resumed = folder.path(folders::VALIDATION_JOURNAL).exists();
        book.progress.stage_started(Stage::Validate, Some(validation_plan.campaign.steps.len()));
        book.mark_running(Stage::Validate)?;
        let dev = devices.open()?;
        if dev.devices().tracker.is_none() {
            return Err(PipelineError::Option {
                option: "devices".into(),
                reason: "the validation stage measures with a laser tracker and the devices have none (add a \
                         `tracker` entry to the devices file, or leave the validation and compensation stages out)"
                    .into(),
            });
        }
        let start_s = dev.devices().clock.now_s();
        let (validation, registration) = crate::validation_stage(
            dev,
            &nominal,
            &models,
            validation_plan,
            &folder,
            opts.campaign.clone(),
            &mut *book.progress,
        )?;
        let end_s = dev.devices().clock.now_s();
        let own_s = if resumed {
            Journal::open(folder.path(folders::VALIDATION_JOURNAL))?
                .records()
                .last()
                .map_or(end_s - start_s, |r| r.time_s)
        } else {
            end_s - start_s
        };
        // the validation's virtual time as the demo has always reported it: everything on the
        // cell's clock after the measurement campaign (the discovery campaign included)
        let reported_s = match clock_start_s {
            Some(c0) if !resumed && (discovered.is_none() || book.fresh.contains(&Stage::Discover)) => {
                end_s - c0 - campaign_time_s
            }
            _ => own_s + if discovered.is_some() { book.device_s(Stage::Discover) } else { 0.0 },
        };
        book.finish(Stage::Validate, Some(own_s), |s| {
            Some(format!(
                "validation: {}{} random poses, {} slices × {} models, {} tracker measurements ({s:.1} s)",
                registration.as_ref().map_or(String::new(), |r| format!("{}; ", r.registration.summary())),
                validation.records.random.len(),
                validation.plan.slices.len(),
                validation.plan.path_runs.len(),
                validation.plan.measurement_count()
            ))
        })?;
        (validation, reported_s)
    } else {
        book.recompute(Stage::Validate)?;
        let journal = Journal::open(folder.path(folders::VALIDATION_JOURNAL))?;
        let records: ValidationRecords = validation_plan.collect(journal.records())?;
        let smrs: Vec<_> =
            nominal.tcp_ids().into_iter().filter_map(|id| nominal.tcp(id).map(|t| (id, t))).collect();
        let results = evaluate(&records, &validation_plan.slices, &models, &smrs)?;
        let t = book.device_s(Stage::Validate)
            + if discovered.is_some() { book.device_s(Stage::Discover) } else { 0.0 };
        (ValidationStage { plan: validation_plan, records, results }, t)
    };
    files.note(folders::VALIDATION_JOURNAL);
    if last == Stage::Validate {
        return finish_early(book, files, Some(fit));
    }

    // 6. compensation and the report
    book.begin(Stage::Report, None)?;
    files.validation_csvs(&validation.records, &validation.plan.slices, &validation.results)?;
    files.plots(&fit, &validation.plan.slices, &validation.results)?;
    let mut report = report::build_report(report::ReportInputs {
        seed: opts.seed,
        setup: setup(&fit),
        plan,
        campaign: &campaign,
        campaign_time_s,
        fit: &fit,
        validation_plan: &validation.plan,
        validation_options: &options,
        validation_time_s,
        compensation: printing_targets
            .as_ref()
            .map(|t| compensation::CompensationSummary::new(t, &validation.results)),
        results: validation.results,
    });
    if let Some(d) = &discovered {
        report.discovery = Some(discovery_stage::DiscoveryReport::of(d)?);
    }
    report.tracker_registration = crate::registration::RegistrationReport::load(out)?;
    if report.tracker_registration.is_some() {
        files.note(crate::registration::TRACKER_REGISTRATION_FILE);
    }
    files.json("report.json", &report)?;
    let discovery_tour = match discovery.filter(|_| discovered.is_some()) {
        Some(stage) => Some(discovery_stage::discovery_tour(stage, &nominal, out)?.0),
        None => None,
    };
    let loop_tour = match discovered.as_ref().and_then(|d| d.measurement_loop.as_ref()).filter(|l| l.ran) {
        Some(_) => Some(
            PlanFolder::new(out.join(crate::discovery_loop::LOOP_PLAN)).read_tour(nominal.joint_kinds())?,
        ),
        None => None,
    };
    let timing = timing::measure(&timing::TimingInputs {
        out,
        nominal: &nominal,
        motion: &opts.nominal.motion_limits(),
        tour: &tour,
        plan: &report.plan,
        discovery_tour: discovery_tour.as_ref(),
        loop_tour: loop_tour.as_ref(),
        validation_steps: &validation.plan.campaign,
    })?;
    book.finish(Stage::Report, None, |_| None)?;
    let stage_seconds = book.seconds.clone();
    files.note("summary.md");
    if discovered.is_some() {
        files.note("summary.html");
    }
    let mut timing = timing;
    timing.set_wall(&stage_seconds, &book.state);
    timing::write(out, &timing)?;
    let outcome = RunOutcome {
        report,
        identification: fit.clone(),
        stage_seconds,
        files: files.written().to_vec(),
        discovery: discovered,
        timing: Some(timing),
    };
    files.summary("summary.md", &outcome)?;
    if outcome.discovery.is_some() {
        report::write_summary_html(out)?;
    }
    Ok(CalibrateOutcome {
        run: Some(outcome),
        identification: Some(fit),
        ran: book.ran,
        recomputed: book.recomputed,
        state: book.state,
    })
}

fn finish_early<S>(
    book: Book<'_>,
    _files: report::Files,
    fit: Option<Identification>,
) -> Result<CalibrateOutcome<S>, PipelineError> {
    Ok(CalibrateOutcome {
        run: None,
        identification: fit,
        ran: book.ran,
        recomputed: book.recomputed,
        state: book.state,
    })
}

/// `report.json`'s `setup` of a run on real devices (`vatcal calibrate`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellRunSetup {
    /// the nominal cell file (copied to `nominal.toml`)
    pub nominal_cell: String,
    /// the devices file
    pub devices: String,
    /// the run's sizes
    pub sizes: RunSizes,
    /// identified parameter set
    pub parameters: String,
    /// estimation method
    pub method: String,
}

impl CellRunSetup {
    /// The setup of a run of `opts` with the devices file `devices` that identified `fit`.
    pub fn of(opts: &RunOptions, nominal_cell: &str, devices: &str, fit: &Identification) -> Self {
        Self {
            nominal_cell: nominal_cell.into(),
            devices: devices.into(),
            sizes: opts.sizes.clone(),
            parameters: format!(
                "{} ({} parameters)",
                discovery_stage::parameter_set_name(&fit.params),
                fit.params.len()
            ),
            method: fit.method.to_string(),
        }
    }
}

/// `report.json`'s `format` of a run on real devices.
pub const CELL_REPORT_FORMAT: &str = "vatcal-calibrate-report";

impl ReportSetup for CellRunSetup {
    fn format(&self) -> &str {
        CELL_REPORT_FORMAT
    }

    fn title(&self, seed: u64) -> String {
        format!("# vatcal calibrate — calibration of {} (seed {seed})", self.nominal_cell)
    }

    fn intro(&self) -> String {
        format!(
            "Everything below was measured on the devices of `{}` (`stages.json`: the stages and their attempts; \
             the journals hold every measurement).",
            self.devices
        )
    }

    fn setup_markdown(&self, v: &crate::ValidationSummary) -> String {
        use std::fmt::Write as _;
        let mut m = String::new();
        let _ = writeln!(
            m,
            "* nominal cell (what the robot controller believes): {} → `nominal.toml`",
            self.nominal_cell
        );
        let _ = writeln!(m, "* devices: `{}`", self.devices);
        let s = &self.sizes;
        let _ = writeln!(
            m,
            "* sizes: {} orientations × {} guide steps per TCP × position, {} measurements, {} random validation poses, \
             {} printing slices",
            s.orientations, s.guide_steps, s.count, v.random_poses, v.printing_path.slices
        );
        m
    }

    fn parameters(&self) -> String {
        self.parameters.clone()
    }

    fn method(&self) -> String {
        self.method.clone()
    }
}
