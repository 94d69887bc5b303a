//! `vatcal observability`: identifiability report of a measurement set (rank, identifiable
//! basis, redundant parameters with what absorbs them, invisible combinations) and its
//! observability indices O1..O5 (see `docs/observability.md`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_observability::identifiability::{
    AnalysisOptions, analyze_jacobian, assemble_jacobian, param_set_from_spec, select_columns,
};
use vatcal_observability::{ColumnScaling, ObservabilityError, observability_indices};

/// Arguments of `vatcal observability`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model file (TOML).
    #[arg(long)]
    pub model: PathBuf,
    /// Measurements or candidate poses: probe rows (`position,tcp,q1..qN`) and/or tracker rows
    /// (`tcp,q1..qN,x,y,z`), N = the model's joints (`q1..q7` on the canonical cell).
    #[arg(long)]
    pub measurements: PathBuf,
    /// Parameters to analyse: `paper34`, `geometric`, `all-identifiable`, `all` (every model
    /// parameter except TCP and calibration-position coordinates, in preference order), or a
    /// comma-separated list of parameter names (earlier names are preferred in the basis).
    #[arg(long, default_value = "all")]
    pub params: String,
    /// Relative rank tolerance on the unit-column-normalised singular values (1e-8 suits the
    /// analytic Jacobian).
    #[arg(long, default_value_t = vatcal_observability::identifiability::DEFAULT_RELATIVE_TOLERANCE)]
    pub tolerance: f64,
    /// Exit with an error when the parameter set is not fully identifiable.
    #[arg(long)]
    pub strict: bool,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.tolerance.is_finite() && args.tolerance > 0.0 && args.tolerance < 1.0,
        "--tolerance must be in (0, 1), got {}",
        args.tolerance
    );
    let model = super::load_model(&args.model)?;
    let measurements = vatcal_io::read_measurements(&args.measurements, &model)?;
    anyhow::ensure!(!measurements.is_empty(), "{}: no measurement rows", args.measurements.display());
    let params = if args.params.trim() == "all" {
        vatcal_observability::identifiability::preference_order(&model)
    } else {
        param_set_from_spec(&args.params, &model, &measurements).context("--params")?
    };
    let j = assemble_jacobian(&model, &measurements, &params).map_err(|e| match &e {
        ObservabilityError::Model { index, .. } | ObservabilityError::NonFinite { index, .. } => {
            anyhow::anyhow!("{}: measurement row {}: {e}", args.measurements.display(), index + 1)
        }
        _ => anyhow::anyhow!("{}: {e}", args.measurements.display()),
    })?;
    let report =
        analyze_jacobian(j.as_ref(), &params, &AnalysisOptions { relative_tolerance: args.tolerance })?;
    // Indices of the identifiable basis (the whole set when it is fully identifiable): the
    // indices of a rank-deficient set are ~0 and say nothing more than the rank.
    let basis = report.identifiable_set();
    let jb = select_columns(j.as_ref(), &params, &basis)?;
    let raw = observability_indices(jb.as_ref(), &basis, ColumnScaling::None)?;
    let normalized = observability_indices(jb.as_ref(), &basis, ColumnScaling::UnitNorm)?;

    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{}: {} measurements, parameter set `{}`",
        args.measurements.display(),
        measurements.len(),
        args.params
    )?;
    write!(out, "{report}")?;
    let what = if report.is_full_rank() { "indices" } else { "indices of the identifiable basis" };
    writeln!(out, "{what}, raw units:               {raw}")?;
    writeln!(out, "{what}, unit-normalised columns: {normalized}")?;
    if !report.is_full_rank() {
        writeln!(
            out,
            "NOT FULLY IDENTIFIABLE: {} of {} parameters; use --params all-identifiable or fix: {}",
            report.rank,
            report.parameter_count,
            report.unidentifiable().iter().map(|p| p.name()).collect::<Vec<_>>().join(", ")
        )?;
        anyhow::ensure!(
            !args.strict,
            "the parameter set `{}` is rank-deficient ({} of {})",
            args.params,
            report.rank,
            report.parameter_count
        );
    }
    Ok(())
}
