//! A tracker reached through an external program (`kind = "command"` in the devices file): the
//! usual way to a vendor SDK or a metrology package. The program is run once per point.
//!
//! **What the program gets.** Its configured arguments, stdin closed, and the environment
//! variables
//!
//! | variable | value |
//! |---|---|
//! | `VATCAL_TRACKER_TARGET` | the target: a TCP id (the SMR in the nest that stands for it), or `0` for the SMR in the probe's trihedral nest (registration) |
//! | `VATCAL_TRACKER_POINT` | 1, 2, 3, … — the number of this request since the driver was created |
//! | `VATCAL_TRACKER_NOMINAL_MM` | where the SMR is expected, `x y z` in mm in the tracker's frame (the beam can be pointed there), or empty when unknown |
//!
//! **What it must print.** One line on stdout: `x y z` in mm (spaces, tabs, commas or
//! semicolons between the numbers; a trailing `mm` is accepted), then exit with status 0. A
//! line `LOS [reason]` says the SMR cannot be seen now.
//!
//! | outcome | [`ErrorKind`] |
//! |---|---|
//! | `LOS …` | `OutOfRange` (line of sight lost) |
//! | anything else that is not `x y z` (or nothing) | `Protocol`, the output quoted |
//! | non-zero exit | `DeviceFault { code: status }`, the end of stderr quoted |
//! | runs longer than the timeout | `Timeout` (the program is killed) |
//! | cannot be started | the I/O error's kind, the program named |

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::command::run;
use vatcal_hardware_traits::{Error, ErrorKind, PositionTracker, Result};

use crate::codec::{clip, format_xyz_mm, parse_xyz_mm};

/// Settings of a [`CommandTracker`].
#[derive(Debug, Clone, PartialEq)]
pub struct CommandTrackerConfig {
    /// the program (a path, or a name looked up in `PATH`)
    pub program: String,
    /// its arguments
    pub args: Vec<String>,
    /// longest run of one measurement (the program is killed after it)
    pub timeout: Duration,
}

impl CommandTrackerConfig {
    /// `program` with `args` and a 30 s timeout.
    pub fn new(program: impl Into<String>, args: Vec<String>) -> Self {
        Self { program: program.into(), args, timeout: Duration::from_secs(30) }
    }
}

/// A tracker that runs a program for every point (see the module docs).
#[derive(Debug, Clone)]
pub struct CommandTracker {
    config: CommandTrackerConfig,
    point: u64,
    label: String,
}

impl CommandTracker {
    /// A tracker running `config.program`; nothing is run until the first measurement.
    pub fn new(config: CommandTrackerConfig) -> Self {
        let label = format!("tracker command `{}`", config.program);
        Self { config, point: 0, label }
    }

    /// The name errors carry: ``tracker command `PROGRAM` ``.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The settings.
    pub fn config(&self) -> &CommandTrackerConfig {
        &self.config
    }
}

/// The reading in a program's first output line, or why there is none.
fn parse_reading(device: &str, target: u32, line: Option<&str>) -> Result<Vector3<f64>> {
    let Some(line) = line else {
        return Err(Error::new(
            ErrorKind::Protocol,
            device,
            format!("target {target}: printed no reading (expected `x y z` in mm)"),
        ));
    };
    let mut words = line.split_whitespace();
    if words.next().is_some_and(|w| w.eq_ignore_ascii_case("LOS")) {
        let why = words.collect::<Vec<_>>().join(" ");
        let why = if why.is_empty() { String::new() } else { format!(": {why}") };
        return Err(Error::new(
            ErrorKind::OutOfRange,
            device,
            format!("target {target}: line of sight lost{}", clip(&why)),
        ));
    }
    parse_xyz_mm(line).map_err(|reason| {
        Error::new(
            ErrorKind::Protocol,
            device,
            format!("target {target}: garbled answer `{}`: {reason}", clip(line)),
        )
    })
}

impl PositionTracker for CommandTracker {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        self.measure_near_mm(target, None)
    }

    fn measure_near_mm(&mut self, target: u32, nominal_mm: Option<&Vector3<f64>>) -> Result<Vector3<f64>> {
        self.point += 1;
        let env = [
            ("VATCAL_TRACKER_TARGET".to_owned(), target.to_string()),
            ("VATCAL_TRACKER_POINT".to_owned(), self.point.to_string()),
            ("VATCAL_TRACKER_NOMINAL_MM".to_owned(), nominal_mm.map(format_xyz_mm).unwrap_or_default()),
        ];
        let c = &self.config;
        let output = run(&self.label, &c.program, &c.args, &env, c.timeout)
            .map_err(|e| e.context(format_args!("target {target}")))?;
        parse_reading(&self.label, target, output.first_line())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_line_of_sight_and_garbage() {
        let p = parse_reading("t", 2, Some("1 2 3")).expect("reading");
        assert_eq!(p, Vector3::new(1.0, 2.0, 3.0));
        let e = parse_reading("t", 2, Some("LOS beam broken")).expect_err("los");
        assert_eq!(e.kind(), ErrorKind::OutOfRange);
        assert!(e.to_string().contains("line of sight lost: beam broken"), "{e}");
        assert_eq!(parse_reading("t", 2, Some("los")).expect_err("los").kind(), ErrorKind::OutOfRange);
        let e = parse_reading("t", 2, Some("hello world")).expect_err("garbage");
        assert_eq!(e.kind(), ErrorKind::Protocol);
        assert!(e.to_string().contains("garbled answer `hello world`"), "{e}");
        assert_eq!(parse_reading("t", 2, None).expect_err("none").kind(), ErrorKind::Protocol);
    }
}
