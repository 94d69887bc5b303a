//! Time on the devices (`timing.json`, the "Time on the devices" section of `summary.md`):
//! each stage's wall time and device-clock time, and from the campaign journals the measured
//! time of every kind of step — moves, probe measurements (auto-centring), plate
//! re-placements, tracker points — against the planner's estimate for the same steps
//! (`vatcal_planning::motion::MotionTimer` on the executed paths, the `[motion]` table's
//! `measurement_s` and `probe_replacement_s`).
//!
//! A step's measured time is the difference of the `time_s` stamps of its journal record and
//! the record before it (the device clock: the wall clock on a real cell, the simulated cell's
//! virtual time on `vatcal sim-cell` and in the demo). The first step's time also holds the
//! activation and homing before it.

use std::path::Path;

use serde::Serialize;
use vatcal_campaign::{CampaignPlan, CampaignStep, Journal, StepOutcome};
use vatcal_core::cell::MotionLimits;
use vatcal_kinematics::Model;
use vatcal_planning::motion::MotionTimer;
use vatcal_planning::output::PlanSummary;

use crate::PipelineError;
use crate::folders::{CAMPAIGN_JOURNAL, DISCOVERY_JOURNAL, LOOP_JOURNAL, VALIDATION_JOURNAL};
use crate::state::StagesFile;

pub use crate::folders::TIMING_FILE;

/// Measured and estimated seconds of one kind of step.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct StepTimes {
    /// steps of this kind
    pub count: usize,
    /// measured on the devices' clock \[s\]
    pub measured_s: f64,
    /// the planner's estimate for the same steps \[s\] (`None`: the planner has no model of it)
    pub estimated_s: Option<f64>,
}

impl StepTimes {
    fn add(&mut self, measured_s: f64, estimated_s: Option<f64>) {
        self.count += 1;
        self.measured_s += measured_s;
        if let Some(e) = estimated_s {
            self.estimated_s = Some(self.estimated_s.unwrap_or(0.0) + e);
        }
    }

    /// Measured seconds per step.
    pub fn measured_mean_s(&self) -> f64 {
        if self.count == 0 { 0.0 } else { self.measured_s / self.count as f64 }
    }
}

/// One campaign (a journal) split by kind of step.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct CampaignTiming {
    /// the journal
    pub journal: String,
    /// span of the journal on the devices' clock \[s\]
    pub total_s: f64,
    /// joint moves between measurement poses (planner: synchronised joint moves at the
    /// `[motion]` speeds × `speed_fraction`, no settling; the first move, from wherever the
    /// homing left the arm, has no estimate)
    pub moves: StepTimes,
    /// probe measurements: auto-centring, from arrival at the approach pose to the record
    /// (planner: `[motion] measurement_s` each)
    pub probe_measurements: StepTimes,
    /// plate re-placements by the operator (planner: `[motion] probe_replacement_s` each)
    pub replacements: StepTimes,
    /// tracker points (the planner has no estimate)
    pub tracker_points: StepTimes,
    /// probe zeroing with the master ball
    pub zeroing: StepTimes,
    /// mean auto-centring corrections per probe measurement
    pub centring_corrections_mean: f64,
}

/// A stage's times.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageTime {
    /// `plan`, `campaign`, … ([`crate::Stage::key`])
    pub stage: String,
    /// wall-clock seconds of the attempt that finished it
    pub wall_s: Option<f64>,
    /// devices' clock seconds (campaign stages)
    pub device_s: Option<f64>,
    /// how often it was started
    pub attempts: u32,
}

/// Everything of `timing.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunTiming {
    /// each stage
    pub stages: Vec<StageTime>,
    /// the planner's estimate of the measurement campaign along its planned paths (its
    /// `summary.json` → `timing.planned_paths_s`) \[s\]
    pub planner_campaign_estimate_s: f64,
    /// the `[motion]` table the planner used
    pub planner_measurement_s: f64,
    /// the `[motion]` table's re-placement time
    pub planner_replacement_s: f64,
    /// the `[motion]` table's speed fraction of planned moves
    pub planner_speed_fraction: f64,
    /// the measurement campaign
    pub campaign: CampaignTiming,
    /// the discovery campaign, when it ran
    pub discovery: Option<CampaignTiming>,
    /// the discovery's measurement loop (propose → measure → rediscover,
    /// `crate::discovery_loop`), when it measured
    pub discovery_loop: Option<CampaignTiming>,
    /// the validation campaign
    pub validation: CampaignTiming,
    /// the discovery's device-time budget \[s\] (`None`: no discovery or no budget)
    pub discovery_budget_s: Option<f64>,
    /// device time the discovery's batches took (Detmax and targeted) \[s\]
    pub discovery_spent_s: Option<f64>,
}

impl RunTiming {
    /// Fills the stages' wall and device times from the stage state (and this call's wall
    /// times, `seconds`, by stage name).
    pub fn set_wall(&mut self, seconds: &[(String, f64)], state: &StagesFile) {
        self.stages = crate::Stage::ALL
            .iter()
            .filter_map(|s| {
                let e = state.entry(*s)?;
                let wall = seconds.iter().find(|(n, _)| n == s.name()).map(|(_, w)| *w).or(e.wall_s);
                Some(StageTime {
                    stage: s.key().into(),
                    wall_s: wall,
                    device_s: e.device_s,
                    attempts: e.attempts,
                })
            })
            .collect();
    }

    /// The "Time on the devices" section of `summary.md`.
    pub fn markdown(&self) -> String {
        use std::fmt::Write as _;
        let mut m = String::new();
        let _ = writeln!(m, "\n## Time on the devices (`timing.json`)\n");
        let _ = writeln!(m, "| stage | wall [s] | devices' clock [min] | attempts |\n|---|---:|---:|---:|");
        for s in &self.stages {
            let _ = writeln!(
                m,
                "| {} | {} | {} | {} |",
                s.stage,
                s.wall_s.map_or("-".into(), |w| format!("{w:.2}")),
                s.device_s.map_or("-".into(), |d| format!("{:.1}", d / 60.0)),
                s.attempts
            );
        }
        let _ = writeln!(
            m,
            "\nMeasured on the devices' clock against the planner's estimate (`[motion]`: speed fraction {}, \
             {} s per measurement, {} s per re-placement; the planner estimated {:.1} min for the measurement \
             campaign):\n",
            self.planner_speed_fraction,
            self.planner_measurement_s,
            self.planner_replacement_s,
            self.planner_campaign_estimate_s / 60.0
        );
        let _ = writeln!(
            m,
            "| campaign | steps | moves measured / estimated [min] | probe measurements: n, s each (estimated) | re-placements: n, s each | tracker points: n, s each | total [min] |\n|---|---:|---:|---:|---:|---:|---:|"
        );
        let mut row = |name: &str, c: &CampaignTiming| {
            let est = |t: &StepTimes| t.estimated_s.map_or("-".into(), |e| format!("{:.1}", e / 60.0));
            let _ = writeln!(
                m,
                "| {name} | {} | {:.1} / {} | {}, {:.2} ({}) | {}, {:.1} | {}, {:.2} | {:.1} |",
                c.moves.count
                    + c.probe_measurements.count
                    + c.replacements.count
                    + c.tracker_points.count
                    + c.zeroing.count,
                c.moves.measured_s / 60.0,
                est(&c.moves),
                c.probe_measurements.count,
                c.probe_measurements.measured_mean_s(),
                if c.probe_measurements.count == 0 {
                    "-".to_string()
                } else {
                    format!("{:.1}", self.planner_measurement_s)
                },
                c.replacements.count,
                c.replacements.measured_mean_s(),
                c.tracker_points.count,
                c.tracker_points.measured_mean_s(),
                c.total_s / 60.0
            );
        };
        row("measurement", &self.campaign);
        if let Some(d) = &self.discovery {
            row("discovery", d);
        }
        if let Some(d) = &self.discovery_loop {
            row("discovery loop", d);
        }
        row("validation", &self.validation);
        m
    }
}

/// What [`measure`] reads.
pub(crate) struct TimingInputs<'a> {
    pub out: &'a Path,
    pub nominal: &'a Model,
    pub motion: &'a MotionLimits,
    pub tour: &'a CampaignPlan,
    pub plan: &'a PlanSummary,
    pub discovery_tour: Option<&'a CampaignPlan>,
    /// the measurement loop's tour, when the loop measured
    pub loop_tour: Option<&'a CampaignPlan>,
    /// the discovery's budget and what its batches spent \[s\], when it had a budget
    pub budget: Option<(f64, f64)>,
    pub validation_steps: &'a CampaignPlan,
}

/// Splits the run folder's journals into kinds of steps (stages are filled by
/// [`RunTiming::set_wall`]).
pub(crate) fn measure(i: &TimingInputs<'_>) -> Result<RunTiming, PipelineError> {
    let timer = MotionTimer::for_model(i.motion, i.nominal)?;
    let campaign = campaign_timing(&i.out.join(CAMPAIGN_JOURNAL), i.tour, &timer)?;
    let discovery = match i.discovery_tour {
        Some(tour) => Some(campaign_timing(&i.out.join(DISCOVERY_JOURNAL), tour, &timer)?),
        None => None,
    };
    let discovery_loop = match i.loop_tour {
        Some(tour) => Some(campaign_timing(&i.out.join(LOOP_JOURNAL), tour, &timer)?),
        None => None,
    };
    let validation = campaign_timing(&i.out.join(VALIDATION_JOURNAL), i.validation_steps, &timer)?;
    Ok(RunTiming {
        stages: Vec::new(),
        planner_campaign_estimate_s: i.plan.timing.planned_paths_s,
        planner_measurement_s: i.motion.measurement_s,
        planner_replacement_s: i.motion.probe_replacement_s,
        planner_speed_fraction: i.motion.speed_fraction,
        campaign,
        discovery,
        discovery_loop,
        validation,
        discovery_budget_s: i.budget.map(|b| b.0),
        discovery_spent_s: i.budget.map(|b| b.1),
    })
}

/// The steps of one journal by kind, `plan` giving each step's kind and planned path.
pub(crate) fn campaign_timing(
    journal: &Path,
    plan: &CampaignPlan,
    timer: &MotionTimer,
) -> Result<CampaignTiming, PipelineError> {
    let j = Journal::open(journal)?;
    let mut t = CampaignTiming { journal: journal.display().to_string(), ..CampaignTiming::default() };
    let mut previous: Option<(f64, vatcal_core::JointVector)> = None;
    let mut corrections = Vec::new();
    for r in j.records() {
        let dt = r.time_s - previous.as_ref().map_or(0.0, |p| p.0);
        if r.resumed {
            // the stop, the recovery and the restart are in this interval: not the step's time
            previous = Some((r.time_s, r.state.joints));
            continue;
        }
        match (plan.steps.get(r.step), &r.outcome) {
            (Some(CampaignStep::Move { path }), _) => {
                let estimate = previous.as_ref().map(|(_, from)| {
                    let mut p = vec![*from];
                    p.extend_from_slice(path);
                    timer.path_time_s(&p)
                });
                t.moves.add(dt, estimate);
            }
            (Some(CampaignStep::Measure { .. }), outcome) => {
                if let StepOutcome::Measured { iterations, .. } = outcome {
                    corrections.push(*iterations as f64);
                }
                t.probe_measurements.add(dt, Some(timer.measurement_s));
            }
            (Some(CampaignStep::PlaceProbe { .. }), _) => {
                t.replacements.add(dt, Some(timer.probe_replacement_s))
            }
            (Some(CampaignStep::Track { .. }), _) => t.tracker_points.add(dt, None),
            (Some(CampaignStep::ZeroProbe { .. }), _) => t.zeroing.add(dt, None),
            _ => {}
        }
        previous = Some((r.time_s, r.state.joints));
    }
    t.total_s = previous.map_or(0.0, |p| p.0);
    if !corrections.is_empty() {
        t.centring_corrections_mean = corrections.iter().sum::<f64>() / corrections.len() as f64;
    }
    Ok(t)
}

/// Writes `timing.json` into the run folder `out`.
pub(crate) fn write(out: &Path, timing: &RunTiming) -> Result<(), PipelineError> {
    let path = out.join(TIMING_FILE);
    let text = serde_json::to_string_pretty(timing)?;
    std::fs::write(&path, text).map_err(|source| PipelineError::Io { path, source })
}
