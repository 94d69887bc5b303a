//! [`Deframer`]: a TCP byte stream cut into NUL-terminated frames.

use vatcal_hardware_traits::transport::{Framing, LineDeframer};

use super::MAX_FRAME_LEN;

pub use vatcal_hardware_traits::transport::FrameError;

/// Cuts a byte stream into NUL-terminated frames: the shared
/// [`LineDeframer`] configured for the
/// Meca500 (frames up to [`MAX_FRAME_LEN`] bytes, empty frames kept). TCP may split or
/// coalesce messages: push whatever arrived, then pop complete frames with `next_frame`; the
/// unterminated tail is kept for the next push. Every method of the shared deframer is
/// available through `Deref`.
#[derive(Debug, Clone)]
pub struct Deframer(LineDeframer);

impl Deframer {
    /// Splits on NUL only (what the robot sends, and what the driver reads).
    pub fn nul_only() -> Self {
        Self(LineDeframer::new(Framing::nul(MAX_FRAME_LEN)))
    }

    /// Splits on NUL **or** LF (the robot also accepts LF-terminated commands, §1.1; a CR
    /// before the LF is removed).
    pub fn nul_or_lf() -> Self {
        Self(LineDeframer::new(Framing::nul_or_lf(MAX_FRAME_LEN)))
    }
}

impl std::ops::Deref for Deframer {
    type Target = LineDeframer;

    fn deref(&self) -> &LineDeframer {
        &self.0
    }
}

impl std::ops::DerefMut for Deframer {
    fn deref_mut(&mut self) -> &mut LineDeframer {
        &mut self.0
    }
}
