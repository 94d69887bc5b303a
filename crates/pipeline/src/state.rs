//! The stage state of a run folder ([`StagesFile`], `stages.json`: each stage `running` or
//! `done`, attempts, wall time and device-clock time) and which stages a call runs
//! ([`CalibrateOptions`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::folders::STAGES_FILE;
use crate::{PipelineError, RunOptions, RunSizes, Stage};

/// `format` of [`STAGES_FILE`].
pub const STAGES_FORMAT: &str = "vatcal-calibrate-stages";

/// Which stages [`crate::calibrate()`] runs.
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
    /// The state of a new run of `opts` (`discovery_count`: the discovery stage's extra
    /// measurements, `None` without it).
    pub(crate) fn new(opts: &RunOptions, discovery_count: Option<usize>) -> Self {
        Self {
            format: STAGES_FORMAT.into(),
            version: 1,
            seed: opts.seed,
            sizes: opts.sizes.clone(),
            discovery_count,
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

    pub(crate) fn save(&self, out: &Path) -> Result<(), PipelineError> {
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

    pub(crate) fn entry_mut(&mut self, stage: Stage) -> &mut StageEntry {
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
    pub(crate) fn check(
        &self,
        opts: &RunOptions,
        count: Option<usize>,
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
        if self.discovery_count.is_some() && count.is_some() && self.discovery_count != count {
            return Err(differ(format!(
                "{:?} discovery measurements (this run: {:?})",
                self.discovery_count, count
            )));
        }
        Ok(())
    }
}
