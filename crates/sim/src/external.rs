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
//! are and the speeds in force before reading a plunger.
//!
//! **Time.** The cell's physics (thermal drift, the time stamps of its context) follows the
//! cell's [`VirtualClock`](vatcal_hardware_traits::VirtualClock), never the wall clock: the
//! external motions advance it by the durations the in-process devices would take (the
//! cell's [`SimTiming`]: joint speeds × speed fraction + settling), a guide motion and the arm
//! motion commanded right after it counting once (they run together), every gauge reading by
//! [`SimTiming::gauge_read_s`], the operator by its re-placement time. A campaign over TCP
//! therefore sees the same temperature at the same plan step as the in-process demo,
//! whatever the simulators' `--time-scale` and the wire's latency.

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::{ArmJoints, LinearFrame};

use crate::cell::VirtualCell;
use crate::config::{SimConfig, SimTiming};
use crate::controller::{LinearMoveError, translate_flange, world_displacement};
use crate::noise::{bits, key, uniform};
use crate::world::{Motion, PendingSegment, padded};

/// Joint changes below this are the protocol's rounding, not motion (1e-9 rad ≈ 6e-8°, well
/// above the Meca500 protocol's 9 decimals of a degree and far below any physical motion).
const WIRE_RESOLUTION_RAD: f64 = 1e-9;

/// Meca500 error code of a move refused for a joint limit.
pub const CODE_JOINT_LIMIT: u16 = 1007;
/// Meca500 error code of a move refused near a singularity.
pub const CODE_SINGULARITY: u16 = 1012;

impl SimConfig {
    /// The configuration of [`VirtualCell::paper`] for the cell `nominal`: the paper's noise
    /// budget and probe imperfections, the timing of the cell file's motion limits.
    pub fn paper_for(nominal: &vatcal_kinematics::Model) -> Self {
        let layout = vatcal_hardware_traits::JointLayout::of(nominal.joint_kinds());
        let arm_kinds: Vec<_> = layout.arm_cell_joints().map(|j| nominal.joint_kind(j)).collect();
        let timing = SimTiming::for_arm(&nominal.to_cell().motion_limits(), &arm_kinds);
        Self { timing, ..Self::default() }
    }
}

impl VirtualCell {
    /// An external arm motion from `from` to `to` \[rad\] starts: the backlash direction of every
    /// joint that moves, a fresh repeatability offset and a new noise epoch, keyed on the two
    /// joint vectors like [`SimArm`](crate::SimArm)'s joint moves.
    pub fn external_motion_started(&self, from: &ArmJoints, to: &ArmJoints) {
        let mut w = self.shared.lock();
        let mut parts = bits(to.as_slice());
        parts.extend(bits(from.as_slice()));
        let event = key(w.seed, "arm-joints", &parts);
        let (from, to) = (padded(from), padded(to));
        w.arm.motion = Motion::at_rest(from);
        let dir_before = w.arm.dir;
        let to_arm = w.to_arm(&to);
        w.start_arm_motion(&to_arm, 1.0, event);
        // a joint commanded to where it already is, up to the wire's precision (9 decimals of
        // a degree: a joint target read back and sent again), does not move: its backlash side
        // stays
        for (j, before) in dir_before.iter().enumerate() {
            if (to[j] - from[j]).abs() < WIRE_RESOLUTION_RAD {
                w.arm.dir[j] = *before;
            }
        }
        match w.pending.last_mut() {
            Some(segment) if segment.arm.is_none() => segment.arm = Some((from, to)),
            _ => w.pending.push(PendingSegment { arm: Some((from, to)), guide: None }),
        }
    }

    /// An external guide motion from `from_mm` to `to_mm` starts (homing included): a fresh
    /// repeatability error and a new noise epoch, like [`SimGuide`](crate::SimGuide).
    pub fn external_guide_motion_started(&self, from_mm: f64, to_mm: f64) {
        let mut w = self.shared.lock();
        w.guide.homed = true;
        w.guide.motion = Motion::at_rest([from_mm]);
        w.start_guide_motion(to_mm, 1.0);
        // a guide motion opens a segment: the campaign moves the guide first, then the arm
        w.pending.push(PendingSegment { arm: None, guide: Some((from_mm, to_mm)) });
    }

    /// Where the external simulators have the joints now (arm \[rad\], guide as reported \[mm\]),
    /// and the speed fractions in force (arm joint speed, guide speed; those of the motions
    /// since the last sync): the physics puts the cell there (the guide's repeatability error
    /// is added physically), and the clock advances by the virtual time of the motions started
    /// since the last sync, as the in-process devices would have taken them (see the module
    /// documentation).
    pub fn external_sync(
        &self,
        arm: &ArmJoints,
        guide_mm: f64,
        arm_speed_fraction: f64,
        guide_speed_fraction: f64,
    ) {
        let mut w = self.shared.lock();
        let pending = std::mem::take(&mut w.pending);
        let elapsed: Duration = pending
            .iter()
            .map(|segment| {
                let a = segment
                    .arm
                    .map_or(Duration::ZERO, |(from, to)| w.arm_duration(&from, &to, arm_speed_fraction));
                let g = segment
                    .guide
                    .map_or(Duration::ZERO, |(from, to)| w.guide_duration(to - from, guide_speed_fraction));
                a.max(g)
            })
            .sum();
        w.clock.advance(elapsed);
        w.arm.motion = Motion::at_rest(padded(arm));
        w.guide.motion = Motion::at_rest([guide_mm]);
    }

    /// Joints \[rad\] that the cell's robot controller (which believes the **nominal** model)
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
        if let Err(e) = w.layout.check_arm(from) {
            return Err((CODE_JOINT_LIMIT, e.to_string()));
        }
        let start = w.cell_joints(w.guide.motion.to[0], from);
        let delta = world_displacement(&w.nominal, &start, translation_mm, frame);
        let executed = delta * w.config.faults.linear_move_gain;
        match translate_flange(&w.nominal, &start, &executed) {
            Ok(q) => {
                w.linear_moves.push(delta);
                Ok(w.layout.arm(&q))
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
    /// (the master-ball preset the probe came with) \[mm\]: a simulated gauge whose own zero
    /// sits there displays the in-process reading. `None` when nothing touches the plunger
    /// (it rests on its stop, fully extended).
    pub fn external_plunger_mm(&self, gauge: usize) -> Option<f64> {
        let w = self.shared.lock();
        let plunger = w.plunger_mm(gauge)?;
        Some(plunger - (w.probe.master_radius_mm - vatcal_hardware_traits::TRICAL_MASTER_PRESET_MM))
    }

    /// The reading error of the next reading of gauge `gauge` (uniform within the gauge's
    /// maximum error, keyed on the current noise epoch like the in-process gauges) \[mm\]. A
    /// reading takes [`SimTiming::gauge_read_s`] of virtual time, like an in-process one.
    pub fn external_reading_noise_mm(&self, gauge: usize) -> f64 {
        let mut w = self.shared.lock();
        let max = w.config.noise.gauge_max_error_mm;
        let mut rng = w.reading_rng("gauge", gauge as u64);
        let read = Duration::from_secs_f64(w.config.timing.gauge_read_s);
        w.clock.advance(read);
        uniform(&mut rng, max)
    }

    /// One tracker reading of `target` (a TCP id, or the probe nest's SMR
    /// [`PROBE_NEST_TARGET`](vatcal_hardware_traits::PROBE_NEST_TARGET)) at the state of the
    /// last [`VirtualCell::external_sync`], exactly as the in-process
    /// [`SimTracker`](crate::SimTracker) reads it — registration error, SMR-nest offsets,
    /// noise keyed on the current epoch, line-of-sight losses — in the world frame \[mm\]. A
    /// reading takes [`SimTiming::tracker_read_s`] of virtual time.
    ///
    /// # Errors
    /// As the in-process tracker: [`ErrorKind::OutOfRange`](vatcal_hardware_traits::ErrorKind)
    /// for an unknown target, a lost line of sight, or the nest SMR without a placed plate.
    pub fn external_track_mm(&self, target: u32) -> vatcal_hardware_traits::Result<Vector3<f64>> {
        let mut w = self.shared.lock();
        let read = Duration::from_secs_f64(w.config.timing.tracker_read_s);
        w.clock.advance(read);
        w.track(target)
    }

    /// The arm's joint limits J1.. in the controller's (nominal) model \[rad\] (a continuous
    /// joint: one turn, see `Model::joint_limits`).
    pub fn arm_joint_limits(&self) -> Vec<(f64, f64)> {
        let w = self.shared.lock();
        let limits = w.nominal.joint_limits();
        w.layout.arm_cell_joints().map(|j| limits[j - 1]).collect()
    }

    /// The guide's stroke in the controller's (nominal) model \[mm\] (`None`: no guide).
    pub fn guide_limits_mm(&self) -> Option<(f64, f64)> {
        let w = self.shared.lock();
        w.layout.guide_joint().map(|g| w.nominal.joint_limits()[g - 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SimConfig;
    use vatcal_core::CellFile;
    use vatcal_hardware_traits::{
        Clock, Gauge, LinearAxis, MotionOptions, Operator, OperatorInstruction, RobotArm,
    };
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
        let (mut arm, mut guide, mut op) = (inproc.arm(), inproc.guide().expect("guide"), inproc.operator());
        arm.activate_and_home(Duration::from_secs(60)).expect("home");
        guide.home(Duration::from_secs(60)).expect("home guide");
        // guide and arm together, waited for together (as the campaign moves them)
        guide.move_absolute_mm(target[0], &options).expect("guide");
        let arm_target = vatcal_hardware_traits::JointLayout::MECA500_ON_GUIDE.arm(&target);
        arm.move_joints(&arm_target, &options).expect("arm");
        guide.wait_idle(Duration::from_secs(60)).expect("guide idle");
        arm.wait_idle(Duration::from_secs(60)).expect("arm idle");
        op.perform(&OperatorInstruction::PlaceProbe { position }).expect("place");
        let d = Vector3::new(0.3, -0.2, 0.1);
        arm.move_linear_relative_and_wait(&d, LinearFrame::Tool, &options).expect("linear");
        let mut gauges = inproc.gauges();
        let inproc_readings: Vec<f64> = gauges.iter_mut().map(|g| g.read_mm().expect("read")).collect();

        // external
        ext.external_guide_motion_started(0.0, 0.0);
        ext.external_guide_motion_started(0.0, target[0]);
        ext.external_motion_started(&ArmJoints::zeros(6), &arm_target);
        ext.operator().perform(&OperatorInstruction::PlaceProbe { position }).expect("place");
        let after = ext.external_linear_target(&arm_target, &d, LinearFrame::Tool).expect("ik");
        assert_eq!(after, arm.joints().expect("joints"), "same controller solution");
        ext.external_motion_started(&arm_target, &after);
        ext.external_sync(&after, target[0], 1.0, 1.0);
        for (i, r) in inproc_readings.iter().enumerate() {
            let p = ext.external_plunger_mm(i).expect("touching");
            assert!((p - r).abs() < 1e-12, "gauge {i}: {p} vs {r}");
            assert_eq!(ext.external_reading_noise_mm(i), 0.0);
        }
        assert_eq!(ext.motion_directions(), inproc.motion_directions());
        // one time base: the same virtual time, apart from the arm's activation and homing
        // (the Meca500 simulator homes on its own)
        let homing = Duration::from_secs_f64(inproc.config().timing.homing_s);
        assert!(inproc.clock().now() > Duration::from_secs(60), "the operator's minute at least");
        assert_eq!(ext.clock().now(), inproc.clock().now() - homing);
    }

    /// A joint target sent again after a read-back (rounded by the wire) is no motion: the
    /// joint keeps its backlash side; a real motion changes it.
    #[test]
    fn wire_rounding_does_not_reverse_a_joint() {
        let nominal = nominal();
        let truth = crate::truth::perturbed_truth(&nominal, 5, &crate::truth::ErrorBudget::realistic());
        let cell = VirtualCell::new(nominal, truth, SimConfig::default(), 5);
        let a = ArmJoints::new([0.1, 0.2, -0.3, 0.4, 0.5, -0.6]);
        cell.external_motion_started(&ArmJoints::zeros(6), &a);
        assert_eq!(cell.motion_directions(), [1, 1, -1, 1, 1, -1]);
        let mut rounded = a;
        rounded[0] -= 1e-12; // 6e-11°: below the Meca500 protocol's 9 decimals
        rounded[1] += 1e-3; // a real motion, same direction
        rounded[2] += 1e-3; // a real reversal
        cell.external_motion_started(&a, &rounded);
        assert_eq!(cell.motion_directions(), [1, 1, 1, 1, 1, -1]);
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
