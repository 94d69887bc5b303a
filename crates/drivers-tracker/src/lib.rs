#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! [`PositionTracker`](vatcal_hardware_traits::PositionTracker) drivers for the laser tracker
//! of the validation campaign (paper §5), one per way a tracker is reached
//! (`tracker = { kind = … }` in the devices file, `docs/drivers.md`):
//!
//! | kind | type | how |
//! |---|---|---|
//! | `sim-cell` | [`LineTracker`] | the tracker line protocol ([`codec`]) over TCP: `vatcal sim-cell`'s virtual tracker, the [`sim::TrackerSim`] of this crate, or a bridge to a real tracker |
//! | `command` | [`CommandTracker`] | an external program run for every point prints `x y z` |
//! | `console` | [`ConsoleTracker`] | the operator types or pastes each reading |
//!
//! Units: mm. The readings are in the tracker's own frame; the validation campaign's
//! registration step (`vatcal_campaign::validation`) measures the SMR in the probe's
//! trihedral nest at the calibration positions and wraps the tracker in a
//! [`RegisteredTracker`](vatcal_hardware_traits::RegisteredTracker) that maps every later
//! reading into the tank frame.
//!
//! ## Layers
//! * [`codec`] — sans-IO: requests and replies of the line protocol, the `x y z` reading
//!   format (property-tested against arbitrary input).
//! * [`driver`] — [`LineTracker`] over any `Transport`, with [`TrackerConfig`] timeouts.
//! * [`command`], [`console`] — the other two kinds.
//! * [`error`] — [`TrackerError`], mapped onto `ErrorKind` (`ERR LOS` → `OutOfRange`, garbage
//!   → `Protocol`, silence → `Timeout`, closed link → `Disconnected`).
//! * [`sim`] — [`sim::TrackerSim`], a tracker on `127.0.0.1:0`, with fault injection.

pub mod codec;
pub mod command;
pub mod console;
pub mod driver;
pub mod error;
pub mod sim;

pub use command::{CommandTracker, CommandTrackerConfig};
pub use console::ConsoleTracker;
pub use driver::{LineTracker, TrackerConfig};
pub use error::TrackerError;
