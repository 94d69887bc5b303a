#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! A [`Gauge`](vatcal_hardware_traits::Gauge) driver for Sylvac digital indicators (the cell's
//! S_Dial WORK Nano Smart) using the Sylvac ASCII command set over a byte transport, the
//! Bluetooth LE payload decoders as pure functions, and a loopback simulator of a gauge.
//! Reference: `docs/drivers.md` and the project's protocol notes (protocols.md §3).
//!
//! ## Layers
//! * [`codec`] — sans-IO: [`Command`] → `TEXT\r`, answer lines → [`Answer`] (value, `ERRn`,
//!   text), lenient value parsing, a CR [`LineDeframer`].
//! * [`ble`] — BLE payloads (Measurement int32 × 10^e, Parameters bitmap, presentation-format
//!   exponent, RemoteResponse reassembly). **No BLE stack is compiled**: btleplug needs D-Bus and
//!   BlueZ; a BLE transport would wrap these decoders behind an off-by-default feature.
//! * [`transport`] — [`Transport`] (TCP, e.g. a serial-to-TCP bridge; the duplex cable with the
//!   `serial` feature: 4800 baud 7E2).
//! * [`driver`] — [`SylvacGauge`] with [`SylvacConfig`].
//! * [`sim`] — [`sim::SylvacSim`], a fake gauge on `127.0.0.1:0` whose plunger a test moves.
//!
//! ## How the trait maps onto the protocol
//! | `Gauge` | wire |
//! |---|---|
//! | connect | `ID?`; `OUT0`; `MM` (forced, configurable); `UNI?` |
//! | `read_mm` | drop pending input, `?` → `+001.2345` (value) / `ERR3` → `OutOfRange` / `ERR0` → `DeviceFault {code: 0}` |
//! | `preset_mm(v)` | `PRE +006.3500` (optionally `PRE ON`), then `?` must read `v` ± 2 µm |
//! | `zero` | `preset_mm(0)` |
//!
//! Units: mm at the trait; an inch display (if not forced to mm) is converted. Timeouts: every
//! query has the configured I/O timeout (500 ms by default); setters listen
//! `setter_ack_window` for an `ERRn`.
//!
//! ## Simulator
//! ```no_run
//! use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge, sim::{SimConfig, SylvacSim}};
//! use vatcal_hardware_traits::Gauge;
//!
//! let sim = SylvacSim::start(SimConfig::default())?;
//! let mut gauge = SylvacGauge::connect_tcp(sim.addr(), SylvacConfig::default())?;
//! sim.set_plunger_mm(3.2);
//! gauge.preset_mm(6.35)?;
//! sim.set_plunger_mm(3.3);
//! assert!((gauge.read_mm()? - 6.45).abs() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod ble;
#[cfg(feature = "ble")]
pub mod ble_link;
pub mod codec;
pub mod driver;
pub mod error;
pub mod sim;
pub mod transport;

#[cfg(feature = "ble")]
pub use ble_link::{BleConfig, BleTarget, BleTransport, SylvacBle};
pub use codec::{Answer, Command, GaugeError, LineDeframer, Unit};
pub use driver::{SylvacConfig, SylvacGauge};
pub use error::SylvacError;
pub use transport::Transport;
