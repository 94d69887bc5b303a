//! A fake Zaber X-LRQ300AP speaking Zaber ASCII on loopback TCP (protocols.md §2.8).
//!
//! [`ZaberSim::start`] binds [`SimConfig::bind`] (default `127.0.0.1:0`) and serves from one
//! background thread until the [`ZaberSim`] is dropped. What it models:
//!
//! * line parser accepting CR, LF or CRLF; optional checksum (verified; a line with a wrong
//!   checksum is ignored, \[UNC\]; replies carry a checksum when the command had one); message
//!   id echo; address 0 = broadcast, other addresses are silent; axis 0 or 1 (`BADAXIS`
//!   otherwise); nothing is sent on connect;
//! * state: position \[microsteps\], busy, homed, warning flags (`WR` after power-up), limits,
//!   `maxspeed`, `accel`, `comm.alert`, `resolution`, device id / serial / version;
//! * commands: status poll, `home`, `move abs|rel`, `stop`, `estop`, `get`/`set` of the
//!   modelled settings, `warnings [clear]`, `system reset`, `driver disable|enable`; anything
//!   else → `RJ … BADCOMMAND`; bad values and targets → `BADDATA`; moves before homing →
//!   `BADDATA` (configurable);
//! * trapezoidal motion from `maxspeed`/`accel` (µsteps/s = maxspeed / 1.6384, µsteps/s² =
//!   accel × 10000 / 1.6384, both \[UNC\]); `NI` when a move is interrupted; alerts
//!   `!AA 1 IDLE WARN` when enabled;
//! * fault injection: [`ZaberSim::inject_stall`] (`FS`), [`ZaberSim::inject_limit_hit`]
//!   (`WL`), [`ZaberSim::set_stalled`] (no answers), [`ZaberSim::drop_clients`].
//!
//! Several TCP clients may be connected at once (like the chain port 55550).

mod device;
mod server;

use std::net::{Ipv4Addr, SocketAddr};
use std::sync::Arc;

use vatcal_hardware_traits::{Clock, SystemClock};

pub use device::{ACCEL_UNIT_FACTOR, SPEED_UNIT_DIVISOR, SimDevice, SimState};
pub use server::ZaberSim;

use crate::driver::{DEFAULT_LEAD_MM, DEFAULT_RESOLUTION, FULL_STEPS_PER_REV};

/// A physical world behind the simulated axis (e.g. the whole virtual cell of
/// `vatcal sim-cell`), told about every motion. Called while the simulator holds its own lock:
/// an implementation must not call back into the [`ZaberSim`].
pub trait AxisBackend: Send + Sync + std::fmt::Debug {
    /// A motion (move or homing) from `from_microsteps` to `to_microsteps` starts.
    fn motion_started(&self, from_microsteps: f64, to_microsteps: f64);

    /// The same with the `maxspeed` the motion runs at (the driver may set it back when the
    /// motion has ended); the default forwards to [`AxisBackend::motion_started`].
    fn motion_started_at(&self, from_microsteps: f64, to_microsteps: f64, maxspeed: i64) {
        let _ = maxspeed;
        self.motion_started(from_microsteps, to_microsteps);
    }
}

/// Simulator settings.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// device address in the (one-device) chain
    pub address: u8,
    /// microstep size \[mm\] (default: the driver's default lead / (200 × 64), \[UNC\])
    pub microstep_mm: f64,
    /// nominal travel \[mm\] (`limit.max` = travel / microstep)
    pub travel_mm: f64,
    /// `resolution` setting (microsteps per full step)
    pub resolution: u32,
    /// initial `maxspeed` [device units]
    pub maxspeed: i64,
    /// initial `accel` [device units]
    pub accel: i64,
    /// position after power-up \[microsteps\] (unknown to the host until homed)
    pub power_up_microsteps: i64,
    /// start already homed (skip the `WR` phase)
    pub start_homed: bool,
    /// refuse `move` before `home` with `BADDATA` (\[UNC\]: some firmware may accept)
    pub reject_move_before_home: bool,
    /// every duration is divided by this
    pub time_scale: f64,
    /// `get deviceid`
    pub device_id: u32,
    /// `get system.serial`
    pub serial: u32,
    /// `get version`
    pub version: String,
    /// `get version.build`
    pub version_build: u32,
    /// time source
    pub clock: Arc<dyn Clock>,
    /// address to listen on (port 0: ephemeral)
    pub bind: SocketAddr,
    /// the physical world behind the axis, if any
    pub backend: Option<Arc<dyn AxisBackend>>,
}

impl SimConfig {
    /// `limit.max` in microsteps.
    pub fn limit_max_microsteps(&self) -> i64 {
        (self.travel_mm / self.microstep_mm).round() as i64
    }

    /// Device speed units for `mm_per_s`.
    pub fn maxspeed_for(mm_per_s: f64, microstep_mm: f64) -> i64 {
        (mm_per_s / microstep_mm * SPEED_UNIT_DIVISOR).round() as i64
    }

    /// Device acceleration units for `mm_per_s2`.
    pub fn accel_for(mm_per_s2: f64, microstep_mm: f64) -> i64 {
        (mm_per_s2 / microstep_mm / ACCEL_UNIT_FACTOR).round().max(1.0) as i64
    }

    /// The default device running `scale` times faster than real time.
    pub fn fast(scale: f64) -> Self {
        Self { time_scale: scale, ..Self::default() }
    }
}

impl Default for SimConfig {
    /// Address 1, 300 mm travel, microstep 2.5 mm / (200 × 64), 20 mm/s, 200 mm/s², unhomed
    /// at 0, real time, an ephemeral port on 127.0.0.1, no backend.
    fn default() -> Self {
        let microstep_mm = DEFAULT_LEAD_MM / (FULL_STEPS_PER_REV * f64::from(DEFAULT_RESOLUTION));
        Self {
            address: 1,
            microstep_mm,
            travel_mm: 300.0,
            resolution: DEFAULT_RESOLUTION,
            maxspeed: Self::maxspeed_for(20.0, microstep_mm),
            accel: Self::accel_for(200.0, microstep_mm),
            power_up_microsteps: 0,
            start_homed: false,
            reject_move_before_home: true,
            time_scale: 1.0,
            device_id: 50_000,
            serial: 12_345,
            version: "7.38".to_owned(),
            version_build: 12_345,
            clock: Arc::new(SystemClock),
            bind: (Ipv4Addr::LOCALHOST, 0).into(),
            backend: None,
        }
    }
}
