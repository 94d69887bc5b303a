//! Helpers shared by the campaign tests: the paper's virtual cell and small plans.
#![allow(dead_code)]

use vatcal_campaign::{CampaignConfig, CampaignPlan, CellDevices, PlanOptions};
use vatcal_core::{CellFile, JointVector, Measurement};
use vatcal_hardware_traits::{TriCal, VirtualClock};
use vatcal_kinematics::Model;
use vatcal_sim::truth::probe_start_poses;
use vatcal_sim::{SimArm, SimGauge, SimGuide, SimOperator, SimTracker, VirtualCell};

pub fn nominal() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml")).expect("fixture");
    Model::from_cell(&cell).expect("model")
}

/// The paper's virtual cell (realistic truth, paper noise) for `seed`.
pub fn paper_cell(seed: u64) -> VirtualCell {
    VirtualCell::paper(nominal(), seed)
}

/// Owned simulated devices, lent to a campaign as trait objects.
pub struct SimDevices {
    pub arm: SimArm,
    pub guide: SimGuide,
    pub probe: TriCal<SimGauge>,
    pub tracker: SimTracker,
    pub operator: SimOperator,
    pub clock: VirtualClock,
}

impl SimDevices {
    pub fn of(cell: &VirtualCell) -> Self {
        Self {
            arm: cell.arm(),
            guide: cell.guide(),
            probe: cell.probe().expect("probe"),
            tracker: cell.tracker(),
            operator: cell.operator(),
            clock: cell.clock(),
        }
    }

    pub fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: &mut self.guide,
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
        }
    }
}

/// Arm clear of the probe (straight up, guide mid-stroke).
pub fn clear_pose() -> JointVector {
    JointVector::from_mm_deg(150.0, [0.0, -30.0, 30.0, 0.0, 0.0, 0.0])
}

/// `n` nominal measurement poses, grouped by calibration position (1, 2, 3).
pub fn poses(n: usize, seed: u64) -> Vec<Measurement> {
    let mut p = probe_start_poses(&nominal(), n, seed);
    p.sort_by_key(|m| m.position());
    p
}

/// A plan over `n` poses with a clear pose before each plate placement.
pub fn plan(n: usize, seed: u64) -> CampaignPlan {
    CampaignPlan::from_poses(&poses(n, seed), &PlanOptions { clear_pose: Some(clear_pose()), zero_probe: false })
}

pub fn quiet_config() -> CampaignConfig {
    CampaignConfig { show_progress: false, ..CampaignConfig::default() }
}

/// Equal measurement sets: same TCPs, targets, joints bit for bit, same `dir` (times may differ
/// after a restart: they are clock readings).
pub fn assert_same_measurements(a: &[Measurement], b: &[Measurement]) {
    assert_eq!(a.len(), b.len(), "measurement counts differ");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(x.tcp, y.tcp, "measurement {k}: tcp");
        assert_eq!(x.target, y.target, "measurement {k}: target");
        assert_eq!(x.context.dir, y.context.dir, "measurement {k}: dir");
        for j in 0..7 {
            assert_eq!(x.q.0[j].to_bits(), y.q.0[j].to_bits(), "measurement {k}: q{} {} vs {}", j + 1, x.q.0[j], y.q.0[j]);
        }
    }
}
