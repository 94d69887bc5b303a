//! Implementing a device trait: a gauge of your own, used as a TriCal 3D probe.
//!
//! Campaign code sees only the traits of this crate. This example implements [`Gauge`] for a
//! hand-driven dial (a struct holding a plunger position), with the out-of-range error the
//! trait requires, builds a [`TriCal`] probe from three of them, and reads a ball offset
//! through the [`Probe3d`] trait object — exactly what `vatcal-campaign` does with real or
//! simulated gauges.
//!
//! ```text
//! cargo run -p vatcal-hardware-traits --example own_gauge
//! ```

use vatcal_hardware_traits::{Error, ErrorKind, Gauge, Probe3d, Result, TriCal, TriCalConfig};

/// A dial gauge whose plunger the example moves by hand.
#[derive(Debug, Default)]
struct HandGauge {
    plunger_mm: f64,
    preset_offset_mm: f64,
}

impl Gauge for HandGauge {
    fn read_mm(&mut self) -> Result<f64> {
        if !(0.0..=12.5).contains(&self.plunger_mm) {
            return Err(Error::new(
                ErrorKind::OutOfRange,
                "hand gauge",
                format!("plunger at {} mm", self.plunger_mm),
            ));
        }
        Ok(self.plunger_mm + self.preset_offset_mm)
    }

    fn preset_mm(&mut self, value_mm: f64) -> Result<()> {
        self.preset_offset_mm = value_mm - self.plunger_mm;
        Ok(())
    }
}

fn main() -> std::result::Result<(), Box<dyn std::error::Error>> {
    let gauges = [HandGauge::default(), HandGauge::default(), HandGauge::default()];
    let mut trical = TriCal::new(gauges, TriCalConfig::new(Vec::new()))?;
    // with the master ball seated the plungers sit mid-travel; preset them
    let master = [8.0, 8.5, 9.0];
    // TriCal owns the gauges; hand them back to move the plungers, then rebuild
    let mut gauges = trical.into_gauges();
    for (g, m) in gauges.iter_mut().zip(master) {
        g.plunger_mm = m;
    }
    trical = TriCal::new(gauges, TriCalConfig::new(Vec::new()))?;
    trical.preset_master()?;
    // a 1-inch ball 0.1 mm off along x, -0.2 mm along y
    let mut gauges = trical.into_gauges();
    for ((g, m), c) in gauges.iter_mut().zip(master).zip([0.1, -0.2, 0.0]) {
        g.plunger_mm = m - 6.35 + c;
    }
    let mut probe: Box<dyn Probe3d> = Box::new(TriCal::new(gauges, TriCalConfig::new(Vec::new()))?);
    let reading = probe.read()?;
    println!(
        "gauges {:?} mm -> ball offset {:.4?} mm, composite {:.4} mm",
        reading.gauges_mm,
        reading.offset_mm.as_slice(),
        reading.composite_mm()
    );
    if (reading.offset_mm.x - 0.1).abs() > 1e-12 || (reading.offset_mm.y + 0.2).abs() > 1e-12 {
        return Err("TriCal did not recover the ball offset".into());
    }

    // a plunger beyond its travel is an error, never a clamped value
    let mut g = HandGauge { plunger_mm: 13.0, preset_offset_mm: 0.0 };
    match g.read_mm() {
        Ok(v) => return Err(format!("read {v} mm beyond the travel").into()),
        Err(e) => println!("refused as expected: {e} (kind {:?})", e.kind()),
    }
    Ok(())
}
