//! `vatcal validate`: position errors of a model (and optionally a baseline model) on tracker
//! measurements, with a before/after histogram and a JSON report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use vatcal_core::training_range::{self, JointExcursion, TrainingRange};
use vatcal_core::{JointKind, Measurement};
use vatcal_identification::{ErrorStats, ValidationReport, validate};
use vatcal_io::RowSource;
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
    /// The tracker's frame is not the model's world: register it first (the rigid motion that
    /// best maps each model's predicted points onto the tracker's, six parameters fitted on the
    /// validation rows themselves), e.g. for a model calibrated from plane contacts or unknown
    /// fixed points alone, whose world frame the data fix only up to such a motion.
    #[arg(long)]
    pub register_frame: bool,
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
    /// the rows outside the model's training range (its cell file's `[training_range]`;
    /// absent when the file has none)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extrapolation: Option<Extrapolation>,
    /// orientation errors of pose rows (absent without them)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<OrientationErrors>,
}

/// Orientation errors of the pose rows' orientation measurements: statistics of the rotation
/// angle between the measured and the predicted tool orientation.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OrientationErrors {
    /// the model under test
    pub model: OrientationStats,
    /// the baseline, if given
    pub baseline: Option<OrientationStats>,
}

/// Statistics of rotation-error angles \[mrad\].
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OrientationStats {
    /// orientation rows
    pub n: usize,
    /// mean angle \[mrad\]
    pub mean_mrad: f64,
    /// RMS angle \[mrad\]
    pub rms_mrad: f64,
    /// median angle \[mrad\]
    pub median_mrad: f64,
    /// 95th percentile \[mrad\]
    pub p95_mrad: f64,
    /// largest angle \[mrad\]
    pub max_mrad: f64,
}

impl OrientationStats {
    fn of(s: &ErrorStats) -> Self {
        Self {
            n: s.n,
            mean_mrad: s.mean,
            rms_mrad: s.rms,
            median_mrad: s.median,
            p95_mrad: s.p95,
            max_mrad: s.max,
        }
    }
}

/// Splits the orientation measurements of pose rows from the position rows (kept with their
/// sources): `(position rows, their sources, orientation rows)`.
fn split_orientation(
    rows: Vec<Measurement>,
    sources: Vec<RowSource>,
) -> (Vec<Measurement>, Vec<RowSource>, Vec<Measurement>) {
    let (mut positions, mut kept, mut orientation) = (Vec::new(), Vec::new(), Vec::new());
    let mut sources = sources.into_iter();
    for m in rows {
        let source = sources.next();
        if m.target.is_orientation() {
            orientation.push(m);
        } else {
            positions.push(m);
            kept.extend(source);
        }
    }
    (positions, kept, orientation)
}

/// Statistics of the orientation errors \[mrad\] of `model` on `rows` (`None` without rows).
fn orientation_errors(
    model: &vatcal_kinematics::Model,
    rows: &[Measurement],
) -> anyhow::Result<Option<ErrorStats>> {
    if rows.is_empty() {
        return Ok(None);
    }
    let v = validate(model, rows).context("validating the orientation rows")?;
    let mrad: Vec<_> = v.errors_mm.iter().map(|e| e * 1e3).collect();
    Ok(Some(ErrorStats::from_errors(&mrad)))
}

/// Prints the orientation errors (statistics in mrad) under the position errors.
fn print_orientation(o: &ErrorStats, baseline: Option<(&PathBuf, &ErrorStats)>, model: &Path) {
    println!("orientation errors of the pose rows (rotation angle, world axes):");
    println!(
        "{:<32} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9}   {:>27}   {:>27}",
        "[mrad]", "n", "mean", "RMS", "median", "95%", "max", "mean x / y / z", "RMS x / y / z"
    );
    if let Some((path, b)) = baseline {
        print_row(&label("baseline", path), b);
    }
    print_row(&label("model", model), o);
}

/// The validation rows whose joints leave the training range of the model under test.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Extrapolation {
    /// the model's training range (mm / deg)
    pub training_range: TrainingRange,
    /// rows with a joint outside it by more than its tolerance (max of 1 % of the joint's
    /// range and 0.5 deg / 0.5 mm)
    pub n_rows: usize,
    /// validation rows in all
    pub n_total: usize,
    /// per joint (index = joint − 1): rows outside on that joint
    pub rows_per_joint: Vec<usize>,
    /// mean error of the model on the rows inside the range \[mm\] (null: none inside)
    pub mean_error_inside_mm: Option<f64>,
    /// mean error of the model on the rows outside \[mm\] (null: none outside)
    pub mean_error_outside_mm: Option<f64>,
    /// every row outside, in file order
    pub rows: Vec<ExtrapolatedRow>,
}

/// One validation row outside the training range.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ExtrapolatedRow {
    /// 0-based index of the row in the file's rows
    pub row: usize,
    /// the file
    pub file: String,
    /// its 1-based line
    pub line: u64,
    /// the model's error there \[mm\]
    pub error_mm: f64,
    /// the joints outside, with value, range and excess (mm / deg)
    pub joints: Vec<JointExcursion>,
}

/// `model` with its base pose moved by the rigid motion that best maps its predicted points of
/// the tracker rows onto the measured ones (`--register-frame`); prints the motion.
fn registered(
    model: vatcal_kinematics::Model,
    tracker: &[Measurement],
    path: &Path,
) -> anyhow::Result<vatcal_kinematics::Model> {
    let points: Vec<Measurement> =
        tracker.iter().filter(|m| matches!(m.target, vatcal_core::Target::Tracker { .. })).copied().collect();
    let options = vatcal_identification::InitOptions { max_rounds: 1, ..Default::default() };
    let init = vatcal_identification::initialise(&model, &points, &options)
        .with_context(|| format!("registering {} onto the tracker frame", path.display()))?;
    anyhow::ensure!(
        init.registered,
        "--register-frame: {} needs at least three tracker rows not on a line",
        path.display()
    );
    let (before, after) = (model.base_frame(), init.model.base_frame());
    let angle = vatcal_core::rotation_error(&after.r, &before.r).norm();
    println!(
        "{}: tracker frame registered (base moved by {:.3} mm and {:.3} mrad; RMS {:.4} -> {:.4} mm)",
        path.display(),
        (after.p - before.p).norm(),
        1e3 * angle,
        init.rms_before_mm,
        init.rms_after_mm
    );
    Ok(init.model)
}

/// Validates the model(s), prints the statistics, writes the plot and the report.
pub fn run(args: Args) -> anyhow::Result<()> {
    // one read of the cell file: the model and its `[training_range]`
    let model_cell = vatcal_core::CellFile::load(&args.model)?;
    let model = super::model_of(&model_cell, &args.model)?;
    let (rows, sources) = args.read.markers_with_sources(&args.tracker, &model)?;
    let (tracker, sources, orientation) = split_orientation(rows, sources);
    // markers: the model must have every TCP the rows use (a calibrated cell written by
    // `identify --unknown-tcps` has them)
    let known = model.tcp_ids();
    let missing = super::markers::missing_tcps(&[tracker.as_slice(), &orientation].concat(), &known);
    if let Some(&(id, row)) = missing.first() {
        let ids: Vec<String> = missing.iter().map(|(id, _)| id.to_string()).collect();
        anyhow::bail!(
            "{}: column `tcp`: unknown tcp id {id} (the model {} has {known:?}): validate the calibrated cell that `vatcal identify --unknown-tcps {}` writes (it contains the fitted markers)",
            sources.get(row).map_or_else(|| args.tracker.display().to_string(), ToString::to_string),
            args.model.display(),
            ids.join(",")
        );
    }
    let model = if args.register_frame { registered(model, &tracker, &args.model)? } else { model };
    let tested =
        validate(&model, &tracker).with_context(|| format!("validating {}", args.model.display()))?;
    let baseline = match &args.baseline {
        Some(path) => {
            // markers the baseline lacks (a nominal cell without the fitted markers) are the
            // model's: the comparison is about the robot, not about where the markers sit
            let mut cell = vatcal_core::CellFile::load(path)?;
            let copied = super::markers::copy_missing_tcps(&mut cell, &model, &tracker);
            if !copied.is_empty() {
                let ids: Vec<String> = copied.iter().map(u32::to_string).collect();
                println!(
                    "note: the baseline {} lacks tcp {}: taken from the model under test (its fitted markers)",
                    path.display(),
                    ids.join(",")
                );
            }
            let base = super::model_of(&cell, path)?;
            let base = if args.register_frame { registered(base, &tracker, path)? } else { base };
            // read again with the baseline: checks the context columns its effects need
            let read = vatcal_io::read_any_measurements_with(&args.tracker, &base, &args.read.options()?)?;
            let (tracker, _, orientation) = split_orientation(read.rows, Vec::new());
            let v = validate(&base, &tracker).with_context(|| format!("validating {}", path.display()))?;
            Some((path, v, orientation_errors(&base, &orientation)?))
        }
        None => None,
    };
    println!("{} validation measurements from {}", tracker.len(), args.tracker.display());
    print_header();
    if let Some((path, v, _)) = &baseline {
        print_row(&label("baseline", path), &v.stats);
    }
    print_row(&label("model", &args.model), &tested.stats);
    let orientation = orientation_errors(&model, &orientation)?;
    if let Some(o) = &orientation {
        let b = baseline.as_ref().and_then(|(p, _, o)| o.as_ref().map(|o| (*p, o)));
        print_orientation(o, b, &args.model);
    }
    let orientation = orientation.map(|model_stats| OrientationErrors {
        baseline: baseline.as_ref().and_then(|(_, _, o)| o.as_ref().map(OrientationStats::of)),
        model: OrientationStats::of(&model_stats),
    });
    let baseline = baseline.map(|(p, v, _)| (p, v));
    let factor = baseline.as_ref().map(|(_, b)| b.stats.mean / tested.stats.mean.max(f64::MIN_POSITIVE));
    if let Some(f) = factor {
        println!("mean error reduced by a factor of {f:.1}");
    }
    // issue 29: postures outside the joint range the model was calibrated on
    let extrapolation = model_cell
        .training_range
        .map(|range| extrapolation(range, model.joint_kinds(), &tracker, &sources, &tested, &args.model));
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
            extrapolation,
            orientation,
        };
        let text = serde_json::to_string_pretty(&out)?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    Ok(())
}

/// Checks every row against the training range: a warning per row outside (stderr, naming
/// file:line and the joints), a summary line, and the report's `extrapolation`.
fn extrapolation(
    training_range: TrainingRange,
    kinds: &[JointKind],
    rows: &[vatcal_core::Measurement],
    sources: &[RowSource],
    tested: &ValidationReport,
    model_path: &Path,
) -> Extrapolation {
    let mut out = Extrapolation {
        n_rows: 0,
        n_total: rows.len(),
        rows_per_joint: vec![0; kinds.len()],
        mean_error_inside_mm: None,
        mean_error_outside_mm: None,
        rows: Vec::new(),
        training_range,
    };
    let (mut inside, mut outside) = ((0.0, 0usize), (0.0, 0usize));
    for (k, m) in rows.iter().enumerate() {
        let error_mm = tested.errors_mm.get(k).map_or(f64::NAN, |e| e.norm());
        let joints = out.training_range.excursions(kinds, &m.q);
        if joints.is_empty() {
            inside = (inside.0 + error_mm, inside.1 + 1);
            continue;
        }
        outside = (outside.0 + error_mm, outside.1 + 1);
        for j in &joints {
            if let Some(n) = out.rows_per_joint.get_mut(j.joint - 1) {
                *n += 1;
            }
        }
        let (file, line) = sources
            .get(k)
            .map_or_else(|| (String::new(), 0), |s: &RowSource| (s.path.display().to_string(), s.line));
        if out.rows.len() < training_range::MAX_WARNINGS {
            eprintln!(
                "warning: {file}:{line}: outside the training range of {}: {} (error {error_mm:.4} mm)",
                model_path.display(),
                training_range::list(&joints)
            );
        }
        out.rows.push(ExtrapolatedRow { row: k, file, line, error_mm, joints });
    }
    out.n_rows = out.rows.len();
    if out.n_rows > training_range::MAX_WARNINGS {
        eprintln!(
            "warning: ... and {} more rows outside the training range (the JSON report lists every one)",
            out.n_rows - training_range::MAX_WARNINGS
        );
    }
    let mean = |(sum, n): (f64, usize)| (n > 0).then(|| sum / n as f64);
    out.mean_error_inside_mm = mean(inside);
    out.mean_error_outside_mm = mean(outside);
    if out.n_rows == 0 {
        println!(
            "extrapolation: every row lies within the training range of {} ({} rows)",
            model_path.display(),
            out.training_range.rows
        );
    } else {
        let per_joint: Vec<String> = out
            .rows_per_joint
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(k, n)| format!("q{} {n}", k + 1))
            .collect();
        let fmt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.4} mm"));
        println!(
            "extrapolation: {} of {} rows leave the training range of {} (rows per joint: {}); mean error {} there, {} inside",
            out.n_rows,
            out.n_total,
            model_path.display(),
            per_joint.join(", "),
            fmt(out.mean_error_outside_mm),
            fmt(out.mean_error_inside_mm)
        );
    }
    out
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
