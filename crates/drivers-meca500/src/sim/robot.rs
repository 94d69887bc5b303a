//! The simulated controller: a pure state machine fed with command frames and the current time,
//! returning the messages to send. No sockets here (see `server.rs`).

use std::collections::{BTreeSet, VecDeque};
use std::time::Duration;

use nalgebra::Isometry3;
use vatcal_hardware_traits::LinearFrame;

use super::SimConfig;
use super::kinematics::{self, IkFailure};
use crate::codec::{
    Banner, Command, RealTimeCodes, Reply, Six, StatusWord, code, format_number, parse_command,
};

/// Real-time monitoring codes the simulator can stream.
pub const SUPPORTED_RT_CODES: [u16; 4] =
    [code::RT_TARGET_JOINTS, code::RT_TARGET_CART, code::RT_JOINTS, code::RT_CART];

/// Checkpoint ids the robot accepts: 1…8000 for applications, 8001…8191 reserved for the
/// client library's own waits (mecademicpy's `WaitIdle` and friends); the real robot accepts
/// the whole range (protocols.md §1.5).
pub const CHECKPOINT_IDS: std::ops::RangeInclusive<u32> = 1..=8191;

/// Error codes that `ResetError` cannot clear.
const NOT_RESETTABLE: [u16; 6] = [
    code::MASTERING_LOST,
    code::NOT_RESETTABLE,
    code::DRIVE_COMM,
    code::INIT_FAILED,
    code::MAINTENANCE,
    code::ESTOP,
];

/// Motion-parameter defaults restored by every activation (§1.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionParams {
    /// `SetJointVel` \[%\]
    pub joint_vel_pct: f64,
    /// `SetJointAcc` \[%\]
    pub joint_acc_pct: f64,
    /// `SetCartLinVel` \[mm/s\]
    pub cart_lin_vel_mm_s: f64,
    /// `SetCartAngVel` [°/s]
    pub cart_ang_vel_deg_s: f64,
    /// `SetCartAcc` \[%\]
    pub cart_acc_pct: f64,
    /// `SetBlending` \[%\]
    pub blending_pct: f64,
    /// `SetJointVelLimit` \[%\]
    pub joint_vel_limit_pct: f64,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            joint_vel_pct: 25.0,
            joint_acc_pct: 80.0,
            cart_lin_vel_mm_s: 150.0,
            cart_ang_vel_deg_s: 45.0,
            cart_acc_pct: 50.0,
            blending_pct: 100.0,
            joint_vel_limit_pct: 100.0,
        }
    }
}

/// A snapshot of the simulated controller, for tests and the CLI.
#[derive(Debug, Clone, PartialEq)]
pub struct SimState {
    /// the status word the robot would report now
    pub status: StatusWord,
    /// joints now \[deg\]
    pub joints_deg: Six,
    /// commands waiting in the motion queue
    pub queue_len: usize,
    /// current error (code, text)
    pub error: Option<(u16, String)>,
    /// motion parameters in force
    pub params: MotionParams,
    /// `SetCtrlPortMonitoring` state
    pub ctrl_port_monitoring: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Active {
    Move { from: Six, to: Six, start: Duration, duration: Duration },
    Delay { until: Duration },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pending {
    Activation,
    Homing,
}

/// The simulated controller.
#[derive(Debug)]
pub struct SimRobot {
    config: SimConfig,
    activated: bool,
    homed: bool,
    error: Option<(u16, String)>,
    paused_since: Option<Duration>,
    estop_pressed: bool,
    joints_deg: Six,
    active: Option<Active>,
    queue: VecDeque<Command>,
    params: MotionParams,
    trf: Isometry3<f64>,
    wrf: Isometry3<f64>,
    eob_events: bool,
    eom_events: bool,
    ctrl_port_monitoring: bool,
    rt_codes: BTreeSet<u16>,
    monitoring_interval_s: f64,
    pending: Option<(Duration, Pending)>,
    last_eob: bool,
    last_pushed_status: Option<StatusWord>,
    fail_next_move: Option<u16>,
}

impl SimRobot {
    /// A deactivated, unhomed, error-free robot at `config.initial_joints_deg`.
    pub fn new(config: SimConfig) -> Self {
        Self {
            joints_deg: config.initial_joints_deg,
            monitoring_interval_s: config.monitoring_interval.as_secs_f64(),
            config,
            activated: false,
            homed: false,
            error: None,
            paused_since: None,
            estop_pressed: false,
            active: None,
            queue: VecDeque::new(),
            params: MotionParams::default(),
            trf: Isometry3::identity(),
            wrf: Isometry3::identity(),
            eob_events: true,
            eom_events: false,
            ctrl_port_monitoring: false,
            rt_codes: BTreeSet::new(),
            pending: None,
            last_eob: true,
            last_pushed_status: None,
            fail_next_move: None,
        }
    }

    /// The banner announced on connect.
    pub fn banner(&self) -> Banner {
        Banner {
            model: self.config.model.clone(),
            revision: self.config.revision,
            virtual_robot: false,
            safe_boot: false,
            version: self.config.firmware,
        }
    }

    /// True while an activation or homing is in progress: further commands wait in the input
    /// buffer until it completes (requests are answered in order).
    pub fn is_busy(&self) -> bool {
        self.pending.is_some()
    }

    /// Whether the monitoring stream is mirrored onto the control port.
    pub fn ctrl_port_monitoring(&self) -> bool {
        self.ctrl_port_monitoring
    }

    /// Monitoring interval.
    pub fn monitoring_interval(&self) -> Duration {
        secs(self.monitoring_interval_s)
    }

    /// The status word now.
    pub fn status_word(&self, now: Duration) -> StatusWord {
        let moving = matches!(self.active, Some(Active::Move { .. })) && self.paused_since.is_none();
        let _ = now;
        StatusWord {
            activated: self.activated,
            homed: self.homed,
            simulation: false,
            error: self.error.is_some(),
            paused: self.paused_since.is_some(),
            end_of_block: self.active.is_none() && self.queue.is_empty(),
            end_of_movement: !moving,
        }
    }

    /// A snapshot.
    pub fn snapshot(&self, now: Duration) -> SimState {
        SimState {
            status: self.status_word(now),
            joints_deg: self.joints_now(now),
            queue_len: self.queue.len(),
            error: self.error.clone(),
            params: self.params,
            ctrl_port_monitoring: self.ctrl_port_monitoring,
        }
    }

    /// `[2007]` if the status changed since the last call (the "push on every change" rule).
    pub fn status_change(&mut self, now: Duration) -> Option<Reply> {
        let s = self.status_word(now);
        if self.last_pushed_status == Some(s) {
            return None;
        }
        self.last_pushed_status = Some(s);
        Some(s.to_reply())
    }

    /// Forgets the last pushed status (a new monitoring client gets the full state).
    pub fn force_status_push(&mut self) {
        self.last_pushed_status = None;
    }

    /// Joints now \[deg\] (interpolated during a move).
    pub fn joints_now(&self, now: Duration) -> Six {
        match self.active {
            Some(Active::Move { from, to, start, duration }) => {
                let t = self.paused_since.unwrap_or(now).saturating_sub(start);
                let s = if duration.is_zero() {
                    1.0
                } else {
                    (t.as_secs_f64() / duration.as_secs_f64()).min(1.0)
                };
                let mut q = from;
                for ((qi, f), t) in q.iter_mut().zip(from).zip(to) {
                    *qi = f + s * (t - f);
                }
                q
            }
            _ => self.joints_deg,
        }
    }

    /// TRF pose in the WRF for joints `q` \[deg\].
    fn tool_pose(&self, q: &Six) -> Isometry3<f64> {
        self.wrf.inverse() * kinematics::forward(q) * self.trf
    }

    /// Sets the joints directly (test hook; refused while a motion is active).
    pub fn set_joints_deg(&mut self, q: Six) -> bool {
        if self.active.is_some() {
            return false;
        }
        self.joints_deg = q;
        true
    }

    // ---- input ---------------------------------------------------------------------------

    /// Handles one received frame (terminator removed) and returns the replies.
    pub fn handle_frame(&mut self, frame: &[u8], now: Duration) -> Vec<Reply> {
        let text = String::from_utf8_lossy(frame);
        let parsed = match parse_command(&text) {
            Ok(p) => p,
            Err(e) => {
                let reply = Reply::new(e.code(), format!("{e}"));
                let enter =
                    e.code() != code::UNKNOWN_COMMAND || self.config.unknown_command_enters_error_mode;
                if enter {
                    self.enter_error(e.code(), &reply.payload, now);
                }
                return vec![reply];
            }
        };
        let command = parsed.command;
        if command == Command::Empty {
            return Vec::new();
        }
        if command.is_queued() {
            return self.accept_queued(command, now).into_iter().collect();
        }
        self.request(command, now)
    }

    fn accept_queued(&mut self, command: Command, now: Duration) -> Option<Reply> {
        let refuse = |code: u16, text: &str| Some((code, text.to_owned()));
        let refusal = if self.error.is_some() {
            refuse(code::IN_ERROR, "The robot is in error.")
        } else if !self.activated {
            refuse(code::NOT_ACTIVATED, "The robot is not activated.")
        } else if command.is_motion() && !self.homed {
            refuse(code::NOT_HOMED, "The robot is not homed.")
        } else if self.queue.len() >= self.config.queue_capacity {
            refuse(code::BUFFER_FULL, "The command buffer is full.")
        } else {
            self.validate_queued(&command).err()
        };
        match refusal {
            None => {
                self.queue.push_back(command);
                None
            }
            Some((c, text)) => {
                if !matches!(c, code::IN_ERROR | code::NOT_ACTIVATED | code::NOT_HOMED) {
                    self.enter_error(c, &text, now);
                }
                Some(Reply::new(c, text))
            }
        }
    }

    /// Range checks done when a queued command arrives.
    fn validate_queued(&self, command: &Command) -> Result<(), (u16, String)> {
        let range = |v: f64, lo: f64, hi: f64, what: &str| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err((code::BAD_ARGUMENTS, format!("{what} {} is outside {lo}..{hi}.", format_number(v))))
            }
        };
        match command {
            Command::SetJointVel(v) => range(*v, 0.001, 100.0, "Joint velocity"),
            Command::SetJointAcc(v) => range(*v, 0.001, 150.0, "Joint acceleration"),
            Command::SetCartLinVel(v) => range(*v, 0.001, 1000.0, "Linear velocity"),
            Command::SetCartAngVel(v) => range(*v, 0.001, 300.0, "Angular velocity"),
            Command::SetCartAcc(v) => range(*v, 0.001, 600.0, "Cartesian acceleration"),
            Command::SetBlending(v) => range(*v, 0.0, 100.0, "Blending"),
            Command::SetJointVelLimit(v) => range(*v, 0.001, 100.0, "Joint velocity limit"),
            Command::Delay(v) => range(*v, 0.0, 1e6, "Delay"),
            Command::SetCheckpoint(n) => range(
                f64::from(*n),
                f64::from(*CHECKPOINT_IDS.start()),
                f64::from(*CHECKPOINT_IDS.end()),
                "Checkpoint id",
            ),
            Command::MoveJoints(q) => self.check_limits(q),
            _ => Ok(()),
        }
    }

    fn check_limits(&self, q: &Six) -> Result<(), (u16, String)> {
        for (i, (v, (lo, hi))) in q.iter().zip(self.config.joint_limits_deg).enumerate() {
            if *v < lo || *v > hi {
                return Err((
                    code::JOINT_LIMIT,
                    format!("Joint {} over limit ({} not in {}..{} deg).", i + 1, format_number(*v), lo, hi),
                ));
            }
        }
        Ok(())
    }

    /// The replies to a command that is not queued: motor state, queries, settings (a queued
    /// command that arrives here is accepted into the queue).
    fn request(&mut self, command: Command, now: Duration) -> Vec<Reply> {
        if let Some(replies) = self.motor_request(&command, now) {
            return replies;
        }
        if let Some(replies) = self.query(&command, now) {
            return replies;
        }
        match command {
            Command::SetRtc(_) | Command::Empty => Vec::new(),
            other => match self.setting(&other, now) {
                Some(replies) => replies,
                // unreachable for well-formed input: queued commands are routed elsewhere
                None => self.accept_queued(other, now).into_iter().collect(),
            },
        }
    }

    /// Activation, homing, error reset, pause/resume/clear; None for another command.
    fn motor_request(&mut self, command: &Command, now: Duration) -> Option<Vec<Reply>> {
        let one = |c: u16, p: &str| vec![Reply::new(c, p)];
        Some(match command {
            Command::ActivateRobot => self.activate(now),
            Command::DeactivateRobot => {
                self.stop_motion(now);
                self.discard_queue();
                self.activated = false;
                self.homed = false;
                self.paused_since = None;
                one(code::DEACTIVATED, "Motors deactivated.")
            }
            Command::Home => self.home(now),
            Command::ResetError => match &self.error {
                None => one(code::NO_ERROR_TO_RESET, "There was no error to reset."),
                Some((c, _)) if NOT_RESETTABLE.contains(c) && (*c != code::ESTOP || self.estop_pressed) => {
                    one(code::NOT_RESETTABLE, "The error cannot be reset.")
                }
                Some(_) => {
                    self.error = None;
                    one(code::ERROR_RESET, "The error was reset.")
                }
            },
            Command::PauseMotion => {
                if !self.activated {
                    return Some(one(code::NOT_ACTIVATED, "The robot is not activated."));
                }
                self.paused_since.get_or_insert(now);
                one(code::PAUSED, "Motion paused.")
            }
            Command::ResumeMotion => {
                if !self.activated {
                    one(code::NOT_ACTIVATED, "The robot is not activated.")
                } else if self.error.is_some() {
                    one(code::IN_ERROR, "The robot is in error.")
                } else {
                    self.resume(now);
                    one(code::RESUMED, "Motion resumed.")
                }
            }
            Command::ClearMotion => {
                self.stop_motion(now);
                let discarded = self.discard_queue();
                self.paused_since.get_or_insert(now);
                let mut out = one(code::CLEARED, "The motion was cleared.");
                out.extend(discarded);
                out
            }
            _ => return None,
        })
    }

    /// `ActivateRobot`: refused in error or with the E-Stop pressed, answered at once when
    /// already active, else pending for the activation time.
    fn activate(&mut self, now: Duration) -> Vec<Reply> {
        let one = |c: u16, p: &str| vec![Reply::new(c, p)];
        if self.error.is_some() {
            one(code::IN_ERROR, "The robot is in error.")
        } else if self.estop_pressed {
            one(code::ACTIVATION_FAILED, "Activation failed: E-Stop pressed.")
        } else if self.activated {
            self.already(
                code::ACTIVATED,
                code::ALREADY_ACTIVATED,
                "Motors activated.",
                "Motors already activated.",
            )
        } else {
            self.pending =
                Some((now.saturating_add(self.scaled(self.config.activation_time)), Pending::Activation));
            Vec::new()
        }
    }

    /// `Home`: refused when not activated or in error, answered at once when already homed,
    /// else pending for the homing time.
    fn home(&mut self, now: Duration) -> Vec<Reply> {
        let one = |c: u16, p: &str| vec![Reply::new(c, p)];
        if !self.activated {
            one(code::NOT_ACTIVATED, "The robot is not activated.")
        } else if self.error.is_some() {
            one(code::IN_ERROR, "The robot is in error.")
        } else if self.homed {
            self.already(code::HOMED, code::ALREADY_HOMED, "Homing done.", "Homing already done.")
        } else {
            self.pending = Some((now.saturating_add(self.scaled(self.config.homing_time)), Pending::Homing));
            Vec::new()
        }
    }

    /// The `Get…` requests (status, joints, pose, frames, firmware, monitoring); None for
    /// another command.
    fn query(&self, command: &Command, now: Duration) -> Option<Vec<Reply>> {
        let reply = match command {
            Command::GetStatusRobot => self.status_word(now).to_reply(),
            Command::GetJoints => six_reply(code::JOINTS, None, &self.joints_now(now)),
            Command::GetPose => six_reply(code::POSE, None, &self.pose_now(now)),
            Command::GetRtTargetJointPos | Command::GetRtJointPos => {
                let c =
                    if *command == Command::GetRtJointPos { code::RT_JOINTS } else { code::RT_TARGET_JOINTS };
                six_reply(c, Some(now), &self.joints_now(now))
            }
            Command::GetRtTargetCartPos | Command::GetRtCartPos => {
                let c = if *command == Command::GetRtCartPos { code::RT_CART } else { code::RT_TARGET_CART };
                six_reply(c, Some(now), &self.pose_now(now))
            }
            Command::GetRobotSerial => Reply::new(code::SERIAL, self.config.serial.clone()),
            Command::GetFwVersion => {
                let (a, b, c) = self.config.firmware;
                Reply::new(code::FW_VERSION, format!("v{a}.{b}.{c}"))
            }
            Command::GetFwVersionFull => {
                let (a, b, c) = self.config.firmware;
                Reply::new(code::FW_VERSION_FULL, format!("{a}.{b}.{c}.0-sim"))
            }
            Command::GetProductType => Reply::new(code::PRODUCT_TYPE, self.config.model.clone()),
            Command::GetTrf => six_reply(code::TRF, None, &kinematics::to_xyzabc(&self.trf)),
            Command::GetWrf => six_reply(code::WRF, None, &kinematics::to_xyzabc(&self.wrf)),
            Command::GetMonitoringInterval => {
                Reply::new(code::MONITORING_INTERVAL, format_number(self.monitoring_interval_s))
            }
            Command::GetRealTimeMonitoring => self.rt_codes_reply(),
            _ => return None,
        };
        Some(vec![reply])
    }

    /// The settings answered at once (monitoring, end-of-block/movement events, queue sync,
    /// control-port monitoring); None for another command.
    fn setting(&mut self, command: &Command, now: Duration) -> Option<Vec<Reply>> {
        let one = |c: u16, p: &str| vec![Reply::new(c, p)];
        Some(match command {
            Command::SetRealTimeMonitoring(codes) => {
                self.rt_codes = match codes {
                    RealTimeCodes::All => SUPPORTED_RT_CODES.into_iter().collect(),
                    RealTimeCodes::Codes(c) => {
                        c.iter().copied().filter(|c| SUPPORTED_RT_CODES.contains(c)).collect()
                    }
                };
                vec![self.rt_codes_reply()]
            }
            Command::SetMonitoringInterval(t) => {
                if (0.001..=1.0).contains(t) {
                    self.monitoring_interval_s = *t;
                    Vec::new()
                } else {
                    self.enter_error(code::BAD_ARGUMENTS, "Monitoring interval out of range.", now);
                    one(code::BAD_ARGUMENTS, "Monitoring interval out of range.")
                }
            }
            Command::SetEob(e) => {
                self.eob_events = *e;
                if *e {
                    one(code::EOB_ON, "End of block is enabled.")
                } else {
                    one(code::EOB_OFF, "End of block is disabled.")
                }
            }
            Command::SetEom(e) => {
                self.eom_events = *e;
                if *e {
                    one(code::EOM_ON, "End of movement is enabled.")
                } else {
                    one(code::EOM_OFF, "End of movement is disabled.")
                }
            }
            Command::SyncCmdQueue(n) => one(code::SYNC, &n.to_string()),
            Command::SetCtrlPortMonitoring(e) => {
                self.ctrl_port_monitoring = *e;
                let mut out = one(code::CTRL_PORT_MONITORING, if *e { "1" } else { "0" });
                if *e {
                    out.push(self.status_word(now).to_reply());
                }
                out
            }
            _ => return None,
        })
    }

    fn already(&self, new_fw: u16, old_fw: u16, new_text: &str, old_text: &str) -> Vec<Reply> {
        if self.config.firmware < (9, 0, 0) {
            vec![Reply::new(old_fw, old_text)]
        } else {
            vec![Reply::new(new_fw, new_text)]
        }
    }

    fn rt_codes_reply(&self) -> Reply {
        Reply::new(
            code::RT_MONITORING,
            self.rt_codes.iter().map(u16::to_string).collect::<Vec<_>>().join(","),
        )
    }

    fn pose_now(&self, now: Duration) -> Six {
        kinematics::to_xyzabc(&self.tool_pose(&self.joints_now(now)))
    }

    fn scaled(&self, d: Duration) -> Duration {
        secs(d.as_secs_f64() / self.config.time_scale)
    }

    // ---- time ----------------------------------------------------------------------------

    /// Advances the controller to `now`: completes activation/homing, runs the motion queue,
    /// and returns the events to send on the control port (`[2000]`/`[2002]` answers,
    /// `[3030]`, `[3012]`, `[3004]`, execution errors).
    pub fn tick(&mut self, now: Duration) -> Vec<Reply> {
        let mut out = Vec::new();
        self.complete_pending(now, &mut out);
        if self.activated && self.error.is_none() && self.paused_since.is_none() {
            self.run_queue(now, &mut out);
        }
        let eob = self.active.is_none() && self.queue.is_empty();
        if eob && !self.last_eob && self.eob_events {
            out.push(Reply::new(code::EOB, "End of block."));
        }
        self.last_eob = eob;
        out
    }

    fn complete_pending(&mut self, now: Duration, out: &mut Vec<Reply>) {
        let Some((done_at, what)) = self.pending else { return };
        if now < done_at {
            return;
        }
        self.pending = None;
        match what {
            Pending::Activation => {
                self.activated = true;
                self.paused_since = None;
                self.params = MotionParams::default();
                out.push(Reply::new(code::ACTIVATED, "Motors activated."));
            }
            Pending::Homing => {
                self.homed = true;
                out.push(Reply::new(code::HOMED, "Homing done."));
            }
        }
    }

    fn run_queue(&mut self, now: Duration, out: &mut Vec<Reply>) {
        loop {
            match self.active {
                Some(Active::Move { to, start, duration, .. }) => {
                    if now < start.saturating_add(duration) {
                        return;
                    }
                    self.joints_deg = to;
                    self.active = None;
                    if self.eom_events {
                        out.push(Reply::new(code::EOM, "End of movement."));
                    }
                }
                Some(Active::Delay { until }) => {
                    if now < until {
                        return;
                    }
                    self.active = None;
                }
                None => {}
            }
            let Some(command) = self.queue.pop_front() else { return };
            if let Err((c, text)) = self.execute(command, now, out) {
                self.enter_error(c, &text, now);
                out.push(Reply::new(c, text));
                return;
            }
        }
    }

    /// Executes one dequeued command (starting a motion if it is a move).
    fn execute(
        &mut self,
        command: Command,
        now: Duration,
        out: &mut Vec<Reply>,
    ) -> Result<(), (u16, String)> {
        let p = &mut self.params;
        match command {
            Command::SetJointVel(v) => p.joint_vel_pct = v,
            Command::SetJointAcc(v) => p.joint_acc_pct = v,
            Command::SetCartLinVel(v) => p.cart_lin_vel_mm_s = v,
            Command::SetCartAngVel(v) => p.cart_ang_vel_deg_s = v,
            Command::SetCartAcc(v) => p.cart_acc_pct = v,
            Command::SetBlending(v) => p.blending_pct = v,
            Command::SetJointVelLimit(v) => p.joint_vel_limit_pct = v,
            Command::SetTrf(s) => self.trf = kinematics::from_xyzabc(&s),
            Command::SetWrf(s) => self.wrf = kinematics::from_xyzabc(&s),
            Command::SetCheckpoint(n) => out.push(Reply::new(code::CHECKPOINT, n.to_string())),
            Command::Delay(t) => {
                self.active = Some(Active::Delay { until: now.saturating_add(self.scaled(secs(t))) })
            }
            motion => self.start_motion(&motion, now)?,
        }
        Ok(())
    }

    fn start_motion(&mut self, command: &Command, now: Duration) -> Result<(), (u16, String)> {
        if let Some(c) = self.fail_next_move.take() {
            return Err((c, format!("Injected failure of {}.", command.name())));
        }
        let from = self.joints_deg;
        let (to, cart_duration_s) = match command {
            Command::MoveJoints(q) => (*q, 0.0),
            Command::MoveJointsRel(d) => {
                let mut q = from;
                for (qi, di) in q.iter_mut().zip(d) {
                    *qi += di;
                }
                (q, 0.0)
            }
            Command::MovePose(p) | Command::MoveLin(p) => {
                self.cartesian_target(&kinematics::from_xyzabc(p))?
            }
            Command::MoveLinRelWrf(d) | Command::MoveLinRelTrf(d) => {
                let speed = self.params.cart_lin_vel_mm_s;
                let solved = self.backend_linear(command, d).and_then(|(translation, frame)| {
                    let backend = self.config.backend.as_ref()?;
                    let q = backend.linear_relative(&from, &translation, frame)?;
                    Some(q.map(|q| (q, translation.norm() / speed)))
                });
                match solved {
                    Some(result) => result?,
                    None => self.builtin_linear_relative(command, d, &from)?,
                }
            }
            other => return Err((code::UNKNOWN_COMMAND, format!("{} is not a motion.", other.name()))),
        };
        self.check_limits(&to)?;
        if let Some(backend) = &self.config.backend {
            backend.motion_started(&from, &to);
        }
        let joint_s = self.joint_move_seconds(&from, &to);
        let duration = secs(joint_s.max(cart_duration_s) / self.config.time_scale);
        self.active = Some(Active::Move { from, to, start: now, duration });
        Ok(())
    }

    /// A translation-only relative move handed to the backend: the translation in the base
    /// axes (`MoveLinRelWrf`, through the WRF's orientation) or the flange axes
    /// (`MoveLinRelTrf`, through the TRF's orientation). `None` without a backend or when the
    /// move also rotates.
    fn backend_linear(&self, command: &Command, d: &Six) -> Option<(nalgebra::Vector3<f64>, LinearFrame)> {
        self.config.backend.as_ref()?;
        if d[3..].iter().any(|a| *a != 0.0) {
            return None;
        }
        let v = nalgebra::Vector3::new(d[0], d[1], d[2]);
        match command {
            Command::MoveLinRelWrf(_) => Some((self.wrf.rotation * v, LinearFrame::World)),
            Command::MoveLinRelTrf(_) => Some((self.trf.rotation * v, LinearFrame::Tool)),
            _ => None,
        }
    }

    /// `MoveLinRelWrf`/`MoveLinRelTrf` on the simulator's built-in kinematics.
    fn builtin_linear_relative(
        &self,
        command: &Command,
        d: &Six,
        from: &Six,
    ) -> Result<(Six, f64), (u16, String)> {
        match command {
            Command::MoveLinRelWrf(_) => {
                let current = self.tool_pose(from);
                let delta = kinematics::from_xyzabc(d);
                let target = Isometry3::from_parts(
                    (current.translation.vector + delta.translation.vector).into(),
                    delta.rotation * current.rotation,
                );
                self.cartesian_target(&target)
            }
            _ => {
                let target = self.tool_pose(from) * kinematics::from_xyzabc(d);
                self.cartesian_target(&target)
            }
        }
    }

    /// Joints for a TRF target pose in the WRF, and the Cartesian duration \[s\] at the current
    /// linear/angular speeds.
    fn cartesian_target(&self, target_tool: &Isometry3<f64>) -> Result<(Six, f64), (u16, String)> {
        let current = self.tool_pose(&self.joints_deg);
        let flange = self.wrf * target_tool * self.trf.inverse();
        let q = kinematics::inverse(&flange, &self.joints_deg).map_err(|f| match f {
            IkFailure::OutOfReach => (code::OUT_OF_REACH, "Pose out of reach.".to_owned()),
            IkFailure::Singular => (code::SINGULARITY, "Linear move would cross a singularity.".to_owned()),
        })?;
        let dist = (target_tool.translation.vector - current.translation.vector).norm();
        let angle = (target_tool.rotation * current.rotation.inverse()).angle().to_degrees();
        let s = (dist / self.params.cart_lin_vel_mm_s).max(angle / self.params.cart_ang_vel_deg_s);
        Ok((q, s))
    }

    /// Constant-speed joint interpolation: the slowest joint at its rated speed × `SetJointVel`
    /// (capped by `SetJointVelLimit`) sets the duration.
    fn joint_move_seconds(&self, from: &Six, to: &Six) -> f64 {
        let pct = self.params.joint_vel_pct.min(self.params.joint_vel_limit_pct) / 100.0;
        from.iter()
            .zip(to)
            .zip(self.config.rated_joint_speed_deg_s)
            .map(|((f, t), rated)| (t - f).abs() / (rated * pct))
            .fold(0.0, f64::max)
    }

    // ---- error mode ----------------------------------------------------------------------

    fn stop_motion(&mut self, now: Duration) {
        self.joints_deg = self.joints_now(now);
        self.active = None;
    }

    /// Empties the queue; `[3040][n]` for each discarded checkpoint on firmware ≥ 10.2.1.
    fn discard_queue(&mut self) -> Vec<Reply> {
        let announce = self.config.firmware >= (10, 2, 1);
        self.queue
            .drain(..)
            .filter_map(|c| match c {
                Command::SetCheckpoint(n) if announce => {
                    Some(Reply::new(code::CHECKPOINT_DISCARDED, n.to_string()))
                }
                _ => None,
            })
            .collect()
    }

    fn resume(&mut self, now: Duration) {
        if let Some(since) = self.paused_since.take() {
            let pause = now.saturating_sub(since);
            match &mut self.active {
                Some(Active::Move { start, .. }) => *start = start.saturating_add(pause),
                Some(Active::Delay { until }) => *until = until.saturating_add(pause),
                None => {}
            }
        }
    }

    /// Error mode: stop, drop the queue, pause. (Discarded-checkpoint events are not sent
    /// here: mecademicpy aborts its waits on the error itself.)
    fn enter_error(&mut self, code: u16, text: &str, now: Duration) {
        self.stop_motion(now);
        let _ = self.discard_queue();
        self.paused_since.get_or_insert(now);
        self.error = Some((code, text.to_owned()));
    }

    /// Fault injection: an asynchronous error event (e.g. `[3005]` motion error).
    pub fn inject_error(&mut self, code: u16, text: &str, now: Duration) -> Reply {
        self.enter_error(code, text, now);
        Reply::new(code, text)
    }

    /// Fault injection: the next move that starts fails with `code` (e.g. `[1012]`).
    pub fn fail_next_move(&mut self, code: u16) {
        self.fail_next_move = Some(code);
    }

    /// Fault injection: E-Stop pressed (motors off, error mode) or released.
    pub fn set_estop(&mut self, pressed: bool, now: Duration) -> Reply {
        self.estop_pressed = pressed;
        if pressed {
            self.enter_error(code::ESTOP, "E-Stop pressed.", now);
            self.activated = false;
            self.homed = false;
            Reply::new(code::ESTOP, "1")
        } else {
            Reply::new(code::ESTOP, "0")
        }
    }

    /// One monitoring cycle: `[2026]`, `[2027]`, enabled 22xx codes, then `[2230][t]`.
    pub fn monitoring_cycle(&self, now: Duration) -> Vec<Reply> {
        let q = self.joints_now(now);
        let pose = self.pose_now(now);
        let mut out = vec![six_reply(code::JOINTS, None, &q), six_reply(code::POSE, None, &pose)];
        for c in &self.rt_codes {
            let values = if matches!(*c, code::RT_TARGET_JOINTS | code::RT_JOINTS) { &q } else { &pose };
            out.push(six_reply(*c, Some(now), values));
        }
        out.push(Reply::new(code::RT_CYCLE_END, micros(now).to_string()));
        out
    }
}

/// Seconds → duration, saturating (NaN or negative → zero, too large → `Duration::MAX`).
fn secs(s: f64) -> Duration {
    if s.is_nan() || s <= 0.0 {
        Duration::ZERO
    } else {
        Duration::try_from_secs_f64(s).unwrap_or(Duration::MAX)
    }
}

fn micros(t: Duration) -> u128 {
    t.as_micros()
}

/// `[code][t,v1..v6]` (with a µs time stamp) or `[code][v1..v6]`.
fn six_reply(c: u16, stamp: Option<Duration>, values: &Six) -> Reply {
    let mut parts: Vec<String> = stamp.map(|t| micros(t).to_string()).into_iter().collect();
    parts.extend(values.iter().map(|v| format_number(*v)));
    Reply::new(c, parts.join(","))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    fn robot() -> SimRobot {
        SimRobot::new(SimConfig {
            activation_time: Duration::ZERO,
            homing_time: Duration::ZERO,
            ..SimConfig::default()
        })
    }

    fn send(r: &mut SimRobot, line: &str, now: Duration) -> Vec<String> {
        let mut out: Vec<String> = r.handle_frame(line.as_bytes(), now).iter().map(Reply::to_text).collect();
        out.extend(r.tick(now).iter().map(Reply::to_text));
        out
    }

    fn ready() -> SimRobot {
        let mut r = robot();
        assert_eq!(send(&mut r, "ActivateRobot", ms(0)), ["[2000][Motors activated.]"]);
        assert_eq!(send(&mut r, "Home", ms(0)), ["[2002][Homing done.]"]);
        r
    }

    #[test]
    fn reproduces_the_error_transcript_of_the_reference() {
        // protocols.md §1.9 (codes faithful; our texts differ)
        let mut r = ready();
        let _ = r.status_change(ms(0));
        let out = send(&mut r, "MoveJoints(200,0,0,0,0,0)", ms(1));
        assert_eq!(out.len(), 1);
        assert!(out[0].starts_with("[1007]"), "{out:?}");
        assert_eq!(r.status_change(ms(1)).map(|s| s.to_text()), Some("[2007][1,1,0,1,1,1,1]".to_owned()));
        assert!(send(&mut r, "SetCheckpoint(8001)", ms(2))[0].starts_with("[1011]"));
        assert_eq!(send(&mut r, "ResetError", ms(3)), ["[2005][The error was reset.]"]);
        assert_eq!(r.status_change(ms(3)).map(|s| s.to_text()), Some("[2007][1,1,0,0,1,1,1]".to_owned()));
        assert_eq!(send(&mut r, "ResumeMotion", ms(4)), ["[2043][Motion resumed.]"]);
        assert_eq!(r.status_change(ms(4)).map(|s| s.to_text()), Some("[2007][1,1,0,0,0,1,1]".to_owned()));
        assert_eq!(send(&mut r, "ResetError", ms(5)), ["[2006][There was no error to reset.]"]);
    }

    #[test]
    fn client_private_checkpoints_are_accepted_beyond_the_range_refused() {
        let mut r = ready();
        for id in [1, 8000, 8001, 8191] {
            assert!(
                send(&mut r, &format!("SetCheckpoint({id})"), ms(0)) == [format!("[3030][{id}]")],
                "{id}"
            );
            assert!(r.error.is_none(), "{id}");
        }
        for id in [0, 8192] {
            assert!(send(&mut r, &format!("SetCheckpoint({id})"), ms(1))[0].starts_with("[1003]"), "{id}");
            assert!(r.error.is_some(), "{id} enters error mode");
            send(&mut r, "ResetError", ms(1));
            send(&mut r, "ResumeMotion", ms(1));
        }
    }

    #[test]
    fn connect_sequence_answers_of_the_reference() {
        let mut r = robot();
        assert_eq!(r.banner().to_reply().to_text(), "[3000][Connected to Meca500 R3 v9.3.0]");
        assert!(send(&mut r, "", ms(0)).is_empty());
        assert_eq!(send(&mut r, "-GetRobotSerial", ms(0)), ["[2083][M500-0000]"]);
        assert_eq!(send(&mut r, "-GetRealTimeMonitoring", ms(0)), ["[2117][]"]);
        assert_eq!(send(&mut r, "-GetMonitoringInterval", ms(0)), ["[2116][0.015]"]);
        assert!(send(&mut r, "-SetRtc(1795314763)", ms(0)).is_empty());
        assert_eq!(send(&mut r, "-SetCtrlPortMonitoring(1)", ms(0)), ["[2096][1]", "[2007][0,0,0,0,0,1,1]"]);
    }

    #[test]
    fn activation_and_homing_state_machine() {
        let mut r = SimRobot::new(SimConfig::default());
        assert!(send(&mut r, "Home", ms(0))[0].starts_with("[1005]"));
        assert!(send(&mut r, "MoveJoints(0,0,0,0,0,0)", ms(0))[0].starts_with("[1005]"));
        assert!(send(&mut r, "ActivateRobot", ms(0)).is_empty(), "activation takes time");
        assert!(r.is_busy());
        let t = SimConfig::default().activation_time;
        assert_eq!(send(&mut r, "", t)[0], "[2000][Motors activated.]");
        assert!(send(&mut r, "MoveJoints(0,0,0,0,0,0)", t)[0].starts_with("[1006]"));
        assert!(r.error.is_none(), "not-homed refusal does not enter error mode");
        assert!(send(&mut r, "Home", t).is_empty());
        let t2 = t + SimConfig::default().homing_time;
        assert_eq!(send(&mut r, "", t2)[0], "[2002][Homing done.]");
        assert_eq!(send(&mut r, "GetStatusRobot", t2), ["[2007][1,1,0,0,0,1,1]"]);
        assert_eq!(send(&mut r, "ActivateRobot", t2), ["[2000][Motors activated.]"]);
        assert_eq!(send(&mut r, "DeactivateRobot", t2), ["[2004][Motors deactivated.]"]);
        assert_eq!(send(&mut r, "GetStatusRobot", t2), ["[2007][0,0,0,0,0,1,1]"]);
    }

    #[test]
    fn joint_move_takes_rated_speed_time_and_ends_with_checkpoint_and_eob() {
        let mut r = ready();
        // J1 rated 150 deg/s at 50 % → 75 deg/s: 30 deg takes 0.4 s
        assert!(send(&mut r, "SetJointVel(50)", ms(0)).is_empty());
        assert!(send(&mut r, "MoveJoints(30,0,0,0,0,0)", ms(0)).is_empty());
        assert!(send(&mut r, "SetCheckpoint(7)", ms(0)).is_empty());
        assert_eq!(send(&mut r, "GetStatusRobot", ms(1)), ["[2007][1,1,0,0,0,0,0]"]);
        let mid = r.joints_now(ms(200))[0];
        assert!((mid - 15.0).abs() < 1e-9, "{mid}");
        assert!(send(&mut r, "", ms(399)).is_empty());
        assert_eq!(send(&mut r, "", ms(400)), ["[3030][7]", "[3012][End of block.]"]);
        assert_eq!(send(&mut r, "GetJoints", ms(401)), ["[2026][30,0,0,0,0,0]"]);
        assert_eq!(send(&mut r, "GetRtTargetJointPos", ms(401)), ["[2200][401000,30,0,0,0,0,0]"]);
    }

    #[test]
    fn pause_resume_and_clear() {
        let mut r = ready();
        send(&mut r, "SetJointVel(100)", ms(0));
        send(&mut r, "MoveJoints(150,0,0,0,0,0)", ms(0)); // 1 s
        send(&mut r, "SetCheckpoint(1)", ms(0));
        assert_eq!(send(&mut r, "PauseMotion", ms(500)), ["[2042][Motion paused.]"]);
        assert!(send(&mut r, "", ms(2000)).is_empty(), "paused: no progress");
        assert!((r.joints_now(ms(2000))[0] - 75.0).abs() < 1e-9);
        assert_eq!(send(&mut r, "ResumeMotion", ms(2000)), ["[2043][Motion resumed.]"]);
        assert_eq!(send(&mut r, "", ms(2500)), ["[3030][1]", "[3012][End of block.]"]);
        send(&mut r, "MoveJoints(0,0,0,0,0,0)", ms(3000));
        send(&mut r, "SetCheckpoint(2)", ms(3000));
        let out = send(&mut r, "ClearMotion", ms(3100));
        assert_eq!(out[0], "[2044][The motion was cleared.]");
        assert!(r.status_word(ms(3100)).paused);
        assert!(send(&mut r, "", ms(9000)).iter().all(|m| !m.starts_with("[3030]")));
    }

    #[test]
    fn cartesian_relative_moves_follow_the_frames() {
        let mut r = ready();
        send(&mut r, "MoveJoints(0,10,20,0,40,0)", ms(0));
        send(&mut r, "", ms(10_000));
        let before = kinematics::forward(&r.joints_now(ms(10_000)));
        send(&mut r, "MoveLinRelWrf(1,2,3,0,0,0)", ms(10_000));
        send(&mut r, "", ms(20_000));
        let after = kinematics::forward(&r.joints_now(ms(20_000)));
        let d = after.translation.vector - before.translation.vector;
        assert!((d - nalgebra::Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-8, "{d}");
        assert!(after.rotation.angle_to(&before.rotation) < 1e-9);
        send(&mut r, "MoveLinRelTrf(0,0,5,0,0,0)", ms(20_000));
        send(&mut r, "", ms(30_000));
        let last = kinematics::forward(&r.joints_now(ms(30_000)));
        let expected = after.translation.vector + after.rotation * nalgebra::Vector3::new(0.0, 0.0, 5.0);
        assert!((last.translation.vector - expected).norm() < 1e-8);
    }

    #[test]
    fn execution_errors_and_injected_faults_enter_error_mode() {
        let mut r = ready();
        // a relative joint move past the limit fails when it executes
        let out = send(&mut r, "MoveJointsRel(0,100,0,0,0,0)", ms(0));
        assert!(out.iter().any(|m| m.starts_with("[1007]")), "{out:?}");
        assert!(r.status_word(ms(1)).error);
        send(&mut r, "ResetError", ms(2));
        send(&mut r, "ResumeMotion", ms(2));
        r.fail_next_move(code::SINGULARITY);
        assert!(send(&mut r, "MoveJoints(1,0,0,0,0,0)", ms(3)).iter().any(|m| m.starts_with("[1012]")));
        send(&mut r, "ResetError", ms(5));
        send(&mut r, "ResumeMotion", ms(5));
        assert_eq!(r.inject_error(code::MOTION_ERROR, "Collision.", ms(6)).to_text(), "[3005][Collision.]");
        assert_eq!(send(&mut r, "ResetError", ms(7)), ["[2005][The error was reset.]"]);
        assert_eq!(r.set_estop(true, ms(8)).to_text(), "[3070][1]");
        assert!(send(&mut r, "ResetError", ms(9))[0].starts_with("[1025]"), "not while pressed");
        r.set_estop(false, ms(10));
        assert_eq!(send(&mut r, "ResetError", ms(11)), ["[2005][The error was reset.]"]);
        assert!(!r.status_word(ms(11)).activated);
    }

    #[test]
    fn syntax_errors_enter_error_mode_unknown_commands_do_not() {
        let mut r = ready();
        assert!(send(&mut r, "Dance", ms(0))[0].starts_with("[1001]"));
        assert!(r.error.is_none());
        assert!(send(&mut r, "MoveJoints(1,2)", ms(0))[0].starts_with("[1003]"));
        assert!(r.error.is_some());
    }

    #[test]
    fn discarded_checkpoints_are_announced_on_recent_firmware() {
        let mut r = SimRobot::new(SimConfig {
            firmware: (10, 2, 1),
            activation_time: Duration::ZERO,
            homing_time: Duration::ZERO,
            ..SimConfig::default()
        });
        send(&mut r, "ActivateRobot", ms(0));
        send(&mut r, "Home", ms(0));
        send(&mut r, "MoveJoints(100,0,0,0,0,0)", ms(0));
        send(&mut r, "SetCheckpoint(5)", ms(0));
        assert_eq!(
            send(&mut r, "ClearMotion", ms(10)),
            ["[2044][The motion was cleared.]", "[3040][5]", "[3012][End of block.]"]
        );
    }

    fn arb_line() -> impl proptest::strategy::Strategy<Value = String> {
        use proptest::prelude::*;
        let names = proptest::sample::select(vec![
            "ActivateRobot",
            "Home",
            "ResetError",
            "ResumeMotion",
            "PauseMotion",
            "ClearMotion",
            "DeactivateRobot",
            "MoveJoints",
            "MoveJointsRel",
            "MovePose",
            "MoveLin",
            "MoveLinRelTrf",
            "MoveLinRelWrf",
            "SetTrf",
            "SetWrf",
            "SetJointVel",
            "SetCartLinVel",
            "SetCheckpoint",
            "Delay",
            "GetJoints",
            "GetPose",
            "GetRtTargetJointPos",
            "SetRealTimeMonitoring",
            "SetMonitoringInterval",
            "SetCtrlPortMonitoring",
            "SyncCmdQueue",
            "Dance",
        ]);
        let arg = prop_oneof![-1e7f64..1e7, -200.0f64..200.0, Just(f64::MAX), Just(0.0)];
        prop_oneof![
            (names, proptest::collection::vec(arg, 0..8)).prop_map(|(n, a)| {
                format!("{n}({})", a.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(","))
            }),
            "[ -~]{0,40}",
        ]
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_input_never_panics(
            lines in proptest::collection::vec(arb_line(), 0..25),
            bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..64),
        ) {
            let mut r = ready();
            for (i, line) in lines.iter().enumerate() {
                let now = ms(10 * i as u64);
                r.handle_frame(line.as_bytes(), now);
                r.tick(now);
                let _ = r.status_change(now);
                let _ = r.monitoring_cycle(now);
            }
            r.handle_frame(&bytes, ms(1000));
            r.tick(Duration::from_secs(1_000_000));
            let s = r.snapshot(Duration::from_secs(1_000_000));
            proptest::prop_assert!(s.joints_deg.iter().all(|q| q.is_finite()));
        }
    }

    #[test]
    fn monitoring_cycle_ends_with_2230() {
        let mut r = ready();
        send(&mut r, "SetRealTimeMonitoring(2200,9999)", ms(0));
        let cycle: Vec<u16> = r.monitoring_cycle(ms(5)).iter().map(|m| m.code).collect();
        assert_eq!(cycle, [2026, 2027, 2200, 2230]);
    }
}
