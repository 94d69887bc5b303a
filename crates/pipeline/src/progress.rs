//! Progress of a run, reported to whoever drives the pipeline (the CLI draws bars from it;
//! library code never draws anything).

use std::time::{Duration, Instant};

/// The stages of a calibration run, in the order [`crate::run`] executes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum Stage {
    /// candidate poses, Detmax selection, tour (`plan/`)
    Plan,
    /// the measurement campaign with the TriCal probe (`campaign.journal`, `measurements.csv`)
    Campaign,
    /// parameter identification (`calibrated.toml`)
    Identify,
    /// discovery campaign, missing-effect discovery and the true-structure fit
    Discover,
    /// laser-tracker validation of the nominal and the calibrated model
    Validate,
    /// report folder (`report.json`, `summary.md`, CSVs, plots)
    Report,
}

impl Stage {
    /// Name used in messages and in the stage timings.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Plan => "plan",
            Stage::Campaign => "measurement campaign",
            Stage::Identify => "identification",
            Stage::Discover => "discovery",
            Stage::Validate => "validation",
            Stage::Report => "report",
        }
    }
}

impl Stage {
    /// Every stage, in the order of a run.
    pub const ALL: [Stage; 6] =
        [Stage::Plan, Stage::Campaign, Stage::Identify, Stage::Discover, Stage::Validate, Stage::Report];

    /// The stage's key on the command line (`--stages`) and in the run folder's stage state
    /// file: `plan`, `campaign`, `identify`, `discovery`, `validation`, `compensation` (the
    /// last stage checks the compensated printing path against the validation and writes the
    /// report).
    pub fn key(self) -> &'static str {
        match self {
            Stage::Plan => "plan",
            Stage::Campaign => "campaign",
            Stage::Identify => "identify",
            Stage::Discover => "discovery",
            Stage::Validate => "validation",
            Stage::Report => "compensation",
        }
    }

    /// The stage of a key ([`Stage::key`]; `report` is accepted for `compensation`).
    pub fn from_key(key: &str) -> Option<Stage> {
        match key.trim() {
            "report" => Some(Stage::Report),
            k => Stage::ALL.into_iter().find(|s| s.key() == k),
        }
    }

    /// Whether the stage moves the devices (a campaign on the cell).
    pub fn uses_devices(self) -> bool {
        matches!(self, Stage::Campaign | Stage::Discover | Stage::Validate)
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Where a campaign-like stage stands after one more journaled step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepProgress {
    /// plan steps done (including steps done before a resume)
    pub steps_done: usize,
    /// plan steps in total
    pub steps_planned: usize,
    /// measurements recorded (probe or tracker)
    pub measurements_done: usize,
    /// measurements in the plan
    pub measurements_planned: usize,
    /// estimated wall-clock time left, from the pace of the steps done in this process
    pub eta: Option<Duration>,
}

/// Receives the progress of a run. Every method has an empty default.
pub trait Progress {
    /// `stage` starts; `steps` is its number of plan steps when known.
    fn stage_started(&mut self, stage: Stage, steps: Option<usize>) {
        let _ = (stage, steps);
    }
    /// One more step of `stage` is done (campaign and validation stages).
    fn step_done(&mut self, stage: Stage, progress: &StepProgress) {
        let _ = (stage, progress);
    }
    /// `stage` finished after `seconds` of wall-clock time; `summary` is one line about it.
    fn stage_finished(&mut self, stage: Stage, summary: &str, seconds: f64) {
        let _ = (stage, summary, seconds);
    }
}

/// Ignores all progress.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}

/// Calls a closure with the summary line of every finished stage (`"plan: … (1.2 s)"`).
pub struct StageLog<'a>(pub &'a mut dyn FnMut(&str));

impl std::fmt::Debug for StageLog<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("StageLog")
    }
}

impl Progress for StageLog<'_> {
    fn stage_finished(&mut self, _stage: Stage, summary: &str, _seconds: f64) {
        (self.0)(summary);
    }
}

/// Counts steps and measurements of a stage and estimates the time left.
#[derive(Debug)]
pub(crate) struct StepCounter {
    start: Instant,
    steps_at_start: usize,
    pub(crate) progress: StepProgress,
}

impl StepCounter {
    pub(crate) fn new(steps_planned: usize, measurements_planned: usize) -> Self {
        Self {
            start: Instant::now(),
            steps_at_start: 0,
            progress: StepProgress {
                steps_done: 0,
                steps_planned,
                measurements_done: 0,
                measurements_planned,
                eta: None,
            },
        }
    }

    /// The stage resumes a journal that already holds `steps` steps and `measurements`
    /// measurements (the pace is measured on the steps of this process only).
    pub(crate) fn resumed(&mut self, steps: usize, measurements: usize) {
        self.steps_at_start = steps;
        self.progress.steps_done = steps;
        self.progress.measurements_done = measurements;
        self.start = Instant::now();
    }

    /// A step was journaled: `step` is its 0-based index; `measured` if it recorded a
    /// measurement.
    pub(crate) fn record(&mut self, step: usize, measured: bool) -> &StepProgress {
        let p = &mut self.progress;
        p.steps_done = step + 1;
        if measured {
            p.measurements_done += 1;
        }
        let here = p.steps_done.saturating_sub(self.steps_at_start);
        let left = p.steps_planned.saturating_sub(p.steps_done);
        p.eta = (here > 0).then(|| self.start.elapsed().mul_f64(left as f64 / here as f64));
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counter_counts_steps_and_measurements_and_estimates_time_left() {
        let mut c = StepCounter::new(4, 2);
        let p = *c.record(0, false);
        assert_eq!((p.steps_done, p.measurements_done), (1, 0));
        let p = *c.record(1, true);
        assert_eq!((p.steps_done, p.measurements_done), (2, 1));
        assert!(p.eta.is_some());
        let p = *c.record(3, true);
        assert_eq!((p.steps_done, p.measurements_done, p.eta), (4, 2, Some(Duration::ZERO)));
        let mut c = StepCounter::new(10, 5);
        c.resumed(6, 3);
        let p = *c.record(6, true);
        assert_eq!((p.steps_done, p.measurements_done), (7, 4));
    }
}
