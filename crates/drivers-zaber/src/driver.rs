//! The blocking Zaber driver: [`ZaberAxis`] implements [`LinearAxis`] over any [`Transport`].

use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use vatcal_hardware_traits::{LinearAxis, MotionOptions, Result as HwResult};

use crate::codec::{Command, LineDeframer, LineEnding, Message, Reply, Status, Warning, parse_warning_list};
use crate::error::ZaberError;
use crate::transport::Transport;
use vatcal_hardware_traits::transport::Deadline as Wait;
use vatcal_hardware_traits::transport::{LinkError, recv_some};

/// TCP port forwarding to the whole daisy chain.
pub const TCP_PORT_CHAIN: u16 = 55550;
/// TCP port reaching only the device that owns the Ethernet port.
pub const TCP_PORT_DEVICE_ONLY: u16 = 55551;

/// Full steps per motor revolution of Zaber stepper stages.
pub const FULL_STEPS_PER_REV: f64 = 200.0;
/// Default microstep `resolution` (microsteps per full step).
pub const DEFAULT_RESOLUTION: u32 = 64;
/// Lead of the X-LRQ300AP lead screw assumed by default [mm/rev]. **Unverified**
/// (protocols.md §2.6 gives 2.5 mm or 1.27 mm as guesses); check `get limit.max` on the real
/// device, see `docs/drivers.md`.
pub const DEFAULT_LEAD_MM: f64 = 2.5;

/// How mm map to microsteps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MicrostepSize {
    /// From the lead screw: `lead_mm / (200 × resolution)`, with `resolution` read from the
    /// device at connection (§2.6).
    FromLead {
        /// lead of the screw [mm per motor revolution]
        lead_mm: f64,
    },
    /// A fixed microstep size \[mm\] (e.g. measured on the real device).
    Fixed {
        /// one microstep \[mm\]
        mm: f64,
    },
}

impl Default for MicrostepSize {
    fn default() -> Self {
        MicrostepSize::FromLead { lead_mm: DEFAULT_LEAD_MM }
    }
}

impl MicrostepSize {
    /// Microstep size \[mm\] for a device microstep `resolution`.
    pub fn microstep_mm(&self, resolution: u32) -> f64 {
        match *self {
            MicrostepSize::FromLead { lead_mm } => {
                lead_mm / (FULL_STEPS_PER_REV * f64::from(resolution.max(1)))
            }
            MicrostepSize::Fixed { mm } => mm,
        }
    }
}

/// The first pause of a wait for IDLE; each next pause doubles up to
/// [`ZaberConfig::poll_interval`].
const FIRST_POLL: Duration = Duration::from_millis(1);

/// Connection settings and timeouts.
#[derive(Debug, Clone, PartialEq)]
pub struct ZaberConfig {
    /// device name used in error messages
    pub name: String,
    /// device address in the chain (1–99)
    pub address: u8,
    /// axis number (1 for the X-LRQ)
    pub axis: u8,
    /// timeout of every command's reply
    pub io_timeout: Duration,
    /// TCP connect timeout
    pub connect_timeout: Duration,
    /// longest pause between two status polls while waiting for IDLE (zaber-motion: ~50 ms;
    /// the first pauses are 1, 2, 4, … ms)
    pub poll_interval: Duration,
    /// append `:CC` checksums to commands (zaber-motion always does)
    pub checksums: bool,
    /// send message ids and match them in replies
    pub message_ids: bool,
    /// line ending of commands
    pub line_ending: LineEnding,
    /// mm ↔ microstep conversion
    pub microstep: MicrostepSize,
    /// scale the move speed with `MotionOptions::speed_fraction` by setting `maxspeed` to
    /// that fraction of the value read at connection for the move (set back to that value
    /// when the move has ended: a wait that sees IDLE, or a stop)
    pub speed_control: bool,
}

impl Default for ZaberConfig {
    /// Address 1, axis 1, 1 s I/O timeout, polls while moving every 1, 2, 4, … ms up to 50 ms,
    /// checksums and ids on, LF, lead
    /// 2.5 mm \[unverified\], speed control on.
    fn default() -> Self {
        Self {
            name: "zaber guide".to_owned(),
            address: 1,
            axis: 1,
            io_timeout: Duration::from_secs(1),
            connect_timeout: Duration::from_secs(5),
            poll_interval: Duration::from_millis(50),
            checksums: true,
            message_ids: true,
            line_ending: LineEnding::Lf,
            microstep: MicrostepSize::default(),
            speed_control: true,
        }
    }
}

/// What the driver learnt from the device at connection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisInfo {
    /// microstep resolution (`get resolution`, default 64 if unsupported)
    pub resolution: u32,
    /// microstep size \[mm\]
    pub microstep_mm: f64,
    /// travel limits \[microsteps\] (`limit.min`, `limit.max`), if the device reports them
    pub limits_microsteps: Option<(i64, i64)>,
    /// `maxspeed` at connection [device units]: the 100 % of the speed fraction
    pub base_maxspeed: Option<i64>,
}

impl AxisInfo {
    /// Travel \[mm\], if known.
    pub fn travel_mm(&self) -> Option<(f64, f64)> {
        self.limits_microsteps.map(|(lo, hi)| (lo as f64 * self.microstep_mm, hi as f64 * self.microstep_mm))
    }
}

/// One axis of a Zaber device (the X-LRQ300AP guide) on the other end of a [`Transport`].
#[derive(Debug)]
pub struct ZaberAxis<T: Transport = TcpStream> {
    transport: T,
    deframer: LineDeframer,
    config: ZaberConfig,
    info: AxisInfo,
    next_id: u8,
    speed_set: Option<i64>,
    alerts: Vec<Message>,
    label: String,
}

impl ZaberAxis<TcpStream> {
    /// Connects to a raw-ASCII TCP port (e.g. `"192.168.0.50:55550"`) and identifies the axis.
    ///
    /// # Examples
    /// Against the protocol simulator:
    /// ```
    /// use vatcal_drivers_zaber::sim::{SimConfig, ZaberSim};
    /// use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig};
    ///
    /// let sim = ZaberSim::start(SimConfig::fast(50.0))?;
    /// let guide = ZaberAxis::connect_tcp(sim.addr(), ZaberConfig::default())?;
    /// let (lo, hi) = guide.info().travel_mm().ok_or("the simulator reports its limits")?;
    /// assert!(lo <= 0.0 && hi > 250.0, "X-LRQ300 travel {lo}..{hi} mm");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`ZaberError::Link`] when the connection cannot be made, drops or times out;
    /// [`ZaberError::Rejected`], [`ZaberError::Malformed`] or [`ZaberError::Protocol`] when the
    /// device does not identify itself as expected.
    pub fn connect_tcp(addr: impl ToSocketAddrs, config: ZaberConfig) -> Result<Self, ZaberError> {
        let stream = vatcal_hardware_traits::transport::connect_tcp(addr, config.connect_timeout)?;
        let peer = stream.peer_addr()?;
        let mut axis = Self::new(stream, config)?;
        axis.label = format!("{} at {peer}", axis.config.name);
        Ok(axis)
    }
}

#[cfg(feature = "serial")]
impl ZaberAxis<crate::transport::SerialTransport> {
    /// Opens a serial port (115200 8N1) and identifies the axis.
    pub fn open_serial(path: &str, baud: u32, config: ZaberConfig) -> Result<Self, ZaberError> {
        let port = crate::transport::SerialTransport::open(path, &crate::transport::serial_settings(baud))?;
        let mut axis = Self::new(port, config)?;
        axis.label = format!("{} at {path}", axis.config.name);
        Ok(axis)
    }
}

impl<T: Transport> ZaberAxis<T> {
    /// Wraps a connected transport and reads resolution, travel limits and `maxspeed`
    /// (settings the device rejects fall back to defaults / unknown).
    pub fn new(transport: T, config: ZaberConfig) -> Result<Self, ZaberError> {
        let mut axis = Self {
            transport,
            deframer: LineDeframer::new(),
            info: AxisInfo {
                resolution: DEFAULT_RESOLUTION,
                microstep_mm: 0.0,
                limits_microsteps: None,
                base_maxspeed: None,
            },
            label: config.name.clone(),
            config,
            next_id: 0,
            speed_set: None,
            alerts: Vec::new(),
        };
        let resolution =
            axis.get_optional_int("resolution")?.and_then(|r| u32::try_from(r).ok()).filter(|&r| r > 0);
        axis.info.resolution = resolution.unwrap_or(DEFAULT_RESOLUTION);
        axis.info.microstep_mm = axis.config.microstep.microstep_mm(axis.info.resolution);
        if !(axis.info.microstep_mm.is_finite() && axis.info.microstep_mm > 0.0) {
            return Err(ZaberError::InvalidArgument(format!("microstep size {} mm", axis.info.microstep_mm)));
        }
        let lo = axis.get_optional_int("limit.min")?;
        let hi = axis.get_optional_int("limit.max")?;
        axis.info.limits_microsteps = lo.zip(hi);
        axis.info.base_maxspeed = axis.get_optional_int("maxspeed")?;
        axis.speed_set = axis.info.base_maxspeed;
        Ok(axis)
    }

    /// What was read at connection.
    pub fn info(&self) -> &AxisInfo {
        &self.info
    }

    /// The name errors carry: [`ZaberConfig::name`] plus ` at <address or port>` when the
    /// driver opened the link itself (e.g. `zaber guide at 127.0.0.1:55550`).
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The configuration.
    pub fn config(&self) -> &ZaberConfig {
        &self.config
    }

    /// Alerts (`!…`) and info lines (`#…`) received so far (drained).
    pub fn take_unsolicited(&mut self) -> Vec<Message> {
        std::mem::take(&mut self.alerts)
    }

    /// Hands the transport back.
    pub fn into_inner(self) -> T {
        self.transport
    }

    /// mm → microsteps (rounded).
    pub fn mm_to_microsteps(&self, mm: f64) -> i64 {
        (mm / self.info.microstep_mm).round() as i64
    }

    /// microsteps → mm.
    pub fn microsteps_to_mm(&self, steps: i64) -> f64 {
        steps as f64 * self.info.microstep_mm
    }

    /// Sends `text` to `axis` of the configured device and returns its accepted reply;
    /// `RJ` becomes [`ZaberError::Rejected`].
    pub fn command(&mut self, axis: u8, text: &str) -> Result<Reply, ZaberError> {
        let reply = self.exchange(axis, text)?;
        if reply.accepted {
            Ok(reply)
        } else {
            Err(ZaberError::Rejected { command: text.to_owned(), reason: reply.data, warning: reply.warning })
        }
    }

    /// Sends `text` and returns the matching reply, accepted or not.
    pub fn exchange(&mut self, axis: u8, text: &str) -> Result<Reply, ZaberError> {
        let mut command = Command::new(self.config.address, axis, text);
        if self.config.message_ids {
            command = command.with_id(self.next_id);
            self.next_id = (self.next_id + 1) % 100;
        }
        self.transport
            .send(&command.encode(self.config.checksums, self.config.line_ending))
            .map_err(|e| LinkError::from_send(e, || format!("sending '{text}'")))?;
        let wait = Wait::new(self.config.io_timeout);
        loop {
            match self.read_message(&wait, text)? {
                Message::Reply(r) if self.matches(&command, &r) => return Ok(r),
                Message::Reply(_) => {} // a late reply to an earlier (timed-out) command
                other => self.alerts.push(other),
            }
        }
    }

    fn matches(&self, command: &Command, reply: &Reply) -> bool {
        reply.address == command.address && (command.id.is_none() || reply.id == command.id)
    }

    /// `get <setting>` on the configured axis as an integer.
    pub fn get_int(&mut self, setting: &str) -> Result<i64, ZaberError> {
        let reply = self.command(self.config.axis, &format!("get {setting}"))?;
        parse_int(&reply)
    }

    /// Like [`Self::get_int`], `None` if the device does not know the setting.
    fn get_optional_int(&mut self, setting: &str) -> Result<Option<i64>, ZaberError> {
        match self.get_int(setting) {
            Ok(v) => Ok(Some(v)),
            Err(ZaberError::Rejected { reason, .. }) if reason == "BADCOMMAND" => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Every active warning flag (`/addr 0 warnings`), most important first.
    pub fn warnings(&mut self) -> Result<Vec<Warning>, ZaberError> {
        let reply = self.command(0, "warnings")?;
        let mut flags = parse_warning_list(&reply.data)?;
        flags.sort_by_key(|w| (w.priority(), w.0));
        Ok(flags)
    }

    /// Clears the clearable flags (`warnings clear`).
    pub fn clear_warnings(&mut self) -> Result<(), ZaberError> {
        self.command(0, "warnings clear").map(|_| ())
    }

    /// Clears the clearable flags before a new motion, refusing with [`ZaberError::Busy`] if
    /// the axis still moves (a new move would interrupt it and leave `NI` behind).
    fn prepare_motion(&mut self) -> Result<(), ZaberError> {
        // a fault latched since the last move (stall, driver disabled, …) means the position
        // may be wrong: refuse to move instead of clearing it silently (homing clears it)
        let faults: Vec<Warning> = self.warnings()?.into_iter().filter(Warning::is_fault).collect();
        if !faults.is_empty() {
            return Err(ZaberError::MotionFailed { flags: faults });
        }
        self.clear_for_motion()
    }

    /// `warnings clear` before a motion; refuses while the axis is busy.
    fn clear_for_motion(&mut self) -> Result<(), ZaberError> {
        let reply = self.command(0, "warnings clear")?;
        if reply.status == Status::Busy { Err(ZaberError::Busy) } else { Ok(()) }
    }

    /// Position \[microsteps\].
    pub fn position_microsteps(&mut self) -> Result<i64, ZaberError> {
        self.get_int("pos")
    }

    /// True when the axis shows neither `WR` nor `WH`, nor a latched fault (`F…`: after a
    /// stall the position is not to be trusted until the axis is homed again).
    pub fn homed(&mut self) -> Result<bool, ZaberError> {
        Ok(!self.warnings()?.iter().any(|w| w.means_not_homed() || w.is_fault()))
    }

    /// Starts homing and waits for IDLE within `timeout`.
    pub fn home_within(&mut self, timeout: Duration) -> Result<(), ZaberError> {
        let wait = Wait::new(timeout);
        self.clear_for_motion()?;
        let r = self.command(self.config.axis, "home").and_then(|_| self.wait_idle_until(&wait));
        self.stop_on_link_fault(&r);
        r
    }

    /// After a lost answer (timeout) or an unreadable one, the axis may still be moving: send
    /// `stop` while the link is up (best effort, its reply is not awaited and is skipped later
    /// by message id). A closed link cannot carry a command.
    fn stop_on_link_fault<R>(&mut self, r: &Result<R, ZaberError>) {
        if let Err(
            ZaberError::Link(LinkError::Timeout { .. })
            | ZaberError::Malformed(_)
            | ZaberError::Frame(_)
            | ZaberError::Protocol(_),
        ) = r
        {
            let stop = Command::new(self.config.address, self.config.axis, "stop");
            let _ = self.transport.send(&stop.encode(self.config.checksums, self.config.line_ending));
        }
    }

    /// Starts an absolute move to `target` microsteps at `speed_fraction` of the base speed.
    pub fn move_absolute_microsteps(&mut self, target: i64, speed_fraction: f64) -> Result<(), ZaberError> {
        if !(speed_fraction.is_finite() && speed_fraction > 0.0) {
            return Err(ZaberError::InvalidArgument(format!(
                "speed fraction {speed_fraction} is not in (0, 1]"
            )));
        }
        if let Some((lo, hi)) = self.info.limits_microsteps
            && (target < lo || target > hi)
        {
            return Err(self.out_of_range(target));
        }
        self.prepare_motion()?;
        self.apply_speed(speed_fraction)?;
        let started = self.command(self.config.axis, &format!("move abs {target}"));
        self.stop_on_link_fault(&started);
        match started {
            Ok(_) => Ok(()),
            Err(ZaberError::Rejected { reason, warning, command }) => {
                if warning.is_some_and(|w| w.means_not_homed()) || !self.homed()? {
                    Err(ZaberError::NotHomed)
                } else if reason == "BADDATA" {
                    Err(self.out_of_range(target))
                } else {
                    Err(ZaberError::Rejected { command, reason, warning })
                }
            }
            Err(e) => Err(e),
        }
    }

    fn out_of_range(&self, target: i64) -> ZaberError {
        let (lo, hi) = self.info.limits_microsteps.unwrap_or((i64::MIN, i64::MAX));
        ZaberError::OutOfRange {
            target_mm: self.microsteps_to_mm(target),
            min_mm: self.microsteps_to_mm(lo),
            max_mm: self.microsteps_to_mm(hi),
        }
    }

    fn apply_speed(&mut self, fraction: f64) -> Result<(), ZaberError> {
        let Some(base) = self.info.base_maxspeed.filter(|_| self.config.speed_control) else { return Ok(()) };
        let wanted = ((base as f64) * fraction.min(1.0)).round().max(1.0) as i64;
        if self.speed_set != Some(wanted) {
            self.command(self.config.axis, &format!("set maxspeed {wanted}"))?;
            self.speed_set = Some(wanted);
        }
        Ok(())
    }

    /// Polls until IDLE (or `timeout`), then checks the flags: a fault, `WL`, `WS` or `NI`
    /// fails with [`ZaberError::MotionFailed`] (the flags are cleared on the device).
    /// If the device stops answering in time or answers garbage, `stop` is sent (without
    /// waiting) before the error is returned. An axis still BUSY at `timeout` that answers
    /// every poll is not stopped ([`ZaberError::MotionNotFinished`]): a caller waiting in
    /// slices waits again; one that gives up calls `stop`.
    pub fn wait_idle_within(&mut self, timeout: Duration) -> Result<(), ZaberError> {
        let r = self.wait_idle_until(&Wait::new(timeout));
        self.stop_on_link_fault(&r);
        r
    }

    fn wait_idle_until(&mut self, wait: &Wait) -> Result<(), ZaberError> {
        // the first polls come quickly (a short move, or a move to where the axis already is,
        // ends within milliseconds), then every `poll_interval`
        let mut pause = FIRST_POLL.min(self.config.poll_interval);
        loop {
            let reply = self.command(self.config.axis, "")?;
            if reply.status == Status::Idle {
                self.restore_speed()?;
                return self.check_motion_flags();
            }
            match wait.remaining() {
                Some(r) => {
                    std::thread::sleep(r.min(pause));
                    pause = (pause * 2).min(self.config.poll_interval);
                }
                // it answered every poll: still moving, not a link fault (not stopped here)
                None => return Err(ZaberError::MotionNotFinished { after: wait.timeout() }),
            }
        }
    }

    /// Puts `maxspeed` back to the value read at connection once the axis is idle: the next
    /// session (a resume, another command) reads the full speed again instead of this move's
    /// fraction of it, so the fractions do not compound from one connection to the next.
    fn restore_speed(&mut self) -> Result<(), ZaberError> {
        let Some(base) = self.info.base_maxspeed.filter(|_| self.config.speed_control) else { return Ok(()) };
        if self.speed_set != Some(base) {
            self.command(self.config.axis, &format!("set maxspeed {base}"))?;
            self.speed_set = Some(base);
        }
        Ok(())
    }

    fn check_motion_flags(&mut self) -> Result<(), ZaberError> {
        let flags: Vec<Warning> = self.warnings()?.into_iter().filter(Warning::fails_motion).collect();
        if flags.is_empty() {
            return Ok(());
        }
        self.clear_warnings()?;
        Err(ZaberError::MotionFailed { flags })
    }

    /// `stop`, wait for IDLE within the I/O timeout, clear the `NI` notice.
    pub fn stop_now(&mut self) -> Result<(), ZaberError> {
        self.command(self.config.axis, "stop")?;
        let wait = Wait::new(self.config.io_timeout);
        loop {
            if self.command(self.config.axis, "")?.status == Status::Idle {
                self.restore_speed()?;
                return self.clear_warnings();
            }
            match wait.remaining() {
                Some(r) => std::thread::sleep(r.min(self.config.poll_interval)),
                None => {
                    return Err(LinkError::Timeout {
                        waiting_for: "IDLE after stop".to_owned(),
                        after: wait.timeout(),
                    }
                    .into());
                }
            }
        }
    }

    fn read_message(&mut self, wait: &Wait, command_text: &str) -> Result<Message, ZaberError> {
        let what = if command_text.is_empty() {
            "reply to a status poll".to_owned()
        } else {
            format!("reply to '{command_text}'")
        };
        let mut buf = [0u8; 1024];
        loop {
            if let Some(line) = self.deframer.next_line()? {
                return Ok(Message::parse(&line)?);
            }
            let Some(remaining) = wait.remaining() else {
                return Err(LinkError::Timeout { waiting_for: what, after: wait.timeout() }.into());
            };
            if let Some(n) =
                recv_some(&mut self.transport, &mut buf, remaining, || format!("waiting for the {what}"))?
            {
                self.deframer.push(&buf[..n]);
            }
        }
    }

    fn hw<R>(&self, r: Result<R, ZaberError>) -> HwResult<R> {
        r.map_err(|e| e.into_hw(&self.label))
    }
}

/// The first data token of a reply as an integer.
fn parse_int(reply: &Reply) -> Result<i64, ZaberError> {
    reply
        .data
        .split_whitespace()
        .next()
        .and_then(|t| t.parse::<i64>().ok())
        .ok_or_else(|| ZaberError::Protocol(format!("expected an integer, got '{}'", reply.data)))
}

impl<T: Transport> LinearAxis for ZaberAxis<T> {
    fn home(&mut self, timeout: Duration) -> HwResult<()> {
        let r = self.home_within(timeout);
        self.hw(r)
    }

    fn is_homed(&mut self) -> HwResult<bool> {
        let r = self.homed();
        self.hw(r)
    }

    fn position_mm(&mut self) -> HwResult<f64> {
        let r = self.position_microsteps().map(|s| self.microsteps_to_mm(s));
        self.hw(r)
    }

    fn move_absolute_mm(&mut self, target_mm: f64, options: &MotionOptions) -> HwResult<()> {
        let r = if target_mm.is_finite() {
            let target = self.mm_to_microsteps(target_mm);
            self.move_absolute_microsteps(target, options.speed_fraction)
        } else {
            Err(ZaberError::InvalidArgument(format!("target {target_mm} mm is not finite")))
        };
        self.hw(r)
    }

    fn wait_idle(&mut self, timeout: Duration) -> HwResult<()> {
        let r = self.wait_idle_within(timeout);
        self.hw(r)
    }

    fn stop(&mut self) -> HwResult<()> {
        let r = self.stop_now();
        self.hw(r)
    }
}
