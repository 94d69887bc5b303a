#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The device traits every vatcal driver implements, and the only thing campaign code sees:
//!
//! | trait | device in the paper's cell |
//! |---|---|
//! | [`RobotArm`] | Mecademic Meca500 (joints in rad, relative linear moves in mm) |
//! | [`LinearAxis`] | Zaber X-LRQ300AP linear guide (mm) |
//! | [`Gauge`] | Sylvac S_Dial WORK Nano Smart indicator (mm) |
//! | [`Probe3d`] | TriCal: three gauges → ball-centre offset ([`TriCal`] builds it from gauges) |
//! | [`PositionTracker`] | laser tracker for validation (world mm) |
//! | [`Thermometer`] | the cell's temperature (°C), recorded as `temperature_c` |
//! | [`Operator`] | the person who re-places the probe plate |
//!
//! [`command`] runs an external program as a device (timeouts, exit codes and stderr as
//! errors) and [`console`] asks a person at a terminal for a line; [`RegisteredTracker`] maps a
//! tracker's readings into the tank frame.
//!
//! plus a [`Clock`] ([`SystemClock`] on hardware, [`VirtualClock`] in simulation), and one
//! concrete [`Error`] carrying a portable [`ErrorKind`].
//!
//! ## Why blocking
//! The devices are slow (a robot move takes seconds, a gauge reading ~100 ms) and a
//! calibration is a strictly sequential script: move, wait, read, correct, record. Blocking
//! calls make that script read like the procedure, are trivial to simulate in virtual time, and
//! keep an async runtime out of every numerical crate. A driver that needs async internally
//! (Bluetooth LE) owns a small runtime and exposes these blocking traits. If an async API is
//! ever needed, it belongs in a sibling crate with the same trait names, not mixed in here.
//!
//! ## Rules every implementation follows
//! * **Units**: mm and rad in every signature; degrees, microsteps and device counts exist only
//!   inside drivers.
//! * **No call waits forever**: motion waits take an explicit timeout ([`MotionOptions`],
//!   `wait_idle(timeout)`), every other call uses the I/O timeout of the driver's
//!   configuration and fails with [`ErrorKind::Timeout`].
//! * **Object-safe** with `&mut self` methods (one owner, no hidden locking); blanket impls
//!   make `&mut T` and `Box<T>` (including `Box<dyn Trait>`) implementations too, so campaign
//!   code can take `&mut dyn RobotArm` and drivers are swappable.
//! * **Errors**: convert the driver's own error into [`Error`] with the closest [`ErrorKind`]
//!   and keep it as `source`.

mod arm;
mod axis;
mod clock;
pub mod command;
pub mod console;
mod error;
mod gauge;
mod operator;
mod probe;
pub mod sim_server;
pub mod testing;
mod thermometer;
mod tracker;
pub mod transport;

pub use arm::{ArmJoints, ArmStatus, JointLayout, LinearFrame, MotionOptions, RobotArm};
pub use axis::LinearAxis;
pub use clock::{Clock, SystemClock, VirtualClock};
pub use error::{Error, ErrorKind, Result, Source};
pub use gauge::Gauge;
pub use operator::{Operator, OperatorInstruction};
pub use probe::{Probe3d, ProbePlacement, ProbeReading, TRICAL_MASTER_PRESET_MM, TriCal, TriCalConfig};
pub use thermometer::{PLAUSIBLE_TEMPERATURE_C, Thermometer, parse_temperature_c};
pub use tracker::{PROBE_NEST_TARGET, PositionTracker, RegisteredTracker};
pub use transport::{Deadline, LinkError, Transport};
