//! The tracker in the validation campaign: registration to the tank frame as the paper does
//! it (the nest SMR at the calibration positions, a rigid fit), and tracker faults — lost line
//! of sight, timeouts, garbled answers — retried, skipped or stopping the campaign safely, with
//! nothing lost on resume.

use std::collections::BTreeSet;

use crate::common;

use common::{SimDevices, nominal, paper_cell, quiet_config};
use nalgebra::{Rotation3, Vector3};
use vatcal_campaign::validation::{
    PrintingPathOptions, RandomPoseOptions, TrackerRegistration, ValidationError, ValidationPlan,
    ValidationPlanOptions, build_validation_plan, evaluate, register_tracker, register_tracker_resuming,
};
use vatcal_campaign::{Campaign, CampaignConfig, CampaignError, CellDevices};
use vatcal_core::{CellFile, Frame};
use vatcal_hardware_traits::{Error, ErrorKind, PositionTracker, Result as HwResult};
use vatcal_kinematics::Model;
use vatcal_planning::CellGeometry;

const SEED: u64 = 12;

/// The in-process tracker standing somewhere else: readings in its own frame.
struct Displaced<T> {
    inner: T,
    tracker_from_world: Frame,
}

impl<T: PositionTracker> PositionTracker for Displaced<T> {
    fn measure_mm(&mut self, target: u32) -> HwResult<Vector3<f64>> {
        Ok(self.tracker_from_world.transform_point(&self.inner.measure_mm(target)?))
    }
}

fn tracker_pose() -> Frame {
    Frame {
        r: *Rotation3::from_euler_angles(0.02, -0.01, 2.4).matrix(),
        p: Vector3::new(1900.0, -1300.0, 250.0),
    }
}

#[test]
fn registration_finds_the_tracker_pose_and_maps_readings_into_the_tank() {
    let model = nominal();
    let cell = paper_cell(SEED);
    let world_from_tracker = tracker_pose();
    let mut tracker = Displaced { inner: cell.tracker(), tracker_from_world: world_from_tracker.inverse() };
    let mut operator = cell.operator();
    let reg = register_tracker(&mut tracker, &mut operator, &model, &[], 2).expect("registration");
    assert_eq!(reg.points.len(), model.position_ids().len());
    // the residual is the tracker's noise at three points (σ 6.7 µm per axis), not zero
    assert!(reg.rms_residual_mm > 1e-4 && reg.max_residual_mm < 0.05, "{}", reg.summary());
    assert!(reg.summary().contains("residual RMS"), "{}", reg.summary());
    println!("{}", reg.summary());
    // registered readings are the in-process (tank-frame) tracker's, up to the registration
    // error over the workspace around the tank (points within 400 mm of the positions)
    let found = reg.tank_from_tracker();
    let centre = model.position_ids().iter().filter_map(|p| model.position(*p)).sum::<Vector3<f64>>() / 3.0;
    for d in [Vector3::zeros(), Vector3::new(400.0, 0.0, 0.0), Vector3::new(0.0, 300.0, 250.0)] {
        let p = centre + d;
        let back = found.transform_point(&world_from_tracker.inverse().transform_point(&p));
        assert!((back - p).norm() < 0.1, "{d}: {:.4} mm off", (back - p).norm());
    }
    let mut registered = reg.register(tracker);
    let direct = cell.tracker().measure_mm(vatcal_hardware_traits::PROBE_NEST_TARGET).expect("direct");
    let via = registered.measure_mm(vatcal_hardware_traits::PROBE_NEST_TARGET).expect("registered");
    assert!((direct - via).norm() < 0.08, "{direct} vs {via}");

    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("tracker-registration.json");
    reg.save(&path).expect("save");
    assert_eq!(TrackerRegistration::load(&path).expect("load"), reg);
    std::fs::write(&path, "{ not json").expect("write");
    let e = TrackerRegistration::load(&path).expect_err("garbage").to_string();
    assert!(e.contains("tracker-registration.json") && e.contains("line 1"), "{e}");
}

/// Counts the tracker's readings.
struct Counting<T> {
    inner: T,
    reads: usize,
}

impl<T: PositionTracker> PositionTracker for Counting<T> {
    fn measure_mm(&mut self, target: u32) -> HwResult<Vector3<f64>> {
        self.reads += 1;
        self.inner.measure_mm(target)
    }
}

/// A registration interrupted after its first nest reading (the reading journaled by the
/// callback) continues with the other positions: the first is not measured again, its reading
/// is used as journaled, and every new reading reaches the callback.
#[test]
fn an_interrupted_registration_continues_without_measuring_a_nest_twice() {
    let model = nominal();
    let cell = paper_cell(SEED);
    let mut tracker = Counting {
        inner: Displaced { inner: cell.tracker(), tracker_from_world: tracker_pose().inverse() },
        reads: 0,
    };
    let mut operator = cell.operator();
    let positions = model.position_ids();
    // the first run stops after one reading (the callback's error stands for the kill)
    let mut journal = Vec::new();
    let stopped = register_tracker_resuming(&mut tracker, &mut operator, &model, &[], 0, &[], &mut |p, v| {
        journal.push((p, v));
        Err(vatcal_campaign::validation::TrackerRegistrationError::Positions("killed".into()))
    });
    assert!(stopped.is_err());
    assert_eq!((tracker.reads, journal.len()), (1, 1));
    let mut added = Vec::new();
    let reg =
        register_tracker_resuming(&mut tracker, &mut operator, &model, &[], 0, &journal, &mut |p, v| {
            added.push((p, v));
            Ok(())
        })
        .expect("registration");
    assert_eq!(tracker.reads, positions.len(), "one reading per position in all");
    assert_eq!(added.iter().map(|(p, _)| *p).collect::<Vec<_>>(), positions[1..].to_vec());
    let first = &reg.points[0];
    assert_eq!(first.position, journal[0].0);
    assert_eq!(first.tracker_mm, [journal[0].1.x, journal[0].1.y, journal[0].1.z], "the journaled reading");
    assert!(reg.max_residual_mm < 0.05, "{}", reg.summary());
}

/// A tracker that reports in the tank frame (`frame = "tank"`) is checked, not registered:
/// the residuals are the raw distances of the nest readings from the calibration positions
/// (no fit absorbs them), the transform is the identity; a displaced tracker fails the check
/// by its displacement.
#[test]
fn the_check_of_a_tank_frame_tracker_keeps_the_readings_as_they_are() {
    let model = nominal();
    let cell = paper_cell(SEED);
    let mut tracker = cell.tracker();
    let mut operator = cell.operator();
    let reg = register_tracker(&mut tracker, &mut operator, &model, &[], 2).expect("registration");
    let check = reg.checked();
    assert_eq!(check.tank_from_tracker().p, Vector3::zeros());
    assert_eq!(check.tank_from_tracker().r, nalgebra::Matrix3::identity());
    for (p, c) in reg.points.iter().zip(&check.points) {
        let raw = (Vector3::from(p.tracker_mm) - Vector3::from(p.tank_mm)).norm();
        assert_eq!(c.residual_mm, raw);
        // the in-process tracker is in the tank frame up to its noise and registration error
        assert!(raw < 0.1, "position {}: {raw} mm", p.position);
    }
    // the fit absorbs part of the raw error: its RMS is not larger than the check's
    assert!(reg.rms_residual_mm <= check.rms_residual_mm + 1e-12);
    let mut moved = Displaced { inner: cell.tracker(), tracker_from_world: tracker_pose().inverse() };
    let far = register_tracker(&mut moved, &mut operator, &model, &[], 2).expect("registration").checked();
    assert!(far.max_residual_mm > 1000.0, "{}", far.summary());
}

/// Loses the line of sight (or answers garbage, or times out) on the given calls.
struct Flaky<T> {
    inner: T,
    calls: usize,
    fail: BTreeSet<usize>,
    kind: ErrorKind,
}

impl<T: PositionTracker> PositionTracker for Flaky<T> {
    fn measure_mm(&mut self, target: u32) -> HwResult<Vector3<f64>> {
        self.calls += 1;
        if self.fail.contains(&self.calls) {
            return Err(Error::new(
                self.kind,
                "flaky tracker",
                format!("call {}: SMR {target} lost", self.calls),
            ));
        }
        self.inner.measure_mm(target)
    }
}

fn plan(model: &Model) -> ValidationPlan {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let opts = ValidationPlanOptions {
        random: RandomPoseOptions { count: 8, ..RandomPoseOptions::default() },
        printing: PrintingPathOptions { slices: 60, ..PrintingPathOptions::default() },
        seed: 3,
        ..ValidationPlanOptions::default()
    };
    build_validation_plan(model, &geometry, &[("nominal", model)], &opts).expect("plan")
}

fn config(skip: bool) -> CampaignConfig {
    CampaignConfig { sync_journal_each_step: false, skip_failed_tracks: skip, ..quiet_config() }
}

fn run(
    plan: &ValidationPlan,
    journal: &std::path::Path,
    fail: &[usize],
    kind: ErrorKind,
    skip: bool,
) -> Result<vatcal_campaign::validation::ValidationRecords, ValidationError> {
    let model = nominal();
    let cell = paper_cell(SEED);
    let mut d = SimDevices::of(&cell);
    let mut tracker = Flaky { inner: cell.tracker(), calls: 0, fail: fail.iter().copied().collect(), kind };
    let devices = CellDevices { tracker: Some(&mut tracker), ..d.devices() };
    plan.run(&mut Campaign::new(devices, &model, config(skip)), journal)
}

#[test]
fn tracker_faults_are_retried_skipped_or_stop_the_campaign_safely() {
    let model = nominal();
    let plan = plan(&model);
    let dir = tempfile::tempdir().expect("tmp");
    let reference =
        run(&plan, &dir.path().join("ref.journal"), &[], ErrorKind::OutOfRange, false).expect("ref");
    assert_eq!(reference.random.len(), 8);
    assert_eq!(reference.skipped, 0);

    // one or two failures in a row: retried (2 retries), the same readings as without faults
    for kind in [ErrorKind::OutOfRange, ErrorKind::Protocol, ErrorKind::Timeout] {
        let journal = dir.path().join(format!("retried-{kind}.journal"));
        let got = run(&plan, &journal, &[2, 6, 7], kind, false).expect("retried");
        assert_eq!(got, reference, "{kind}");
    }

    // three failures in a row on the 3rd random pose: skipped with the skip policy ...
    let fail = [3, 4, 5];
    let got =
        run(&plan, &dir.path().join("skipped.journal"), &fail, ErrorKind::OutOfRange, true).expect("skip");
    assert_eq!((got.skipped, got.random.len()), (1, 7));
    assert_eq!(got.random[..2], reference.random[..2]);
    let smrs: Vec<_> = model.tcp_ids().into_iter().map(|id| (id, model.tcp(id).expect("tcp"))).collect();
    let results = evaluate(&got, &plan.slices, &[("nominal", &model)], &smrs).expect("evaluates");
    assert_eq!(results[0].random.errors_mm.len(), 7);

    // ... or the campaign stops, naming the fault and the attempts; a resume with a healthy
    // tracker measures the point again and loses nothing
    let journal = dir.path().join("stopped.journal");
    let e = run(&plan, &journal, &fail, ErrorKind::OutOfRange, false).expect_err("stops");
    let text = e.to_string();
    assert!(text.contains("3 attempts") && text.contains("SMR") && text.contains("lost"), "{text}");
    assert!(
        matches!(&e, ValidationError::Campaign(c) if matches!(**c, CampaignError::Device { ref source, .. } if source.kind() == ErrorKind::OutOfRange)),
        "{e}"
    );
    let resumed = run(&plan, &journal, &[], ErrorKind::OutOfRange, false).expect("resumed");
    assert_eq!(resumed.random.len(), 8);
    for (a, b) in resumed.random.iter().zip(&reference.random) {
        assert_eq!((a.tcp, a.q), (b.tcp, b.q));
    }
    // an operator who cancels is not retried
    let e =
        run(&plan, &dir.path().join("cancel.journal"), &[1], ErrorKind::Cancelled, true).expect_err("cancel");
    assert!(e.to_string().contains("1 attempt)"), "{e}");
}

/// Random poses only (no printing path): a short plan for the trackers driven by hand.
fn random_only(model: &Model, count: usize) -> ValidationPlan {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let opts = ValidationPlanOptions {
        random: RandomPoseOptions { count, ..RandomPoseOptions::default() },
        printing: PrintingPathOptions { slices: 0, ..PrintingPathOptions::default() },
        seed: 5,
        ..ValidationPlanOptions::default()
    };
    build_validation_plan(model, &geometry, &[("nominal", model)], &opts).expect("plan")
}

fn validate_with(
    plan: &ValidationPlan,
    tracker: &mut dyn PositionTracker,
    journal: &std::path::Path,
) -> Vec<Vector3<f64>> {
    let model = nominal();
    let cell = paper_cell(SEED);
    let mut d = SimDevices::of(&cell);
    let devices = CellDevices { tracker: Some(tracker), ..d.devices() };
    let records = plan.run(&mut Campaign::new(devices, &model, config(false)), journal).expect("validation");
    let results = evaluate(&records, &plan.slices, &[("nominal", &model)], &[]).expect("evaluate");
    results[0].random.errors_mm.clone()
}

#[test]
fn a_command_tracker_backed_by_a_script_validates_a_short_plan() {
    let model = nominal();
    let plan = random_only(&model, 6);
    // the "tracker": the SMR where the controller expects it, 0.25 mm further along x
    let script =
        "echo \"$VATCAL_TRACKER_NOMINAL_MM\" | awk '{ printf \"%.6f %.6f %.6f\\n\", $1 + 0.25, $2, $3 }'";
    let mut tracker = vatcal_drivers_tracker::CommandTracker::new(
        vatcal_drivers_tracker::CommandTrackerConfig::new("sh", vec!["-c".into(), script.into()]),
    );
    let dir = tempfile::tempdir().expect("tmp");
    let errors = validate_with(&plan, &mut tracker, &dir.path().join("command.journal"));
    assert_eq!(errors.len(), 6);
    for e in errors {
        assert!((e - Vector3::new(0.25, 0.0, 0.0)).amax() < 1e-5, "{e}");
    }
}

#[test]
fn a_console_tracker_fed_by_the_operator_validates_a_short_plan() {
    let model = nominal();
    let plan = random_only(&model, 5);
    // what the operator pastes: the controller's prediction 0.1 mm lower, after one typo
    let mut input = String::from("12.5 13\n");
    for pose in &plan.random_poses {
        let p = model.tcp_position(&pose.q, pose.tcp).expect("fk") - Vector3::new(0.0, 0.0, 0.1);
        input.push_str(&format!("{:.6}, {:.6}, {:.6}\n", p.x, p.y, p.z));
    }
    let mut prompts = Vec::new();
    let mut tracker = vatcal_drivers_tracker::ConsoleTracker::new(input.as_bytes(), &mut prompts);
    let dir = tempfile::tempdir().expect("tmp");
    let errors = validate_with(&plan, &mut tracker, &dir.path().join("console.journal"));
    assert_eq!(errors.len(), 5);
    for e in errors {
        assert!((e - Vector3::new(0.0, 0.0, -0.1)).amax() < 1e-5, "{e}");
    }
    let prompts = String::from_utf8(prompts).expect("utf8");
    assert!(prompts.contains("not a reading") && prompts.contains("expected near"), "{prompts}");
}
