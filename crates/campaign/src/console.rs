//! An [`Operator`] for a terminal: prints each instruction and waits for Enter.

use std::io::{Stderr, Write};

use vatcal_hardware_traits::console::{Console, LineSource, SharedStdin};
use vatcal_hardware_traits::{Operator, OperatorInstruction, Result};

/// Prints the instruction to `output` and reads one line from `input`: an empty line (Enter)
/// confirms, `abort` (or end of input) cancels with
/// [`ErrorKind::Cancelled`](vatcal_hardware_traits::ErrorKind::Cancelled).
#[derive(Debug)]
pub struct ConsoleOperator<R, W> {
    console: Console<R, W>,
}

impl ConsoleOperator<SharedStdin, Stderr> {
    /// Instructions on stderr, confirmations from stdin.
    pub fn stdio() -> Self {
        Self { console: Console::stdio() }
    }
}

impl<R: LineSource, W: Write + Send> ConsoleOperator<R, W> {
    /// An operator on any line-based input and output.
    pub fn new(input: R, output: W) -> Self {
        Self { console: Console::new(input, output) }
    }
}

impl<R: LineSource, W: Write + Send> Operator for ConsoleOperator<R, W> {
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()> {
        let prompt = format!("\n>>> {instruction}.\n    Press Enter when done, or type `abort`: ");
        self.console.ask("console operator", &instruction.to_string(), &prompt).map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_hardware_traits::ErrorKind;

    #[test]
    fn enter_confirms_abort_and_eof_cancel() {
        let mut out = Vec::new();
        let mut op = ConsoleOperator::new("\nabort\n".as_bytes(), &mut out);
        op.perform(&OperatorInstruction::PlaceProbe { position: 2 }).expect("enter");
        let e = op.perform(&OperatorInstruction::RemoveMasterBall).expect_err("abort");
        assert_eq!(e.kind(), ErrorKind::Cancelled);
        let e = op.perform(&OperatorInstruction::RemoveMasterBall).expect_err("eof");
        assert_eq!(e.kind(), ErrorKind::Cancelled);
        let text = String::from_utf8(out).expect("utf8");
        assert!(text.contains("place the probe plate at calibration position 2"), "{text}");
    }
}
