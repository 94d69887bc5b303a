//! The virtual cell: a hidden true robot behind simulated devices.
//!
//! Builds a hidden truth (the canonical nominal with realistic random errors, seed 5), wraps it
//! in a [`VirtualCell`] with the paper's noise budget, homes the simulated arm and guide through
//! the device traits, moves to a pose, and reads the simulated laser tracker. The nominal model
//! (what the controller believes) misses the true position by about a millimetre — the error
//! a calibration removes. Synthetic probe data without devices comes from [`truth`].
//!
//! ```text
//! cargo run -p vatcal-sim --example virtual_cell
//! ```

use std::time::Duration;

use vatcal_core::{CellFile, JointVector};
use vatcal_hardware_traits::{Clock, JointLayout, LinearAxis, MotionOptions, PositionTracker, RobotArm};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
};
use vatcal_sim::{SimConfig, VirtualCell};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell_file =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let nominal = Model::from_cell(&cell_file)?;
    let truth = perturbed_truth(&nominal, 5, &ErrorBudget::realistic());
    let cell = VirtualCell::new(nominal.clone(), truth.clone(), SimConfig::default(), 5);

    let (mut arm, mut guide, mut tracker) =
        (cell.arm(), cell.guide().expect("the canonical cell has a guide"), cell.tracker());
    arm.activate_and_home(Duration::from_secs(60))?;
    guide.home(Duration::from_secs(60))?;
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    let options = MotionOptions::default();
    guide.move_absolute_and_wait(q.guide_mm(), &options)?;
    arm.move_joints_and_wait(&JointLayout::MECA500_ON_GUIDE.arm(&q), &options)?;

    let tcp = 1;
    let measured = tracker.measure_mm(tcp)?;
    let believed = nominal.tcp_position(&q, tcp)?;
    let true_p = truth.tcp_position(&q, tcp)?;
    println!("virtual time after homing and moving: {:?}", cell.clock().now());
    println!("tracker reads TCP {tcp} at {:.4?} mm", measured.as_slice());
    println!(
        "nominal model predicts  {:.4?} mm: {:.4} mm off",
        believed.as_slice(),
        (believed - measured).norm()
    );
    println!(
        "hidden truth gives      {:.4?} mm: {:.4} mm off (tracker noise)",
        true_p.as_slice(),
        (true_p - measured).norm()
    );

    // synthetic probe measurements straight from the truth (no device simulation)
    let starts = probe_start_poses(&nominal, 6, 1);
    let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise::default(), 2);
    for m in &probe {
        println!(
            "probe measurement: position {:?}, TCP {}, nominal residual {:.4} mm",
            m.position(),
            m.tcp,
            nominal.residual(m)?.norm()
        );
    }
    Ok(())
}
