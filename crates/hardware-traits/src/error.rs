//! The one error type every device trait returns.
//!
//! Device traits must stay object-safe (`Box<dyn RobotArm>`), so they cannot use associated
//! error types; instead every driver converts its own rich error into [`Error`], which carries
//! a portable [`ErrorKind`] (embedded-hal style), the device name, a human-readable message and
//! the driver's error as `source`. Callers branch on the kind, users read the message.

use std::fmt;
use std::time::Duration;

/// Portable category of a device error. Callers decide what to do from the kind alone
/// (retry on [`ErrorKind::Busy`], reset on [`ErrorKind::DeviceFault`], abort on
/// [`ErrorKind::Disconnected`], ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A blocking call did not complete within its timeout.
    Timeout,
    /// The connection to the device is gone (socket closed, BLE link lost, port unplugged).
    Disconnected,
    /// The device answered something the driver does not understand.
    Protocol,
    /// The device reported a fault with its own numeric code (e.g. a Meca500 `[1007]` joint
    /// limit, a Zaber warning flag mapped to a number).
    DeviceFault {
        /// the device's own error code
        code: i32,
    },
    /// The device must be homed (or activated) first.
    NotHomed,
    /// A value is outside the device's range (a joint limit, a gauge beyond its travel, a guide
    /// target beyond the stroke).
    OutOfRange,
    /// The device is busy (e.g. still moving) and refused the request.
    Busy,
    /// An operating-system I/O error.
    Io,
    /// The operator (or a caller) cancelled the operation.
    Cancelled,
    /// Anything else.
    Other,
}

impl ErrorKind {
    /// The portable kind of an OS I/O error: timeouts → [`ErrorKind::Timeout`], closed, refused
    /// or reset connections → [`ErrorKind::Disconnected`], everything else → [`ErrorKind::Io`].
    pub fn of_io(e: &std::io::Error) -> Self {
        use std::io::ErrorKind as K;
        match e.kind() {
            K::TimedOut | K::WouldBlock => ErrorKind::Timeout,
            K::ConnectionReset
            | K::ConnectionAborted
            | K::ConnectionRefused
            | K::NotConnected
            | K::BrokenPipe
            | K::UnexpectedEof => ErrorKind::Disconnected,
            _ => ErrorKind::Io,
        }
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ErrorKind::Timeout => f.write_str("timeout"),
            ErrorKind::Disconnected => f.write_str("disconnected"),
            ErrorKind::Protocol => f.write_str("protocol error"),
            ErrorKind::DeviceFault { code } => write!(f, "device fault {code}"),
            ErrorKind::NotHomed => f.write_str("not homed"),
            ErrorKind::OutOfRange => f.write_str("out of range"),
            ErrorKind::Busy => f.write_str("busy"),
            ErrorKind::Io => f.write_str("I/O error"),
            ErrorKind::Cancelled => f.write_str("cancelled"),
            ErrorKind::Other => f.write_str("error"),
        }
    }
}

/// Boxed driver-specific cause of an [`Error`].
pub type Source = Box<dyn std::error::Error + Send + Sync + 'static>;

/// A device error: kind + device + message (+ the driver's own error as `source`).
///
/// Display: `"<device>: <kind>: <message>"`, e.g.
/// `gauge 2: out of range: reading 6.412 mm is outside ±6 mm`.
#[derive(Debug, thiserror::Error)]
#[error("{device}: {kind}: {message}")]
pub struct Error {
    kind: ErrorKind,
    device: String,
    message: String,
    #[source]
    source: Option<Source>,
}

/// `Result` with [`Error`] as the default error type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// A new error of `kind` raised by `device` (a short name such as `"meca500"`,
    /// `"gauge 2"`, `"sim guide"`).
    pub fn new(kind: ErrorKind, device: impl Into<String>, message: impl Into<String>) -> Self {
        Self { kind, device: device.into(), message: message.into(), source: None }
    }

    /// Attaches the driver's own error as the cause.
    pub fn with_source(mut self, source: impl Into<Source>) -> Self {
        self.source = Some(source.into());
        self
    }

    /// A [`ErrorKind::Timeout`] error: `what` did not finish within `timeout`.
    pub fn timeout(device: impl Into<String>, what: &str, timeout: Duration) -> Self {
        Self::new(
            ErrorKind::Timeout,
            device,
            format!("{what} did not finish within {:.3} s", timeout.as_secs_f64()),
        )
    }

    /// Wraps an OS I/O error, mapping its kind: timeouts → [`ErrorKind::Timeout`], closed or
    /// reset connections → [`ErrorKind::Disconnected`], everything else → [`ErrorKind::Io`].
    pub fn from_io(device: impl Into<String>, e: std::io::Error) -> Self {
        Self::new(ErrorKind::of_io(&e), device, e.to_string()).with_source(e)
    }

    /// The portable category.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The device that raised the error.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// The human-readable message (without device and kind).
    pub fn message(&self) -> &str {
        &self.message
    }

    /// True for [`ErrorKind::Timeout`].
    pub fn is_timeout(&self) -> bool {
        self.kind == ErrorKind::Timeout
    }

    /// Prefixes the message with context (e.g. `"step 12: "`), keeping kind, device and source.
    pub fn context(mut self, context: impl fmt::Display) -> Self {
        self.message = format!("{context}: {}", self.message);
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error as _;

    #[test]
    fn display_names_device_kind_and_message() {
        let e = Error::new(ErrorKind::DeviceFault { code: 1007 }, "meca500", "joint 2 over its limit");
        assert_eq!(e.to_string(), "meca500: device fault 1007: joint 2 over its limit");
        assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 1007 });
        let e = e.context("step 3");
        assert_eq!(e.message(), "step 3: joint 2 over its limit");
    }

    #[test]
    fn io_errors_map_to_portable_kinds_and_keep_their_source() {
        let cases = [
            (std::io::ErrorKind::TimedOut, ErrorKind::Timeout),
            (std::io::ErrorKind::BrokenPipe, ErrorKind::Disconnected),
            (std::io::ErrorKind::ConnectionReset, ErrorKind::Disconnected),
            (std::io::ErrorKind::PermissionDenied, ErrorKind::Io),
        ];
        for (io, kind) in cases {
            let e = Error::from_io("zaber", std::io::Error::new(io, "boom"));
            assert_eq!(e.kind(), kind);
            assert!(e.source().is_some());
        }
        let t = Error::timeout("gauge 1", "read", Duration::from_millis(1500));
        assert!(t.is_timeout());
        assert!(t.to_string().contains("1.500 s"), "{t}");
    }
}
