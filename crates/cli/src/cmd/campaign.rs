//! `vatcal campaign`: run a planned measurement campaign on the real cell (or on
//! `vatcal sim-cell`) described by a devices file.
//!
//! Order: read the model, the plan folder and the devices file (every error before anything
//! connects) → connect → check every device and print what was found → run the tour with
//! auto-centering and the operator prompts, journaling every step → `measurements.csv`.
//!
//! The plan folder says its kind (`summary.json`, `vatcal plan --kind`): a calibration plan
//! writes `campaign.journal` and `measurements.csv`; a discovery plan runs with its two-sided
//! repeats into `discovery.journal` and `discovery_measurements.csv`; a validation plan needs
//! the devices file's tracker, registers it first (`tracker-registration.json`, as `vatcal
//! calibrate` does) and writes `validation.journal` and `validation_measurements.csv`
//! (tracker rows in the tank frame). The same functions as `vatcal calibrate`'s stages
//! (`vatcal_pipeline::plans`).
//! Ctrl-C (or SIGTERM) stops the arm and the guide and leaves a journal that `--resume`
//! continues. See `docs/campaign.md`.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, bail};
use vatcal_campaign::{CampaignConfig, CampaignPlan, CampaignReport};
use vatcal_devices::DevicesFile;
use vatcal_hardware_traits::{JointLayout, MotionOptions};
use vatcal_kinematics::Model;
use vatcal_pipeline::plans::{discovery_campaign_stage, discovery_tour_of, tracker_campaign_stage};
use vatcal_pipeline::stop::StopFlag;
use vatcal_pipeline::{PipelineError, PlanFolder, PlanKind, RegistrationReport, RunFolder};

pub use super::shared::cell::OperatorKind;
use super::shared::cell::{
    RealCell, check_cell_options, connect_cell, install_stop_handler, load_nominal, one_line,
};
use super::shared::progress::BarProgress;

/// Arguments of `vatcal campaign`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Devices file (TOML): which driver and address for the arm, guide and gauges.
    #[arg(long, value_name = "DEVICES.toml")]
    pub devices: PathBuf,
    /// Plan folder written by `vatcal plan` (its `tour.csv` is run; `summary.json` says whether
    /// it is a calibration, discovery or validation plan).
    #[arg(long, value_name = "DIR")]
    pub plan: PathBuf,
    /// Run folder (created if missing): `campaign.journal`, `measurements.csv` (calibration
    /// plans), `discovery.journal`, `discovery_measurements.csv` (discovery plans),
    /// `tracker-registration.json`, `validation.journal`, `validation_measurements.csv`
    /// (validation plans).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Continue the journal in `--out` (after a crash, Ctrl-C or a device fault).
    #[arg(long)]
    pub resume: bool,
    /// Who re-places the probe plate.
    #[arg(long, value_enum, default_value = "console")]
    pub operator: OperatorKind,
    /// Nominal cell the robot controller believes (default: the built-in
    /// fixtures/meca500-zaber.toml); must be the one the plan was made with.
    #[arg(long, value_name = "CELL.toml")]
    pub model: Option<PathBuf>,
    /// Speed of the planned moves as a fraction of each device's maximum.
    #[arg(long, default_value_t = 0.25)]
    pub speed: f64,
    /// Timeout of every move and of homing \[s\].
    #[arg(long, default_value_t = 120.0)]
    pub motion_timeout_s: f64,
    /// Skip a measurement whose auto-centering is refused (recorded in the journal) instead
    /// of stopping.
    #[arg(long)]
    pub skip_failed: bool,
    /// Never draw the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The plan folder's kind and its campaign (a discovery plan's tour with its two-sided
/// repeats), checked against the nominal model.
fn read_plan(args: &Args, nominal: &Model, nominal_source: &str) -> anyhow::Result<(PlanKind, CampaignPlan)> {
    let plan_folder = PlanFolder::new(&args.plan);
    let header = plan_folder.read_header()?;
    let tour = match header.kind {
        PlanKind::Discovery => {
            discovery_tour_of(
                &plan_folder,
                nominal,
                header.two_sided_repeats.unwrap_or(0),
                header.repeat_overshoot_deg.unwrap_or(0.0).to_radians(),
            )?
            .0
        }
        PlanKind::Calibration | PlanKind::Validation => plan_folder.read_tour(nominal.joint_kinds())?,
    };
    tour.validate(nominal)
        .with_context(|| format!("{}: the plan does not fit {nominal_source}", args.plan.display()))?;
    Ok((header.kind, tour))
}

/// A campaign already started in the run folder needs `--resume`; `--resume` needs one.
fn check_journal(args: &Args, kind: PlanKind, folder: &RunFolder) -> anyhow::Result<()> {
    let journal = folder.path(kind.journal());
    // a validation campaign starts with the tracker registration, journaled too
    let started = journal.exists() || (kind == PlanKind::Validation && folder.validation_started());
    match (started, args.resume) {
        (true, false) => bail!(
            "{} exists: pass --resume to continue that campaign, or choose another --out",
            if journal.exists() {
                journal.display().to_string()
            } else {
                format!("{}'s registration", args.out.display())
            }
        ),
        (false, true) => bail!("--resume: {} does not exist (nothing to resume)", journal.display()),
        _ => Ok(()),
    }
}

/// The campaign settings of the options (the devices file's noise recorded with the data).
fn campaign_config(args: &Args, devices_file: &DevicesFile) -> CampaignConfig {
    let timeout = Duration::from_secs_f64(args.motion_timeout_s);
    CampaignConfig {
        motion: MotionOptions { speed_fraction: args.speed, timeout },
        home_timeout: timeout,
        skip_failed_measurements: args.skip_failed,
        show_progress: false,
        note: format!("vatcal campaign, plan {}, devices {}", args.plan.display(), args.devices.display()),
        noise: {
            let (probe_sigma_mm, tracker_sigma_mm) = devices_file.noise_sigmas_mm();
            vatcal_io::metadata::NoiseMetadata {
                probe_sigma_mm,
                tracker_sigma_mm,
                orientation_sigma_mrad: None,
            }
        },
        ..CampaignConfig::default()
    }
}

/// Runs the campaign of a plan of `kind` (the pipeline's stage for that kind) on the cell.
fn run_kind(
    kind: PlanKind,
    cell: &mut RealCell,
    nominal: &Model,
    tour: &CampaignPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut BarProgress,
) -> Result<(CampaignReport, Option<RegistrationReport>), PipelineError> {
    match kind {
        PlanKind::Calibration => {
            vatcal_pipeline::campaign_stage(cell, nominal, tour, folder, config, progress).map(|r| (r, None))
        }
        PlanKind::Discovery => {
            discovery_campaign_stage(cell, nominal, tour, folder, config, progress).map(|r| (r, None))
        }
        PlanKind::Validation => {
            let (report, registration) =
                tracker_campaign_stage(cell, nominal, tour, folder, config, progress)?;
            vatcal_io::write_measurements_for(
                folder.path(kind.measurements()),
                &report.measurements,
                nominal.joint_kinds(),
            )?;
            Ok((report, registration))
        }
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    // everything that can be checked without the cell, before connecting
    let (nominal, nominal_source) = load_nominal(args.model.as_ref())?;
    let (kind, tour) = read_plan(&args, &nominal, &nominal_source)?;
    let devices_file = DevicesFile::load(&args.devices)?;
    devices_file.check_cell(&JointLayout::of(nominal.joint_kinds()), &nominal.describe_chain())?;
    check_cell_options(args.speed, args.motion_timeout_s, args.operator, &devices_file, &args.devices)?;
    if kind == PlanKind::Validation && devices_file.tracker.is_none() {
        bail!(
            "{}: {} is a validation plan and the devices file has no `tracker` (docs/formats.md, devices file)",
            args.devices.display(),
            args.plan.display()
        );
    }
    let folder = RunFolder::new(&args.out);
    check_journal(&args, kind, &folder)?;
    folder.create()?;

    let flag = StopFlag::new();
    install_stop_handler(&flag)?;

    println!(
        "vatcal campaign: {} plan, {} measurements in {} steps from {}, devices {}, run folder {}",
        kind.key(),
        tour.measurement_count(),
        tour.steps.len(),
        args.plan.display(),
        args.devices.display(),
        args.out.display()
    );
    let timeout = Duration::from_secs_f64(args.motion_timeout_s);
    let mut cell = connect_cell(&devices_file, args.operator, &nominal, &flag, timeout)?;
    let config = campaign_config(&args, &devices_file);
    let mut progress = BarProgress::new(!args.quiet && std::io::stderr().is_terminal());
    let result = run_kind(kind, &mut cell, &nominal, &tour, &folder, config, &mut progress);
    progress.clear();
    let journal = folder.path(kind.journal());
    match result {
        Ok((report, registration)) => {
            if let Some(r) = registration {
                println!("tracker registration ({}): {}", r.mode, r.registration.summary());
            }
            println!(
                "campaign complete: {} measurements ({} skipped){}; wrote {}",
                report.measurements.len(),
                report.skipped,
                report.resumed_at_step.map_or(String::new(), |s| format!(", resumed at step {s}")),
                folder.path(kind.measurements()).display()
            );
            Ok(())
        }
        Err(e) => {
            cell.stop_motion();
            let done = vatcal_campaign::Journal::open(&journal).map(|j| j.measurements().len()).unwrap_or(0);
            let hint = format!(
                "{done} measurements are safe in {}; fix the cause and run the same command with --resume",
                journal.display()
            );
            if flag.is_raised() {
                bail!("campaign interrupted: {hint}");
            }
            bail!("campaign stopped ({hint}): {}", one_line(&e))
        }
    }
}
