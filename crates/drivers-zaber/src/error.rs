//! The driver's own error type and its mapping onto the portable
//! [`vatcal_hardware_traits::ErrorKind`].

use vatcal_hardware_traits::{Error as HwError, ErrorKind, LinkError};

use crate::codec::{LineTooLong, ParseError, Warning};

/// Everything that can go wrong talking to a Zaber device.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ZaberError {
    /// The link failed: an I/O error, the connection closed, or no answer in time.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The device rejected a command (`RJ`) with this reason (`BADDATA`, `BADCOMMAND`, …).
    #[error("command '{command}' rejected: {reason} (flag {})", warning.map(|w| w.to_string()).unwrap_or_else(|| "--".to_owned()))]
    Rejected {
        /// the command text
        command: String,
        /// the rejection reason word
        reason: String,
        /// the flag shown in the reply
        warning: Option<Warning>,
    },
    /// A move ended with a fault or warning flag (stall, limit, interruption, …).
    #[error("motion failed: flags {}", flags.iter().map(|f| f.to_string()).collect::<Vec<_>>().join(" "))]
    MotionFailed {
        /// every flag that was active after the move, most important first
        flags: Vec<Warning>,
    },
    /// The axis is still moving; the new command was not sent.
    #[error("the axis is busy (still moving)")]
    Busy,
    /// The axis has no reference position (`WR`/`WH`): home it first.
    #[error("the axis is not homed (home it first)")]
    NotHomed,
    /// A target beyond the travel.
    #[error("target {target_mm} mm is outside the travel {min_mm}..{max_mm} mm")]
    OutOfRange {
        /// requested target \[mm\]
        target_mm: f64,
        /// lower travel limit \[mm\]
        min_mm: f64,
        /// upper travel limit \[mm\]
        max_mm: f64,
    },
    /// A line could not be parsed.
    #[error("malformed message: {0}")]
    Malformed(#[from] ParseError),
    /// An overlong line arrived.
    #[error("framing: {0}")]
    Frame(#[from] LineTooLong),
    /// The device answered something unexpected.
    #[error("protocol: {0}")]
    Protocol(String),
    /// A caller passed an unusable value.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// The axis was still BUSY when the wait's timeout expired and answers every poll (kind
    /// [`ErrorKind::Timeout`]): still moving. Not a link fault, so the driver does not stop
    /// it; the caller decides (wait again, or `stop`).
    #[error("the motion had not ended within {:.3} s (the axis answers: still moving)", after.as_secs_f64())]
    MotionNotFinished {
        /// the wait's timeout
        after: std::time::Duration,
    },
}

impl From<std::io::Error> for ZaberError {
    fn from(e: std::io::Error) -> Self {
        ZaberError::Link(LinkError::Io(e))
    }
}

impl ZaberError {
    /// The portable kind. Rejections: `BADDATA` → `OutOfRange`; `BADCOMMAND`, `BADAXIS`,
    /// `BADMESSAGEID`, `DEVICEONLY` → `Protocol`; `AGAIN`, `FULL`, `STATUSBUSY` → `Busy`;
    /// `DRIVERDISABLED` → `DeviceFault` with the `FO` code; others → `Other`. Motion failures
    /// → `DeviceFault` with the most important flag's code ([`Warning::code`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ZaberError::Link(e) => e.kind(),
            ZaberError::Rejected { reason, .. } => rejection_kind(reason),
            ZaberError::MotionFailed { flags } => match flags.first() {
                Some(f) => ErrorKind::DeviceFault { code: f.code() },
                None => ErrorKind::Other,
            },
            ZaberError::NotHomed => ErrorKind::NotHomed,
            ZaberError::Busy => ErrorKind::Busy,
            ZaberError::OutOfRange { .. } | ZaberError::InvalidArgument(_) => ErrorKind::OutOfRange,
            ZaberError::Malformed(_) | ZaberError::Frame(_) | ZaberError::Protocol(_) => ErrorKind::Protocol,
            ZaberError::MotionNotFinished { .. } => ErrorKind::Timeout,
        }
    }

    /// Converts into the trait-level error of device `device`, keeping `self` as source.
    pub fn into_hw(self, device: &str) -> HwError {
        match self {
            ZaberError::Link(e) => e.into_hw(device),
            other => HwError::new(other.kind(), device, other.to_string()).with_source(other),
        }
    }
}

/// Portable kind of a rejection reason.
pub fn rejection_kind(reason: &str) -> ErrorKind {
    match reason {
        "BADDATA" => ErrorKind::OutOfRange,
        "BADCOMMAND" | "BADAXIS" | "BADMESSAGEID" | "DEVICEONLY" => ErrorKind::Protocol,
        "AGAIN" | "FULL" | "STATUSBUSY" => ErrorKind::Busy,
        "DRIVERDISABLED" => ErrorKind::DeviceFault { code: Warning::DRIVER_DISABLED.code() },
        _ => ErrorKind::Other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds() {
        let rj =
            |r: &str| ZaberError::Rejected { command: "x".into(), reason: r.into(), warning: None }.kind();
        assert_eq!(rj("BADDATA"), ErrorKind::OutOfRange);
        assert_eq!(rj("BADCOMMAND"), ErrorKind::Protocol);
        assert_eq!(rj("STATUSBUSY"), ErrorKind::Busy);
        assert_eq!(rj("DRIVERDISABLED"), ErrorKind::DeviceFault { code: 0x464f });
        let failed = ZaberError::MotionFailed { flags: vec![Warning::STALL, Warning::INTERRUPTED] };
        assert_eq!(failed.kind(), ErrorKind::DeviceFault { code: 0x4653 });
        assert_eq!(ZaberError::NotHomed.into_hw("guide").kind(), ErrorKind::NotHomed);
    }
}
