//! The virtual cell's physics behind **external** motion simulators.
//!
//! In-process, [`SimArm`](crate::SimArm) and [`SimGuide`](crate::SimGuide) own the motions of
//! the cell. Protocol simulators (the Meca500, Zaber and Sylvac servers of `vatcal sim-cell`)
//! own their motions themselves — queues, timing, protocol states — and only need the physics:
//! these methods let them tell the cell where the arm and the guide go, ask the cell's
//! controller model (the nominal one) for a relative linear move, and read the gauges' plunger
//! positions from the true ball against the true probe plate. Truth, probe imperfections,
//! noise budget and noise keys are those of the in-process devices.
//!
//! Protocol: call [`VirtualCell::external_motion_started`] /
//! [`VirtualCell::external_guide_motion_started`] when a motion starts (backlash direction,
//! repeatability draw, noise epoch), and [`VirtualCell::external_sync`] with where the joints
//! are before reading a plunger.

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::{ArmJoints, LinearFrame};

use crate::cell::VirtualCell;
use crate::config::{SimConfig, SimTiming};
use crate::controller::{LinearMoveError, translate_flange, world_displacement};
use crate::noise::{bits, key, uniform};
use crate::world::Motion;

/// Meca500 error code of a move refused for a joint limit.
pub const CODE_JOINT_LIMIT: u16 = 1007;
/// Meca500 error code of a move refused near a singularity.
pub const CODE_SINGULARITY: u16 = 1012;

impl SimConfig {
    /// The configuration of [`VirtualCell::paper`] for the cell `nominal`: the paper's noise
    /// budget and probe imperfections, the timing of the cell file's motion limits.
    pub fn paper_for(nominal: &vatcal_kinematics::Model) -> Self {
        Self { timing: SimTiming::from_motion_limits(&nominal.to_cell().motion_limits()), ..Self::default() }
    }
}

impl VirtualCell {
    /// An external arm motion from `from` to `to` [rad] starts: the backlash direction of every
    /// joint that moves, a fresh repeatability offset and a new noise epoch, keyed on the two
    /// joint vectors like [`SimArm`](crate::SimArm)'s joint moves.
    pub fn external_motion_started(&self, from: &ArmJoints, to: &ArmJoints) {
        let mut w = self.shared.lock();
        let mut parts = bits(&to.0);
        parts.extend(bits(&from.0));
        let event = key(w.seed, "arm-joints", &parts);
        w.arm.motion = Motion::at_rest(from.0);
        w.start_arm_motion(to.0, 1.0, event);
    }

    /// An external guide motion from `from_mm` to `to_mm` starts (homing included): a fresh
    /// repeatability error and a new noise epoch, like [`SimGuide`](crate::SimGuide).
    pub fn external_guide_motion_started(&self, from_mm: f64, to_mm: f64) {
        let mut w = self.shared.lock();
        w.guide.homed = true;
        w.guide.motion = Motion::at_rest([from_mm]);
        w.start_guide_motion(to_mm, 1.0);
    }

    /// Where the external simulators have the joints now (arm [rad], guide as reported [mm]),
    /// and their time: the physics puts the cell there (the guide's repeatability error is
    /// added physically) and the clock forward to `now` (never back).
    pub fn external_sync(&self, arm: &ArmJoints, guide_mm: f64, now: Duration) {
        let mut w = self.shared.lock();
        w.clock.advance_to(now);
        w.arm.motion = Motion::at_rest(arm.0);
        w.guide.motion = Motion::at_rest([guide_mm]);
    }

    /// Joints [rad] that the cell's robot controller (which believes the **nominal** model)
    /// commands for a relative linear move of `translation_mm` in the axes of `frame`, from
    /// `from` with the guide at its last target, exactly as [`SimArm`](crate::SimArm) solves it
    /// (including the injected [`SimFaults::linear_move_gain`](crate::SimFaults)); or the
    /// controller's refusal as a Meca500 `(code, message)`: [`CODE_SINGULARITY`] or
    /// [`CODE_JOINT_LIMIT`].
    pub fn external_linear_target(
        &self,
        from: &ArmJoints,
        translation_mm: &Vector3<f64>,
        frame: LinearFrame,
    ) -> Result<ArmJoints, (u16, String)> {
        let mut w = self.shared.lock();
        if !translation_mm.iter().all(|v| v.is_finite()) {
            return Err((CODE_SINGULARITY, "non-finite displacement".into()));
        }
        let start = from.with_guide(w.guide.motion.to[0]);
        let delta = world_displacement(&w.nominal, &start, translation_mm, frame);
        let executed = delta * w.config.faults.linear_move_gain;
        match translate_flange(&w.nominal, &start, &executed) {
            Ok(q) => {
                w.linear_moves.push(delta);
                Ok(ArmJoints::from_joint_vector(&q))
            }
            Err(LinearMoveError::Singular) => {
                Err((CODE_SINGULARITY, "linear move would cross a singularity".into()))
            }
            Err(LinearMoveError::Limit(joint)) => {
                Err((CODE_JOINT_LIMIT, format!("linear move would put joint {joint} over its limit")))
            }
        }
    }

    /// Noise-free reading of gauge `gauge` (0..3) at the state of the last
    /// [`VirtualCell::external_sync`], relative to the probe's zero at the start of the session
    /// (the master-ball preset the probe came with) [mm]: a simulated gauge whose own zero
    /// sits there displays the in-process reading. `None` when nothing touches the plunger
    /// (it rests on its stop, fully extended).
    pub fn external_plunger_mm(&self, gauge: usize) -> Option<f64> {
        let w = self.shared.lock();
        let plunger = w.plunger_mm(gauge)?;
        Some(plunger - (w.probe.master_radius_mm - vatcal_hardware_traits::TRICAL_MASTER_PRESET_MM))
    }

    /// The reading error of the next reading of gauge `gauge` (uniform within the gauge's
    /// maximum error, keyed on the current noise epoch like the in-process gauges) [mm].
    pub fn external_reading_noise_mm(&self, gauge: usize) -> f64 {
        let mut w = self.shared.lock();
        let max = w.config.noise.gauge_max_error_mm;
        let mut rng = w.reading_rng("gauge", gauge as u64);
        uniform(&mut rng, max)
    }

    /// The arm's joint limits J1..J6 in the controller's (nominal) model [rad].
    pub fn arm_joint_limits(&self) -> [(f64, f64); 6] {
        let limits = self.shared.lock().nominal.joint_limits().to_vec();
        let mut out = [(0.0, 0.0); 6];
        for (o, l) in out.iter_mut().zip(limits.iter().skip(1)) {
            *o = *l;
        }
        out
    }

    /// The guide's stroke in the controller's (nominal) model [mm].
    pub fn guide_limits_mm(&self) -> (f64, f64) {
        self.shared.lock().nominal.joint_limits()[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SimConfig;
    use vatcal_core::CellFile;
    use vatcal_hardware_traits::{Gauge, LinearAxis, MotionOptions, Operator, OperatorInstruction, RobotArm};
    use vatcal_kinematics::Model;

    fn nominal() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    /// The external path reproduces the in-process devices exactly (same commands, noise off).
    #[test]
    fn external_drive_matches_the_in_process_devices() {
        let nominal = nominal();
        let truth = crate::truth::perturbed_truth(&nominal, 5, &crate::truth::ErrorBudget::realistic());
        let config = SimConfig { noise: crate::NoiseBudget::none(), ..SimConfig::default() };
        let inproc = VirtualCell::new(nominal.clone(), truth.clone(), config, 5);
        let ext = VirtualCell::new(nominal.clone(), truth, config, 5);
        let position = nominal.position_ids()[0];
        let tcp = nominal.tcp_ids()[0];
        let target = vatcal_planning_free_pose(&nominal, position, tcp);
        let options = MotionOptions { speed_fraction: 1.0, ..MotionOptions::default() };

        // in-process
        let (mut arm, mut guide, mut op) = (inproc.arm(), inproc.guide(), inproc.operator());
        arm.activate_and_home(Duration::from_secs(60)).expect("home");
        guide.home(Duration::from_secs(60)).expect("home guide");
        guide.move_absolute_mm(target[0], &options).expect("guide");
        guide.wait_idle(Duration::from_secs(60)).expect("guide idle");
        let arm_target = ArmJoints::from_joint_vector(&target);
        arm.move_joints_and_wait(&arm_target, &options).expect("arm");
        op.perform(&OperatorInstruction::PlaceProbe { position }).expect("place");
        let d = Vector3::new(0.3, -0.2, 0.1);
        arm.move_linear_relative_and_wait(&d, LinearFrame::Tool, &options).expect("linear");
        let mut gauges = inproc.gauges();
        let inproc_readings: Vec<f64> = gauges.iter_mut().map(|g| g.read_mm().expect("read")).collect();

        // external
        ext.external_guide_motion_started(0.0, 0.0);
        ext.external_guide_motion_started(0.0, target[0]);
        ext.external_motion_started(&ArmJoints([0.0; 6]), &arm_target);
        ext.operator().perform(&OperatorInstruction::PlaceProbe { position }).expect("place");
        let after = ext.external_linear_target(&arm_target, &d, LinearFrame::Tool).expect("ik");
        assert_eq!(after, arm.joints().expect("joints"), "same controller solution");
        ext.external_motion_started(&arm_target, &after);
        ext.external_sync(&after, target[0], Duration::from_secs(1));
        for (i, r) in inproc_readings.iter().enumerate() {
            let p = ext.external_plunger_mm(i).expect("touching");
            assert!((p - r).abs() < 1e-12, "gauge {i}: {p} vs {r}");
            assert_eq!(ext.external_reading_noise_mm(i), 0.0);
        }
        assert_eq!(ext.motion_directions(), inproc.motion_directions());
    }

    /// Joints that put the nominal TCP `tcp` near calibration position `position` (a pose
    /// from the truth module's probe start poses).
    fn vatcal_planning_free_pose(model: &Model, position: u32, tcp: u32) -> vatcal_core::JointVector {
        crate::truth::probe_start_poses(model, 40, 3)
            .into_iter()
            .find(|m| m.tcp == tcp && m.target == vatcal_core::Target::Probe { position })
            .map(|m| m.q)
            .expect("a start pose for the first position and TCP")
    }
}
