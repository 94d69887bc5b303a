//! Helpers shared by the campaign tests: the paper's virtual cell and small plans.
#![allow(dead_code)]

use vatcal_campaign::{CampaignConfig, CampaignPlan, CampaignPlanOptions, CellDevices};
use vatcal_core::{CellFile, JointVector, Measurement};
use vatcal_hardware_traits::{Thermometer, TriCal, VirtualClock};
use vatcal_kinematics::Model;
use vatcal_sim::truth::probe_start_poses;
use vatcal_sim::{
    SimArm, SimGauge, SimGuide, SimOperator, SimThermometer, SimTracker, VirtualCell, translation_joint_gain,
};

pub fn nominal() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
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
    /// the cell's thermometer, when it has a temperature channel
    pub thermometer: Option<SimThermometer>,
}

impl SimDevices {
    pub fn of(cell: &VirtualCell) -> Self {
        Self {
            arm: cell.arm(),
            guide: cell.guide().expect("the canonical cell has a guide"),
            probe: cell.probe().expect("probe"),
            tracker: cell.tracker(),
            operator: cell.operator(),
            clock: cell.clock(),
            thermometer: cell.thermometer(),
        }
    }

    pub fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: Some(&mut self.guide),
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
            thermometer: self.thermometer.as_mut().map(|t| t as &mut dyn Thermometer),
        }
    }
}

/// Arm clear of the probe (straight up, guide mid-stroke).
pub fn clear_pose() -> JointVector {
    JointVector::from_mm_deg(150.0, [0.0, -30.0, 30.0, 0.0, 0.0, 0.0])
}

/// True when every arm joint is 0.15 rad inside its limits and the arm is away from
/// singularities (at most 0.03 rad of joint motion per mm of translation): a pose a planner
/// would accept for centering.
pub fn well_conditioned(model: &Model, q: &JointVector) -> bool {
    let limits = model.joint_limits();
    let inside = (1..7).all(|k| q[k] > limits[k].0 + 0.15 && q[k] < limits[k].1 - 0.15);
    inside && translation_joint_gain(model, q).is_some_and(|g| g < 0.03)
}

/// `n` well-conditioned nominal measurement poses, grouped by calibration position (1, 2, 3).
pub fn poses(n: usize, seed: u64) -> Vec<Measurement> {
    let model = nominal();
    let mut p: Vec<Measurement> = probe_start_poses(&model, 6 * n, seed)
        .into_iter()
        .filter(|m| well_conditioned(&model, &m.q))
        .take(n)
        .collect();
    assert_eq!(p.len(), n, "not enough well-conditioned poses");
    p.sort_by_key(|m| m.position());
    p
}

/// A plan over `n` poses with a clear pose before each plate placement.
pub fn plan(n: usize, seed: u64) -> CampaignPlan {
    CampaignPlan::from_poses(
        &poses(n, seed),
        &CampaignPlanOptions { clear_pose: Some(clear_pose()), zero_probe: false },
    )
}

pub fn quiet_config() -> CampaignConfig {
    CampaignConfig { show_progress: false, ..CampaignConfig::default() }
}

/// The same measurements up to the CSV's mm/deg round trip (1e-12 relative).
pub fn assert_close_measurements(a: &[Measurement], b: &[Measurement]) {
    assert_eq!(a.len(), b.len(), "measurement counts differ");
    for (x, y) in a.iter().zip(b) {
        assert_eq!(
            (x.tcp, x.target, x.context.dir, x.context.time_s),
            (y.tcp, y.target, y.context.dir, y.context.time_s)
        );
        for j in 0..7 {
            assert!((x.q[j] - y.q[j]).abs() <= 1e-12 * x.q[j].abs().max(1.0));
        }
    }
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
            assert_eq!(
                x.q[j].to_bits(),
                y.q[j].to_bits(),
                "measurement {k}: q{} {} vs {}",
                j + 1,
                x.q[j],
                y.q[j]
            );
        }
    }
}
