//! The whole virtual cell over TCP, driven by the real drivers.
//!
//! Starts a [`SimCell`] (the cell of `vatcal demo --seed 3`, noise off, 1000× fast, ephemeral
//! ports on 127.0.0.1), connects the Meca500, Zaber and Sylvac drivers to it exactly as to the
//! real devices, places the probe plate through the cell-control port (the operator), moves the
//! guide and the arm to a probe pose, and reads the three gauges (the plungers follow the
//! hidden true ball against the true probe plate; `vatcal campaign` presets them with the
//! master ball and auto-centres from there).
//!
//! ```text
//! cargo run -p vatcal-sim-cell --example drive_over_tcp
//! ```

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::Duration;

use vatcal_drivers_meca500::{Meca500, Meca500Config};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::{Gauge, JointLayout, LinearAxis, MotionOptions, RobotArm};
use vatcal_sim_cell::{Ports, SimCell, SimCellOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let options = SimCellOptions {
        ports: Ports::ephemeral(),
        noise: false,
        time_scale: 1000.0,
        ..SimCellOptions::paper(3)?
    };
    let sim = SimCell::start(options)?;
    let addrs = sim.addrs();
    for (name, addr) in addrs.named() {
        println!("{name:>20} on {addr}");
    }

    let timeout = Duration::from_secs(20);
    let mut arm = Meca500::connect_tcp(addrs.meca500_control, Meca500Config::default())?;
    let mut guide = ZaberAxis::connect_tcp(
        addrs.zaber.ok_or("the canonical cell has a guide")?,
        ZaberConfig { poll_interval: Duration::from_millis(2), ..ZaberConfig::default() },
    )?;
    let mut gauges = Vec::new();
    for g in addrs.gauges {
        gauges.push(SylvacGauge::connect_tcp(g, SylvacConfig::default())?);
    }
    arm.activate_and_home(timeout)?;
    guide.home(timeout)?;

    // a nominal pose that puts a TCP on a calibration position
    let nominal = sim.cell().nominal();
    let pose = vatcal_sim::truth::probe_start_poses(&nominal, 30, 11)
        .into_iter()
        .find(|m| vatcal_sim::translation_joint_gain(&nominal, &m.q).is_some_and(|g| g < 0.03))
        .ok_or("no well-conditioned start pose")?;
    let position = pose.position().ok_or("a probe pose")?;

    // the operator places the plate: one text line on the cell-control port
    let mut control = TcpStream::connect(addrs.control)?;
    control.set_read_timeout(Some(timeout))?;
    control.write_all(format!("PLACE {position}\n").as_bytes())?;
    let mut answer = String::new();
    BufReader::new(control.try_clone()?).read_line(&mut answer)?;
    println!("cell control: {}", answer.trim_end());

    let fast = MotionOptions { speed_fraction: 1.0, timeout };
    guide.move_absolute_and_wait(pose.q.guide_mm(), &fast)?;
    arm.move_joints_and_wait(&JointLayout::MECA500_ON_GUIDE.arm(&pose.q), &fast)?;
    let readings: Vec<f64> = gauges.iter_mut().map(|g| g.read_mm()).collect::<Result<_, _>>()?;
    println!("TCP {} at calibration position {position}: raw gauge readings {readings:?} mm", pose.tcp);
    Ok(())
}
