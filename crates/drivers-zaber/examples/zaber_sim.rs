//! The Zaber linear-guide driver talking to its own ASCII-protocol simulator on 127.0.0.1.
//!
//! Starts the simulated X-LRQ300AP (ephemeral TCP port, 50× fast motion), connects the driver
//! as it would connect to a real device (`ZaberAxis::connect_tcp(..)` or
//! `ZaberAxis::open_serial("/dev/ttyUSB0", 115_200, ..)`), reads the axis identity, homes,
//! moves to 120 mm and reads the position back. The simulator stops when dropped.
//!
//! ```text
//! cargo run -p vatcal-drivers-zaber --example zaber_sim
//! ```

use std::time::Duration;

use vatcal_drivers_zaber::sim::{SimConfig, ZaberSim};
use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::{LinearAxis, MotionOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sim = ZaberSim::start(SimConfig::fast(50.0))?;
    println!("simulated Zaber device listening on {}", sim.addr());
    let config = ZaberConfig { poll_interval: Duration::from_millis(5), ..ZaberConfig::default() };
    let mut guide = ZaberAxis::connect_tcp(sim.addr(), config)?;
    let info = *guide.info();
    println!(
        "axis: resolution {}, microstep {:.6} µm, travel {:?} mm",
        info.resolution,
        info.microstep_mm * 1e3,
        info.travel_mm()
    );

    println!("homed before homing: {}", guide.is_homed()?);
    guide.home(Duration::from_secs(10))?;
    let options = MotionOptions { speed_fraction: 1.0, timeout: Duration::from_secs(10) };
    guide.move_absolute_and_wait(120.0, &options)?;
    let at = guide.position_mm()?;
    println!("position read back: {at} mm ({} microsteps)", guide.mm_to_microsteps(at));
    if (at - 120.0).abs() > info.microstep_mm {
        return Err(format!("guide at {at} mm, commanded 120 mm").into());
    }
    Ok(())
}
