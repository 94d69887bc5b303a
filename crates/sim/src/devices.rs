//! The simulated devices: each implements one trait of `vatcal-hardware-traits` on the shared
//! [`World`](crate::world::World).

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::{
    ArmJoints, ArmStatus, Clock, Error, ErrorKind, Gauge, LinearAxis, LinearFrame, MotionOptions, Operator,
    OperatorInstruction, PositionTracker, Result, RobotArm, Thermometer, VirtualClock,
};

use crate::controller::{LinearMoveError, translate_flange, world_displacement};
use crate::noise::{bits, key};
use crate::world::World;

/// I/O timeout of the simulated devices (used when a fault makes a reading hang).
pub const SIM_IO_TIMEOUT: Duration = Duration::from_secs(2);

/// Shared handle to the world.
#[derive(Debug, Clone)]
pub(crate) struct Shared {
    pub world: Arc<Mutex<World>>,
    pub clock: VirtualClock,
}

impl Shared {
    pub fn lock(&self) -> MutexGuard<'_, World> {
        self.world.lock().unwrap_or_else(|p| p.into_inner())
    }
}

fn check_speed(device: &str, options: &MotionOptions) -> Result<()> {
    if options.speed_fraction > 0.0 && options.speed_fraction <= 1.0 {
        Ok(())
    } else {
        Err(Error::new(
            ErrorKind::OutOfRange,
            device,
            format!("speed fraction {} is not in (0, 1]", options.speed_fraction),
        ))
    }
}

/// Blocks (in virtual time) until `end`, or fails after `timeout`.
fn wait_until(clock: &VirtualClock, device: &str, end: Duration, timeout: Duration) -> Result<()> {
    let remaining = end.saturating_sub(clock.now());
    if remaining > timeout {
        clock.sleep(timeout);
        return Err(Error::timeout(device, "motion", timeout));
    }
    clock.sleep(remaining);
    Ok(())
}

/// The simulated robot arm: the arm joints of the cell's chain
/// ([`JointLayout`](vatcal_hardware_traits::JointLayout) of the nominal model — the six
/// Meca500 joints on the canonical cell, all joints of a chain without a guide). Its
/// controller believes the **nominal** model: joint moves are exact, relative linear moves are
/// solved on the nominal geometry while the physics is the true one. [`LinearFrame::World`] is
/// the axes of the frame the arm is mounted on (MDH frame 1, the carriage, on a cell with a
/// guide; frame 0, the robot base, otherwise); [`LinearFrame::Tool`] the flange axes (MDH frame
/// N). Error codes follow the Meca500: 1005/1006 not activated/homed, 1007 joint limit, 1011 in
/// error, 1012 singularity; a target with another number of joints is refused
/// ([`ErrorKind::OutOfRange`]).
#[derive(Debug, Clone)]
pub struct SimArm {
    pub(crate) shared: Shared,
}

const ARM: &str = "sim arm";

impl SimArm {
    fn ready(w: &World) -> Result<()> {
        if !w.arm.activated || !w.arm.homed {
            return Err(Error::new(ErrorKind::NotHomed, ARM, "activate and home the arm first"));
        }
        if let Some((code, msg)) = &w.arm.error {
            return Err(Error::new(
                ErrorKind::DeviceFault { code: 1011 },
                ARM,
                format!("in error ({code}: {msg})"),
            ));
        }
        if w.arm.motion.moving(w.now()) {
            return Err(Error::new(ErrorKind::Busy, ARM, "still moving"));
        }
        Ok(())
    }

    fn fault(w: &mut World, code: i32, message: String) -> Error {
        w.arm.error = Some((code, message.clone()));
        Error::new(ErrorKind::DeviceFault { code }, ARM, message)
    }

    fn check_limits(w: &mut World, arm: &ArmJoints) -> Result<()> {
        for j in 0..arm.len() {
            let joint = w.layout.cell_joint(j);
            let Some((lo, hi)) = w.nominal.joint_limit(joint) else { continue };
            if !(lo..=hi).contains(&arm[j]) {
                let msg = if w.nominal.is_revolute(joint) {
                    format!(
                        "joint J{} target {:.3} deg is outside [{:.1}, {:.1}] deg",
                        j + 1,
                        arm[j].to_degrees(),
                        lo.to_degrees(),
                        hi.to_degrees()
                    )
                } else {
                    format!("joint J{} target {:.3} mm is outside [{lo:.1}, {hi:.1}] mm", j + 1, arm[j])
                };
                return Err(Self::fault(w, 1007, msg));
            }
        }
        Ok(())
    }
}

impl RobotArm for SimArm {
    fn joint_count(&self) -> usize {
        self.shared.lock().arm_count()
    }

    fn activate_and_home(&mut self, timeout: Duration) -> Result<()> {
        let homing = {
            let w = self.shared.lock();
            if w.arm.activated && w.arm.homed {
                return Ok(());
            }
            Duration::from_secs_f64(w.config.timing.homing_s)
        };
        if homing > timeout {
            self.shared.clock.sleep(timeout);
            return Err(Error::timeout(ARM, "activation and homing", timeout));
        }
        self.shared.clock.sleep(homing);
        let mut w = self.shared.lock();
        w.arm.activated = true;
        w.arm.homed = true;
        Ok(())
    }

    fn status(&mut self) -> Result<ArmStatus> {
        let w = self.shared.lock();
        Ok(ArmStatus {
            activated: w.arm.activated,
            homed: w.arm.homed,
            moving: w.arm.motion.moving(w.now()),
            error: w.arm.error.clone(),
        })
    }

    fn joints(&mut self) -> Result<ArmJoints> {
        Ok(self.shared.lock().arm_joints())
    }

    fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> Result<()> {
        check_speed(ARM, options)?;
        let mut w = self.shared.lock();
        w.layout.check_arm(target)?;
        Self::ready(&w)?;
        if !target.as_slice().iter().all(|v| v.is_finite()) {
            return Err(Self::fault(&mut w, 1003, "non-finite joint target".into()));
        }
        Self::check_limits(&mut w, target)?;
        let n = w.arm_count();
        let mut parts = bits(target.as_slice());
        parts.extend(bits(&w.arm.motion.to[..n]));
        let event = key(w.seed, "arm-joints", &parts);
        w.start_arm_motion(target, options.speed_fraction, event);
        Ok(())
    }

    fn move_linear_relative(
        &mut self,
        displacement_mm: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> Result<()> {
        check_speed(ARM, options)?;
        let mut w = self.shared.lock();
        Self::ready(&w)?;
        if !displacement_mm.iter().all(|v| v.is_finite()) {
            return Err(Self::fault(&mut w, 1003, "non-finite displacement".into()));
        }
        let start = w.cell_joints(w.guide.motion.to[0], &w.to_arm(&w.arm.motion.to));
        let delta = world_displacement(&w.nominal, &start, displacement_mm, frame);
        let executed = delta * w.config.faults.linear_move_gain;
        let target = match translate_flange(&w.nominal, &start, &executed) {
            Ok(q) => w.layout.arm(&q),
            Err(LinearMoveError::Singular) => {
                return Err(Self::fault(&mut w, 1012, "linear move would cross a singularity".into()));
            }
            Err(LinearMoveError::Limit(joint)) => {
                return Err(Self::fault(
                    &mut w,
                    1007,
                    format!("linear move would put joint {joint} over its limit"),
                ));
            }
        };
        let n = w.arm_count();
        let mut parts = bits(&w.arm.motion.to[..n]);
        parts.extend(bits(displacement_mm.as_slice()));
        parts.push(frame as u64);
        let event = key(w.seed, "arm-linear", &parts);
        w.linear_moves.push(delta);
        w.start_arm_motion(&target, options.speed_fraction, event);
        Ok(())
    }

    fn wait_idle(&mut self, timeout: Duration) -> Result<()> {
        let end = {
            let w = self.shared.lock();
            if let Some((code, msg)) = &w.arm.error {
                return Err(Error::new(ErrorKind::DeviceFault { code: *code }, ARM, msg.clone()));
            }
            w.arm.motion.end
        };
        wait_until(&self.shared.clock, ARM, end, timeout)
    }

    fn stop(&mut self) -> Result<()> {
        let mut w = self.shared.lock();
        let now = w.now();
        let here = w.arm.motion.position(now);
        w.arm.motion.to = here;
        w.arm.motion.end = now;
        Ok(())
    }

    fn reset_error(&mut self) -> Result<()> {
        self.shared.lock().arm.error = None;
        Ok(())
    }
}

/// The simulated Zaber guide (only on a cell whose chain has one, see
/// [`VirtualCell::guide`](crate::VirtualCell::guide)): reports the commanded position, is
/// physically off by its repeatability error (drawn per move).
#[derive(Debug, Clone)]
pub struct SimGuide {
    pub(crate) shared: Shared,
}

const GUIDE: &str = "sim guide";

impl LinearAxis for SimGuide {
    fn home(&mut self, timeout: Duration) -> Result<()> {
        let end = {
            let mut w = self.shared.lock();
            w.guide.homed = true;
            w.start_guide_motion(0.0, 1.0);
            w.guide.motion.end
        };
        wait_until(&self.shared.clock, GUIDE, end, timeout)
    }

    fn is_homed(&mut self) -> Result<bool> {
        Ok(self.shared.lock().guide.homed)
    }

    fn position_mm(&mut self) -> Result<f64> {
        Ok(self.shared.lock().guide_mm())
    }

    fn move_absolute_mm(&mut self, target_mm: f64, options: &MotionOptions) -> Result<()> {
        check_speed(GUIDE, options)?;
        let mut w = self.shared.lock();
        if !w.guide.homed {
            return Err(Error::new(ErrorKind::NotHomed, GUIDE, "home the guide first"));
        }
        if w.guide.motion.moving(w.now()) {
            return Err(Error::new(ErrorKind::Busy, GUIDE, "still moving"));
        }
        let (lo, hi) = w.nominal.joint_limits()[0];
        if !target_mm.is_finite() || !(lo..=hi).contains(&target_mm) {
            return Err(Error::new(
                ErrorKind::OutOfRange,
                GUIDE,
                format!("target {target_mm} mm is outside the stroke [{lo}, {hi}] mm"),
            ));
        }
        w.start_guide_motion(target_mm, options.speed_fraction);
        Ok(())
    }

    fn wait_idle(&mut self, timeout: Duration) -> Result<()> {
        let end = self.shared.lock().guide.motion.end;
        wait_until(&self.shared.clock, GUIDE, end, timeout)
    }

    fn stop(&mut self) -> Result<()> {
        let mut w = self.shared.lock();
        let now = w.now();
        let here = w.guide.motion.position(now);
        w.guide.motion.to = here;
        w.guide.motion.end = now;
        Ok(())
    }
}

/// One simulated gauge of the TriCal (index 0..3): flat tip on the nearest ball, true (tilted)
/// axis, uniform error within the gauge's maximum error, ±range.
#[derive(Debug, Clone)]
pub struct SimGauge {
    pub(crate) shared: Shared,
    pub(crate) index: usize,
}

impl Gauge for SimGauge {
    fn read_mm(&mut self) -> Result<f64> {
        let (timeouts, read_s) = {
            let w = self.shared.lock();
            (w.config.faults.gauge_timeouts, w.config.timing.gauge_read_s)
        };
        if timeouts {
            self.shared.clock.sleep(SIM_IO_TIMEOUT);
            return Err(Error::timeout(format!("sim gauge {}", self.index + 1), "reading", SIM_IO_TIMEOUT));
        }
        self.shared.clock.sleep(Duration::from_secs_f64(read_s));
        self.shared.lock().read_gauge(self.index)
    }

    fn preset_mm(&mut self, value_mm: f64) -> Result<()> {
        self.shared.lock().preset_gauge(self.index, value_mm)
    }
}

/// The simulated laser tracker: true position of the SMR (taken at the ball centre of TCP
/// `target`) plus Gaussian noise.
#[derive(Debug, Clone)]
pub struct SimTracker {
    pub(crate) shared: Shared,
}

impl PositionTracker for SimTracker {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        let read_s = self.shared.lock().config.timing.tracker_read_s;
        self.shared.clock.sleep(Duration::from_secs_f64(read_s));
        self.shared.lock().track(target)
    }
}

/// The simulated thermometer of a cell with a temperature channel
/// ([`CellPhysics::thermal`](crate::CellPhysics::thermal)): the cell's temperature at the
/// virtual time — the one the truth's thermal drift sees — with the noise and resolution of
/// [`ThermometerSpec`](crate::ThermometerSpec). A reading takes no virtual time.
#[derive(Debug, Clone)]
pub struct SimThermometer {
    pub(crate) shared: Shared,
}

impl Thermometer for SimThermometer {
    fn read_c(&mut self) -> Result<f64> {
        self.shared.lock().thermometer_c().ok_or_else(|| {
            Error::new(
                ErrorKind::Disconnected,
                "sim thermometer",
                "the virtual cell has no temperature channel",
            )
        })
    }
}

/// The simulated operator: does what it is asked at once (plus the configured time).
#[derive(Debug, Clone)]
pub struct SimOperator {
    pub(crate) shared: Shared,
}

const OPERATOR: &str = "sim operator";

impl Operator for SimOperator {
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()> {
        let mut w = self.shared.lock();
        match instruction {
            OperatorInstruction::PlaceProbe { position } => {
                if w.truth.position(*position).is_none() {
                    return Err(Error::new(
                        ErrorKind::OutOfRange,
                        OPERATOR,
                        format!("there is no calibration position {position}"),
                    ));
                }
                w.plate = Some(*position);
                w.master_ball = false;
                let event = key(w.seed, "plate", &[u64::from(*position)]);
                w.new_epoch(event);
                let s = w.config.timing.operator_s;
                drop(w);
                self.shared.clock.sleep(Duration::from_secs_f64(s));
            }
            OperatorInstruction::SeatMasterBall { position } => {
                if w.plate != Some(*position) {
                    return Err(Error::new(
                        ErrorKind::Other,
                        OPERATOR,
                        format!("the plate is at {:?}, not at position {position}", w.plate),
                    ));
                }
                w.master_ball = true;
            }
            OperatorInstruction::RemoveMasterBall => w.master_ball = false,
            // the nest SMR sits where the master ball's centre would: the tracker reads the
            // probe origin whenever the plate is placed
            OperatorInstruction::SeatNestSmr { .. }
            | OperatorInstruction::RemoveNestSmr
            | OperatorInstruction::ConfirmMotion { .. } => {}
        }
        Ok(())
    }
}
