//! Parsing, validation and connection of a devices file.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;
use toml::Spanned;
use vatcal_drivers_meca500::driver::{Meca500, Meca500Config};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_drivers_tracker::{
    CommandTracker, CommandTrackerConfig, ConsoleTracker, LineTracker, TrackerConfig,
};
use vatcal_drivers_zaber::driver::{AxisInfo, MicrostepSize, ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::{
    Gauge, JointLayout, LinearAxis, PositionTracker, ProbePlacement, RobotArm, Thermometer, TriCalConfig,
};

use crate::sim_control::SimControl;
use crate::thermometer::{CommandThermometer, FileThermometer, SimCellThermometer};

/// Why a devices file was rejected or a device could not be connected.
#[derive(Debug, thiserror::Error)]
pub enum DevicesError {
    /// The file cannot be read.
    #[error("{path}: {cause}")]
    Read {
        /// the file
        path: PathBuf,
        /// cause (stated in the message, not repeated as a source)
        cause: std::io::Error,
    },
    /// The file is not valid TOML or does not have the expected keys (unknown key, missing
    /// device, wrong type); the message names the line and the key.
    #[error("{path}: {message}")]
    Parse {
        /// the file
        path: PathBuf,
        /// the TOML parser's message (line, column, key)
        message: String,
    },
    /// A field has an invalid value.
    #[error("{path}:{line}: `{field}`: {reason}")]
    Field {
        /// the file
        path: PathBuf,
        /// 1-based line of the value (0 if unknown)
        line: usize,
        /// the field, e.g. `gauges[2].tcp`
        field: String,
        /// what is wrong
        reason: String,
    },
    /// The file does not fit the cell's model: a guide for a chain without one, or no guide
    /// for a chain that has one.
    #[error("{path}: {reason}")]
    Cell {
        /// the file
        path: PathBuf,
        /// what does not fit
        reason: String,
    },
    /// A device could not be connected (or did not identify itself).
    #[error("connecting the {role} ({what}): {cause}")]
    Connect {
        /// `arm`, `guide`, `gauge 2`, `sim_control`
        role: String,
        /// kind and address
        what: String,
        /// the device error (names the device; stated in the message, not repeated as a
        /// source)
        cause: vatcal_hardware_traits::Error,
    },
}

/// How a device is reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Link {
    /// TCP `host:port` (the device itself, a serial-to-TCP bridge or a simulator)
    Tcp(String),
    /// serial port path (needs the `serial` feature)
    Serial {
        /// e.g. `/dev/ttyUSB0`
        path: String,
        /// baud rate (Zaber: 115200; Sylvac: fixed by the driver)
        baud: u32,
    },
}

impl std::fmt::Display for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Link::Tcp(a) => write!(f, "tcp {a}"),
            Link::Serial { path, baud } => write!(f, "serial {path} at {baud} Bd"),
        }
    }
}

/// `arm = { kind = "meca500", address = "…:10000", … }`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSpec {
    /// driver: `meca500`
    pub kind: Spanned<String>,
    /// control port `host:port` (Meca500: 10000)
    pub address: Spanned<String>,
    /// monitoring port `host:port` (Meca500: 10001); optional, checked but not used yet
    pub monitoring: Option<Spanned<String>>,
    /// timeout of every request \[ms\] (default 2000)
    pub io_timeout_ms: Option<Spanned<u64>>,
    /// timeout of the connection and the banner \[ms\] (default 5000)
    pub connect_timeout_ms: Option<Spanned<u64>>,
}

/// `guide = { kind = "zaber", tcp = "…:55550" }` or `{ kind = "zaber", serial = "/dev/ttyUSB0" }`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuideSpec {
    /// driver: `zaber`
    pub kind: Spanned<String>,
    /// raw-ASCII TCP port `host:port` (Zaber: 55550)
    pub tcp: Option<Spanned<String>>,
    /// serial port path
    pub serial: Option<Spanned<String>>,
    /// serial baud rate (default 115200)
    pub baud: Option<Spanned<u32>>,
    /// device address in the daisy chain (default 1)
    pub device: Option<Spanned<u8>>,
    /// axis number (default 1)
    pub axis: Option<Spanned<u8>>,
    /// lead of the screw [mm per revolution] for the mm ↔ microstep conversion (default: the
    /// driver's)
    pub lead_mm: Option<Spanned<f64>>,
    /// timeout of every reply \[ms\] (default 1000)
    pub io_timeout_ms: Option<Spanned<u64>>,
    /// TCP connect timeout \[ms\] (default 5000)
    pub connect_timeout_ms: Option<Spanned<u64>>,
}

/// `{ kind = "sylvac", tcp = "…" }` or `{ kind = "sylvac", serial = "/dev/ttyUSB1" }`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaugeSpec {
    /// driver: `sylvac`
    pub kind: Spanned<String>,
    /// TCP `host:port` (a serial-to-TCP bridge or the simulator)
    pub tcp: Option<Spanned<String>>,
    /// serial port path (4800 7E2, fixed by the driver)
    pub serial: Option<Spanned<String>>,
    /// timeout of every query \[ms\] (default 500)
    pub io_timeout_ms: Option<Spanned<u64>>,
    /// TCP connect timeout \[ms\] (default 2000)
    pub connect_timeout_ms: Option<Spanned<u64>>,
}

/// `tracker = { kind = "sim-cell" | "command" | "console", … }` (optional): the laser tracker
/// of the validation campaign (`vatcal_drivers_tracker`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerSpec {
    /// `sim-cell` (the tracker line protocol over TCP: `vatcal sim-cell`'s tracker or a bridge
    /// to a real one), `command` (a program run for every point) or `console` (the operator
    /// types each reading)
    pub kind: Spanned<String>,
    /// `sim-cell`: TCP `host:port`
    pub tcp: Option<Spanned<String>>,
    /// `command`: the program and its arguments; it prints `x y z` in mm
    pub command: Option<Spanned<Vec<String>>>,
    /// timeout of one measurement `ms` (default: `sim-cell` 10000, `command` 30000; a
    /// `console` tracker waits for the operator)
    pub io_timeout_ms: Option<Spanned<u64>>,
    /// `sim-cell`: TCP connect timeout `ms` (default 5000)
    pub connect_timeout_ms: Option<Spanned<u64>>,
    /// the frame of the readings: `tracker` (default: the instrument's own frame, registered to
    /// the tank by the validation's registration step) or `tank` (the tracker's software is
    /// registered already; the registration step only checks it)
    pub frame: Option<Spanned<String>>,
}

/// `sim_control = { tcp = "127.0.0.1:55570" }`: the cell-control port of `vatcal sim-cell`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimControlSpec {
    /// TCP `host:port`
    pub tcp: Spanned<String>,
    /// timeout of every answer \[ms\] (default 5000)
    pub io_timeout_ms: Option<Spanned<u64>>,
}

/// `thermometer = { kind = "sim-cell" | "file" | "command", … }` (optional): the cell
/// temperature recorded as `temperature_c` beside every measurement (see
/// [`crate::thermometer`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermometerSpec {
    /// `sim-cell` (`TEMP?` on the `sim_control` port), `file` or `command`
    pub kind: Spanned<String>,
    /// `file`: the file whose first line is the reading
    pub path: Option<Spanned<String>>,
    /// `command`: the program and its arguments; its first output line is the reading
    pub command: Option<Spanned<Vec<String>>>,
    /// reading × scale = °C (default 1; 0.001 for a file in m°C)
    pub scale: Option<Spanned<f64>>,
    /// `command`: longest run \[ms\] (default 5000); `sim-cell`: answer timeout (default the
    /// `sim_control` one)
    pub io_timeout_ms: Option<Spanned<u64>>,
}

/// `probe = { range_mm = 6.0 }` (optional): the TriCal built from the three gauges.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// each gauge reading must stay within ±range \[mm\] (default 6)
    pub range_mm: Option<Spanned<f64>>,
}

/// `[noise]` (optional): the measuring instruments' noise, σ per axis of one probe row and
/// of one tracker row [mm]. `vatcal campaign` records it in the measurements CSV
/// (`# vatcal-noise:` line, `docs/formats.md`), where `vatcal discover` finds it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseSpec {
    /// σ per axis of a probe row [mm] (robot and guide repeatability, gauge error)
    pub probe_sigma_mm: Option<Spanned<f64>>,
    /// σ per axis of a tracker row [mm]
    pub tracker_sigma_mm: Option<Spanned<f64>>,
}

/// A parsed and validated devices file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DevicesFile {
    /// the robot arm
    pub arm: ArmSpec,
    /// the linear guide (only for a cell whose chain has one: joint 1 prismatic, followed by
    /// the arm)
    pub guide: Option<GuideSpec>,
    /// the three TriCal gauges, gauge 1 first
    pub gauges: Vec<GaugeSpec>,
    /// a laser tracker (validation only)
    pub tracker: Option<TrackerSpec>,
    /// the cell-control port of a simulated cell (`--operator auto`)
    pub sim_control: Option<SimControlSpec>,
    /// the probe
    pub probe: Option<ProbeSpec>,
    /// a thermometer (optional)
    pub thermometer: Option<ThermometerSpec>,
    /// the instruments' noise (optional)
    pub noise: Option<NoiseSpec>,
    #[serde(skip)]
    source: PathBuf,
}

/// The connected devices, as trait objects.
pub struct ConnectedDevices {
    /// the robot arm
    pub arm: Box<dyn RobotArm>,
    /// the linear guide, if the file names one
    pub guide: Option<Box<dyn LinearAxis>>,
    /// the three gauges, gauge 1 first
    pub gauges: [Box<dyn Gauge>; 3],
    /// the tracker, if any
    pub tracker: Option<Box<dyn PositionTracker>>,
    /// the simulator's cell-control connection, if the file names one
    pub sim_control: Option<SimControl>,
    /// the thermometer, if the file names one
    pub thermometer: Option<Box<dyn Thermometer>>,
    /// one line per device: role, driver, link and what it reported at connection
    pub found: Vec<String>,
}

impl std::fmt::Debug for ConnectedDevices {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ConnectedDevices").field("found", &self.found).finish_non_exhaustive()
    }
}

/// Checks a `host:port` address without resolving it.
fn check_address(text: &str) -> Result<(), String> {
    let Some((host, port)) = text.rsplit_once(':') else {
        return Err(format!("`{text}` is not `host:port`"));
    };
    if host.is_empty() || host.contains(char::is_whitespace) {
        return Err(format!("`{text}`: the host is empty or contains spaces"));
    }
    match port.parse::<u16>() {
        Ok(p) if p > 0 => Ok(()),
        _ => Err(format!("`{text}`: the port must be a number in 1..=65535")),
    }
}

fn ms(v: &Option<Spanned<u64>>, default: Duration) -> Duration {
    v.as_ref().map_or(default, |v| Duration::from_millis(*v.get_ref()))
}

impl DevicesFile {
    /// Reads and validates a devices file.
    ///
    /// # Examples
    /// ```
    /// use vatcal_devices::DevicesFile;
    ///
    /// let file = DevicesFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/devices-example.toml"))?;
    /// assert_eq!(file.source().file_name().and_then(|n| n.to_str()), Some("devices-example.toml"));
    /// # Ok::<(), vatcal_devices::DevicesError>(())
    /// ```
    ///
    /// # Errors
    /// As [`DevicesFile::parse`], or the file cannot be read.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DevicesError> {
        let path = path.as_ref();
        let text =
            std::fs::read_to_string(path).map_err(|cause| DevicesError::Read { path: path.into(), cause })?;
        Self::parse(&text, path)
    }

    /// Parses and validates the text of a devices file (`source` names it in errors).
    ///
    /// # Examples
    /// A file without a guide and gauges is refused before anything connects:
    /// ```
    /// use vatcal_devices::DevicesFile;
    ///
    /// let e = DevicesFile::parse("arm = { kind = \"meca500\", address = \"192.168.0.100:10000\" }\n", "typo.toml")
    ///     .expect_err("no guide, no gauges");
    /// assert!(e.to_string().contains("typo.toml"), "{e}");
    /// ```
    ///
    /// # Errors
    /// [`DevicesError::Parse`] for invalid TOML, unknown keys, missing devices or wrong types;
    /// [`DevicesError::Field`] for an unknown `kind`, a bad address, not exactly three gauges,
    /// both or neither of `tcp`/`serial`, a serial link without the `serial` feature, a zero
    /// timeout, or a tracker entry of an unknown kind or without what its kind needs.
    pub fn parse(text: &str, source: impl AsRef<Path>) -> Result<Self, DevicesError> {
        let source = source.as_ref();
        let mut file: Self = toml::from_str(text).map_err(|e| DevicesError::Parse {
            path: source.into(),
            message: e.to_string().trim_end().replace('\n', " ").replace("  ", " "),
        })?;
        file.source = source.into();
        file.validate(text)?;
        Ok(file)
    }

    /// The file this was read from.
    pub fn source(&self) -> &Path {
        &self.source
    }

    fn field_error(
        &self,
        text: &str,
        span: std::ops::Range<usize>,
        field: &str,
        reason: String,
    ) -> DevicesError {
        let line = text.get(..span.start).map_or(0, |t| t.matches('\n').count() + 1);
        DevicesError::Field { path: self.source.clone(), line, field: field.into(), reason }
    }

    fn validate(&self, text: &str) -> Result<(), DevicesError> {
        let err = |span: std::ops::Range<usize>, field: &str, reason: String| {
            self.field_error(text, span, field, reason)
        };
        let kind = |k: &Spanned<String>, field: &str, expected: &str| {
            if k.get_ref() == expected {
                Ok(())
            } else {
                Err(err(
                    k.span(),
                    &format!("{field}.kind"),
                    format!("unknown kind `{}` (supported: `{expected}`)", k.get_ref()),
                ))
            }
        };
        let address = |a: &Spanned<String>, field: &str| {
            check_address(a.get_ref()).map_err(|reason| err(a.span(), field, reason))
        };
        let timeout = |t: &Option<Spanned<u64>>, field: &str| match t {
            Some(t) if *t.get_ref() == 0 || *t.get_ref() > 3_600_000 => {
                Err(err(t.span(), field, format!("{} ms is not in 1..=3600000", t.get_ref())))
            }
            _ => Ok(()),
        };
        let a = &self.arm;
        kind(&a.kind, "arm", "meca500")?;
        address(&a.address, "arm.address")?;
        if let Some(m) = &a.monitoring {
            address(m, "arm.monitoring")?;
        }
        timeout(&a.io_timeout_ms, "arm.io_timeout_ms")?;
        timeout(&a.connect_timeout_ms, "arm.connect_timeout_ms")?;

        if let Some(g) = &self.guide {
            kind(&g.kind, "guide", "zaber")?;
            self.check_link(text, g.tcp.as_ref(), g.serial.as_ref(), "guide", g.kind.span())?;
            timeout(&g.io_timeout_ms, "guide.io_timeout_ms")?;
            timeout(&g.connect_timeout_ms, "guide.connect_timeout_ms")?;
            if let Some(l) = &g.lead_mm
                && !(l.get_ref().is_finite() && *l.get_ref() > 0.0)
            {
                return Err(err(l.span(), "guide.lead_mm", format!("{} must be > 0", l.get_ref())));
            }
            for (name, v) in [("guide.device", &g.device), ("guide.axis", &g.axis)] {
                if let Some(v) = v
                    && *v.get_ref() == 0
                {
                    return Err(err(v.span(), name, "must be at least 1".into()));
                }
            }
        }

        if self.gauges.len() != 3 {
            return Err(DevicesError::Field {
                path: self.source.clone(),
                line: 0,
                field: "gauges".into(),
                reason: format!("the TriCal needs exactly 3 gauges, the file lists {}", self.gauges.len()),
            });
        }
        for (i, s) in self.gauges.iter().enumerate() {
            let field = format!("gauges[{i}]");
            kind(&s.kind, &field, "sylvac")?;
            self.check_link(text, s.tcp.as_ref(), s.serial.as_ref(), &field, s.kind.span())?;
            timeout(&s.io_timeout_ms, &format!("{field}.io_timeout_ms"))?;
            timeout(&s.connect_timeout_ms, &format!("{field}.connect_timeout_ms"))?;
        }
        if let Some(t) = &self.tracker {
            self.check_tracker(text, t)?;
            timeout(&t.io_timeout_ms, "tracker.io_timeout_ms")?;
            timeout(&t.connect_timeout_ms, "tracker.connect_timeout_ms")?;
        }
        if let Some(c) = &self.sim_control {
            address(&c.tcp, "sim_control.tcp")?;
            timeout(&c.io_timeout_ms, "sim_control.io_timeout_ms")?;
        }
        if let Some(t) = &self.thermometer {
            self.check_thermometer(text, t)?;
        }
        if let Some(p) = &self.probe
            && let Some(r) = &p.range_mm
            && !(r.get_ref().is_finite() && *r.get_ref() > 0.0)
        {
            return Err(err(r.span(), "probe.range_mm", format!("{} must be > 0", r.get_ref())));
        }
        if let Some(n) = &self.noise {
            for (v, field) in
                [(&n.probe_sigma_mm, "noise.probe_sigma_mm"), (&n.tracker_sigma_mm, "noise.tracker_sigma_mm")]
            {
                if let Some(v) = v
                    && !(v.get_ref().is_finite() && *v.get_ref() > 0.0)
                {
                    return Err(err(
                        v.span(),
                        field,
                        format!("{} must be a positive number of mm", v.get_ref()),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The instruments' noise of the `[noise]` table: (probe σ, tracker σ) per axis \[mm\].
    pub fn noise_sigmas_mm(&self) -> (Option<f64>, Option<f64>) {
        let get = |v: &Option<Spanned<f64>>| v.as_ref().map(|s| *s.get_ref());
        self.noise.as_ref().map_or((None, None), |n| (get(&n.probe_sigma_mm), get(&n.tracker_sigma_mm)))
    }

    fn check_tracker(&self, text: &str, t: &TrackerSpec) -> Result<(), DevicesError> {
        let err = |span: std::ops::Range<usize>, field: &str, reason: String| {
            self.field_error(text, span, field, reason)
        };
        let kind = t.kind.get_ref().as_str();
        let (needs_tcp, needs_command) = match kind {
            "sim-cell" => (true, false),
            "command" => (false, true),
            "console" => (false, false),
            other => {
                return Err(err(
                    t.kind.span(),
                    "tracker.kind",
                    format!("unknown kind `{other}` (supported: `sim-cell`, `command`, `console`)"),
                ));
            }
        };
        match (&t.tcp, needs_tcp) {
            (None, true) => {
                return Err(err(
                    t.kind.span(),
                    "tracker.tcp",
                    "a `sim-cell` tracker needs `tcp = \"host:port\"` (vatcal sim-cell: port 55580)".into(),
                ));
            }
            (Some(a), true) => check_address(a.get_ref()).map_err(|r| err(a.span(), "tracker.tcp", r))?,
            (Some(a), false) => {
                return Err(err(a.span(), "tracker.tcp", format!("not used by a `{kind}` tracker")));
            }
            (None, false) => {}
        }
        match (&t.command, needs_command) {
            (None, true) => {
                return Err(err(
                    t.kind.span(),
                    "tracker.command",
                    "a `command` tracker needs `command = [\"program\", \"arg\", …]`".into(),
                ));
            }
            (Some(c), true) if c.get_ref().first().is_none_or(|p| p.trim().is_empty()) => {
                return Err(err(c.span(), "tracker.command", "names no program".into()));
            }
            (Some(c), false) => {
                return Err(err(c.span(), "tracker.command", format!("not used by a `{kind}` tracker")));
            }
            _ => {}
        }
        if let Some(c) = &t.connect_timeout_ms
            && !needs_tcp
        {
            return Err(err(
                c.span(),
                "tracker.connect_timeout_ms",
                format!("not used by a `{kind}` tracker"),
            ));
        }
        if kind == "console"
            && let Some(c) = &t.io_timeout_ms
        {
            return Err(err(
                c.span(),
                "tracker.io_timeout_ms",
                "not used by a `console` tracker (it waits for the operator)".into(),
            ));
        }
        match &t.frame {
            Some(f) if !matches!(f.get_ref().as_str(), "tracker" | "tank") => Err(err(
                f.span(),
                "tracker.frame",
                format!("`{}`: the readings' frame is `tracker` (default) or `tank`", f.get_ref()),
            )),
            _ => Ok(()),
        }
    }

    /// True when the file's tracker reports in the tank frame already (`frame = "tank"`);
    /// `false` for the default `tracker` frame (the registration step finds `tank ← tracker`)
    /// or without a tracker.
    pub fn tracker_reports_in_tank_frame(&self) -> bool {
        self.tracker.as_ref().and_then(|t| t.frame.as_ref()).is_some_and(|f| f.get_ref() == "tank")
    }

    /// Connects the tracker of the file, if any (nothing is measured: a `command` tracker runs
    /// its program at the first point, a `console` tracker asks at the first point).
    fn connect_tracker(
        &self,
        found: &mut Vec<String>,
    ) -> Result<Option<Box<dyn PositionTracker>>, DevicesError> {
        let Some(t) = &self.tracker else { return Ok(None) };
        let frame = if self.tracker_reports_in_tank_frame() { "tank frame" } else { "tracker frame" };
        match t.kind.get_ref().as_str() {
            "sim-cell" => {
                let address = t.tcp.as_ref().map(|a| a.get_ref().clone()).unwrap_or_default();
                let d = TrackerConfig::default();
                let config = TrackerConfig {
                    io_timeout: ms(&t.io_timeout_ms, d.io_timeout),
                    connect_timeout: ms(&t.connect_timeout_ms, d.connect_timeout),
                    ..d
                };
                let tracker = LineTracker::connect_tcp(address.as_str(), config).map_err(|e| {
                    DevicesError::Connect {
                        role: "tracker".into(),
                        what: format!("sim-cell tracker at {address}"),
                        cause: e.into_hw("tracker"),
                    }
                })?;
                found.push(format!("tracker: sim-cell at {address}: `{}` ({frame})", tracker.identity()));
                Ok(Some(Box::new(tracker)))
            }
            "command" => {
                let command = t.command.as_ref().map(|c| c.get_ref().clone()).unwrap_or_default();
                let (program, args) = command
                    .split_first()
                    .map_or((String::new(), Vec::new()), |(p, a)| (p.clone(), a.to_vec()));
                let mut config = CommandTrackerConfig::new(program, args);
                config.timeout = ms(&t.io_timeout_ms, config.timeout);
                found.push(format!("tracker: command {} ({frame})", command.join(" ")));
                Ok(Some(Box::new(CommandTracker::new(config))))
            }
            _ => {
                found.push(format!("tracker: console (the operator types each reading; {frame})"));
                Ok(Some(Box::new(ConsoleTracker::stdio())))
            }
        }
    }

    fn check_thermometer(&self, text: &str, t: &ThermometerSpec) -> Result<(), DevicesError> {
        let err = |span: std::ops::Range<usize>, field: &str, reason: String| {
            self.field_error(text, span, field, reason)
        };
        let kind = t.kind.get_ref().as_str();
        let (needs_path, needs_command) = match kind {
            "sim-cell" => {
                if self.sim_control.is_none() {
                    return Err(err(
                        t.kind.span(),
                        "thermometer.kind",
                        "`sim-cell` reads `TEMP?` on the simulator's cell-control port: add \
                         `sim_control = { tcp = \"host:port\" }`"
                            .into(),
                    ));
                }
                (false, false)
            }
            "file" => (true, false),
            "command" => (false, true),
            other => {
                return Err(err(
                    t.kind.span(),
                    "thermometer.kind",
                    format!("unknown kind `{other}` (supported: `sim-cell`, `file`, `command`)"),
                ));
            }
        };
        match (&t.path, needs_path) {
            (None, true) => {
                return Err(err(
                    t.kind.span(),
                    "thermometer.path",
                    "a `file` thermometer needs `path`".into(),
                ));
            }
            (Some(p), false) => {
                return Err(err(p.span(), "thermometer.path", format!("not used by a `{kind}` thermometer")));
            }
            (Some(p), true) if p.get_ref().trim().is_empty() => {
                return Err(err(p.span(), "thermometer.path", "is empty".into()));
            }
            _ => {}
        }
        match (&t.command, needs_command) {
            (None, true) => {
                return Err(err(
                    t.kind.span(),
                    "thermometer.command",
                    "a `command` thermometer needs `command = [\"program\", \"arg\", …]`".into(),
                ));
            }
            (Some(c), false) => {
                return Err(err(
                    c.span(),
                    "thermometer.command",
                    format!("not used by a `{kind}` thermometer"),
                ));
            }
            (Some(c), true) if c.get_ref().first().is_none_or(|p| p.trim().is_empty()) => {
                return Err(err(c.span(), "thermometer.command", "names no program".into()));
            }
            _ => {}
        }
        if let Some(sc) = &t.scale
            && !(sc.get_ref().is_finite() && *sc.get_ref() != 0.0)
        {
            return Err(err(
                sc.span(),
                "thermometer.scale",
                format!("{} must be finite and non-zero", sc.get_ref()),
            ));
        }
        match &t.io_timeout_ms {
            Some(v) if *v.get_ref() == 0 || *v.get_ref() > 3_600_000 => Err(err(
                v.span(),
                "thermometer.io_timeout_ms",
                format!("{} ms is not in 1..=3600000", v.get_ref()),
            )),
            _ => Ok(()),
        }
    }

    /// Connects the thermometer of the file (after `sim_control`, which `sim-cell` uses) and
    /// takes one reading, so a wrong sensor is found before anything moves.
    fn connect_thermometer(
        &self,
        sim_control: Option<&SimControl>,
        found: &mut Vec<String>,
    ) -> Result<Option<Box<dyn Thermometer>>, DevicesError> {
        let Some(t) = &self.thermometer else { return Ok(None) };
        let scale = t.scale.as_ref().map_or(1.0, |s| *s.get_ref());
        let (mut thermometer, what): (Box<dyn Thermometer>, String) = match t.kind.get_ref().as_str() {
            "sim-cell" => {
                let control = sim_control.ok_or_else(|| DevicesError::Field {
                    path: self.source.clone(),
                    line: 0,
                    field: "thermometer.kind".into(),
                    reason: "`sim-cell` needs `sim_control`".into(),
                })?;
                let control = control.reconnect().map_err(|cause| DevicesError::Connect {
                    role: "thermometer".into(),
                    what: "sim-cell".into(),
                    cause,
                })?;
                (Box::new(SimCellThermometer::new(control)), "sim-cell TEMP?".into())
            }
            "file" => {
                let path = t.path.as_ref().map(|p| p.get_ref().clone()).unwrap_or_default();
                (Box::new(FileThermometer::new(&path, scale)), format!("file {path}"))
            }
            _ => {
                let command = t.command.as_ref().map(|c| c.get_ref().clone()).unwrap_or_default();
                let timeout = ms(&t.io_timeout_ms, Duration::from_secs(5));
                let (program, args) = command
                    .split_first()
                    .map_or((String::new(), Vec::new()), |(p, a)| (p.clone(), a.to_vec()));
                (
                    Box::new(CommandThermometer::new(program, args, scale, timeout)),
                    format!("command {}", command.join(" ")),
                )
            }
        };
        let first = thermometer.read_c().map_err(|cause| DevicesError::Connect {
            role: "thermometer".into(),
            what: what.clone(),
            cause,
        })?;
        found.push(format!("thermometer: {what}: {first:.2} °C"));
        Ok(Some(thermometer))
    }

    fn check_link(
        &self,
        text: &str,
        tcp: Option<&Spanned<String>>,
        serial: Option<&Spanned<String>>,
        field: &str,
        span: std::ops::Range<usize>,
    ) -> Result<(), DevicesError> {
        match (tcp, serial) {
            (Some(t), None) => check_address(t.get_ref())
                .map_err(|reason| self.field_error(text, t.span(), &format!("{field}.tcp"), reason)),
            (None, Some(s)) => {
                if s.get_ref().trim().is_empty() {
                    return Err(self.field_error(
                        text,
                        s.span(),
                        &format!("{field}.serial"),
                        "empty path".into(),
                    ));
                }
                if cfg!(feature = "serial") {
                    Ok(())
                } else {
                    Err(self.field_error(
                        text,
                        s.span(),
                        &format!("{field}.serial"),
                        "this vatcal was built without the `serial` feature (use a TCP bridge or rebuild with --features serial)".into(),
                    ))
                }
            }
            (Some(_), Some(s)) => {
                Err(self.field_error(text, s.span(), field, "give either `tcp` or `serial`, not both".into()))
            }
            (None, None) => Err(self.field_error(
                text,
                span,
                field,
                "needs `tcp = \"host:port\"` or `serial = \"/dev/…\"`".into(),
            )),
        }
    }

    /// `Ok` when the file fits a cell whose joints split as `layout` (from the cell model's
    /// joint kinds): a `guide` entry exactly when the chain has a guide. `chain` describes the
    /// chain in the message (e.g. `Model::describe_chain`).
    ///
    /// # Errors
    /// [`DevicesError::Cell`] naming the file and what does not fit.
    pub fn check_cell(&self, layout: &JointLayout, chain: &str) -> Result<(), DevicesError> {
        let reason = match (layout.has_guide(), self.guide.is_some()) {
            (true, false) => format!(
                "the cell's model ({chain}) has a guide (joint 1, prismatic) but the devices file has no `guide` entry"
            ),
            (false, true) => format!(
                "the devices file has a `guide` entry but the cell's model ({chain}) has no guide: remove it"
            ),
            _ => return Ok(()),
        };
        Err(DevicesError::Cell { path: self.source.clone(), reason })
    }

    /// How the guide is reached (`None` without a guide).
    pub fn guide_link(&self) -> Option<Link> {
        let g = self.guide.as_ref()?;
        Some(link(g.tcp.as_ref(), g.serial.as_ref(), g.baud.as_ref().map_or(115_200, |b| *b.get_ref())))
    }

    /// How gauge `i` (0-based) is reached.
    pub fn gauge_link(&self, i: usize) -> Option<Link> {
        self.gauges.get(i).map(|g| link(g.tcp.as_ref(), g.serial.as_ref(), 4800))
    }

    /// The TriCal configuration: `placements` (from the nominal cell) and the range of the
    /// `probe` entry.
    pub fn probe_config(&self, placements: Vec<ProbePlacement>) -> TriCalConfig {
        let mut c = TriCalConfig::new(placements);
        if let Some(r) = self.probe.as_ref().and_then(|p| p.range_mm.as_ref()) {
            c.range_mm = *r.get_ref();
        }
        c
    }

    /// The driver configuration of the arm.
    pub fn arm_config(&self) -> Meca500Config {
        let d = Meca500Config::default();
        Meca500Config {
            io_timeout: ms(&self.arm.io_timeout_ms, d.io_timeout),
            connect_timeout: ms(&self.arm.connect_timeout_ms, d.connect_timeout),
            ..d
        }
    }

    /// The driver configuration of the guide (the defaults without a `guide` entry).
    pub fn guide_config(&self) -> ZaberConfig {
        let d = ZaberConfig::default();
        let Some(g) = &self.guide else { return d };
        ZaberConfig {
            address: g.device.as_ref().map_or(d.address, |v| *v.get_ref()),
            axis: g.axis.as_ref().map_or(d.axis, |v| *v.get_ref()),
            io_timeout: ms(&g.io_timeout_ms, d.io_timeout),
            connect_timeout: ms(&g.connect_timeout_ms, d.connect_timeout),
            microstep: g
                .lead_mm
                .as_ref()
                .map_or(d.microstep, |l| MicrostepSize::FromLead { lead_mm: *l.get_ref() }),
            ..d
        }
    }

    /// The driver configuration of gauge `i` (0-based; named `gauge i+1`).
    pub fn gauge_config(&self, i: usize) -> SylvacConfig {
        let d = SylvacConfig::default();
        let g = self.gauges.get(i);
        SylvacConfig {
            name: format!("gauge {}", i + 1),
            io_timeout: ms(&g.and_then(|g| g.io_timeout_ms.clone()), d.io_timeout),
            connect_timeout: ms(&g.and_then(|g| g.connect_timeout_ms.clone()), d.connect_timeout),
            ..d
        }
    }

    /// Connects every device with its driver (arm, guide, gauges 1–3, then the simulator's
    /// control port if named). Nothing moves: the drivers only identify the devices.
    ///
    /// # Examples
    /// The three protocol simulators stand in for the devices here (a real cell: the file's
    /// addresses):
    /// ```
    /// use vatcal_devices::DevicesFile;
    /// use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig as MecaSim};
    /// use vatcal_drivers_sylvac::sim::{SimConfig as GaugeSim, SylvacSim};
    /// use vatcal_drivers_zaber::sim::{SimConfig as ZaberSimConfig, ZaberSim};
    /// use vatcal_hardware_traits::Gauge;
    ///
    /// let arm = Meca500Sim::start(MecaSim::fast(20.0))?;
    /// let guide = ZaberSim::start(ZaberSimConfig::fast(50.0))?;
    /// let g = [SylvacSim::start(GaugeSim::default())?, SylvacSim::start(GaugeSim::default())?, SylvacSim::start(GaugeSim::default())?];
    /// let text = format!(
    ///     "arm = {{ kind = \"meca500\", address = \"{}\" }}\nguide = {{ kind = \"zaber\", tcp = \"{}\" }}\n\
    ///      gauges = [{{ kind = \"sylvac\", tcp = \"{}\" }}, {{ kind = \"sylvac\", tcp = \"{}\" }}, {{ kind = \"sylvac\", tcp = \"{}\" }}]\n",
    ///     arm.control_addr(), guide.addr(), g[0].addr(), g[1].addr(), g[2].addr()
    /// );
    /// let mut devices = DevicesFile::parse(&text, "simulators.toml")?.connect()?;
    /// g[2].set_plunger_mm(2.5);
    /// assert_eq!(devices.gauges[2].read_mm()?, 2.5);
    /// assert_eq!(devices.found.len(), 5); // arm, guide, three gauges
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// The first device that cannot be connected ([`DevicesError::Connect`] names it).
    pub fn connect(&self) -> Result<ConnectedDevices, DevicesError> {
        let mut found = Vec::new();
        let address = self.arm.address.get_ref().clone();
        let arm =
            Meca500::connect_tcp(address.as_str(), self.arm_config()).map_err(|e| DevicesError::Connect {
                role: "arm".into(),
                what: format!("meca500 at {address}"),
                cause: e.into_hw("meca500"),
            })?;
        let b = arm.banner();
        found.push(format!(
            "arm: meca500 at {address}: {} firmware {}.{}.{}{}",
            b.model,
            b.version.0,
            b.version.1,
            b.version.2,
            if b.virtual_robot { " (virtual robot)" } else { "" }
        ));

        let guide = match self.guide_link() {
            None => None,
            Some(guide_link) => {
                let (guide, info) =
                    connect_guide(&guide_link, self.guide_config()).map_err(|e| DevicesError::Connect {
                        role: "guide".into(),
                        what: format!("zaber over {guide_link}"),
                        cause: e.into_hw("zaber guide"),
                    })?;
                let travel = info
                    .travel_mm()
                    .map_or("travel unknown".to_string(), |(lo, hi)| format!("travel {lo:.1}..{hi:.1} mm"));
                found.push(format!("guide: zaber over {guide_link}: {travel}"));
                Some(guide)
            }
        };

        let mut gauges: Vec<Box<dyn Gauge>> = Vec::with_capacity(3);
        for i in 0..3 {
            let Some(link) = self.gauge_link(i) else { break };
            let config = self.gauge_config(i);
            let name = config.name.clone();
            let (gauge, id) = connect_gauge(&link, config).map_err(|e| DevicesError::Connect {
                role: name.clone(),
                what: format!("sylvac over {link}"),
                cause: e.into_hw(&name),
            })?;
            found.push(format!("{name}: sylvac over {link}: id `{id}`"));
            gauges.push(gauge);
        }
        let gauges: [Box<dyn Gauge>; 3] = gauges.try_into().map_err(|_| DevicesError::Field {
            path: self.source.clone(),
            line: 0,
            field: "gauges".into(),
            reason: "the TriCal needs exactly 3 gauges".into(),
        })?;

        let sim_control = match &self.sim_control {
            None => None,
            Some(c) => {
                let io = ms(&c.io_timeout_ms, Duration::from_secs(5));
                let address = c.tcp.get_ref();
                let connect_err = |cause| DevicesError::Connect {
                    role: "sim_control".into(),
                    what: format!("tcp {address}"),
                    cause,
                };
                let mut control =
                    SimControl::connect(address, Duration::from_secs(5), io).map_err(connect_err)?;
                let placement = control.placement().map_err(connect_err)?;
                let at = placement.map_or("not placed yet".to_string(), |p| format!("at placement {p}"));
                found.push(format!("sim_control: tcp {address}: probe plate {at}"));
                Some(control)
            }
        };
        let thermometer = self.connect_thermometer(sim_control.as_ref(), &mut found)?;
        let tracker = self.connect_tracker(&mut found)?;
        Ok(ConnectedDevices { arm: Box::new(arm), guide, gauges, tracker, sim_control, thermometer, found })
    }
}

fn link(tcp: Option<&Spanned<String>>, serial: Option<&Spanned<String>>, baud: u32) -> Link {
    match (tcp, serial) {
        (_, Some(s)) => Link::Serial { path: s.get_ref().clone(), baud },
        (Some(t), None) => Link::Tcp(t.get_ref().clone()),
        (None, None) => Link::Tcp(String::new()),
    }
}

/// A connected guide and what it reported at connection.
type GuideAndInfo = (Box<dyn LinearAxis>, AxisInfo);

fn connect_guide(link: &Link, config: ZaberConfig) -> Result<GuideAndInfo, vatcal_drivers_zaber::ZaberError> {
    match link {
        Link::Tcp(a) => {
            let g = ZaberAxis::connect_tcp(a.as_str(), config)?;
            let info = *g.info();
            Ok((Box::new(g), info))
        }
        #[cfg(feature = "serial")]
        Link::Serial { path, baud } => {
            let g = ZaberAxis::open_serial(path, *baud, config)?;
            let info = *g.info();
            Ok((Box::new(g), info))
        }
        #[cfg(not(feature = "serial"))]
        Link::Serial { path, .. } => Err(vatcal_drivers_zaber::ZaberError::from(std::io::Error::other(
            format!("{path}: built without the `serial` feature"),
        ))),
    }
}

fn connect_gauge(
    link: &Link,
    config: SylvacConfig,
) -> Result<(Box<dyn Gauge>, String), vatcal_drivers_sylvac::SylvacError> {
    match link {
        Link::Tcp(a) => {
            let g = SylvacGauge::connect_tcp(a.as_str(), config)?;
            let id = g.id().to_string();
            Ok((Box::new(g), id))
        }
        #[cfg(feature = "serial")]
        Link::Serial { path, .. } => {
            let g = SylvacGauge::open_serial(path, config)?;
            let id = g.id().to_string();
            Ok((Box::new(g), id))
        }
        #[cfg(not(feature = "serial"))]
        Link::Serial { path, .. } => Err(vatcal_drivers_sylvac::SylvacError::from(std::io::Error::other(
            format!("{path}: built without the `serial` feature"),
        ))),
    }
}
