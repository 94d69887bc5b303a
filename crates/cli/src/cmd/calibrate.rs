//! `vatcal calibrate`: the demo's whole sequence — plan, measurement campaign,
//! identification, discovery campaign and discovery, tracker validation, compensation and the
//! report — on the devices a devices file names, as resumable stages of one run folder
//! (`vatcal_pipeline::calibrate`; `vatcal demo` is the same pipeline on the in-process
//! virtual cell).
//!
//! Everything that can be checked without the cell (model, devices file, options, the run
//! folder's stage state) is checked before anything connects; the devices are connected only
//! when a stage that moves them runs. Ctrl-C stops the arm and the guide and leaves the stage
//! `running`: the same command with `--resume` continues it. See `docs/campaign.md`.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::bail;
use vatcal_campaign::CampaignConfig;
use vatcal_devices::DevicesFile;
use vatcal_hardware_traits::{JointLayout, MotionOptions};
use vatcal_kinematics::Model;
use vatcal_pipeline::calibrate::CellRunSetup;
use vatcal_pipeline::stop::StopFlag;
use vatcal_pipeline::{
    CalibrateOptions, DeviceSet, DeviceSource, DiscoveryStageOptions, PipelineError, RunOptions, Stage,
};

use super::shared::cell::{
    OperatorKind, RealCell, check_cell_options, connect_cell, install_stop_handler, load_nominal, one_line,
};
use super::shared::progress::BarProgress;

/// Arguments of `vatcal calibrate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Devices file (TOML): arm, guide, gauges, tracker, thermometer, simulator control.
    #[arg(long, value_name = "DEVICES.toml")]
    pub devices: PathBuf,
    /// Run folder (created if missing): plan, journals, measurements, models, report.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Continue the run folder: skip the stages done, continue the interrupted one.
    #[arg(long)]
    pub resume: bool,
    /// Stages to run, a comma list of plan, campaign, identify, discovery, validation,
    /// compensation (default: all). Without `plan` (and without --resume) each named stage is
    /// run again on the run folder; the stages before it must be done.
    #[arg(long, value_name = "LIST")]
    pub stages: Option<String>,
    /// Who re-places the probe plate.
    #[arg(long, value_enum, default_value = "console")]
    pub operator: OperatorKind,
    /// Nominal cell the robot controller believes (default: the built-in
    /// fixtures/meca500-zaber.toml).
    #[arg(long, visible_alias = "cell", value_name = "CELL.toml")]
    pub model: Option<PathBuf>,
    /// Master seed: planning, discovery and validation poses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The small sizes of `vatcal demo --quick`: 20 orientations, 3 guide steps, 40
    /// measurements, 200 random validation poses, 60 discovery measurements (the other size
    /// options are then ignored except --slices).
    #[arg(long)]
    pub quick: bool,
    /// Sizes of the run.
    #[command(flatten)]
    pub sizes: super::size_args::SizeArgs,
    /// Extra probe measurements of the discovery stage, at most (the budget,
    /// `--discovery-budget-min`, plans fewer when they do not fit).
    #[arg(long, default_value_t = 360)]
    pub discovery_count: usize,
    /// Device time the discovery measurements may take, in minutes (default 15), or `none`
    /// (`--discovery-count` measurements and the targeted batch, whatever they take): the
    /// Detmax batch is sized to fit it, less a reserve for the targeted batch, which is
    /// measured only when it fits what is left (docs/discovery.md, "The measurement budget").
    #[arg(long, value_name = "MIN|none", default_value = super::shared::budget::DEFAULT_BUDGET_MIN, value_parser = super::shared::budget::parse_budget_min)]
    pub discovery_budget_min: super::shared::budget::BudgetSeconds,
    /// Skip the discovery stage (the validation then measures the nominal and the calibrated
    /// model only).
    #[arg(long)]
    pub no_discovery: bool,
    /// Probe measurement noise per axis the discovery's size rule assumes \[mm\] (default: the
    /// paper's device budget: robot and guide repeatability, gauge error).
    #[arg(long)]
    pub probe_sigma_mm: Option<f64>,
    /// Tracker noise per axis the discovery's size rule assumes \[mm\] (default: the paper's
    /// tracker, 20 µm 3σ).
    #[arg(long)]
    pub tracker_sigma_mm: Option<f64>,
    /// Speed of the planned moves as a fraction of each device's maximum.
    #[arg(long, default_value_t = 0.25)]
    pub speed: f64,
    /// Timeout of every move and of homing \[s\].
    #[arg(long, default_value_t = 120.0)]
    pub motion_timeout_s: f64,
    /// Stop on a measurement whose auto-centering is refused instead of skipping it (the
    /// demo skips and counts them).
    #[arg(long)]
    pub stop_on_failed: bool,
    /// Never draw the progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// The cell, connected when a stage first needs it.
struct LazyCell<'a> {
    file: &'a DevicesFile,
    operator: OperatorKind,
    nominal: &'a Model,
    flag: &'a StopFlag,
    timeout: Duration,
    cell: Option<RealCell>,
}

impl DeviceSource for LazyCell<'_> {
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError> {
        if self.cell.is_none() {
            let cell = connect_cell(self.file, self.operator, self.nominal, self.flag, self.timeout)
                .map_err(|e| PipelineError::Option { option: "devices".into(), reason: format!("{e:#}") })?;
            self.cell = Some(cell);
        }
        match self.cell.as_mut() {
            Some(cell) => Ok(cell),
            None => Err(PipelineError::Option { option: "devices".into(), reason: "not connected".into() }),
        }
    }
}

/// The pipeline's options of the arguments: the nominal cell (the built-in canonical cell by
/// default) and the campaign settings.
fn run_options(args: &Args, sizes: vatcal_pipeline::RunSizes) -> anyhow::Result<RunOptions> {
    let timeout = Duration::from_secs_f64(args.motion_timeout_s);
    let nominal_cell = match &args.model {
        Some(p) => vatcal_core::CellFile::load(p)?,
        None => {
            vatcal_core::CellFile::from_toml_str(vatcal_demo::BUILT_IN_CELL, vatcal_demo::BUILT_IN_CELL_NAME)?
        }
    };
    Ok(RunOptions {
        seed: args.seed,
        nominal: nominal_cell,
        sizes,
        campaign: CampaignConfig {
            motion: MotionOptions { speed_fraction: args.speed, timeout },
            home_timeout: timeout,
            skip_failed_measurements: !args.stop_on_failed,
            show_progress: false,
            note: format!("vatcal calibrate, seed {}, devices {}", args.seed, args.devices.display()),
            ..CampaignConfig::default()
        },
    })
}

/// The discovery stage's options (`None` with `--no-discovery`): the candidate effects of the
/// chain, the instruments' noise (the paper's budget unless given).
fn discovery_options(args: &Args, nominal: &Model, count: usize) -> Option<DiscoveryStageOptions> {
    let (probe_default, tracker_default) =
        vatcal_demo::instrument_noise_mm(&vatcal_sim::NoiseBudget::paper());
    (!args.no_discovery).then(|| DiscoveryStageOptions {
        plan_effects: vatcal_pipeline::discovery_stage::plan_effects_for(nominal),
        count,
        budget_s: args.discovery_budget_min.0,
        ..DiscoveryStageOptions::new(args.seed).with_instrument_noise(
            args.probe_sigma_mm.unwrap_or(probe_default),
            args.tracker_sigma_mm.unwrap_or(tracker_default),
        )
    })
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (nominal, nominal_source) = load_nominal(args.model.as_ref())?;
    let devices_file = DevicesFile::load(&args.devices)?;
    devices_file.check_cell(&JointLayout::of(nominal.joint_kinds()), &nominal.describe_chain())?;
    check_cell_options(args.speed, args.motion_timeout_s, args.operator, &devices_file, &args.devices)?;
    let stages = match &args.stages {
        Some(list) => CalibrateOptions::parse_stages(list)?,
        None => Stage::ALL.to_vec(),
    };
    let cal = CalibrateOptions { stages, resume: args.resume };
    let mut sizes = args.sizes.run_sizes();
    let mut discovery_count = args.discovery_count;
    if args.quick {
        sizes = sizes.quick();
        discovery_count = 60;
    }
    let opts = run_options(&args, sizes)?;
    let discovery = discovery_options(&args, &nominal, discovery_count);
    let mut cal = cal;
    if discovery.is_none() {
        cal.stages.retain(|s| *s != Stage::Discover);
    }

    let timeout = Duration::from_secs_f64(args.motion_timeout_s);
    let flag = StopFlag::new();
    install_stop_handler(&flag)?;
    println!(
        "vatcal calibrate: {} with the devices of {}, stages {}{}, run folder {}",
        nominal_source,
        args.devices.display(),
        cal.stages.iter().map(|s| s.key()).collect::<Vec<_>>().join(","),
        if cal.resume { " (resume)" } else { "" },
        args.out.display()
    );
    let mut source = LazyCell {
        file: &devices_file,
        operator: args.operator,
        nominal: &nominal,
        flag: &flag,
        timeout,
        cell: None,
    };
    let mut progress = BarProgress::new(!args.quiet && std::io::stderr().is_terminal());
    let devices_name = args.devices.display().to_string();
    let result = vatcal_pipeline::calibrate(
        &opts,
        discovery.as_ref(),
        &cal,
        &mut source,
        |fit| CellRunSetup::of(&opts, &nominal_source, &devices_name, fit),
        &args.out,
        &mut progress,
    );
    progress.clear();
    match result {
        Ok(outcome) => {
            let names = |v: &[Stage]| v.iter().map(|s| s.key()).collect::<Vec<_>>().join(", ");
            println!(
                "stages run: {}{}",
                if outcome.ran.is_empty() { "none".into() } else { names(&outcome.ran) },
                if outcome.recomputed.is_empty() {
                    String::new()
                } else {
                    format!("; recomputed from the run folder: {}", names(&outcome.recomputed))
                }
            );
            if let Some(run) = &outcome.run {
                println!();
                print!("{}", vatcal_pipeline::comparison_table(&run.report));
                println!("\nreport in {} (summary.md, report.json, timing.json, plots)", args.out.display());
            }
            Ok(())
        }
        Err(e) => {
            if let Some(cell) = source.cell.as_mut() {
                cell.stop_motion();
            }
            let hint = format!(
                "the journals in {} keep every completed step; fix the cause and run the same command with --resume",
                args.out.display()
            );
            if flag.is_raised() {
                bail!("calibration interrupted: {hint}");
            }
            bail!("calibration stopped ({hint}): {}", one_line(&e))
        }
    }
}
