//! From a devices file to connected trait objects.
//!
//! Parses `fixtures/devices-example.toml` (the paper's cell on a lab network) and prints what it
//! describes; shows that a mistake is refused before anything connects; then starts the three
//! drivers' protocol simulators on 127.0.0.1, writes a devices file pointing at them, connects
//! it ([`DevicesFile::connect`]) and uses the devices only through the trait objects — as
//! `vatcal campaign --devices FILE` does.
//!
//! ```text
//! cargo run -p vatcal-devices --example connect_devices
//! ```

use std::time::Duration;

use vatcal_devices::DevicesFile;
use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig as MecaSim};
use vatcal_drivers_sylvac::sim::{SimConfig as SylvacSimConfig, SylvacSim};
use vatcal_drivers_zaber::sim::{SimConfig as ZaberSimConfig, ZaberSim};
use vatcal_hardware_traits::{ArmJoints, MotionOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let example =
        DevicesFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/devices-example.toml"))?;
    println!("{}: {example:#?}", example.source().display());

    match DevicesFile::parse("arm = { kind = \"meca500\", address = \"192.168.0.100\" }\n", "typo.toml") {
        Ok(_) => return Err("a file without a guide and gauges must be refused".into()),
        Err(e) => println!("refused as expected: {e}"),
    }

    // the three protocol simulators, on ephemeral ports
    let meca = Meca500Sim::start(MecaSim::fast(20.0))?;
    let zaber = ZaberSim::start(ZaberSimConfig::fast(50.0))?;
    let gauges = [
        SylvacSim::start(SylvacSimConfig::default())?,
        SylvacSim::start(SylvacSimConfig::default())?,
        SylvacSim::start(SylvacSimConfig::default())?,
    ];
    let text = format!(
        "arm = {{ kind = \"meca500\", address = \"{}\" }}\n\
         guide = {{ kind = \"zaber\", tcp = \"{}\" }}\n\
         gauges = [\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n]\n",
        meca.control_addr(),
        zaber.addr(),
        gauges[0].addr(),
        gauges[1].addr(),
        gauges[2].addr()
    );
    let file = DevicesFile::parse(&text, "simulators.toml")?;
    let mut devices = file.connect()?;
    for line in &devices.found {
        println!("found: {line}");
    }
    let timeout = Duration::from_secs(10);
    let fast = MotionOptions { speed_fraction: 1.0, timeout };
    devices.arm.activate_and_home(timeout)?;
    let Some(guide) = devices.guide.as_mut() else { return Err("the file names a guide".into()) };
    guide.home(timeout)?;
    guide.move_absolute_and_wait(75.0, &fast)?;
    devices
        .arm
        .move_joints_and_wait(&ArmJoints::from_deg_array([0.0, -20.0, 20.0, 0.0, 30.0, 0.0]), &fast)?;
    gauges[1].set_plunger_mm(2.5);
    println!(
        "guide at {} mm, arm at {:.3?} deg, gauge 2 reads {} mm",
        guide.position_mm()?,
        devices.arm.joints()?.to_deg(),
        devices.gauges[1].read_mm()?
    );
    Ok(())
}
