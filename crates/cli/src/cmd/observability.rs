//! `vatcal observability`: identifiability report of a measurement set (rank, identifiable
//! basis, redundant parameters with what absorbs them, invisible combinations) and its
//! observability indices O1..O5 (see `docs/observability.md`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::{Measurement, ParamId, ParamSet, PlaneDof};
use vatcal_kinematics::Model;
use vatcal_observability::identifiability::{
    AnalysisOptions, analyze_jacobian, preference_order, select_columns,
};
use vatcal_observability::sets::{DataDesign, assemble_design_jacobian, resolve_spec};
use vatcal_observability::{ColumnScaling, ObservabilityError, observability_indices_for};

/// Arguments of `vatcal observability`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model file (TOML).
    #[arg(long)]
    pub model: PathBuf,
    /// Measurements or candidate poses: probe rows (`position,tcp,q1..qN`), tracker rows
    /// (`tcp,q1..qN,x,y,z`) and/or plane rows (`plane,tcp,q1..qN[,normal]`), N = the model's
    /// joints (`q1..q7` on the canonical cell). Contact planes the cell file lacks are unknown:
    /// first estimated through the model's contacts, their tilts and offsets analysed with the
    /// rest.
    #[arg(long)]
    pub measurements: PathBuf,
    /// Parameters to analyse: `paper34`, `geometric`, `all-identifiable`, `all` (every model
    /// parameter except TCP and calibration-position coordinates and the cell file's contact
    /// planes, in preference order; the unknown planes' tilts and offsets first), a generic set
    /// (`registration`, `joint-offsets`, `kinematic`, `kinematic+compliance`), or a
    /// comma-separated list of parameter names (earlier names are preferred in the basis).
    #[arg(long, default_value = "all")]
    pub params: String,
    /// A known distance between two parallel contact planes, `A,B,MM` or `A,B,MM,SIGMA_MM`
    /// (plane B lies MM above plane A; as `vatcal identify`): three constraint rows that fix the
    /// scale plane rows alone leave free. Repeatable.
    #[arg(long = "plane-distance", value_name = "A,B,MM[,SIGMA_MM]")]
    pub plane_distances: Vec<String>,
    /// Relative rank tolerance on the unit-column-normalised singular values (1e-8 suits the
    /// analytic Jacobian).
    #[arg(long, default_value_t = vatcal_observability::identifiability::DEFAULT_RELATIVE_TOLERANCE)]
    pub tolerance: f64,
    /// Exit with an error when the parameter set is not fully identifiable.
    #[arg(long)]
    pub strict: bool,
}

/// The model with the planes the rows name and the cell lacks, the rows and their design (the
/// unknown planes free, the known plane distances).
fn load(args: &Args) -> anyhow::Result<(Model, Vec<Measurement>, DataDesign)> {
    let mut cell = vatcal_core::CellFile::load(&args.model)?;
    let model = super::model_of(&cell, &args.model)?;
    let measurements = vatcal_io::read_measurements(&args.measurements, &model)?;
    anyhow::ensure!(!measurements.is_empty(), "{}: no measurement rows", args.measurements.display());
    let (model, free_planes) =
        super::planes::model_with_unknown_planes(&mut cell, model, &args.model, &measurements)?;
    let design = DataDesign {
        free_planes,
        plane_distances: super::planes::plane_distances(&args.plane_distances)?,
        ..DataDesign::default()
    };
    design.check(&model).context("--plane-distance")?;
    Ok((model, measurements, design))
}

/// "N measurements (P plane contacts, R informative rows, D known plane distance(s))" — the
/// parentheses only when there are plane rows or distances.
fn counts(measurements: &[Measurement], design: &DataDesign) -> String {
    let planes = measurements.iter().filter(|m| m.target.is_plane()).count();
    let mut text = format!("{} measurements", measurements.len());
    if planes > 0 || !design.plane_distances.is_empty() {
        text += &format!(
            " ({planes} plane contact(s), {} informative rows",
            vatcal_core::informative_rows(measurements)
        );
        if !design.plane_distances.is_empty() {
            text += &format!(", {} known plane distance(s)", design.plane_distances.len());
        }
        text += ")";
    }
    text
}

/// What plane rows cannot see, said once in words (the rank test names parameters, not why).
fn plane_notes(measurements: &[Measurement], design: &DataDesign) -> Vec<String> {
    if !measurements.iter().any(|m| m.target.is_plane()) {
        return Vec::new();
    }
    let mut notes = Vec::new();
    if measurements.iter().all(|m| m.target.is_plane()) {
        notes.push(
            "note: plane rows see the TCP's height along each plane's normal (and, pressed, the tool axis's tilt) only: moving the cell along the planes or turning it about their normal is invisible".to_string(),
        );
    }
    if !vatcal_observability::sets::anchored(measurements, design) && design.constraint_rows() == 0 {
        notes.push(
            "note: every row is on a plane the cell file lacks and no --plane-distance is given: nothing fixes a length, so the scale of the chain is free".to_string(),
        );
    }
    notes
}

/// The parameters of `--params` on these data: `all` is [`preference_order`] after the free
/// planes' tilts and offsets.
fn resolve(
    args: &Args,
    model: &Model,
    measurements: &[Measurement],
    design: &DataDesign,
) -> anyhow::Result<ParamSet> {
    if args.params.trim() != "all" {
        return resolve_spec(&args.params, model, measurements, design).context("--params");
    }
    let mut v: Vec<ParamId> = design
        .free_planes
        .iter()
        .flat_map(|id| PlaneDof::ALL.map(|dof| ParamId::Plane { id: *id, dof }))
        .collect();
    v.extend(preference_order(model).0);
    Ok(ParamSet(v))
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.tolerance.is_finite() && args.tolerance > 0.0 && args.tolerance < 1.0,
        "--tolerance must be in (0, 1), got {}",
        args.tolerance
    );
    let (model, measurements, design) = load(&args)?;
    let params = resolve(&args, &model, &measurements, &design)?;
    let j = assemble_design_jacobian(&model, &measurements, &design, &params).map_err(|e| match &e {
        ObservabilityError::Model { index, .. } | ObservabilityError::NonFinite { index, .. } => {
            anyhow::anyhow!("{}: measurement row {}: {e}", args.measurements.display(), index + 1)
        }
        _ => anyhow::anyhow!("{}: {e}", args.measurements.display()),
    })?;
    let mut report =
        analyze_jacobian(j.as_ref(), &params, &AnalysisOptions { relative_tolerance: args.tolerance })?;
    report.measurement_count = measurements.len();
    report.equation_count = vatcal_core::informative_rows(&measurements) + design.constraint_rows();
    // Indices of the identifiable basis (the whole set when it is fully identifiable): the
    // indices of a rank-deficient set are ~0 and say nothing more than the rank.
    let basis = report.identifiable_set();
    let jb = select_columns(j.as_ref(), &params, &basis)?;
    // O1's m is the number of measurements (a plane contact is one pose; distance rows are none)
    let m = measurements.len();
    let raw = observability_indices_for(jb.as_ref(), &basis, ColumnScaling::None, m)?;
    let normalized = observability_indices_for(jb.as_ref(), &basis, ColumnScaling::UnitNorm, m)?;

    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{}: {}, parameter set `{}`",
        args.measurements.display(),
        counts(&measurements, &design),
        args.params
    )?;
    write!(out, "{report}")?;
    for note in plane_notes(&measurements, &design) {
        writeln!(out, "{note}")?;
    }
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
