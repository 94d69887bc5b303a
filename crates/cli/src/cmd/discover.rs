//! `vatcal discover`: find missing physical effects in a model, add them one at a time, and show
//! how much the gap to the data shrinks (see `docs/discovery.md`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::{Measurement, ParamSet};
use vatcal_discovery::{DiscoverOptions, Discovery, discover, write_effect_plots};
use vatcal_kinematics::Model;

/// Arguments of `vatcal discover`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model file (TOML) to start from (usually the nominal cell).
    #[arg(long)]
    pub model: PathBuf,
    /// Measurements to fit: probe rows (`position,tcp,q1..qN`) and/or tracker rows
    /// (`tcp,q1..qN,x,y,z`), N = the model's joints; optional `time_s`, `temperature_c`, `dir{i}`
    /// (revolute joints i) columns enable the drift and backlash candidates.
    #[arg(long)]
    pub measurements: PathBuf,
    /// Independent validation measurements (e.g. tracker rows), used only to report the gap.
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// Starting parameter set: `default` (`paper34` on the canonical Meca500-on-guide cell,
    /// `all-identifiable` on any other chain), `paper34`, `geometric`, `all-identifiable`, or a
    /// comma-separated list of parameter names.
    #[arg(long, default_value = "default")]
    pub params: String,
    /// Write the final model (with the added effects) here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the full report (JSON) here, and beside it the same name with `.html`: one
    /// self-contained page (plots inline) readable offline in a browser.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write one SVG per added effect (residual vs its driving variable, before/after) here.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Seed of the cross-validation folds.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Family-wise false-alarm probability of the screening over all rounds: round r spends
    /// `alpha·6/(π² r²)`, shared by its candidates (Bonferroni), so the total over every round
    /// stays below alpha.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Number of cross-validation folds.
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Known measurement noise per axis \[mm\]; by default it is estimated from each fit.
    #[arg(long)]
    pub noise_mm: Option<f64>,
    /// The probe's known measurement noise, σ per axis of a probe row \[mm\] (device
    /// specifications: robot and guide repeatability and gauge error). With
    /// `--tracker-sigma-mm` (or alone, on probe-only data) the size rule compares an effect's
    /// prediction change with it instead of the fit's σ̂, which unmodelled effects inflate.
    #[arg(long)]
    pub probe_sigma_mm: Option<f64>,
    /// The tracker's known measurement noise, σ per axis of a tracker row \[mm\]; with both
    /// sigmas the probe and tracker rows are weighted by them.
    #[arg(long)]
    pub tracker_sigma_mm: Option<f64>,
    /// Standard deviation of the CMM coordinates of the TCPs and calibration positions \[mm\],
    /// included in the reported prediction uncertainty.
    #[arg(long, default_value_t = 0.002)]
    pub cmm_sigma_mm: f64,
}

fn read_all(path: &PathBuf, model: &Model) -> anyhow::Result<Vec<Measurement>> {
    let m = vatcal_io::read_measurements(path, model)?;
    anyhow::ensure!(!m.is_empty(), "{}: no measurement rows", path.display());
    Ok(m)
}

fn parameter_set(spec: &str, model: &Model, measurements: &[Measurement]) -> anyhow::Result<ParamSet> {
    vatcal_observability::identifiability::param_set_from_spec(spec, model, measurements)
        .with_context(|| format!("--params `{spec}`"))
}

fn check_options(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.alpha > 0.0 && args.alpha < 1.0, "--alpha must be in (0, 1), got {}", args.alpha);
    anyhow::ensure!(args.folds >= 2, "--folds must be at least 2, got {}", args.folds);
    anyhow::ensure!(
        args.cmm_sigma_mm.is_finite() && args.cmm_sigma_mm >= 0.0,
        "--cmm-sigma-mm must be >= 0, got {}",
        args.cmm_sigma_mm
    );
    for (option, value) in [
        ("--noise-mm", args.noise_mm),
        ("--probe-sigma-mm", args.probe_sigma_mm),
        ("--tracker-sigma-mm", args.tracker_sigma_mm),
    ] {
        if let Some(s) = value {
            anyhow::ensure!(s.is_finite() && s > 0.0, "{option} must be a positive number, got {s}");
        }
    }
    Ok(())
}

/// The instruments' known noise from `--probe-sigma-mm` / `--tracker-sigma-mm`; the sigma of
/// a kind the data holds must be given when the other one is (else the size rule would mix a
/// known σ with an estimated one).
fn instrument_sigmas(
    args: &Args,
    measurements: &[Measurement],
) -> anyhow::Result<Option<vatcal_identification::KindSigmas>> {
    if args.probe_sigma_mm.is_none() && args.tracker_sigma_mm.is_none() {
        return Ok(None);
    }
    let has_probe = measurements.iter().any(|m| matches!(m.target, vatcal_core::Target::Probe { .. }));
    let has_tracker = measurements.iter().any(|m| matches!(m.target, vatcal_core::Target::Tracker { .. }));
    anyhow::ensure!(
        !has_probe || args.probe_sigma_mm.is_some(),
        "--tracker-sigma-mm given but {} holds probe rows: give --probe-sigma-mm too",
        args.measurements.display()
    );
    anyhow::ensure!(
        !has_tracker || args.tracker_sigma_mm.is_some(),
        "--probe-sigma-mm given but {} holds tracker rows: give --tracker-sigma-mm too",
        args.measurements.display()
    );
    Ok(Some(vatcal_identification::KindSigmas {
        probe_mm: args.probe_sigma_mm,
        tracker_mm: args.tracker_sigma_mm,
    }))
}

fn print_text(out: &mut impl Write, d: &Discovery) -> std::io::Result<()> {
    for round in &d.rounds {
        let driver = round
            .location
            .first()
            .map(|s| format!("; residual depends most on {}", s.sentence()))
            .unwrap_or_default();
        writeln!(
            out,
            "round {}: {} parameters, RMS residual {:.4} mm{driver}",
            round.index,
            round.fit.params.len(),
            round.fit.fit_errors.rms
        )?;
        writeln!(out, "  {}", round.decision)?;
    }
    for n in &d.negligible_effects {
        writeln!(
            out,
            "detected, negligible ({:.1} um): {} (round {}, not added)",
            n.change_um, n.label, n.round
        )?;
    }
    for x in &d.removed_effects {
        writeln!(
            out,
            "removed by the backward check in round {}: {} (added in round {})",
            x.removed_in_round, x.label, x.added_in_round
        )?;
    }
    for note in &d.notes {
        writeln!(out, "note: {note}")?;
    }
    if let Some(u) = &d.uncertainty {
        writeln!(
            out,
            "predicted TCP uncertainty ({} {} poses): mean |sigma| {:.4} mm statistical, {:.4} mm with {:.4} mm CMM errors",
            u.count, u.poses, u.statistical_mean_mm, u.with_cmm_mean_mm, u.cmm_sigma_mm
        )?;
    }
    let names: Vec<&str> = d.added_effects.iter().map(|a| a.label.as_str()).collect();
    writeln!(
        out,
        "result: {} effect(s) added{}; gap ({}) {:.4} -> {:.4} mm",
        names.len(),
        if names.is_empty() { String::new() } else { format!(" ({})", names.join(", ")) },
        d.final_gap.headline_name(),
        d.initial_gap_mm,
        d.final_gap_mm
    )
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    check_options(&args)?;
    let model = super::load_model(&args.model)?;
    let measurements = read_all(&args.measurements, &model)?;
    let validation = args.validation.as_ref().map(|p| read_all(p, &model)).transpose()?;
    let params = parameter_set(&args.params, &model, &measurements)?;
    let options = DiscoverOptions {
        alpha: args.alpha,
        folds: args.folds,
        seed: args.seed,
        known_sigma_mm: args.noise_mm,
        cmm_sigma_mm: args.cmm_sigma_mm,
        instrument_sigmas: instrument_sigmas(&args, &measurements)?,
        ..DiscoverOptions::default()
    };
    let d = discover(&model, &measurements, &params, validation.as_deref(), &options)?;
    print_text(&mut std::io::stdout().lock(), &d)?;
    if let Some(path) = &args.out {
        d.model
            .to_cell()
            .save(path)
            .with_context(|| format!("writing the final model to {}", path.display()))?;
    }
    if let Some(path) = &args.report {
        let json = serde_json::to_string_pretty(&d)?;
        std::fs::write(path, json).with_context(|| format!("writing the report to {}", path.display()))?;
        let html_path = if path.extension().is_some_and(|e| e == "html") {
            path.with_extension("report.html")
        } else {
            path.with_extension("html")
        };
        vatcal_discovery::html_report(&d)
            .and_then(|h| h.save(&html_path))
            .with_context(|| format!("writing the HTML report to {}", html_path.display()))?;
    }
    if let Some(dir) = &args.plots {
        write_effect_plots(&d, dir).with_context(|| format!("writing plots to {}", dir.display()))?;
    }
    Ok(())
}
