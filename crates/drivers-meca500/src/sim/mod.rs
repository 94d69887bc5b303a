//! A fake Meca500 speaking the TCP text API on loopback (protocols.md §1.12 checklist).
//!
//! [`Meca500Sim::start`] binds [`SimConfig::control_bind`] (default `127.0.0.1:0`, an ephemeral
//! port) and [`SimConfig::monitoring_bind`] if the monitoring port is enabled, and serves from one background thread until the
//! [`Meca500Sim`] is dropped. What it models:
//!
//! * banner `[3000][Connected to Meca500 R3 v9.3.0]` (model, revision and firmware
//!   configurable); one control client at a time — a second one gets `[3001]` and is closed;
//! * NUL framing both ways, LF accepted on input, empty commands ignored, leading `-`
//!   stripped, case-insensitive names, `[1001]`/`[1002]`/`[1003]` for unknown/bad syntax/bad
//!   arguments, `[3003]` for overlong input;
//! * activation and homing with durations, `[1005]`/`[1006]`/`[1011]` refusals of queued
//!   commands, the status word, error mode (stop, drop queue, pause), `ResetError`,
//!   `ResumeMotion`, `PauseMotion`, `ClearMotion` (paused afterwards), checkpoint ids 1…8191
//!   (8001…8191 are the client library's own, as on the robot), `[3040]` on
//!   firmware ≥ 10.2.1;
//! * a motion queue: `MoveJoints`/`MoveJointsRel` (constant-speed joint interpolation at the
//!   rated speeds × `SetJointVel`), `MovePose`/`MoveLin`/`MoveLinRelWrf`/`MoveLinRelTrf`
//!   (nominal kinematics + numerical IK; joint-interpolated path; duration from
//!   `SetCartLinVel`/`SetCartAngVel`), `Delay`, `SetCheckpoint` → `[3030]`, `[3012]` end of
//!   block (on by default), `[3004]` end of movement (if enabled), joint limits → `[1007]`;
//! * `[2007]` pushed on every status change to monitoring clients (and to the control client
//!   after `SetCtrlPortMonitoring(1)`), and a monitoring cycle `[2026]`, `[2027]`, enabled
//!   22xx codes, `[2230][t]` every interval;
//! * fault injection: [`Meca500Sim::inject_error`], [`Meca500Sim::fail_next_move`],
//!   [`Meca500Sim::set_estop`], [`Meca500Sim::drop_client`], [`Meca500Sim::set_stalled`].
//!
//! Time comes from [`SimConfig::clock`]; [`SimConfig::time_scale`] speeds every duration up.

mod kinematics;
mod robot;
mod server;

use std::net::{Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::{Clock, LinearFrame, SystemClock};

pub use kinematics::{
    IkFailure, forward as forward_kinematics, from_xyzabc, inverse as inverse_kinematics, to_xyzabc,
};
pub use robot::{CHECKPOINT_IDS, MotionParams, SUPPORTED_RT_CODES, SimRobot, SimState};
pub use server::Meca500Sim;

use crate::codec::Six;

/// Default joint limits \[deg\] of a Meca500 on firmware 9.2 (protocols.md §1.10).
pub const DEFAULT_JOINT_LIMITS_DEG: [(f64, f64); 6] =
    [(-175.0, 175.0), (-70.0, 90.0), (-135.0, 70.0), (-170.0, 170.0), (-115.0, 115.0), (-36_000.0, 36_000.0)];

/// Rated joint speeds [°/s] of a Meca500 R3 (the 100 % of `SetJointVel`).
pub const RATED_JOINT_SPEED_DEG_S: [f64; 6] = [150.0, 150.0, 180.0, 300.0, 300.0, 500.0];

/// A physical world behind the simulated controller (e.g. the whole virtual cell of
/// `vatcal sim-cell`): it is told about every motion and may solve relative linear moves with
/// the controller model of the cell instead of the simulator's built-in Meca500 kinematics.
///
/// The simulator calls these methods while it holds its own lock: an implementation must not
/// call back into the [`Meca500Sim`].
pub trait ArmBackend: Send + Sync + std::fmt::Debug {
    /// A motion from `from_deg` to `to_deg` starts (it passed the joint-limit check).
    fn motion_started(&self, from_deg: &Six, to_deg: &Six);

    /// Joints \[deg\] that translate the flange by `translation_mm` (expressed in the axes of
    /// the robot's base frame for [`LinearFrame::World`], of the flange for
    /// [`LinearFrame::Tool`]) from `from_deg` with the orientation kept, or the robot's refusal
    /// `(code, message)`. `None`: use the simulator's built-in kinematics.
    fn linear_relative(
        &self,
        from_deg: &Six,
        translation_mm: &Vector3<f64>,
        frame: LinearFrame,
    ) -> Option<Result<Six, (u16, String)>>;
}

/// Simulator settings.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// model word in the banner
    pub model: String,
    /// hardware revision in the banner (`R3`)
    pub revision: Option<u8>,
    /// firmware version in the banner; changes a few behaviours (`[2001]`/`[2003]` below 9.0,
    /// `[3040]` from 10.2.1)
    pub firmware: (u32, u32, u32),
    /// `GetRobotSerial` answer
    pub serial: String,
    /// joint limits \[deg\]
    pub joint_limits_deg: [(f64, f64); 6],
    /// rated joint speeds [°/s]
    pub rated_joint_speed_deg_s: [f64; 6],
    /// every simulated duration is divided by this (10 → ten times faster than real)
    pub time_scale: f64,
    /// time `ActivateRobot` takes before `[2000]` (before scaling)
    pub activation_time: Duration,
    /// time `Home` takes before `[2002]` (before scaling)
    pub homing_time: Duration,
    /// joints at power-up \[deg\]
    pub initial_joints_deg: Six,
    /// an unknown command (`[1001]`) puts the robot into error mode (\[UNC\] on recent firmware)
    pub unknown_command_enters_error_mode: bool,
    /// motion-queue capacity (overflow → `[1000]`)
    pub queue_capacity: usize,
    /// initial monitoring interval
    pub monitoring_interval: Duration,
    /// open the monitoring port too
    pub monitoring_port: bool,
    /// time source
    pub clock: Arc<dyn Clock>,
    /// address of the control port (port 0: ephemeral)
    pub control_bind: SocketAddr,
    /// address of the monitoring port, if enabled (port 0: ephemeral)
    pub monitoring_bind: SocketAddr,
    /// the physical world behind the controller, if any
    pub backend: Option<Arc<dyn ArmBackend>>,
}

impl Default for SimConfig {
    /// Meca500 R3 v9.3.0, factory limits and speeds, real time, 1 s activation, 1.5 s homing,
    /// zero joints, monitoring every 15 ms on its own port, ephemeral ports on 127.0.0.1, no
    /// backend.
    fn default() -> Self {
        Self {
            model: "Meca500".to_owned(),
            revision: Some(3),
            firmware: (9, 3, 0),
            serial: "M500-0000".to_owned(),
            joint_limits_deg: DEFAULT_JOINT_LIMITS_DEG,
            rated_joint_speed_deg_s: RATED_JOINT_SPEED_DEG_S,
            time_scale: 1.0,
            activation_time: Duration::from_millis(1000),
            homing_time: Duration::from_millis(1500),
            initial_joints_deg: [0.0; 6],
            unknown_command_enters_error_mode: false,
            queue_capacity: 1000,
            monitoring_interval: Duration::from_millis(15),
            monitoring_port: true,
            clock: Arc::new(SystemClock),
            control_bind: (Ipv4Addr::LOCALHOST, 0).into(),
            monitoring_bind: (Ipv4Addr::LOCALHOST, 0).into(),
            backend: None,
        }
    }
}

impl SimConfig {
    /// The default robot running `scale` times faster than real time.
    pub fn fast(scale: f64) -> Self {
        Self { time_scale: scale, ..Self::default() }
    }
}

/// Addresses a started simulator listens on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimAddrs {
    /// control port (the robot's 10000)
    pub control: SocketAddr,
    /// monitoring port (the robot's 10001), if enabled
    pub monitoring: Option<SocketAddr>,
}
