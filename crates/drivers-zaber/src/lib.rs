#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! A [`LinearAxis`](vatcal_hardware_traits::LinearAxis) driver for the Zaber X-LRQ300AP linear
//! guide over the Zaber ASCII protocol, and a protocol simulator of the device. Reference:
//! `docs/drivers.md` and the project's protocol notes (protocols.md §2).
//!
//! ## Layers
//! * [`codec`] — sans-IO: [`Command`] ↔ `/addr axis [id] text[:CC]` lines, device lines →
//!   [`Message`] (`@` reply, `#` info, `!` alert), checksums, [`Warning`] flags, a
//!   [`LineDeframer`] for CR/LF/CRLF.
//! * [`transport`] — [`Transport`] (TCP; serial with the `serial` feature).
//! * [`driver`] — [`ZaberAxis`] with [`ZaberConfig`] (timeouts, addressing, mm ↔ microstep).
//! * [`sim`] — [`sim::ZaberSim`], a fake device on `127.0.0.1:0`.
//!
//! ## How the trait maps onto the protocol
//! | `LinearAxis` | wire |
//! |---|---|
//! | `home` | `/1 0 warnings clear` (refuse if BUSY), `/1 1 home`, poll `/1 1` until IDLE, check flags |
//! | `is_homed` | `/1 0 warnings`: neither `WR` nor `WH` |
//! | `position_mm` | `/1 1 get pos` × microstep size |
//! | `move_absolute_mm` | range check against `limit.min/max`, `warnings clear`, `set maxspeed` (if the fraction changed), `/1 1 move abs N` |
//! | `wait_idle` | poll `/1 1` every `poll_interval` until IDLE, then `warnings`: any fault, `WL`, `WS`, `NI` → error |
//! | `stop` | `/1 1 stop`, poll until IDLE, `warnings clear` |
//!
//! Units: the trait speaks mm; the device speaks integer microsteps. One microstep is
//! `lead / (200 × resolution)` ([`MicrostepSize`]); the X-LRQ300AP lead is **not verified**
//! (default 2.5 mm, see `docs/drivers.md`). Errors: `RJ BADDATA` → `OutOfRange` (or `NotHomed`
//! if `WR`/`WH` is shown), fault flags after a move → `DeviceFault` with the flag's code
//! ([`Warning::code`]), silence → `Timeout`, closed socket → `Disconnected`.
//!
//! ## Simulator
//! ```no_run
//! use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig, sim::{SimConfig, ZaberSim}};
//! use vatcal_hardware_traits::{LinearAxis, MotionOptions};
//! use std::time::Duration;
//!
//! let sim = ZaberSim::start(SimConfig::fast(10.0))?;
//! let mut guide = ZaberAxis::connect_tcp(sim.addr(), ZaberConfig::default())?;
//! guide.home(Duration::from_secs(30))?;
//! guide.move_absolute_and_wait(120.0, &MotionOptions::default())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod codec;
pub mod driver;
pub mod error;
pub mod sim;
pub mod transport;

pub use codec::{Command, LineDeframer, LineEnding, Message, Reply, Warning};
pub use driver::{AxisInfo, MicrostepSize, TCP_PORT_CHAIN, TCP_PORT_DEVICE_ONLY, ZaberAxis, ZaberConfig};
pub use error::ZaberError;
pub use transport::Transport;
