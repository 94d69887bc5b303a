//! `vatcal select`: Detmax (D-optimal) selection of N measurement poses from a candidate set
//! (see `docs/observability.md`).
//!
//! Writes the chosen rows with exactly the columns of the input, and prints O1..O5, rank and
//! condition number of the selection, followed by the paper's ablation: the best selections
//! restricted to one and to two calibration positions (probe rows only: plane and tracker rows
//! have no calibration position and are left out of the restricted pools).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::Measurement;
use vatcal_observability::ObservabilityError;
use vatcal_observability::detmax::{
    AblationRow, Candidates, DetmaxOptions, Objective, SelectionIndices, detmax, position_ablation,
    selection_indices,
};
use vatcal_observability::sets::{DataDesign, resolve_spec};

/// Arguments of `vatcal select`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model file (TOML).
    #[arg(long)]
    pub model: PathBuf,
    /// Candidate poses (`position,tcp,q1..qN` for the model's N joints; mm for prismatic, degrees
    /// for revolute joints; other columns are copied to the output unchanged). Plane rows
    /// (`plane,tcp,q1..qN[,normal]`) and tracker rows (`tcp,q1..qN,x,y,z`) may be mixed in;
    /// contact planes the cell file lacks are estimated from the candidate rows and their tilts
    /// and offsets are parameters the selection must identify too.
    #[arg(long)]
    pub candidates: PathBuf,
    /// Number of poses to select.
    #[arg(long)]
    pub count: usize,
    /// Master seed of the random restarts.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Number of random restarts (run in parallel; the best is kept).
    #[arg(long, default_value_t = 8)]
    pub restarts: usize,
    /// Parameters the poses must identify: `default` (`paper34` on the canonical
    /// Meca500-on-guide cell, `all-identifiable` on any other chain), `paper34`, `geometric`,
    /// `all-identifiable`, or a comma-separated list of parameter names.
    #[arg(long, default_value = "default")]
    pub params: String,
    /// Maximum depth of Mitchell-style excursions after each exchange converges (0 = plain
    /// Wynn–Mitchell exchange).
    #[arg(long, default_value_t = 3)]
    pub excursions: usize,
    /// Objective: o1 (D-optimal, fast) or o2..o5 (exact evaluation on column-normalised
    /// Jacobians, slower).
    #[arg(long, default_value = "o1")]
    pub objective: String,
    /// Candidate rows that must be selected: comma-separated 1-based data-row numbers (file
    /// order, header and comment lines not counted).
    #[arg(long, value_delimiter = ',')]
    pub fixed: Vec<usize>,
    /// Skip the 1- and 2-position ablation.
    #[arg(long)]
    pub no_ablation: bool,
    /// Output file (same columns as the input).
    #[arg(long)]
    pub out: PathBuf,
}

fn options(args: &Args, objective: Objective) -> anyhow::Result<DetmaxOptions> {
    anyhow::ensure!(args.count > 0, "--count must be at least 1");
    anyhow::ensure!(args.restarts > 0, "--restarts must be at least 1");
    let fixed = args
        .fixed
        .iter()
        .map(|row| {
            anyhow::ensure!(*row >= 1, "--fixed: row numbers start at 1, got {row}");
            Ok(row - 1)
        })
        .collect::<anyhow::Result<Vec<usize>>>()?;
    Ok(DetmaxOptions {
        restarts: args.restarts,
        seed: args.seed,
        excursions: (args.excursions > 0).then_some(args.excursions),
        fixed,
        objective,
        ..DetmaxOptions::new(args.count)
    })
}

fn describe(i: &SelectionIndices) -> String {
    format!(
        "O1 {:.4} (raw units)  O2 {:.4e}  O3 {:.4e}  O4 {:.4e}  O5 {:.4e}  cond {:.4e}  σ_min {:.4e} (unit-normalised columns)  rank {}/{}",
        i.raw.o1,
        i.normalized.o2,
        i.normalized.o3,
        i.normalized.o4,
        i.normalized.o5,
        i.normalized.condition_number,
        i.normalized.sigma_min,
        i.raw.rank,
        i.raw.parameter_count
    )
}

fn print_ablation(
    out: &mut impl Write,
    size: usize,
    rows: &[AblationRow],
    count: usize,
) -> std::io::Result<()> {
    for r in rows {
        let ids: Vec<String> = r.positions.iter().map(u32::to_string).collect();
        match &r.indices {
            Some(i) => writeln!(
                out,
                "  positions {{{}}} ({} candidates): {}",
                ids.join(","),
                r.candidate_count,
                describe(i)
            )?,
            None => writeln!(
                out,
                "  positions {{{}}}: only {} candidates, fewer than {count}; skipped",
                ids.join(","),
                r.candidate_count
            )?,
        }
    }
    if let Some((r, i)) = rows
        .iter()
        .filter_map(|r| r.indices.as_ref().map(|i| (r, i)))
        .max_by(|a, b| a.1.raw.o1.total_cmp(&b.1.raw.o1))
    {
        let ids: Vec<String> = r.positions.iter().map(u32::to_string).collect();
        writeln!(
            out,
            "  best with {size} position(s): {{{}}}, O1 {:.4}, rank {}/{}",
            ids.join(","),
            i.raw.o1,
            i.raw.rank,
            i.raw.parameter_count
        )?;
    }
    Ok(())
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let objective = Objective::parse(&args.objective).with_context(|| {
        format!("--objective must be one of o1, o2, o3, o4, o5, got `{}`", args.objective)
    })?;
    let opts = options(&args, objective)?;
    let mut cell = vatcal_core::CellFile::load(&args.model)?;
    let model = vatcal_kinematics::Model::from_cell(&cell)
        .with_context(|| format!("{}: cannot build the model", args.model.display()))?;
    let table = vatcal_io::read_candidates(&args.candidates, &model)?;
    // plane rows: the planes the cell lacks are estimated from the candidates and analysed free
    let (model, free_planes) =
        super::planes::model_with_unknown_planes(&mut cell, model, &args.model, &table.measurements)?;
    let design = DataDesign { free_planes, ..DataDesign::default() };
    let n = table.measurements.len();
    anyhow::ensure!(
        n >= args.count,
        "{}: {n} candidate poses, fewer than --count {} (choose a smaller --count or add candidates)",
        args.candidates.display(),
        args.count
    );
    if let Some(row) = opts.fixed.iter().find(|k| **k >= n) {
        anyhow::bail!(
            "--fixed: row {} does not exist ({} has {n} candidate rows)",
            row + 1,
            args.candidates.display()
        );
    }
    let params = resolve_spec(&args.params, &model, &table.measurements, &design).context("--params")?;
    let candidates = Candidates::from_measurements(&model, &table.measurements, &params)
        .map_err(|e| anyhow::anyhow!("{}: {}", args.candidates.display(), with_line(e, &table.lines)))?;
    // Objectives other than O1 depend on the column scaling: select on unit columns.
    let scaled;
    let work = if objective == Objective::O1 {
        &candidates
    } else {
        let f = vatcal_observability::identifiability::column_scale_factors(
            candidates.stacked(),
            &params.0,
            vatcal_observability::ColumnScaling::UnitNorm,
        );
        scaled = candidates.scaled(&f);
        &scaled
    };
    let selection = detmax(work, &opts).map_err(|e| match e {
        ObservabilityError::RankDeficient { message, .. } => anyhow::anyhow!(
            "{}: these candidates cannot identify the parameter set `{}`: {message}",
            args.candidates.display(),
            args.params
        ),
        other => anyhow::anyhow!("{}: {other}", args.candidates.display()),
    })?;
    table
        .write_subset(&args.out, &selection.selected)
        .with_context(|| format!("writing the selection to {}", args.out.display()))?;

    let mut out = std::io::stdout().lock();
    let won = &selection.restarts[selection.best_restart];
    writeln!(
        out,
        "selected {} of {n} candidates for {} parameters ({}; restart {} of {} won after {} exchanges) -> {}",
        selection.selected.len(),
        params.len(),
        args.params,
        selection.best_restart + 1,
        selection.restarts.len(),
        won.exchanges,
        args.out.display()
    )?;
    let indices = selection_indices(&candidates, &selection.selected)?;
    writeln!(out, "selection: {}", describe(&indices))?;
    if !args.no_ablation {
        ablation(&mut out, &candidates, &table.measurements, &opts, args.count)?;
    }
    Ok(())
}

/// The paper's ablation over the probe rows' calibration positions. Plane and tracker rows
/// have no calibration position: they are left out of every restricted pool (and named), and
/// without probe rows the ablation is skipped.
fn ablation(
    out: &mut impl Write,
    candidates: &Candidates,
    measurements: &[Measurement],
    opts: &DetmaxOptions,
    count: usize,
) -> anyhow::Result<()> {
    let positions: Vec<Option<u32>> = measurements.iter().map(|m| m.position()).collect();
    let others = positions.iter().filter(|p| p.is_none()).count();
    if others == positions.len() {
        writeln!(
            out,
            "ablation: no probe rows at calibration positions ({others} plane/tracker rows); skipped"
        )?;
        return Ok(());
    }
    let left_out = if others > 0 { format!("; {others} plane/tracker rows left out") } else { String::new() };
    let ablation_opts = DetmaxOptions { objective: Objective::O1, ..opts.clone() };
    writeln!(
        out,
        "ablation (best Detmax selection of {count} poses restricted to fewer calibration positions{left_out}):"
    )?;
    for size in [1, 2] {
        let rows = position_ablation(candidates, &positions, size, &ablation_opts)?;
        print_ablation(out, size, &rows, count)?;
    }
    Ok(())
}

/// Adds the file line to an error that names a candidate index.
fn with_line(e: ObservabilityError, lines: &[u64]) -> String {
    match &e {
        ObservabilityError::Model { index, .. } | ObservabilityError::NonFinite { index, .. } => {
            format!("line {}: {e}", lines.get(*index).copied().unwrap_or(0))
        }
        _ => e.to_string(),
    }
}
