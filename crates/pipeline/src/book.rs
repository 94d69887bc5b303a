//! The bookkeeping of one [`crate::calibrate()`] call: which stages it runs, the stage state
//! file (`stages.json`), each stage's wall time, the progress reports and the list of files
//! written.

use std::path::Path;
use std::time::Instant;

use vatcal_core::JointKind;
use vatcal_identification::Identification;

use crate::files::Files;
use crate::folders::{NOMINAL_CELL, RunFolder, STAGES_FILE};
use crate::outcome::{CalibrateOutcome, RunOutcome};
use crate::state::{CalibrateOptions, StageStatus, StagesFile};
use crate::{PipelineError, Progress, RunOptions, Stage};

/// Stage bookkeeping: the stage state file, wall clock, progress, files.
pub(crate) struct Book<'p> {
    out: &'p Path,
    cal: &'p CalibrateOptions,
    pub state: StagesFile,
    pub progress: &'p mut dyn Progress,
    start: Instant,
    pub seconds: Vec<(String, f64)>,
    ran: Vec<Stage>,
    recomputed: Vec<Stage>,
    /// the stages run in this call from their start (not resumed): the device-clock arithmetic
    /// of the report may use this process's clock readings
    pub fresh: Vec<Stage>,
    /// the files of the run folder, in the order the summary lists them
    pub files: Files,
}

impl<'p> Book<'p> {
    /// Opens the run folder for the call: a fresh run (the `plan` stage selected, no resume)
    /// removes the journals and the stage state first; otherwise the folder's stage state must
    /// be of the same options. Copies the nominal cell into the folder.
    pub fn open(
        opts: &RunOptions,
        discovery_count: Option<usize>,
        cal: &'p CalibrateOptions,
        folder: &'p RunFolder,
        kinds: &[JointKind],
        progress: &'p mut dyn Progress,
    ) -> Result<Self, PipelineError> {
        let out = folder.dir();
        folder.create()?;
        let fresh = !cal.resume && cal.stages.contains(&Stage::Plan);
        let state = if fresh {
            folder.remove_journals()?;
            folder.remove(STAGES_FILE)?;
            StagesFile::new(opts, discovery_count)
        } else {
            match StagesFile::load(out)? {
                Some(s) => {
                    s.check(opts, discovery_count, out)?;
                    s
                }
                None if cal.resume => {
                    return Err(PipelineError::Folder {
                        path: out.join(STAGES_FILE),
                        reason: "no stage state: nothing to resume (start the run without --resume)".into(),
                    });
                }
                None => StagesFile::new(opts, discovery_count),
            }
        };
        state.save(out)?;
        let mut files = Files::new(out, kinds);
        files.cell(NOMINAL_CELL, &opts.nominal)?;
        Ok(Self {
            out,
            cal,
            state,
            progress,
            start: Instant::now(),
            seconds: Vec::new(),
            ran: Vec::new(),
            recomputed: Vec::new(),
            fresh: Vec::new(),
            files,
        })
    }

    /// Whether `stage` runs in this call: selected, and not already done when resuming.
    pub fn runs(&self, stage: Stage) -> bool {
        self.cal.stages.contains(&stage) && !(self.cal.resume && self.state.is_done(stage))
    }

    /// Whether `stage` was selected for this call.
    pub fn selected(&self, stage: Stage) -> bool {
        self.cal.stages.contains(&stage)
    }

    /// Whether a running `stage` measures afresh (its journal removed first): a stage run again
    /// on its own does; a resumed one continues its journal.
    pub fn restarts(&self, stage: Stage) -> bool {
        !self.cal.resume || self.state.entry(stage).is_none()
    }

    /// `stage` starts running (progress, state `running`, later stages no longer done).
    pub fn begin(&mut self, stage: Stage, steps: Option<usize>) -> Result<(), PipelineError> {
        self.start = Instant::now();
        self.progress.stage_started(stage, steps);
        self.mark_running(stage)
    }

    /// `stage` is `running` in the state file (attempts counted, later stages dropped).
    pub fn mark_running(&mut self, stage: Stage) -> Result<(), PipelineError> {
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

    /// The stage's wall clock starts now.
    pub fn restart_clock(&mut self) {
        self.start = Instant::now();
    }

    /// `stage` is done: `line` receives its wall time and returns the summary line.
    pub fn finish(
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
    pub fn recompute(&mut self, stage: Stage) -> Result<(), PipelineError> {
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

    /// The devices' clock seconds of a stage done earlier (0 when unknown).
    pub fn device_s(&self, stage: Stage) -> f64 {
        self.state.entry(stage).and_then(|e| e.device_s).unwrap_or(0.0)
    }

    /// What the call did: the report (`run`, when the last stage ran) and the identification.
    pub fn outcome<S>(self, run: Option<RunOutcome<S>>, fit: Option<Identification>) -> CalibrateOutcome<S> {
        CalibrateOutcome {
            run,
            identification: fit,
            ran: self.ran,
            recomputed: self.recomputed,
            state: self.state,
        }
    }
}
