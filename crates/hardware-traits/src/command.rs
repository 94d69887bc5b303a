//! Running an external program as a device: the way a user reaches a vendor SDK, a metrology
//! package or a sensor tool (a thermometer, a laser tracker) without a driver in vatcal.
//!
//! [`run`] starts the program with its arguments and extra environment variables, closes its
//! stdin, collects stdout and stderr (each on its own thread, so a chatty program cannot block
//! on a full pipe), and kills it when it runs longer than the timeout. The caller parses the
//! output; the errors name the device and say what happened:
//!
//! | what happened | [`ErrorKind`] |
//! |---|---|
//! | the program cannot be started (not found, not executable) | the I/O error's kind ([`ErrorKind::of_io`]) |
//! | it ran longer than the timeout (it was killed) | [`ErrorKind::Timeout`] |
//! | it exited with a non-zero status | [`ErrorKind::DeviceFault`] with the exit code (−1 when killed by a signal), the end of its stderr in the message |

use std::io::Read;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use crate::error::{Error, ErrorKind, Result};

/// How long [`run`] sleeps between two checks of a running child.
const POLL: Duration = Duration::from_millis(2);
/// At most this many bytes of stderr are quoted in an error.
const STDERR_QUOTE: usize = 600;

/// What a program printed, after it exited successfully.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Output {
    /// standard output (invalid UTF-8 replaced by U+FFFD)
    pub stdout: String,
    /// standard error (invalid UTF-8 replaced by U+FFFD)
    pub stderr: String,
}

impl Output {
    /// The first line of stdout that is not blank, trimmed (`None`: no such line).
    pub fn first_line(&self) -> Option<&str> {
        self.stdout.lines().map(str::trim).find(|l| !l.is_empty())
    }
}

/// Runs `program` with `args` and the extra environment `env`, waiting at most `timeout`
/// (see the module docs). `device` names the device in the errors.
///
/// # Errors
/// The program cannot be started, runs longer than `timeout` (it is killed), or exits with a
/// non-zero status (the message quotes the end of its stderr).
pub fn run(
    device: &str,
    program: &str,
    args: &[String],
    env: &[(String, String)],
    timeout: Duration,
) -> Result<Output> {
    let mut child = Command::new(program)
        .args(args)
        .envs(env.iter().map(|(k, v)| (k.as_str(), v.as_str())))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| Error::from_io(device, e).context(format!("starting `{program}`")))?;
    let stdout = child.stdout.take().map(drain);
    let stderr = child.stderr.take().map(drain);
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if start.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::new(
                    ErrorKind::Timeout,
                    device,
                    format!(
                        "`{program}` did not finish within {:.3} s (it was killed)",
                        timeout.as_secs_f64()
                    ),
                ));
            }
            Ok(None) => std::thread::sleep(POLL),
            Err(e) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::from_io(device, e).context(format!("waiting for `{program}`")));
            }
        }
    };
    let collect = |h: Option<std::thread::JoinHandle<Vec<u8>>>| {
        h.and_then(|h| h.join().ok()).map(|b| String::from_utf8_lossy(&b).into_owned()).unwrap_or_default()
    };
    let output = Output { stdout: collect(stdout), stderr: collect(stderr) };
    if !status.success() {
        return Err(Error::new(
            ErrorKind::DeviceFault { code: status.code().unwrap_or(-1) },
            device,
            format!("`{program}` {}{}", describe(status), stderr_quote(&output.stderr)),
        ));
    }
    Ok(output)
}

/// Reads a pipe to its end on a thread of its own.
fn drain(mut pipe: impl Read + Send + 'static) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = pipe.read_to_end(&mut bytes);
        bytes
    })
}

fn describe(status: ExitStatus) -> String {
    match status.code() {
        Some(code) => format!("exited with status {code}"),
        None => format!("was stopped ({status})"),
    }
}

/// `; stderr: …` with the last [`STDERR_QUOTE`] bytes of `stderr` on one line, or nothing.
fn stderr_quote(stderr: &str) -> String {
    let text = stderr.trim();
    if text.is_empty() {
        return "; it printed nothing on stderr".into();
    }
    let mut start = text.len().saturating_sub(STDERR_QUOTE);
    while !text.is_char_boundary(start) {
        start += 1;
    }
    let cut = if start > 0 { "…" } else { "" };
    format!("; stderr: {cut}{}", text[start..].replace('\n', " | "))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sh(script: &str, timeout_ms: u64) -> Result<Output> {
        run("test device", "sh", &["-c".into(), script.into()], &[], Duration::from_millis(timeout_ms))
    }

    #[test]
    fn output_environment_and_failures() {
        let out = run(
            "d",
            "sh",
            &["-c".into(), "echo; echo \"  $A $1 \"".into(), "x".into(), "arg1".into()],
            &[("A".into(), "from-env".into())],
            Duration::from_secs(5),
        )
        .expect("runs");
        assert_eq!(out.first_line(), Some("from-env arg1"));

        let e = sh("echo partial; echo 'no SMR in view' >&2; exit 4", 5000).expect_err("exit 4");
        assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 4 });
        assert!(e.to_string().contains("status 4") && e.to_string().contains("no SMR in view"), "{e}");
        assert!(e.to_string().starts_with("test device: "), "{e}");

        let started = Instant::now();
        let e = sh("sleep 5", 100).expect_err("slow");
        assert!(e.is_timeout() && e.to_string().contains("killed"), "{e}");
        assert!(started.elapsed() < Duration::from_secs(3), "the child was killed, not waited for");

        let e = run("d", "/nonexistent/tracker-tool", &[], &[], Duration::from_secs(1)).expect_err("missing");
        assert!(e.to_string().contains("/nonexistent/tracker-tool"), "{e}");
    }

    #[test]
    fn a_large_output_does_not_block_and_stderr_is_quoted_from_its_end() {
        let out = sh("head -c 300000 /dev/zero | tr '\\0' 'a'; echo", 10_000).expect("big output");
        assert_eq!(out.stdout.trim().len(), 300_000);
        let e = sh("i=0; while [ $i -lt 200 ]; do echo line$i >&2; i=$((i+1)); done; exit 1", 10_000)
            .expect_err("fails");
        let text = e.to_string();
        assert!(text.contains("line199") && !text.contains("line1 |"), "{text}");
    }
}
