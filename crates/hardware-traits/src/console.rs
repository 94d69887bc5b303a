//! A person at a terminal as part of a device: an instruction is printed, the answer is one
//! typed (or pasted) line. Used by the console operator of `vatcal campaign --operator
//! console` and by the console laser tracker (the operator reads the tracker's software and
//! types the coordinates).

use std::io::{BufRead, Stderr, Write};

use crate::error::{Error, ErrorKind, Result};

/// Where typed lines come from: any [`BufRead`], or [`SharedStdin`].
pub trait LineSource: Send {
    /// Appends the next line (with its terminator) to `buf`; `Ok(0)` at the end of input.
    ///
    /// # Errors
    /// The input cannot be read.
    fn read_line(&mut self, buf: &mut String) -> std::io::Result<usize>;
}

impl<R: BufRead + Send> LineSource for R {
    fn read_line(&mut self, buf: &mut String) -> std::io::Result<usize> {
        BufRead::read_line(self, buf)
    }
}

/// The process's stdin, read through its one shared buffer (locked per line): several consoles
/// (the operator and a console tracker) can read it in turn without one buffering lines
/// meant for the other.
#[derive(Debug, Clone, Copy, Default)]
pub struct SharedStdin;

impl LineSource for SharedStdin {
    fn read_line(&mut self, buf: &mut String) -> std::io::Result<usize> {
        std::io::stdin().read_line(buf)
    }
}

/// One typed line per question: prints the prompt to `output`, reads a line from `input`.
/// End of input, or a line `abort`, is [`ErrorKind::Cancelled`].
#[derive(Debug)]
pub struct Console<R, W> {
    input: R,
    output: W,
}

impl Console<SharedStdin, Stderr> {
    /// Prompts on stderr (stdout stays for results), answers from stdin ([`SharedStdin`]).
    pub fn stdio() -> Self {
        Self::new(SharedStdin, std::io::stderr())
    }
}

impl<R: LineSource, W: Write + Send> Console<R, W> {
    /// A console on any line-based input and output.
    pub fn new(input: R, output: W) -> Self {
        Self { input, output }
    }

    /// Writes `text` (a line, e.g. why the last answer was refused) without waiting for input.
    ///
    /// # Errors
    /// The output cannot be written ([`ErrorKind::Io`]).
    pub fn say(&mut self, device: &str, text: &str) -> Result<()> {
        writeln!(self.output, "{text}").map_err(|e| Error::from_io(device, e))?;
        self.output.flush().map_err(|e| Error::from_io(device, e))
    }

    /// Prints `prompt` and returns the answer line, trimmed.
    ///
    /// # Errors
    /// [`ErrorKind::Cancelled`] at the end of the input or for `abort` (any case); the I/O
    /// error's kind when the console cannot be read or written. `device` and `what` (the
    /// question, in a few words) name the cancellation.
    pub fn ask(&mut self, device: &str, what: &str, prompt: &str) -> Result<String> {
        self.say(device, prompt)?;
        let mut line = String::new();
        let n = self.input.read_line(&mut line).map_err(|e| Error::from_io(device, e))?;
        let answer = line.trim();
        if n == 0 || answer.eq_ignore_ascii_case("abort") {
            return Err(Error::new(ErrorKind::Cancelled, device, format!("operator cancelled: {what}")));
        }
        Ok(answer.to_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_are_trimmed_abort_and_end_cancel() {
        let mut out = Vec::new();
        let mut c = Console::new(" 1 2 3 \nABORT\n".as_bytes(), &mut out);
        assert_eq!(c.ask("tracker", "q", "type it").expect("answer"), "1 2 3");
        assert_eq!(c.ask("tracker", "q", "again").expect_err("abort").kind(), ErrorKind::Cancelled);
        let e = c.ask("tracker", "measuring target 2", "again").expect_err("end");
        assert_eq!(e.kind(), ErrorKind::Cancelled);
        assert!(e.to_string().contains("measuring target 2"), "{e}");
        assert!(String::from_utf8(out).expect("utf8").starts_with("type it\n"));
    }
}
