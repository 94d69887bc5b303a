//! The blocking Meca500 driver: [`Meca500`] implements [`RobotArm`] over any [`Transport`].

use std::collections::VecDeque;
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::{
    ArmJoints, ArmStatus, LinearFrame, MotionOptions, Result as HwResult, RobotArm,
};

use crate::codec::{Banner, Command, Deframer, Reply, Six, StatusWord, code};
use crate::error::Meca500Error;
use crate::transport::Transport;
use vatcal_hardware_traits::transport::Deadline as Wait;
use vatcal_hardware_traits::transport::{LinkError, recv_some};

/// Factory control port of the robot.
pub const CONTROL_PORT: u16 = 10000;
/// Factory monitoring port of the robot.
pub const MONITORING_PORT: u16 = 10001;

/// Checkpoint ids the driver cycles through (mecademicpy reserves 8001…8191 for itself).
const CHECKPOINT_IDS: std::ops::RangeInclusive<u32> = 1..=8000;
/// How many reached/discarded checkpoint ids are remembered.
const CHECKPOINT_MEMORY: usize = 64;

/// Which joint values [`RobotArm::joints`] returns (§1.7: decide explicitly).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum JointReadback {
    /// `GetRtTargetJointPos` → `[2200]`: the joints the controller commands (default; what
    /// mecademicpy's synchronous `GetRtTargetJointPos()` returns).
    #[default]
    Target,
    /// `GetRtJointPos` → `[2210]`: the encoder joints (target minus servo error).
    Measured,
    /// `GetJoints` → `[2026]`: the legacy query (older firmware).
    Legacy,
}

/// Connection settings and timeouts.
#[derive(Debug, Clone, PartialEq)]
pub struct Meca500Config {
    /// device name used in error messages
    pub name: String,
    /// timeout of every request (status, joints, move acceptance, stop, reset)
    pub io_timeout: Duration,
    /// timeout of the TCP connect and of the banner
    pub connect_timeout: Duration,
    /// which joints `joints()` reads
    pub joint_readback: JointReadback,
    /// Cartesian speed \[mm/s\] that `MotionOptions::speed_fraction = 1` maps to
    /// (`SetCartLinVel` accepts up to 1000 mm/s)
    pub max_linear_speed_mm_s: f64,
    /// longest pause between two `GetStatusRobot` polls while waiting for end-of-block (the
    /// first pauses are 1, 2, 4, … ms)
    pub status_poll_interval: Duration,
    /// send `SetTrf(0,0,0,0,0,0)` after activation so that [`LinearFrame::Tool`] is the flange
    /// frame (see `docs/drivers.md`)
    pub reset_trf_on_activate: bool,
}

impl Default for Meca500Config {
    /// 2 s I/O timeout, 5 s connect timeout, target joints, 1000 mm/s at full speed, 10 ms
    /// status polls, TRF reset on activation.
    fn default() -> Self {
        Self {
            name: "meca500".to_owned(),
            io_timeout: Duration::from_secs(2),
            connect_timeout: Duration::from_secs(5),
            joint_readback: JointReadback::Target,
            max_linear_speed_mm_s: 1000.0,
            status_poll_interval: Duration::from_millis(10),
            reset_trf_on_activate: true,
        }
    }
}

/// What a request does with error messages that arrive before its answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum OnError {
    /// fail with the error
    Fail,
    /// remember it (for `status()`), keep waiting for the answer
    Record,
}

/// A Meca500 on the other end of a [`Transport`] (normally the TCP control port 10000).
///
/// One reader: every message that arrives is routed by its code — status words update the
/// cached status, checkpoints are remembered, error codes are recorded and fail the call that
/// saw them (see `docs/drivers.md` for the exact sequences).
#[derive(Debug)]
pub struct Meca500<T: Transport = TcpStream> {
    transport: T,
    deframer: Deframer,
    config: Meca500Config,
    banner: Banner,
    last_status: Option<StatusWord>,
    last_error: Option<(u16, String)>,
    next_checkpoint: u32,
    next_sync: u32,
    reached: VecDeque<u32>,
    discarded: VecDeque<u32>,
    label: String,
}

impl Meca500<TcpStream> {
    /// Connects to the control port at `addr` (e.g. `"192.168.0.100:10000"`) and reads the
    /// banner.
    ///
    /// # Examples
    /// Against the protocol simulator (a real robot: its address and port 10000):
    /// ```
    /// use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig};
    /// use vatcal_drivers_meca500::{Meca500, Meca500Config};
    ///
    /// let sim = Meca500Sim::start(SimConfig::fast(20.0))?;
    /// let robot = Meca500::connect_tcp(sim.control_addr(), Meca500Config::default())?;
    /// assert!(robot.banner().model.contains("Meca500"));
    /// // nothing listening: an error, not a hang (connect_timeout bounds the wait)
    /// let closed = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?;
    /// assert!(Meca500::connect_tcp(closed, Meca500Config::default()).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`Meca500Error::Link`] when the connection cannot be made or drops, or no banner comes
    /// within `config.connect_timeout`; [`Meca500Error::Banner`] when the robot refuses the
    /// connection (`[3001]` another client is connected) or sends no valid banner.
    pub fn connect_tcp(addr: impl ToSocketAddrs, config: Meca500Config) -> Result<Self, Meca500Error> {
        let stream = vatcal_hardware_traits::transport::connect_tcp(addr, config.connect_timeout)?;
        let peer = stream.peer_addr()?;
        let mut robot = Self::new(stream, config)?;
        robot.label = format!("{} at {peer}", robot.config.name);
        Ok(robot)
    }
}

impl<T: Transport> Meca500<T> {
    /// Wraps a connected transport and reads the `[3000]` banner within
    /// `config.connect_timeout`. A refusal (`[3001]` another client, …) is an error.
    pub fn new(transport: T, config: Meca500Config) -> Result<Self, Meca500Error> {
        let mut driver = Self {
            transport,
            deframer: Deframer::nul_only(),
            banner: Banner {
                model: String::new(),
                revision: None,
                virtual_robot: false,
                safe_boot: false,
                version: (0, 0, 0),
            },
            label: config.name.clone(),
            config,
            last_status: None,
            last_error: None,
            next_checkpoint: *CHECKPOINT_IDS.start(),
            next_sync: 1,
            reached: VecDeque::new(),
            discarded: VecDeque::new(),
        };
        let first = driver.read_reply(&Wait::new(driver.config.connect_timeout), "connection banner")?;
        driver.banner = Banner::from_reply(&first)?;
        Ok(driver)
    }

    /// What the robot announced on connect.
    pub fn banner(&self) -> &Banner {
        &self.banner
    }

    /// The name errors carry: [`Meca500Config::name`] plus ` at <address>` when the driver
    /// opened the connection itself (e.g. `meca500 at 192.168.0.100:10000`).
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The configuration.
    pub fn config(&self) -> &Meca500Config {
        &self.config
    }

    /// The last status word seen (from a query or pushed by the robot).
    pub fn last_status(&self) -> Option<StatusWord> {
        self.last_status
    }

    /// The last error code and text the robot reported since the last reset.
    pub fn last_error(&self) -> Option<&(u16, String)> {
        self.last_error.as_ref()
    }

    /// Hands the transport back.
    pub fn into_inner(self) -> T {
        self.transport
    }

    /// Sends one command without waiting for anything.
    pub fn send(&mut self, command: &Command) -> Result<(), Meca500Error> {
        self.transport
            .send(&command.encode())
            .map_err(|e| LinkError::from_send(e, || format!("sending {}", command.name())).into())
    }

    /// Sends a request and returns the first reply whose code is in `answers`; an error
    /// message arriving first fails the call. Times out after `config.io_timeout`.
    pub fn request(&mut self, command: &Command, answers: &[u16]) -> Result<Reply, Meca500Error> {
        let wait = Wait::new(self.config.io_timeout);
        self.request_with(command, answers, OnError::Fail, &wait)
    }

    /// Sends queued commands followed by `SyncCmdQueue(n)` and waits for `[2097][n]`: when it
    /// returns `Ok`, the robot accepted every command (refusals such as `[1007]` arrive before
    /// the marker and are returned as errors).
    pub fn send_queued(&mut self, commands: &[Command]) -> Result<(), Meca500Error> {
        for c in commands {
            self.send(c)?;
        }
        let wait = Wait::new(self.config.io_timeout);
        match self.sync(&wait)? {
            Some(err) => Err(err),
            None => Ok(()),
        }
    }

    /// Queries `[2007]`.
    pub fn status_word(&mut self) -> Result<StatusWord, Meca500Error> {
        let wait = Wait::new(self.config.io_timeout);
        self.query_status(&wait)
    }

    /// Current joints in degrees, read as configured by [`Meca500Config::joint_readback`].
    pub fn joints_deg(&mut self) -> Result<Six, Meca500Error> {
        let (command, answer) = match self.config.joint_readback {
            JointReadback::Target => (Command::GetRtTargetJointPos, code::RT_TARGET_JOINTS),
            JointReadback::Measured => (Command::GetRtJointPos, code::RT_JOINTS),
            JointReadback::Legacy => (Command::GetJoints, code::JOINTS),
        };
        Ok(self.request(&command, &[answer])?.last_six()?)
    }

    /// Current target pose `x, y, z \[mm\], α, β, γ \[deg\]` of the TRF in the WRF
    /// (`GetRtTargetCartPos`).
    pub fn pose_mm_deg(&mut self) -> Result<Six, Meca500Error> {
        Ok(self.request(&Command::GetRtTargetCartPos, &[code::RT_TARGET_CART])?.last_six()?)
    }

    /// Activates and homes if needed, resumes a paused queue, resets the TRF if configured.
    pub fn activate_and_home_within(&mut self, timeout: Duration) -> Result<(), Meca500Error> {
        let wait = Wait::new(timeout);
        let status = self.query_status(&wait)?;
        if status.error {
            return Err(self.error_mode_error());
        }
        if !status.activated {
            self.request_with(
                &Command::ActivateRobot,
                &[code::ACTIVATED, code::ALREADY_ACTIVATED],
                OnError::Fail,
                &wait,
            )?;
        }
        if !status.homed {
            self.request_with(&Command::Home, &[code::HOMED, code::ALREADY_HOMED], OnError::Fail, &wait)?;
        }
        if self.query_status(&wait)?.paused {
            self.request_with(&Command::ResumeMotion, &[code::RESUMED], OnError::Fail, &wait)?;
        }
        if self.config.reset_trf_on_activate {
            self.send_queued(&[Command::SetTrf([0.0; 6])])?;
        }
        Ok(())
    }

    /// Sends `SetCheckpoint(k)`, waits for `[3030][k]`, then polls `[2007]` until end-of-block.
    /// If the robot stops answering in time or answers garbage, the motion may still run:
    /// `ClearMotion` is sent (without waiting) before the error is returned. A motion still
    /// running when `timeout` expires while the robot answers is not a fault and is not stopped
    /// ([`Meca500Error::MotionNotFinished`]): a caller waiting in slices (to check a Ctrl-C flag
    /// between them) waits again; one that gives up calls `stop`.
    pub fn wait_idle_within(&mut self, timeout: Duration) -> Result<(), Meca500Error> {
        let r = self.wait_idle_inner(timeout);
        self.stop_on_link_fault(&r);
        r
    }

    fn wait_idle_inner(&mut self, timeout: Duration) -> Result<(), Meca500Error> {
        let mut wait = Wait::new(timeout);
        let k = self.take_checkpoint_id();
        self.send(&Command::SetCheckpoint(k))?;
        loop {
            if self.reached.contains(&k) {
                break;
            }
            if self.discarded.contains(&k) {
                return Err(Meca500Error::CheckpointDiscarded(k));
            }
            let reply = match self.read_reply(&wait, "the end of the motion (checkpoint)") {
                Ok(reply) => reply,
                Err(e @ Meca500Error::Link(LinkError::Timeout { .. })) => {
                    // no checkpoint in time: a robot that still answers is still moving (not
                    // a link fault: it is not stopped here); one that does not is a link fault
                    let alive = self.query_status(&Wait::new(self.config.io_timeout));
                    match alive {
                        Ok(status) if status.error => return Err(self.error_mode_error()),
                        Ok(_) if self.reached.contains(&k) => {
                            // reached while we asked: the end of block follows within ms
                            wait = Wait::new(self.config.io_timeout);
                            break;
                        }
                        Ok(_) => return Err(Meca500Error::MotionNotFinished { after: timeout }),
                        Err(_) => return Err(e),
                    }
                }
                Err(e) => return Err(e),
            };
            if reply.is_error() {
                let err = self.robot_error(&reply);
                self.drain();
                return Err(err);
            }
        }
        // the end of block follows the checkpoint within milliseconds: poll after 1, 2, 4, …
        // ms, at most every `status_poll_interval`
        let mut next = Duration::from_millis(1).min(self.config.status_poll_interval);
        loop {
            let status = self.query_status(&wait)?;
            if status.error {
                return Err(self.error_mode_error());
            }
            if status.end_of_block {
                return Ok(());
            }
            let pause = wait.remaining().map(|r| r.min(next));
            next = (next * 2).min(self.config.status_poll_interval);
            match pause {
                Some(p) => std::thread::sleep(p),
                // it answers every query: still moving, not a link fault
                None => return Err(Meca500Error::MotionNotFinished { after: timeout }),
            }
        }
    }

    /// `ClearMotion` then `ResumeMotion` (so that later moves run; in error mode the resume
    /// is refused with `[1011]`, which is accepted here: `reset_error` resumes).
    pub fn clear_motion(&mut self) -> Result<(), Meca500Error> {
        let wait = Wait::new(self.config.io_timeout);
        self.request_with(&Command::ClearMotion, &[code::CLEARED], OnError::Record, &wait)?;
        self.request_with(
            &Command::ResumeMotion,
            &[code::RESUMED, code::IN_ERROR, code::NOT_ACTIVATED],
            OnError::Record,
            &wait,
        )?;
        Ok(())
    }

    /// `ResetError` (fails with the robot's code if the error is not resettable), then
    /// `ResumeMotion` if the motors are still activated.
    pub fn reset_and_resume(&mut self) -> Result<(), Meca500Error> {
        let wait = Wait::new(self.config.io_timeout);
        let answers =
            [code::ERROR_RESET, code::NO_ERROR_TO_RESET, code::MASTERING_LOST, code::NOT_RESETTABLE];
        let reply = self.request_with(&Command::ResetError, &answers, OnError::Record, &wait)?;
        if matches!(reply.code, code::MASTERING_LOST | code::NOT_RESETTABLE) {
            return Err(Meca500Error::Robot { code: reply.code, text: reply.payload });
        }
        self.last_error = None;
        let status = self.query_status(&wait)?;
        if status.activated && status.paused {
            self.request_with(&Command::ResumeMotion, &[code::RESUMED], OnError::Fail, &wait)?;
        }
        Ok(())
    }

    // ---- internals ----------------------------------------------------------------------

    /// After a lost answer (timeout) or an unreadable one, a motion may still be running: send
    /// `ClearMotion` while the link is up (best effort, no wait; `activate_and_home` or
    /// `stop` resumes the queue later). Robot errors need nothing (error mode stops the arm),
    /// and a closed link cannot carry a command.
    fn stop_on_link_fault<R>(&mut self, r: &Result<R, Meca500Error>) {
        if let Err(
            Meca500Error::Link(LinkError::Timeout { .. })
            | Meca500Error::Malformed(_)
            | Meca500Error::Frame(_),
        ) = r
        {
            let _ = self.send(&Command::ClearMotion);
        }
    }

    fn take_checkpoint_id(&mut self) -> u32 {
        let k = self.next_checkpoint;
        self.next_checkpoint = if k >= *CHECKPOINT_IDS.end() { *CHECKPOINT_IDS.start() } else { k + 1 };
        self.reached.retain(|&r| r != k);
        self.discarded.retain(|&r| r != k);
        k
    }

    fn request_with(
        &mut self,
        command: &Command,
        answers: &[u16],
        on_error: OnError,
        wait: &Wait,
    ) -> Result<Reply, Meca500Error> {
        self.send(command)?;
        let what = format!("answer to {}", command.name());
        loop {
            let reply = self.read_reply(wait, &what)?;
            if answers.contains(&reply.code) {
                return Ok(reply);
            }
            if reply.is_error() && on_error == OnError::Fail {
                return Err(self.robot_error(&reply));
            }
        }
    }

    fn query_status(&mut self, wait: &Wait) -> Result<StatusWord, Meca500Error> {
        let reply = self.request_with(&Command::GetStatusRobot, &[code::STATUS], OnError::Record, wait)?;
        Ok(StatusWord::from_reply(&reply)?)
    }

    /// `SyncCmdQueue(n)` → waits for `[2097][n]`; returns the first error seen on the way.
    fn sync(&mut self, wait: &Wait) -> Result<Option<Meca500Error>, Meca500Error> {
        let n = self.next_sync;
        self.next_sync = self.next_sync.wrapping_add(1).max(1);
        self.send(&Command::SyncCmdQueue(n))?;
        let mut first_error = None;
        loop {
            let reply = self.read_reply(wait, "SyncCmdQueue marker")?;
            if reply.code == code::SYNC && reply.values().ok().as_deref() == Some(&[f64::from(n)]) {
                return Ok(first_error);
            }
            if reply.is_error() && first_error.is_none() {
                first_error = Some(self.robot_error(&reply));
            }
        }
    }

    /// Consumes the answers to everything sent so far (best effort, bounded by the I/O
    /// timeout), so that stale refusals do not fail the next call.
    fn drain(&mut self) {
        let wait = Wait::new(self.config.io_timeout);
        let _ = self.sync(&wait);
    }

    /// Error for a robot message; a `[1011]` (already in error) reports the original cause.
    fn robot_error(&self, reply: &Reply) -> Meca500Error {
        match (&self.last_error, reply.code) {
            (Some((original, text)), code::IN_ERROR) if *original != code::IN_ERROR => Meca500Error::Robot {
                code: *original,
                text: format!("{text} (robot in error mode; later command refused with [1011])"),
            },
            _ => Meca500Error::Robot { code: reply.code, text: describe(reply) },
        }
    }

    fn error_mode_error(&self) -> Meca500Error {
        match &self.last_error {
            Some((code, text)) => Meca500Error::Robot { code: *code, text: text.clone() },
            None => Meca500Error::Robot {
                code: code::IN_ERROR,
                text: "the robot is in error mode (cause not seen by this connection); reset it first"
                    .to_owned(),
            },
        }
    }

    fn timeout_error(&self, wait: &Wait, what: &str) -> Meca500Error {
        LinkError::Timeout { waiting_for: what.to_owned(), after: wait.timeout() }.into()
    }

    /// Next message from the robot, routed through [`Self::observe`].
    fn read_reply(&mut self, wait: &Wait, what: &str) -> Result<Reply, Meca500Error> {
        let mut buf = [0u8; 2048];
        loop {
            if let Some(frame) = self.deframer.next_frame()? {
                if frame.is_empty() {
                    continue;
                }
                let reply = Reply::parse(&frame)?;
                self.observe(&reply);
                return Ok(reply);
            }
            let Some(remaining) = wait.remaining() else {
                return Err(self.timeout_error(wait, what));
            };
            if let Some(n) =
                recv_some(&mut self.transport, &mut buf, remaining, || format!("waiting for {what}"))?
            {
                self.deframer.push(&buf[..n]);
            }
        }
    }

    /// Updates the cached state from any message.
    fn observe(&mut self, reply: &Reply) {
        match reply.code {
            code::STATUS => {
                if let Ok(s) = StatusWord::from_reply(reply) {
                    self.last_status = Some(s);
                }
            }
            code::CHECKPOINT | code::CHECKPOINT_DISCARDED => {
                if let Ok(id) = reply.payload.trim().parse::<u32>() {
                    let list =
                        if reply.code == code::CHECKPOINT { &mut self.reached } else { &mut self.discarded };
                    list.push_back(id);
                    if list.len() > CHECKPOINT_MEMORY {
                        list.pop_front();
                    }
                }
            }
            _ if reply.is_error() => {
                let keep_original = reply.code == code::IN_ERROR && self.last_error.is_some();
                if !keep_original {
                    self.last_error = Some((reply.code, describe(reply)));
                }
            }
            _ => {}
        }
    }

    fn hw<R>(&self, r: Result<R, Meca500Error>) -> HwResult<R> {
        r.map_err(|e| e.into_hw(&self.label))
    }
}

/// The text of an error message; safety stops (whose payload is only `1`) get a sentence.
fn describe(reply: &Reply) -> String {
    match reply.code {
        code::ESTOP => {
            "E-Stop pressed: motors off; release it, reset the error, activate and home".to_owned()
        }
        code::PSTOP1 => "P-Stop 1 active: motion stopped".to_owned(),
        code::PSTOP2 => "P-Stop 2 active: motion stopped".to_owned(),
        _ => reply.payload.clone(),
    }
}

/// Checks a speed fraction and turns it into a percentage for `SetJointVel` (0.001–100).
fn joint_speed_percent(fraction: f64) -> Result<f64, Meca500Error> {
    if !(fraction.is_finite() && fraction > 0.0) {
        return Err(Meca500Error::InvalidArgument(format!("speed fraction {fraction} is not in (0, 1]")));
    }
    Ok((fraction * 100.0).clamp(0.001, 100.0))
}

fn finite_or_err(values: &[f64], what: &str) -> Result<(), Meca500Error> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Meca500Error::InvalidArgument(format!("{what} {values:?} is not finite")))
    }
}

/// The Meca500's six joint targets \[deg\], or an error naming the joint count it was given.
fn six_joints_deg(target: &ArmJoints) -> Result<[f64; 6], Meca500Error> {
    <[f64; 6]>::try_from(target.to_deg().as_slice()).map_err(|_| {
        Meca500Error::InvalidArgument(format!(
            "the Meca500 has 6 joints, got a target of {} joints (is the cell's model another robot?)",
            target.len()
        ))
    })
}

impl<T: Transport> RobotArm for Meca500<T> {
    fn joint_count(&self) -> usize {
        6
    }

    fn activate_and_home(&mut self, timeout: Duration) -> HwResult<()> {
        let r = self.activate_and_home_within(timeout);
        self.hw(r)
    }

    fn status(&mut self) -> HwResult<ArmStatus> {
        let r = self.status_word();
        let word = self.hw(r)?;
        let error = word.error.then(|| {
            self.last_error
                .clone()
                .map(|(c, t)| (i32::from(c), t))
                .unwrap_or_else(|| (0, "in error mode".to_owned()))
        });
        Ok(ArmStatus { activated: word.activated, homed: word.homed, moving: !word.end_of_block, error })
    }

    fn joints(&mut self) -> HwResult<ArmJoints> {
        let r = self.joints_deg();
        Ok(ArmJoints::from_deg_array(self.hw(r)?))
    }

    fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> HwResult<()> {
        let r = six_joints_deg(target)
            .and_then(|deg| finite_or_err(&deg, "joint target").map(|()| deg))
            .and_then(|deg| joint_speed_percent(options.speed_fraction).map(|p| (deg, p)))
            .and_then(|(deg, p)| self.send_queued(&[Command::SetJointVel(p), Command::MoveJoints(deg)]));
        self.stop_on_link_fault(&r);
        self.hw(r)
    }

    fn move_linear_relative(
        &mut self,
        displacement_mm: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> HwResult<()> {
        let d = [displacement_mm.x, displacement_mm.y, displacement_mm.z, 0.0, 0.0, 0.0];
        let move_cmd = match frame {
            LinearFrame::World => Command::MoveLinRelWrf(d),
            LinearFrame::Tool => Command::MoveLinRelTrf(d),
        };
        let max = self.config.max_linear_speed_mm_s;
        let r = finite_or_err(&d, "displacement")
            .and_then(|()| joint_speed_percent(options.speed_fraction))
            .and_then(|p| self.send_queued(&[Command::SetCartLinVel(p / 100.0 * max), move_cmd]));
        self.stop_on_link_fault(&r);
        self.hw(r)
    }

    fn wait_idle(&mut self, timeout: Duration) -> HwResult<()> {
        let r = self.wait_idle_within(timeout);
        self.hw(r)
    }

    fn stop(&mut self) -> HwResult<()> {
        let r = self.clear_motion();
        self.hw(r)
    }

    fn reset_error(&mut self) -> HwResult<()> {
        let r = self.reset_and_resume();
        self.hw(r)
    }
}
