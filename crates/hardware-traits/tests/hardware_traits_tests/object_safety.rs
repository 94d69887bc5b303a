//! Every trait works as a trait object, and through `&mut T` / `Box<T>`: a campaign written
//! against `&mut dyn Trait` accepts any driver.

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::{
    ArmJoints, ArmStatus, Error, ErrorKind, Gauge, LinearAxis, LinearFrame, MotionOptions, Operator,
    OperatorInstruction, PositionTracker, Probe3d, ProbePlacement, Result, RobotArm, TriCal, TriCalConfig,
};

#[derive(Debug, Default)]
struct CountingArm {
    joints: ArmJoints,
    moves: usize,
    waits: usize,
}

impl RobotArm for CountingArm {
    fn joint_count(&self) -> usize {
        6
    }
    fn activate_and_home(&mut self, _timeout: Duration) -> Result<()> {
        Ok(())
    }
    fn status(&mut self) -> Result<ArmStatus> {
        Ok(ArmStatus { activated: true, homed: true, ..ArmStatus::default() })
    }
    fn joints(&mut self) -> Result<ArmJoints> {
        Ok(self.joints)
    }
    fn move_joints(&mut self, target: &ArmJoints, _options: &MotionOptions) -> Result<()> {
        self.joints = *target;
        self.moves += 1;
        Ok(())
    }
    fn move_linear_relative(&mut self, _d: &Vector3<f64>, _f: LinearFrame, _o: &MotionOptions) -> Result<()> {
        Err(Error::new(ErrorKind::DeviceFault { code: 1012 }, "counting arm", "singularity"))
    }
    fn wait_idle(&mut self, _timeout: Duration) -> Result<()> {
        self.waits += 1;
        Ok(())
    }
    fn stop(&mut self) -> Result<()> {
        Ok(())
    }
    fn reset_error(&mut self) -> Result<()> {
        Ok(())
    }
}

#[derive(Debug, Default)]
struct Axis(f64);

impl LinearAxis for Axis {
    fn home(&mut self, _timeout: Duration) -> Result<()> {
        self.0 = 0.0;
        Ok(())
    }
    fn is_homed(&mut self) -> Result<bool> {
        Ok(true)
    }
    fn position_mm(&mut self) -> Result<f64> {
        Ok(self.0)
    }
    fn move_absolute_mm(&mut self, target_mm: f64, _options: &MotionOptions) -> Result<()> {
        if !(0.0..=300.0).contains(&target_mm) {
            return Err(Error::new(ErrorKind::OutOfRange, "axis", "beyond the stroke"));
        }
        self.0 = target_mm;
        Ok(())
    }
    fn wait_idle(&mut self, _timeout: Duration) -> Result<()> {
        Ok(())
    }
    fn stop(&mut self) -> Result<()> {
        Ok(())
    }
}

#[derive(Debug)]
struct Fixed(f64);

impl Gauge for Fixed {
    fn read_mm(&mut self) -> Result<f64> {
        Ok(self.0)
    }
    fn preset_mm(&mut self, value_mm: f64) -> Result<()> {
        self.0 = value_mm;
        Ok(())
    }
}

#[derive(Debug)]
struct Tracker;

impl PositionTracker for Tracker {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        Ok(Vector3::new(f64::from(target), 0.0, 0.0))
    }
}

#[derive(Debug, Default)]
struct Log(Vec<String>);

impl Operator for Log {
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()> {
        self.0.push(instruction.to_string());
        Ok(())
    }
}

/// Generic code written once against trait objects.
fn drive(arm: &mut dyn RobotArm, axis: &mut dyn LinearAxis, probe: &mut dyn Probe3d) -> Result<f64> {
    arm.move_joints_and_wait(&ArmJoints::new([0.1; 6]), &MotionOptions::default())?;
    axis.move_absolute_and_wait(150.0, &MotionOptions::default())?;
    Ok(probe.read()?.composite_mm())
}

#[test]
fn trait_objects_and_forwarding_impls() {
    let mut arm = CountingArm::default();
    let mut axis = Axis::default();
    let gauges: [Box<dyn Gauge>; 3] = [Box::new(Fixed(0.003)), Box::new(Fixed(0.0)), Box::new(Fixed(-0.004))];
    let mut probe =
        TriCal::new(gauges, TriCalConfig::new(vec![ProbePlacement::trihedral(1, 0.0)])).expect("probe");
    {
        // &mut T is itself an implementation
        let mut by_ref = &mut arm;
        let composite = drive(&mut by_ref, &mut axis, &mut probe).expect("drive");
        assert!((composite - 0.005).abs() < 1e-12);
    }
    assert_eq!((arm.moves, arm.waits), (1, 1), "provided method forwarded through &mut");
    let mut boxed: Box<dyn RobotArm> = Box::new(arm);
    boxed.move_joints_and_wait(&ArmJoints::new([0.2; 6]), &MotionOptions::default()).expect("boxed move");
    assert_eq!(boxed.joints().expect("joints"), ArmJoints::new([0.2; 6]));
    let e = boxed
        .move_linear_relative_and_wait(&Vector3::x(), LinearFrame::Tool, &MotionOptions::default())
        .expect_err("fault");
    assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 1012 });

    let mut boxed_axis: Box<dyn LinearAxis> = Box::new(axis);
    assert_eq!(
        boxed_axis.move_absolute_mm(400.0, &MotionOptions::default()).expect_err("range").kind(),
        ErrorKind::OutOfRange
    );

    let mut tracker: Box<dyn PositionTracker> = Box::new(Tracker);
    assert_eq!(tracker.measure_mm(3).expect("measure").x, 3.0);

    let mut log = Log::default();
    {
        let mut op: Box<dyn Operator + '_> = Box::new(&mut log);
        op.perform(&OperatorInstruction::PlaceProbe { position: 2 }).expect("op");
    }
    assert_eq!(log.0, vec!["place the probe plate at calibration position 2".to_string()]);

    let mut boxed_probe: Box<dyn Probe3d> = Box::new(probe);
    assert!(boxed_probe.placement(1).is_some() && boxed_probe.placement(2).is_none());
    boxed_probe.preset_master().expect("preset");
    let e = boxed_probe.read().expect_err("6.35 mm is outside the ±6 mm working range");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("6.35"), "{e}");
}
