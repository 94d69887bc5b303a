//! The line-protocol tracker driver talking to its own simulator on 127.0.0.1.
//!
//! Starts the simulated tracker (ephemeral TCP port), puts an SMR somewhere, connects the
//! driver as it would connect to `vatcal sim-cell`'s tracker or a bridge to a real one, reads
//! it back, then shows the line-of-sight fault. The simulator stops when dropped.
//!
//! ```text
//! cargo run -p vatcal-drivers-tracker --example tracker_sim
//! ```

use nalgebra::Vector3;
use vatcal_drivers_tracker::sim::{SimConfig, TrackerSim};
use vatcal_drivers_tracker::{LineTracker, TrackerConfig};
use vatcal_hardware_traits::PositionTracker;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sim = TrackerSim::start(SimConfig::default())?;
    println!("simulated tracker listening on {}", sim.addr());
    let smr = Vector3::new(812.5, -40.25, 1300.0);
    sim.set_target_mm(2, smr);
    let mut tracker = LineTracker::connect_tcp(sim.addr(), TrackerConfig::default())?;
    println!("tracker: {}", tracker.identity());
    let p = tracker.measure_mm(2)?;
    println!("target 2 at {:.6} {:.6} {:.6} mm", p.x, p.y, p.z);
    if (p - smr).norm() > 1e-6 {
        return Err(format!("read {p}, expected {smr}").into());
    }
    sim.set_line_of_sight(false);
    match tracker.measure_mm(2) {
        Err(e) => println!("with the beam broken: {e}"),
        Ok(p) => return Err(format!("read {p} without line of sight").into()),
    }
    Ok(())
}
