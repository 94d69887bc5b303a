//! Discovery that asks for the data it needs, in the main job (issue 21 item 3): when the
//! discovery loop ends with a **borderline** candidate (refitted but not added: rejected by the
//! held-out test, detected but negligible, passed but not best) or with **rivals** the
//! validation rows did not settle ([`vatcal_discovery::propose::borderline_effects`]), the
//! discovery stage proposes `N` extra probe measurements that decide it
//! ([`vatcal_discovery::propose::propose`]: Ds-optimal for the undecided effects' parameters,
//! from the planner's collision-checked candidates), plans them as a campaign
//! (`discovery_loop_plan/`), measures them on the same devices with the campaign runner
//! (`discovery_loop.journal`, resumable like every campaign), runs discovery on all data
//! twice — continued from the model before the loop and from the starting parameters again —
//! keeps the one with the lower cross-validated gap ([`LoopChoice`]) and reports before /
//! after ([`LoopReport`]). With nothing borderline no loop runs and
//! the report says so.
//!
//! [`propose_plan`] is also what `vatcal discover --propose N --out-plan DIR` runs.

use serde::Serialize;
use vatcal_campaign::{CampaignConfig, CampaignPlan};
use vatcal_core::effects::EffectSpec;
use vatcal_core::{JointVector, Measurement, ParamId, ParamSet};
use vatcal_discovery::propose::borderline_effects;
use vatcal_discovery::propose::{Borderline, Proposal, design_quality, propose};
use vatcal_discovery::workflow::{CandidateStatus, file_value};
use vatcal_discovery::{DiscoverOptions, Discovery, discover};
use vatcal_kinematics::Model;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::plan::{Plan, PlanOptions, StepKind, campaign_candidates, plan_selection};

use crate::budget::{BatchSpend, BudgetReport, MIN_SIGMA_GAIN, PREDICTION_MARGIN, measure_steps};
use crate::campaign_runner::run_campaign;
use crate::folders::{LOOP_PROPOSAL, RunFolder};
use crate::{DeviceSet, PipelineError, Progress, RunOptions, Stage, plan_options};

pub use crate::folders::{LOOP_JOURNAL, LOOP_MEASUREMENTS_CSV, LOOP_PLAN};

/// The measurements proposed to decide some candidate effects, planned as a campaign.
#[derive(Debug, Clone)]
pub struct ProposedPlan {
    /// what was selected and the predicted standard deviations before / after
    pub proposal: Proposal,
    /// the campaign plan of the selection (order, collision-free paths, timing)
    pub plan: Plan,
    /// size of the candidate pool the selection was made from
    pub pool: usize,
}

/// Proposes `opts.count` probe measurements that best determine the parameters of `focus`
/// given the parameters `d` fitted, with `measurements` (the data `d` ran on) held fixed: the
/// pool is the planner's collision-checked candidate poses for `plan_model` on `geometry`
/// (`opts.candidates`), the selection [`vatcal_discovery::propose::propose`] (Jacobians of
/// `d.model`, rows weighted by `d`'s noise per kind), the plan
/// [`vatcal_planning::plan::plan_selection`] (order and paths from `opts.start`).
///
/// With `probe_at`, the probe plate left at that calibration position by the campaign before:
/// the pool is that position's candidates (when it has any), and the plan starts without
/// placing the plate again — a re-placement is the costliest step of a small batch (≈ 60 s
/// against ≈ 10 s per measurement).
///
/// # Errors
/// No measurable candidate pose, an effect the model cannot take, or a planning failure.
pub fn propose_plan(
    d: &Discovery,
    measurements: &[Measurement],
    focus: &[EffectSpec],
    plan_model: &Model,
    geometry: &CellGeometry,
    opts: &PlanOptions,
    probe_at: Option<u32>,
) -> Result<ProposedPlan, PipelineError> {
    let mut candidates = campaign_candidates(plan_model, geometry, opts)?;
    if let Some(p) = probe_at
        && candidates.candidates.iter().any(|c| c.position == p)
    {
        candidates.candidates.retain(|c| c.position == p);
    }
    let pool: Vec<Measurement> =
        candidates.candidates.iter().map(|c| Measurement::probe(c.position, c.tcp, c.q)).collect();
    if pool.is_empty() {
        return Err(PipelineError::Option {
            option: "proposal".into(),
            reason: "the planner found no measurable candidate pose".into(),
        });
    }
    let weights = d.kind_sigmas.weights();
    let proposal = propose(&d.model, &d.params, measurements, focus, &pool, opts.count, &weights)?;
    let n = pool.len();
    let mut plan = plan_selection(plan_model, geometry, candidates, proposal.selected.clone(), opts)?;
    if let Some(p) = probe_at
        && plan.steps.first().is_some_and(|s| s.kind == StepKind::ReplaceProbe && s.position == p)
    {
        // the plate is already there
        plan.steps.remove(0);
    }
    Ok(ProposedPlan { proposal, plan, pool: n })
}

/// One parameter of a targeted effect: predicted and achieved standard deviation, in file
/// units (degrees, mm; the key names the unit).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopParam {
    /// parameter name with its unit, e.g. `cyclic_sin_j5_h1_deg`
    pub name: String,
    /// predicted σ with the data before the loop (design, at the loop's noise σ)
    pub std_before: f64,
    /// predicted σ with the proposed measurements added (as planned)
    pub std_predicted: f64,
    /// σ of the same design formula on the measurements actually made (centring moves the
    /// poses; skipped measurements are missing)
    pub std_achieved: f64,
    /// σ of the identified value when the second discovery refitted the effect (its fit's own
    /// σ̂, which includes any physics still unmodelled)
    pub std_fitted: Option<f64>,
    /// the identified value, when refitted
    pub value: Option<f64>,
}

/// A candidate effect the loop targeted and what became of it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopTarget {
    /// the effect
    pub label: String,
    /// why it was undecided before the loop
    pub before: String,
    /// the decision of the discovery on all data (`added in round r`, or the status of the
    /// last round it was scored in)
    pub decision: String,
    /// its parameters not fitted before the loop
    pub params: Vec<LoopParam>,
}

/// `report.json`'s `discovery.loop`: the measurements discovery asked for, and the before /
/// after of the discovery on all data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopReport {
    /// whether a loop ran
    pub ran: bool,
    /// one sentence: why it ran (which candidates) or why not
    pub reason: String,
    /// the targeted candidates
    pub targets: Vec<LoopTarget>,
    /// measurements proposed
    pub proposed: usize,
    /// of those, measured (auto-centering may skip some)
    pub measured: usize,
    /// candidate poses the proposal chose from
    pub pool: usize,
    /// σ per axis of a probe row the standard deviations are scaled with \[mm\] (the noise
    /// reference of the first discovery)
    pub noise_mm: f64,
    /// effects in the discovered model before the loop
    pub effects_before: Vec<String>,
    /// effects in the discovered model after the loop
    pub effects_after: Vec<String>,
    /// cross-validated gap of the discovered model before the loop (its data) \[mm\]
    pub gap_before_mm: f64,
    /// cross-validated gap of the discovered model after the loop (all data) \[mm\]
    pub gap_after_mm: f64,
    /// which discovery on all data was kept (when the loop ran)
    pub choice: Option<LoopChoice>,
}

/// The two discoveries on all data after the loop's measurements, and which was kept: the
/// one continued from the model before the loop ([`continued_discovery`]) or the one from the
/// starting parameters again; the lower cross-validated gap on all data wins (the same data
/// and folds for both), the continued one on a tie.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopChoice {
    /// whether the continued discovery was kept
    pub kept_continued: bool,
    /// cross-validated gap of the continued discovery \[mm\]
    pub continued_gap_mm: f64,
    /// effects of the continued discovery
    pub continued_effects: usize,
    /// cross-validated gap of the discovery from the starting parameters \[mm\] (`None`: not
    /// run, the continued discovery left nothing undecided)
    pub fresh_gap_mm: Option<f64>,
    /// effects of the discovery from the starting parameters (`None`: not run)
    pub fresh_effects: Option<usize>,
}

impl LoopChoice {
    /// Compares the continued discovery with the one from the starting parameters.
    pub fn of(continued: &Discovery, fresh: &Discovery) -> Self {
        Self {
            kept_continued: continued.final_gap_mm <= fresh.final_gap_mm,
            continued_gap_mm: continued.final_gap_mm,
            continued_effects: continued.added_effects.len(),
            fresh_gap_mm: Some(fresh.final_gap_mm),
            fresh_effects: Some(fresh.added_effects.len()),
        }
    }

    /// The continued discovery kept without a search from the starting parameters (it left
    /// nothing undecided).
    pub fn continued_only(continued: &Discovery) -> Self {
        Self {
            kept_continued: true,
            continued_gap_mm: continued.final_gap_mm,
            continued_effects: continued.added_effects.len(),
            fresh_gap_mm: None,
            fresh_effects: None,
        }
    }

    /// One line for people.
    pub fn line(&self) -> String {
        let continued =
            ("continued from the model before the loop", self.continued_gap_mm, self.continued_effects);
        let (Some(fresh_gap), Some(fresh_effects)) = (self.fresh_gap_mm, self.fresh_effects) else {
            return format!(
                "kept the discovery {} (cross-validated gap {:.4} mm, {} effects); no search from the starting parameters: the continued one left nothing undecided",
                continued.0, continued.1, continued.2
            );
        };
        let fresh = ("from the starting parameters again", fresh_gap, fresh_effects);
        let (kept, other) = if self.kept_continued { (continued, fresh) } else { (fresh, continued) };
        format!(
            "kept the discovery {} (cross-validated gap {:.4} mm, {} effects; the other {:.4} mm, {} effects)",
            kept.0, kept.1, kept.2, other.1, other.2
        )
    }
}

impl LoopReport {
    /// The report when no loop ran, with the reason.
    pub fn not_run(d: &Discovery, reason: impl Into<String>) -> Self {
        Self {
            ran: false,
            reason: reason.into(),
            targets: Vec::new(),
            proposed: 0,
            measured: 0,
            pool: 0,
            noise_mm: noise_mm(d),
            effects_before: labels(d),
            effects_after: labels(d),
            gap_before_mm: d.final_gap_mm,
            gap_after_mm: d.final_gap_mm,
            choice: None,
        }
    }

    /// The report of a loop: `first` on `before` (the data at hand), the proposal `proposed`
    /// for `targets`, the measurements made `made`, `second` on all data.
    ///
    /// # Errors
    /// The design of the measurements made cannot be evaluated (a Jacobian fails).
    pub fn of(
        first: &Discovery,
        before: &[Measurement],
        targets: &[Borderline],
        proposed: &ProposedPlan,
        made: &[Measurement],
        second: &Discovery,
    ) -> Result<Self, PipelineError> {
        let sigma = noise_mm(first);
        let specs: Vec<EffectSpec> = targets.iter().map(|t| t.spec).collect();
        let weights = first.kind_sigmas.weights();
        let (_, achieved) = design_quality(&first.model, &first.params, before, &specs, made, &weights)?;
        let p = &proposed.proposal;
        let std_of = |ids: &[ParamId]| -> Vec<(ParamId, usize)> {
            ids.iter().filter_map(|id| p.focus_ids.iter().position(|f| f == id).map(|k| (*id, k))).collect()
        };
        let mut out = Vec::new();
        for t in targets {
            let label = t.spec.label();
            let (decision, fitted) = decision_of(second, &label);
            let params = std_of(&t.spec.params())
                .into_iter()
                .map(|(id, k)| {
                    let (name, _) = file_value(id, 0.0);
                    let scaled = |v: &[f64]| v.get(k).map_or(f64::NAN, |s| file_value(id, s * sigma).1);
                    LoopParam {
                        std_before: scaled(&p.std_before),
                        std_predicted: scaled(&p.std_after),
                        std_achieved: scaled(&achieved),
                        std_fitted: fitted.and_then(|(_, s)| s.get(&name).copied()),
                        value: fitted.and_then(|(v, _)| v.get(&name).copied()),
                        name,
                    }
                })
                .collect();
            out.push(LoopTarget { label, before: t.why.clone(), decision, params });
        }
        Ok(Self {
            ran: true,
            reason: format!(
                "undecided after discovery: {}",
                targets
                    .iter()
                    .map(|t| format!("{} ({})", t.spec.label(), t.why))
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            targets: out,
            proposed: p.selected.len(),
            measured: made.len(),
            pool: proposed.pool,
            noise_mm: sigma,
            effects_before: labels(first),
            effects_after: labels(second),
            gap_before_mm: first.final_gap_mm,
            gap_after_mm: second.final_gap_mm,
            choice: None,
        })
    }

    /// Lines for people (text output, `summary.md`).
    pub fn lines(&self) -> Vec<String> {
        let mut v = vec![if self.ran {
            format!(
                "measurement loop: {}; {} measurements proposed from {} candidate poses, {} measured; discovery on all data: \
                 cross-validated gap {:.4} -> {:.4} mm, {} -> {} effect(s)",
                self.reason,
                self.proposed,
                self.pool,
                self.measured,
                self.gap_before_mm,
                self.gap_after_mm,
                self.effects_before.len(),
                self.effects_after.len()
            )
        } else {
            format!("measurement loop: not run ({})", self.reason)
        }];
        if let Some(c) = &self.choice {
            v.push(format!("  {}", c.line()));
        }
        for t in &self.targets {
            let stds: Vec<String> = t
                .params
                .iter()
                .map(|p| {
                    format!(
                        "{}: sigma {:.3e} -> predicted {:.3e}, achieved {:.3e}{}",
                        p.name,
                        p.std_before,
                        p.std_predicted,
                        p.std_achieved,
                        p.std_fitted.map_or(String::new(), |s| format!(", fitted {s:.3e}"))
                    )
                })
                .collect();
            v.push(format!("  {}: {} -> {}; {}", t.label, t.before, t.decision, stds.join("; ")));
        }
        v
    }
}

/// σ per axis of a probe row of `d`'s noise reference (the instruments' when known, else the
/// last fit's σ̂) \[mm\].
fn noise_mm(d: &Discovery) -> f64 {
    d.noise
        .sigmas
        .probe_mm
        .or(d.kind_sigmas.probe_mm)
        .or_else(|| d.rounds.last().map(|r| r.fit.sigma_hat_mm))
        .unwrap_or(f64::NAN)
}

fn labels(d: &Discovery) -> Vec<String> {
    d.added_effects.iter().map(|a| a.label.clone()).collect()
}

type Values<'a> = (&'a std::collections::BTreeMap<String, f64>, &'a std::collections::BTreeMap<String, f64>);

/// What discovery decided about `label`, and its identified values and σ when refitted.
fn decision_of<'a>(d: &'a Discovery, label: &str) -> (String, Option<Values<'a>>) {
    if let Some(a) = d.added_effects.iter().find(|a| a.label == label) {
        return (format!("added in round {}", a.round), Some((&a.values, &a.std_errors)));
    }
    let mut text = "not scored (its data columns are missing)".to_string();
    let mut fitted = None;
    for round in &d.rounds {
        if let Some(c) = round.candidates.iter().find(|c| c.label == label) {
            let status = match &c.status {
                CandidateStatus::MissingData(r) => format!("not tested: {r}"),
                CandidateStatus::AlreadyInModel => "already in the model".to_string(),
                CandidateStatus::NotDiscoverable => {
                    "not discoverable (absorbed by the fitted parameters)".into()
                }
                CandidateStatus::NotSignificant => "not significant on the screening data".into(),
                CandidateStatus::NotRefitted => "significant, not refitted (others scored higher)".into(),
                CandidateStatus::Rejected(r) => format!("rejected: {r}"),
                CandidateStatus::DetectedNegligible(r) => r.clone(),
                CandidateStatus::PassedNotBest => "passed, not best".into(),
                CandidateStatus::Added => "added".into(),
            };
            text = format!("round {} (last scored): {status}", round.index);
            fitted = c.refit.as_ref().map(|r| (&r.values, &r.std_errors));
        }
    }
    if let Some(a) = d.ambiguities.iter().find(|a| a.rivals.iter().any(|r| r == label)) {
        text.push_str(&format!("; {}", a.sentence));
    }
    (text, fitted)
}

/// The loop's discovery on all data, continued from the discovered model before the loop:
/// `cont` ran from `first`'s model and parameters, so the effects `first` added on the data at
/// hand stay (unless `cont`'s backward check removed them) and the new measurements decide the
/// undecided candidates on top of them. A discovery from scratch on all data re-runs the
/// greedy search and may end at another structure, better or worse (the demo's seed 1: 11
/// effects and a cross-validated gap of 0.0305 mm from scratch, 21 effects and 0.0195 mm
/// continued); the stage runs both and keeps the lower gap ([`LoopChoice`]). The result reads as one discovery: `first`'s rounds and additions, then
/// `cont`'s, numbered on; the gap before is `first`'s, the gap after `cont`'s.
pub fn continued_discovery(first: &Discovery, mut cont: Discovery) -> Discovery {
    let offset = first.rounds.len();
    for r in &mut cont.rounds {
        r.index += offset;
    }
    for a in &mut cont.added_effects {
        a.round += offset;
    }
    for r in &mut cont.removed_effects {
        r.removed_in_round += offset;
        if !first.added_effects.iter().any(|a| a.label == r.label) {
            r.added_in_round += offset;
        }
    }
    for a in &mut cont.ambiguities {
        a.round += offset;
    }
    for b in &mut cont.bound_hits {
        b.round += offset;
    }
    for n in &mut cont.negligible_effects {
        n.round += offset;
    }
    let removed = |label: &str| cont.removed_effects.iter().any(|r| r.label == label);
    let mut added: Vec<_> = first.added_effects.iter().filter(|a| !removed(&a.label)).cloned().collect();
    added.append(&mut cont.added_effects);
    cont.added_effects = added;
    let mut rounds = first.rounds.clone();
    rounds.append(&mut cont.rounds);
    cont.rounds = rounds;
    let mut removed_before = first.removed_effects.clone();
    removed_before.append(&mut cont.removed_effects);
    cont.removed_effects = removed_before;
    cont.initial_gap = first.initial_gap.clone();
    cont.initial_gap_mm = first.initial_gap_mm;
    cont
}

/// How the measurement loop runs (the discovery stage's loop settings).
#[derive(Debug, Clone, Copy)]
pub struct LoopSettings<'a> {
    /// measurements proposed when the discovery ends undecided; 0: no loop
    pub count: usize,
    /// at most this many undecided candidates are targeted
    pub targets: usize,
    /// the discovery's settings (each rediscovery on all data)
    pub discover: &'a DiscoverOptions,
}

/// What the measurement loop works on.
#[derive(Debug, Clone, Copy)]
pub struct LoopInputs<'a> {
    /// the run's options (cell, sizes, seed)
    pub opts: &'a RunOptions,
    /// the nominal model (the loop's campaign is planned and run on it)
    pub nominal: &'a Model,
    /// the calibrated model (the fresh rediscovery starts from it)
    pub calibrated: &'a Model,
    /// the calibration's parameters (the paper's 34 on the canonical cell)
    pub base: &'a ParamSet,
    /// the run folder (`discovery_loop_plan/`, `discovery_loop.journal`)
    pub folder: &'a RunFolder,
    /// where the campaign before left the probe plate (the loop measures there, without a
    /// re-placement); `None`: anywhere
    pub probe_at: Option<u32>,
}

/// The devices the measurement loop measures on (`None`: read the loop's journal instead).
#[allow(missing_debug_implementations)]
pub struct LoopDevices<'a> {
    /// the cell's devices
    pub devices: &'a mut dyn DeviceSet,
    /// campaign settings
    pub config: CampaignConfig,
    /// progress reports
    pub progress: &'a mut dyn Progress,
}

/// What the measurement loop produced.
#[derive(Debug, Clone)]
pub struct LoopOutcome {
    /// the discovery kept (the first one when no loop measured)
    pub discovery: Discovery,
    /// the loop's report (`None`: no loop configured)
    pub report: Option<LoopReport>,
    /// the probe measurements the loop added
    pub measurements: Vec<Measurement>,
    /// where the loop's campaign left the arm (`None`: it did not measure)
    pub last_joints: Option<JointVector>,
}

/// The measurement loop after the first discovery `first` on the probe data `all`: with
/// `settings.count > 0` and borderline or rival candidates, the proposed measurements are
/// planned into `discovery_loop_plan/` (starting at `start`), measured on `devices` (journal
/// `discovery_loop.journal`, resumed when present) or, without devices, read from that
/// journal, and discovery runs on all data, continued from the model before the loop and from
/// the starting parameters again, the lower cross-validated gap kept ([`LoopChoice`]).
/// Deterministic: a finished run read back from its journal gives the same outcome.
///
/// # Errors
/// The proposal cannot be planned, the loop's campaign fails or (no devices) its journal is
/// missing, or a rediscovery fails.
#[allow(clippy::too_many_arguments)]
pub fn measurement_loop(
    inputs: &LoopInputs<'_>,
    settings: &LoopSettings<'_>,
    first: Discovery,
    all: &[Measurement],
    start: Option<JointVector>,
    devices: Option<LoopDevices<'_>>,
    mut budget: Option<&mut BudgetReport>,
) -> Result<LoopOutcome, PipelineError> {
    let none =
        |discovery, report| LoopOutcome { discovery, report, measurements: Vec::new(), last_joints: None };
    let mut stop = |why: &str| {
        if let Some(b) = budget.as_deref_mut() {
            b.stop = why.to_string();
        }
    };
    if settings.count == 0 {
        stop("no targeted batch configured (loop count 0)");
        return Ok(none(first, None));
    }
    let targets = borderline_effects(&first, all, settings.targets);
    if targets.is_empty() {
        let why = "nothing borderline: no candidate of the last round was refitted and left undecided, no unsettled rivals";
        stop(&format!("every question decided after the Detmax batch ({why})"));
        let report = LoopReport::not_run(&first, why);
        return Ok(none(first, Some(report)));
    }
    let LoopInputs { opts, nominal, calibrated, base, folder, probe_at } = *inputs;
    let geometry = CellGeometry::from_cell(&opts.nominal)?;
    let mut plan_opts = plan_options(opts);
    plan_opts.count = settings.count;
    plan_opts.params = first.params.clone();
    plan_opts.start = start;
    plan_opts.seed = opts.seed ^ 0x000d_15c0_100b_0004;
    let focus: Vec<EffectSpec> = targets.iter().map(|t| t.spec).collect();
    let proposed = propose_plan(&first, all, &focus, nominal, &geometry, &plan_opts, probe_at)?;
    let plan_folder = folder.loop_plan();
    plan_folder.write(&proposed.plan)?;
    let proposal = plan_folder.path(LOOP_PROPOSAL);
    std::fs::write(&proposal, serde_json::to_string_pretty(&proposed.proposal)?)
        .map_err(|e| PipelineError::Io { path: proposal.clone(), source: e })?;
    let tour = plan_folder.read_tour(nominal.joint_kinds())?;
    if let Some(b) = budget.as_deref_mut()
        && let Some(why) = targeted_batch_refused(b, &tour, start, &proposed.proposal)
    {
        b.stop = why.clone();
        return Ok(none(first.clone(), Some(LoopReport::not_run(&first, why))));
    }
    let made = match devices {
        Some(LoopDevices { devices, config, progress }) => {
            let journal = folder.path(LOOP_JOURNAL);
            // the plate stays where the Detmax batch left it (the plan starts there)
            let config = vatcal_campaign::CampaignConfig { plate_at_start: probe_at, ..config };
            run_campaign(devices, nominal, &tour, &journal, config, Stage::Discover, None, progress)?
        }
        None => folder.journal_report(LOOP_JOURNAL)?,
    };
    vatcal_io::write_measurements_for(
        folder.path(LOOP_MEASUREMENTS_CSV),
        &made.measurements,
        nominal.joint_kinds(),
    )?;
    if let Some(b) = budget {
        // a stop and restart between its steps is not spent budget
        let device_s = made.device_s();
        if let Some(last) = b.batches.last_mut() {
            last.device_s = Some(device_s);
        }
        b.spent_s += device_s;
        b.stop = "the targeted batch was the stage's last (one per run)".into();
    }
    let mut with_loop = all.to_vec();
    with_loop.extend_from_slice(&made.measurements);
    // the new rows decide the undecided candidates on top of the model before the loop; only
    // when that continued discovery still leaves something undecided is the search run again
    // from the 34 parameters (greedy, it can end at another structure), the lower
    // cross-validated gap kept (same folds)
    let cont = discover(&first.model, &with_loop, &first.params, None, settings.discover)?;
    let decided = borderline_effects(&cont, &with_loop, settings.targets).is_empty();
    let continued = continued_discovery(&first, cont);
    let (second, choice) = if decided {
        let choice = LoopChoice::continued_only(&continued);
        (continued, choice)
    } else {
        let fresh = discover(calibrated, &with_loop, base, None, settings.discover)?;
        let choice = LoopChoice::of(&continued, &fresh);
        (if choice.kept_continued { continued } else { fresh }, choice)
    };
    let mut report = LoopReport::of(&first, all, &targets, &proposed, &made.measurements, &second)?;
    report.choice = Some(choice);
    Ok(LoopOutcome {
        discovery: second,
        report: Some(report),
        last_joints: made.records.last().map(|r| r.state.joints),
        measurements: made.measurements,
    })
}

/// Why the targeted batch `tour` (proposed as `proposal`) is not measured, if it is not: it
/// does not fit what is left of the budget `b`, or it would shrink no undecided parameter's σ
/// by [`MIN_SIGMA_GAIN`] (the expected gain too small for its device time). Records the batch
/// (not measured yet) in `b`.
fn targeted_batch_refused(
    b: &mut BudgetReport,
    tour: &CampaignPlan,
    start: Option<JointVector>,
    proposal: &Proposal,
) -> Option<String> {
    let predicted_s = b.time_model.predict_s(tour, start);
    let planned = measure_steps(tour);
    b.push(BatchSpend { batch: "targeted".into(), planned, predicted_s, device_s: None });
    let gain = proposal
        .std_before
        .iter()
        .zip(&proposal.std_after)
        .filter(|(before, _)| **before > 0.0)
        .map(|(before, after)| 1.0 - after / before)
        .fold(0.0, f64::max);
    if PREDICTION_MARGIN * predicted_s > b.left_s() {
        return Some(format!(
            "the targeted batch ({planned} measurements, {predicted_s:.0} s predicted, {PREDICTION_MARGIN} x with the margin) does not fit the {:.0} s left of the {:.0} s budget",
            b.left_s(),
            b.budget_s
        ));
    }
    if gain < MIN_SIGMA_GAIN {
        return Some(format!(
            "the targeted batch would shrink the undecided parameters' sigma by at most {:.0} % (< {:.0} %): too little for {predicted_s:.0} s of device time",
            100.0 * gain,
            100.0 * MIN_SIGMA_GAIN
        ));
    }
    None
}
