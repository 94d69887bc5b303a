//! A measurement campaign on the virtual cell: plan, run, journal, resume.
//!
//! Takes 6 well-conditioned probe poses of the canonical cell, makes a [`CampaignPlan`] (plate
//! placements, moves, measurements), and runs it with [`Campaign`] on the simulated devices of
//! `vatcal-sim` (the paper's noise, a hidden true robot): every measurement is auto-centred on
//! the TriCal and journaled. Running the same plan on the same journal again resumes — here
//! there is nothing left to do, so nothing is measured twice. The real cell is the same code
//! with the devices of a devices file (`vatcal-devices`).
//!
//! ```text
//! cargo run -p vatcal-campaign --example run_campaign
//! ```

use vatcal_campaign::{
    Campaign, CampaignConfig, CampaignPlan, CampaignPlanOptions, CellDevices, export_measurements,
};
use vatcal_core::{CellFile, JointVector, Measurement};
use vatcal_hardware_traits::{TriCal, VirtualClock};
use vatcal_kinematics::Model;
use vatcal_sim::truth::probe_start_poses;
use vatcal_sim::{SimArm, SimGauge, SimGuide, SimOperator, SimTracker, VirtualCell, translation_joint_gain};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell_file =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let nominal = Model::from_cell(&cell_file)?;
    let cell = VirtualCell::paper(nominal.clone(), 2024);

    // 6 poses away from singularities, grouped by calibration position
    let mut poses: Vec<Measurement> = probe_start_poses(&nominal, 40, 1)
        .into_iter()
        .filter(|m| translation_joint_gain(&nominal, &m.q).is_some_and(|g| g < 0.03))
        .take(6)
        .collect();
    poses.sort_by_key(|m| m.position());
    let clear = JointVector::from_mm_deg(150.0, [0.0, -30.0, 30.0, 0.0, 0.0, 0.0]);
    let plan =
        CampaignPlan::from_poses(&poses, &CampaignPlanOptions { clear_pose: Some(clear), zero_probe: false });
    println!("plan: {} steps, {} measurements", plan.steps.len(), plan.measurement_count());

    let dir = std::env::temp_dir().join(format!("vatcal-campaign-example-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let journal = dir.join("campaign.journal");
    let config = CampaignConfig { show_progress: false, ..CampaignConfig::default() };
    let mut devices = SimDevices {
        arm: cell.arm(),
        guide: cell.guide().expect("the canonical cell has a guide"),
        probe: cell.probe()?,
        tracker: cell.tracker(),
        operator: cell.operator(),
        clock: cell.clock(),
        thermometer: cell.thermometer(),
    };
    let report = Campaign::new(devices.lend(), &nominal, config.clone()).run(&plan, &journal)?;
    let truth = cell.truth();
    for m in &report.measurements {
        println!(
            "position {:?} TCP {}: t = {:6.1} s, nominal residual {:.4} mm, true residual {:.4} mm",
            m.position(),
            m.tcp,
            m.context.time_s.unwrap_or(f64::NAN),
            nominal.residual(m)?.norm(),
            truth.residual(m)?.norm()
        );
    }

    // the same plan on the same journal: a resume with nothing left to do
    let again = Campaign::new(devices.lend(), &nominal, config).run(&plan, &journal)?;
    println!(
        "second run resumed at step {:?}, {} measurements (none repeated)",
        again.resumed_at_step,
        again.measurements.len()
    );
    if again.measurements != report.measurements {
        return Err("a resumed campaign must return the journaled measurements unchanged".into());
    }
    let csv = dir.join("measurements.csv");
    println!("{} measurements exported to {}", export_measurements(&journal, &csv)?, csv.display());
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}

/// The simulated devices, owned here and lent to each campaign as trait objects.
struct SimDevices {
    arm: SimArm,
    guide: SimGuide,
    probe: TriCal<SimGauge>,
    tracker: SimTracker,
    operator: SimOperator,
    clock: VirtualClock,
    thermometer: Option<vatcal_sim::SimThermometer>,
}

impl SimDevices {
    fn lend(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: Some(&mut self.guide),
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
            thermometer: self.thermometer.as_mut().map(|t| t as &mut dyn vatcal_hardware_traits::Thermometer),
        }
    }
}
