//! A tracker driven by hand (`kind = "console"` in the devices file): for each point the
//! operator reads the tracker's software and types or pastes the reading.
//!
//! The prompt (on stderr with [`ConsoleTracker::stdio`]) names the target and, when known,
//! where the SMR is expected. The answer is `x y z` in mm (spaces, tabs, commas or
//! semicolons; a pasted spreadsheet row works), `los` when the SMR cannot be seen (the point
//! is then retried or skipped as the campaign's options say), or `abort` (or the end of the
//! input) to stop the campaign safely. Anything else is refused with the reason and asked
//! again.

use std::io::{Stderr, Write};

use nalgebra::Vector3;
use vatcal_hardware_traits::console::{Console, LineSource, SharedStdin};
use vatcal_hardware_traits::{Error, ErrorKind, PROBE_NEST_TARGET, PositionTracker, Result};

use crate::codec::{format_xyz_mm, parse_xyz_mm};

const DEVICE: &str = "console tracker";

/// The operator as a tracker (see the module docs).
#[derive(Debug)]
pub struct ConsoleTracker<R, W> {
    console: Console<R, W>,
}

impl ConsoleTracker<SharedStdin, Stderr> {
    /// Prompts on stderr, readings from stdin (shared with a console operator: each reads
    /// its own lines).
    pub fn stdio() -> Self {
        Self { console: Console::stdio() }
    }
}

impl<R: LineSource, W: Write + Send> ConsoleTracker<R, W> {
    /// A console tracker on any line-based input and output.
    pub fn new(input: R, output: W) -> Self {
        Self { console: Console::new(input, output) }
    }
}

impl<R: LineSource, W: Write + Send> PositionTracker for ConsoleTracker<R, W> {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        self.measure_near_mm(target, None)
    }

    fn measure_near_mm(&mut self, target: u32, nominal_mm: Option<&Vector3<f64>>) -> Result<Vector3<f64>> {
        let what = if target == PROBE_NEST_TARGET {
            "the SMR in the probe's trihedral nest".to_owned()
        } else {
            format!("the SMR of target {target}")
        };
        let near =
            nominal_mm.map(|p| format!(" (expected near {} mm)", format_xyz_mm(p))).unwrap_or_default();
        let prompt = format!(
            "\n>>> Tracker: measure {what}{near}.\n    Type or paste `x y z` in mm, `los` if it cannot be seen, or `abort`:"
        );
        loop {
            let answer = self.console.ask(DEVICE, &format!("measuring {what}"), &prompt)?;
            if answer.eq_ignore_ascii_case("los") {
                return Err(Error::new(
                    ErrorKind::OutOfRange,
                    DEVICE,
                    format!("target {target}: line of sight lost (the operator said so)"),
                ));
            }
            match parse_xyz_mm(&answer) {
                Ok(p) => return Ok(p),
                Err(reason) => {
                    self.console.say(DEVICE, &format!("    not a reading: {reason}; try again"))?
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_readings_re_prompt_los_and_abort() {
        let input = "1 2\n12.5, -3, 400.25\nlos\nnonsense\nabort\n";
        let mut out = Vec::new();
        let mut t = ConsoleTracker::new(input.as_bytes(), &mut out);
        let p = t.measure_near_mm(2, Some(&Vector3::new(12.0, -3.0, 400.0))).expect("second line");
        assert_eq!(p, Vector3::new(12.5, -3.0, 400.25));
        assert_eq!(t.measure_mm(PROBE_NEST_TARGET).expect_err("los").kind(), ErrorKind::OutOfRange);
        assert_eq!(t.measure_mm(1).expect_err("abort").kind(), ErrorKind::Cancelled);
        let text = String::from_utf8(out).expect("utf8");
        assert!(text.contains("expected near 12.000000 -3.000000 400.000000 mm"), "{text}");
        assert!(text.contains("not a reading: `1 2` is not `x y z` (mm): 2 values"), "{text}");
        assert!(text.contains("trihedral nest") && text.contains("`nonsense` is not `x y z`"), "{text}");
    }
}
