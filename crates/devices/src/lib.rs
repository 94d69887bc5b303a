#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The **devices file** (TOML, `docs/formats.md`): which driver implements each device trait
//! of `vatcal-hardware-traits`, where the device is, and the driver's timeouts.
//!
//! ```toml
//! arm = { kind = "meca500", address = "192.168.0.100:10000", monitoring = "192.168.0.100:10001" }
//! guide = { kind = "zaber", tcp = "192.168.0.50:55550" }       # or serial = "/dev/ttyUSB0"
//! gauges = [
//!     { kind = "sylvac", tcp = "192.168.0.60:55561" },          # or serial = "/dev/ttyUSB1"
//!     { kind = "sylvac", tcp = "192.168.0.60:55562" },
//!     { kind = "sylvac", tcp = "192.168.0.60:55563" },
//! ]
//! sim_control = { tcp = "127.0.0.1:55570" }                    # only for `vatcal sim-cell`
//! ```
//!
//! [`DevicesFile::parse`] rejects unknown keys, missing devices, a wrong number of gauges and
//! bad addresses with one error naming the file, the line and the field — before anything
//! connects or moves. [`DevicesFile::connect`] then connects each device with its driver's
//! public API and returns boxed trait objects ([`ConnectedDevices`]), so the calibration
//! pipeline never depends on a driver.
//!
//! [`SimControl`] speaks the cell-control line protocol of `vatcal sim-cell`
//! (`PLACE <n>` → `OK PLACE <n>`, `PLACEMENT?` → `PLACEMENT <n>`); [`SimControlOperator`] is
//! the operator of `vatcal campaign --operator auto`, who re-places the probe plate by telling
//! the simulator; [`SimCellClock`] is that campaign's clock, the simulated cell's virtual time
//! (`TIME?` → `TIME <s>`).
//!
//! An optional `thermometer` records the cell temperature (`temperature_c`) beside every
//! measurement ([`thermometer`]):
//!
//! ```toml
//! thermometer = { kind = "sim-cell" }                                   # `TEMP?` of `vatcal sim-cell` (needs sim_control)
//! thermometer = { kind = "file", path = "/sys/bus/w1/devices/28-0123/temperature", scale = 0.001 }
//! thermometer = { kind = "command", command = ["pt100-read", "--channel", "1"], io_timeout_ms = 3000 }
//! ```

mod file;
mod sim_control;
pub mod thermometer;

pub use file::{
    ArmSpec, ConnectedDevices, DevicesError, DevicesFile, GaugeSpec, GuideSpec, Link, ProbeSpec,
    SimControlSpec, ThermometerSpec, TrackerSpec,
};
pub use sim_control::{SimCellClock, SimControl, SimControlOperator};
pub use thermometer::{CommandThermometer, FileThermometer, SimCellThermometer};
