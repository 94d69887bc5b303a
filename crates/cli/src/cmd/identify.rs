//! `vatcal identify`: identify model parameters from probe (and/or tracker) measurements and
//! write the calibrated cell file, with an optional JSON report.

use std::path::PathBuf;

use anyhow::{Context, bail};
use vatcal_core::{Measurement, ParamSet};
use vatcal_identification::{
    FailureReport, Identification, IdentificationReport, IdentifyError, IdentifyOptions, IterationLog,
    KindWeights, Method, file_unit_label, identify, to_file_units,
};
use vatcal_kinematics::Model;

/// Arguments of `vatcal identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Starting (nominal) cell model file (TOML, `meca500-zaber-cell` or `serial-robot-cell`).
    #[arg(long)]
    pub model: PathBuf,
    /// Probe measurements: CSV with columns position,tcp,q1..qN for the model's N joints (mm for
    /// prismatic, degrees for revolute joints; the canonical cell: q1 mm, q2..q7 degrees).
    #[arg(long)]
    pub measurements: PathBuf,
    /// Where to write the calibrated cell file (same format as --model).
    #[arg(long)]
    pub out: PathBuf,
    /// Parameters to identify: `default` (`paper34` on the canonical Meca500-on-guide cell,
    /// `all-identifiable` on any other chain), `paper34`, `geometric`, `all-identifiable` (every
    /// model parameter these measurements can identify) or a comma-separated list of names
    /// (e.g. `d_4,theta_offset_2,c_3`).
    #[arg(long, default_value = "default")]
    pub params: String,
    /// Estimation method: `lm` (Levenberg-Marquardt), `gn` (Gauss-Newton) or `paper` (the
    /// paper's Table 7 taken literally, for comparison: it diverges on realistic data).
    #[arg(long, default_value = "lm")]
    pub method: String,
    /// Write the JSON report (parameters in file units, iteration log, statistics) here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Additional tracker measurements: CSV with columns tcp,q1..qN,x,y,z (world, mm).
    #[arg(long)]
    pub tracker: Option<PathBuf>,
    /// Weight of tracker rows relative to probe rows (inverse-variance ratio,
    /// (sigma_probe / sigma_tracker)^2).
    #[arg(long, default_value_t = 1.0)]
    pub tracker_weight: f64,
    /// Iteration cap.
    #[arg(long, default_value_t = 50)]
    pub max_iterations: usize,
    /// Refuse the fit when the condition number of the column-normalised Jacobian at the
    /// solution exceeds this (healthy designs: ~30).
    #[arg(long, default_value_t = 1e3)]
    pub max_condition_number: f64,
    /// Units, limit tolerance and directions of the measurement files.
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
}

/// Runs the identification, prints one line per iteration and a summary, writes the outputs.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(&args.model)?;
    let measurements = read_all(&args, &model)?;
    let method: Method = args.method.parse().map_err(anyhow::Error::msg).context("--method")?;
    let params = resolve_params(&args.params, &model, &measurements)?;
    let options = IdentifyOptions {
        method,
        max_iterations: args.max_iterations,
        max_condition_number: args.max_condition_number,
        weights: KindWeights { probe: 1.0, tracker: args.tracker_weight },
        ..IdentifyOptions::default()
    };
    println!(
        "identifying {} parameters from {} measurements with {method}",
        params.len(),
        measurements.len()
    );
    let fit = match identify(&model, &measurements, &params, &options) {
        Ok(fit) => fit,
        Err(IdentifyError::NotConverged(report)) => {
            print_log(&report.iterations);
            print_failure(&report);
            bail!("{}", IdentifyError::NotConverged(report));
        }
        Err(e) => return Err(e).context(format!("cannot identify from {}", args.measurements.display())),
    };
    print_log(&fit.iterations);
    print_summary(&fit);
    fit.model
        .to_cell()
        .save(&args.out)
        .with_context(|| format!("cannot write the calibrated model to {}", args.out.display()))?;
    println!("calibrated model written to {}", args.out.display());
    if let Some(path) = &args.report {
        IdentificationReport::from_identification(&fit).save(path)?;
        println!("report written to {}", path.display());
    }
    Ok(())
}

fn read_all(args: &Args, model: &Model) -> anyhow::Result<Vec<Measurement>> {
    let mut measurements = args.read.probe(&args.measurements, model)?;
    if let Some(path) = &args.tracker {
        measurements.extend(args.read.tracker(path, model)?);
    }
    Ok(measurements)
}

/// `default`, `paper34`, `geometric`, a name list, or `all-identifiable` (resolved on the data
/// by the identifiability analysis, which is printed).
fn resolve_params(spec: &str, model: &Model, measurements: &[Measurement]) -> anyhow::Result<ParamSet> {
    let set = vatcal_observability::identifiability::param_set_from_spec(spec, model, measurements)
        .with_context(|| format!("--params `{spec}`"))?;
    if spec.trim() == "all-identifiable" || (spec.trim() == "default" && !model.is_meca500_on_guide()) {
        println!("all-identifiable: {}", set.names().join(","));
    }
    Ok(set)
}

fn print_log(log: &[IterationLog]) {
    println!(
        "{:>4}  {:>12}  {:>12}  {:>12}  {:>10}  {:>10}",
        "iter", "mean [mm]", "RMS [mm]", "max [mm]", "lambda", "step"
    );
    for it in log {
        println!(
            "{:>4}  {:>12.6}  {:>12.6}  {:>12.6}  {:>10.3e}  {:>10.3e}",
            it.iteration, it.mean_mm, it.rms_mm, it.max_mm, it.lambda, it.step_norm
        );
    }
}

fn print_failure(report: &FailureReport) {
    if report.method == Method::PaperLiteral {
        eprintln!(
            "note: the paper-literal method sums per-pose pseudo-inverse corrections; it is not a \
             least-squares method (see docs/identification.md). Use --method lm."
        );
    }
}

fn print_summary(fit: &Identification) {
    let s = &fit.residual_stats;
    println!("{}", fit.termination.describe());
    println!("residuals: {}", s.one_line());
    println!(
        "sigma_hat {:.5} mm (dof {}), condition number {:.1} (column-normalised Jacobian)",
        fit.sigma_hat_mm, fit.dof, fit.condition_number
    );
    println!(
        "{:<18} {:>10} {:>16} {:>16} {:>14} {:>12}",
        "parameter", "unit", "nominal", "identified", "delta", "sigma"
    );
    for (k, p) in fit.params.iter().enumerate() {
        let f = |v: f64| to_file_units(*p, v);
        println!(
            "{:<18} {:>10} {:>16.6} {:>16.6} {:>14.6e} {:>12.3e}",
            p.name(),
            file_unit_label(*p),
            f(fit.start_values[k]),
            f(fit.values[k]),
            f(fit.values[k] - fit.start_values[k]),
            f(fit.sigma[k])
        );
    }
    if !fit.strong_correlations.is_empty() {
        let pairs: Vec<String> =
            fit.strong_correlations.iter().map(|(a, b, c)| format!("{a}/{b} {c:+.3}")).collect();
        println!("strongly correlated (|rho| > {}): {}", fit.correlation_threshold, pairs.join(", "));
    }
}
