//! [`VirtualCell`]: the simulated robot arm (+ guide, when the chain has one) + TriCal +
//! tracker + operator, sharing one hidden true model and one virtual clock.

use std::sync::{Arc, Mutex};

use nalgebra::Vector3;
use vatcal_core::JointVector;
use vatcal_hardware_traits::{JointLayout, TriCal, TriCalConfig, VirtualClock};
use vatcal_kinematics::Model;

use crate::config::{SimConfig, SimFaults};
use crate::devices::{Shared, SimArm, SimGauge, SimGuide, SimOperator, SimThermometer, SimTracker};
use crate::truth::{ErrorBudget, perturbed_truth};
use crate::world::World;

/// A virtual cell of any serial chain: the simulated arm has the chain's arm joints and the
/// guide exists only when the chain has one ([`JointLayout`] of the nominal model: the
/// canonical cell is the Meca500 on its guide, `fixtures/ur5e.toml` a six-axis arm alone).
///
/// * The **truth** (a [`Model`], e.g. from [`perturbed_truth`], possibly with catalog effects)
///   decides where the balls physically are; the **nominal** model is what the simulated robot
///   controller believes (relative linear moves are solved on it) and where the probe
///   placements are configured.
/// * Noise follows [`SimConfig::noise`] (the paper's budget by default) and is derived from
///   `(seed, command, state)` only — see the `noise` module — so the same commands from the
///   same state always give the same result, even across processes.
/// * Time is virtual ([`VirtualClock`]): motions, readings and the operator advance it.
///
/// Devices are cheap handles on the shared state; create as many as needed. The `true_*`
/// methods are oracles for tests and reports — campaign code must not use them.
#[derive(Debug, Clone)]
pub struct VirtualCell {
    pub(crate) shared: Shared,
}

impl VirtualCell {
    /// A cell whose physics is `truth`, whose controller believes `nominal`, with a fresh
    /// virtual clock at zero.
    pub fn new(nominal: Model, truth: Model, config: SimConfig, seed: u64) -> Self {
        Self::with_clock(nominal, truth, config, seed, VirtualClock::new())
    }

    /// Like [`VirtualCell::new`] on a given clock (e.g. one that resumes at a later time).
    pub fn with_clock(
        nominal: Model,
        truth: Model,
        config: SimConfig,
        seed: u64,
        clock: VirtualClock,
    ) -> Self {
        let world = World::new(nominal, truth, config, seed, clock.clone());
        Self { shared: Shared { world: Arc::new(Mutex::new(world)), clock } }
    }

    /// The paper's cell: truth = [`perturbed_truth`]`(nominal, seed, ErrorBudget::realistic())`,
    /// default [`SimConfig`] with the timing of the nominal cell file's motion limits.
    pub fn paper(nominal: Model, seed: u64) -> Self {
        let truth = perturbed_truth(&nominal, seed, &ErrorBudget::realistic());
        let config = SimConfig::paper_for(&nominal);
        Self::new(nominal, truth, config, seed)
    }

    /// The simulated robot arm.
    pub fn arm(&self) -> SimArm {
        SimArm { shared: self.shared.clone() }
    }

    /// The simulated linear guide, when the chain has one (`None` otherwise).
    pub fn guide(&self) -> Option<SimGuide> {
        self.layout().has_guide().then(|| SimGuide { shared: self.shared.clone() })
    }

    /// How the cell's joints split into the guide and the arm (from the nominal model).
    pub fn layout(&self) -> JointLayout {
        self.shared.lock().layout
    }

    /// The three simulated gauges of the TriCal.
    pub fn gauges(&self) -> [SimGauge; 3] {
        [0, 1, 2].map(|index| SimGauge { shared: self.shared.clone(), index })
    }

    /// The TriCal configuration a campaign would use: nominal orthogonal axes, ±range, and the
    /// three trihedral placements rotated about the tank axis toward each nominal calibration
    /// position.
    pub fn probe_config(&self) -> TriCalConfig {
        let w = self.shared.lock();
        let mut c = TriCalConfig::new(w.nominal_placements.clone());
        c.range_mm = w.config.gauge_range_mm;
        c
    }

    /// The TriCal built from [`VirtualCell::gauges`] and [`VirtualCell::probe_config`]; fails
    /// only if the configured gauge range is not positive.
    pub fn probe(&self) -> vatcal_hardware_traits::Result<TriCal<SimGauge>> {
        TriCal::new(self.gauges(), self.probe_config())
    }

    /// The simulated laser tracker.
    pub fn tracker(&self) -> SimTracker {
        SimTracker { shared: self.shared.clone() }
    }

    /// The simulated thermometer, when the cell has a temperature channel
    /// ([`CellPhysics::thermal`](crate::CellPhysics::thermal)); `None` otherwise (a cell
    /// without a thermometer records no `temperature_c`).
    pub fn thermometer(&self) -> Option<SimThermometer> {
        let has_channel = self.shared.lock().config.physics.thermal.is_some();
        has_channel.then(|| SimThermometer { shared: self.shared.clone() })
    }

    /// The simulated operator.
    pub fn operator(&self) -> SimOperator {
        SimOperator { shared: self.shared.clone() }
    }

    /// The cell's clock (shared by every device).
    pub fn clock(&self) -> VirtualClock {
        self.shared.clock.clone()
    }

    /// Replaces the injected faults.
    pub fn set_faults(&self, faults: SimFaults) {
        self.shared.lock().config.faults = faults;
    }

    /// The configuration.
    pub fn config(&self) -> SimConfig {
        self.shared.lock().config
    }

    /// The nominal model (what the controller believes).
    pub fn nominal(&self) -> Model {
        self.shared.lock().nominal.clone()
    }

    /// Oracle: the hidden true model.
    pub fn truth(&self) -> Model {
        self.shared.lock().truth.clone()
    }

    /// Oracle: the context the true model sees now (approach directions, virtual time, the
    /// true cell temperature when the cell has a temperature channel).
    pub fn context(&self) -> vatcal_core::MeasurementContext {
        self.shared.lock().context()
    }

    /// Oracle: the true world position of ball `tcp` now (with all physical errors) \[mm\].
    pub fn true_ball_position_mm(&self, tcp: u32) -> Option<Vector3<f64>> {
        self.shared.lock().ball_world(tcp)
    }

    /// Oracle: true offset of ball `tcp` from the true probe origin of the current plate
    /// placement, in world axes \[mm\]; `None` without a plate.
    pub fn true_ball_offset_mm(&self, tcp: u32) -> Option<Vector3<f64>> {
        let w = self.shared.lock();
        let origin = w.truth.position(w.plate?)?;
        Some(w.ball_world(tcp)? - origin)
    }

    /// Oracle: where the joints physically are (guide including its repeatability error).
    pub fn physical_joints(&self) -> JointVector {
        self.shared.lock().physical_joints()
    }

    /// Oracle: sign of the last motion of each arm joint (J1..; cell joints 2..7 on the
    /// canonical cell; 0 = never moved), as the truth's backlash effect sees it.
    pub fn motion_directions(&self) -> Vec<i8> {
        self.shared.lock().arm_dirs().to_vec()
    }

    /// Oracle: the world displacements requested by every relative linear move so far \[mm\].
    pub fn linear_moves(&self) -> Vec<Vector3<f64>> {
        self.shared.lock().linear_moves.clone()
    }

    /// Oracle: the calibration position the plate is at.
    pub fn plate_position(&self) -> Option<u32> {
        self.shared.lock().plate
    }
}
