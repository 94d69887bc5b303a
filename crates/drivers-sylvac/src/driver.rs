//! The blocking Sylvac driver: [`SylvacGauge`] implements [`Gauge`] over any [`Transport`].

use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use vatcal_hardware_traits::{Gauge, Result as HwResult};

use crate::codec::{Answer, Command, LineDeframer, MAX_PRESET_MM, Unit};
use crate::error::SylvacError;
use crate::transport::Transport;
use vatcal_hardware_traits::transport::Deadline as Wait;
use vatcal_hardware_traits::transport::{LinkError, recv_some};

/// Connection settings and timeouts.
#[derive(Debug, Clone, PartialEq)]
pub struct SylvacConfig {
    /// device name used in error messages (e.g. `"gauge 1"`)
    pub name: String,
    /// timeout of every query (the cable manual says an answer comes within ~100 ms)
    pub io_timeout: Duration,
    /// TCP connect timeout
    pub connect_timeout: Duration,
    /// switch the gauge to mm at connection (`MM`); otherwise the unit is read with `UNI?` and
    /// inch readings are converted
    pub force_mm: bool,
    /// how long to listen for an answer after a setter (`MM`, `PRE …`); a setter may be
    /// silent (\[UNC\]), an `ERRn` in this window fails it
    pub setter_ack_window: Duration,
    /// after a preset, read the gauge and fail if it differs from the preset by more than this
    /// \[mm\] (`None`: no check)
    pub preset_tolerance_mm: Option<f64>,
    /// send `PRE ON` after `PRE ±value` (\[UNC\] whether the gauge needs it)
    pub preset_mode_on: bool,
}

impl Default for SylvacConfig {
    /// 500 ms I/O timeout, mm forced, 100 ms setter window, preset checked to 2 µm, no
    /// `PRE ON`.
    fn default() -> Self {
        Self {
            name: "gauge".to_owned(),
            io_timeout: Duration::from_millis(500),
            connect_timeout: Duration::from_secs(2),
            force_mm: true,
            setter_ack_window: Duration::from_millis(100),
            preset_tolerance_mm: Some(0.002),
            preset_mode_on: false,
        }
    }
}

/// A Sylvac gauge on the other end of a [`Transport`] (cable, serial-to-TCP bridge, simulator).
#[derive(Debug)]
pub struct SylvacGauge<T: Transport = TcpStream> {
    transport: T,
    deframer: LineDeframer,
    config: SylvacConfig,
    unit: Unit,
    id: String,
    label: String,
}

impl SylvacGauge<TcpStream> {
    /// Connects over TCP (a serial-to-TCP bridge or the simulator) and identifies the gauge.
    ///
    /// # Examples
    /// Against the simulator:
    /// ```
    /// use vatcal_drivers_sylvac::sim::{SimConfig, SylvacSim};
    /// use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
    /// use vatcal_hardware_traits::Gauge;
    ///
    /// let sim = SylvacSim::start(SimConfig::default())?;
    /// let mut gauge = SylvacGauge::connect_tcp(sim.addr(), SylvacConfig::default())?;
    /// sim.set_plunger_mm(1.2345);
    /// assert!((gauge.read_mm()? - 1.2345).abs() < 1e-9);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`SylvacError::Link`] when the connection cannot be made, drops or times out;
    /// [`SylvacError::Gauge`] or [`SylvacError::UnexpectedAnswer`] when the gauge does not
    /// identify itself as expected.
    pub fn connect_tcp(addr: impl ToSocketAddrs, config: SylvacConfig) -> Result<Self, SylvacError> {
        let stream = vatcal_hardware_traits::transport::connect_tcp(addr, config.connect_timeout)?;
        let peer = stream.peer_addr()?;
        let mut gauge = Self::new(stream, config)?;
        gauge.label = format!("{} at {peer}", gauge.config.name);
        Ok(gauge)
    }
}

#[cfg(feature = "serial")]
impl SylvacGauge<crate::transport::SerialTransport> {
    /// Opens a duplex cable (4800 7E2) and identifies the gauge.
    pub fn open_serial(path: &str, config: SylvacConfig) -> Result<Self, SylvacError> {
        let port = crate::transport::SerialTransport::open(path, &crate::transport::SERIAL_SETTINGS)?;
        let mut gauge = Self::new(port, config)?;
        gauge.label = format!("{} at {path}", gauge.config.name);
        Ok(gauge)
    }
}

impl<T: Transport> SylvacGauge<T> {
    /// Wraps a connected transport: reads `ID?`, switches continuous output off (`OUT0`),
    /// forces mm (`MM`, if configured) and reads `UNI?`.
    pub fn new(transport: T, config: SylvacConfig) -> Result<Self, SylvacError> {
        let mut gauge = Self {
            transport,
            deframer: LineDeframer::new(),
            label: config.name.clone(),
            config,
            unit: Unit::Mm,
            id: String::new(),
        };
        gauge.id = match gauge.query(&Command::Id)? {
            Answer::Text(t) => t,
            Answer::Value(v) => v.to_string(),
            Answer::Error(e) => return Err(SylvacError::Gauge { command: Command::Id.to_text(), error: e }),
        };
        // streamed values (`OUT1`) would race with answers to `?`: the driver polls
        gauge.setter(&Command::ContinuousOutput(false))?;
        if gauge.config.force_mm {
            gauge.setter(&Command::SetUnit(Unit::Mm))?;
        }
        gauge.unit = match gauge.query(&Command::UnitQuery)? {
            Answer::Text(t) if t.eq_ignore_ascii_case("MM") => Unit::Mm,
            Answer::Text(t) if t.eq_ignore_ascii_case("IN") => Unit::Inch,
            other => return Err(unexpected(&Command::UnitQuery, &other)),
        };
        Ok(gauge)
    }

    /// The instrument id (`ID?`), e.g. `SY289`.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The display unit.
    pub fn unit(&self) -> Unit {
        self.unit
    }

    /// The name errors carry: [`SylvacConfig::name`] plus ` at <address or port>` when the
    /// driver opened the link itself (e.g. `gauge 1 at 127.0.0.1:55561`).
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The configuration.
    pub fn config(&self) -> &SylvacConfig {
        &self.config
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// Replaces the name errors carry (see [`Self::label`]).
    #[cfg(feature = "ble")]
    pub(crate) fn set_label(&mut self, label: String) {
        self.label = label;
    }

    /// Hands the transport back.
    pub fn into_inner(self) -> T {
        self.transport
    }

    /// Sends a query and returns its answer. For `?` the first value or error line counts
    /// (a stray setter acknowledgement is skipped); for other queries, the first line.
    pub fn query(&mut self, command: &Command) -> Result<Answer, SylvacError> {
        self.discard_pending()?;
        self.send_command(command)?;
        let wait = Wait::new(self.config.io_timeout);
        // a text line before the value of `?` may be a late setter acknowledgement: skip it,
        // but if no value follows, report it (garbage) rather than a bare timeout
        let mut skipped: Option<String> = None;
        loop {
            let line = match self.read_line(&wait, command) {
                Ok(line) => line,
                Err(SylvacError::Link(LinkError::Timeout { .. })) if skipped.is_some() => {
                    let answer = skipped.unwrap_or_default();
                    return Err(SylvacError::UnexpectedAnswer { command: command.to_text(), answer });
                }
                Err(e) => return Err(e),
            };
            let answer = Answer::parse(&line);
            match (&answer, command) {
                (Answer::Text(t), Command::Read) => skipped = Some(t.clone()),
                (Answer::Error(e), _) => {
                    return Err(SylvacError::Gauge { command: command.to_text(), error: *e });
                }
                _ => return Ok(answer),
            }
        }
    }

    /// Sends a setter; an `ERRn` within [`SylvacConfig::setter_ack_window`] fails it, any other
    /// answer (or none) accepts it.
    pub fn setter(&mut self, command: &Command) -> Result<(), SylvacError> {
        self.discard_pending()?;
        self.send_command(command)?;
        let wait = Wait::new(self.config.setter_ack_window);
        match self.read_line(&wait, command) {
            Ok(line) => match Answer::parse(&line) {
                Answer::Error(e) => Err(SylvacError::Gauge { command: command.to_text(), error: e }),
                _ => Ok(()),
            },
            Err(SylvacError::Link(LinkError::Timeout { .. })) => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Current reading in mm.
    pub fn reading_mm(&mut self) -> Result<f64, SylvacError> {
        match self.query(&Command::Read)? {
            Answer::Value(v) => Ok(self.unit.to_mm(v)),
            other => Err(unexpected(&Command::Read, &other)),
        }
    }

    /// Presets the current position to read `value_mm` (`PRE ±XXX.YYYY` in the display unit),
    /// then checks the reading if configured.
    pub fn set_preset_mm(&mut self, value_mm: f64) -> Result<(), SylvacError> {
        if !(value_mm.is_finite() && value_mm.abs() <= MAX_PRESET_MM) {
            return Err(SylvacError::PresetOutOfRange { value_mm });
        }
        self.setter(&Command::Preset(self.unit.from_mm(value_mm)))?;
        if self.config.preset_mode_on {
            self.setter(&Command::PresetMode(true))?;
        }
        if let Some(tol) = self.config.preset_tolerance_mm {
            let read_mm = self.reading_mm()?;
            if (read_mm - value_mm).abs() > tol {
                return Err(SylvacError::PresetNotApplied { wanted_mm: value_mm, read_mm });
            }
        }
        Ok(())
    }

    fn send_command(&mut self, command: &Command) -> Result<(), SylvacError> {
        self.transport
            .send(&command.encode())
            .map_err(|e| LinkError::from_send(e, || format!("sending '{command}'")).into())
    }

    /// Drops whatever arrived unasked (late acknowledgements, continuous output).
    fn discard_pending(&mut self) -> Result<(), SylvacError> {
        let mut buf = [0u8; 512];
        loop {
            if recv_some(&mut self.transport, &mut buf, Duration::ZERO, || {
                "idle (before a request)".to_owned()
            })?
            .is_none()
            {
                break;
            }
        }
        self.deframer.clear();
        Ok(())
    }

    fn read_line(&mut self, wait: &Wait, command: &Command) -> Result<String, SylvacError> {
        let mut buf = [0u8; 512];
        loop {
            if let Some(line) = self.deframer.next_line()? {
                return Ok(line);
            }
            let Some(remaining) = wait.remaining() else {
                return Err(LinkError::Timeout {
                    waiting_for: format!("answer to '{command}'"),
                    after: wait.timeout(),
                }
                .into());
            };
            if let Some(n) = recv_some(&mut self.transport, &mut buf, remaining, || {
                format!("waiting for the answer to '{command}'")
            })? {
                self.deframer.push(&buf[..n]);
            }
        }
    }

    fn hw<R>(&self, r: Result<R, SylvacError>) -> HwResult<R> {
        r.map_err(|e| e.into_hw(&self.label))
    }
}

fn unexpected(command: &Command, answer: &Answer) -> SylvacError {
    let answer = match answer {
        Answer::Value(v) => v.to_string(),
        Answer::Error(e) => e.to_text(),
        Answer::Text(t) => t.clone(),
    };
    SylvacError::UnexpectedAnswer { command: command.to_text(), answer }
}

impl<T: Transport> Gauge for SylvacGauge<T> {
    fn read_mm(&mut self) -> HwResult<f64> {
        let r = self.reading_mm();
        self.hw(r)
    }

    fn preset_mm(&mut self, value_mm: f64) -> HwResult<()> {
        let r = self.set_preset_mm(value_mm);
        self.hw(r)
    }
}
