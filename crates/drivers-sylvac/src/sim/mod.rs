//! A fake Sylvac gauge speaking the ASCII command set over loopback TCP (protocols.md §3.5:
//! the byte stream a serial-to-TCP bridge to a duplex cable would carry, identical to the
//! BLE RemoteRequest/RemoteResponse payloads).
//!
//! [`SylvacSim::start`] binds [`SimConfig::bind`] (default `127.0.0.1:0`) — one listener per
//! gauge — and serves from a background thread until dropped. The test moves the plunger with
//! [`SylvacSim::set_plunger_mm`], or a [`PlungerSource`] (a simulated world) decides where it
//! is. Modelled: `?` (value with sign, zero padding and the
//! configured decimals \[UNC\]), `ERR3` beyond the measuring range, `ERR0` on an injected sensor
//! fault, `ERR1` for unknown commands, `PRE ±v` / `PRE ON|OFF` / `PRE?`, `MM`/`IN`/`UNI?`,
//! `UNI0/1`, `STO0/1` (frozen display), `KEY`, `SET?`, `BAT?`, `ID?`, `VER?`, `OUT1`
//! (continuous output every [`SimConfig::output_interval`]), `SVR0/1`; resolution
//! quantisation and seeded Gaussian noise (ChaCha8). Setters are silent by default
//! ([`SimConfig::ack_setters`] makes them answer `OK`).

mod gauge;
mod server;

use std::net::{Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use vatcal_hardware_traits::{Clock, SystemClock};

pub use gauge::{SimGauge, SimState};
pub use server::SylvacSim;

/// Where the plunger physically is, when a world outside the simulator decides it (e.g. the
/// ball of the virtual cell of `vatcal sim-cell` pressing on it). Called on every reading and
/// preset, while the simulator holds its own lock.
pub trait PlungerSource: Send + Sync + std::fmt::Debug {
    /// Plunger position now \[mm\] (0 = fully extended, beyond `0..=range_mm` the gauge
    /// answers `ERR3`), without reading noise.
    fn plunger_mm(&self) -> f64;

    /// Reading error of one reading \[mm\], added to the displayed value before quantisation
    /// (the simulator's own Gaussian noise, if any, is added too).
    fn reading_noise_mm(&self) -> f64 {
        0.0
    }
}

/// Simulator settings.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// `ID?` answer
    pub id: String,
    /// `VER?` answer
    pub version: String,
    /// measuring range \[mm\]: the plunger must stay in `0..=range_mm`, else `ERR3` (\[UNC\] for
    /// the S_Dial WORK Nano)
    pub range_mm: f64,
    /// display resolution \[mm\] (readings are rounded to it)
    pub resolution_mm: f64,
    /// decimals written in mm (inch: one more)
    pub decimals_mm: usize,
    /// standard deviation of the Gaussian reading noise \[mm\]
    pub noise_std_mm: f64,
    /// noise seed
    pub seed: u64,
    /// plunger position at start \[mm\]
    pub initial_plunger_mm: f64,
    /// setters answer `OK` (default: silent, \[UNC\])
    pub ack_setters: bool,
    /// `PRE ±v` only stores the value; `PRE ON` applies it (\[UNC\])
    pub preset_requires_on: bool,
    /// period of the continuous output (`OUT1`)
    pub output_interval: Duration,
    /// time source
    pub clock: Arc<dyn Clock>,
    /// address to listen on (port 0: ephemeral)
    pub bind: SocketAddr,
    /// where the plunger is (overrides [`SylvacSim::set_plunger_mm`]), if a world decides it
    pub plunger: Option<Arc<dyn PlungerSource>>,
    /// start with the preset on so that a plunger at this position \[mm\] reads zero (a gauge
    /// zeroed before the session), instead of displaying the raw plunger position
    pub zeroed_at_mm: Option<f64>,
}

impl Default for SimConfig {
    /// `SY289`, 12.5 mm range, 0.1 µm resolution, 4 decimals, no noise, plunger at 0, silent
    /// setters, continuous output every 100 ms, an ephemeral port on 127.0.0.1, plunger set by
    /// the test, not zeroed.
    fn default() -> Self {
        Self {
            id: "SY289".to_owned(),
            version: "V1.10 01.06.2021".to_owned(),
            range_mm: 12.5,
            resolution_mm: 0.0001,
            decimals_mm: 4,
            noise_std_mm: 0.0,
            seed: 1,
            initial_plunger_mm: 0.0,
            ack_setters: false,
            preset_requires_on: false,
            output_interval: Duration::from_millis(100),
            clock: Arc::new(SystemClock),
            bind: (Ipv4Addr::LOCALHOST, 0).into(),
            plunger: None,
            zeroed_at_mm: None,
        }
    }
}
