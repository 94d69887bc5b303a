//! The driver's own error type and its mapping onto the portable
//! [`vatcal_hardware_traits::ErrorKind`].

use vatcal_hardware_traits::{Error as HwError, ErrorKind, LinkError};

use crate::codec::{GaugeError, LineTooLong, MAX_PRESET_MM};

/// Everything that can go wrong talking to a Sylvac gauge.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SylvacError {
    /// The link failed: an I/O error, the connection closed, or no answer in time.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The gauge answered `ERRn`.
    #[error("'{command}' answered {error}")]
    Gauge {
        /// the command
        command: String,
        /// the error answer
        error: GaugeError,
    },
    /// An answer of the wrong form.
    #[error("'{command}' answered '{answer}'")]
    UnexpectedAnswer {
        /// the command
        command: String,
        /// what came back
        answer: String,
    },
    /// The Bluetooth LE stack failed (no adapter, no D-Bus, lost link, missing characteristic).
    #[error("Bluetooth LE: {0}")]
    Ble(String),
    /// An overlong line arrived.
    #[error("framing: {0}")]
    Frame(#[from] LineTooLong),
    /// A preset beyond ±199.999 mm or not finite.
    #[error("preset {value_mm} mm is outside ±{MAX_PRESET_MM} mm")]
    PresetOutOfRange {
        /// requested preset \[mm\]
        value_mm: f64,
    },
    /// After a preset, the gauge does not read the preset value.
    #[error("preset {wanted_mm} mm not applied: the gauge reads {read_mm} mm")]
    PresetNotApplied {
        /// requested preset \[mm\]
        wanted_mm: f64,
        /// reading right after \[mm\]
        read_mm: f64,
    },
}

impl From<std::io::Error> for SylvacError {
    fn from(e: std::io::Error) -> Self {
        SylvacError::Link(LinkError::Io(e))
    }
}

impl SylvacError {
    /// The portable kind: `ERR3` → `OutOfRange`, `ERR0` → `DeviceFault { code: 0 }`, `ERR1`/
    /// `ERR2` and odd answers → `Protocol`.
    pub fn kind(&self) -> ErrorKind {
        match self {
            SylvacError::Link(e) => e.kind(),
            SylvacError::Gauge { error: GaugeError::RangeExceeded, .. } => ErrorKind::OutOfRange,
            SylvacError::Gauge { error: GaugeError::Sensor, .. } => ErrorKind::DeviceFault { code: 0 },
            SylvacError::Gauge { .. } | SylvacError::UnexpectedAnswer { .. } | SylvacError::Frame(_) => {
                ErrorKind::Protocol
            }
            SylvacError::PresetOutOfRange { .. } => ErrorKind::OutOfRange,
            SylvacError::Ble(_) => ErrorKind::Io,
            SylvacError::PresetNotApplied { .. } => ErrorKind::Protocol,
        }
    }

    /// Converts into the trait-level error of device `device`, keeping `self` as source.
    pub fn into_hw(self, device: &str) -> HwError {
        match self {
            SylvacError::Link(e) => e.into_hw(device),
            other => HwError::new(other.kind(), device, other.to_string()).with_source(other),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds() {
        let g = |error| SylvacError::Gauge { command: "?".into(), error }.kind();
        assert_eq!(g(GaugeError::RangeExceeded), ErrorKind::OutOfRange);
        assert_eq!(g(GaugeError::Sensor), ErrorKind::DeviceFault { code: 0 });
        assert_eq!(g(GaugeError::UnknownCommand), ErrorKind::Protocol);
        assert_eq!(
            SylvacError::PresetOutOfRange { value_mm: 300.0 }.into_hw("gauge 1").kind(),
            ErrorKind::OutOfRange
        );
    }
}
