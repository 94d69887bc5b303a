//! The whole simulated calibration in one call, at small sizes.
//!
//! [`run_demo`] plans the measurements, runs the campaign on the virtual cell, identifies the
//! paper's 34 parameters, validates nominal and calibrated models with the simulated laser
//! tracker and writes the report folder. Here with small sizes (120 orientations × 3 guide
//! steps, 40 measurements, 60 random validation poses, a 30-slice path), the `ideal` hidden
//! truth (only the 34 parameters' errors) and no discovery stage, so it runs in seconds;
//! `vatcal demo` runs the paper's sizes.
//!
//! ```text
//! cargo run -p vatcal-demo --example small_demo -- /tmp/small-demo
//! ```

use vatcal_demo::{DemoOptions, DemoSizes, TruthSpec, run_demo};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("vatcal-small-demo"));
    let mut options = DemoOptions::new(11)?;
    options.sizes = DemoSizes { orientations: 120, guide_steps: 3, count: 40, random_poses: 60, slices: 30 };
    options.truth = TruthSpec::Ideal;
    options.discovery = false;
    let outcome = run_demo(&options, &out, &mut |line| println!("{line}"))?;
    println!("{}", outcome.comparison_table());
    let nominal = outcome.validation("nominal").ok_or("nominal validation")?.random.stats.mean;
    let calibrated = outcome.validation("calibrated").ok_or("calibrated validation")?.random.stats.mean;
    println!(
        "random poses: nominal {nominal:.4} mm -> calibrated {calibrated:.4} mm; report in {}",
        out.display()
    );
    if calibrated > 0.1 * nominal {
        return Err("the calibration must cut the mean error by at least 10×".into());
    }
    Ok(())
}
