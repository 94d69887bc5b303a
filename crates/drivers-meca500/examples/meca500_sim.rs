//! The Meca500 driver talking to its own protocol simulator over TCP on 127.0.0.1.
//!
//! Starts the simulator (ephemeral port, 20× fast motion), connects the driver exactly as it
//! would connect to a real robot (`Meca500::connect_tcp("192.168.0.100:10000", ..)`),
//! activates and homes, moves the joints, reads them back and reads the pose of the flange.
//! The simulator stops when dropped.
//!
//! ```text
//! cargo run -p vatcal-drivers-meca500 --example meca500_sim
//! ```

use std::time::Duration;

use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig};
use vatcal_drivers_meca500::{Meca500, Meca500Config};
use vatcal_hardware_traits::{ArmJoints, MotionOptions, RobotArm};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sim = Meca500Sim::start(SimConfig::fast(20.0))?;
    println!("simulated Meca500 listening on {}", sim.control_addr());
    let mut robot = Meca500::connect_tcp(sim.control_addr(), Meca500Config::default())?;
    let banner = robot.banner();
    println!("connected: {} firmware {:?}", banner.model, banner.version);

    robot.activate_and_home(Duration::from_secs(10))?;
    println!("status after homing: {:?}", robot.status()?);

    let target = ArmJoints::from_deg_array([10.0, -20.0, 30.0, 5.0, 40.0, -15.0]);
    let options = MotionOptions { speed_fraction: 1.0, timeout: Duration::from_secs(10) };
    robot.move_joints_and_wait(&target, &options)?;
    let q = robot.joints()?;
    println!("joints read back [deg]: {:.4?}", q.to_deg());
    println!("flange pose (x, y, z mm, alpha, beta, gamma deg): {:.3?}", robot.pose_mm_deg()?);
    let diff = q.max_abs_diff(&target);
    if diff > 1e-9 {
        return Err(format!("read-back differs from the target by {diff} rad").into());
    }
    Ok(())
}
