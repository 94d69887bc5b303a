//! The stages of [`crate::calibrate()`], one function each: run the stage (its bookkeeping in
//! [`Book`]) or, when it is done from an earlier call, recompute its outputs from the run
//! folder. Each takes the outputs of the stages before it and returns its own; the stage
//! modules do the work.

use vatcal_campaign::validation::ValidationPlanOptions;
use vatcal_campaign::{CampaignPlan, CampaignReport, Journal};
use vatcal_core::{JointVector, ParamSet};
use vatcal_identification::Identification;
use vatcal_kinematics::Model;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::PlanSummary;

use crate::book::Book;
use crate::campaign_stage::{campaign_stage, device_span};
use crate::compensation::{CompensationSummary, PrintingPathTargets, check_printing_path};
use crate::devices::DeviceSource;
use crate::discovery_stage::{
    DiscoveryOutcome, DiscoveryStageOptions, discovery_recompute, discovery_stage, discovery_tour,
};
use crate::files::Files;
use crate::folders::{
    CALIBRATED_CELL, CAMPAIGN_JOURNAL, DISCOVERY_JOURNAL, DISCOVERY_MEASUREMENTS_CSV, LOOP_JOURNAL,
    LOOP_MEASUREMENTS_CSV, LOOP_PLAN, LOOP_PROPOSAL, MEASUREMENTS_CSV, PLAN_DIR, REPORT_JSON, RunFolder,
    SUMMARY_HTML, SUMMARY_MD, TRACKER_REGISTRATION_FILE, VALIDATION_JOURNAL,
};
use crate::identify_stage::{calibrated_cell, identify_stage};
use crate::outcome::{CalibrateOutcome, RunOutcome};
use crate::plan_stage::{plan_recompute, plan_stage};
use crate::registration::RegistrationReport;
use crate::report::{ReportInputs, ReportSetup, build_report};
use crate::summary::summary_markdown;
use crate::summary_html::write_summary_html;
use crate::timing::{RunTiming, TimingInputs};
use crate::validation_stage::{ValidationStage, validation_plan, validation_recompute, validation_stage};
use crate::{CALIBRATED, DISCOVERED, NOMINAL, PipelineError, RunOptions, Stage, TRUE_STRUCTURE};

/// What every stage of a call reads: the run's options, the nominal model and cell geometry,
/// the run folder.
pub(crate) struct Run<'a> {
    pub opts: &'a RunOptions,
    pub discovery: Option<&'a DiscoveryStageOptions>,
    pub nominal: Model,
    pub geometry: CellGeometry,
    pub folder: RunFolder,
}

impl<'a> Run<'a> {
    /// The run of `opts` into the folder `out`.
    pub fn new(
        opts: &'a RunOptions,
        discovery: Option<&'a DiscoveryStageOptions>,
        out: &std::path::Path,
    ) -> Result<Self, PipelineError> {
        Ok(Self {
            opts,
            discovery,
            nominal: Model::from_cell(&opts.nominal)?,
            geometry: CellGeometry::from_cell(&opts.nominal)?,
            folder: RunFolder::new(out),
        })
    }
}

/// The `plan` stage: the plan's summary and parameter set.
pub(crate) fn plan(run: &Run<'_>, book: &mut Book<'_>) -> Result<(PlanSummary, ParamSet), PipelineError> {
    let planned = if book.runs(Stage::Plan) {
        book.begin(Stage::Plan, None)?;
        let (candidates, plan, params) =
            plan_stage(run.opts, &run.nominal, &run.geometry, &run.folder.plan())?;
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
        plan_recompute(run.opts, &run.nominal, &run.geometry)?
    };
    book.files.note_plan(PLAN_DIR);
    Ok(planned)
}

/// The `campaign` stage's outputs.
pub(crate) struct Measured {
    /// the plan folder's tour
    pub tour: CampaignPlan,
    /// every measurement and journal record
    pub campaign: CampaignReport,
    /// the campaign's time on the devices' clock
    pub time_s: f64,
    /// the devices' clock at the start, when the campaign ran from its start in this call
    pub clock_start_s: Option<f64>,
}

impl Measured {
    /// Where the campaign left the arm.
    fn last_joints(&self) -> Option<JointVector> {
        self.campaign.records.last().map(|r| r.state.joints)
    }
}

/// The `campaign` stage: measured on the devices, or read back from its journal.
pub(crate) fn campaign(
    run: &Run<'_>,
    book: &mut Book<'_>,
    devices: &mut dyn DeviceSource,
) -> Result<Measured, PipelineError> {
    let tour = run.folder.plan().read_tour(run.nominal.joint_kinds())?;
    let mut clock_start_s = None;
    let (campaign, time_s) = if book.runs(Stage::Campaign) {
        if book.restarts(Stage::Campaign) {
            run.folder.remove(CAMPAIGN_JOURNAL)?;
        }
        book.mark_running(Stage::Campaign)?;
        book.restart_clock();
        let dev = devices.open()?;
        let start_s = dev.devices().clock.now_s();
        let config = run.opts.campaign.clone();
        let campaign = campaign_stage(dev, &run.nominal, &tour, &run.folder, config, &mut *book.progress)?;
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
        (run.folder.journal_report(CAMPAIGN_JOURNAL)?, book.device_s(Stage::Campaign))
    };
    book.files.note(CAMPAIGN_JOURNAL);
    book.files.note(MEASUREMENTS_CSV);
    Ok(Measured { tour, campaign, time_s, clock_start_s })
}

/// The `identify` stage (deterministic: recomputed from the journal when done).
pub(crate) fn identify(
    run: &Run<'_>,
    book: &mut Book<'_>,
    measured: &Measured,
    params: &ParamSet,
) -> Result<Identification, PipelineError> {
    let measurements = &measured.campaign.measurements;
    if !book.runs(Stage::Identify) {
        book.recompute(Stage::Identify)?;
        book.files.note(CALIBRATED_CELL);
        return identify_stage(&run.nominal, measurements, params);
    }
    book.begin(Stage::Identify, None)?;
    let fit = identify_stage(&run.nominal, measurements, params)?;
    book.files.cell(CALIBRATED_CELL, &calibrated_cell(&fit, measurements))?;
    book.finish(Stage::Identify, None, |s| {
        Some(format!(
            "identification: {} parameters, {} iterations, residual mean {:.4} mm ({s:.1} s)",
            fit.params.len(),
            fit.iterations.len().saturating_sub(1),
            fit.residual_stats.mean
        ))
    })?;
    Ok(fit)
}

/// The `discovery` stage, optional: `None` when the run has no discovery stage, or it is
/// neither selected nor done.
pub(crate) fn discovery(
    run: &Run<'_>,
    book: &mut Book<'_>,
    devices: &mut dyn DeviceSource,
    fit: &Identification,
    measured: &Measured,
) -> Result<Option<DiscoveryOutcome>, PipelineError> {
    let wanted = book.selected(Stage::Discover) || book.state.is_done(Stage::Discover);
    let Some(stage) = run.discovery.filter(|_| wanted) else {
        return Ok(None);
    };
    if book.runs(Stage::Discover) {
        return measure_discovery(run, book, devices, stage, fit, measured).map(Some);
    }
    book.recompute(Stage::Discover)?;
    let (opts, nominal, calibration) = (run.opts, &run.nominal, &measured.campaign.measurements);
    let out = run.folder.dir();
    let d = discovery_recompute(opts, stage, nominal, &fit.model, &fit.params, calibration, out)?;
    note_discovery_files(&mut book.files, &d);
    for p in &d.plots {
        book.files.note(&p.file);
    }
    Ok(Some(d))
}

/// The discovery stage measured on the devices (its journal continued when resumed).
fn measure_discovery(
    run: &Run<'_>,
    book: &mut Book<'_>,
    devices: &mut dyn DeviceSource,
    stage: &DiscoveryStageOptions,
    fit: &Identification,
    measured: &Measured,
) -> Result<DiscoveryOutcome, PipelineError> {
    if book.restarts(Stage::Discover) {
        run.folder.remove(DISCOVERY_JOURNAL)?;
    }
    book.mark_running(Stage::Discover)?;
    book.restart_clock();
    let dev = devices.open()?;
    let start_s = dev.devices().clock.now_s();
    let resumed = run.folder.path(DISCOVERY_JOURNAL).exists();
    let d = discovery_stage(
        run.opts,
        stage,
        dev,
        &run.nominal,
        &fit.model,
        &fit.params,
        &measured.campaign.measurements,
        measured.last_joints(),
        run.folder.dir(),
        run.opts.campaign.clone(),
        &mut *book.progress,
    )?;
    let clock_delta = dev.devices().clock.now_s() - start_s;
    let t = if resumed {
        let journal = run.folder.journal_report(DISCOVERY_JOURNAL)?;
        journal.records.last().map_or(clock_delta, |r| r.time_s)
    } else {
        book.fresh.push(Stage::Discover);
        clock_delta
    };
    note_discovery_files(&mut book.files, &d);
    for p in &d.plots {
        book.files.svg(&p.file, &p.svg)?;
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
    Ok(d)
}

/// The discovery campaign's files and, when the measurement loop measured, the loop's.
fn note_discovery_files(files: &mut Files, d: &DiscoveryOutcome) {
    files.note(DISCOVERY_JOURNAL);
    files.note(DISCOVERY_MEASUREMENTS_CSV);
    if d.measurement_loop.as_ref().is_some_and(|l| l.ran) {
        files.note(LOOP_JOURNAL);
        files.note(LOOP_MEASUREMENTS_CSV);
        files.note_plan(LOOP_PLAN);
        files.note(std::path::Path::new(LOOP_PLAN).join(LOOP_PROPOSAL));
    }
}

/// The `validation` stage's outputs.
pub(crate) struct Validated {
    /// the plan, the tracker records, each model's errors
    pub stage: ValidationStage,
    /// the options the plan was built with
    pub options: ValidationPlanOptions,
    /// the compensation's targets of the printing path, checked before any motion (`None`
    /// without a printing path)
    pub printing_targets: Option<PrintingPathTargets>,
    /// the validation's time on the devices' clock, as the report gives it
    pub time_s: f64,
}

/// The models the validation commands: nominal, calibrated and, with a discovery, the
/// discovered and the true-structure model.
fn validated_models<'m>(
    nominal: &'m Model,
    fit: &'m Identification,
    discovered: Option<&'m DiscoveryOutcome>,
) -> Vec<(&'static str, &'m Model)> {
    let mut models: Vec<(&str, &Model)> = vec![(NOMINAL, nominal), (CALIBRATED, &fit.model)];
    if let Some(d) = discovered {
        models.push((DISCOVERED, &d.discovery.model));
        if let Some(t) = &d.true_structure {
            models.push((TRUE_STRUCTURE, t));
        }
    }
    models
}

/// The `validation` stage: planned from where the last campaign left the arm, the printing
/// path checked against the compensation's targets, then measured (or recomputed from its
/// journal when done).
pub(crate) fn validation(
    run: &Run<'_>,
    book: &mut Book<'_>,
    devices: &mut dyn DeviceSource,
    fit: &Identification,
    discovered: Option<&DiscoveryOutcome>,
    measured: &Measured,
) -> Result<Validated, PipelineError> {
    let start = discovered.and_then(|d| d.last_joints).or(measured.last_joints());
    let models = validated_models(&run.nominal, fit, discovered);
    let (plan, options) = validation_plan(run.opts, &run.nominal, &run.geometry, &models, start)?;
    let printing_targets = match plan.slices.is_empty() {
        true => None,
        false => Some(check_printing_path(&run.nominal, &fit.model, &plan)?),
    };
    let discovery_s = if discovered.is_some() { book.device_s(Stage::Discover) } else { 0.0 };
    let (stage, time_s) = if book.runs(Stage::Validate) {
        measure_validation(run, book, devices, &models, plan, discovered.is_some(), measured)?
    } else {
        book.recompute(Stage::Validate)?;
        let v = validation_recompute(&run.nominal, &models, plan, &run.folder)?;
        (v, book.device_s(Stage::Validate) + discovery_s)
    };
    book.files.note(VALIDATION_JOURNAL);
    Ok(Validated { stage, options, printing_targets, time_s })
}

/// The validation measured on the devices: its own time on the devices' clock in the stage
/// state, and the time the report gives it (everything on the cell's clock after the
/// measurement campaign, the discovery campaign included, as the demo has always reported it).
fn measure_validation(
    run: &Run<'_>,
    book: &mut Book<'_>,
    devices: &mut dyn DeviceSource,
    models: &[(&str, &Model)],
    plan: vatcal_campaign::validation::ValidationPlan,
    discovered: bool,
    measured: &Measured,
) -> Result<(ValidationStage, f64), PipelineError> {
    if book.restarts(Stage::Validate) {
        run.folder.remove(VALIDATION_JOURNAL)?;
        run.folder.remove_registration()?;
    }
    let resumed = run.folder.path(VALIDATION_JOURNAL).exists();
    book.progress.stage_started(Stage::Validate, Some(plan.campaign.steps.len()));
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
    let config = run.opts.campaign.clone();
    let (validation, registration) =
        validation_stage(dev, &run.nominal, models, plan, &run.folder, config, &mut *book.progress)?;
    let end_s = dev.devices().clock.now_s();
    let own_s = match resumed {
        true => Journal::open(run.folder.path(VALIDATION_JOURNAL))?
            .records()
            .last()
            .map_or(end_s - start_s, |r| r.time_s),
        false => end_s - start_s,
    };
    let reported_s = match measured.clock_start_s {
        Some(c0) if !resumed && (!discovered || book.fresh.contains(&Stage::Discover)) => {
            end_s - c0 - measured.time_s
        }
        _ => own_s + if discovered { book.device_s(Stage::Discover) } else { 0.0 },
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
    Ok((validation, reported_s))
}

/// The time on the devices of every campaign of the run folder, against the planner's
/// estimates (stage times filled by the caller).
pub(crate) fn measure_timing(
    run: &Run<'_>,
    measured: &Measured,
    plan: &PlanSummary,
    discovered: Option<&DiscoveryOutcome>,
    validation_steps: &CampaignPlan,
) -> Result<RunTiming, PipelineError> {
    let out = run.folder.dir();
    let discovery_tour = match run.discovery.filter(|_| discovered.is_some()) {
        Some(stage) => Some(discovery_tour(stage, &run.nominal, out)?.0),
        None => None,
    };
    let loop_tour = match discovered.and_then(|d| d.measurement_loop.as_ref()).filter(|l| l.ran) {
        Some(_) => Some(run.folder.loop_plan().read_tour(run.nominal.joint_kinds())?),
        None => None,
    };
    crate::timing::measure(&TimingInputs {
        out,
        nominal: &run.nominal,
        motion: &run.opts.nominal.motion_limits(),
        tour: &measured.tour,
        plan,
        discovery_tour: discovery_tour.as_ref(),
        loop_tour: loop_tour.as_ref(),
        budget: discovered.and_then(|d| d.budget.as_ref()).map(|b| (b.budget_s, b.spent_s)),
        validation_steps,
    })
}

/// The `compensation` stage, the last: the compensation summary of the printing path, the
/// report (`report.json`, `summary.md`, `summary.html` with a discovery), the validation's CSVs,
/// the plots and `timing.json`, from the outputs of every stage before it.
#[allow(clippy::too_many_arguments)] // the outputs of the five stages before it
pub(crate) fn report<S: ReportSetup>(
    run: &Run<'_>,
    mut book: Book<'_>,
    setup: S,
    plan: PlanSummary,
    measured: Measured,
    fit: Identification,
    discovered: Option<DiscoveryOutcome>,
    validated: Validated,
) -> Result<CalibrateOutcome<S>, PipelineError> {
    let out = run.folder.dir();
    book.begin(Stage::Report, None)?;
    let ValidationStage { plan: validation_plan, records, results } = validated.stage;
    book.files.validation_csvs(&records, &validation_plan.slices, &results)?;
    book.files.plots(&fit, &validation_plan.slices, &results)?;
    let compensation = validated.printing_targets.as_ref().map(|t| CompensationSummary::new(t, &results));
    let tracker_registration = RegistrationReport::load(out)?;
    let report = build_report(ReportInputs {
        seed: run.opts.seed,
        setup,
        plan,
        campaign: &measured.campaign,
        campaign_time_s: measured.time_s,
        fit: &fit,
        validation_plan: &validation_plan,
        validation_options: &validated.options,
        validation_time_s: validated.time_s,
        compensation,
        results,
        discovery: discovered.as_ref(),
        tracker_registration,
    })?;
    if report.tracker_registration.is_some() {
        book.files.note(TRACKER_REGISTRATION_FILE);
    }
    book.files.json(REPORT_JSON, &report)?;
    let mut timing =
        measure_timing(run, &measured, &report.plan, discovered.as_ref(), &validation_plan.campaign)?;
    book.finish(Stage::Report, None, |_| None)?;
    let stage_seconds = book.seconds.clone();
    book.files.note(SUMMARY_MD);
    if discovered.is_some() {
        book.files.note(SUMMARY_HTML);
    }
    timing.set_wall(&stage_seconds, &book.state);
    crate::timing::write(out, &timing)?;
    let outcome = RunOutcome {
        report,
        identification: fit.clone(),
        stage_seconds,
        files: book.files.written().to_vec(),
        discovery: discovered,
        timing: Some(timing),
    };
    let summary = out.join(SUMMARY_MD);
    std::fs::write(&summary, summary_markdown(&outcome))
        .map_err(|source| PipelineError::Io { path: summary, source })?;
    if outcome.discovery.is_some() {
        write_summary_html(out)?;
    }
    Ok(book.outcome(Some(outcome), Some(fit)))
}
