//! `vatcal discover`: find missing physical effects in a model, add them one at a time, and show
//! how much the gap to the data shrinks (see `docs/discovery.md`).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::effects::EffectKind;
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
    /// Independent validation measurements (e.g. tracker rows), used only to report the gap
    /// (unless `--validation-decides`).
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// Let the `--validation` rows also decide: choose among near-equivalent effects (the one
    /// predicting them significantly better) and refuse additions that make them worse. Off
    /// by default: measured on the discovery benchmark it names fewer hidden effects, and the
    /// reported validation gap is then no longer an independent estimate (docs/discovery.md).
    #[arg(long)]
    pub validation_decides: bool,
    /// Starting parameter set, resolved as by `vatcal identify` (same initialisation of the base
    /// pose and measured TCPs on a chain other than the canonical cell): `default` (`paper34` on
    /// the canonical Meca500-on-guide cell; on any other chain the set chosen by
    /// cross-validation), `registration`, `joint-offsets`, `kinematic`, `paper34`, `geometric`,
    /// `all-identifiable`, or a comma-separated list of parameter names.
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
    /// included in the reported prediction uncertainty; a correction of those coordinates
    /// (an effect driven by the TCP or the position) must change predictions by more than
    /// sqrt(3) times it to be added.
    #[arg(long, default_value_t = 0.002)]
    pub cmm_sigma_mm: f64,
    /// The physical floor of the noise reference, sigma per axis \[mm\]: no reference
    /// (replicates, stated noise, estimate) is taken below it, and no effect whose predictions
    /// change by less than sqrt(3) times it is added (default: 1 um, the resolution of the
    /// finest instrument vatcal reads; 0 switches it off).
    #[arg(long, default_value_t = 0.001)]
    pub noise_floor_mm: f64,
    /// Do not re-examine earlier additions when the forward search stops (the swap check:
    /// one or two added effects are replaced by one or two look-alikes on the data that
    /// predict the held-out points significantly better, or, with fewer parameters, no worse
    /// by more than one standard error; docs/discovery.md).
    #[arg(long)]
    pub no_lookalike_swap: bool,
    /// Do not run the joint search when no single effect and no block passes (all scored
    /// candidates considered together by a cross-validated forward path on the screening half,
    /// the chosen set confirmed together on the confirmation half; docs/discovery.md).
    #[arg(long)]
    pub no_joint_search: bool,
    /// Markers (TCPs) at unknown offsets: the TCP ids the rows use that the cell file lacks,
    /// comma-separated, or `all`; added at TCP 1's offset and fitted as by `vatcal identify
    /// --unknown-tcps`. Without it such rows are an error.
    #[arg(long, value_name = "IDS|all")]
    pub unknown_tcps: Option<String>,
    /// Units, limit tolerance and directions of the measurement files.
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
    /// Propose this many extra probe measurements that would decide the borderline or
    /// ambiguous candidates of the last round (Ds-optimal for their parameters given the
    /// others, from the planner's collision-checked candidates of the cell); needs
    /// `--out-plan`.
    #[arg(long, requires = "out_plan")]
    pub propose: Option<usize>,
    /// Write the proposed measurements here as a plan folder (`vatcal campaign --plan DIR`
    /// runs it), with `proposal.json` (the targeted effects, predicted standard deviations of
    /// their parameters before and after).
    #[arg(long, requires = "propose")]
    pub out_plan: Option<PathBuf>,
    /// Tool orientations per calibration position and TCP sampled for the proposal's
    /// candidate pool.
    #[arg(long, default_value_t = 24)]
    pub propose_orientations: usize,
    /// How many of the last round's undecided candidates (best screening score first) the
    /// proposal is designed to decide; 1 puts all of the measurements' information on the best
    /// one.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..))]
    pub propose_focus: u16,
    /// Plausibility bound of an effect's parameters, `NAME=VALUE` in file units (deg for
    /// angles, mm for lengths), e.g. `--bound joint-backlash=1.0`; repeatable. Overrides the
    /// cell file's `[plausibility_bounds]` table and the bounds scaled to the chain.
    #[arg(long = "bound", value_name = "NAME=VALUE")]
    pub bounds: Vec<String>,
    /// A catalog effect not to propose (e.g. `--exclude-effect link-out-of-plane` to test the
    /// physical effects only); repeatable.
    #[arg(long = "exclude-effect", value_name = "NAME")]
    pub exclude_effects: Vec<String>,
}

fn read_all(
    path: &std::path::Path,
    model: &Model,
    read: &super::read_args::ReadArgs,
) -> anyhow::Result<Vec<Measurement>> {
    let m = read.measurements(path, model)?;
    anyhow::ensure!(!m.is_empty(), "{}: no measurement rows", path.display());
    Ok(m)
}

/// The start model and the starting set: the same initialisation and default choice as
/// `vatcal identify` (`vatcal_identification::prepare_calibration`; the canonical cell with its
/// own sets starts from its nominal model).
fn start_and_parameter_set(
    args: &Args,
    model: &Model,
    measurements: &[Measurement],
) -> anyhow::Result<(Model, ParamSet)> {
    let cv = vatcal_identification::CvOptions { folds: args.folds, seed: args.seed, ..Default::default() };
    let prepared = vatcal_identification::prepare_calibration(
        model,
        measurements,
        &args.params,
        &Default::default(),
        &Default::default(),
        &cv,
    )
    .with_context(|| format!("--params `{}`", args.params))?;
    Ok((prepared.start, prepared.params))
}

fn check_options(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.alpha > 0.0 && args.alpha < 1.0, "--alpha must be in (0, 1), got {}", args.alpha);
    anyhow::ensure!(args.folds >= 2, "--folds must be at least 2, got {}", args.folds);
    anyhow::ensure!(
        args.cmm_sigma_mm.is_finite() && args.cmm_sigma_mm >= 0.0,
        "--cmm-sigma-mm must be >= 0, got {}",
        args.cmm_sigma_mm
    );
    anyhow::ensure!(
        args.noise_floor_mm.is_finite() && args.noise_floor_mm >= 0.0,
        "--noise-floor-mm must be >= 0, got {}",
        args.noise_floor_mm
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
    let (probe_sigma_mm, tracker_sigma_mm, _) = recorded_noise(args)?;
    if probe_sigma_mm.is_none() && tracker_sigma_mm.is_none() {
        return Ok(None);
    }
    let has_probe = measurements.iter().any(|m| matches!(m.target, vatcal_core::Target::Probe { .. }));
    let has_tracker = measurements.iter().any(|m| matches!(m.target, vatcal_core::Target::Tracker { .. }));
    anyhow::ensure!(
        !has_probe || probe_sigma_mm.is_some(),
        "the tracker sigma is known (--tracker-sigma-mm or the file's `# vatcal-noise:` line) but {} holds probe rows: give --probe-sigma-mm too",
        args.measurements.display()
    );
    anyhow::ensure!(
        !has_tracker || tracker_sigma_mm.is_some(),
        "the probe sigma is known (--probe-sigma-mm or the file's `# vatcal-noise:` line) but {} holds tracker rows: give --tracker-sigma-mm too",
        args.measurements.display()
    );
    Ok(Some(vatcal_identification::KindSigmas { probe_mm: probe_sigma_mm, tracker_mm: tracker_sigma_mm }))
}

/// The plausibility-bound overrides: the cell file's optional `[plausibility_bounds]` table
/// (`joint-backlash = 1.0`), then `--bound NAME=VALUE` (which wins).
fn bound_overrides(args: &Args) -> anyhow::Result<BTreeMap<String, f64>> {
    let mut out = BTreeMap::new();
    let cell = vatcal_core::CellFile::load(&args.model)?;
    let mut put = |name: &str, v: f64, what: &str| -> anyhow::Result<()> {
        known_effect(name, what)?;
        anyhow::ensure!(
            v.is_finite() && v > 0.0,
            "{what}: the bound of `{name}` must be a positive number, got {v}"
        );
        out.insert(name.to_string(), v);
        Ok(())
    };
    if let Some(table) = cell.extra.get("plausibility_bounds") {
        let what = format!("{}: [plausibility_bounds]", args.model.display());
        let table = table.as_table().with_context(|| format!("{what} must be a table"))?;
        for (name, v) in table {
            let v = v
                .as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .with_context(|| format!("{what}: `{name}` must be a number"))?;
            put(name, v, &what)?;
        }
    }
    for b in &args.bounds {
        let (name, v) = b.split_once('=').with_context(|| format!("--bound `{b}`: expected NAME=VALUE"))?;
        let v: f64 = v.trim().parse().with_context(|| format!("--bound `{b}`: `{v}` is not a number"))?;
        put(name.trim(), v, "--bound")?;
    }
    Ok(out)
}

/// `--exclude-effect NAME`: catalog names only.
fn excluded_effects(args: &Args) -> anyhow::Result<Vec<String>> {
    for name in &args.exclude_effects {
        known_effect(name, "--exclude-effect")?;
    }
    Ok(args.exclude_effects.clone())
}

/// `Ok` when `name` is a catalog effect's name; the error (prefixed by `what`) lists them.
fn known_effect(name: &str, what: &str) -> anyhow::Result<()> {
    anyhow::ensure!(
        EffectKind::from_name(name).is_some(),
        "{what}: unknown effect `{name}` (catalog names: {})",
        vatcal_core::effects::catalog().iter().map(|e| e.name()).collect::<Vec<_>>().join(", ")
    );
    Ok(())
}

/// The instruments' noise: `--probe-sigma-mm` / `--tracker-sigma-mm`, else what the
/// measurement file records (`# vatcal-noise:`), with where it came from.
fn recorded_noise(args: &Args) -> anyhow::Result<(Option<f64>, Option<f64>, Option<String>)> {
    let meta = vatcal_io::metadata::read_metadata(&args.measurements)?.noise.unwrap_or_default();
    let probe = args.probe_sigma_mm.or(meta.probe_sigma_mm);
    let tracker = args.tracker_sigma_mm.or(meta.tracker_sigma_mm);
    let from_file = (args.probe_sigma_mm.is_none() && meta.probe_sigma_mm.is_some())
        || (args.tracker_sigma_mm.is_none() && meta.tracker_sigma_mm.is_some());
    let from_flags = args.probe_sigma_mm.is_some() || args.tracker_sigma_mm.is_some();
    let origin = match (from_flags, from_file) {
        (true, true) => Some(format!(
            "--probe-sigma-mm/--tracker-sigma-mm and the `# vatcal-noise:` line of {}",
            args.measurements.display()
        )),
        (true, false) => Some("--probe-sigma-mm/--tracker-sigma-mm".to_string()),
        (false, true) => Some(format!("recorded in {} (`# vatcal-noise:`)", args.measurements.display())),
        (false, false) => None,
    };
    Ok((probe, tracker, origin))
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
    for h in &d.bound_hits {
        writeln!(
            out,
            "refused at a plausibility bound (round {}, held-out z = {:.1}): {}; if the bound is wrong for this robot, set it with --bound {}=VALUE",
            h.round, h.heldout_z, h.reason, h.effect
        )?;
    }
    if let Some(last) = d.rounds.last() {
        for c in last.candidates.iter().filter(|c| c.detectability.is_some()).take(5) {
            if let Some(p) = &c.detectability {
                writeln!(out, "undecided: {}: {}", c.label, p.sentence())?;
            }
        }
    }
    writeln!(out, "{}", d.noise.explanation)?;
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
    let mut cell = vatcal_core::CellFile::load(&args.model)?;
    let model = super::model_of(&cell, &args.model)?;
    let (measurements, sources) = args.read.markers_with_sources(&args.measurements, &model)?;
    anyhow::ensure!(!measurements.is_empty(), "{}: no measurement rows", args.measurements.display());
    // issue 31: TCP ids the rows use that the cell lacks are markers at unknown offsets
    let (model, _markers) = super::markers::model_with_unknown_tcps(
        &mut cell,
        model,
        &args.model,
        args.unknown_tcps.as_deref(),
        &measurements,
        &sources,
    )?;
    let validation = args.validation.as_ref().map(|p| read_all(p, &model, &args.read)).transpose()?;
    let (model, params) = start_and_parameter_set(&args, &model, &measurements)?;
    let options = DiscoverOptions {
        alpha: args.alpha,
        folds: args.folds,
        seed: args.seed,
        known_sigma_mm: args.noise_mm,
        cmm_sigma_mm: args.cmm_sigma_mm,
        noise_floor_mm: args.noise_floor_mm,
        lookalike_swap: !args.no_lookalike_swap,
        validation_decides: args.validation_decides,
        joint_search: !args.no_joint_search,
        instrument_sigmas: instrument_sigmas(&args, &measurements)?,
        instrument_noise_origin: recorded_noise(&args)?.2,
        bound_overrides: bound_overrides(&args)?,
        excluded_effects: excluded_effects(&args)?,
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
    if let (Some(count), Some(dir)) = (args.propose, &args.out_plan) {
        propose_plan(&args, &d, &measurements, count, dir)?;
    }
    Ok(())
}

/// `--propose N --out-plan DIR`: the measurements that decide the last round's borderline or
/// rival candidates, planned as a campaign on the cell (`vatcal_pipeline::discovery_loop::
/// propose_plan`, the same the demo's measurement loop runs).
fn propose_plan(
    args: &Args,
    d: &Discovery,
    measurements: &[Measurement],
    count: usize,
    dir: &std::path::Path,
) -> anyhow::Result<()> {
    use vatcal_planning::candidates::CandidateOptions;
    use vatcal_planning::plan::PlanOptions;
    anyhow::ensure!(count > 0, "--propose must be at least 1");
    let focus = vatcal_discovery::propose::focus_effects(d, measurements, usize::from(args.propose_focus));
    if focus.is_empty() {
        println!("proposal: nothing to decide (the last round scored no candidate); no plan written");
        return Ok(());
    }
    let cell = vatcal_core::CellFile::load(&args.model)?;
    let geometry = vatcal_planning::geometry::CellGeometry::from_cell(&cell)
        .with_context(|| format!("{}", args.model.display()))?;
    let opts = PlanOptions {
        candidates: CandidateOptions {
            orientations: args.propose_orientations,
            progress: false,
            ..CandidateOptions::default()
        },
        count,
        params: d.params.clone(),
        motion: cell.motion_limits(),
        seed: args.seed,
        ..PlanOptions::default()
    };
    let proposed = vatcal_pipeline::discovery_loop::propose_plan(
        d,
        measurements,
        &focus,
        &d.model,
        &geometry,
        &opts,
        None,
    )
    .context("proposing measurements")?;
    let proposal = &proposed.proposal;
    let summary = vatcal_planning::output::write_plan(&proposed.plan, dir)?;
    let json = serde_json::to_string_pretty(proposal)?;
    std::fs::write(dir.join("proposal.json"), json)
        .with_context(|| format!("writing {}", dir.join("proposal.json").display()))?;
    println!(
        "proposal: {} measurements to decide {} (from {} candidate poses); predicted sigma of {}: {} -> {} (per unit noise); plan written to {}",
        proposal.selected.len(),
        proposal.focus.join(" / "),
        proposed.pool,
        proposal.focus_params.join(", "),
        fmt_list(&proposal.std_before),
        fmt_list(&proposal.std_after),
        dir.display()
    );
    println!("{}", summary.text());
    Ok(())
}

fn fmt_list(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>().join(", ")
}
