//! The virtual-cell demo for any serial chain (`vatcal demo --cell CELL.toml` on a cell that is
//! not the canonical Meca500-on-guide cell), at the **model level**.
//!
//! The canonical demo ([`crate::run_demo`]) runs the device-level virtual cell of `vatcal-sim`
//! (a simulated Meca500, Zaber guide, TriCal gauges, tracker and operator, driven through the
//! campaign's device traits). Those simulated devices are Meca500-on-guide only, so for any
//! other chain this module simulates each measurement directly on the hidden true model:
//!
//! 1. **plan**: [`vatcal_planning::plan_campaign`] on the nominal model (candidates with the
//!    numerical IK, Detmax on the chain's default parameter set, tour, collision-free paths);
//! 2. **hidden truth**: [`vatcal_sim::truth::perturbed_truth`] — the nominal model with seeded
//!    random errors of the [`ErrorBudget`] size on every MDH + beta row, the base pose, the
//!    compliances, TCPs and calibration positions (its any-chain branch);
//! 3. **measure** (model-level auto-centring): for every planned measurement, the true joints
//!    that put the ball on the probe origin plus a gauge residual (Gaussian,
//!    [`ModelLevelNoise::centring_sigma_mm`] per axis) with the tool orientation of the
//!    commanded pose (a local solve on the truth from the commanded joints,
//!    [`vatcal_planning::ik::ModelIk::refine_from`]); the recorded joints are those plus
//!    joint-encoder noise ([`ModelLevelNoise::encoder_sigma_deg`] / `_mm`);
//! 4. **identify** the plan's parameter set from the nominal model
//!    ([`vatcal_identification::identify`]);
//! 5. **validate** nominal and calibrated models on held-out poses: random joint vectors inside
//!    the limits (10 % margin), a random TCP each, the truth's TCP position plus tracker noise
//!    ([`ModelLevelNoise::tracker_sigma_mm`]).
//!
//! What it does not simulate (the canonical demo does): device protocols, robot and guide
//! repeatability as separate sources, gauge axis tilts, tool-changer offsets, the printing-path
//! validation and the discovery stage. `docs/virtual-cell.md` states the difference.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use vatcal_core::{CellFile, JointVector, Measurement, deg_to_rad};
use vatcal_identification::{IdentifyOptions, identify, validate};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::ik::{ModelIk, RefineOptions};
use vatcal_planning::numeric_ik::MultiStartOptions;
use vatcal_planning::output::write_plan;
use vatcal_planning::plan::{PlanOptions, plan_campaign};
use vatcal_sim::truth::ErrorBudget;

use crate::DemoError;

/// Noise of the model-level measurements (internal units are converted at use).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModelLevelNoise {
    /// residual of the auto-centring: the true ball centre ends this far from the probe origin,
    /// Gaussian per axis [mm] (the canonical cell: 5 µm composite threshold, gauges 1.2 µm)
    pub centring_sigma_mm: f64,
    /// joint-encoder noise of the recorded revolute joints, Gaussian [deg]
    pub encoder_sigma_deg: f64,
    /// encoder noise of the recorded prismatic joints, Gaussian [mm]
    pub encoder_sigma_mm: f64,
    /// tracker noise of the validation poses, Gaussian per axis [mm]
    pub tracker_sigma_mm: f64,
}

impl Default for ModelLevelNoise {
    /// 2 µm centring residual (as `vatcal_sim::truth::ProbeNoise`), 0.0001° encoders (about
    /// 1 µm at 600 mm), 1 µm on prismatic joints, tracker 10 µm (the canonical budget's 30 µm 3σ).
    fn default() -> Self {
        Self {
            centring_sigma_mm: 0.002,
            encoder_sigma_deg: 1e-4,
            encoder_sigma_mm: 0.001,
            tracker_sigma_mm: 0.01,
        }
    }
}

/// Options of [`run_any_chain_demo`].
#[derive(Debug, Clone)]
pub struct AnyChainDemoOptions {
    /// master seed: truth, noise, planning, validation poses
    pub seed: u64,
    /// the nominal cell (any chain)
    pub nominal: CellFile,
    /// where it comes from (for the report)
    pub nominal_source: String,
    /// candidate orientations per TCP × calibration position
    pub orientations: usize,
    /// guide positions (chains with a prismatic joint)
    pub guide_steps: usize,
    /// measurements selected
    pub count: usize,
    /// held-out validation poses
    pub validation_poses: usize,
    /// Detmax restarts
    pub detmax_restarts: usize,
    /// errors of the hidden truth
    pub budget: ErrorBudget,
    /// measurement noise
    pub noise: ModelLevelNoise,
}

impl AnyChainDemoOptions {
    /// The default sizes (500 orientations, 10 guide steps, 40 measurements, 500 validation
    /// poses) on `nominal`.
    pub fn new(seed: u64, nominal: CellFile, nominal_source: impl Into<String>) -> Self {
        Self {
            seed,
            nominal,
            nominal_source: nominal_source.into(),
            orientations: 500,
            guide_steps: 10,
            count: 40,
            validation_poses: 500,
            detmax_restarts: 8,
            budget: ErrorBudget::realistic(),
            noise: ModelLevelNoise::default(),
        }
    }

    /// Small sizes for tests and a quick look (20 orientations, 3 guide steps, 2 Detmax
    /// restarts, 200 validation poses).
    pub fn quick(mut self) -> Self {
        self.orientations = 20;
        self.guide_steps = 3;
        self.validation_poses = 200;
        self.detmax_restarts = 2;
        self
    }
}

/// Mean / RMS / max of position errors [mm].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorSummary {
    /// mean distance
    pub mean_mm: f64,
    /// root mean square distance
    pub rms_mm: f64,
    /// largest distance
    pub max_mm: f64,
}

/// Everything the model-level demo measured (`report.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AnyChainReport {
    /// report format
    pub format: String,
    /// master seed
    pub seed: u64,
    /// nominal cell source
    pub nominal_cell: String,
    /// chain description, e.g. `6 joints (RRRRRR)`
    pub chain: String,
    /// how the measurements were simulated
    pub measurement_level: String,
    /// candidates that passed every planning stage
    pub candidates: usize,
    /// measurements planned / simulated (a planned pose the truth cannot reach is dropped)
    pub measurements_planned: usize,
    /// measurements simulated
    pub measurements: usize,
    /// names of the identified parameters
    pub parameters: Vec<String>,
    /// identification converged
    pub converged: bool,
    /// RMS of the identification residuals [mm]
    pub fit_rms_mm: f64,
    /// errors of the nominal model on the held-out poses (TCP position vs tracker)
    pub nominal: ErrorSummary,
    /// errors of the calibrated model on the held-out poses
    pub calibrated: ErrorSummary,
    /// held-out validation poses
    pub validation_poses: usize,
    /// measurement noise
    pub noise: ModelLevelNoise,
    /// truth error sizes: MDH lengths [mm], MDH angles [deg], base translation [mm], base
    /// angles [deg]
    pub truth_sigmas: [f64; 4],
    /// wall-clock seconds per stage (not deterministic)
    #[serde(skip)]
    pub stage_seconds: Vec<(String, f64)>,
}

/// Format name of the model-level `report.json`.
pub const ANY_CHAIN_REPORT_FORMAT: &str = "vatcal-demo-any-chain-report/1";

/// What [`run_any_chain_demo`] produced.
#[derive(Debug, Clone)]
pub struct AnyChainOutcome {
    /// the numbers (also `report.json`)
    pub report: AnyChainReport,
    /// the hidden truth (oracle)
    pub truth: Model,
    /// the calibrated model
    pub calibrated: Model,
    /// the simulated probe measurements (recorded joints)
    pub measurements: Vec<Measurement>,
    /// the held-out validation poses (tracker measurements of the truth)
    pub validation: Vec<Measurement>,
    /// files written, relative to the output folder
    pub files: Vec<PathBuf>,
}

fn gauss(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return 0.0;
    }
    Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(rng))
}

/// Model-level probe measurements (see the module docs, step 3): for each planned
/// `(position, tcp, commanded joints)`, the truth's joints that put the ball centre on the
/// probe origin plus the centring residual, with the commanded pose's tool orientation, then
/// encoder noise. A planned pose whose local solve does not converge on the truth is dropped.
pub fn model_level_probe_measurements(
    truth: &Model,
    planned: &[Measurement],
    noise: &ModelLevelNoise,
    seed: u64,
) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let Ok(ik) = ModelIk::numerical(truth, MultiStartOptions::default()) else {
        return Vec::new();
    };
    let refine = RefineOptions { max_iterations: 100, ..RefineOptions::default() };
    let mut out = Vec::with_capacity(planned.len());
    for m in planned {
        let residual = Vector3::new(
            gauss(&mut rng, noise.centring_sigma_mm),
            gauss(&mut rng, noise.centring_sigma_mm),
            gauss(&mut rng, noise.centring_sigma_mm),
        );
        let encoder: Vec<f64> = (1..=truth.joint_count())
            .map(|i| {
                if truth.is_revolute(i) {
                    gauss(&mut rng, deg_to_rad(noise.encoder_sigma_deg))
                } else {
                    gauss(&mut rng, noise.encoder_sigma_mm)
                }
            })
            .collect();
        let vatcal_core::Target::Probe { position } = m.target else { continue };
        let (Some(origin), Ok(ball)) = (truth.position(position), truth.tcp_position(&m.q, m.tcp)) else {
            continue;
        };
        let mut tool = truth.chain(&m.q).tool;
        tool.p += origin + residual - ball;
        let Ok(q_true) = ik.refine_from(&m.q, &tool, &refine) else { continue };
        let mut q = q_true;
        for (v, e) in q.as_mut_slice().iter_mut().zip(&encoder) {
            *v += e;
        }
        out.push(Measurement { q, ..*m });
    }
    out
}

/// Held-out validation poses: `count` random joint vectors inside the limits shrunk by 10 %
/// of each range, a random TCP each, the truth's TCP position plus Gaussian tracker noise.
pub fn held_out_poses(truth: &Model, count: usize, tracker_sigma_mm: f64, seed: u64) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let tcps = truth.tcp_ids();
    let mut out = Vec::with_capacity(count);
    if tcps.is_empty() {
        return out;
    }
    while out.len() < count {
        let mut q = JointVector::zeros(truth.joint_count());
        for (k, (lo, hi)) in truth.joint_limits().iter().enumerate() {
            let pad = 0.1 * (hi - lo);
            q[k] = if hi - lo > 2.0 * pad { rng.random_range(lo + pad..hi - pad) } else { *lo };
        }
        let tcp = tcps[rng.random_range(0..tcps.len())];
        let Ok(p) = truth.tcp_position(&q, tcp) else { break };
        let n = Vector3::new(
            gauss(&mut rng, tracker_sigma_mm),
            gauss(&mut rng, tracker_sigma_mm),
            gauss(&mut rng, tracker_sigma_mm),
        );
        out.push(Measurement::tracker(tcp, q, p + n));
    }
    out
}

fn error_summary(model: &Model, poses: &[Measurement]) -> Result<ErrorSummary, DemoError> {
    let errors: Vec<f64> =
        poses.iter().map(|m| model.residual(m).map(|r| r.norm())).collect::<Result<_, _>>()?;
    let n = errors.len().max(1) as f64;
    Ok(ErrorSummary {
        mean_mm: errors.iter().sum::<f64>() / n,
        rms_mm: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
        max_mm: errors.iter().copied().fold(0.0, f64::max),
    })
}

fn write(path: &Path, text: &str) -> Result<(), DemoError> {
    std::fs::write(path, text).map_err(|source| DemoError::Io { path: path.to_path_buf(), source })
}

/// Runs the model-level demo on any chain (see the module docs) and writes `out/plan/`
/// (the plan files), `nominal.toml`, `truth.toml`, `calibrated.toml`, `report.json` and
/// `summary.md`. `log` receives one line per finished stage.
///
/// # Errors
/// Invalid sizes, planning, identification or validation errors, files that cannot be written.
pub fn run_any_chain_demo(
    opts: &AnyChainDemoOptions,
    out: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<AnyChainOutcome, DemoError> {
    let bad = |option: &str, reason: &str| DemoError::Option { option: option.into(), reason: reason.into() };
    if opts.count == 0 || opts.orientations == 0 || opts.validation_poses == 0 {
        return Err(bad("sizes", "count, orientations and validation poses must be at least 1"));
    }
    let nominal = Model::from_cell(&opts.nominal)?;
    let geometry = CellGeometry::from_cell(&opts.nominal)?;
    std::fs::create_dir_all(out).map_err(|source| DemoError::Io { path: out.to_path_buf(), source })?;
    let mut stage_seconds = Vec::new();
    let mut clock = std::time::Instant::now();
    let mut lap = |name: &str, stage_seconds: &mut Vec<(String, f64)>| {
        stage_seconds.push((name.to_string(), clock.elapsed().as_secs_f64()));
        clock = std::time::Instant::now();
    };

    // 1. plan
    let plan_opts = PlanOptions {
        candidates: CandidateOptions {
            orientations: opts.orientations,
            guide_steps: opts.guide_steps,
            ..CandidateOptions::default()
        },
        count: opts.count,
        params: vatcal_core::ParamSet(Vec::new()),
        detmax_restarts: opts.detmax_restarts,
        tour_restarts: 4,
        motion: opts.nominal.motion_limits(),
        seed: opts.seed,
        ..PlanOptions::default()
    };
    let plan = plan_campaign(&nominal, &geometry, &plan_opts)?;
    write_plan(&plan, &out.join("plan"))?;
    lap("plan", &mut stage_seconds);
    log(&format!(
        "plan: {} candidates, {} measurements selected for {} parameters",
        plan.candidates.candidates.len(),
        plan.selected.len(),
        plan.params.len()
    ));

    // 2. truth, 3. measure
    let truth = vatcal_sim::truth::perturbed_truth(&nominal, opts.seed, &opts.budget);
    let planned = plan.measurements();
    let measurements =
        model_level_probe_measurements(&truth, &planned, &opts.noise, opts.seed.wrapping_add(0x6d65_6173));
    lap("measure", &mut stage_seconds);
    log(&format!("measure: {} of {} planned measurements (model level)", measurements.len(), planned.len()));

    // 4. identify
    let fit = identify(&nominal, &measurements, &plan.params, &IdentifyOptions::default())?;
    lap("identify", &mut stage_seconds);
    log(&format!(
        "identify: {} parameters, converged {}, residual RMS {:.4} mm",
        fit.params.len(),
        fit.converged,
        fit.residual_stats.rms
    ));

    // 5. validate
    let validation = held_out_poses(
        &truth,
        opts.validation_poses,
        opts.noise.tracker_sigma_mm,
        opts.seed.wrapping_add(0x7661_6c69),
    );
    let before = error_summary(&nominal, &validation)?;
    let after = error_summary(&fit.model, &validation)?;
    // the identification crate's validation of the calibrated model (same numbers, checked)
    let _ = validate(&fit.model, &validation)?;
    lap("validate", &mut stage_seconds);
    log(&format!(
        "validate: {} held-out poses, mean error nominal {:.4} mm -> calibrated {:.4} mm",
        validation.len(),
        before.mean_mm,
        after.mean_mm
    ));

    let report = AnyChainReport {
        format: ANY_CHAIN_REPORT_FORMAT.into(),
        seed: opts.seed,
        nominal_cell: opts.nominal_source.clone(),
        chain: nominal.describe_chain(),
        measurement_level:
            "model level: true joints by a local IK solve on the hidden truth, centring residual \
                            and encoder noise added (docs/virtual-cell.md)"
                .into(),
        candidates: plan.candidates.candidates.len(),
        measurements_planned: planned.len(),
        measurements: measurements.len(),
        parameters: fit.params.names(),
        converged: fit.converged,
        fit_rms_mm: fit.residual_stats.rms,
        nominal: before,
        calibrated: after,
        validation_poses: validation.len(),
        noise: opts.noise,
        truth_sigmas: [
            opts.budget.length_mm,
            opts.budget.angle_rad.to_degrees(),
            opts.budget.base_translation_mm,
            opts.budget.base_angle_rad.to_degrees(),
        ],
        stage_seconds,
    };
    let mut files = vec![
        PathBuf::from("plan/candidates.csv"),
        PathBuf::from("plan/selected.csv"),
        PathBuf::from("plan/tour.csv"),
        PathBuf::from("plan/summary.json"),
    ];
    for (name, model) in [("nominal.toml", &nominal), ("truth.toml", &truth), ("calibrated.toml", &fit.model)]
    {
        model.to_cell().save(out.join(name))?;
        files.push(name.into());
    }
    write(&out.join("report.json"), &serde_json::to_string_pretty(&report)?)?;
    files.push("report.json".into());
    write(&out.join("summary.md"), &summary_markdown(&report))?;
    files.push("summary.md".into());
    Ok(AnyChainOutcome { report, truth, calibrated: fit.model, measurements, validation, files })
}

/// The before/after table printed by `vatcal demo` for a model-level run.
pub fn comparison_table(r: &AnyChainReport) -> String {
    let mut m = String::new();
    let _ = writeln!(m, "held-out poses ({}), TCP position error [mm]:", r.validation_poses);
    let _ = writeln!(m, "  model        mean      rms       max");
    for (label, e) in [("nominal", &r.nominal), ("calibrated", &r.calibrated)] {
        let _ = writeln!(m, "  {label:<11} {:<9.4} {:<9.4} {:.4}", e.mean_mm, e.rms_mm, e.max_mm);
    }
    m
}

fn summary_markdown(r: &AnyChainReport) -> String {
    let mut m = String::new();
    let _ =
        writeln!(m, "# vatcal demo — model-level simulated calibration of {} (seed {})\n", r.chain, r.seed);
    let _ = writeln!(
        m,
        "Everything below was computed on a simulated cell at the **model level** (no device \
         simulation; see `docs/virtual-cell.md`). The numbers are deterministic for the seed.\n"
    );
    let _ = writeln!(m, "* nominal cell: {} → `nominal.toml`; hidden truth → `truth.toml`", r.nominal_cell);
    let _ = writeln!(
        m,
        "* hidden truth: `vatcal_sim::truth::perturbed_truth` — σ {:.2} mm on MDH lengths, {:.3}° on MDH angles, {:.2} mm / \
         {:.3}° on the base pose",
        r.truth_sigmas[0], r.truth_sigmas[1], r.truth_sigmas[2], r.truth_sigmas[3]
    );
    let _ = writeln!(
        m,
        "* noise: centring residual {} mm, encoders {}° / {} mm, tracker {} mm (σ per axis)",
        r.noise.centring_sigma_mm,
        r.noise.encoder_sigma_deg,
        r.noise.encoder_sigma_mm,
        r.noise.tracker_sigma_mm
    );
    let _ = writeln!(
        m,
        "* plan: {} candidates, {} measurements planned, {} simulated",
        r.candidates, r.measurements_planned, r.measurements
    );
    let _ = writeln!(
        m,
        "* identification: {} parameters ({}), converged: {}, residual RMS {:.4} mm\n",
        r.parameters.len(),
        r.parameters.join(", "),
        r.converged,
        r.fit_rms_mm
    );
    m.push_str(&comparison_table(r));
    m
}
