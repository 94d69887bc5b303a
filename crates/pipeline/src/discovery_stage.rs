//! The discovery stage (issue 11 item 3): after the paper's calibration, a second probe
//! campaign on the same cell, the missing-effect discovery (`vatcal-discovery`) on all probe
//! data, and — when the caller knows it (a simulated cell's oracle) — a fit with the true
//! effect structure, the floor any discovered model can reach. The validation then measures
//! the discovered and the true-structure model with the same tracker runs as the others.
//!
//! The extra measurements are selected by Detmax for the paper's 34 parameters **plus** the
//! directions of the candidate effects ([`DiscoveryStageOptions::plan_effects`], switched on at
//! zero in the planning model), so the poses excite what the 34 parameters cannot explain.
//! Every probe measurement carries its context (`dir2..dir7` of the last motion, `time_s` and,
//! when the cell has a thermometer, `temperature_c`, from the campaign journal), which the
//! backlash and drift candidates need. A few planned poses are measured twice, approached
//! from opposite sides on every revolute joint ([`add_two_sided_repeats`]), so backlash is
//! excited explicitly.

use std::fmt::Write as _;
use std::path::Path;

use vatcal_campaign::{CampaignConfig, CampaignPlan, CampaignReport};
use vatcal_core::effects::EffectSpec;
use vatcal_core::{JointVector, Measurement, ParamSet};
use vatcal_discovery::plots::{effect_plot_file_name, effect_plot_svg};
use vatcal_discovery::{DiscoverOptions, Discovery, discover};
use vatcal_hardware_traits::JointLayout;
use vatcal_identification::{IdentifyOptions, identify};
use vatcal_kinematics::Model;
use vatcal_kinematics::effects::{DataAvailability, missing_data};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::motion::MotionTimer;
use vatcal_planning::output::PlanSummary;
use vatcal_planning::plan::plan_campaign;

use crate::budget::{
    BatchSpend, BudgetReport, DEFAULT_DISCOVERY_BUDGET_S, DeviceTimeModel, PREDICTION_MARGIN, fit_batch,
    journal_end, measure_steps, targeted_reserve_s,
};
use crate::campaign_runner::run_campaign;
pub use crate::discovery_loop::LoopDevices;
use crate::discovery_loop::{LoopInputs, LoopReport, LoopSettings, measurement_loop};
pub use crate::folders::{DISCOVERY_JOURNAL, DISCOVERY_MEASUREMENTS_CSV, DISCOVERY_PLAN};
use crate::folders::{PlanFolder, PlanHeader, PlanKind, RunFolder};
pub use crate::options::{DISCOVERED, TRUE_STRUCTURE};
pub use crate::two_sided::add_two_sided_repeats;
use crate::{DeviceSet, PipelineError, Progress, RunOptions, Stage};

/// Settings of the discovery stage.
#[derive(Debug, Clone)]
pub struct DiscoveryStageOptions {
    /// extra probe measurements selected by Detmax
    pub count: usize,
    /// candidate effects whose directions the Detmax selection also excites
    pub plan_effects: Vec<EffectSpec>,
    /// the true effect structure (oracle of a simulated cell); `None` on a real cell: no
    /// true-structure row
    pub true_effects: Option<Vec<EffectSpec>>,
    /// settings of the discovery loop
    pub discover: DiscoverOptions,
    /// planned poses measured a second time right after the first, approached from the
    /// opposite direction on every revolute joint ([`add_two_sided_repeats`]), so that
    /// backlash is excited explicitly
    pub two_sided_repeats: usize,
    /// how far past the measurement pose each joint is taken before the opposite-side
    /// approach of a repeat \[rad\] (well above any lost motion of the gears)
    pub repeat_overshoot_rad: f64,
    /// measurements the **loop** proposes when the discovery ends with borderline or rival
    /// candidates (`crate::discovery_loop`); 0: no loop
    pub loop_count: usize,
    /// at most this many undecided candidates are targeted by the loop
    pub loop_targets: usize,
    /// device-time budget of the discovery measurements \[s\] ([`crate::budget`]): the Detmax
    /// batch is sized to fit it (`count` is then the largest size tried) and the targeted
    /// batch is measured only when it fits what is left; `None`: `count` measurements and the
    /// loop whatever they take. Default ([`DiscoveryStageOptions::new`]): 15 min
    /// ([`DEFAULT_DISCOVERY_BUDGET_S`]), the same as the default of `--discovery-budget-min`
    /// of `vatcal demo` and `vatcal calibrate`
    pub budget_s: Option<f64>,
}

impl DiscoveryStageOptions {
    /// At most 360 extra measurements planned for [`default_plan_effects`] plus 12 two-sided
    /// repeats (1 mrad overshoot), sized to fit a device-time budget of 15 min
    /// ([`DEFAULT_DISCOVERY_BUDGET_S`], as the CLI's `--discovery-budget-min`; set `budget_s`
    /// to `None` for all 360 whatever they take); the discovery's defaults with `seed`. Give
    /// the instruments' noise with [`DiscoveryStageOptions::with_instrument_noise`] so that the
    /// size rule does not compare with σ̂, which the physics still unmodelled inflates to
    /// ~0.1 mm (docs/discovery.md). 360, not 120 (unbudgeted): the held-out improvement of each
    /// further effect is masked by the misfit of the ones still missing, and its z grows with
    /// √n (measured on seed 2: 3 effects added from 189 measurements, 7 from 284).
    pub fn new(seed: u64) -> Self {
        Self {
            count: 360,
            plan_effects: default_plan_effects(),
            true_effects: None,
            discover: DiscoverOptions { seed, ..DiscoverOptions::default() },
            two_sided_repeats: 12,
            repeat_overshoot_rad: 1e-3,
            loop_count: 12,
            loop_targets: 2,
            // 15 min of device time, as `--discovery-budget-min` of `vatcal demo` and
            // `vatcal calibrate`: with the joint search the budgeted campaign gives the demo a
            // discovered/34 error of 22-30 % (docs/discovery.md, "The measurement budget")
            budget_s: Some(DEFAULT_DISCOVERY_BUDGET_S),
        }
    }

    /// The same with the instruments' known noise per axis: probe measurements (after
    /// centring, the offset read by the gauges) and tracker measurements \[mm\].
    pub fn with_instrument_noise(mut self, probe_mm: f64, tracker_mm: f64) -> Self {
        self.discover.instrument_sigmas = Some(vatcal_identification::KindSigmas {
            probe_mm: Some(probe_mm),
            tracker_mm: Some(tracker_mm),
        });
        self
    }
}

/// The candidate effects the discovery campaign is planned for on the canonical cell: gear
/// harmonics 1 and 2 of joints 2..7 and a quadratic guide pitch/yaw/roll (the carriage tilt is
/// left out: about one axis it is indistinguishable from the compliance of joint 2 on the
/// candidate poses). [`plan_effects_for`] gives them for any chain.
pub fn default_plan_effects() -> Vec<EffectSpec> {
    let mut v = Vec::new();
    for joint in 2..=7u8 {
        for harmonic in 1..=2u8 {
            v.push(EffectSpec::JointCyclic { joint, harmonic });
        }
    }
    v.push(EffectSpec::GuideAngular { order: 2 });
    v
}

/// The candidate effects of [`default_plan_effects`] for the chain of `model`: gear harmonics
/// 1 and 2 of every revolute joint, and the quadratic guide pitch/yaw/roll when the chain has
/// a guide ([`JointLayout`]). Equal to [`default_plan_effects`] on the canonical cell.
pub fn plan_effects_for(model: &Model) -> Vec<EffectSpec> {
    let mut v = Vec::new();
    for joint in (1..=model.joint_count()).filter(|j| model.is_revolute(*j)) {
        for harmonic in 1..=2u8 {
            v.push(EffectSpec::JointCyclic { joint: joint as u8, harmonic });
        }
    }
    if JointLayout::of(model.joint_kinds()).has_guide() {
        v.push(EffectSpec::GuideAngular { order: 2 });
    }
    v
}

/// An SVG of one added effect (residual against its driving variable, before and after).
#[derive(Debug, Clone, PartialEq)]
pub struct EffectPlot {
    /// file name in the run folder (`discovery_step1-….svg`)
    pub file: String,
    /// what it shows
    pub caption: String,
    /// the SVG document
    pub svg: String,
}

/// What the discovery stage produced.
#[derive(Debug, Clone)]
pub struct DiscoveryOutcome {
    /// the discovery loop's result (final model, added effects, rounds)
    pub discovery: Discovery,
    /// probe measurements of the discovery campaign (beyond the calibration's)
    pub extra_measurements: usize,
    /// of those, repeats of a planned pose approached from the opposite side on every
    /// revolute joint ([`add_two_sided_repeats`])
    pub two_sided_repeats: usize,
    /// probe measurements the discovery used in all
    pub total_measurements: usize,
    /// the measurement loop (`crate::discovery_loop`): `None` when the stage has no loop
    /// (`loop_count` 0)
    pub measurement_loop: Option<LoopReport>,
    /// the model fitted with the true effect structure, when the oracle was given and the fit
    /// succeeded
    pub true_structure: Option<Model>,
    /// how the true-structure model was fitted, or why it is missing
    pub true_structure_note: String,
    /// one plot per added effect
    pub plots: Vec<EffectPlot>,
    /// where the discovery campaign left the arm
    pub last_joints: Option<JointVector>,
    /// number of the calibration's parameters (the base of the discovery; 34 on the canonical
    /// cell)
    pub base_params: usize,
    /// how the summary names the calibration's parameters: `the paper's 34 parameters`, or
    /// `the calibration's N parameters` for another set
    pub base_name: String,
    /// the direction columns recorded with each measurement, e.g. `dir2..dir7` on the
    /// canonical cell, `dir1..dir6` on a six-joint arm
    pub dir_columns: String,
    /// how the device-time budget sized the batches and what they cost (`None`: no budget)
    pub budget: Option<BudgetReport>,
}

/// How the summary names a calibration parameter set: `the paper's 34 parameters` for
/// [`ParamSet::paper34`], `the calibration's N parameters` otherwise.
pub fn parameter_set_name(set: &ParamSet) -> String {
    if set == &ParamSet::paper34() {
        format!("the paper's {} parameters", set.len())
    } else {
        format!("the calibration's {} parameters", set.len())
    }
}

/// The `dir{i}` columns of a chain's revolute joints for text: `dir2..dir7` when they are
/// consecutive, else the list (`dir1,dir3`), `none` without revolute joints.
pub fn dir_columns_text(kinds: &[vatcal_core::JointKind]) -> String {
    let cols = vatcal_io::dir_columns(kinds);
    let consecutive = cols.windows(2).all(|w| w[1].0 == w[0].0 + 1);
    match cols.as_slice() {
        [] => "none".to_string(),
        [(_, one)] => one.clone(),
        [(_, first), .., (_, last)] if consecutive => format!("{first}..{last}"),
        _ => cols.iter().map(|(_, c)| c.as_str()).collect::<Vec<_>>().join(","),
    }
}

/// Plans the discovery campaign (Detmax for the calibration's parameters `base` — the paper's
/// 34 on the canonical cell — and the candidate effects' directions), starting at `start`,
/// into `folder`.
///
/// # Errors
/// An invalid candidate effect or a planning failure.
pub fn plan_discovery(
    opts: &RunOptions,
    stage: &DiscoveryStageOptions,
    nominal: &Model,
    base: &ParamSet,
    geometry: &CellGeometry,
    start: Option<JointVector>,
    folder: &PlanFolder,
) -> Result<PlanSummary, PipelineError> {
    plan_discovery_of(opts, stage, stage.count, nominal, base, geometry, start, folder)
}

/// [`plan_discovery`] with `count` measurements.
#[allow(clippy::too_many_arguments)]
fn plan_discovery_of(
    opts: &RunOptions,
    stage: &DiscoveryStageOptions,
    count: usize,
    nominal: &Model,
    base: &ParamSet,
    geometry: &CellGeometry,
    start: Option<JointVector>,
    folder: &PlanFolder,
) -> Result<PlanSummary, PipelineError> {
    let mut model = nominal.clone();
    let mut params = base.0.clone();
    for spec in &stage.plan_effects {
        model.enable_effect(*spec)?;
        for id in spec.params() {
            if !params.contains(&id) {
                params.push(id);
            }
        }
    }
    let mut options = crate::plan_options(opts);
    options.count = count;
    options.params = ParamSet(params);
    options.start = start;
    options.seed = opts.seed ^ 0x000d_15c0_7e11_0003;
    let plan = plan_campaign(&model, geometry, &options)?;
    let summary = folder.write(&plan)?;
    folder.mark(&PlanHeader {
        kind: PlanKind::Discovery,
        two_sided_repeats: Some(stage.two_sided_repeats),
        repeat_overshoot_deg: Some(stage.repeat_overshoot_rad.to_degrees()),
    })?;
    Ok(summary)
}

/// The discovery campaign of a discovery plan folder: its `tour.csv` with `repeats` two-sided
/// repeats added ([`add_two_sided_repeats`]), and the number added.
///
/// # Errors
/// A missing or bad `tour.csv`.
pub fn discovery_tour_of(
    folder: &PlanFolder,
    nominal: &Model,
    repeats: usize,
    overshoot_rad: f64,
) -> Result<(CampaignPlan, usize), PipelineError> {
    let mut tour = folder.read_tour(nominal.joint_kinds())?;
    let added = add_two_sided_repeats(&mut tour, nominal, repeats, overshoot_rad);
    Ok((tour, added))
}

/// Runs a discovery campaign `tour` ([`discovery_tour_of`]) on `devices` into the run folder's
/// `discovery.journal` (resumed when present) and writes `discovery_measurements.csv` (probe
/// rows with `dir{i}`, `time_s` and, with a thermometer, `temperature_c`).
///
/// # Errors
/// The campaign's error (the journal keeps every completed step).
pub fn discovery_campaign_stage(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    tour: &CampaignPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<CampaignReport, PipelineError> {
    let journal = folder.path(PlanKind::Discovery.journal());
    let campaign = run_campaign(devices, nominal, tour, &journal, config, Stage::Discover, None, progress)?;
    vatcal_io::write_measurements_for(
        folder.path(PlanKind::Discovery.measurements()),
        &campaign.measurements,
        nominal.joint_kinds(),
    )?;
    Ok(campaign)
}

/// Runs the whole discovery stage: plans and runs the extra probe campaign on `devices`
/// (journal `discovery.journal`, `discovery_measurements.csv`), discovers missing effects from
/// `calibrated` on all probe data, fits the true structure when it is known. A
/// `discovery.journal` of the same plan already in `out` is resumed (nothing measured twice);
/// remove it to measure afresh.
///
/// # Errors
/// Planning, the campaign, or the discovery loop fails (a failed true-structure fit is only
/// noted).
#[allow(clippy::too_many_arguments)]
pub fn discovery_stage(
    opts: &RunOptions,
    stage: &DiscoveryStageOptions,
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    calibrated: &Model,
    base: &ParamSet,
    calibration: &[Measurement],
    start: Option<JointVector>,
    out: &Path,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<DiscoveryOutcome, PipelineError> {
    let folder = RunFolder::new(out);
    let geometry = CellGeometry::from_cell(&opts.nominal)?;
    let inputs = AnalysisInputs { opts, stage, nominal, calibrated, base, calibration, out };
    let clock = calibration_clock(&inputs)?;
    match (stage.budget_s, &clock) {
        (Some(budget_s), Some(clock)) => plan_within_budget(&inputs, budget_s, clock, &geometry, start)?,
        _ => {
            plan_discovery(opts, stage, nominal, base, &geometry, start, &folder.discovery_plan())?;
        }
    }
    let (tour, repeats) = discovery_tour(stage, nominal, out)?;
    let campaign = discovery_campaign_stage(devices, nominal, &tour, &folder, config.clone(), progress)?;
    let budget = detmax_spend(&inputs, clock, &tour, &campaign);
    discovery_analysis(&inputs, &campaign, repeats, Some(LoopDevices { devices, config, progress }), budget)
}

/// The time model of the cell's devices ([`DeviceTimeModel`]), learned on the run folder's
/// calibration campaign (`campaign.journal` with `plan/tour.csv`); the planner's estimates
/// when there is none.
///
/// # Errors
/// A bad journal or tour, or motion limits the planner cannot time.
pub fn device_time_model(
    opts: &RunOptions,
    nominal: &Model,
    out: &Path,
) -> Result<DeviceTimeModel, PipelineError> {
    let folder = RunFolder::new(out);
    let timer = MotionTimer::for_model(&opts.nominal.motion_limits(), nominal)?;
    let journal = folder.journal();
    if !journal.is_file() || !folder.plan().path(crate::folders::TOUR_CSV).is_file() {
        return Ok(DeviceTimeModel::planner(timer));
    }
    let tour = folder.plan().read_tour(nominal.joint_kinds())?;
    DeviceTimeModel::from_campaign(&journal, &tour, timer)
}

/// With a budget, the time model of the cell's devices ([`device_time_model`]) and where the
/// calibration campaign left the arm (the start of the Detmax batch's first move); `None`
/// without a budget. Read once per stage from the run folder's calibration journal.
///
/// # Errors
/// As [`device_time_model`].
fn calibration_clock(
    inputs: &AnalysisInputs<'_>,
) -> Result<Option<(DeviceTimeModel, Option<JointVector>)>, PipelineError> {
    if inputs.stage.budget_s.is_none() {
        return Ok(None);
    }
    let time = device_time_model(inputs.opts, inputs.nominal, inputs.out)?;
    Ok(Some((time, journal_end(&RunFolder::new(inputs.out).journal()))))
}

/// The device time held back for the targeted batch: the loop's measurements at the probe
/// placement the Detmax batch ends at (no re-placement; 0 without a loop).
fn targeted_reserve(inputs: &AnalysisInputs<'_>, time: &DeviceTimeModel) -> f64 {
    let stage = inputs.stage;
    if stage.loop_count == 0 {
        return 0.0;
    }
    PREDICTION_MARGIN * targeted_reserve_s(time, stage.loop_count, 0)
}

/// Plans the Detmax batch into `discovery_plan/` sized to fit `budget_s` less the targeted
/// batch's reserve ([`fit_batch`], predictions by [`device_time_model`]; at most
/// `stage.count` measurements).
///
/// # Errors
/// A planning failure, or a budget that cannot fit the smallest batch.
fn plan_within_budget(
    inputs: &AnalysisInputs<'_>,
    budget_s: f64,
    (time, arm_at): &(DeviceTimeModel, Option<JointVector>),
    geometry: &CellGeometry,
    start: Option<JointVector>,
) -> Result<(), PipelineError> {
    let AnalysisInputs { opts, stage, nominal, base, out, .. } = *inputs;
    let reserve = targeted_reserve(inputs, time);
    let folder = RunFolder::new(out).discovery_plan();
    let fixed = opts.nominal.calibration_positions.len() as f64 * time.placement_s;
    let arm_at = *arm_at;
    let predict = |count: usize| -> Result<f64, PipelineError> {
        plan_discovery_of(opts, stage, count, nominal, base, geometry, start, &folder)?;
        let (tour, _) = discovery_tour(stage, nominal, out)?;
        Ok(PREDICTION_MARGIN * time.predict_s(&tour, arm_at))
    };
    // Detmax needs a pose per three parameters it plans for, and a margin over that
    let planned_params = base.len() + stage.plan_effects.iter().map(|e| e.params().len()).sum::<usize>();
    let min_count = planned_params.div_ceil(3) + 6;
    match fit_batch(stage.count, min_count, budget_s - reserve, fixed, predict)? {
        Some(_) => Ok(()),
        None => Err(PipelineError::Option {
            option: "discovery budget".into(),
            reason: format!(
                "{:.1} min of device time cannot fit the smallest Detmax batch ({} measurements for {planned_params} parameters) with {reserve:.0} s held back for the targeted batch",
                budget_s / 60.0,
                min_count.max(crate::budget::MIN_DETMAX_BATCH)
            ),
        }),
    }
}

/// The budget report after the Detmax batch (`tour`, measured as `campaign`; `clock` from
/// [`calibration_clock`]): `None` without a budget. The same from a run's devices and from its
/// journals.
fn detmax_spend(
    inputs: &AnalysisInputs<'_>,
    clock: Option<(DeviceTimeModel, Option<JointVector>)>,
    tour: &CampaignPlan,
    campaign: &CampaignReport,
) -> Option<BudgetReport> {
    let (budget_s, (time, arm_at)) = (inputs.stage.budget_s?, clock?);
    let mut report = BudgetReport {
        budget_s,
        time_model: time,
        targeted_reserve_s: targeted_reserve(inputs, &time),
        batches: Vec::new(),
        spent_s: 0.0,
        stop: String::new(),
    };
    report.push(BatchSpend {
        batch: "detmax".into(),
        planned: measure_steps(tour),
        predicted_s: time.predict_s(tour, arm_at),
        device_s: Some(campaign.device_s()),
    });
    Some(report)
}

/// The discovery stage of a finished run recomputed from its journals (`discovery.journal`
/// and, when the loop ran, `discovery_loop.journal` in `out`): the same outcome as the run
/// that measured them.
///
/// # Errors
/// A missing or bad journal or plan, or the discovery loop fails.
#[allow(clippy::too_many_arguments)]
pub fn discovery_recompute(
    opts: &RunOptions,
    stage: &DiscoveryStageOptions,
    nominal: &Model,
    calibrated: &Model,
    base: &ParamSet,
    calibration: &[Measurement],
    out: &Path,
) -> Result<DiscoveryOutcome, PipelineError> {
    let (tour, repeats) = discovery_tour(stage, nominal, out)?;
    let campaign = RunFolder::new(out).journal_report(DISCOVERY_JOURNAL)?;
    let inputs = AnalysisInputs { opts, stage, nominal, calibrated, base, calibration, out };
    let budget = detmax_spend(&inputs, calibration_clock(&inputs)?, &tour, &campaign);
    discovery_analysis(&inputs, &campaign, repeats, None, budget)
}

/// What the offline half of the discovery stage works on ([`discovery_analysis`]).
#[derive(Clone, Copy)]
#[allow(missing_debug_implementations)]
pub struct AnalysisInputs<'a> {
    /// the run's options (cell, sizes, seed)
    pub opts: &'a RunOptions,
    /// the stage's options
    pub stage: &'a DiscoveryStageOptions,
    /// the nominal model (plans and campaigns run on it)
    pub nominal: &'a Model,
    /// the calibrated model discovery starts from
    pub calibrated: &'a Model,
    /// the calibration's parameters (the paper's 34 on the canonical cell)
    pub base: &'a ParamSet,
    /// the calibration's probe measurements
    pub calibration: &'a [Measurement],
    /// the run folder
    pub out: &'a Path,
}

/// The discovery campaign of the plan folder `out/discovery_plan` (written by
/// [`plan_discovery`]) with its two-sided repeats ([`add_two_sided_repeats`]), and the number
/// of repeats.
///
/// # Errors
/// A missing or bad `tour.csv`.
pub fn discovery_tour(
    stage: &DiscoveryStageOptions,
    nominal: &Model,
    out: &Path,
) -> Result<(vatcal_campaign::CampaignPlan, usize), PipelineError> {
    discovery_tour_of(
        &RunFolder::new(out).discovery_plan(),
        nominal,
        stage.two_sided_repeats,
        stage.repeat_overshoot_rad,
    )
}

/// The offline half of the discovery stage: the discovery loop on the calibration's and the
/// discovery campaign's probe measurements, then the **measurement loop**
/// ([`measurement_loop`]: proposed measurements that decide borderline or rival candidates,
/// measured on `devices` or, without devices, read from `discovery_loop.journal`), then the
/// true-structure fit (oracle given) on the same data and one plot per added effect.
/// Deterministic: a finished run read back from its journals gives the same outcome.
///
/// # Errors
/// The discovery loop fails, the proposal cannot be planned, the loop's campaign fails or (no
/// devices) its journal is missing (a failed true-structure fit is only noted).
pub fn discovery_analysis(
    inputs: &AnalysisInputs<'_>,
    campaign: &vatcal_campaign::CampaignReport,
    repeats: usize,
    devices: Option<LoopDevices<'_>>,
    mut budget: Option<BudgetReport>,
) -> Result<DiscoveryOutcome, PipelineError> {
    let AnalysisInputs { opts, stage, nominal, calibrated, base, calibration, out } = *inputs;
    let mut all = calibration.to_vec();
    all.extend_from_slice(&campaign.measurements);
    let first = discover(calibrated, &all, base, None, &stage.discover)?;
    let campaign_end = campaign.records.last().map(|r| r.state.joints);
    let folder = RunFolder::new(out);
    // where the Detmax batch left the probe plate: the targeted batch measures there
    let probe_at = campaign.records.iter().rev().find_map(|r| match r.outcome {
        vatcal_campaign::StepOutcome::ProbePlaced { position } => Some(position),
        _ => None,
    });
    let loop_inputs = LoopInputs { opts, nominal, calibrated, base, folder: &folder, probe_at };
    let settings =
        LoopSettings { count: stage.loop_count, targets: stage.loop_targets, discover: &stage.discover };
    let looped =
        measurement_loop(&loop_inputs, &settings, first, &all, campaign_end, devices, budget.as_mut())?;
    all.extend_from_slice(&looped.measurements);
    let (true_structure, true_structure_note) = match &stage.true_effects {
        None => (None, "no true structure known (a real cell)".to_string()),
        Some(effects) => match true_structure_fit(calibrated, &all, base, effects) {
            Ok((m, note)) => (Some(m), note),
            Err(e) => (None, format!("the true-structure fit failed: {}", error_chain(&e))),
        },
    };
    Ok(DiscoveryOutcome {
        two_sided_repeats: repeats,
        extra_measurements: campaign.measurements.len(),
        total_measurements: all.len(),
        measurement_loop: looped.report,
        plots: effect_plots(&looped.discovery)?,
        discovery: looped.discovery,
        true_structure,
        true_structure_note,
        last_joints: looped.last_joints.or(campaign_end),
        base_params: base.len(),
        base_name: parameter_set_name(base),
        dir_columns: dir_columns_text(nominal.joint_kinds()),
        budget,
    })
}

/// One plot per added effect: the residual against its driving variable, before and after.
fn effect_plots(discovery: &Discovery) -> Result<Vec<EffectPlot>, PipelineError> {
    let mut plots = Vec::new();
    for (k, added) in discovery.added_effects.iter().enumerate() {
        plots.push(EffectPlot {
            file: format!("discovery_{}", effect_plot_file_name(k + 1, added)),
            caption: format!(
                "{}: residual against {} before and after it was added",
                added.label, added.plot.x_label
            ),
            svg: effect_plot_svg(k + 1, added)?,
        });
    }
    Ok(plots)
}

fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut source = e.source();
    while let Some(x) = source {
        let _ = write!(s, ": {x}");
        source = x.source();
    }
    s
}

/// Fits the calibration's parameters `base` (the paper's 34 on the canonical cell) plus every
/// parameter of `effects` (switched on in `start`) to `measurements`. The effect parameters get a weak prior (their typical scale) toward zero
/// so that components the data cannot see (e.g. a gear harmonic of very high order) stay
/// bounded instead of refusing the fit; effects the data lacks a column for are left out.
///
/// # Errors
/// The identification fails.
pub fn true_structure_fit(
    start: &Model,
    measurements: &[Measurement],
    base: &ParamSet,
    effects: &[EffectSpec],
) -> Result<(Model, String), PipelineError> {
    let data = DataAvailability::of(measurements);
    let mut model = start.clone();
    let mut params = base.0.clone();
    let mut priors = vec![f64::INFINITY; params.len()];
    let mut left_out = Vec::new();
    let mut used = 0;
    for spec in effects {
        if let Some(why) = missing_data(spec, &data) {
            left_out.push(format!("{} ({why})", spec.label()));
            continue;
        }
        model.enable_effect(*spec)?;
        used += 1;
        for id in spec.params() {
            if !params.contains(&id) {
                params.push(id);
                priors.push(id.typical_scale());
            }
        }
    }
    let options = IdentifyOptions {
        priors: Some(priors),
        max_condition_number: f64::INFINITY,
        ..IdentifyOptions::default()
    };
    let fit = identify(&model, measurements, &ParamSet(params), &options)?;
    let base_name = if base == &ParamSet::paper34() {
        "paper34".to_string()
    } else {
        format!("{} parameters", base.len())
    };
    let mut note = format!(
        "{base_name} + {} parameters of the truth's {used} effects (weak prior of their typical scale toward 0), \
         {} probe measurements",
        fit.params.len().saturating_sub(base.len()),
        measurements.len()
    );
    if !left_out.is_empty() {
        let _ = write!(note, "; left out (data lacks a column): {}", left_out.join(", "));
    }
    Ok((fit.model, note))
}
