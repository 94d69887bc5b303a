//! The driver's own error type and its mapping onto the portable
//! [`vatcal_hardware_traits::ErrorKind`].

use vatcal_hardware_traits::{Error as HwError, ErrorKind, LinkError};

use crate::codec::{BannerError, FrameError, ReplyError, code};

/// Everything that can go wrong talking to a Meca500.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Meca500Error {
    /// The link failed: an I/O error, the connection closed, or no answer in time.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The robot refused a command or reported an error (codes 1000–1999, 3005, 3070, …).
    #[error("robot error [{code}]: {text}")]
    Robot {
        /// the robot's code
        code: u16,
        /// the robot's text (wording varies between firmware versions; never matched on)
        text: String,
    },
    /// The banner was a refusal or could not be understood.
    #[error("connection: {0}")]
    Banner(#[from] BannerError),
    /// A message could not be parsed.
    #[error("malformed message: {0}")]
    Malformed(#[from] ReplyError),
    /// A framing error (message without terminator).
    #[error("framing: {0}")]
    Frame(#[from] FrameError),
    /// A checkpoint was discarded (`[3040]`): the motion queue was cleared before reaching it.
    #[error("checkpoint {0} discarded: the motion was cleared")]
    CheckpointDiscarded(u32),
    /// A caller passed an unusable value (NaN, infinite, non-positive speed).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// The motion had not ended when the wait's timeout expired, and the robot still answers
    /// (kind [`ErrorKind::Timeout`]): it is still moving. Not a link fault, so the driver does
    /// not stop it; the caller decides (wait again, or `stop`).
    #[error("the motion had not ended within {:.3} s (the robot answers: still moving)", after.as_secs_f64())]
    MotionNotFinished {
        /// the wait's timeout
        after: std::time::Duration,
    },
}

impl From<std::io::Error> for Meca500Error {
    fn from(e: std::io::Error) -> Self {
        Meca500Error::Link(LinkError::Io(e))
    }
}

impl Meca500Error {
    /// The portable kind: 1005/1006 → [`ErrorKind::NotHomed`], 1000 (buffer full) and 3001
    /// (another client) → [`ErrorKind::Busy`], every other robot code →
    /// [`ErrorKind::DeviceFault`] with that code.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Meca500Error::Link(e) => e.kind(),
            Meca500Error::Robot { code, .. } => robot_code_kind(*code),
            Meca500Error::Banner(BannerError::Refused(r)) => robot_code_kind(r.code),
            Meca500Error::Banner(_) | Meca500Error::Malformed(_) | Meca500Error::Frame(_) => {
                ErrorKind::Protocol
            }
            Meca500Error::CheckpointDiscarded(_) => ErrorKind::Cancelled,
            Meca500Error::InvalidArgument(_) => ErrorKind::OutOfRange,
            Meca500Error::MotionNotFinished { .. } => ErrorKind::Timeout,
        }
    }

    /// Converts into the trait-level error of device `device`, keeping `self` as source.
    pub fn into_hw(self, device: &str) -> HwError {
        match self {
            Meca500Error::Link(e) => e.into_hw(device),
            other => HwError::new(other.kind(), device, other.to_string()).with_source(other),
        }
    }
}

/// Portable kind of a robot code.
pub fn robot_code_kind(c: u16) -> ErrorKind {
    match c {
        code::NOT_ACTIVATED | code::NOT_HOMED => ErrorKind::NotHomed,
        code::BUFFER_FULL | code::ANOTHER_USER => ErrorKind::Busy,
        other => ErrorKind::DeviceFault { code: i32::from(other) },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::Reply;

    #[test]
    fn kinds() {
        let robot = |code| Meca500Error::Robot { code, text: String::new() };
        assert_eq!(robot(1007).kind(), ErrorKind::DeviceFault { code: 1007 });
        assert_eq!(robot(3005).kind(), ErrorKind::DeviceFault { code: 3005 });
        assert_eq!(robot(1005).kind(), ErrorKind::NotHomed);
        assert_eq!(robot(1006).kind(), ErrorKind::NotHomed);
        assert_eq!(robot(1000).kind(), ErrorKind::Busy);
        assert_eq!(Meca500Error::Banner(BannerError::Refused(Reply::new(3001, "x"))).kind(), ErrorKind::Busy);
        let closed = Meca500Error::from(LinkError::Disconnected {
            during: "waiting for the end of the motion".into(),
        });
        assert_eq!(closed.kind(), ErrorKind::Disconnected);
        assert_eq!(closed.to_string(), "connection closed while waiting for the end of the motion");
        let io = Meca500Error::from(std::io::Error::new(std::io::ErrorKind::BrokenPipe, "x"));
        assert_eq!(io.kind(), ErrorKind::Disconnected);
        let hw = robot(1007).into_hw("meca500");
        assert_eq!(hw.kind(), ErrorKind::DeviceFault { code: 1007 });
        assert_eq!(hw.device(), "meca500");
        assert!(std::error::Error::source(&hw).is_some());
    }
}
