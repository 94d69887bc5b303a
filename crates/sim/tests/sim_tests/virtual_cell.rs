//! The simulated devices behave like the paper's cell: exact joint moves, relative moves
//! solved on the nominal model, gauges that read the true ball offset through their true axes,
//! the paper's noise, deterministic and history-free noise, typed errors.

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_core::{CellFile, JointVector};
use vatcal_hardware_traits::{
    ArmJoints, Clock, ErrorKind, Gauge, JointLayout, LinearAxis, LinearFrame, MotionOptions, Operator,
    OperatorInstruction, PositionTracker, Probe3d, RobotArm, Thermometer,
};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, probe_start_poses, reach};
use vatcal_sim::{SimConfig, SimFaults, VirtualCell};

fn nominal() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    Model::from_cell(&cell).expect("model")
}

fn opts() -> MotionOptions {
    MotionOptions::default()
}

/// A cell with the arm and guide homed, the plate at `position`.
fn ready_cell(config: SimConfig, seed: u64, position: u32) -> VirtualCell {
    let m = nominal();
    let truth = perturbed_truth(&m, seed, &ErrorBudget::realistic());
    let cell = VirtualCell::new(m, truth, config, seed);
    cell.arm().activate_and_home(Duration::from_secs(60)).expect("home arm");
    cell.guide().expect("the canonical cell has a guide").home(Duration::from_secs(60)).expect("home guide");
    cell.operator().perform(&OperatorInstruction::PlaceProbe { position }).expect("plate");
    cell
}

fn go_to(cell: &VirtualCell, q: &JointVector) {
    cell.guide()
        .expect("the canonical cell has a guide")
        .move_absolute_and_wait(q.guide_mm(), &opts())
        .expect("guide");
    cell.arm().move_joints_and_wait(&JointLayout::MECA500_ON_GUIDE.arm(q), &opts()).expect("arm");
}

/// A nominal start pose for (position 1, some TCP).
fn start_pose(position: u32) -> (u32, JointVector) {
    let poses = probe_start_poses(&nominal(), 6, 21);
    let p = poses.iter().find(|p| p.position() == Some(position)).expect("pose");
    (p.tcp, p.q)
}

#[test]
fn relative_moves_are_exact_on_the_nominal_model_only() {
    let cell = ready_cell(SimConfig::ideal(), 3, 1);
    let (tcp, q) = start_pose(1);
    go_to(&cell, &q);
    let nominal = cell.nominal();
    let before_nominal = nominal.tcp_position(&q, tcp).expect("fk");
    let before_true = cell.true_ball_position_mm(tcp).expect("ball");
    let d = Vector3::new(1.0, -0.5, 0.75);
    let flange = nominal.chain(&q).frames[7];
    cell.arm().move_linear_relative_and_wait(&d, LinearFrame::Tool, &opts()).expect("move");
    let q2 = JointLayout::MECA500_ON_GUIDE
        .join(Some(q.guide_mm()), &cell.arm().joints().expect("joints"))
        .expect("joints");
    let moved_nominal = nominal.tcp_position(&q2, tcp).expect("fk") - before_nominal;
    assert!((moved_nominal - flange.r * d).norm() < 1e-8, "nominal displacement {moved_nominal}");
    let moved_true = cell.true_ball_position_mm(tcp).expect("ball") - before_true;
    let discrepancy = (moved_true - flange.r * d).norm();
    assert!(discrepancy > 1e-5, "truth must differ from the controller's belief");
    assert!(discrepancy < 0.05 * d.norm(), "but only by a few percent: {discrepancy}");
    assert_eq!(cell.linear_moves().len(), 1);
}

#[test]
fn ideal_gauges_read_the_ball_offset_along_the_probe_axes() {
    let cell = ready_cell(SimConfig::ideal(), 4, 2);
    let (tcp, q0) = start_pose(2);
    let truth = cell.truth();
    let origin = truth.position(2).expect("position");
    let q = reach(&truth, &q0, tcp, &origin, 1e-11).expect("reach");
    go_to(&cell, &q);
    let mut probe = cell.probe().expect("probe");
    let r = probe.read().expect("read");
    assert!(r.composite_mm() < 1e-8, "centred ball reads zero: {:?}", r.gauges_mm);
    // a known offset, in probe axes
    let placement = probe.placement(2).expect("placement");
    let offset_probe = Vector3::new(0.3, -1.2, 2.0);
    let q_off = reach(&truth, &q, tcp, &(origin + placement.to_world(&offset_probe)), 1e-11).expect("reach");
    go_to(&cell, &q_off);
    let r = probe.read().expect("read");
    assert!((r.offset_mm - offset_probe).norm() < 1e-8, "{} vs {offset_probe}", r.offset_mm);
}

#[test]
fn imperfect_probe_reads_close_to_but_not_exactly_the_offset() {
    let cell = ready_cell(SimConfig::default(), 5, 3);
    let (tcp, q0) = start_pose(3);
    let truth = cell.truth();
    let mut probe = cell.probe().expect("probe");
    let placement = probe.placement(3).expect("placement");
    let offset_probe = Vector3::new(2.0, 1.0, -1.5);
    let target = truth.position(3).expect("p") + placement.to_world(&offset_probe);
    go_to(&cell, &reach(&truth, &q0, tcp, &target, 1e-11).expect("reach"));
    let r = probe.read().expect("read");
    let err = (r.offset_mm - offset_probe).norm();
    // tilted axes (0.3°), placement rotation (0.1°), tool changer and robot noise (µm)
    assert!(err > 1e-4 && err < 0.03, "offset error {err} mm");
}

#[test]
fn gauge_noise_stays_within_its_maximum_error() {
    let cell = ready_cell(SimConfig::default(), 6, 1);
    let (_, q) = start_pose(1);
    go_to(&cell, &q);
    let mut g = cell.gauges();
    let first = g[0].read_mm().expect("read");
    let reads: Vec<f64> = (0..200).map(|_| g[0].read_mm().expect("read")).collect();
    let spread =
        reads.iter().fold(f64::MIN, |a, b| a.max(*b)) - reads.iter().fold(f64::MAX, |a, b| a.min(*b));
    assert!(spread > 0.001 && spread <= 0.0024 + 1e-12, "spread {spread}");
    assert!(reads.iter().all(|r| (r - first).abs() <= 0.0024 + 1e-12));
}

#[test]
fn out_of_range_and_no_contact_are_errors() {
    let cell = ready_cell(SimConfig::ideal(), 7, 1);
    let (tcp, q0) = start_pose(1);
    let truth = cell.truth();
    let mut probe = cell.probe().expect("probe");
    // 6.5 mm along gauge 1 (a world z offset spreads over the three 54.7°-inclined gauges)
    let along_gauge_1 = probe.placement(1).expect("placement").to_world(&Vector3::new(6.5, 0.0, 0.0));
    let target = truth.position(1).expect("p") + along_gauge_1;
    go_to(&cell, &reach(&truth, &q0, tcp, &target, 1e-11).expect("reach"));
    let e = probe.read().expect_err("beyond ±6 mm");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("sim gauge 1"), "{e}");
    // far away: nothing touches
    go_to(&cell, &JointVector::default());
    let e = cell.gauges()[1].read_mm().expect_err("no contact");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("nothing touches"), "{e}");
}

#[test]
fn limits_errors_reset_and_not_homed() {
    let m = nominal();
    let cell = VirtualCell::new(m.clone(), m, SimConfig::ideal(), 1);
    let mut arm = cell.arm();
    let e = arm.move_joints(&ArmJoints::new([0.0; 6]), &opts()).expect_err("not homed");
    assert_eq!(e.kind(), ErrorKind::NotHomed);
    assert_eq!(
        cell.guide()
            .expect("the canonical cell has a guide")
            .move_absolute_mm(10.0, &opts())
            .expect_err("not homed")
            .kind(),
        ErrorKind::NotHomed
    );
    arm.activate_and_home(Duration::from_secs(60)).expect("home");
    let e = arm
        .move_joints(&ArmJoints::from_deg_array([0.0, 100.0, 0.0, 0.0, 0.0, 0.0]), &opts())
        .expect_err("limit");
    assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 1007 });
    assert!(e.to_string().contains("J2"), "{e}");
    let e = arm.move_joints(&ArmJoints::new([0.1; 6]), &opts()).expect_err("in error");
    assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 1011 });
    assert!(arm.status().expect("status").error.is_some());
    arm.reset_error().expect("reset");
    arm.move_joints_and_wait(&ArmJoints::new([0.1; 6]), &opts()).expect("moves after reset");
    let mut guide = cell.guide().expect("the canonical cell has a guide");
    guide.home(Duration::from_secs(60)).expect("home");
    assert_eq!(guide.move_absolute_mm(301.0, &opts()).expect_err("stroke").kind(), ErrorKind::OutOfRange);
}

#[test]
fn motions_take_virtual_time_and_waits_time_out() {
    let m = nominal();
    let cell = VirtualCell::new(m.clone(), m, SimConfig::ideal(), 1);
    let clock = cell.clock();
    let mut arm = cell.arm();
    arm.activate_and_home(Duration::from_secs(60)).expect("home");
    let t0 = clock.now();
    // J1 by 90° at 25 % of 150°/s = 2.4 s + 0.3 s settling
    let fast = MotionOptions { speed_fraction: 0.25, timeout: Duration::from_millis(500) };
    arm.move_joints(&ArmJoints::from_deg_array([90.0, 0.0, 0.0, 0.0, 0.0, 0.0]), &fast).expect("start");
    assert_eq!(arm.move_joints(&ArmJoints::new([0.0; 6]), &fast).expect_err("busy").kind(), ErrorKind::Busy);
    let e = arm.wait_idle(Duration::from_millis(500)).expect_err("timeout");
    assert!(e.is_timeout());
    assert_eq!(clock.now() - t0, Duration::from_millis(500));
    let mid = arm.joints().expect("joints").to_deg()[0];
    assert!(mid > 10.0 && mid < 30.0, "interpolated mid-motion: {mid}");
    arm.wait_idle(Duration::from_secs(10)).expect("done");
    assert!(((clock.now() - t0).as_secs_f64() - 2.7).abs() < 1e-6);
    assert_eq!(arm.joints().expect("joints").to_deg()[0], 90.0f64.to_radians().to_degrees());
    assert_eq!(cell.motion_directions(), [1, 0, 0, 0, 0, 0]);
    arm.move_joints_and_wait(&ArmJoints::from_deg_array([80.0, 0.0, 0.0, 0.0, 0.0, 1.0]), &opts())
        .expect("back");
    assert_eq!(cell.motion_directions(), [-1, 0, 0, 0, 0, 1]);
}

#[test]
fn noise_is_deterministic_and_history_free() {
    let (_, q) = start_pose(1);
    let mut other = q;
    other[3] += 0.05;
    let read = |history: &[JointVector]| -> [f64; 3] {
        let cell = ready_cell(SimConfig::default(), 9, 1);
        for h in history {
            go_to(&cell, h);
        }
        let mut probe = cell.probe().expect("probe");
        probe.read().expect("read").gauges_mm
    };
    let a = read(&[other, q]);
    let b = read(&[JointVector::from_mm_deg(0.0, [0.0, 0.0, 0.0, 0.0, 30.0, 0.0]), other, q]);
    assert_eq!(a, b, "same last commands from the same state: same noise");
    let c = read(&[q]);
    assert_ne!(a, c, "a different previous state: a fresh repeatability draw");
}

#[test]
fn tracker_noise_matches_the_budget() {
    let cell = ready_cell(SimConfig::default(), 10, 1);
    let (tcp, q) = start_pose(1);
    go_to(&cell, &q);
    let truth_p = cell.true_ball_position_mm(tcp).expect("ball");
    let mut tracker = cell.tracker();
    let n = 600;
    let errs: Vec<Vector3<f64>> =
        (0..n).map(|_| tracker.measure_mm(tcp).expect("measure") - truth_p).collect();
    let sd = (errs.iter().map(|e| e.norm_squared()).sum::<f64>() / (3 * n) as f64).sqrt();
    assert!((sd - 0.020 / 3.0).abs() < 0.0008, "per-axis sigma {sd}");
}

#[test]
fn injected_gauge_timeouts_are_typed() {
    let cell = ready_cell(SimConfig::ideal(), 11, 1);
    cell.set_faults(SimFaults { gauge_timeouts: true, ..SimFaults::default() });
    let e = cell.gauges()[2].read_mm().expect_err("timeout");
    assert!(e.is_timeout() && e.device() == "sim gauge 3", "{e}");
}

#[test]
fn the_thermometer_reads_the_temperature_the_truth_sees() {
    let m = nominal();
    // no temperature channel, no thermometer
    assert!(VirtualCell::paper(m.clone(), 3).thermometer().is_none());
    let cell = vatcal_sim::truth::TruthSpec::PaperLike.virtual_cell(m, 3).expect("cell");
    let profile = cell.config().physics.thermal.expect("temperature channel");
    let spec = cell.config().thermometer;
    let mut thermometer = cell.thermometer().expect("thermometer");
    let clock = cell.clock();
    let (mut sum, mut sum2, n) = (0.0, 0.0, 400);
    for i in 0..n {
        clock.sleep(Duration::from_secs(10));
        let before = clock.now();
        let read = thermometer.read_c().expect("reading");
        // takes no virtual time, shows the resolution, follows the truth's context
        assert_eq!(clock.now(), before);
        let steps = read / spec.resolution_k;
        assert!((steps - steps.round()).abs() < 1e-6, "{read} is not a multiple of the resolution");
        let t = clock.now().as_secs_f64();
        let truth_c = cell.context().temperature_c.expect("truth sees the temperature");
        assert_eq!(truth_c, profile.at(t));
        let e = read - truth_c;
        sum += e;
        sum2 += e * e;
        // deterministic: the same instant reads the same value
        assert_eq!(thermometer.read_c().expect("again"), read, "reading {i}");
    }
    let mean = sum / f64::from(n);
    let sd = (sum2 / f64::from(n) - mean * mean).sqrt();
    // σ² + resolution²/12
    let expected = (spec.sigma_k.powi(2) + spec.resolution_k.powi(2) / 12.0).sqrt();
    assert!(mean.abs() < 4.0 * expected / f64::from(n).sqrt(), "bias {mean} K");
    assert!((sd / expected - 1.0).abs() < 0.15, "σ {sd} K, expected {expected} K");
    // the warm-up is visible over the 4000 s: the channel carries the drift's information
    assert!(profile.at(4000.0) - profile.at(0.0) > 1.0);
}
