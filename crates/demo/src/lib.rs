#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The whole calibration of the paper, simulated end to end in one call ([`run_demo`]; the
//! `vatcal demo` command): the pipeline of `vatcal-pipeline` (plan → measurement campaign →
//! identification → validation → report) on the in-process virtual cell of `vatcal-sim`,
//! whose hidden truth is `perturbed_truth(nominal, seed, &ErrorBudget::realistic())` — the
//! robot controller believes the nominal model, the devices have the paper's noise budget.
//!
//! This crate only wires the virtual cell ([`SimDevices`]) and describes it for the report
//! ([`DemoSetup`]); every stage, file format and the report itself live in the pipeline.
//!
//! The hidden truth is chosen by [`DemoOptions::truth`] (default `paper-like`: the paper's 34
//! parameters' errors plus the physics they miss, `docs/virtual-cell.md`; `ideal`: only the 34
//! parameters' errors).
//!
//! Everything is seeded: the same options give the same numbers (`report.json` is identical
//! byte for byte; only the wall-clock times in `summary.md` change).
//!
//! Any other serial chain (a cell file that is not the canonical Meca500-on-guide cell, e.g.
//! `fixtures/ur5e.toml`) runs the **same** pipeline on the virtual cell of that chain: the
//! simulated arm has the chain's joints, the guide exists only if the chain has one, the
//! identified set is the chain's identifiable default set, the discovery stage looks for gear
//! harmonics of every revolute joint, and the validation has random poses only (no printing
//! path: that needs the canonical cell's guide and tank; `docs/virtual-cell.md`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;
use vatcal_campaign::validation::ModelValidation;
use vatcal_campaign::{CampaignConfig, CellDevices};
use vatcal_core::CellFile;
use vatcal_hardware_traits::{TriCal, VirtualClock};
use vatcal_identification::Identification;
use vatcal_kinematics::Model;
use vatcal_pipeline::report::ValidationSummary;
use vatcal_pipeline::{
    CalibrateOptions, CalibrateOutcome, DeviceSet, DiscoveryStageOptions, Progress, ReportSetup, RunOptions,
    RunReport, StageLog,
};
use vatcal_sim::truth::ErrorBudget;
pub use vatcal_sim::truth::TruthSpec;
use vatcal_sim::{
    NoiseBudget, ProbeImperfections, SimArm, SimGauge, SimGuide, SimOperator, SimTracker, VirtualCell,
};

pub use vatcal_pipeline::{
    CampaignSummary, PAPER, PaperFigures, PipelineError as DemoError, REPORT_FORMAT, RunSizes as DemoSizes,
    ValidationSummary as DemoValidationSummary,
};

/// The canonical nominal cell (`fixtures/meca500-zaber.toml`), built into the binary so that
/// the demo runs from any directory.
pub const BUILT_IN_CELL: &str = vatcal_core::CANONICAL_CELL_TOML;

/// Name of the built-in cell in messages and in the report.
pub const BUILT_IN_CELL_NAME: &str = "fixtures/meca500-zaber.toml (built in)";

/// Options of [`run_demo`]. New options (another hidden truth, more stages) are added here as
/// fields with a default in [`DemoOptions::new`].
#[derive(Debug, Clone)]
pub struct DemoOptions {
    /// master seed: hidden truth, device noise, planning, validation poses
    pub seed: u64,
    /// the nominal cell (what the robot controller believes)
    pub nominal: CellFile,
    /// where the nominal cell comes from (for the report)
    pub nominal_source: String,
    /// sizes of every stage
    pub sizes: DemoSizes,
    /// the hidden truth of the virtual cell (default: paper-like)
    pub truth: TruthSpec,
    /// run the discovery stage after the calibration (default: on): extra probe measurements,
    /// missing-effect discovery, and the fit with the truth's effect structure (the oracle)
    pub discovery: bool,
    /// extra probe measurements of the discovery stage, at most (default 360,
    /// `DiscoveryStageOptions::new`; the budget plans fewer when they do not fit)
    pub discovery_count: usize,
    /// device-time budget of the discovery measurements \[s\] (default 15 min,
    /// `DiscoveryStageOptions::budget_s`; `None`: `discovery_count` whatever it takes)
    pub discovery_budget_s: Option<f64>,
    /// which stages run, and whether the report folder is resumed (default: every stage, a
    /// fresh run; `vatcal demo --stages … --resume`)
    pub calibrate: CalibrateOptions,
}

impl DemoOptions {
    /// The paper's sizes on the built-in cell, seed `seed`.
    ///
    /// # Errors
    /// Only if the built-in cell does not parse (a build defect).
    pub fn new(seed: u64) -> Result<Self, DemoError> {
        let nominal = CellFile::from_toml_str(BUILT_IN_CELL, BUILT_IN_CELL_NAME)?;
        Ok(Self {
            seed,
            nominal,
            nominal_source: BUILT_IN_CELL_NAME.into(),
            sizes: DemoSizes::default(),
            truth: TruthSpec::PaperLike,
            discovery: true,
            discovery_count: DiscoveryStageOptions::new(seed).count,
            discovery_budget_s: DiscoveryStageOptions::new(seed).budget_s,
            calibrate: CalibrateOptions::default(),
        })
    }

    /// Small sizes for a quick look at a chain (`vatcal demo --quick`): 20 orientations, 3
    /// guide steps, 40 measurements, 200 random validation poses, 60 discovery measurements
    /// (the printing path's slices as given).
    pub fn quick(mut self) -> Self {
        self.sizes = self.sizes.quick();
        self.discovery_count = 60;
        self
    }

    /// The pipeline options of the demo: the campaign settings of [`campaign_config`].
    pub fn run_options(&self) -> RunOptions {
        RunOptions {
            seed: self.seed,
            nominal: self.nominal.clone(),
            sizes: self.sizes.clone(),
            campaign: campaign_config(self.seed),
        }
    }
}

/// The campaign settings of the demo: a measurement whose auto-centering is refused is skipped
/// (and counted) instead of stopping the run; the journal is written record by record but
/// synced once at the end (the virtual cell's steps take microseconds); no progress bar (the
/// pipeline reports progress to its caller).
pub fn campaign_config(seed: u64) -> CampaignConfig {
    CampaignConfig {
        skip_failed_measurements: true,
        show_progress: false,
        sync_journal_each_step: false,
        note: format!("vatcal demo, seed {seed}"),
        ..CampaignConfig::default()
    }
}

/// How the simulation was set up (`report.json`'s `setup`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoSetup {
    /// where the nominal cell came from (copied to `nominal.toml`)
    pub nominal_cell: String,
    /// how the hidden truth was made
    pub hidden_truth: String,
    /// whether the truth's geometric errors are exactly ± the sizes below with random signs
    /// (`paper-like`, [`vatcal_sim::truth::signed_truth`]) instead of Gaussian with these σ
    pub truth_errors_fixed_size: bool,
    /// standard deviation (or, with `truth_errors_fixed_size`, the fixed size) of the MDH
    /// length errors of the truth \[mm\]
    pub truth_length_sigma_mm: f64,
    /// standard deviation of the MDH angle errors of the truth \[deg\]
    pub truth_angle_sigma_deg: f64,
    /// standard deviation of the base translation errors \[mm\]
    pub truth_base_translation_sigma_mm: f64,
    /// standard deviation of the base rotation errors \[deg\]
    pub truth_base_angle_sigma_deg: f64,
    /// range of the joint compliances of the truth \[rad/(N·m)\]
    pub truth_compliance_range_rad_per_n_m: (f64, f64),
    /// robot repeatability (3σ) \[mm\]
    pub robot_repeatability_mm: f64,
    /// guide repeatability (3σ) \[mm\]
    pub guide_repeatability_mm: f64,
    /// tool-changer repeatability (3σ) \[mm\]
    pub tool_changer_repeatability_mm: f64,
    /// gauge maximum error (uniform) \[mm\]
    pub gauge_max_error_mm: f64,
    /// tracker error per axis (3σ) \[mm\]
    pub tracker_error_mm: f64,
    /// largest tilt of a true gauge axis from its nominal direction \[deg\]
    pub gauge_axis_tilt_deg: f64,
    /// candidate orientations per TCP × position
    pub orientations: usize,
    /// guide positions of the candidates
    pub guide_steps: usize,
    /// measurements selected
    pub count: usize,
    /// identified parameter set
    pub parameters: String,
    /// estimation method
    pub method: String,
    /// how the summary names the identified set (`the paper's 34 parameters`, `the
    /// calibration's N parameters`; not in `report.json`)
    #[serde(skip)]
    pub parameters_name: String,
    /// number of identified parameters (not in `report.json`)
    #[serde(skip)]
    pub parameter_count: usize,
    /// whether the cell's chain has an external guide (not in `report.json`): the summary
    /// leaves out guide noise, guide steps and guide physics otherwise
    #[serde(skip)]
    pub has_guide: bool,
}

impl DemoSetup {
    /// The setup of a demo with `opts` that identified `fit`.
    pub fn of(opts: &DemoOptions, fit: &Identification) -> Self {
        let fixed = opts.truth == TruthSpec::PaperLike;
        let e = if fixed { ErrorBudget::paper_like() } else { ErrorBudget::realistic() };
        let n = NoiseBudget::paper();
        let p = ProbeImperfections::default();
        Self {
            nominal_cell: opts.nominal_source.clone(),
            hidden_truth: match &opts.truth {
                TruthSpec::Ideal => format!(
                    "vatcal_sim::truth::perturbed_truth(nominal, {}, &ErrorBudget::realistic())",
                    opts.seed
                ),
                TruthSpec::PaperLike => format!(
                    "vatcal_sim::truth::paper_like_truth(nominal, {}, &PaperLikePhysics::paper())",
                    opts.seed
                ),
                TruthSpec::File(p) => format!("truth cell file {}", p.display()),
            },
            truth_errors_fixed_size: fixed,
            truth_length_sigma_mm: e.length_mm,
            truth_angle_sigma_deg: e.angle_rad.to_degrees(),
            truth_base_translation_sigma_mm: e.base_translation_mm,
            truth_base_angle_sigma_deg: e.base_angle_rad.to_degrees(),
            truth_compliance_range_rad_per_n_m: e.compliance_range,
            robot_repeatability_mm: n.robot_repeatability_mm,
            guide_repeatability_mm: n.guide_repeatability_mm,
            tool_changer_repeatability_mm: n.tool_changer_repeatability_mm,
            gauge_max_error_mm: n.gauge_max_error_mm,
            tracker_error_mm: n.tracker_error_mm,
            gauge_axis_tilt_deg: p.gauge_axis_tilt_rad.to_degrees(),
            orientations: opts.sizes.orientations,
            guide_steps: opts.sizes.guide_steps,
            count: opts.sizes.count,
            parameters: if fit.params == vatcal_core::ParamSet::paper34() {
                format!("paper34 ({} parameters)", fit.params.len())
            } else {
                format!("the chain's identifiable default set ({} parameters)", fit.params.len())
            },
            method: fit.method.to_string(),
            parameters_name: vatcal_pipeline::discovery_stage::parameter_set_name(&fit.params),
            parameter_count: fit.params.len(),
            has_guide: fit.model.guide_joint().is_some(),
        }
    }
}

impl ReportSetup for DemoSetup {
    fn format(&self) -> &str {
        REPORT_FORMAT
    }

    fn title(&self, seed: u64) -> String {
        format!("# vatcal demo — simulated calibration of the virtual cell (seed {seed})")
    }

    fn intro(&self) -> String {
        "Everything below was computed on the **virtual cell**: no hardware was used. The numbers \
         are deterministic for the seed (`report.json` holds all of them)."
            .into()
    }

    fn setup_markdown(&self, v: &ValidationSummary) -> String {
        let s = self;
        let mut m = String::new();
        let _ = writeln!(
            m,
            "* nominal cell (what the simulated robot controller believes): {} → `nominal.toml`",
            s.nominal_cell
        );
        let _ = writeln!(
            m,
            "* hidden truth: `{}` — nominal + random errors {} {:.2} mm on the MDH lengths, {:.3}° on the \
             MDH angles, {:.2} mm / {:.3}° on the base pose, joint compliances drawn in {:.1e}..{:.1e} rad/(N·m)",
            s.hidden_truth,
            if s.truth_errors_fixed_size { "of exactly ± (random signs)" } else { "with σ" },
            s.truth_length_sigma_mm,
            s.truth_angle_sigma_deg,
            s.truth_base_translation_sigma_mm,
            s.truth_base_angle_sigma_deg,
            s.truth_compliance_range_rad_per_n_m.0,
            s.truth_compliance_range_rad_per_n_m.1
        );
        let guide_noise =
            if s.has_guide { format!(", guide {} mm", s.guide_repeatability_mm) } else { String::new() };
        let _ = writeln!(
            m,
            "* device noise (the paper's budget, 3σ): robot {} mm{guide_noise}, tool changer {} mm, gauges {} mm \
             (uniform), tracker {} mm per axis; TriCal gauge axes tilted by up to {:.1}° (unknown to the campaign)",
            s.robot_repeatability_mm,
            s.tool_changer_repeatability_mm,
            s.gauge_max_error_mm,
            s.tracker_error_mm,
            s.gauge_axis_tilt_deg
        );
        let guide_steps =
            if s.has_guide { format!(" × {} guide steps", s.guide_steps) } else { String::new() };
        let slices = match v.printing_path.slices {
            0 => String::new(),
            n => format!(", {n} printing slices"),
        };
        let _ = writeln!(
            m,
            "* sizes: {} orientations{guide_steps} per TCP × position, {} measurements, {} random validation \
             poses{slices}",
            s.orientations, s.count, v.random_poses
        );
        m
    }

    fn parameters(&self) -> String {
        self.parameters.clone()
    }

    fn comparison_note(&self) -> String {
        let (set, n) = (&self.parameters_name, self.parameter_count);
        if self.hidden_truth.contains("perturbed_truth") {
            format!(
                "The hidden truth (`--truth ideal`) differs from the nominal cell only in {set}, \
             so a calibrated model can match it up to the noise of the simulated devices: the calibrated errors \
             above are that noise floor (tracker, robot and tool-changer repeatability). The paper's 0.271 / \
             0.220 mm also contain whatever the real cell does beyond the model, and the real tracker's \
             registration errors."
            )
        } else {
            let guide = if self.has_guide {
                "guide angular and straightness errors, carriage tilt under the arm's weight, "
            } else {
                ""
            };
            format!(
                "The hidden truth also contains physics {set} do not model (strain-wave gear \
             harmonics, backlash, {guide}wrong masses, CMM errors, a tool-changer offset, thermal growth, tracker \
             registration and SMR errors; `docs/virtual-cell.md`), so the calibrated errors above are what the \
             {n}-parameter model leaves, like the paper's 0.271 / 0.220 mm; `--truth ideal` shows the devices' \
             noise floor instead."
            )
        }
    }

    fn method(&self) -> String {
        self.method.clone()
    }
}

/// Everything the demo measured (`report.json`).
pub type DemoReport = RunReport<DemoSetup>;

/// What a demo produced.
#[derive(Debug, Clone)]
pub struct DemoOutcome {
    /// the report (also written as `report.json`)
    pub report: DemoReport,
    /// the identification (calibrated model, statistics)
    pub identification: Identification,
    /// the hidden true model of the virtual cell (oracle: a real cell has none)
    pub truth: Model,
    /// wall-clock seconds of every stage
    pub stage_seconds: Vec<(String, f64)>,
    /// the files written, relative to the output directory
    pub files: Vec<PathBuf>,
    /// the discovery stage, when it ran
    pub discovery: Option<vatcal_pipeline::DiscoveryOutcome>,
}

impl DemoOutcome {
    /// The validation of the model labelled `label` (`nominal` or `calibrated`).
    pub fn validation(&self, label: &str) -> Option<&ModelValidation> {
        self.report.model(label)
    }

    /// The short before/after table printed by `vatcal demo`.
    pub fn comparison_table(&self) -> String {
        vatcal_pipeline::comparison_table(&self.report)
    }
}

/// Owned simulated devices of one virtual cell, lent to campaigns as trait objects.
#[derive(Debug)]
pub struct SimDevices {
    arm: SimArm,
    /// the guide, when the cell's chain has one
    guide: Option<SimGuide>,
    probe: TriCal<SimGauge>,
    tracker: SimTracker,
    operator: SimOperator,
    clock: VirtualClock,
    /// the cell's thermometer when it has a temperature channel (paper-like truth)
    thermometer: Option<vatcal_sim::SimThermometer>,
}

impl SimDevices {
    /// The devices of `cell`.
    ///
    /// # Errors
    /// The cell's probe configuration is invalid.
    pub fn of(cell: &VirtualCell) -> Result<Self, DemoError> {
        Ok(Self {
            arm: cell.arm(),
            guide: cell.guide(),
            probe: cell.probe()?,
            tracker: cell.tracker(),
            operator: cell.operator(),
            clock: cell.clock(),
            thermometer: cell.thermometer(),
        })
    }
}

impl DeviceSet for SimDevices {
    fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: self.guide.as_mut().map(|g| g as &mut dyn vatcal_hardware_traits::LinearAxis),
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
            thermometer: self.thermometer.as_mut().map(|t| t as &mut dyn vatcal_hardware_traits::Thermometer),
        }
    }
}

/// The instruments' noise per axis \[mm\] that a cell with the device budget `noise` declares
/// (its data sheets; 3σ figures): a probe measurement — the ball where the recorded centring
/// offset says — carries the robot's and the guide's repeatability of that motion and the
/// gauge error (uniform, σ = max/√3); a tracker measurement the tracker's error. The
/// tool-changer repeatability is drawn once per session, a systematic offset, not noise.
pub fn instrument_noise_mm(noise: &vatcal_sim::NoiseBudget) -> (f64, f64) {
    let probe = ((noise.robot_repeatability_mm / 3.0).powi(2)
        + (noise.guide_repeatability_mm / 3.0).powi(2)
        + (noise.gauge_max_error_mm / 3f64.sqrt()).powi(2))
    .sqrt();
    (probe, noise.tracker_error_mm / 3.0)
}

/// Runs the whole simulated calibration and writes the report folder `out` (created if
/// missing; the demo's own files in it are replaced, its journals removed first so the run
/// starts afresh). `log` receives one line per finished stage.
///
/// # Errors
/// Invalid sizes (checked before anything runs), any stage's error ([`DemoError`]), or a file
/// that cannot be written.
pub fn run_demo(opts: &DemoOptions, out: &Path, log: &mut dyn FnMut(&str)) -> Result<DemoOutcome, DemoError> {
    run_demo_with_progress(opts, out, &mut StageLog(log))
}

/// [`run_demo`] reporting every stage and step to `progress`.
///
/// # Errors
/// As [`run_demo`]; also when [`DemoOptions::calibrate`] stops before the report.
pub fn run_demo_with_progress(
    opts: &DemoOptions,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<DemoOutcome, DemoError> {
    let (outcome, truth) = run_demo_stages(opts, out, progress)?;
    let Some(run) = outcome.run else {
        return Err(DemoError::Option {
            option: "stages".into(),
            reason: "the selected stages stop before the report (the compensation stage writes it)".into(),
        });
    };
    Ok(DemoOutcome {
        report: run.report,
        identification: run.identification,
        truth,
        stage_seconds: run.stage_seconds,
        files: run.files,
        discovery: run.discovery,
    })
}

/// The stages of [`DemoOptions::calibrate`] on the in-process virtual cell — the pipeline's
/// `calibrate`, exactly what `vatcal calibrate` runs on real devices — and the hidden true
/// model (oracle). A resumed run starts a new virtual cell of the same seed, as a restarted
/// `vatcal sim-cell` would: its clock starts at zero.
///
/// # Errors
/// As [`run_demo`].
pub fn run_demo_stages(
    opts: &DemoOptions,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<(CalibrateOutcome<DemoSetup>, Model), DemoError> {
    opts.sizes.check()?;
    let nominal = Model::from_cell(&opts.nominal)?;
    let cell = opts
        .truth
        .virtual_cell(nominal.clone(), opts.seed)
        .map_err(|e| DemoError::Option { option: "truth".into(), reason: e.to_string() })?;
    let mut devices = SimDevices::of(&cell)?;
    let (probe_sigma_mm, tracker_sigma_mm) = instrument_noise_mm(&cell.config().noise);
    let stage = opts.discovery.then(|| DiscoveryStageOptions {
        true_effects: Some(cell.truth().effects().to_vec()),
        plan_effects: vatcal_pipeline::discovery_stage::plan_effects_for(&nominal),
        count: opts.discovery_count,
        budget_s: opts.discovery_budget_s,
        ..DiscoveryStageOptions::new(opts.seed).with_instrument_noise(probe_sigma_mm, tracker_sigma_mm)
    });
    let outcome = vatcal_pipeline::calibrate(
        &opts.run_options(),
        stage.as_ref(),
        &opts.calibrate,
        &mut devices,
        |fit| DemoSetup::of(opts, fit),
        out,
        progress,
    )?;
    Ok((outcome, cell.truth()))
}
