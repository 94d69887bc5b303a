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

use serde::{Deserialize, Serialize};

use crate::PipelineError;

/// Files of a plan folder, in the order `vatcal plan` writes them.
pub const PLAN_FILES: [&str; 4] = ["candidates.csv", "selected.csv", "tour.csv", "summary.json"];
/// The tour of a plan folder.
pub const TOUR_CSV: &str = "tour.csv";
/// The summary of a plan folder (with its [`PlanHeader`]).
pub const PLAN_SUMMARY: &str = "summary.json";

/// The calibration plan folder in a run folder.
pub const PLAN_DIR: &str = "plan";
/// The nominal cell, copied into a run folder.
pub const NOMINAL_CELL: &str = "nominal.toml";
/// The stage state file of a run folder.
pub const STAGES_FILE: &str = "stages.json";
/// The journal of the measurement campaign in a run folder.
pub const CAMPAIGN_JOURNAL: &str = "campaign.journal";
/// The measurements of the campaign in a run folder.
pub const MEASUREMENTS_CSV: &str = "measurements.csv";
/// The identified cell in a run folder.
pub const CALIBRATED_CELL: &str = "calibrated.toml";
/// Plan folder of the discovery campaign (in the run folder).
pub const DISCOVERY_PLAN: &str = "discovery_plan";
/// Journal of the discovery campaign (in the run folder).
pub const DISCOVERY_JOURNAL: &str = "discovery.journal";
/// Probe measurements of the discovery campaign (in the run folder).
pub const DISCOVERY_MEASUREMENTS_CSV: &str = "discovery_measurements.csv";
/// Plan folder of the discovery's measurement loop (in the run folder).
pub const LOOP_PLAN: &str = "discovery_loop_plan";
/// The measurement loop's proposal, in its plan folder.
pub const LOOP_PROPOSAL: &str = "proposal.json";
/// Journal of the measurement loop's campaign (in the run folder).
pub const LOOP_JOURNAL: &str = "discovery_loop.journal";
/// Probe measurements of the measurement loop (in the run folder).
pub const LOOP_MEASUREMENTS_CSV: &str = "discovery_loop_measurements.csv";
/// The tracker registration of a run folder (JSON).
pub const TRACKER_REGISTRATION_FILE: &str = "tracker-registration.json";
/// The nest readings of an unfinished tracker registration (JSON list of `{"position": n,
/// "tracker_mm": [x, y, z]}`), written after every reading and removed once the fit is saved:
/// a registration interrupted between two readings (kill -9, a fault) continues with the next
/// position instead of measuring the nest again.
pub const TRACKER_READINGS_FILE: &str = "tracker-registration.readings.json";
/// The journal of the validation campaign in a run folder.
pub const VALIDATION_JOURNAL: &str = "validation.journal";
/// Tracker rows of a validation campaign run by hand (tank frame; `tcp,q1..qN,x,y,z` and the
/// context columns, what `vatcal validate` and `vatcal identify` read).
pub const VALIDATION_MEASUREMENTS_CSV: &str = "validation_measurements.csv";
/// The report of a run.
pub const REPORT_JSON: &str = "report.json";
/// The summary of a run.
pub const SUMMARY_MD: &str = "summary.md";
/// The summary of a run as one page with its plots (written with a discovery stage).
pub const SUMMARY_HTML: &str = "summary.html";
/// The timing file of a run folder.
pub const TIMING_FILE: &str = "timing.json";
/// The tracker measurements at the validation's random poses.
pub const VALIDATION_RANDOM_CSV: &str = "validation_random.csv";
/// Per random pose and model, the error vectors.
pub const VALIDATION_RANDOM_ERRORS_CSV: &str = "validation_random_errors.csv";
/// Per printing-path slice and model, the errors.
pub const PRINTING_PATH_ERRORS_CSV: &str = "printing_path_errors.csv";
/// Histogram of the random-pose errors (the paper's Fig. 8).
pub const RANDOM_ERRORS_HISTOGRAM_SVG: &str = "random_errors_histogram.svg";
/// Printing-path errors of every model (the paper's Fig. 10).
pub const PATH_ERRORS_SVG: &str = "path_errors.svg";
/// Printing-path errors of the calibrated model alone.
pub const PATH_ERRORS_CALIBRATED_SVG: &str = "path_errors_calibrated.svg";
/// The identification's convergence.
pub const IDENTIFICATION_CONVERGENCE_SVG: &str = "identification_convergence.svg";

/// The tracker measurements of the printing-path run commanded by the model `label`.
pub fn validation_path_csv(label: &str) -> String {
    format!("validation_path_{label}.csv")
}

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
        Ok(CampaignPlan::read_tour_for(self.path(TOUR_CSV), kinds)?)
    }

    /// Reads `summary.json` as JSON (the plan summary is written for people and reports; its
    /// fields are documented in `docs/planning.md`).
    ///
    /// # Errors
    /// A missing or unparsable file.
    pub fn read_summary(&self) -> Result<serde_json::Value, PipelineError> {
        let path = self.path(PLAN_SUMMARY);
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

    /// The calibration plan folder (`plan/`).
    pub fn plan(&self) -> PlanFolder {
        PlanFolder::new(self.path(PLAN_DIR))
    }

    /// The discovery campaign's plan folder (`discovery_plan/`).
    pub fn discovery_plan(&self) -> PlanFolder {
        PlanFolder::new(self.path(DISCOVERY_PLAN))
    }

    /// The measurement loop's plan folder (`discovery_loop_plan/`).
    pub fn loop_plan(&self) -> PlanFolder {
        PlanFolder::new(self.path(LOOP_PLAN))
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
        for name in [CAMPAIGN_JOURNAL, DISCOVERY_JOURNAL, VALIDATION_JOURNAL] {
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
        self.remove(TRACKER_REGISTRATION_FILE)?;
        self.remove(TRACKER_READINGS_FILE)
    }

    /// Whether a validation campaign was started in the folder: its journal, the tracker
    /// registration or journaled nest readings exist.
    pub fn validation_started(&self) -> bool {
        [VALIDATION_JOURNAL, TRACKER_REGISTRATION_FILE, TRACKER_READINGS_FILE]
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

/// What a plan folder is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlanKind {
    /// the probe campaign the identification uses (`vatcal plan`'s default)
    Calibration,
    /// the extra probe campaign of the discovery, with two-sided repeats
    Discovery,
    /// the laser-tracker validation: random poses and the printing path
    Validation,
}

impl PlanKind {
    /// `calibration`, `discovery` or `validation`.
    pub fn key(self) -> &'static str {
        match self {
            Self::Calibration => "calibration",
            Self::Discovery => "discovery",
            Self::Validation => "validation",
        }
    }

    /// The journal its campaign writes in a run folder.
    pub fn journal(self) -> &'static str {
        match self {
            Self::Calibration => CAMPAIGN_JOURNAL,
            Self::Discovery => DISCOVERY_JOURNAL,
            Self::Validation => VALIDATION_JOURNAL,
        }
    }

    /// The measurements CSV its campaign writes in a run folder.
    pub fn measurements(self) -> &'static str {
        match self {
            Self::Calibration => MEASUREMENTS_CSV,
            Self::Discovery => DISCOVERY_MEASUREMENTS_CSV,
            Self::Validation => VALIDATION_MEASUREMENTS_CSV,
        }
    }
}

/// The part of a plan folder's `summary.json` that says what the folder is (other fields are
/// the plan's summary, for people).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanHeader {
    /// the kind (absent: a calibration plan)
    #[serde(default = "calibration")]
    pub kind: PlanKind,
    /// discovery plans: planned poses measured again from the opposite side
    /// ([`crate::two_sided::add_two_sided_repeats`])
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub two_sided_repeats: Option<usize>,
    /// discovery plans: how far past the pose each joint is taken before the opposite-side
    /// approach of a repeat \[deg\]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repeat_overshoot_deg: Option<f64>,
}

fn calibration() -> PlanKind {
    PlanKind::Calibration
}

impl PlanFolder {
    /// What the folder is ([`PlanHeader`] from `summary.json`; no summary: a calibration plan).
    ///
    /// # Errors
    /// An unreadable or invalid `summary.json`, or a discovery plan without its repeat
    /// settings (file and field named).
    pub fn read_header(&self) -> Result<PlanHeader, PipelineError> {
        let path = self.path(PLAN_SUMMARY);
        if !path.exists() {
            return Ok(PlanHeader {
                kind: PlanKind::Calibration,
                two_sided_repeats: None,
                repeat_overshoot_deg: None,
            });
        }
        let text = std::fs::read_to_string(&path)
            .map_err(|source| PipelineError::Io { path: path.clone(), source })?;
        let header: PlanHeader = serde_json::from_str(&text).map_err(|e| PipelineError::Folder {
            path: path.clone(),
            reason: format!("field `kind`: {e}"),
        })?;
        if header.kind == PlanKind::Discovery
            && (header.two_sided_repeats.is_none() || header.repeat_overshoot_deg.is_none())
        {
            return Err(PipelineError::Folder {
                path,
                reason: "a discovery plan needs `two_sided_repeats` and `repeat_overshoot_deg`".into(),
            });
        }
        if let Some(d) = header.repeat_overshoot_deg.filter(|d| !(d.is_finite() && *d >= 0.0)) {
            return Err(PipelineError::Folder {
                path,
                reason: format!("field `repeat_overshoot_deg`: {d} is not a finite angle ≥ 0"),
            });
        }
        Ok(header)
    }

    /// Adds `header` to the folder's `summary.json` (written by the planner first).
    ///
    /// # Errors
    /// A missing or unparsable summary, or one that cannot be written.
    pub fn mark(&self, header: &PlanHeader) -> Result<(), PipelineError> {
        let path = self.path(PLAN_SUMMARY);
        let mut summary = self.read_summary()?;
        let extra = serde_json::to_value(header)?;
        if let (Some(obj), Some(add)) = (summary.as_object_mut(), extra.as_object()) {
            for (k, v) in add {
                obj.insert(k.clone(), v.clone());
            }
        }
        let text = serde_json::to_string_pretty(&summary)? + "\n";
        std::fs::write(&path, text).map_err(|source| PipelineError::Io { path, source })
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

    #[test]
    fn a_plan_folder_says_its_kind_and_a_discovery_plan_its_repeats() {
        let dir = tempfile::tempdir().expect("tmp");
        let folder = PlanFolder::new(dir.path());
        // no summary, or a planner's summary without `kind`: a calibration plan
        assert_eq!(folder.read_header().expect("none").kind, PlanKind::Calibration);
        std::fs::write(folder.path("summary.json"), r#"{"selected": 40, "timing": {}}"#).expect("write");
        assert_eq!(folder.read_header().expect("planner's").kind, PlanKind::Calibration);
        folder
            .mark(&PlanHeader {
                kind: PlanKind::Discovery,
                two_sided_repeats: Some(4),
                repeat_overshoot_deg: Some(0.0573),
            })
            .expect("mark");
        let header = folder.read_header().expect("discovery");
        assert_eq!((header.kind, header.two_sided_repeats), (PlanKind::Discovery, Some(4)));
        assert_eq!(folder.read_summary().expect("summary")["selected"], 40, "the planner's fields are kept");
        std::fs::write(folder.path("summary.json"), r#"{"kind": "discovery"}"#).expect("write");
        let e = folder.read_header().expect_err("no repeats").to_string();
        assert!(e.contains("summary.json") && e.contains("two_sided_repeats"), "{e}");
        std::fs::write(folder.path("summary.json"), r#"{"kind": "survey"}"#).expect("write");
        let e = folder.read_header().expect_err("unknown kind").to_string();
        assert!(e.contains("summary.json") && e.contains("kind") && e.contains("survey"), "{e}");
    }
}
