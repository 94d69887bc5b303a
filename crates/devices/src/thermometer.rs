//! Thermometers for real and simulated cells (`thermometer = { … }` in the devices file):
//!
//! | kind | reads |
//! |---|---|
//! | `sim-cell` | `TEMP?` on the cell-control port of `vatcal sim-cell` ([`SimControl::temperature_c`]) |
//! | `file` | the first line of a text file a sensor daemon keeps up to date (`23.41`, `23.41 C`), times `scale` (e.g. `0.001` for a Linux 1-wire `temperature` file in m°C) |
//! | `command` | the first line a program prints, times `scale` (e.g. a vendor tool that queries a PT100 logger) |
//!
//! Every reading is checked with [`parse_temperature_c`] (a number, within the plausible
//! range), so a missing, stale-empty or garbled sensor output is an error, never a made-up
//! temperature.

use std::path::PathBuf;
use std::time::Duration;

use vatcal_hardware_traits::{Error, ErrorKind, Result, Thermometer, parse_temperature_c};

use crate::sim_control::SimControl;

/// The temperature of a simulated cell, read with `TEMP?` over its cell-control port.
#[derive(Debug)]
pub struct SimCellThermometer {
    control: SimControl,
}

impl SimCellThermometer {
    /// A thermometer on `control` (use a connection of its own, e.g. [`SimControl::reconnect`]).
    pub fn new(control: SimControl) -> Self {
        Self { control }
    }
}

impl Thermometer for SimCellThermometer {
    fn read_c(&mut self) -> Result<f64> {
        self.control.temperature_c()
    }
}

/// Scales the first line of `text` and checks it is a plausible temperature.
fn scaled(device: &str, text: &str, scale: f64) -> Result<f64> {
    let line = text.lines().map(str::trim).find(|l| !l.is_empty()).unwrap_or("");
    if line.is_empty() {
        return Err(Error::new(ErrorKind::Protocol, device, "empty reading"));
    }
    if scale == 1.0 {
        return parse_temperature_c(device, line);
    }
    let raw: f64 = line
        .parse()
        .map_err(|_| Error::new(ErrorKind::Protocol, device, format!("`{line}` is not a number")))?;
    parse_temperature_c(device, &(raw * scale).to_string())
}

/// A sensor whose current reading is the first line of a file (°C, or raw counts × `scale`).
#[derive(Debug, Clone)]
pub struct FileThermometer {
    path: PathBuf,
    scale: f64,
}

impl FileThermometer {
    /// Reads `path`; each reading is its first non-empty line × `scale` \[°C\].
    pub fn new(path: impl Into<PathBuf>, scale: f64) -> Self {
        Self { path: path.into(), scale }
    }

    fn device(&self) -> String {
        format!("thermometer file {}", self.path.display())
    }
}

impl Thermometer for FileThermometer {
    fn read_c(&mut self) -> Result<f64> {
        let device = self.device();
        let text = std::fs::read_to_string(&self.path).map_err(|e| Error::from_io(device.clone(), e))?;
        scaled(&device, &text, self.scale)
    }
}

/// A sensor read by running a program: its first output line × `scale` \[°C\]. A program that
/// fails, prints nothing or runs longer than the timeout is an error (and is killed).
#[derive(Debug, Clone)]
pub struct CommandThermometer {
    program: String,
    args: Vec<String>,
    scale: f64,
    timeout: Duration,
}

impl CommandThermometer {
    /// Runs `program` with `args`; readings are its first output line × `scale`; a run longer
    /// than `timeout` is a [`ErrorKind::Timeout`].
    pub fn new(program: impl Into<String>, args: Vec<String>, scale: f64, timeout: Duration) -> Self {
        Self { program: program.into(), args, scale, timeout }
    }

    fn device(&self) -> String {
        format!("thermometer command `{}`", self.program)
    }
}

impl Thermometer for CommandThermometer {
    fn read_c(&mut self) -> Result<f64> {
        let device = self.device();
        let output =
            vatcal_hardware_traits::command::run(&device, &self.program, &self.args, &[], self.timeout)?;
        scaled(&device, &output.stdout, self.scale)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_sensor_is_read_scaled_and_checked() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("temperature");
        std::fs::write(&path, "21437\n").expect("write");
        let mut t = FileThermometer::new(&path, 0.001);
        assert!((t.read_c().expect("read") - 21.437).abs() < 1e-12);
        std::fs::write(&path, "22.5 C\n").expect("write");
        assert_eq!(FileThermometer::new(&path, 1.0).read_c().expect("read"), 22.5);
        for (text, kind) in
            [("", ErrorKind::Protocol), ("err", ErrorKind::Protocol), ("850", ErrorKind::OutOfRange)]
        {
            std::fs::write(&path, text).expect("write");
            let e = FileThermometer::new(&path, 1.0).read_c().expect_err(text);
            assert_eq!(e.kind(), kind, "{text}: {e}");
            assert!(e.to_string().contains("temperature"), "names the file: {e}");
        }
        let e = FileThermometer::new(dir.path().join("missing"), 1.0).read_c().expect_err("missing");
        assert!(e.to_string().contains("missing"), "{e}");
    }

    #[test]
    fn a_command_sensor_is_run_and_checked() {
        let sh = |script: &str, timeout_ms: u64| {
            CommandThermometer::new(
                "sh",
                vec!["-c".into(), script.into()],
                1.0,
                Duration::from_millis(timeout_ms),
            )
        };
        assert_eq!(sh("echo 23.25", 5000).read_c().expect("read"), 23.25);
        assert_eq!(
            sh("echo nope; exit 3", 5000).read_c().expect_err("fails").kind(),
            ErrorKind::DeviceFault { code: 3 }
        );
        assert_eq!(sh("echo", 5000).read_c().expect_err("empty").kind(), ErrorKind::Protocol);
        assert!(sh("sleep 5", 100).read_c().expect_err("slow").is_timeout());
        let e = CommandThermometer::new("/nonexistent/sensor", vec![], 1.0, Duration::from_secs(1))
            .read_c()
            .expect_err("no program");
        assert!(e.to_string().contains("/nonexistent/sensor"), "{e}");
    }
}
