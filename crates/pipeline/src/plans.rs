//! The three kinds of plan folder and their campaigns, shared by `vatcal calibrate`'s stages
//! and the by-hand commands (`vatcal plan --kind …`, `vatcal campaign --plan DIR`):
//!
//! | kind | planned by | `tour.csv` | campaign journal | measurements |
//! |---|---|---|---|---|
//! | `calibration` | [`crate::plan_stage`] (`vatcal plan`) | probe poses | `campaign.journal` | `measurements.csv` |
//! | `discovery` | [`crate::discovery_stage::plan_discovery`] | probe poses; the two-sided repeats are added when it is run ([`discovery_tour_of`]) | `discovery.journal` | `discovery_measurements.csv` |
//! | `validation` | [`validation_plan`] + [`write_validation_plan`] | tracker poses (`track` rows): random poses, then the printing path commanded by each model | `validation.journal` | `validation_measurements.csv` (tracker rows, tank frame) |
//!
//! The folder says its kind in `summary.json` (`"kind"`; a summary without it, or no summary,
//! is a calibration plan, as `vatcal plan` has always written them), with what its campaign
//! needs besides the tour (a discovery plan's repeats).

use serde::{Deserialize, Serialize};
use vatcal_campaign::validation::{ValidationPlan, ValidationPlanOptions, build_validation_plan};
use vatcal_campaign::{CampaignConfig, CampaignPlan, CampaignReport};
use vatcal_core::JointVector;
use vatcal_kinematics::Model;
use vatcal_planning::geometry::CellGeometry;

use crate::folders::{PlanFolder, RunFolder, VALIDATION_JOURNAL};
use crate::registration::RegistrationReport;
use crate::{DeviceSet, PipelineError, Progress, RunOptions, Stage};

/// Tracker rows of a validation campaign run by hand (tank frame; `tcp,q1..qN,x,y,z` and the
/// context columns, what `vatcal validate` and `vatcal identify` read).
pub const VALIDATION_MEASUREMENTS_CSV: &str = "validation_measurements.csv";

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
            Self::Calibration => crate::folders::CAMPAIGN_JOURNAL,
            Self::Discovery => crate::discovery_stage::DISCOVERY_JOURNAL,
            Self::Validation => VALIDATION_JOURNAL,
        }
    }

    /// The measurements CSV its campaign writes in a run folder.
    pub fn measurements(self) -> &'static str {
        match self {
            Self::Calibration => crate::folders::MEASUREMENTS_CSV,
            Self::Discovery => crate::discovery_stage::DISCOVERY_MEASUREMENTS_CSV,
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
    /// ([`crate::discovery_stage::add_two_sided_repeats`])
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
        let path = self.path("summary.json");
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
        let path = self.path("summary.json");
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

/// The discovery campaign of a discovery plan folder: its `tour.csv` with `repeats` two-sided
/// repeats added ([`crate::discovery_stage::add_two_sided_repeats`]), and the number added.
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
    let added = crate::discovery_stage::add_two_sided_repeats(&mut tour, nominal, repeats, overshoot_rad);
    Ok((tour, added))
}

/// The validation campaign of a run — random poses and the printing path commanded by each of
/// `commanding` (the nominal model first) — as the `validation` stage of `vatcal calibrate`
/// plans it ([`crate::validation_options`] of `opts`, starting at `start`; a chain without the
/// printing path is validated on random poses within one turn per joint), and its options.
///
/// # Errors
/// The plan cannot be built (too few collision-free poses, a path no model can command, …).
pub fn validation_plan(
    opts: &RunOptions,
    nominal: &Model,
    geometry: &CellGeometry,
    commanding: &[(&str, &Model)],
    start: Option<JointVector>,
) -> Result<(ValidationPlan, ValidationPlanOptions), PipelineError> {
    let mut options = crate::validation_options(opts, start);
    if !crate::has_printing_path(nominal) {
        options.printing.slices = 0;
        // one turn per joint: the path planner connects the random poses of a ±360° arm
        options.random.revolute_range_deg = Some(360.0);
    }
    let plan = build_validation_plan(nominal, geometry, commanding, &options)?;
    Ok((plan, options))
}

/// `summary.json` of a validation plan folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationPlanSummary {
    /// `validation`
    pub kind: PlanKind,
    /// the master seed (the validation's own seed is derived from it, [`crate::validation_seed`])
    pub seed: u64,
    /// random poses (visited first)
    pub random_poses: usize,
    /// slices of the printing path (0 on a chain without it)
    pub slices: usize,
    /// the models commanding a run of the printing path, in execution order
    pub path_runs: Vec<String>,
    /// SMRs measured at every slice
    pub slice_targets: Vec<u32>,
    /// tracker measurements in all
    pub tracker_measurements: usize,
    /// campaign steps
    pub steps: usize,
    /// legs between random poses that needed RRT-Connect
    pub rrt_legs: usize,
}

/// Writes a validation plan folder: `tour.csv` (`track` rows) and `summary.json`
/// ([`ValidationPlanSummary`]); returns the summary.
///
/// # Errors
/// A file that cannot be written.
pub fn write_validation_plan(
    plan: &ValidationPlan,
    nominal: &Model,
    seed: u64,
    folder: &PlanFolder,
) -> Result<ValidationPlanSummary, PipelineError> {
    std::fs::create_dir_all(folder.dir())
        .map_err(|source| PipelineError::Io { path: folder.dir().to_path_buf(), source })?;
    plan.campaign.write_tour_for(folder.path("tour.csv"), nominal.joint_kinds())?;
    let summary = ValidationPlanSummary {
        kind: PlanKind::Validation,
        seed,
        random_poses: plan.random_poses.len(),
        slices: plan.slices.len(),
        path_runs: plan.path_runs.iter().map(|r| r.label.clone()).collect(),
        slice_targets: plan.slice_targets.clone(),
        tracker_measurements: plan.measurement_count(),
        steps: plan.campaign.steps.len(),
        rrt_legs: plan.rrt_legs,
    };
    let path = folder.path("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .map_err(|source| PipelineError::Io { path, source })?;
    Ok(summary)
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
    let campaign =
        crate::run_campaign(devices, nominal, tour, &journal, config, Stage::Discover, None, progress)?;
    vatcal_io::write_measurements_for(
        folder.path(PlanKind::Discovery.measurements()),
        &campaign.measurements,
        nominal.joint_kinds(),
    )?;
    Ok(campaign)
}

/// Runs a tracker campaign `tour` (a validation plan's) on `devices` into the run folder's
/// `validation.journal` (resumed when present): first the tracker registration
/// ([`crate::registration::registration_step`]: the folder's when there is one), then every
/// step, each tracker reading mapped into the tank frame by the registration.
///
/// # Errors
/// The devices have no tracker (before anything moves), the registration or the campaign
/// fails.
pub fn tracker_campaign_stage(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    tour: &CampaignPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<(CampaignReport, Option<RegistrationReport>), PipelineError> {
    if devices.devices().tracker.is_none() {
        return Err(PipelineError::Option {
            option: "devices".into(),
            reason: "the validation measures with a laser tracker and the devices have none (add a `tracker` entry \
                     to the devices file)"
                .into(),
        });
    }
    let registration =
        crate::registration::registration_step(devices, nominal, folder.dir(), config.tracker_retries)?;
    let frame = registration.as_ref().and_then(|r| r.tank_from_tracker());
    let journal = folder.path(VALIDATION_JOURNAL);
    let report = crate::run_campaign(
        devices,
        nominal,
        tour,
        &journal,
        config,
        Stage::Validate,
        frame.as_ref(),
        progress,
    )?;
    Ok((report, registration))
}

#[cfg(test)]
mod tests {
    use super::*;

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
