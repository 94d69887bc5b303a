//! `vatcal demo`: the whole simulated calibration on the virtual cell — plan, measurement
//! campaign, identification, laser-tracker validation — and a report folder.
//!
//! The work is done by `vatcal_demo::run_demo`; this module parses the arguments, prints one
//! line per stage and the before/after table. See `docs/campaign.md`.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::CellFile;
use vatcal_demo::{DemoOptions, run_demo};

/// Arguments of `vatcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Master seed: hidden true cell, device noise, planning and validation poses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Report folder (created if missing; the demo's files in it are replaced).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Nominal cell file (default: the built-in fixtures/meca500-zaber.toml).
    #[arg(long, value_name = "CELL.toml")]
    pub model: Option<PathBuf>,
    /// Random tool orientations per TCP × calibration position for the candidates.
    #[arg(long, default_value_t = 500)]
    pub orientations: usize,
    /// Guide positions of the candidates.
    #[arg(long, default_value_t = 10)]
    pub guide_steps: usize,
    /// Measurements selected by Detmax.
    #[arg(long, default_value_t = 40)]
    pub count: usize,
    /// Random validation poses measured by the tracker.
    #[arg(long, default_value_t = 573)]
    pub random_poses: usize,
    /// Slices of the validation printing path.
    #[arg(long, default_value_t = 300)]
    pub slices: usize,
    /// Hidden truth of the virtual cell: `ideal` (errors of the 34 parameters only),
    /// `paper-like` (plus the physics they miss, docs/virtual-cell.md) or a cell file of the truth.
    #[arg(long, default_value = "paper-like", value_name = "ideal|paper-like|FILE")]
    pub truth: vatcal_demo::TruthSpec,
    /// Never draw progress bars (they are drawn only when stdout is a terminal).
    #[arg(long)]
    pub quiet: bool,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut opts = DemoOptions::new(args.seed)?;
    if let Some(path) = &args.model {
        opts.nominal = CellFile::load(path)?;
        opts.nominal_source = path.display().to_string();
    }
    opts.sizes.orientations = args.orientations;
    opts.sizes.guide_steps = args.guide_steps;
    opts.sizes.count = args.count;
    opts.sizes.random_poses = args.random_poses;
    opts.sizes.slices = args.slices;
    opts.show_progress = !args.quiet && std::io::stdout().is_terminal();
    opts.truth = args.truth.clone();
    println!(
        "vatcal demo: simulated calibration of {} (seed {}, truth {}), report in {}",
        opts.nominal_source,
        args.seed,
        opts.truth,
        args.out.display()
    );
    let outcome = run_demo(&opts, &args.out, &mut |line: &str| println!("  {line}"))
        .with_context(|| format!("demo (seed {}, report folder {})", args.seed, args.out.display()))?;
    println!();
    print!("{}", outcome.comparison_table());
    let total: f64 = outcome.stage_seconds.iter().map(|(_, s)| s).sum();
    println!(
        "\ndone in {total:.1} s; see {} (summary.md, report.json, plots, calibrated.toml)",
        args.out.display()
    );
    Ok(())
}
