//! The report folder of a calibration run: `report.json` (one writer: `Files::json`),
//! `summary.md`, the measurement and error CSVs and the SVG plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;
use vatcal_campaign::validation::plots::{path_error_svg, random_error_histogram_svg};
use vatcal_campaign::validation::{
    ModelValidation, PathValidation, PrintingPathOptions, PrintingSlice, RandomPoseOptions, ValidationPlan,
    ValidationPlanOptions, ValidationRecords,
};
use vatcal_campaign::{CampaignReport, StepOutcome};
use vatcal_core::{CellFile, JointKind, Measurement};
use vatcal_identification::{ErrorStats, Identification, IdentificationReport};
use vatcal_planning::output::PlanSummary;
use vatcal_report::{PlotSpec, Series, line_plot_svg, save_svg};

use crate::{CALIBRATED, NOMINAL, PipelineError, RunOutcome};

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
    pub compensation: Option<crate::compensation::CompensationSummary>,
    /// the paper's figures, for comparison (not ours)
    pub paper: PaperFigures,
    /// the discovery stage, when it ran
    #[serde(skip_serializing_if = "Option::is_none")]
    pub discovery: Option<crate::discovery_stage::DiscoveryReport>,
    /// the tracker registration of the validation (per calibration position residual, RMS, the
    /// transform); `None` when the tracker was not registered (the demo's in-process tracker)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tracker_registration: Option<crate::registration::RegistrationReport>,
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
    pub compensation: Option<crate::compensation::CompensationSummary>,
}

pub(crate) fn build_report<S: ReportSetup>(i: ReportInputs<'_, S>) -> RunReport<S> {
    let vp = i.validation_plan;
    RunReport {
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
        discovery: None,
        tracker_registration: None,
    }
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

fn stats_of<'a, S>(
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

/// Writes the files of the report folder and remembers their names.
pub(crate) struct Files {
    out: PathBuf,
    written: Vec<PathBuf>,
    /// the joints of the cell's chain (the measurement files' `q1..qN`, `dir{j}`)
    kinds: Vec<JointKind>,
}

impl Files {
    pub fn new(out: &Path, kinds: &[JointKind]) -> Self {
        Self { out: out.to_path_buf(), written: Vec::new(), kinds: kinds.to_vec() }
    }

    pub fn written(&self) -> &[PathBuf] {
        &self.written
    }

    /// Remembers a file written by someone else.
    pub fn note(&mut self, name: impl Into<PathBuf>) {
        self.written.push(name.into());
    }

    pub fn record_plan(&mut self) {
        for name in ["candidates.csv", "selected.csv", "tour.csv", "summary.json"] {
            self.note(Path::new("plan").join(name));
        }
    }

    fn text(&mut self, name: &str, text: &str) -> Result<(), PipelineError> {
        let path = self.out.join(name);
        std::fs::write(&path, text).map_err(|source| PipelineError::Io { path, source })?;
        self.note(name);
        Ok(())
    }

    pub fn cell(&mut self, name: &str, cell: &CellFile) -> Result<(), PipelineError> {
        cell.save(self.out.join(name))?;
        self.note(name);
        Ok(())
    }

    pub fn measurements(&mut self, name: &str, m: &[Measurement]) -> Result<(), PipelineError> {
        vatcal_io::write_measurements_for(self.out.join(name), m, &self.kinds)?;
        self.note(name);
        Ok(())
    }

    pub fn json(&mut self, name: &str, value: &impl Serialize) -> Result<(), PipelineError> {
        let text = serde_json::to_string_pretty(value)?;
        self.text(name, &text)
    }

    pub(crate) fn svg(&mut self, name: &str, svg: &str) -> Result<(), PipelineError> {
        save_svg(self.out.join(name), svg)?;
        self.note(name);
        Ok(())
    }

    /// The tracker measurements (random poses, each path run) and the error tables.
    pub fn validation_csvs(
        &mut self,
        records: &ValidationRecords,
        slices: &[PrintingSlice],
        results: &[ModelValidation],
    ) -> Result<(), PipelineError> {
        self.measurements("validation_random.csv", &records.random)?;
        for p in &records.paths {
            self.measurements(
                &format!("validation_path_{}.csv", p.label),
                &records.path_measurements(&p.label),
            )?;
        }
        self.text("validation_random_errors.csv", &random_errors_csv(records, results))?;
        if slices.is_empty() {
            // a chain without the printing path
            return Ok(());
        }
        self.text("printing_path_errors.csv", &path_errors_csv(slices, results))
    }

    /// The SVG plots: histogram (Fig. 8), path errors (Fig. 10, all models and the calibrated
    /// one alone), identification convergence.
    pub fn plots(
        &mut self,
        fit: &Identification,
        slices: &[PrintingSlice],
        results: &[ModelValidation],
    ) -> Result<(), PipelineError> {
        self.svg("random_errors_histogram.svg", &random_error_histogram_svg(results, 40)?)?;
        let paths: Vec<&PathValidation> = results.iter().filter_map(|r| r.path.as_ref()).collect();
        if slices.is_empty() || paths.is_empty() {
            // a chain without the printing path
            return self.svg("identification_convergence.svg", &convergence_svg(fit)?);
        }
        let title = "Position error at the tank bottom along the printing path";
        self.svg("path_errors.svg", &path_error_svg(title, slices, &paths)?)?;
        let calibrated: Vec<&PathValidation> =
            paths.iter().copied().filter(|p| p.label == CALIBRATED).collect();
        if !calibrated.is_empty() {
            let title = "Position error along the printing path, calibrated model";
            self.svg("path_errors_calibrated.svg", &path_error_svg(title, slices, &calibrated)?)?;
        }
        self.svg("identification_convergence.svg", &convergence_svg(fit)?)
    }

    pub fn summary<S: ReportSetup>(
        &mut self,
        name: &str,
        outcome: &RunOutcome<S>,
    ) -> Result<(), PipelineError> {
        let path = self.out.join(name);
        std::fs::write(&path, summary_markdown(outcome)).map_err(|source| PipelineError::Io { path, source })
    }
}

fn convergence_svg(fit: &Identification) -> Result<String, vatcal_report::PlotError> {
    let x: Vec<f64> = fit.iterations.iter().map(|l| l.iteration as f64).collect();
    let y: Vec<f64> = fit.iterations.iter().map(|l| l.mean_mm.max(1e-12).log10()).collect();
    let spec = PlotSpec::new(
        "Identification (Levenberg-Marquardt): mean residual per iteration",
        "iteration",
        "log10(mean residual / 1 mm)",
    );
    line_plot_svg(&spec, &x, &[Series::new("mean residual of the probe measurements", &y)])
}

/// `pose,tcp,<label>_dx_mm,<label>_dy_mm,<label>_dz_mm,<label>_error_mm,...`
fn random_errors_csv(records: &ValidationRecords, results: &[ModelValidation]) -> String {
    let mut out = String::from("pose,tcp");
    for r in results {
        let l = &r.label;
        let _ = write!(out, ",{l}_dx_mm,{l}_dy_mm,{l}_dz_mm,{l}_error_mm");
    }
    out.push('\n');
    for (k, m) in records.random.iter().enumerate() {
        let _ = write!(out, "{k},{}", m.tcp);
        for r in results {
            if let Some(e) = r.random.errors_mm.get(k) {
                let _ = write!(out, ",{},{},{},{}", e.x, e.y, e.z, e.norm());
            }
        }
        out.push('\n');
    }
    out
}

/// `slice,part_height_mm,target_x_mm,target_y_mm,target_z_mm`, then per model
/// `<label>_dx_mm,<label>_dy_mm,<label>_dz_mm,<label>_error_mm,<label>_plate_error_mm,
/// <label>_orientation_error_deg`.
fn path_errors_csv(slices: &[PrintingSlice], results: &[ModelValidation]) -> String {
    let paths: Vec<&PathValidation> = results.iter().filter_map(|r| r.path.as_ref()).collect();
    let mut out = String::from("slice,part_height_mm,target_x_mm,target_y_mm,target_z_mm");
    for p in &paths {
        let l = &p.label;
        let _ = write!(
            out,
            ",{l}_dx_mm,{l}_dy_mm,{l}_dz_mm,{l}_error_mm,{l}_plate_error_mm,{l}_orientation_error_deg"
        );
    }
    out.push('\n');
    for (k, s) in slices.iter().enumerate() {
        let t = s.tip_world_mm;
        let _ = write!(out, "{},{},{},{},{}", s.index, s.part_height_mm, t.x, t.y, t.z);
        for p in &paths {
            let e = p.tip_errors_mm[k];
            let _ = write!(
                out,
                ",{},{},{},{},{},{}",
                e.x,
                e.y,
                e.z,
                e.norm(),
                p.plate_errors_mm[k].norm(),
                p.orientation_errors_rad[k].to_degrees()
            );
        }
        out.push('\n');
    }
    out
}

fn stats_row(name: &str, s: &ErrorStats) -> String {
    format!(
        "| {name} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |\n",
        s.n, s.mean, s.rms, s.median, s.p95, s.max
    )
}

/// `summary.md`: setup, counts, identification log, before/after tables, the paper's figures,
/// files, wall-clock times.
fn summary_markdown<S: ReportSetup>(outcome: &RunOutcome<S>) -> String {
    let r = &outcome.report;
    let s = &r.setup;
    let mut m = String::new();
    let _ = writeln!(m, "{}\n", s.title(r.seed));
    let _ = writeln!(m, "{}\n", s.intro());
    let _ = writeln!(m, "## Setup\n");
    let _ = writeln!(m, "{}", s.setup_markdown(&r.validation));
    let _ = writeln!(m, "## 1. Plan (`plan/`)\n\n```text\n{}\n```\n", r.plan.text());

    let c = &r.campaign;
    let per: Vec<String> = c.per_position.iter().map(|(p, n)| format!("{n} at position {p}")).collect();
    let _ = writeln!(m, "## 2. Measurement campaign (`campaign.journal`, `measurements.csv`)\n");
    let _ = writeln!(
        m,
        "{} probe measurements ({}), {} skipped; auto-centering took {:.1} corrective moves on average \
         (at most {}), leaving {:.2} µm on average; {} campaign steps, {:.1} min of virtual time.\n",
        c.measurements,
        per.join(", "),
        c.skipped,
        c.centering_moves_mean,
        c.centering_moves_max,
        c.final_offset_mean_mm * 1000.0,
        c.plan_steps,
        c.virtual_time_s / 60.0
    );

    let id = &r.identification;
    let _ = writeln!(m, "## 3. Identification (`calibrated.toml`)\n");
    let _ = writeln!(
        m,
        "{}, {} from {} probe measurements: {} ({:?}).\n",
        s.parameters(),
        s.method(),
        id.n_probe,
        if id.converged { "converged" } else { "not converged" },
        id.termination
    );
    let _ = writeln!(m, "| iteration | mean [mm] | RMS [mm] | max [mm] | λ |\n|---:|---:|---:|---:|---:|");
    for it in &id.iterations {
        let _ = writeln!(
            m,
            "| {} | {:.6} | {:.6} | {:.6} | {:.2e} |",
            it.iteration, it.mean_mm, it.rms_mm, it.max_mm, it.lambda
        );
    }
    let _ = writeln!(
        m,
        "\nConvergence: `identification_convergence.svg`. Residuals at the solution: {}; σ̂ = {:.4} mm (dof {}), condition number {:.1}.\n",
        id.residual_stats.one_line(),
        id.sigma_hat_mm,
        id.dof,
        id.condition_number
    );
    let _ = writeln!(m, "| parameter | unit | nominal | identified | Δ | σ |\n|---|---|---:|---:|---:|---:|");
    for p in &id.parameters {
        let _ = writeln!(
            m,
            "| {} | {} | {:.6} | {:.6} | {:+.3e} | {:.1e} |",
            p.name,
            p.unit,
            p.nominal_file_units,
            p.identified_file_units,
            p.delta_file_units,
            p.sigma_file_units
        );
    }
    let _ = writeln!(m);

    let v = &r.validation;
    let _ = writeln!(m, "## 4. Validation with the simulated laser tracker (`validation.journal`)\n");
    let _ = writeln!(
        m,
        "* **random poses**: {} joint vectors over the whole workspace (≥ {}° inside the joint limits, \
         collision-free), one SMR measured at each; error = tracker − FK of the model \
         (`validation_random.csv`, `validation_random_errors.csv`, `random_errors_histogram.svg`, the paper's Fig. 8);",
        v.random_poses, v.random_options.joint_margin_deg
    );
    let p = &v.printing_path;
    if p.slices == 0 {
        let _ = writeln!(
            m,
            "* **printing path**: none (the tank path, lifted by the guide one layer per slice, exists for the \
             canonical Meca500-on-guide cell only);"
        );
    } else {
        let _ = writeln!(
            m,
            "* **printing path**: {} slices of {} mm; the part's end stays on the tank bottom (world z = {} mm) and \
         follows a half circle of radius {} mm while the plate tilts by up to {}° and turns by {}°; the guide \
         lifts by one layer per slice from {:.1} mm. Each model *commands* its own run through its IK; the three \
         SMRs measured at each slice give the end-effector pose, carried to the end of the part (lever effect). \
         Error = measured − intended there (`validation_path_*.csv`, `printing_path_errors.csv`, \
         `path_errors.svg`, `path_errors_calibrated.svg`, the paper's Figs. 9–10);",
            p.slices,
            p.layer_mm,
            p.start_mm[2],
            p.lateral_radius_mm,
            p.tilt_max_deg,
            p.spin_deg,
            v.guide_start_mm
        );
    }
    let _ = writeln!(
        m,
        "* {} tracker measurements in {} campaign steps ({} legs between random poses needed RRT-Connect), \
         {:.1} min of virtual time.\n",
        v.tracker_measurements,
        v.campaign_steps,
        v.rrt_legs,
        v.virtual_time_s / 60.0
    );
    let _ = writeln!(
        m,
        "| position error [mm] | n | mean | RMS | median | p95 | max |\n|---|---:|---:|---:|---:|---:|---:|"
    );
    for model in &v.models {
        m.push_str(&stats_row(&format!("random poses, {} model", model.label), &model.random.stats));
    }
    for model in &v.models {
        if let Some(path) = &model.path {
            m.push_str(&stats_row(
                &format!("printing path (part end), {} model", model.label),
                &path.tip_stats,
            ));
            m.push_str(&stats_row(
                &format!("printing path (build plate), {} model", model.label),
                &path.plate_stats,
            ));
        }
    }
    let _ = writeln!(m, "\n### Compared with the paper (their measurements, not ours)\n");
    let _ = writeln!(m, "| mean position error [mm] | nominal | calibrated |\n|---|---:|---:|");
    let (nr, np) = stats_of(r, NOMINAL);
    let (cr, cp) = stats_of(r, CALIBRATED);
    let f = |s: Option<&ErrorStats>| s.map_or("-".to_string(), |s| format!("{:.3}", s.mean));
    let _ = writeln!(m, "| this demo, random poses (n = {}) | {} | {} |", v.random_poses, f(nr), f(cr));
    let _ = writeln!(
        m,
        "| **paper**, random poses (n = {}, FARO Vantage E tracker) | {:.3} | {:.3} |",
        PAPER.random_poses, PAPER.random_nominal_mean_mm, PAPER.random_calibrated_mean_mm
    );
    if p.slices > 0 {
        let _ = writeln!(m, "| this demo, printing path ({} slices) | {} | {} |", p.slices, f(np), f(cp));
    }
    let _ = writeln!(
        m,
        "| **paper**, printing path ({} slices) | {:.3} | {:.3} |",
        PAPER.path_slices, PAPER.path_nominal_mean_mm, PAPER.path_calibrated_mean_mm
    );
    if let Some(c) = &r.compensation {
        m.push_str(&crate::compensation::summary_markdown(c));
    }
    if let Some(reg) = &r.tracker_registration {
        let _ = writeln!(m);
        m.push_str(&reg.markdown());
    }
    if let Some(d) = &outcome.discovery {
        m.push_str(&crate::discovery_stage::summary_section(r, d));
    }
    let note = outcome.report.setup.comparison_note();
    if !note.is_empty() {
        let _ = writeln!(m, "\n{note}\n");
    }

    let _ = writeln!(m, "## Files\n");
    for file in &outcome.files {
        let _ = writeln!(m, "* `{}`", file.display());
    }
    let _ = writeln!(m, "\n## Wall-clock time\n");
    let total: f64 = outcome.stage_seconds.iter().map(|(_, s)| s).sum();
    for (name, secs) in &outcome.stage_seconds {
        let _ = writeln!(m, "* {name}: {secs:.2} s");
    }
    let _ = writeln!(m, "* total: {total:.2} s");
    if let Some(t) = &outcome.timing {
        m.push_str(&t.markdown());
    }
    m
}

/// Writes `summary.html` from `summary.md` and the SVG files of the run folder `out`.
pub(crate) fn write_summary_html(out: &Path) -> Result<(), PipelineError> {
    let read = |path: std::path::PathBuf| {
        std::fs::read_to_string(&path).map_err(|source| PipelineError::Io { path, source })
    };
    let markdown = read(out.join("summary.md"))?;
    let mut names: Vec<String> = std::fs::read_dir(out)
        .map_err(|source| PipelineError::Io { path: out.to_path_buf(), source })?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".svg"))
        .collect();
    names.sort();
    let mut svgs = Vec::new();
    for n in names {
        let svg = read(out.join(&n))?;
        svgs.push((n, svg));
    }
    crate::discovery_stage::summary_html(&markdown, &svgs).save(out.join("summary.html"))?;
    Ok(())
}
