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
use vatcal_campaign::{CampaignConfig, CellDevices, ConsoleOperator};
use vatcal_core::CellFile;
use vatcal_devices::{ConnectedDevices, DevicesFile, SimControlOperator};
use vatcal_hardware_traits::{
    Clock, ErrorKind, Gauge, JointLayout, LinearAxis, MotionOptions, Operator, PositionTracker,
    ProbePlacement, RobotArm, SystemClock, Thermometer, TriCal,
};
use vatcal_kinematics::Model;
use vatcal_pipeline::plans::{discovery_campaign_stage, discovery_tour_of, tracker_campaign_stage};
use vatcal_pipeline::stop::{StopFlag, StoppableArm, StoppableAxis};
use vatcal_pipeline::{DeviceSet, PlanFolder, PlanKind, RunFolder};

use super::demo::BarProgress;

/// Who re-places the probe plate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OperatorKind {
    /// a person at the cell: the instruction is printed, Enter confirms
    Console,
    /// the simulator (`sim_control` in the devices file) moves the plate
    Auto,
}

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

/// The connected devices, wrapped so that Ctrl-C stops the arm and the guide (also the
/// devices of `vatcal calibrate`).
pub(crate) struct RealCell {
    pub(crate) arm: StoppableArm<Box<dyn RobotArm>>,
    /// the guide, on a cell whose chain has one
    pub(crate) guide: Option<StoppableAxis<Box<dyn LinearAxis>>>,
    pub(crate) probe: TriCal<Box<dyn Gauge>>,
    /// the devices file's tracker (the validation's)
    pub(crate) tracker: Option<Box<dyn PositionTracker>>,
    /// the devices file says the tracker reports in the tank frame (`frame = "tank"`): the
    /// validation checks its registration instead of registering it
    pub(crate) tracker_in_tank_frame: bool,
    pub(crate) operator: Box<dyn Operator>,
    /// the wall clock, or the simulated cell's virtual time with `--operator auto`
    pub(crate) clock: Box<dyn Clock>,
    /// the devices file's thermometer: every measurement records `temperature_c`
    pub(crate) thermometer: Option<Box<dyn Thermometer>>,
}

impl DeviceSet for RealCell {
    fn tracker_registration(&self) -> vatcal_pipeline::TrackerRegistrationMode {
        if self.tracker_in_tank_frame {
            vatcal_pipeline::TrackerRegistrationMode::Check
        } else {
            vatcal_pipeline::TrackerRegistrationMode::Register
        }
    }

    fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: self.guide.as_mut().map(|g| g as &mut dyn LinearAxis),
            probe: &mut self.probe,
            tracker: self.tracker.as_mut().map(|t| t as &mut dyn PositionTracker),
            operator: &mut self.operator,
            clock: &*self.clock,
            thermometer: self.thermometer.as_mut().map(|t| t as &mut dyn Thermometer),
        }
    }
}

impl RealCell {
    /// Stops the arm and the guide (best effort; errors are printed).
    pub(crate) fn stop_motion(&mut self) {
        if let Err(e) = self.arm.inner_mut().stop() {
            eprintln!("warning: stopping the arm: {e}");
        }
        if let Some(Err(e)) = self.guide.as_mut().map(|g| g.inner_mut().stop()) {
            eprintln!("warning: stopping the guide: {e}");
        }
    }
}

pub(crate) fn load_nominal(path: Option<&PathBuf>) -> anyhow::Result<(Model, String)> {
    let (cell, source) = match path {
        Some(p) => (CellFile::load(p)?, p.display().to_string()),
        None => (
            CellFile::from_toml_str(vatcal_demo::BUILT_IN_CELL, vatcal_demo::BUILT_IN_CELL_NAME)?,
            vatcal_demo::BUILT_IN_CELL_NAME.to_string(),
        ),
    };
    let model = Model::from_cell(&cell).with_context(|| format!("{source}: cannot build the model"))?;
    Ok((model, source))
}

/// Checks every device before anything moves; prints what it finds. An arm in error mode
/// (the fault that stopped the previous run) has its error reset; the arm is activated
/// and homed and the guide homed if needed (the campaign would do it anyway; doing it here
/// shows the operator the state of the cell first).
pub(crate) fn check_devices(cell: &mut RealCell, timeout: Duration) -> anyhow::Result<()> {
    let status = cell.arm.status().context("arm: reading the status")?;
    println!(
        "  arm: activated {}, homed {}, error {}",
        status.activated,
        status.homed,
        status.error.as_ref().map_or("none".to_string(), |(code, text)| format!("[{code}] {text}"))
    );
    if let Some((code, text)) = &status.error {
        // a fault stopped the previous run (robot error, released E-stop): the operator fixed
        // the cause and asked to continue; leaving error mode moves nothing
        println!("  arm: in error mode [{code}] {text}; resetting the error …");
        cell.arm.reset_error().context("arm: resetting the error")?;
    }
    if !(status.activated && status.homed && status.error.is_none()) {
        println!("  arm: activating and homing …");
    }
    cell.arm.activate_and_home(timeout).context("arm: activating and homing")?;
    let joints = cell.arm.joints().context("arm: reading the joints")?;
    let deg: Vec<f64> = joints.to_deg().iter().map(|v| (v * 1000.0).round() / 1000.0).collect();
    println!("  arm: joints {deg:?} deg");
    if let Some(guide) = cell.guide.as_mut() {
        let homed = guide.is_homed().context("guide: reading the state")?;
        if !homed {
            println!("  guide: not homed, homing …");
            guide.home(timeout).context("guide: homing")?;
        }
        let at = guide.position_mm().context("guide: reading the position")?;
        println!("  guide: homed, at {at:.3} mm");
    }
    let range = vatcal_hardware_traits::Probe3d::range_mm(&cell.probe);
    match vatcal_hardware_traits::Probe3d::read(&mut cell.probe) {
        Ok(r) => println!(
            "  gauges: {:.4}, {:.4}, {:.4} mm (within ±{range} mm)",
            r.gauges_mm[0], r.gauges_mm[1], r.gauges_mm[2]
        ),
        // no ball in the probe yet: the plungers rest beyond the range; they answered
        Err(e) if e.kind() == ErrorKind::OutOfRange => {
            println!("  gauges: answering; a reading is beyond ±{range} mm (no ball seated yet): {e}")
        }
        Err(e) => return Err(anyhow::Error::new(e).context("gauges: reading the three gauges")),
    }
    Ok(())
}

/// The error and its causes on one line, without repeating a cause whose text an outer error
/// already quotes (the campaign's errors carry their device error in their own message).
pub(crate) fn one_line(e: &(dyn std::error::Error + 'static)) -> String {
    let mut line = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        cause = c.source();
    }
    line
}

/// Checks the options shared by `vatcal campaign` and `vatcal calibrate`: the speed fraction,
/// the motion timeout, and a simulator control port for the automatic operator.
pub(crate) fn check_cell_options(
    speed: f64,
    motion_timeout_s: f64,
    operator: OperatorKind,
    devices_file: &DevicesFile,
    devices: &std::path::Path,
) -> anyhow::Result<()> {
    if !(speed > 0.0 && speed <= 1.0) {
        bail!("--speed must be in (0, 1], got {speed}");
    }
    if !(motion_timeout_s.is_finite() && motion_timeout_s > 0.0) {
        bail!("--motion-timeout-s must be > 0, got {motion_timeout_s}");
    }
    if operator == OperatorKind::Auto && devices_file.sim_control.is_none() {
        bail!(
            "{}: `--operator auto` needs `sim_control = {{ tcp = \"host:port\" }}` (the simulator's cell-control port)",
            devices.display()
        );
    }
    Ok(())
}

/// Connects the devices of `devices_file` (printing what it found), builds the probe for the
/// calibration positions of `nominal`, picks the operator and the clock, and checks every
/// device ([`check_devices`]; on failure the motion is stopped).
pub(crate) fn connect_cell(
    devices_file: &DevicesFile,
    operator: OperatorKind,
    nominal: &Model,
    flag: &StopFlag,
    timeout: Duration,
) -> anyhow::Result<RealCell> {
    println!("connecting:");
    let ConnectedDevices { arm, guide, gauges, sim_control, thermometer, found, tracker } =
        devices_file.connect()?;
    for line in &found {
        println!("  {line}");
    }
    // with the simulated operator, `time_s` is the simulated cell's virtual time (what the
    // in-process demo records), not the wall clock of a run sped up by `--time-scale`
    let mut clock: Box<dyn Clock> = Box::new(SystemClock);
    let operator: Box<dyn Operator> = match (operator, sim_control) {
        (OperatorKind::Auto, Some(control)) => {
            clock = Box::new(control.clock().context("reading the simulated cell's clock (TIME?)")?);
            Box::new(SimControlOperator::new(control))
        }
        (OperatorKind::Auto, None) => bail!("--operator auto: no sim_control connection"),
        (OperatorKind::Console, _) => Box::new(ConsoleOperator::stdio()),
    };
    let positions: Vec<_> =
        nominal.position_ids().into_iter().filter_map(|id| nominal.position(id).map(|p| (id, p))).collect();
    let probe = TriCal::new(gauges, devices_file.probe_config(ProbePlacement::radial_placements(&positions)))
        .context("building the TriCal probe")?;
    let mut cell = RealCell {
        arm: StoppableArm::new(arm, flag.clone()),
        guide: guide.map(|g| StoppableAxis::new(g, flag.clone())),
        probe,
        tracker,
        tracker_in_tank_frame: devices_file.tracker_reports_in_tank_frame(),
        operator,
        clock,
        thermometer,
    };
    println!("checking:");
    if let Err(e) = check_devices(&mut cell, timeout) {
        cell.stop_motion();
        return Err(e);
    }
    Ok(cell)
}

/// Installs the Ctrl-C handler: the first interrupt raises `flag` (the arm and the guide
/// stop, the journal keeps every completed step), the second exits.
pub(crate) fn install_stop_handler(flag: &StopFlag) -> anyhow::Result<()> {
    let handler_flag = flag.clone();
    ctrlc::set_handler(move || {
        if handler_flag.is_raised() {
            eprintln!("\nsecond interrupt: exiting now (the journal keeps every completed step)");
            std::process::exit(130);
        }
        eprintln!("\ninterrupt: stopping the arm and the guide …");
        handler_flag.raise();
    })
    .context("installing the Ctrl-C handler")
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    // everything that can be checked without the cell, before connecting
    let (nominal, nominal_source) = load_nominal(args.model.as_ref())?;
    let plan_folder = PlanFolder::new(&args.plan);
    let header = plan_folder.read_header()?;
    let kind = header.kind;
    let tour = match kind {
        PlanKind::Discovery => {
            discovery_tour_of(
                &plan_folder,
                &nominal,
                header.two_sided_repeats.unwrap_or(0),
                header.repeat_overshoot_deg.unwrap_or(0.0).to_radians(),
            )?
            .0
        }
        PlanKind::Calibration | PlanKind::Validation => plan_folder.read_tour(nominal.joint_kinds())?,
    };
    tour.validate(&nominal)
        .with_context(|| format!("{}: the plan does not fit {nominal_source}", args.plan.display()))?;
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
        _ => {}
    }
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

    let config = CampaignConfig {
        motion: MotionOptions { speed_fraction: args.speed, timeout },
        home_timeout: timeout,
        skip_failed_measurements: args.skip_failed,
        show_progress: false,
        note: format!("vatcal campaign, plan {}, devices {}", args.plan.display(), args.devices.display()),
        noise: {
            let (probe_sigma_mm, tracker_sigma_mm) = devices_file.noise_sigmas_mm();
            vatcal_io::metadata::NoiseMetadata { probe_sigma_mm, tracker_sigma_mm }
        },
        ..CampaignConfig::default()
    };
    let mut progress = BarProgress::new(!args.quiet && std::io::stderr().is_terminal());
    let result = match kind {
        PlanKind::Calibration => {
            vatcal_pipeline::campaign_stage(&mut cell, &nominal, &tour, &folder, config, &mut progress)
                .map(|r| (r, None))
        }
        PlanKind::Discovery => {
            discovery_campaign_stage(&mut cell, &nominal, &tour, &folder, config, &mut progress)
                .map(|r| (r, None))
        }
        PlanKind::Validation => {
            tracker_campaign_stage(&mut cell, &nominal, &tour, &folder, config, &mut progress).and_then(
                |(report, registration)| {
                    vatcal_io::write_measurements_for(
                        folder.path(kind.measurements()),
                        &report.measurements,
                        nominal.joint_kinds(),
                    )?;
                    Ok((report, registration))
                },
            )
        }
    };
    progress.clear();
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

#[cfg(test)]
mod tests {
    use super::one_line;

    #[derive(Debug)]
    struct E(&'static str, Option<Box<E>>);
    impl std::fmt::Display for E {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(self.0)
        }
    }
    impl std::error::Error for E {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            self.1.as_deref().map(|e| e as &(dyn std::error::Error + 'static))
        }
    }

    #[test]
    fn one_line_skips_causes_already_quoted() {
        let inner = E("gauge 2: timeout", None);
        let middle = E("step 3: centring: gauge 2: timeout", Some(Box::new(inner)));
        let outer = E("campaign failed", Some(Box::new(middle)));
        assert_eq!(one_line(&outer), "campaign failed: step 3: centring: gauge 2: timeout");
    }
}
