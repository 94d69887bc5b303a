//! `vatcal demo`: the whole simulated calibration on the virtual cell — plan, measurement
//! campaign, identification, laser-tracker validation — and a report folder.
//!
//! The work is done by `vatcal_demo::run_demo_with_progress` (the `vatcal-pipeline` run on the
//! in-process virtual cell); this module parses the arguments, draws the progress bars
//! (`shared::progress::BarProgress`, also used by `vatcal campaign` and `vatcal calibrate`), prints one line per stage and the
//! before/after table. See `docs/campaign.md`.
//!
//! A cell file that is not the canonical Meca500-on-guide cell (`--cell fixtures/ur5e.toml`)
//! runs the same pipeline on the virtual cell of that chain (no guide unless the chain has
//! one, random validation poses only: `docs/virtual-cell.md`).

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_core::CellFile;
use vatcal_demo::{DemoOptions, run_demo_with_progress};

use super::shared::progress::BarProgress;

/// Arguments of `vatcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Master seed: hidden true cell, device noise, planning and validation poses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Report folder (created if missing; the demo's files in it are replaced).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Nominal cell file (default: the built-in fixtures/meca500-zaber.toml); any serial chain
    /// runs on its own virtual cell (validation without the printing path unless it is the
    /// canonical cell).
    #[arg(long, visible_alias = "cell", value_name = "CELL.toml")]
    pub model: Option<PathBuf>,
    /// Small sizes for a quick look (any chain other than the canonical cell: 20 orientations,
    /// 3 guide steps, 40 measurements, 200 random validation poses; the canonical cell:
    /// ignored, give the sizes).
    #[arg(long)]
    pub quick: bool,
    /// Sizes of the run.
    #[command(flatten)]
    pub sizes: super::size_args::SizeArgs,
    /// Extra probe measurements of the discovery stage, at most (default: the discovery's own,
    /// 360; the budget, `--discovery-budget-min`, plans fewer when they do not fit; as
    /// `vatcal calibrate --discovery-count`).
    #[arg(long)]
    pub discovery_count: Option<usize>,
    /// Device time the discovery measurements may take, in minutes (default 15), or `none`
    /// (`--discovery-count` measurements and the targeted batch, whatever they take): the
    /// Detmax batch is sized to fit it, less a reserve for the targeted batch, which is
    /// measured only when it fits what is left (docs/discovery.md, "The measurement budget").
    #[arg(long, value_name = "MIN|none", default_value = super::shared::budget::DEFAULT_BUDGET_MIN, value_parser = super::shared::budget::parse_budget_min)]
    pub discovery_budget_min: super::shared::budget::BudgetSeconds,
    /// Hidden truth of the virtual cell: `ideal` (errors of the 34 parameters only),
    /// `paper-like` (plus the physics they miss, docs/virtual-cell.md) or a cell file of the truth.
    #[arg(long, default_value = "paper-like", value_name = "ideal|paper-like|FILE")]
    pub truth: vatcal_demo::TruthSpec,
    /// Skip the discovery stage (extra probe campaign, missing-effect discovery, true-structure
    /// fit) that runs after the calibration.
    #[arg(long)]
    pub no_discovery: bool,
    /// Never draw progress bars (they are drawn only when stdout is a terminal).
    #[arg(long)]
    pub quiet: bool,
    /// Continue the report folder (`stages.json`): skip the stages done, continue the
    /// interrupted one on a new virtual cell of the same seed (as `vatcal calibrate --resume`).
    #[arg(long)]
    pub resume: bool,
    /// Stages to run, a comma list of plan, campaign, identify, discovery, validation,
    /// compensation (default: all; as `vatcal calibrate --stages`).
    #[arg(long, value_name = "LIST")]
    pub stages: Option<String>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut opts = DemoOptions::new(args.seed)?;
    let mut chain = None;
    if let Some(path) = &args.model {
        opts.nominal = CellFile::load(path)?;
        opts.nominal_source = path.display().to_string();
        let model = super::model_of(&opts.nominal, path)?;
        if !model.is_meca500_on_guide() {
            chain = Some(model.describe_chain());
        }
    }
    opts.sizes = args.sizes.run_sizes();
    if chain.is_some() && args.quick {
        opts = opts.quick();
    }
    if let Some(count) = args.discovery_count {
        opts.discovery_count = count;
    }
    let mut progress = BarProgress::new(!args.quiet && std::io::stdout().is_terminal());
    opts.truth = args.truth.clone();
    opts.discovery = !args.no_discovery;
    opts.discovery_budget_s = args.discovery_budget_min.0;
    println!(
        "vatcal demo: simulated calibration of {}{} (seed {}, truth {}), report in {}",
        opts.nominal_source,
        chain.as_ref().map_or(String::new(), |c| format!(" ({c}, no printing path)")),
        args.seed,
        opts.truth,
        args.out.display()
    );
    if let Some(list) = &args.stages {
        opts.calibrate.stages = vatcal_pipeline::CalibrateOptions::parse_stages(list)?;
    }
    opts.calibrate.resume = args.resume;
    if opts.calibrate.resume || opts.calibrate.stages.last() != Some(&vatcal_pipeline::Stage::Report) {
        let (outcome, _) = vatcal_demo::run_demo_stages(&opts, &args.out, &mut progress)
            .with_context(|| format!("demo (seed {}, report folder {})", args.seed, args.out.display()))?;
        let names = |v: &[vatcal_pipeline::Stage]| v.iter().map(|s| s.key()).collect::<Vec<_>>().join(", ");
        println!("stages run: {}; recomputed: {}", names(&outcome.ran), names(&outcome.recomputed));
        if let Some(run) = &outcome.run {
            println!();
            print!("{}", vatcal_pipeline::comparison_table(&run.report));
        }
        return Ok(());
    }
    let outcome = run_demo_with_progress(&opts, &args.out, &mut progress)
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
