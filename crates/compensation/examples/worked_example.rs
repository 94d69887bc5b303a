//! The worked example of `docs/compensation.md`.
//!
//! Writes a stand-in calibrated cell file (the canonical cell with realistic errors of the
//! virtual cell, `vatcal_sim::truth::perturbed_truth`, seed 4) to the path given as the first
//! argument (default `calibrated-example.toml`), then compensates the first pose of
//! `fixtures/compensate-poses.csv` and prints every intermediate number.
//!
//! ```text
//! cargo run -p vatcal-compensation --example worked_example -- /tmp/calibrated-example.toml
//! ```
//!
//! With a second argument naming another fixture (e.g. `ur5e.toml`), it only writes that
//! fixture's stand-in calibrated file (same errors budget and seed) for the any-chain example.

use vatcal_compensation::{Compensator, PoseRequest, SolveOptions, rotation_to_euler_xyz_deg};
use vatcal_core::{CellFile, MeasurementContext};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "calibrated-example.toml".into());
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/");
    if let Some(fixture) = std::env::args().nth(2) {
        let nominal = Model::from_cell(&CellFile::load(format!("{root}{fixture}"))?)?;
        perturbed_truth(&nominal, 4, &ErrorBudget::realistic()).to_cell().save(&out)?;
        println!("stand-in calibrated {fixture} written to {out}");
        return Ok(());
    }
    let nominal = Model::from_cell(&CellFile::load(format!("{root}meca500-zaber.toml"))?)?;
    perturbed_truth(&nominal, 4, &ErrorBudget::realistic()).to_cell().save(&out)?;
    let calibrated = Model::from_cell(&CellFile::load(&out)?)?;
    println!("calibrated cell written to {out}");

    // first row of fixtures/compensate-poses.csv
    let request = PoseRequest::on_guide(2, 100.0, [60.0, -40.0, 40.0], [180.0, 0.0, 0.0]);
    println!("request: {request:?}");
    let target = request.tool_target(&calibrated, 0)?;
    println!("tool-changer frame wanted (world): p = {:?} mm", target.tool.p.as_slice());
    let comp = Compensator::new(&calibrated, &nominal)?;
    let c = comp.compensate_pose(&request, None, &SolveOptions::default())?;
    println!("compensated q1..q7 (mm, deg): {:?}", c.q.to_mm_deg());
    println!(
        "branch {} | residual {:.3e} mm, {:.3e} deg | {} Newton iterations",
        c.branch,
        c.position_residual_mm,
        c.rotation_residual_rad.to_degrees(),
        c.iterations
    );
    let uncompensated = Compensator::new(&nominal, &nominal)?.compensate_pose(
        &request,
        Some(&c.q),
        &SolveOptions::default(),
    )?;
    println!("uncompensated (nominal IK) q1..q7: {:?}", uncompensated.q.to_mm_deg());
    let true_miss = calibrated.tcp_position(&uncompensated.q, 2)? - nalgebra::Vector3::from(request.xyz_mm);
    println!(
        "the nominal joints would put the TCP {:.4} mm off (calibrated model): {:?}",
        true_miss.norm(),
        true_miss.as_slice()
    );
    let corrected = comp.corrected_pose(&c.q, 2, MeasurementContext::default())?;
    println!("corrected world pose (--emit poses): {:?}", corrected.world);
    println!("MoveJoints{:?}", corrected.controller_joints_deg.unwrap_or_default());
    println!("MovePose{:?}", corrected.controller_pose.unwrap_or_default());
    let abc = rotation_to_euler_xyz_deg(&target.tool.r);
    println!("check: Euler angles of the wanted tool frame {abc:?}");
    Ok(())
}
