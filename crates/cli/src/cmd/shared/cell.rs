//! The real cell of `vatcal campaign` and `vatcal calibrate`: the devices file's devices
//! connected and checked, wrapped so that Ctrl-C stops the arm and the guide ([`RealCell`]),
//! and the options and error lines both commands share.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, bail};
use vatcal_campaign::{CellDevices, ConsoleOperator};
use vatcal_core::CellFile;
use vatcal_devices::{ConnectedDevices, DevicesFile, SimControlOperator};
use vatcal_hardware_traits::{
    Clock, ErrorKind, Gauge, LinearAxis, Operator, PositionTracker, ProbePlacement, RobotArm, SystemClock,
    Thermometer, TriCal,
};
use vatcal_kinematics::Model;
use vatcal_pipeline::DeviceSet;
use vatcal_pipeline::stop::{StopFlag, StoppableArm, StoppableAxis};

/// Who re-places the probe plate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OperatorKind {
    /// a person at the cell: the instruction is printed, Enter confirms
    Console,
    /// the simulator (`sim_control` in the devices file) moves the plate
    Auto,
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
