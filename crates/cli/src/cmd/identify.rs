//! `vatcal identify`: identify model parameters from probe and/or tracker measurements (and
//! known distances between fixed points) and write the calibrated cell file, with an optional
//! JSON report. The library call is `vatcal_identification::calibrate`.

use std::path::PathBuf;

use anyhow::{Context, bail};
use vatcal_core::training_range::TrainingRange;
use vatcal_core::{Measurement, Target};
use vatcal_identification::{
    BadRowReport, BadRowsReport, DroppedRow, RobustFit, RobustLoss, RobustOptions, RobustReport,
    SIGMA_ESTIMATOR, calibrate_dropping_outliers, calibrate_robust, flag_outliers,
};
use vatcal_identification::{
    Calibration, CvOptions, CvSelection, ErrorStats, FailureReport, FittedScatter, Identification,
    IdentificationReport, IdentifyError, IdentifyOptions, IterationLog, KindWeights, Method, PriorKind,
    PriorOverride, PriorWidths, calibrate, file_unit_label, fit_with_fitted_scatter, to_file_units,
};
use vatcal_io::RowSource;
use vatcal_kinematics::Model;
use vatcal_observability::sets::DataDesign;

/// Arguments of `vatcal identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Starting (nominal) cell model file (TOML, `meca500-zaber-cell` or `serial-robot-cell`).
    #[arg(long)]
    pub model: PathBuf,
    /// Measurements: CSV with probe rows (position,tcp,q1..qN), tracker rows (tcp,q1..qN,x,y,z,
    /// world mm) or both (a row with an empty `position` is a tracker row); joints in mm for
    /// prismatic, degrees for revolute joints (the canonical cell: q1 mm, q2..q7 degrees). Or
    /// pose rows: tracker rows plus the tool body's rotation (qw,qx,qy,qz / rx,ry,rz /
    /// roll,pitch,yaw / `euler_<seq>_1..3`; see docs/formats.md).
    #[arg(long)]
    pub measurements: Option<PathBuf>,
    /// Where to write the calibrated cell file (same format as --model).
    #[arg(long)]
    pub out: PathBuf,
    /// Parameters to identify: `default` (`paper34` on the canonical Meca500-on-guide cell; on
    /// any other chain the set among registration, joint-offsets, kinematic and
    /// kinematic+compliance chosen by cross-validation), `registration` (base pose + measured
    /// TCPs + unknown points), `joint-offsets`, `kinematic`, `kinematic+compliance`,
    /// `all-identifiable`, `paper34` and `geometric` (canonical cell only) or a comma-separated
    /// list of names (e.g. `d_4,theta_offset_2,c_3`).
    #[arg(long, default_value = "default")]
    pub params: String,
    /// Estimation method: `lm` (Levenberg-Marquardt), `gn` (Gauss-Newton) or `paper` (the
    /// paper's Table 7 taken literally, for comparison: it diverges on realistic data).
    #[arg(long, default_value = "lm")]
    pub method: String,
    /// Write the JSON report (parameters in file units, iteration log, statistics) here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// More measurements: CSV with tracker rows tcp,q1..qN,x,y,z (world, mm), probe rows, or both.
    #[arg(long)]
    pub tracker: Option<PathBuf>,
    /// Weight of tracker rows relative to probe rows (inverse-variance ratio,
    /// (sigma_probe / sigma_tracker)^2).
    #[arg(long, default_value_t = 1.0)]
    pub tracker_weight: f64,
    /// Weight of the orientation half of pose rows relative to probe rows, in mm²/rad²:
    /// (sigma_probe in mm / sigma_orientation in rad)^2, e.g. 100 puts 0.01 mm against 1 mrad.
    /// Without it the weight is fitted: fit with 100, estimate the scatter of each kind from
    /// the residuals, refit with the weight it calls for, until it settles (at most 3 fits).
    #[arg(long)]
    pub orientation_weight: Option<f64>,
    /// Calibration positions (fixed points) whose coordinates are unknown and identified with
    /// the rest: a comma-separated list of ids (a position the cell file lacks is added) or
    /// `all` (every position of the cell file).
    #[arg(long)]
    pub unknown_positions: Option<String>,
    /// Markers (TCPs) at unknown offsets, e.g. several points of one tracked body: a
    /// comma-separated list of the TCP ids the rows use that the cell file lacks (added at TCP
    /// 1's offset, placed by the initialisation, identified with the rest), or `all` (every such
    /// id). Without it such rows are an error, and so is a listed id the cell file has.
    #[arg(long, value_name = "IDS|all")]
    pub unknown_tcps: Option<String>,
    /// A known distance between two fixed points, `A,B,MM` or `A,B,MM,SIGMA_MM` (default sigma
    /// 0.01 mm, the fixture's): a measurement of its own that fixes the scale, weighed against
    /// the data rows by their own fitted scatter. Repeatable.
    #[arg(long = "point-distance")]
    pub point_distances: Vec<String>,
    /// A known distance between two parallel contact planes of plane rows, `A,B,MM` or
    /// `A,B,MM,SIGMA_MM` (plane B lies MM above plane A along their common normal, e.g. a gauge
    /// block's top face on a table; default sigma 0.01 mm, also of their parallelism over
    /// 100 mm): fixes the scale plane rows alone leave free. Repeatable.
    #[arg(long = "plane-distance", value_name = "A,B,MM[,SIGMA_MM]")]
    pub plane_distances: Vec<String>,
    /// `--params default` on a chain other than the canonical cell: number of folds of the
    /// cross-validation that chooses the prior scale (posture groups dealt into K folds; K at
    /// least the number of postures: leave-one-posture-out).
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Repetitions of the K-fold split, each with its own shuffle (repeated K-fold).
    #[arg(long, default_value_t = 3)]
    pub cv_repeats: usize,
    /// Seed of the cross-validation's first shuffle.
    #[arg(long, default_value_t = 1)]
    pub cv_seed: u64,
    /// Priors toward the nominal values at this multiple of the realistic widths (10 mrad joint
    /// zeros, 1 mm lengths, 3 mrad twists and tilts, 2 mrad of gravity deflection;
    /// docs/identification.md). With `--params default` on another chain the scale is otherwise
    /// chosen by cross-validation among 0.1, 0.3, 1, 3, 10 and 30; with any other `--params`
    /// it adds priors to that set (none without it or --prior).
    #[arg(long)]
    pub prior_scale: Option<f64>,
    /// The prior width of one kind of parameter at scale 1, with its unit: e.g.
    /// `theta_offset=50mrad`, `length=0.5mm`, `alpha=0.1deg`, `beta=2mrad`,
    /// `compliance=1mrad` (deflection at the joint's largest gravity torque),
    /// `prismatic_offset=2mm`, `tcp=free`. Repeatable; with a named `--params` and no
    /// --prior-scale the scale is 1.
    #[arg(long = "prior", value_name = "KIND=WIDTH")]
    pub priors: Vec<String>,
    /// Iteration cap.
    #[arg(long, default_value_t = 50)]
    pub max_iterations: usize,
    /// Refuse the fit when the condition number of the column-normalised Jacobian at the
    /// solution exceeds this (healthy designs: ~30). Not applied to a set chosen by
    /// cross-validation (reported instead).
    #[arg(long, default_value_t = 1e3)]
    pub max_condition_number: f64,
    /// After the fit, name the rows (file:line) whose residual norm is beyond K robust sigma
    /// (sigma = median residual norm / 1.5382, the median of a 3-D Gaussian's norm); they are
    /// kept in the fit unless --robust or --drop-outliers says otherwise.
    #[arg(long, value_name = "K", default_value_t = vatcal_identification::DEFAULT_OUTLIER_K)]
    pub outlier_k: f64,
    /// Down-weight bad rows: iteratively reweighted least squares with the `huber` (c = 1.345)
    /// or `cauchy` (c = 2.385) weights, c in robust sigma.
    #[arg(long, value_name = "LOSS", conflicts_with = "drop_outliers")]
    pub robust: Option<String>,
    /// Remove the rows beyond K robust sigma and calibrate again on the rows kept (the
    /// parameter set's choice included), until no kept row is beyond (at most 5 rounds).
    #[arg(long, value_name = "K")]
    pub drop_outliers: Option<f64>,
    /// Units, limit tolerance and directions of the measurement files.
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
}

/// What the fit knows beyond the rows: the unknown fixed points and planes, the known distances
/// (`--point-distance`, `--plane-distance`), checked against the model.
fn data_design(
    args: &Args,
    model: &Model,
    free_positions: Vec<u32>,
    free_planes: Vec<u32>,
) -> anyhow::Result<DataDesign> {
    let distances = super::planes::point_distances(&args.point_distances)?;
    let design = DataDesign {
        free_positions,
        distances,
        free_planes,
        plane_distances: super::planes::plane_distances(&args.plane_distances)?,
    };
    design.check(model).context("--point-distance / --plane-distance / --unknown-positions")?;
    Ok(design)
}

/// Runs the identification, prints one line per iteration and a summary, writes the outputs.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut cell = vatcal_core::CellFile::load(&args.model)?;
    let free_positions = add_unknown_positions(&mut cell, args.unknown_positions.as_deref())?;
    let model = super::model_of(&cell, &args.model)?;
    let (measurements, sources) = read_all(&args, &model)?;
    // issue 31: TCP ids the rows use that the cell lacks are markers at unknown offsets
    let (model, markers) = super::markers::model_with_unknown_tcps(
        &mut cell,
        model,
        &args.model,
        args.unknown_tcps.as_deref(),
        &measurements,
        &sources,
    )?;
    // plane rows: planes the cell lacks are identified
    let (model, free_planes) =
        super::planes::model_with_unknown_planes(&mut cell, model, &args.model, &measurements)?;
    let model = with_tool_rotation(model, &measurements)?;
    let method: Method = args.method.parse().map_err(anyhow::Error::msg).context("--method")?;
    let design = data_design(&args, &model, free_positions, free_planes)?;
    let options = IdentifyOptions {
        method,
        max_iterations: args.max_iterations,
        max_condition_number: args.max_condition_number,
        weights: KindWeights {
            probe: 1.0,
            tracker: args.tracker_weight,
            orientation: stated_orientation_weight(&args, &measurements)?
                .unwrap_or(KindWeights::DEFAULT_ORIENTATION),
            plane: 1.0,
        },
        ..IdentifyOptions::default()
    };
    let cv = cv_options(&args)?;
    let source = [&args.measurements, &args.tracker]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" + ");
    println!(
        "identifying `{}` from {} with {method}",
        args.params.trim(),
        row_counts(&measurements, design.distances.len() + design.plane_distances.len())
    );
    let bad_rows = BadRowArgs::of(&args)?;
    let fitted = calibrate_weighed(&args, &bad_rows, &model, &measurements, &design, &options, &cv);
    let ((cal, handling), scatter) = match fitted {
        Ok(fitted) => fitted,
        Err(IdentifyError::NotConverged(report)) => {
            print_log(&report.iterations);
            print_failure(&report);
            bail!("{}", IdentifyError::NotConverged(report));
        }
        Err(e) => return Err(e).context(format!("cannot identify from {source}")),
    };
    if let Some(init) = &cal.init {
        println!(
            "initialisation: RMS residual {:.4} mm (nominal) -> {:.4} mm after {} round(s) ({})",
            init.rms_before_mm,
            init.rms_after_mm,
            init.rounds,
            if init.registered {
                "base pose registered, measured TCPs and unknown points solved"
            } else {
                "measured TCPs, unknown points and planes solved; the base pose is absorbed by the points or planes"
            }
        );
    }
    match &cal.selection {
        Some(sel) => print_selection(sel),
        None if args.params.trim() != "paper34" && cal.init.is_some() => {
            println!("{}: {}", args.params.trim(), cal.params.names().join(","));
        }
        None if args.params.trim() == "all-identifiable" => {
            println!("all-identifiable: {}", cal.params.names().join(","));
        }
        None => {}
    }
    let fit = &cal.fit;
    print_log(&fit.iterations);
    print_summary(fit, &cal.prior_sigmas, &handling.kept_rows(&measurements));
    if let Some(s) = &scatter {
        println!("{}", s.one_line());
    }
    print_markers(fit, &measurements, &markers);
    print_weak_directions(&cal);
    if cal.selection.is_some() && fit.condition_number > args.max_condition_number {
        println!(
            "note: condition number {:.3e} above {:.0e}: accepted because the set was chosen by cross-validation; combinations the data barely see are only trustworthy near the training postures (--prior-scale keeps them near nominal)",
            fit.condition_number, args.max_condition_number
        );
    }
    // issue 29: the bad rows, and the joint range of the rows the fit used
    let bad_report = report_bad_rows(&bad_rows, &handling, fit, &measurements, &sources, &options.weights)?;
    // a pose row's orientation measurement repeats its tracker measurement's posture
    let fitted_rows = handling.kept_rows(&measurements);
    let postures = fitted_rows.iter().filter(|m| !m.target.is_orientation()).map(|m| &m.q);
    let training_range = TrainingRange::from_postures(model.joint_kinds(), postures);
    print_training_range(training_range.as_ref(), model.joint_kinds());
    let mut calibrated = fit.model.to_cell();
    calibrated.training_range = training_range.clone();
    calibrated
        .save(&args.out)
        .with_context(|| format!("cannot write the calibrated model to {}", args.out.display()))?;
    println!("calibrated model written to {}", args.out.display());
    if let Some(path) = &args.report {
        let mut report = IdentificationReport::from_calibration(&cal);
        report.bad_rows = Some(bad_report);
        report.training_range = training_range;
        report.fitted_scatter = scatter;
        report.save(path)?;
        println!("report written to {}", path.display());
    }
    Ok(())
}

/// What `--outlier-k`, `--robust` and `--drop-outliers` ask for.
struct BadRowArgs {
    k: f64,
    robust: Option<RobustOptions>,
    drop_k: Option<f64>,
}

impl BadRowArgs {
    fn of(args: &Args) -> anyhow::Result<Self> {
        let positive = |flag: &str, k: f64| -> anyhow::Result<f64> {
            anyhow::ensure!(k.is_finite() && k > 0.0, "{flag} must be a positive number, got {k}");
            Ok(k)
        };
        let robust = match &args.robust {
            Some(text) => {
                let loss: RobustLoss = text.parse().map_err(anyhow::Error::msg).context("--robust")?;
                Some(RobustOptions::new(loss))
            }
            None => None,
        };
        Ok(Self {
            k: positive("--outlier-k", args.outlier_k)?,
            robust,
            drop_k: args.drop_outliers.map(|k| positive("--drop-outliers", k)).transpose()?,
        })
    }
}

/// How the bad rows were handled in the final fit.
enum Handling {
    /// flagged and kept (the default)
    Kept,
    /// down-weighted (`--robust`)
    Robust(Box<RobustFit>),
    /// removed before the final calibration (`--drop-outliers`)
    Dropped { kept: Vec<usize>, dropped: Vec<DroppedRow>, rounds: usize },
}

impl Handling {
    /// Indices (into all rows) of the rows of the final fit.
    fn kept_indices(&self, n: usize) -> Vec<usize> {
        match self {
            Handling::Dropped { kept, .. } => kept.clone(),
            _ => (0..n).collect(),
        }
    }

    /// The rows of the final fit.
    fn kept_rows(&self, rows: &[Measurement]) -> Vec<Measurement> {
        self.kept_indices(rows.len()).into_iter().map(|i| rows[i]).collect()
    }
}

/// The calibration of `vatcal identify`: `calibrate` (default), the robust fit or the
/// calibration on the rows kept after dropping the bad ones.
fn calibrate_rows(
    bad: &BadRowArgs,
    model: &Model,
    rows: &[Measurement],
    spec: &str,
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
) -> Result<(Calibration, Handling), IdentifyError> {
    if let Some(robust) = &bad.robust {
        let r = calibrate_robust(model, rows, spec, design, options, cv, robust)?;
        return Ok((r.calibration, Handling::Robust(Box::new(r.robust))));
    }
    if let Some(k) = bad.drop_k {
        let d = calibrate_dropping_outliers(model, rows, spec, design, options, cv, k)?;
        let handling = Handling::Dropped { kept: d.kept, dropped: d.dropped, rounds: d.rounds };
        return Ok((d.calibration, handling));
    }
    Ok((calibrate(model, rows, spec, design, options, cv)?, Handling::Kept))
}

/// The summary's counts: "N measurements (P probe, T tracker[, O orientation][, C plane
/// contact(s)][, D known distance(s)])"; a pose row counts as one tracker and one orientation
/// measurement.
fn row_counts(rows: &[Measurement], distances: usize) -> String {
    let count = |f: fn(&Target) -> bool| rows.iter().filter(|m| f(&m.target)).count();
    let n_probe = count(|t| matches!(t, Target::Probe { .. }));
    let n_orientation = count(Target::is_orientation);
    let n_plane = count(Target::is_plane);
    let n_tracker = rows.len() - n_probe - n_orientation - n_plane;
    let mut text = format!("{} measurements ({n_probe} probe, {n_tracker} tracker", rows.len());
    if n_orientation > 0 {
        text += &format!(", {n_orientation} orientation");
    }
    if n_plane > 0 {
        text += &format!(", {n_plane} plane contact(s)");
    }
    if distances > 0 {
        text += &format!(", {distances} known distance(s)");
    }
    text + ")"
}

/// [`calibrate_rows`]; with orientation rows and no `--orientation-weight`, refitted with the
/// orientation weight the fitted scatter calls for until it settles. The scatter is returned
/// whenever there are orientation rows.
#[allow(clippy::type_complexity)]
fn calibrate_weighed(
    args: &Args,
    bad: &BadRowArgs,
    model: &Model,
    rows: &[Measurement],
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
) -> Result<((Calibration, Handling), Option<FittedScatter>), IdentifyError> {
    let spec = args.params.as_str();
    if !rows.iter().any(|m| m.target.is_orientation()) {
        return Ok((calibrate_rows(bad, model, rows, spec, design, options, cv)?, None));
    }
    let scatter = |(cal, handling): &(Calibration, Handling), w: &KindWeights| {
        FittedScatter::of(&handling.kept_rows(rows), &cal.fit, w)
    };
    if args.orientation_weight.is_some()
        || stated_noise(args).is_some_and(|n| n.orientation_sigma_mrad.is_some())
    {
        let out = calibrate_rows(bad, model, rows, spec, design, options, cv)?;
        let s = FittedScatter { stated: true, ..scatter(&out, &options.weights) };
        return Ok((out, Some(s)));
    }
    let (out, s) =
        fit_with_fitted_scatter(options, |o| calibrate_rows(bad, model, rows, spec, design, o, cv), scatter)?;
    Ok((out, Some(s)))
}

/// The instruments' noise recorded in the measurement files (`# vatcal-noise:` of
/// `--measurements`, else of `--tracker`), when any; unreadable metadata counts as none (the
/// readers report a bad file).
fn stated_noise(args: &Args) -> Option<vatcal_io::metadata::NoiseMetadata> {
    [&args.measurements, &args.tracker]
        .into_iter()
        .flatten()
        .find_map(|p| vatcal_io::metadata::read_metadata(p).ok().and_then(|m| m.noise))
}

/// The orientation weight the user states: `--orientation-weight`, else the files' recorded
/// noise (`orientation_sigma_mrad` with the σ of the reference kind — probe rows when there are
/// any, else tracker rows): `w_ref · (σ_ref / σ_orientation)²` in mm²/rad². `None`: fitted
/// from the scatter.
///
/// # Errors
/// An orientation σ is recorded but the reference kind's σ is not.
fn stated_orientation_weight(args: &Args, rows: &[Measurement]) -> anyhow::Result<Option<f64>> {
    if let Some(w) = args.orientation_weight {
        return Ok(Some(w));
    }
    let Some(noise) = stated_noise(args) else { return Ok(None) };
    let Some(sigma_mrad) = noise.orientation_sigma_mrad else { return Ok(None) };
    let probe_rows = rows.iter().any(|m| m.position().is_some());
    let (reference, w_ref, name) = if probe_rows {
        (noise.probe_sigma_mm, 1.0, "probe_sigma_mm")
    } else {
        (noise.tracker_sigma_mm, args.tracker_weight, "tracker_sigma_mm")
    };
    let sigma_ref = reference.ok_or_else(|| {
        anyhow::anyhow!(
            "the measurement file records orientation_sigma_mrad but not {name}: the orientation weight needs both (or give --orientation-weight)"
        )
    })?;
    Ok(Some(w_ref * (sigma_ref / (1e-3 * sigma_mrad)).powi(2)))
}

/// A row's residual norm with its unit: mm, or mrad for an orientation row (its residual is
/// in rad; the JSON report keeps the number as it is).
fn residual_text(row: &Measurement, norm: f64) -> String {
    if row.target.is_orientation() { format!("{:.4} mrad", 1e3 * norm) } else { format!("{norm:.4} mm") }
}

/// Rows named at most in the terminal (the report lists all).
const MAX_BAD_ROWS_SHOWN: usize = 20;

/// Names the final fit's rows beyond k robust σ̂ (and the dropped ones), prints them and
/// returns the report's `bad_rows`.
fn report_bad_rows(
    bad: &BadRowArgs,
    handling: &Handling,
    fit: &Identification,
    rows: &[Measurement],
    sources: &[RowSource],
    weights: &KindWeights,
) -> anyhow::Result<BadRowsReport> {
    let kept = handling.kept_indices(rows.len());
    let fitted: Vec<Measurement> = kept.iter().map(|i| rows[*i]).collect();
    let scan = flag_outliers(&fit.residuals, &fitted, weights, bad.k)?;
    let named = |row: usize, residual_mm: f64, sigmas: f64| BadRowReport {
        row,
        file: sources.get(row).map(|s| s.path.display().to_string()),
        line: sources.get(row).map(|s| s.line),
        residual_mm,
        sigmas,
        weight: None,
        round: None,
    };
    let where_ =
        |row: usize| sources.get(row).map_or_else(|| format!("row {}", row + 1), ToString::to_string);
    let mut report = BadRowsReport {
        sigma_estimator: SIGMA_ESTIMATOR.to_string(),
        robust_sigma_mm: scan.sigma_mm,
        k: bad.k,
        threshold_mm: bad.k * scan.sigma_mm,
        rows: Vec::new(),
        robust: None,
        dropped: Vec::new(),
        drop_k: bad.drop_k,
    };
    if let Handling::Dropped { dropped, rounds, .. } = handling {
        println!(
            "--drop-outliers {}: {} row(s) removed in {rounds} calibration(s){}",
            bad.drop_k.unwrap_or(bad.k),
            dropped.len(),
            if dropped.is_empty() { "" } else { ":" }
        );
        for d in dropped {
            println!(
                "  {}  residual {} ({:.1} robust sigma), round {}",
                where_(d.index),
                residual_text(&rows[d.index], d.residual_mm),
                d.sigmas,
                d.round
            );
            report
                .dropped
                .push(BadRowReport { round: Some(d.round), ..named(d.index, d.residual_mm, d.sigmas) });
        }
    }
    if let Handling::Robust(r) = handling {
        println!(
            "robust fit ({}, c = {} robust sigma): {} reweighting round(s), {}; RMS residual of the unweighted fit {:.4} mm",
            r.options.loss,
            r.options.tuning,
            r.rounds,
            if r.converged { "weights settled" } else { "weights still changing at the round cap" },
            r.unweighted_rms_mm
        );
        report.robust = Some(RobustReport::from_fit(r));
    }
    let what = match handling {
        Handling::Kept => {
            "kept in the fit (--robust huber|cauchy down-weights them, --drop-outliers K removes them)"
        }
        Handling::Robust(_) => "down-weighted",
        Handling::Dropped { .. } => "kept (still beyond after the last round)",
    };
    println!(
        "bad rows: {} beyond {} x robust sigma {:.5} mm ({SIGMA_ESTIMATOR}){}",
        scan.rows.len(),
        bad.k,
        scan.sigma_mm,
        if scan.rows.is_empty() { String::new() } else { format!(": {what}") }
    );
    for (shown, f) in scan.rows.iter().enumerate() {
        let row = kept[f.index];
        let weight = match handling {
            Handling::Robust(r) => r.weights.get(f.index).copied(),
            _ => None,
        };
        if shown < MAX_BAD_ROWS_SHOWN {
            println!(
                "  {}  residual {} ({:.1} robust sigma){}",
                where_(row),
                residual_text(&rows[row], f.residual_mm),
                f.sigmas,
                weight.map_or_else(String::new, |w| format!(", weight {w:.3e}"))
            );
        }
        report.rows.push(BadRowReport { weight, ..named(row, f.residual_mm, f.sigmas) });
    }
    if scan.rows.len() > MAX_BAD_ROWS_SHOWN {
        println!("  ... and {} more (the JSON report lists every one)", scan.rows.len() - MAX_BAD_ROWS_SHOWN);
    }
    Ok(report)
}

/// One line: the joint range the fit used, written into the calibrated file.
fn print_training_range(range: Option<&TrainingRange>, kinds: &[vatcal_core::JointKind]) {
    let Some(r) = range else { return };
    let joints: Vec<String> = kinds
        .iter()
        .enumerate()
        .map(|(k, kind)| format!("q{} {:.3}..{:.3} {}", k + 1, r.q_min[k], r.q_max[k], kind.file_unit()))
        .collect();
    println!(
        "training range ({} rows; `vatcal validate` and `compensate` warn beyond it): {}",
        r.rows,
        joints.join(", ")
    );
}

/// The cross-validation and prior options of `--folds`, `--cv-repeats`, `--cv-seed`,
/// `--prior-scale` and `--prior`.
fn cv_options(args: &Args) -> anyhow::Result<CvOptions> {
    anyhow::ensure!(args.folds >= 2, "--folds must be at least 2, got {}", args.folds);
    anyhow::ensure!(args.cv_repeats >= 1, "--cv-repeats must be at least 1, got {}", args.cv_repeats);
    if let Some(k) = args.prior_scale {
        anyhow::ensure!(k.is_finite() && k > 0.0, "--prior-scale must be a positive number, got {k}");
    }
    let mut widths = PriorWidths::realistic();
    for text in &args.priors {
        let o: PriorOverride = text.parse().map_err(anyhow::Error::msg).context("--prior")?;
        widths.set(o.kind, o.width);
    }
    // a named set gets priors only when asked for; --prior alone means scale 1
    let named = args.params.trim() != "default";
    let prior_scale = match args.prior_scale {
        None if named && !args.priors.is_empty() => Some(1.0),
        k => k,
    };
    Ok(CvOptions {
        folds: args.folds,
        repeats: args.cv_repeats,
        seed: args.cv_seed,
        widths,
        prior_scale,
        ..CvOptions::default()
    })
}

/// The cross-validation table and the reason of the choice.
fn print_selection(sel: &CvSelection) {
    let split = if sel.folds >= sel.groups {
        "leave-one-posture-out".to_string()
    } else {
        format!("{} x {}-fold cross-validation", sel.repeats, sel.folds)
    };
    println!(
        "choosing the prior scale by {split} over {} posture groups (seed {}; priors at 1 = realistic widths):",
        sel.groups, sel.seed
    );
    println!(
        "{:<32} {:>7} {:>14} {:>15} {:>12}  note",
        "set", "params", "CV RMS [mm]", "train RMS [mm]", "condition"
    );
    for (k, c) in sel.candidates.iter().enumerate() {
        match &c.rejected {
            Some(why) => println!(
                "{:<32} {:>7} {:>14} {:>15} {:>12}  rejected: {why}",
                c.label(),
                c.params.len(),
                "-",
                "-",
                "-"
            ),
            None => println!(
                "{:<32} {:>7} {:>14.5} {:>15.5} {:>12.1}  {}",
                c.label(),
                c.params.len(),
                c.cv_rms_mm,
                c.train_rms_mm,
                c.condition_number,
                match (k == sel.chosen, c.capped_fits) {
                    (true, 0) => "<- chosen".to_string(),
                    (true, n) => format!(
                        "<- chosen ({n} fold fit(s) stopped at the iteration cap, scored at their last iterate)"
                    ),
                    (false, 0) => String::new(),
                    (false, n) =>
                        format!("{n} fold fit(s) stopped at the iteration cap, scored at their last iterate"),
                }
            ),
        }
    }
    println!("{}", sel.reason);
    println!("{}: {}", sel.chosen().label(), sel.chosen().params.names().join(","));
}

/// Marks the positions of `--unknown-positions` as unknown: a position the cell file lacks is
/// added at a distinct placeholder (the initialisation places it). Returns the free ids.
fn add_unknown_positions(cell: &mut vatcal_core::CellFile, spec: Option<&str>) -> anyhow::Result<Vec<u32>> {
    let Some(spec) = spec else { return Ok(Vec::new()) };
    let ids: Vec<u32> = if spec.trim() == "all" {
        cell.calibration_positions.iter().map(|p| p.id).collect()
    } else {
        spec.split(',')
            .map(|s| {
                s.trim().parse::<u32>().map_err(|_| {
                    anyhow::anyhow!(
                        "--unknown-positions: `{}` is not a position id (expected ids like 0,1 or `all`)",
                        s.trim()
                    )
                })
            })
            .collect::<anyhow::Result<_>>()?
    };
    if ids.is_empty() {
        bail!("--unknown-positions: no position ids given");
    }
    for (k, id) in ids.iter().enumerate() {
        if !cell.calibration_positions.iter().any(|p| p.id == *id) {
            cell.calibration_positions.push(vatcal_core::cell::PointEntry {
                id: *id,
                x_mm: 100.0 * k as f64,
                y_mm: 0.0,
                z_mm: 0.0,
            });
        }
    }
    Ok(ids)
}

/// With pose rows (orientation measurements) the tool body's rotation is unknown: the
/// `tool-frame` effect is switched on (its tilt joins the generic sets; the last joint's offset
/// turns the body about the flange axis).
fn with_tool_rotation(mut model: Model, measurements: &[Measurement]) -> anyhow::Result<Model> {
    if measurements.iter().any(|m| m.target.is_orientation()) {
        model.enable_effect(vatcal_core::EffectSpec::ToolFrame).context("pose rows: the tool frame")?;
    }
    Ok(model)
}

/// Every row of `--measurements` and `--tracker` (each file: probe rows, tracker rows or both),
/// with the file and line of each.
fn read_all(args: &Args, model: &Model) -> anyhow::Result<(Vec<Measurement>, Vec<RowSource>)> {
    if args.measurements.is_none() && args.tracker.is_none() {
        bail!("no measurements: give --measurements FILE (probe and/or tracker rows) and/or --tracker FILE");
    }
    let (mut measurements, mut sources) = (Vec::new(), Vec::new());
    for path in [&args.measurements, &args.tracker].into_iter().flatten() {
        // any TCP id: the ones the cell lacks are resolved by --unknown-tcps
        let (rows, lines) = args.read.markers_with_sources(path, model)?;
        measurements.extend(rows);
        sources.extend(lines);
    }
    Ok((measurements, sources))
}

fn print_log(log: &[IterationLog]) {
    let orientation = log.iter().any(|it| it.orientation_rms_mrad.is_some());
    println!(
        "{:>4}  {:>12}  {:>12}  {:>12}  {:>10}  {:>10}{}",
        "iter",
        "mean [mm]",
        "RMS [mm]",
        "max [mm]",
        "lambda",
        "step",
        if orientation { format!("  {:>16}", "orient RMS [mrad]") } else { String::new() }
    );
    for it in log {
        println!(
            "{:>4}  {:>12.6}  {:>12.6}  {:>12.6}  {:>10.3e}  {:>10.3e}{}",
            it.iteration,
            it.mean_mm,
            it.rms_mm,
            it.max_mm,
            it.lambda,
            it.step_norm,
            it.orientation_rms_mrad.map_or(String::new(), |o| format!("  {o:>16.4}"))
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

/// The markers (TCP offsets in frame N, mm, with their sigma) of the TCPs the rows use, and a
/// warning for a marker of `--unknown-tcps` the fitted set left at its placeholder.
fn print_markers(fit: &Identification, rows: &[Measurement], markers: &super::markers::UnknownTcps) {
    println!("markers (TCP offsets in the flange frame N, sigma of each coordinate):");
    for line in super::markers::marker_lines(fit, rows, markers) {
        println!("{line}");
    }
    for id in super::markers::unfitted(fit, markers) {
        eprintln!(
            "warning: tcp {id} (--unknown-tcps) is not in the fitted set: it stays at its placeholder; add tcp{id}_x,tcp{id}_y,tcp{id}_z to --params"
        );
    }
}

/// The directions the data excite less than the priors (or the realistic widths) do.
fn print_weak_directions(cal: &Calibration) {
    if cal.weak_directions.is_empty() {
        return;
    }
    let against = if cal.prior_sigmas.is_empty() {
        "the realistic prior widths (this fit had no priors: these combinations are fitted to noise; --prior-scale 1 would hold them)"
    } else {
        "the priors (held near nominal by them)"
    };
    println!("weakly excited directions ({}), against {against}:", cal.weak_directions.len());
    for d in &cal.weak_directions {
        println!("  {}", d.sentence());
    }
}

/// The residuals line: with orientation rows (in rad) one line for the position rows and one
/// for the orientation rows (mrad).
fn print_residuals(fit: &Identification, rows: &[Measurement]) {
    if !rows.iter().any(|m| m.target.is_orientation()) || rows.len() != fit.residuals.len() {
        println!("residuals: {}", fit.residual_stats.one_line());
        return;
    }
    let of = |orientation: bool| -> Vec<nalgebra::Vector3<f64>> {
        rows.iter()
            .zip(&fit.residuals)
            .filter(|(m, _)| m.target.is_orientation() == orientation)
            .map(|(_, r)| *r)
            .collect()
    };
    let positions = of(false);
    if !positions.is_empty() {
        println!("residuals of the position rows: {}", ErrorStats::from_errors(&positions).one_line());
    }
    let o = ErrorStats::from_errors(&of(true));
    println!(
        "residuals of the orientation rows: mean {:.4} mrad, RMS {:.4} mrad, median {:.4} mrad, 95% {:.4} mrad, max {:.4} mrad (n = {})",
        1e3 * o.mean,
        1e3 * o.rms,
        1e3 * o.median,
        1e3 * o.p95,
        1e3 * o.max,
        o.n
    );
}

fn print_summary(fit: &Identification, prior_sigmas: &[f64], rows: &[Measurement]) {
    println!("{}", fit.termination.describe());
    print_residuals(fit, rows);
    println!(
        "sigma_hat {:.5} mm (dof {}), condition number {:.1} (column-normalised Jacobian)",
        fit.sigma_hat_mm, fit.dof, fit.condition_number
    );
    let priors = prior_sigmas.len() == fit.params.len();
    if priors {
        println!(
            "{:<18} {:>10} {:>16} {:>16} {:>14} {:>12} {:>16} {:>10}",
            "parameter", "unit", "nominal", "identified", "delta", "sigma", "prior", "post/prior"
        );
    } else {
        println!(
            "{:<18} {:>10} {:>16} {:>16} {:>14} {:>12}",
            "parameter", "unit", "nominal", "identified", "delta", "sigma"
        );
    }
    for (k, p) in fit.params.iter().enumerate() {
        let f = |v: f64| to_file_units(*p, v);
        let row = format!(
            "{:<18} {:>10} {:>16.6} {:>16.6} {:>14.6e} {:>12.3e}",
            p.name(),
            file_unit_label(*p),
            f(fit.start_values[k]),
            f(fit.values[k]),
            f(fit.values[k] - fit.start_values[k]),
            f(fit.sigma[k])
        );
        if priors {
            let s = prior_sigmas[k];
            let kind = PriorKind::of(*p, &fit.model);
            let (prior, ratio) = if s.is_finite() {
                (format!("{:.3e} {}", f(s), kind), format!("{:.2}", fit.sigma[k] / s))
            } else {
                ("free".to_string(), "-".to_string())
            };
            println!("{row} {prior:>16} {ratio:>10}");
        } else {
            println!("{row}");
        }
    }
    if !fit.strong_correlations.is_empty() {
        let pairs: Vec<String> =
            fit.strong_correlations.iter().map(|(a, b, c)| format!("{a}/{b} {c:+.3}")).collect();
        println!("strongly correlated (|rho| > {}): {}", fit.correlation_threshold, pairs.join(", "));
    }
}
