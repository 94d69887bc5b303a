//! The drivers' own error type and its mapping onto the portable
//! [`vatcal_hardware_traits::ErrorKind`].

use vatcal_hardware_traits::transport::{FrameError, LinkError};
use vatcal_hardware_traits::{Error as HwError, ErrorKind};

use crate::codec::ErrorCode;

/// Everything that can go wrong talking to a tracker over the line protocol.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TrackerError {
    /// The link failed: an I/O error, the connection closed, or no answer in time.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// An overlong line arrived.
    #[error("framing: {0}")]
    Frame(#[from] FrameError),
    /// The tracker refused the request (`ERR <CODE> …`).
    #[error("'{request}' answered {code}: {message}")]
    Refused {
        /// the request
        request: String,
        /// the error code
        code: ErrorCode,
        /// the tracker's words
        message: String,
    },
    /// An answer that is not a reply, or a reading that is not `x y z`.
    #[error("'{request}' answered garbage '{answer}': {reason}")]
    Garbled {
        /// the request
        request: String,
        /// what came back (clipped)
        answer: String,
        /// why it is garbage
        reason: String,
    },
}

impl From<std::io::Error> for TrackerError {
    fn from(e: std::io::Error) -> Self {
        TrackerError::Link(LinkError::Io(e))
    }
}

impl TrackerError {
    /// The portable kind: `LOS` and `TARGET` → [`ErrorKind::OutOfRange`] (the trait's "cannot
    /// be seen"), `DEVICE` → [`ErrorKind::DeviceFault`] (code 0), `REQUEST`, garbage and
    /// framing → [`ErrorKind::Protocol`], the link's own kinds.
    pub fn kind(&self) -> ErrorKind {
        match self {
            TrackerError::Link(e) => e.kind(),
            TrackerError::Refused { code: ErrorCode::LineOfSight | ErrorCode::UnknownTarget, .. } => {
                ErrorKind::OutOfRange
            }
            TrackerError::Refused { code: ErrorCode::Device, .. } => ErrorKind::DeviceFault { code: 0 },
            TrackerError::Refused { code: ErrorCode::BadRequest, .. }
            | TrackerError::Garbled { .. }
            | TrackerError::Frame(_) => ErrorKind::Protocol,
        }
    }

    /// Converts into the trait-level error of device `device`, keeping `self` as source.
    pub fn into_hw(self, device: &str) -> HwError {
        match self {
            TrackerError::Link(e) => e.into_hw(device),
            other => HwError::new(other.kind(), device, other.to_string()).with_source(other),
        }
    }
}
