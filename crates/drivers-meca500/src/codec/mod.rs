//! Sans-IO codec of the Meca500 TCP text API (protocols.md §1.2–1.6).
//!
//! Pure functions only: [`Command`] ↔ text/bytes, bytes → [`Reply`], a [`Deframer`] that cuts
//! a TCP byte stream into NUL-terminated frames, the [`StatusWord`] of `[2007]` and the
//! connection [`Banner`]. Both the driver and the simulator use these types, so the two sides
//! cannot drift apart silently.

//!
//! One file per job: [`Command`] and its encoding (`command.rs`), the parsing of a received
//! command line (`command_parse.rs`), the reply and event [`code`]s, [`Reply`] parsing, the
//! [`StatusWord`], the [`Banner`] and the [`Deframer`].

mod banner;
pub mod code;
mod command;
mod command_parse;
mod deframer;
mod reply;
mod status;

#[cfg(test)]
mod tests;

pub use banner::{Banner, BannerError, KNOWN_MODELS};
pub use command::{Command, RealTimeCodes, format_number};
pub use command_parse::{CommandError, ParsedCommand, parse_command};
pub use deframer::{Deframer, FrameError};
pub use reply::{Reply, ReplyError};
pub use status::StatusWord;

/// Byte that ends every message in both directions.
pub const NUL: u8 = 0;

/// Longest frame (command or reply) the deframer accepts before reporting
/// [`FrameError::TooLong`] (the robot answers `[3003]` to overlong commands).
pub const MAX_FRAME_LEN: usize = 4096;

/// Number of decimals used when writing a floating-point argument (the manual allows up to 9).
pub const ARG_DECIMALS: usize = 9;

/// Six numbers: joint angles \[deg\] or a pose `x, y, z \[mm\], α, β, γ \[deg\]`.
pub type Six = [f64; 6];
