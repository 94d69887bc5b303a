//! The plan folder and the run folder: every command reads and writes them through here, so
//! each file format has one reader and one writer.
//!
//! | file | format | writer | reader |
//! |---|---|---|---|
//! | `plan/candidates.csv`, `plan/selected.csv` | `position,tcp,q1..q7` (mm, deg) | [`PlanFolder::write`] (`vatcal_planning::output`) | `vatcal_io::read_candidates` |
//! | `plan/tour.csv` | `step,kind,position,tcp,q1..q7,time_s` | [`PlanFolder::write`] (`vatcal_planning::output`) | [`PlanFolder::read_tour`] (`vatcal_campaign::CampaignPlan::read_tour`) |
//! | `plan/summary.json` | [`PlanSummary`] | [`PlanFolder::write`] | [`PlanFolder::read_summary`] |
//! | `run/campaign.journal` | checksummed JSON lines | `vatcal_campaign::Journal` | `vatcal_campaign::Journal` |
//! | `run/measurements.csv` | `position,tcp,q1..q7,time_s,dir2..dir7` | [`RunFolder::write_measurements`] (`vatcal_io`) | [`RunFolder::read_measurements`] (`vatcal_io`) |
//! | `run/report.json` | [`crate::RunReport`] | `report::Files::json` | (JSON) |

use std::path::{Path, PathBuf};

use vatcal_campaign::{CampaignPlan, CampaignReport, Journal, StepOutcome};
use vatcal_core::{JointKind, Measurement};
use vatcal_kinematics::Model;
use vatcal_planning::output::{PlanSummary, write_plan};
use vatcal_planning::plan::Plan;

use crate::PipelineError;

/// Files of a plan folder, in the order `vatcal plan` writes them.
pub const PLAN_FILES: [&str; 4] = ["candidates.csv", "selected.csv", "tour.csv", "summary.json"];
/// The journal of the measurement campaign in a run folder.
pub const CAMPAIGN_JOURNAL: &str = "campaign.journal";
/// The journal of the validation campaign in a run folder.
pub const VALIDATION_JOURNAL: &str = "validation.journal";
/// The measurements of the campaign in a run folder.
pub const MEASUREMENTS_CSV: &str = "measurements.csv";
/// The identified cell in a run folder.
pub const CALIBRATED_CELL: &str = "calibrated.toml";

/// A plan folder written by `vatcal plan` (or by the demo's plan stage).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlanFolder {
    dir: PathBuf,
}

impl PlanFolder {
    /// The plan folder `dir` (nothing is read yet).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Path of one of its files.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Writes [`PLAN_FILES`] (folder created if missing); returns the summary.
    ///
    /// # Errors
    /// A file that cannot be written.
    pub fn write(&self, plan: &Plan) -> Result<PlanSummary, PipelineError> {
        Ok(write_plan(plan, &self.dir)?)
    }

    /// Reads `tour.csv` of a chain with joints `kinds` (`model.joint_kinds()`: `q1..qN`) as
    /// campaign steps (validate them against the model before running).
    ///
    /// # Errors
    /// A missing folder or tour file, a tour of another joint count, or a bad row (file, line
    /// and column named).
    pub fn read_tour(&self, kinds: &[JointKind]) -> Result<CampaignPlan, PipelineError> {
        if !self.dir.is_dir() {
            return Err(PipelineError::Folder {
                path: self.dir.clone(),
                reason: "is not a plan folder (no such directory; write one with `vatcal plan`)".into(),
            });
        }
        Ok(CampaignPlan::read_tour_for(self.path("tour.csv"), kinds)?)
    }

    /// Reads `summary.json` as JSON (the plan summary is written for people and reports; its
    /// fields are documented in `docs/planning.md`).
    ///
    /// # Errors
    /// A missing or unparsable file.
    pub fn read_summary(&self) -> Result<serde_json::Value, PipelineError> {
        let path = self.path("summary.json");
        let text = std::fs::read_to_string(&path)
            .map_err(|e| PipelineError::Folder { path: path.clone(), reason: e.to_string() })?;
        serde_json::from_str(&text).map_err(|e| PipelineError::Folder { path, reason: e.to_string() })
    }
}

/// A run folder: journals, measurements, identified cell and report of one calibration run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunFolder {
    dir: PathBuf,
}

impl RunFolder {
    /// The run folder `dir` (nothing is created yet).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// Creates the folder if missing.
    ///
    /// # Errors
    /// The folder cannot be created.
    pub fn create(&self) -> Result<(), PipelineError> {
        std::fs::create_dir_all(&self.dir)
            .map_err(|source| PipelineError::Io { path: self.dir.clone(), source })
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Path of one of its files.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// The campaign journal.
    pub fn journal(&self) -> PathBuf {
        self.path(CAMPAIGN_JOURNAL)
    }

    /// The measurements CSV.
    pub fn measurements(&self) -> PathBuf {
        self.path(MEASUREMENTS_CSV)
    }

    /// Writes the measurements CSV of a chain with joints `kinds` (`position,tcp,q1..qN,
    /// time_s,dir{j}`, mm/deg; the canonical cell: `q1..q7`, `dir2..dir7`).
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write_measurements(
        &self,
        measurements: &[Measurement],
        kinds: &[JointKind],
    ) -> Result<(), PipelineError> {
        Ok(vatcal_io::write_measurements_for(self.measurements(), measurements, kinds)?)
    }

    /// Reads the measurements CSV (probe and tracker rows), checked against `model`.
    ///
    /// # Errors
    /// A missing file or a bad row (file, line and column named).
    pub fn read_measurements(&self, model: &Model) -> Result<Vec<Measurement>, PipelineError> {
        Ok(vatcal_io::read_measurements(self.measurements(), model)?)
    }

    /// The measurements recorded in the campaign journal so far (a finished or an interrupted
    /// campaign).
    ///
    /// # Errors
    /// A missing or damaged journal.
    pub fn journal_measurements(&self) -> Result<Vec<Measurement>, PipelineError> {
        Ok(Journal::open(self.journal())?.measurements())
    }

    /// Removes the journals of an earlier run (measurement, discovery and validation campaigns,
    /// the tracker registration) so that the next one starts afresh.
    ///
    /// # Errors
    /// A journal that exists but cannot be removed.
    pub fn remove_journals(&self) -> Result<(), PipelineError> {
        for name in [CAMPAIGN_JOURNAL, crate::discovery_stage::DISCOVERY_JOURNAL, VALIDATION_JOURNAL] {
            self.remove(name)?;
        }
        self.remove_registration()
    }

    /// Removes the tracker registration and its journaled nest readings (a validation measured
    /// afresh registers the tracker again).
    ///
    /// # Errors
    /// A file exists but cannot be removed.
    pub fn remove_registration(&self) -> Result<(), PipelineError> {
        self.remove(crate::registration::TRACKER_REGISTRATION_FILE)?;
        self.remove(crate::registration::TRACKER_READINGS_FILE)
    }

    /// Whether a validation campaign was started in the folder: its journal, the tracker
    /// registration or journaled nest readings exist.
    pub fn validation_started(&self) -> bool {
        [
            VALIDATION_JOURNAL,
            crate::registration::TRACKER_REGISTRATION_FILE,
            crate::registration::TRACKER_READINGS_FILE,
        ]
        .iter()
        .any(|name| self.path(name).exists())
    }

    /// Removes one file of the folder if it exists.
    ///
    /// # Errors
    /// The file exists but cannot be removed.
    pub fn remove(&self, name: &str) -> Result<(), PipelineError> {
        let path = self.path(name);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|source| PipelineError::Io { path, source })?;
        }
        Ok(())
    }

    /// What a finished campaign of the journal `name` recorded, read from the journal alone
    /// (no device is touched): every measurement and record, the skipped measurements.
    ///
    /// # Errors
    /// A missing or damaged journal.
    pub fn journal_report(&self, name: &str) -> Result<CampaignReport, PipelineError> {
        let journal = Journal::open(self.path(name))?;
        let records = journal.records().to_vec();
        let skipped = records.iter().filter(|r| matches!(r.outcome, StepOutcome::Skipped { .. })).count();
        Ok(CampaignReport {
            measurements: journal.measurements(),
            records,
            resumed_at_step: None,
            torn_bytes_dropped: journal.torn_bytes_dropped(),
            skipped,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_plan_folder_or_tour_is_named() {
        let dir = tempfile::tempdir().expect("tmp");
        let missing = PlanFolder::new(dir.path().join("nope"));
        let e = missing.read_tour(&vatcal_io::MECA500_ON_GUIDE_KINDS).expect_err("missing").to_string();
        assert!(e.contains("nope") && e.contains("vatcal plan"), "{e}");
        let empty = PlanFolder::new(dir.path());
        let e = empty.read_tour(&vatcal_io::MECA500_ON_GUIDE_KINDS).expect_err("no tour").to_string();
        assert!(e.contains("tour.csv"), "{e}");
    }

    #[test]
    fn run_folder_writes_and_reads_measurements_and_removes_journals() {
        let dir = tempfile::tempdir().expect("tmp");
        let run = RunFolder::new(dir.path().join("run"));
        run.create().expect("create");
        std::fs::write(run.journal(), "x").expect("journal");
        run.remove_journals().expect("remove");
        assert!(!run.journal().exists());
        let e = run.journal_measurements().expect_err("no journal").to_string();
        assert!(e.contains("campaign.journal"), "{e}");
    }
}
