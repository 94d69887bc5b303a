//! The Sylvac gauge driver talking to its own simulator on 127.0.0.1, and three of them
//! forming the TriCal 3D probe.
//!
//! Starts three simulated gauges (ephemeral TCP ports), connects the driver to each as it
//! would connect to a real gauge over a serial-to-TCP bridge (`SylvacGauge::connect_tcp`) or a
//! serial port, sets the plungers, reads them, and combines the three readings into a 3D
//! offset with `TriCal`. The simulators stop when dropped.
//!
//! ```text
//! cargo run -p vatcal-drivers-sylvac --example sylvac_sim
//! ```

use vatcal_drivers_sylvac::sim::{SimConfig, SylvacSim};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_hardware_traits::{Gauge, Probe3d, TriCal, TriCalConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sims = [
        SylvacSim::start(SimConfig::default())?,
        SylvacSim::start(SimConfig::default())?,
        SylvacSim::start(SimConfig::default())?,
    ];
    let mut gauge = SylvacGauge::connect_tcp(sims[0].addr(), SylvacConfig::default())?;
    println!("gauge on {}: id {}, unit {:?}", sims[0].addr(), gauge.id(), gauge.unit());
    for mm in [0.0, 1.2345, 6.35] {
        sims[0].set_plunger_mm(mm);
        println!("  plunger at {mm} mm reads {} mm", gauge.read_mm()?);
    }
    drop(gauge);

    // the TriCal probe: preset with the master ball seated, then a 1-inch ball offset by c
    let gauges = [0, 1, 2].map(|i| SylvacGauge::connect_tcp(sims[i].addr(), SylvacConfig::default()));
    let [g1, g2, g3] = gauges;
    let mut probe = TriCal::new([g1?, g2?, g3?], TriCalConfig::new(Vec::new()))?;
    let master = [8.0, 8.5, 9.0];
    for (s, p) in sims.iter().zip(master) {
        s.set_plunger_mm(p);
    }
    probe.preset_master()?;
    let c = [0.12, -0.3, 0.05];
    for ((s, p), ci) in sims.iter().zip(master).zip(c) {
        s.set_plunger_mm(p - 6.35 + ci); // plunger_i = master_i - 6.35 + c_i
    }
    let reading = probe.read()?;
    println!(
        "gauges read {:?} mm -> ball offset {:.4?} mm (set: {c:?})",
        reading.gauges_mm,
        reading.offset_mm.as_slice()
    );
    let err = reading.offset_mm.iter().zip(c).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    if err > 1e-9 {
        return Err(format!("TriCal offset off by {err} mm").into());
    }
    Ok(())
}
