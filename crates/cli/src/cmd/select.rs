//! `vatcal select`: Detmax (D-optimal) selection of N measurement poses from a candidate set
//! (see `docs/observability.md`).
//!
//! Writes the chosen rows with exactly the columns of the input, and prints O1..O5, rank and
//! condition number of the selection, followed by the paper's ablation: the best selections
//! restricted to one and to two calibration positions (probe rows only: plane and tracker rows
//! have no calibration position and are left out of the restricted pools). Known distances
//! (`--point-distance`, `--plane-distance`) are rows in every design (unweighted, as
//! `vatcal observability` counts them); the ablation leaves them out and says so.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::Measurement;
use vatcal_kinematics::Model;
use vatcal_observability::ObservabilityError;
use vatcal_observability::detmax::{
    AblationRow, Candidates, DetmaxOptions, Objective, SelectionIndices, detmax_with_prior,
    position_ablation, selection_indices_with_prior,
};
use vatcal_observability::sets::{DataDesign, anchored, resolve_spec};

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
    /// A known distance between two calibration positions (fixed points), `A,B,MM` or
    /// `A,B,MM,SIGMA_MM` (as `vatcal identify`; SIGMA_MM is accepted and unused): one row in
    /// every design, unweighted like `vatcal observability` counts it. It informs only the coordinates of A and B, so it
    /// matters only when they are among --params. Repeatable.
    #[arg(long = "point-distance", value_name = "A,B,MM[,SIGMA_MM]")]
    pub point_distances: Vec<String>,
    /// A known distance between two parallel contact planes of plane rows, `A,B,MM` or
    /// `A,B,MM,SIGMA_MM` (plane B lies MM above plane A along their common normal, e.g. a gauge
    /// block's top face on a table; as `vatcal identify`; SIGMA_MM is accepted and unused):
    /// three rows in every design
    /// (distance and parallelism, unweighted like `vatcal observability` counts them) that fix
    /// the scale plane rows on unknown planes leave free. Repeatable.
    #[arg(long = "plane-distance", value_name = "A,B,MM[,SIGMA_MM]")]
    pub plane_distances: Vec<String>,
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
    let model = super::model_of(&cell, &args.model)?;
    let table = vatcal_io::read_candidates(&args.candidates, &model)?;
    // plane rows: the planes the cell lacks are estimated from the candidates and analysed free
    let (model, free_planes) =
        super::planes::model_with_unknown_planes(&mut cell, model, &args.model, &table.measurements)?;
    let design = data_design(&args, &model, free_planes)?;
    if scale_free(&table.measurements, &design) {
        // the rank test at the nominal model may not see it (the rows do not fit it exactly)
        println!(
            "note: every candidate is on a plane the cell file lacks and no known distance is given: nothing fixes a length, so the scale of the chain is free; give one with --plane-distance A,B,MM or --point-distance A,B,MM"
        );
    }
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
    // the known distances: rows in every design, unweighted (as `vatcal observability`)
    let prior = design.constraint_jacobian(&model, &params).context("--point-distance / --plane-distance")?;
    for (k, d) in design.distances.iter().enumerate() {
        // a point distance informs the two points' coordinates only (select holds them fixed
        // unless --params names them)
        if (0..prior.ncols()).all(|c| prior[(k, c)] == 0.0) {
            println!(
                "note: --point-distance {},{}: neither point's coordinates are among the parameters, so this distance adds nothing to the selection",
                d.a, d.b
            );
        }
    }
    // Objectives other than O1 depend on the column scaling: select on unit columns (the
    // candidates' column norms; the prior rows scaled the same way).
    let (scaled, mut scaled_prior);
    let (work, work_prior) = if objective == Objective::O1 {
        (&candidates, prior.as_ref())
    } else {
        let f = vatcal_observability::identifiability::column_scale_factors(
            candidates.stacked(),
            &params.0,
            vatcal_observability::ColumnScaling::UnitNorm,
        );
        scaled = candidates.scaled(&f);
        scaled_prior = prior.clone();
        vatcal_observability::identifiability::scale_columns(&mut scaled_prior, &f);
        (&scaled, scaled_prior.as_ref())
    };
    let selection = detmax_with_prior(work, work_prior, &opts)
        .map_err(|e| selection_error(e, &args, &table.measurements, &design))?;
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
    if prior.nrows() > 0 {
        writeln!(
            out,
            "known distances: {} point, {} plane ({} rows in every design, unweighted; counted in the indices below, not as poses)",
            design.distances.len(),
            design.plane_distances.len(),
            prior.nrows()
        )?;
    }
    let indices = selection_indices_with_prior(&candidates, prior.as_ref(), &selection.selected)?;
    writeln!(out, "selection: {}", describe(&indices))?;
    if !args.no_ablation {
        let with_prior = prior.nrows() > 0;
        ablation(&mut out, &candidates, &table.measurements, &opts, args.count, with_prior)?;
    }
    Ok(())
}

/// The design of the selection: the unknown planes free, the known distances
/// (`--point-distance`, `--plane-distance`, parsed as `vatcal identify` does), checked against
/// the model.
fn data_design(args: &Args, model: &Model, free_planes: Vec<u32>) -> anyhow::Result<DataDesign> {
    let distances = super::planes::point_distances(&args.point_distances)?;
    let design = DataDesign {
        distances,
        free_planes,
        plane_distances: super::planes::plane_distances(&args.plane_distances)?,
        ..DataDesign::default()
    };
    design.check(model).context("--point-distance / --plane-distance")?;
    Ok(design)
}

/// True when the candidates are plane rows on planes the cell file lacks (nothing anchored) and
/// no known distance is given: nothing fixes the scale of the chain.
fn scale_free(measurements: &[Measurement], design: &DataDesign) -> bool {
    design.constraint_rows() == 0
        && measurements.iter().any(|m| m.target.is_plane())
        && !anchored(measurements, design)
}

/// The error of a failed selection, naming the candidate file; a rank-deficiency of plane rows
/// on unknown planes without a known distance names the flags that fix the scale.
fn selection_error(
    e: ObservabilityError,
    args: &Args,
    measurements: &[Measurement],
    design: &DataDesign,
) -> anyhow::Error {
    match e {
        ObservabilityError::RankDeficient { message, .. } => {
            let hint = if scale_free(measurements, design) {
                "; the candidates are plane contacts on planes the cell file lacks and nothing fixes the scale of the chain: give a known distance between two of the planes (--plane-distance A,B,MM) or two fixed points (--point-distance A,B,MM)"
            } else {
                ""
            };
            anyhow::anyhow!(
                "{}: these candidates cannot identify the parameter set `{}`: {message}{hint}",
                args.candidates.display(),
                args.params
            )
        }
        other => anyhow::anyhow!("{}: {other}", args.candidates.display()),
    }
}

/// The paper's ablation over the probe rows' calibration positions. Plane and tracker rows
/// have no calibration position: they are left out of every restricted pool (and named), and
/// without probe rows the ablation is skipped. The known distances are left out of it (said in
/// its header when there are some).
fn ablation(
    out: &mut impl Write,
    candidates: &Candidates,
    measurements: &[Measurement],
    opts: &DetmaxOptions,
    count: usize,
    with_prior: bool,
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
    let mut left_out =
        if others > 0 { format!("; {others} plane/tracker rows left out") } else { String::new() };
    if with_prior {
        left_out += "; the known distances left out";
    }
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
