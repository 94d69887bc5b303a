//! The report of a calibration run (`report.json`, [`RunReport`]): built from the stages'
//! outputs — the plan's summary, the campaign, the identification, the validation, the
//! compensation check, the discovery and the tracker registration — and the before/after table
//! of `vatcal demo` ([`comparison_table`]). `summary.md` is written by `crate::summary`, the
//! CSVs and plots by `crate::report_files`.

use std::fmt::Write as _;

use serde::Serialize;
use vatcal_campaign::validation::{
    ModelValidation, PrintingPathOptions, RandomPoseOptions, ValidationPlan, ValidationPlanOptions,
};
use vatcal_campaign::{CampaignReport, StepOutcome};
use vatcal_identification::{ErrorStats, Identification, IdentificationReport};
use vatcal_planning::output::PlanSummary;

use crate::compensation::CompensationSummary;
use crate::discovery_loop::LoopReport;
use crate::discovery_stage::DiscoveryOutcome;
use crate::registration::RegistrationReport;
use crate::{CALIBRATED, NOMINAL, PipelineError};

/// Value of [`RunReport::format`] for the simulated demo.
pub const REPORT_FORMAT: &str = "vatcal-demo-report/1";

/// How the cell of a run was set up: serialised as the `setup` object of `report.json` and
/// described in `summary.md`. The demo's setup names the hidden truth and the noise budget;
/// a real cell's names its devices.
pub trait ReportSetup: Serialize {
    /// value of `report.json`'s `format`
    fn format(&self) -> &str;
    /// the first line of `summary.md` (a Markdown heading)
    fn title(&self, seed: u64) -> String;
    /// the paragraph under the title
    fn intro(&self) -> String;
    /// the bullet list of the `## Setup` section (`validation`: the sizes of the validation)
    fn setup_markdown(&self, validation: &ValidationSummary) -> String;
    /// the identified parameter set, e.g. `paper34 (34 parameters)`
    fn parameters(&self) -> String;
    /// the estimation method
    fn method(&self) -> String;
    /// a paragraph under the comparison with the paper (what the numbers can and cannot show);
    /// empty: none
    fn comparison_note(&self) -> String {
        String::new()
    }
}

/// The paper's validation figures (Rolland et al., §5), quoted for comparison.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperFigures {
    /// random poses measured
    pub random_poses: usize,
    /// mean error at the random poses, nominal model \[mm\]
    pub random_nominal_mean_mm: f64,
    /// mean error at the random poses, calibrated model \[mm\]
    pub random_calibrated_mean_mm: f64,
    /// slices of the printing path
    pub path_slices: usize,
    /// mean error along the printing path, nominal model \[mm\]
    pub path_nominal_mean_mm: f64,
    /// mean error along the printing path, calibrated model \[mm\]
    pub path_calibrated_mean_mm: f64,
}

/// The paper's figures: 573 poses, 1.272 → 0.271 mm; 300 slices, 1.192 → 0.220 mm.
pub const PAPER: PaperFigures = PaperFigures {
    random_poses: 573,
    random_nominal_mean_mm: 1.272,
    random_calibrated_mean_mm: 0.271,
    path_slices: 300,
    path_nominal_mean_mm: 1.192,
    path_calibrated_mean_mm: 0.220,
};

/// The measurement campaign.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CampaignSummary {
    /// steps of the executed plan
    pub plan_steps: usize,
    /// probe measurements recorded
    pub measurements: usize,
    /// measurements skipped because auto-centering refused
    pub skipped: usize,
    /// measurements per calibration position `(position, count)`
    pub per_position: Vec<(u32, usize)>,
    /// mean number of auto-centering moves per measurement
    pub centering_moves_mean: f64,
    /// largest number of auto-centering moves
    pub centering_moves_max: usize,
    /// mean composite offset left after centering (final gauge reading) \[mm\]
    pub final_offset_mean_mm: f64,
    /// virtual time of the campaign (motions, readings, plate re-placements) \[s\]
    pub virtual_time_s: f64,
}

/// The validation campaign.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValidationSummary {
    /// random poses measured
    pub random_poses: usize,
    /// how they were drawn
    pub random_options: RandomPoseOptions,
    /// the printing path
    pub printing_path: PrintingPathOptions,
    /// guide position at the first slice \[mm\]
    pub guide_start_mm: f64,
    /// steps of the validation campaign
    pub campaign_steps: usize,
    /// tracker measurements taken
    pub tracker_measurements: usize,
    /// legs between random poses that needed RRT-Connect
    pub rrt_legs: usize,
    /// virtual time of the validation \[s\]
    pub virtual_time_s: f64,
    /// errors of each model (random poses and the path it commanded), with every error vector
    pub models: Vec<ModelValidation>,
}

/// Everything a run measured (`report.json`). Deterministic for a given seed and options on
/// the virtual cell.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunReport<S> {
    /// [`ReportSetup::format`] of the setup
    pub format: String,
    /// master seed
    pub seed: u64,
    /// the cell and the sizes
    pub setup: S,
    /// the plan (`plan/summary.json`)
    pub plan: PlanSummary,
    /// the measurement campaign
    pub campaign: CampaignSummary,
    /// the identification (parameters in file units, iteration log, statistics)
    pub identification: IdentificationReport,
    /// the validation with the simulated laser tracker
    pub validation: ValidationSummary,
    /// the printing path commanded with uncompensated and compensated targets
    /// (`vatcal-compensation`, the library of `vatcal compensate`); `None` for a chain without
    /// the printing path (`crate::has_printing_path`)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compensation: Option<CompensationSummary>,
    /// the paper's figures, for comparison (not ours)
    pub paper: PaperFigures,
    /// the discovery stage, when it ran
    #[serde(skip_serializing_if = "Option::is_none")]
    pub discovery: Option<DiscoveryReport>,
    /// the tracker registration of the validation (per calibration position residual, RMS, the
    /// transform); `None` when the tracker was not registered (the demo's in-process tracker)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tracker_registration: Option<RegistrationReport>,
}

impl<S> RunReport<S> {
    /// The validation of the model labelled `label`.
    pub fn model(&self, label: &str) -> Option<&ModelValidation> {
        self.validation.models.iter().find(|m| m.label == label)
    }
}

/// What [`build_report`] needs.
pub(crate) struct ReportInputs<'a, S> {
    pub seed: u64,
    pub setup: S,
    pub plan: PlanSummary,
    pub campaign: &'a CampaignReport,
    pub campaign_time_s: f64,
    pub fit: &'a Identification,
    pub validation_plan: &'a ValidationPlan,
    pub validation_options: &'a ValidationPlanOptions,
    pub validation_time_s: f64,
    pub results: Vec<ModelValidation>,
    pub compensation: Option<CompensationSummary>,
    pub discovery: Option<&'a DiscoveryOutcome>,
    pub tracker_registration: Option<RegistrationReport>,
}

/// The report of a run from its stages' outputs.
pub(crate) fn build_report<S: ReportSetup>(i: ReportInputs<'_, S>) -> Result<RunReport<S>, PipelineError> {
    let vp = i.validation_plan;
    Ok(RunReport {
        format: i.setup.format().to_string(),
        seed: i.seed,
        setup: i.setup,
        plan: i.plan,
        campaign: campaign_summary(i.campaign, i.campaign_time_s),
        identification: IdentificationReport::from_identification(i.fit),
        validation: ValidationSummary {
            random_poses: vp.random_poses.len(),
            random_options: i.validation_options.random.clone(),
            printing_path: i.validation_options.printing.clone(),
            guide_start_mm: vp.path_runs.first().and_then(|r| r.joints.first()).map_or(0.0, |q| q.guide_mm()),
            campaign_steps: vp.campaign.steps.len(),
            tracker_measurements: vp.measurement_count(),
            rrt_legs: vp.rrt_legs,
            virtual_time_s: i.validation_time_s,
            models: i.results,
        },
        compensation: i.compensation,
        paper: PAPER,
        discovery: i.discovery.map(DiscoveryReport::of).transpose()?,
        tracker_registration: i.tracker_registration,
    })
}

pub(crate) fn campaign_summary(report: &CampaignReport, virtual_time_s: f64) -> CampaignSummary {
    let mut moves = Vec::new();
    let mut offsets = Vec::new();
    let mut per_position: Vec<(u32, usize)> = Vec::new();
    for r in &report.records {
        if let StepOutcome::Measured { position, iterations, offset_mm, .. } = &r.outcome {
            moves.push(*iterations);
            offsets.push(nalgebra::Vector3::from(*offset_mm).norm());
            match per_position.iter_mut().find(|e| e.0 == *position) {
                Some(e) => e.1 += 1,
                None => per_position.push((*position, 1)),
            }
        }
    }
    let mean = |v: &[f64]| if v.is_empty() { 0.0 } else { v.iter().sum::<f64>() / v.len() as f64 };
    let moves_f: Vec<f64> = moves.iter().map(|m| *m as f64).collect();
    CampaignSummary {
        plan_steps: report.records.len(),
        measurements: report.measurements.len(),
        skipped: report.skipped,
        per_position,
        centering_moves_mean: mean(&moves_f),
        centering_moves_max: moves.iter().copied().max().unwrap_or(0),
        final_offset_mean_mm: mean(&offsets),
        virtual_time_s,
    }
}

pub(crate) fn stats_of<'a, S>(
    report: &'a RunReport<S>,
    label: &str,
) -> (Option<&'a ErrorStats>, Option<&'a ErrorStats>) {
    let m = report.model(label);
    (m.map(|m| &m.random.stats), m.and_then(|m| m.path.as_ref()).map(|p| &p.tip_stats))
}

/// The before/after table of `vatcal demo` (mean, 95th percentile and max per model, and the
/// paper's means).
pub fn comparison_table<S>(report: &RunReport<S>) -> String {
    let (nr, np) = stats_of(report, NOMINAL);
    let (cr, cp) = stats_of(report, CALIBRATED);
    let cells = |s: Option<&ErrorStats>| match s {
        Some(s) => format!("{:>7.3} {:>7.3} {:>7.3}", s.mean, s.p95, s.max),
        None => format!("{:>7} {:>7} {:>7}", "-", "-", "-"),
    };
    let n_random = nr.map_or(0, |s| s.n);
    let n_path = np.map_or(0, |s| s.n);
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{:<32} {:^23}   {:^23}   {:^17}",
        "position error [mm]", "nominal", "calibrated", "paper's means"
    );
    let _ = writeln!(
        t,
        "{:<32} {:>7} {:>7} {:>7}   {:>7} {:>7} {:>7}   {:^17}",
        "", "mean", "p95", "max", "mean", "p95", "max", "nominal → calib."
    );
    let _ = writeln!(
        t,
        "{:<32} {}   {}   {:>7.3} → {:<7.3}",
        format!("random poses (n = {n_random})"),
        cells(nr),
        cells(cr),
        PAPER.random_nominal_mean_mm,
        PAPER.random_calibrated_mean_mm
    );
    let _ = writeln!(
        t,
        "{:<32} {}   {}   {:>7.3} → {:<7.3}",
        format!("printing path ({n_path} slices)"),
        cells(np),
        cells(cp),
        PAPER.path_nominal_mean_mm,
        PAPER.path_calibrated_mean_mm
    );
    t.lines().map(str::trim_end).collect::<Vec<_>>().join("\n") + "\n"
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
    /// how the device-time budget sized the discovery's batches, what they cost and why the
    /// measuring stopped (`None`: no budget)
    pub budget: Option<crate::budget::BudgetReport>,
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
            budget: o.budget.clone(),
        })
    }
}
