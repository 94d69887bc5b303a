//! `vatcal validate`: position errors of a model (and optionally a baseline model) on tracker
//! measurements, with a before/after histogram and a JSON report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use vatcal_identification::{ErrorStats, ValidationReport, validate};
use vatcal_report::{HistogramOptions, PlotSpec, Series, histogram_svg, save_svg};

/// Arguments of `vatcal validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model to validate (e.g. the calibrated cell file).
    #[arg(long)]
    pub model: PathBuf,
    /// Optional baseline model to compare with (e.g. the nominal cell file).
    #[arg(long)]
    pub baseline: Option<PathBuf>,
    /// Validation measurements: CSV with tracker rows tcp,q1..qN,x,y,z (N = the model's joints;
    /// world, mm), probe rows position,tcp,q1..qN (error = the model's position − FK), or both
    /// (a row with an empty `position` is a tracker row), and the optional context columns time_s, temperature_c, dir{i} for revolute joints i
    /// (applied to the models' effects; required when a model has backlash or thermal drift).
    #[arg(long)]
    pub tracker: PathBuf,
    /// Write a histogram of the error magnitudes (baseline and model) as SVG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the statistics and every error vector as JSON.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Number of histogram bins.
    #[arg(long, default_value_t = 40)]
    pub bins: usize,
    /// Units, limit tolerance and directions of the measurement file.
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
}

/// One validated model in the JSON report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ValidatedModel {
    /// the cell file
    pub model_file: String,
    /// errors and statistics
    pub validation: ValidationReport,
}

/// The JSON report of `vatcal validate`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ValidateOutput {
    /// the validation measurements
    pub tracker_file: String,
    /// the model under test
    pub model: ValidatedModel,
    /// the baseline, if given
    pub baseline: Option<ValidatedModel>,
    /// baseline mean error / model mean error, if a baseline was given
    pub mean_improvement_factor: Option<f64>,
}

/// Validates the model(s), prints the statistics, writes the plot and the report.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(&args.model)?;
    let tracker = args.read.measurements(&args.tracker, &model)?;
    let tested =
        validate(&model, &tracker).with_context(|| format!("validating {}", args.model.display()))?;
    let baseline = match &args.baseline {
        Some(path) => {
            let base = super::load_model(path)?;
            // read again with the baseline: checks the context columns its effects need
            let tracker =
                vatcal_io::read_measurements_with(&args.tracker, &base, &args.read.options()?)?.rows;
            Some((path, validate(&base, &tracker).with_context(|| format!("validating {}", path.display()))?))
        }
        None => None,
    };
    println!("{} validation measurements from {}", tracker.len(), args.tracker.display());
    print_header();
    if let Some((path, v)) = &baseline {
        print_row(&label("baseline", path), &v.stats);
    }
    print_row(&label("model", &args.model), &tested.stats);
    let factor = baseline.as_ref().map(|(_, b)| b.stats.mean / tested.stats.mean.max(f64::MIN_POSITIVE));
    if let Some(f) = factor {
        println!("mean error reduced by a factor of {f:.1}");
    }
    if let Some(path) = &args.plot {
        write_histogram(path, &args, &tested, baseline.as_ref().map(|(_, b)| b))?;
        println!("histogram written to {}", path.display());
    }
    if let Some(path) = &args.report {
        let out = ValidateOutput {
            tracker_file: args.tracker.display().to_string(),
            model: ValidatedModel { model_file: args.model.display().to_string(), validation: tested },
            baseline: baseline
                .map(|(p, v)| ValidatedModel { model_file: p.display().to_string(), validation: v }),
            mean_improvement_factor: factor,
        };
        let text = serde_json::to_string_pretty(&out)?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    Ok(())
}

fn label(role: &str, path: &Path) -> String {
    let name =
        path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    format!("{role} ({name})")
}

fn print_header() {
    println!(
        "{:<32} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9}   {:>27}   {:>27}",
        "[mm]", "n", "mean", "RMS", "median", "95%", "max", "mean x / y / z", "RMS x / y / z"
    );
}

fn print_row(name: &str, s: &ErrorStats) {
    let [mx, my, mz] = s.axis_mean;
    let [rx, ry, rz] = s.axis_rms;
    println!(
        "{name:<32} {:>5} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}   {mx:>+8.4} {my:>+8.4} {mz:>+8.4}   {rx:>8.4} {ry:>8.4} {rz:>8.4}",
        s.n, s.mean, s.rms, s.median, s.p95, s.max
    );
}

fn write_histogram(
    path: &Path,
    args: &Args,
    tested: &ValidationReport,
    baseline: Option<&ValidationReport>,
) -> anyhow::Result<()> {
    let tested_values = tested.magnitudes();
    let baseline_values = baseline.map(ValidationReport::magnitudes);
    let tested_label = label("model", &args.model);
    let baseline_label = args.baseline.as_deref().map(|p| label("baseline", p)).unwrap_or_default();
    let mut series = Vec::new();
    if let Some(values) = &baseline_values {
        series.push(Series::new(&baseline_label, values));
    }
    series.push(Series::new(&tested_label, &tested_values));
    let spec =
        PlotSpec::new("Position error on validation poses", "position error [mm]", "share of poses [%]");
    let svg =
        histogram_svg(&spec, &series, &HistogramOptions { bins: args.bins, ..HistogramOptions::default() })?;
    save_svg(path, &svg)?;
    Ok(())
}
