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

use serde::Serialize;
use vatcal_campaign::CampaignConfig;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{JointVector, Measurement, ParamSet};
use vatcal_discovery::plots::{effect_plot_file_name, effect_plot_svg};
use vatcal_discovery::{DiscoverOptions, Discovery, discover};
use vatcal_hardware_traits::JointLayout;
use vatcal_identification::{IdentifyOptions, identify};
use vatcal_kinematics::Model;
use vatcal_kinematics::effects::{DataAvailability, missing_data};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::PlanSummary;
use vatcal_planning::plan::plan_campaign;

use crate::discovery_loop::{LOOP_JOURNAL, LOOP_MEASUREMENTS_CSV, LOOP_PLAN, LoopReport, propose_plan};
use crate::folders::{PlanFolder, RunFolder};
use crate::plans::{PlanHeader, PlanKind};
use crate::{CALIBRATED, DeviceSet, NOMINAL, PipelineError, Progress, RunOptions, RunReport, Stage};

/// Label of the discovered model in the validation.
pub const DISCOVERED: &str = "discovered";
/// Label of the model fitted with the true effect structure (the floor) in the validation.
pub const TRUE_STRUCTURE: &str = "true-structure";
/// Journal of the discovery campaign (in the run folder).
pub const DISCOVERY_JOURNAL: &str = "discovery.journal";
/// Probe measurements of the discovery campaign (in the run folder).
pub const DISCOVERY_MEASUREMENTS_CSV: &str = "discovery_measurements.csv";
/// Plan folder of the discovery campaign (in the run folder).
pub const DISCOVERY_PLAN: &str = "discovery_plan";

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
}

impl DiscoveryStageOptions {
    /// 360 extra measurements planned for [`default_plan_effects`] plus 12 two-sided repeats
    /// (1 mrad overshoot); the discovery's defaults with `seed`. Give the instruments' noise with [`DiscoveryStageOptions::with_instrument_noise`]
    /// so that the size rule does not compare with σ̂, which the physics still unmodelled
    /// inflates to ~0.1 mm (docs/discovery.md). 360, not 120: the held-out improvement of
    /// each further effect is masked by the misfit of the ones still missing, and its z grows
    /// with √n (measured on seed 2: 3 effects added from 189 measurements, 7 from 284).
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

/// `report.json`'s `discovery` object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscoveryReport {
    /// probe measurements of the discovery campaign (beyond the calibration's)
    pub extra_measurements: usize,
    /// of those, two-sided repeats (a planned pose approached again from the opposite side
    /// on every revolute joint)
    pub two_sided_repeats: usize,
    /// probe measurements the discovery used in all (the loop's included)
    pub total_measurements: usize,
    /// the measurement loop: the candidates it targeted, predicted vs achieved standard
    /// deviations, their decisions, the gap before / after (`None`: no loop configured)
    #[serde(rename = "loop")]
    pub measurement_loop: Option<LoopReport>,
    /// fitted parameters of the discovered model
    pub params: Vec<String>,
    /// the effects added, as `vatcal discover --report` writes them
    pub added_effects: serde_json::Value,
    /// effects detected but too small to matter
    pub negligible_effects: serde_json::Value,
    /// effects removed by the backward check
    pub removed_effects: serde_json::Value,
    /// cross-validated gap of the 34-parameter model on the probe data \[mm\]
    pub initial_gap_mm: f64,
    /// cross-validated gap of the discovered model on the probe data \[mm\]
    pub final_gap_mm: f64,
    /// how the true-structure model was fitted, or why it is missing
    pub true_structure: String,
    /// the loop's remarks
    pub notes: Vec<String>,
}

impl DiscoveryReport {
    /// The report of `o`.
    ///
    /// # Errors
    /// The discovery cannot be serialised (not expected).
    pub fn of(o: &DiscoveryOutcome) -> Result<Self, PipelineError> {
        let d = &o.discovery;
        Ok(Self {
            extra_measurements: o.extra_measurements,
            two_sided_repeats: o.two_sided_repeats,
            total_measurements: o.total_measurements,
            measurement_loop: o.measurement_loop.clone(),
            params: d.params.names(),
            added_effects: serde_json::to_value(&d.added_effects)?,
            negligible_effects: serde_json::to_value(&d.negligible_effects)?,
            removed_effects: serde_json::to_value(&d.removed_effects)?,
            initial_gap_mm: d.initial_gap_mm,
            final_gap_mm: d.final_gap_mm,
            true_structure: o.true_structure_note.clone(),
            notes: d.notes.clone(),
        })
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
    options.count = stage.count;
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

/// Adds up to `count` **two-sided repeats** to a campaign plan: measure steps spread evenly
/// over the plan are each followed by a move that takes every revolute joint `overshoot_rad`
/// past the measurement pose on the side it arrived from and back, and a second measurement
/// of the same ball at the same position. The first measurement of the pose is centred with
/// each joint's last motion in the planned direction `s` (auto-centering keeps the approach
/// side), the repeat with `−s` on every revolute joint, so the pair differs by twice the
/// backlash of every joint (`dir2..dir7` are recorded with each). A pose whose overshoot
/// waypoint would leave the joint limits of `model` is not repeated. Returns the number of
/// repeats added.
///
/// The ball stays on the probe: the overshoot moves it by about `overshoot_rad` times the
/// lever arms (≈ 0.3–0.7 mm for 1 mrad), well inside the gauges' range, like the approach
/// overshoot of auto-centering.
pub fn add_two_sided_repeats(
    plan: &mut vatcal_campaign::CampaignPlan,
    model: &Model,
    count: usize,
    overshoot_rad: f64,
) -> usize {
    use vatcal_campaign::CampaignStep;
    if count == 0 || overshoot_rad <= 0.0 {
        return 0;
    }
    // the planned approach side of every measurement: the sign of the last motion of each
    // revolute joint through the plan's waypoints (0: not moved yet)
    let revolute: Vec<usize> = (0..model.joint_count()).filter(|k| model.is_revolute(k + 1)).collect();
    let mut measures = Vec::new();
    let mut dir = vec![0i8; revolute.len()];
    let mut current: Option<JointVector> = None;
    for (k, step) in plan.steps.iter().enumerate() {
        match step {
            CampaignStep::Move { path } => {
                for w in path {
                    if let Some(c) = current {
                        for (d, j) in dir.iter_mut().zip(&revolute) {
                            let (a, b) = (c[*j], w[*j]);
                            if b != a {
                                *d = if b > a { 1 } else { -1 };
                            }
                        }
                    }
                    current = Some(*w);
                }
            }
            CampaignStep::Measure { position, tcp } => {
                if let Some(q) = current {
                    measures.push((k, *position, *tcp, q, dir.clone()));
                }
            }
            _ => {}
        }
    }
    if measures.is_empty() {
        return 0;
    }
    let wanted = count.min(measures.len());
    let mut chosen = Vec::new();
    let mut next = 0usize;
    for i in 0..wanted {
        // evenly spread, moving on when a pose is too close to a limit
        let from = (i * measures.len() / wanted).max(next);
        let Some(found) = (from..measures.len()).find(|&m| {
            let (_, _, _, q, s) = &measures[m];
            let mut w = *q;
            for (j, sj) in revolute.iter().zip(s) {
                w[*j] += overshoot_rad * if *sj < 0 { -1.0 } else { 1.0 };
            }
            model.limit_violation(&w).is_none()
        }) else {
            break;
        };
        chosen.push(found);
        next = found + 1;
    }
    // insert from the back so the step indices stay valid
    for &m in chosen.iter().rev() {
        let (k, position, tcp, q, s) = &measures[m];
        let (k, position, tcp, q) = (*k, *position, *tcp, *q);
        let mut past = q;
        for (j, sj) in revolute.iter().zip(s) {
            past[*j] += overshoot_rad * if *sj < 0 { -1.0 } else { 1.0 };
        }
        plan.steps.insert(k + 1, CampaignStep::Move { path: vec![past, q] });
        plan.steps.insert(k + 2, CampaignStep::Measure { position, tcp });
    }
    chosen.len()
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
    let geometry = CellGeometry::from_cell(&opts.nominal)?;
    let plan_folder = PlanFolder::new(out.join(DISCOVERY_PLAN));
    plan_discovery(opts, stage, nominal, base, &geometry, start, &plan_folder)?;
    let (tour, repeats) = discovery_tour(stage, nominal, out)?;
    let campaign = crate::plans::discovery_campaign_stage(
        devices,
        nominal,
        &tour,
        &RunFolder::new(out),
        config.clone(),
        progress,
    )?;
    let inputs = AnalysisInputs { opts, stage, nominal, calibrated, base, calibration, out };
    discovery_analysis(&inputs, &campaign, repeats, Some(LoopDevices { devices, config, progress }))
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
    let (_, repeats) = discovery_tour(stage, nominal, out)?;
    let campaign = RunFolder::new(out).journal_report(DISCOVERY_JOURNAL)?;
    let inputs = AnalysisInputs { opts, stage, nominal, calibrated, base, calibration, out };
    discovery_analysis(&inputs, &campaign, repeats, None)
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

/// The devices the measurement loop measures on (`None` in [`discovery_analysis`]: read the
/// loop's journal instead).
#[allow(missing_debug_implementations)]
pub struct LoopDevices<'a> {
    /// the cell's devices
    pub devices: &'a mut dyn DeviceSet,
    /// campaign settings
    pub config: CampaignConfig,
    /// progress reports
    pub progress: &'a mut dyn Progress,
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
    crate::plans::discovery_tour_of(
        &PlanFolder::new(out.join(DISCOVERY_PLAN)),
        nominal,
        stage.two_sided_repeats,
        stage.repeat_overshoot_rad,
    )
}

/// The offline half of the discovery stage: the discovery loop on the calibration's and the
/// discovery campaign's probe measurements; when it ends with borderline or rival candidates
/// and `stage.loop_count > 0`, the **measurement loop** (`crate::discovery_loop`): the
/// proposed measurements are planned into `discovery_loop_plan/`, measured on `devices`
/// (journal `discovery_loop.journal`, resumed when present) or, without devices, read from
/// that journal, and discovery runs on all data, continued from the model before the loop and from the starting parameters again, the lower cross-validated gap kept ([`crate::discovery_loop::LoopChoice`]); then the true-structure fit (oracle
/// given) on the same data and one plot per added effect. Deterministic: a finished run read
/// back from its journals gives the same outcome.
///
/// # Errors
/// The discovery loop fails, the proposal cannot be planned, the loop's campaign fails or (no
/// devices) its journal is missing (a failed true-structure fit is only noted).
pub fn discovery_analysis(
    inputs: &AnalysisInputs<'_>,
    campaign: &vatcal_campaign::CampaignReport,
    repeats: usize,
    devices: Option<LoopDevices<'_>>,
) -> Result<DiscoveryOutcome, PipelineError> {
    let AnalysisInputs { opts, stage, nominal, calibrated, base, calibration, out } = *inputs;
    let mut all = calibration.to_vec();
    all.extend_from_slice(&campaign.measurements);
    let first = discover(calibrated, &all, base, None, &stage.discover)?;
    let mut last_joints = campaign.records.last().map(|r| r.state.joints);
    let (discovery, measurement_loop) = if stage.loop_count == 0 {
        (first, None)
    } else {
        let targets = vatcal_discovery::propose::borderline_effects(&first, &all, stage.loop_targets);
        if targets.is_empty() {
            let report = LoopReport::not_run(
                &first,
                "nothing borderline: no candidate of the last round was refitted and left undecided, no unsettled rivals",
            );
            (first, Some(report))
        } else {
            let geometry = CellGeometry::from_cell(&opts.nominal)?;
            let mut plan_opts = crate::plan_options(opts);
            plan_opts.count = stage.loop_count;
            plan_opts.params = first.params.clone();
            plan_opts.start = last_joints;
            plan_opts.seed = opts.seed ^ 0x000d_15c0_100b_0004;
            let focus: Vec<EffectSpec> = targets.iter().map(|t| t.spec).collect();
            let proposed = propose_plan(&first, &all, &focus, nominal, &geometry, &plan_opts)?;
            let folder = PlanFolder::new(out.join(LOOP_PLAN));
            folder.write(&proposed.plan)?;
            std::fs::write(
                out.join(LOOP_PLAN).join("proposal.json"),
                serde_json::to_string_pretty(&proposed.proposal)?,
            )
            .map_err(|e| PipelineError::Io { path: out.join(LOOP_PLAN).join("proposal.json"), source: e })?;
            let tour = folder.read_tour(nominal.joint_kinds())?;
            let journal = RunFolder::new(out).path(LOOP_JOURNAL);
            let made = match devices {
                Some(LoopDevices { devices, config, progress }) => crate::run_campaign(
                    devices,
                    nominal,
                    &tour,
                    &journal,
                    config,
                    Stage::Discover,
                    None,
                    progress,
                )?,
                None => RunFolder::new(out).journal_report(LOOP_JOURNAL)?,
            };
            vatcal_io::write_measurements_for(
                out.join(LOOP_MEASUREMENTS_CSV),
                &made.measurements,
                nominal.joint_kinds(),
            )?;
            let before = all.clone();
            all.extend_from_slice(&made.measurements);
            last_joints = made.records.last().map(|r| r.state.joints).or(last_joints);
            // two ways to use the new rows: continue from the model before the loop, or search
            // again from the 34 parameters; both are scored by cross-validation on the same
            // data (same folds), the lower gap is kept. Independent: side by side
            let (cont, fresh) = rayon::join(
                || discover(&first.model, &all, &first.params, None, &stage.discover),
                || discover(calibrated, &all, base, None, &stage.discover),
            );
            let continued = crate::discovery_loop::continued_discovery(&first, cont?);
            let fresh = fresh?;
            let choice = crate::discovery_loop::LoopChoice::of(&continued, &fresh);
            let second = if choice.kept_continued { continued } else { fresh };
            let mut report =
                LoopReport::of(&first, &before, &targets, &proposed, &made.measurements, &second)?;
            report.choice = Some(choice);
            (second, Some(report))
        }
    };
    let (true_structure, true_structure_note) = match &stage.true_effects {
        None => (None, "no true structure known (a real cell)".to_string()),
        Some(effects) => match true_structure_fit(calibrated, &all, base, effects) {
            Ok((m, note)) => (Some(m), note),
            Err(e) => (None, format!("the true-structure fit failed: {}", error_chain(&e))),
        },
    };
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
    Ok(DiscoveryOutcome {
        two_sided_repeats: repeats,
        extra_measurements: campaign.measurements.len(),
        total_measurements: all.len(),
        measurement_loop,
        discovery,
        true_structure,
        true_structure_note,
        plots,
        last_joints,
        base_params: base.len(),
        base_name: parameter_set_name(base),
        dir_columns: dir_columns_text(nominal.joint_kinds()),
    })
}

/// Notes the measurement loop's files in the run's file list, when the loop ran.
pub(crate) fn note_loop_files(o: &DiscoveryOutcome, files: &mut crate::report::Files) {
    if o.measurement_loop.as_ref().is_some_and(|l| l.ran) {
        files.note(LOOP_JOURNAL);
        files.note(LOOP_MEASUREMENTS_CSV);
        for name in ["candidates.csv", "selected.csv", "tour.csv", "summary.json", "proposal.json"] {
            files.note(Path::new(LOOP_PLAN).join(name));
        }
    }
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

/// The discovery section of `summary.md`: the four-row comparison, each added effect and how
/// much of the gap it closed, the plots.
pub fn summary_section<S>(report: &RunReport<S>, o: &DiscoveryOutcome) -> String {
    let mut m = String::new();
    let d = &o.discovery;
    let _ = writeln!(m, "## 5. Discovery (`{DISCOVERY_JOURNAL}`, `{DISCOVERY_MEASUREMENTS_CSV}`)\n");
    let _ = writeln!(
        m,
        "{} extra probe measurements (Detmax for the {n} parameters and the candidate effects' directions, \
         {} of them two-sided repeats: a planned pose measured again right after, approached from the \
         opposite side on every revolute joint; `{}`, `time_s` and, with a thermometer, \
         `temperature_c` recorded) joined the calibration's; the discovery loop (screening \
         and held-out confirmation on separate splits) ran on all {} of them, starting from the calibrated \
         {n}-parameter model. Cross-validated gap on the probe data: {:.4} → {:.4} mm.\n",
        o.extra_measurements,
        o.two_sided_repeats,
        o.dir_columns,
        o.total_measurements,
        d.initial_gap_mm,
        d.final_gap_mm,
        n = o.base_params,
    );
    let _ = writeln!(
        m,
        "| model (tracker validation) | random poses mean [mm] | random p95 [mm] | printing path mean [mm] | build plate mean [mm] |\n|---|---:|---:|---:|---:|"
    );
    for (label, name) in [
        (NOMINAL, "nominal"),
        (CALIBRATED, o.base_name.as_str()),
        (DISCOVERED, "discovered"),
        (TRUE_STRUCTURE, "true structure (floor)"),
    ] {
        let Some(v) = report.model(label) else {
            let _ = writeln!(m, "| {name} | - | - | - | - |");
            continue;
        };
        let path = v.path.as_ref();
        let _ = writeln!(
            m,
            "| {name} | {:.4} | {:.4} | {} | {} |",
            v.random.stats.mean,
            v.random.stats.p95,
            path.map_or("-".into(), |p| format!("{:.4}", p.tip_stats.mean)),
            path.map_or("-".into(), |p| format!("{:.4}", p.plate_stats.mean)),
        );
    }
    let mean = |l: &str| report.model(l).map(|v| v.random.stats.mean);
    if let (Some(c), Some(x)) = (mean(CALIBRATED), mean(DISCOVERED)) {
        let _ = write!(
            m,
            "\nDiscovered / {}-parameter mean random-pose error: **{:.0} %**",
            o.base_params,
            100.0 * x / c
        );
        if let Some(t) = mean(TRUE_STRUCTURE) {
            let closed = if c > t { 100.0 * (c - x) / (c - t) } else { f64::NAN };
            let _ = write!(m, "; share of the gap to the true structure closed: **{closed:.0} %**");
        }
        let _ = writeln!(m, ".\n");
    }
    let _ = writeln!(m, "True-structure fit: {}.\n", o.true_structure_note);
    if d.added_effects.is_empty() {
        let _ = writeln!(
            m,
            "No effect was added: none passed the held-out confirmation and the negligibility check, so the \
             `discovered` row is {} refitted on all {} probe measurements (its gain over \
             the {}-parameter row comes from the extra measurements, not from a new effect).\n",
            o.base_name, o.total_measurements, o.base_params
        );
    } else {
        let _ = writeln!(
            m,
            "| step | effect added | meaning | held-out gap before → after [mm] | share of the probe gap closed |\n|---:|---|---|---:|---:|"
        );
        let span = (d.initial_gap_mm - d.final_gap_mm).max(f64::MIN_POSITIVE);
        for (k, a) in d.added_effects.iter().enumerate() {
            // effects added in the same round were confirmed together as one block
            let block = d.added_effects.iter().filter(|b| b.round == a.round).count();
            let first = k == 0 || d.added_effects[k - 1].round != a.round;
            let share = if first {
                format!("{:.0} %", 100.0 * (a.gap_before_mm - a.gap_after_mm) / span)
            } else {
                "(same block)".to_string()
            };
            let label = if block > 1 {
                format!("{} (block of {block}, round {})", a.label, a.round)
            } else {
                a.label.clone()
            };
            let _ = writeln!(
                m,
                "| {} | {label} | {} | {:.4} → {:.4} | {share} |",
                k + 1,
                a.meaning,
                a.gap_before_mm,
                a.gap_after_mm,
            );
        }
        let _ = writeln!(m);
    }
    if let Some(l) = &o.measurement_loop {
        let lines = l.lines();
        let _ = writeln!(
            m,
            "**Measurement loop** (`{LOOP_PLAN}/`, `{LOOP_JOURNAL}`): {}\n",
            lines.join("\n").trim_start_matches("measurement loop: ")
        );
    }
    for n in &d.negligible_effects {
        let _ = writeln!(m, "* detected, negligible ({:.1} µm): {} (not added)", n.change_um, n.label);
    }
    for x in &d.removed_effects {
        let _ = writeln!(m, "* removed by the backward check: {}", x.label);
    }
    for p in &o.plots {
        let _ = writeln!(m, "* `{}`: {}", p.file, p.caption);
    }
    let _ = writeln!(m);
    m
}

/// `summary.html`: the text of `summary.md` as one self-contained page (headings as nested
/// sections with a table of contents, tables, code blocks, paragraphs), each SVG plot of the
/// run (`(file name, svg)`) inline right after the first paragraph, list item or table that
/// names its file — beside the text it illustrates; a plot the text never names goes to a last
/// section "Other plots".
pub fn summary_html(markdown: &str, svgs: &[(String, String)]) -> vatcal_report::html::HtmlReport {
    use vatcal_report::html::HtmlReport;
    let mut lines = markdown.lines().peekable();
    let title = lines.peek().map_or("vatcal", |l| l.trim_start_matches('#').trim()).to_string();
    lines.next();
    let mut r = HtmlReport::new(title);
    let mut placed = vec![false; svgs.len()];
    // the plots `text` names (not placed yet), as figures after it
    let mut figures = |r: &mut HtmlReport, text: &str| {
        for ((name, svg), done) in svgs.iter().zip(placed.iter_mut()) {
            if !*done && text.contains(name.as_str()) {
                r.svg(svg.clone(), name.clone());
                *done = true;
            }
        }
    };
    let mut para = String::new();
    let flush = |r: &mut HtmlReport, para: &mut String, figures: &mut dyn FnMut(&mut HtmlReport, &str)| {
        if !para.trim().is_empty() {
            r.paragraph(para.trim().to_string());
            figures(r, para);
        }
        para.clear();
    };
    let cells = |l: &str| -> Vec<String> {
        l.trim().trim_matches('|').split('|').map(|c| c.trim().to_string()).collect()
    };
    while let Some(line) = lines.next() {
        if let Some(h) = line.strip_prefix('#') {
            flush(&mut r, &mut para, &mut figures);
            let text = h.trim_start_matches('#').trim();
            if h.starts_with('#') {
                r.subheading(text);
            } else {
                r.heading(text);
            }
        } else if line.starts_with("```") {
            flush(&mut r, &mut para, &mut figures);
            let mut block = String::new();
            for l in lines.by_ref() {
                if l.starts_with("```") {
                    break;
                }
                block.push_str(l);
                block.push('\n');
            }
            r.preformatted(block.clone());
            figures(&mut r, &block);
        } else if line.starts_with('|') {
            flush(&mut r, &mut para, &mut figures);
            let header = cells(line);
            let mut rows = Vec::new();
            let mut text = line.to_string();
            while let Some(l) = lines.peek() {
                if !l.starts_with('|') {
                    break;
                }
                let row = cells(l);
                if !row.iter().all(|c| c.chars().all(|ch| matches!(ch, '-' | ':'))) {
                    rows.push(row);
                }
                text.push_str(l);
                lines.next();
            }
            let h: Vec<&str> = header.iter().map(String::as_str).collect();
            r.table(&h, &rows);
            figures(&mut r, &text);
        } else if line.starts_with("* ") {
            flush(&mut r, &mut para, &mut figures);
            r.paragraph(line.to_string());
            figures(&mut r, line);
        } else if line.trim().is_empty() {
            flush(&mut r, &mut para, &mut figures);
        } else {
            para.push_str(line);
            para.push('\n');
        }
    }
    flush(&mut r, &mut para, &mut figures);
    let rest: Vec<&(String, String)> =
        svgs.iter().zip(&placed).filter(|(_, done)| !**done).map(|(s, _)| s).collect();
    if !rest.is_empty() {
        r.heading("Other plots");
        for (name, svg) in rest {
            r.svg(svg.clone(), name.clone());
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_campaign::{Campaign, CampaignPlan, CampaignPlanOptions, CampaignStep, CellDevices};
    use vatcal_core::params::{EffectParam, ParamId};
    use vatcal_core::{CellFile, Target};
    use vatcal_hardware_traits::Thermometer;

    fn nominal() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    /// Two-sided repeats on the virtual cell with backlash on every joint: each repeat is the
    /// same pose, recorded with every revolute joint's direction reversed, and the backlash
    /// shows in the recorded joints (the nominal FK of the pair differs by far more than the
    /// repeatability); the plan's other steps are unchanged.
    #[test]
    fn two_sided_repeats_reverse_every_joint_and_excite_backlash() {
        let model = nominal();
        let limits = model.joint_limits();
        let poses: Vec<Measurement> = vatcal_sim::truth::probe_start_poses(&model, 60, 11)
            .into_iter()
            .filter(|m| {
                (1..7).all(|k| m.q[k] > limits[k].0 + 0.15 && m.q[k] < limits[k].1 - 0.15)
                    && vatcal_sim::translation_joint_gain(&model, &m.q).is_some_and(|g| g < 0.03)
            })
            .take(8)
            .collect();
        assert_eq!(poses.len(), 8);
        let clear = JointVector::from_mm_deg(150.0, [0.0, -30.0, 30.0, 0.0, 0.0, 0.0]);
        let mut plan = CampaignPlan::from_poses(
            &poses,
            &CampaignPlanOptions { clear_pose: Some(clear), zero_probe: false },
        );
        let original = plan.clone();
        assert_eq!(add_two_sided_repeats(&mut plan, &model, 3, 1e-3), 3);
        assert_eq!(plan.measurement_count(), original.measurement_count() + 3);
        // removing each inserted (overshoot move, measure) pair gives the original plan back
        let mut kept = Vec::new();
        let mut k = 0;
        while k < plan.steps.len() {
            kept.push(&plan.steps[k]);
            if let (CampaignStep::Measure { .. }, Some(CampaignStep::Move { path }), Some(again)) =
                (&plan.steps[k], plan.steps.get(k + 1), plan.steps.get(k + 2))
                && path.len() == 2
                && again == &plan.steps[k]
                && matches!(&plan.steps[k - 1], CampaignStep::Move { path: p } if p.last() == Some(&path[1]))
            {
                let step = (1..7).map(|j| (path[0][j] - path[1][j]).abs()).fold(0.0, f64::max);
                assert!((step - 1e-3).abs() < 1e-12, "overshoot {step} rad");
                k += 3;
                continue;
            }
            k += 1;
        }
        assert_eq!(kept, original.steps.iter().collect::<Vec<_>>(), "only pairs were inserted");

        let mut truth =
            vatcal_sim::truth::perturbed_truth(&model, 4, &vatcal_sim::truth::ErrorBudget::realistic());
        let b = 0.01f64.to_radians();
        for joint in 2..=7u8 {
            truth.enable_effect(EffectSpec::JointBacklash { joint }).expect("backlash");
            truth.set_param(ParamId::Effect(EffectParam::Backlash { joint }), b).expect("value");
        }
        let cell = vatcal_sim::VirtualCell::new(model.clone(), truth, vatcal_sim::SimConfig::default(), 4);
        let (mut arm, mut guide, mut operator) =
            (cell.arm(), cell.guide().expect("the canonical cell has a guide"), cell.operator());
        let mut probe = cell.probe().expect("probe");
        let clock = cell.clock();
        assert!(cell.thermometer().is_none());
        let mut no_thermometer: Option<vatcal_sim::SimThermometer> = None;
        let devices = CellDevices {
            arm: &mut arm,
            guide: Some(&mut guide),
            probe: &mut probe,
            tracker: None,
            operator: &mut operator,
            clock: &clock,
            thermometer: no_thermometer.as_mut().map(|t| t as &mut dyn Thermometer),
        };
        let dir = tempfile::tempdir().expect("tmp");
        let config = CampaignConfig { show_progress: false, ..CampaignConfig::default() };
        let report =
            Campaign::new(devices, &model, config).run(&plan, dir.path().join("j")).expect("campaign");
        assert_eq!(report.measurements.len(), plan.measurement_count());
        let mut pairs = 0;
        for w in report.measurements.windows(2) {
            let (a, r) = (&w[0], &w[1]);
            if a.tcp != r.tcp || a.target != r.target || !matches!(a.target, Target::Probe { .. }) {
                continue;
            }
            pairs += 1;
            let (da, dr) = (a.context.dir.expect("dir"), r.context.dir.expect("dir"));
            for j in 1..7 {
                assert!(da[j] != 0 && dr[j] == -da[j], "joint {}: {da:?} then {dr:?}", j + 1);
            }
            let shift = (model.tcp_position(&a.q, a.tcp).expect("fk")
                - model.tcp_position(&r.q, r.tcp).expect("fk"))
            .norm();
            assert!(shift > 0.03, "backlash of 0.01 deg per joint moves the centred pose by {shift} mm");
        }
        assert_eq!(pairs, 3);
    }
}
