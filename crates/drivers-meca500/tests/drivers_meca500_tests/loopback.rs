//! The driver against the simulator over real TCP on 127.0.0.1 (ephemeral ports). Every wait
//! is bounded by a timeout; the simulator stops when dropped.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use vatcal_drivers_meca500::codec::{Deframer, Reply, code};
use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig, forward_kinematics};
use vatcal_drivers_meca500::{JointReadback, Meca500, Meca500Config};
use vatcal_hardware_traits::{ArmJoints, ErrorKind, LinearFrame, MotionOptions, RobotArm};

const TIMEOUT: Duration = Duration::from_secs(5);

fn fast_sim() -> Meca500Sim {
    Meca500Sim::start(SimConfig::fast(20.0)).unwrap_or_else(|e| panic!("sim: {e}"))
}

fn config() -> Meca500Config {
    Meca500Config { io_timeout: Duration::from_millis(1000), ..Meca500Config::default() }
}

fn connect(sim: &Meca500Sim, config: Meca500Config) -> Meca500 {
    Meca500::connect_tcp(sim.control_addr(), config).unwrap_or_else(|e| panic!("connect: {e}"))
}

fn ready(sim: &Meca500Sim) -> Meca500 {
    let mut robot = connect(sim, config());
    robot.activate_and_home(TIMEOUT).unwrap_or_else(|e| panic!("activate: {e}"));
    robot
}

fn full_speed() -> MotionOptions {
    MotionOptions { speed_fraction: 1.0, timeout: TIMEOUT }
}

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn err_kind<T: std::fmt::Debug>(r: vatcal_hardware_traits::Result<T>) -> ErrorKind {
    match r {
        Ok(v) => panic!("expected an error, got {v:?}"),
        Err(e) => e.kind(),
    }
}

#[test]
fn connect_activate_and_home() {
    let sim = fast_sim();
    let mut robot = connect(&sim, config());
    assert_eq!(robot.banner().version, (9, 3, 0));
    assert_eq!(robot.banner().model, "Meca500");
    let s = ok(robot.status());
    assert!(!s.activated && !s.homed && s.error.is_none());
    assert_eq!(err_kind(robot.move_joints(&ArmJoints::default(), &full_speed())), ErrorKind::NotHomed);
    ok(robot.activate_and_home(TIMEOUT));
    let s = ok(robot.status());
    assert!(s.activated && s.homed && !s.moving && s.error.is_none(), "{s:?}");
    // idempotent
    ok(robot.activate_and_home(TIMEOUT));
    assert!(sim.state().status.activated);
}

#[test]
fn a_target_of_another_joint_count_is_refused_before_anything_is_sent() {
    let sim = fast_sim();
    let mut robot = ready(&sim);
    assert_eq!(robot.joint_count(), 6);
    assert_eq!(ok(robot.joints()).len(), 6);
    let seven = ArmJoints::from_deg_array([10.0, -20.0, 30.0, 5.0, 40.0, -15.0, 3.0]);
    let e = robot.move_joints(&seven, &full_speed()).expect_err("7 joints for a Meca500");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("6 joints") && e.to_string().contains("7 joints"), "{e}");
    assert!(sim.state().joints_deg.iter().all(|v| *v == 0.0), "nothing moved");
}

#[test]
fn joint_moves_read_back_in_radians() {
    let sim = fast_sim();
    let mut robot = ready(&sim);
    let target_deg = [10.0, -20.0, 30.0, 5.0, 40.0, -15.0];
    let target = ArmJoints::from_deg_array(target_deg);
    ok(robot.move_joints_and_wait(&target, &full_speed()));
    let q = ok(robot.joints());
    assert!(q.max_abs_diff(&target) < 1e-9, "{q:?}");
    for (a, b) in sim.state().joints_deg.iter().zip(target_deg) {
        assert!((a - b).abs() < 1e-9);
    }
    // other read-back sources agree at rest
    for readback in [JointReadback::Measured, JointReadback::Legacy] {
        drop(robot);
        robot = connect(&sim, Meca500Config { joint_readback: readback, ..config() });
        assert!(ok(robot.joints()).max_abs_diff(&target) < 1e-9, "{readback:?}");
    }
}

#[test]
fn motion_is_reported_while_it_runs_and_waits_are_bounded() {
    let sim = Meca500Sim::start(SimConfig {
        activation_time: Duration::ZERO,
        homing_time: Duration::ZERO,
        ..SimConfig::default()
    })
    .unwrap_or_else(|e| panic!("{e}"));
    let mut robot = ready(&sim);
    // J1 at 5 % of 150 deg/s: 30 deg take 4 s
    let slow = MotionOptions { speed_fraction: 0.05, timeout: TIMEOUT };
    ok(robot.move_joints(&ArmJoints::from_deg_array([30.0, 0.0, 0.0, 0.0, 0.0, 0.0]), &slow));
    assert!(ok(robot.status()).moving);
    let t0 = Instant::now();
    assert_eq!(err_kind(robot.wait_idle(Duration::from_millis(200))), ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2));
    // stop: motion cleared and resumed, so the next move runs
    ok(robot.stop());
    let after_stop = sim.state();
    assert!(!after_stop.status.paused && after_stop.queue_len == 0);
    let stopped_at = ok(robot.joints());
    assert!(stopped_at[0] > 0.0 && stopped_at[0] < 30f64.to_radians());
    ok(robot.move_joints_and_wait(&ArmJoints::from_deg_array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0]), &full_speed()));
    assert!(!ok(robot.status()).moving);
}

#[test]
fn linear_relative_moves_in_world_and_tool_axes() {
    let sim = fast_sim();
    let mut robot = ready(&sim);
    ok(robot
        .move_joints_and_wait(&ArmJoints::from_deg_array([5.0, 10.0, 20.0, 10.0, 40.0, 5.0]), &full_speed()));
    let flange = |r: &mut Meca500| {
        let deg: [f64; 6] = ok(r.joints()).to_deg().try_into().unwrap_or_else(|_| panic!("six joints"));
        forward_kinematics(&deg)
    };
    let before = flange(&mut robot);
    let d = Vector3::new(1.5, -2.0, 0.75);
    ok(robot.move_linear_relative_and_wait(&d, LinearFrame::World, &full_speed()));
    let after = flange(&mut robot);
    assert!((after.translation.vector - before.translation.vector - d).norm() < 1e-6);
    assert!(after.rotation.angle_to(&before.rotation) < 1e-9);
    ok(robot.move_linear_relative_and_wait(&d, LinearFrame::Tool, &full_speed()));
    let last = flange(&mut robot);
    let expected = after.translation.vector + after.rotation * d;
    assert!((last.translation.vector - expected).norm() < 1e-6);
    // the pose query agrees with the kinematics
    let pose = ok(robot.pose_mm_deg());
    assert!((Vector3::new(pose[0], pose[1], pose[2]) - last.translation.vector).norm() < 1e-6);
}

#[test]
fn joint_limit_is_a_device_fault_with_the_code_and_reset_recovers() {
    let sim = fast_sim();
    let mut robot = ready(&sim);
    let over = ArmJoints::from_deg_array([0.0, 100.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(err_kind(robot.move_joints(&over, &full_speed())), ErrorKind::DeviceFault { code: 1007 });
    let s = ok(robot.status());
    assert_eq!(s.error.as_ref().map(|e| e.0), Some(1007), "{s:?}");
    // later commands are refused with [1011]; the driver reports the original cause
    assert_eq!(err_kind(robot.wait_idle(TIMEOUT)), ErrorKind::DeviceFault { code: 1007 });
    ok(robot.reset_error());
    let s = ok(robot.status());
    assert!(s.error.is_none() && s.activated, "{s:?}");
    assert!(!sim.state().status.paused, "reset_error resumes motion");
    ok(robot
        .move_joints_and_wait(&ArmJoints::from_deg_array([0.0, 10.0, 0.0, 0.0, 20.0, 0.0]), &full_speed()));
}

#[test]
fn execution_errors_fail_the_wait() {
    let sim = fast_sim();
    let mut robot = ready(&sim);
    // singularity on a Cartesian move at q5 = 0
    assert!(sim.state().joints_deg[4].abs() < 1e-12);
    // (the robot may refuse at once, or while the driver waits)
    let up = Vector3::new(0.0, 0.0, 1.0);
    let result = robot
        .move_linear_relative(&up, LinearFrame::World, &full_speed())
        .and_then(|()| robot.wait_idle(TIMEOUT));
    assert_eq!(err_kind(result), ErrorKind::DeviceFault { code: 1012 });
    ok(robot.reset_error());
    // an asynchronous motion error while waiting
    let slow = MotionOptions { speed_fraction: 0.01, timeout: TIMEOUT };
    ok(robot.move_joints(&ArmJoints::from_deg_array([60.0, 0.0, 0.0, 0.0, 0.0, 0.0]), &slow));
    let result = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(50));
            sim.inject_error(code::MOTION_ERROR, "Collision detected.");
        });
        robot.wait_idle(TIMEOUT)
    });
    assert_eq!(err_kind(result), ErrorKind::DeviceFault { code: 3005 });
    ok(robot.reset_error());
    assert!(ok(robot.status()).error.is_none());
}

#[test]
fn estop_needs_reset_and_reactivation() {
    let sim = fast_sim();
    let mut robot = ready(&sim);
    sim.set_estop(true);
    let deadline = Instant::now() + TIMEOUT;
    let status = loop {
        let s = ok(robot.status());
        if s.error.is_some() || Instant::now() > deadline {
            break s;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert_eq!(status.error.map(|e| e.0), Some(3070));
    assert!(!status.activated);
    assert_eq!(err_kind(robot.reset_error()), ErrorKind::DeviceFault { code: 1025 }, "not while pressed");
    sim.set_estop(false);
    ok(robot.reset_error());
    ok(robot.activate_and_home(TIMEOUT));
    ok(robot.move_joints_and_wait(&ArmJoints::from_deg_array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]), &full_speed()));
}

#[test]
fn stalled_robot_times_out_and_recovers() {
    let sim = fast_sim();
    let mut robot = connect(&sim, Meca500Config { io_timeout: Duration::from_millis(200), ..config() });
    sim.set_stalled(true);
    let t0 = Instant::now();
    assert_eq!(err_kind(robot.status()), ErrorKind::Timeout);
    assert_eq!(err_kind(robot.joints()), ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    sim.set_stalled(false);
    ok(robot.status());
}

#[test]
fn dropped_connection_is_disconnected() {
    let sim = fast_sim();
    let mut robot = connect(&sim, config());
    ok(robot.status());
    sim.drop_client();
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(err_kind(robot.status()), ErrorKind::Disconnected);
    // a new client is accepted once the old one is gone
    let mut again = connect(&sim, config());
    ok(again.status());
}

#[test]
fn second_client_is_refused_busy() {
    let sim = fast_sim();
    let _first = connect(&sim, config());
    match Meca500::connect_tcp(sim.control_addr(), config()) {
        Ok(_) => panic!("second client accepted"),
        Err(e) => assert_eq!(e.into_hw("meca500").kind(), ErrorKind::Busy),
    }
}

/// Reads frames until `pred` matches one (bounded by `timeout`).
fn read_until(
    stream: &mut TcpStream,
    d: &mut Deframer,
    timeout: Duration,
    pred: impl Fn(&Reply) -> bool,
) -> Vec<Reply> {
    let deadline = Instant::now() + timeout;
    let mut seen = Vec::new();
    let mut buf = [0u8; 4096];
    while Instant::now() < deadline {
        while let Ok(Some(frame)) = d.next_frame() {
            let r = ok(Reply::parse(&frame));
            let done = pred(&r);
            seen.push(r);
            if done {
                return seen;
            }
        }
        ok(stream.set_read_timeout(Some(Duration::from_millis(20))));
        if let Ok(n) = stream.read(&mut buf) {
            if n == 0 {
                break;
            }
            d.push(&buf[..n]);
        }
    }
    panic!("condition not met within {timeout:?}; saw {seen:?}");
}

#[test]
fn raw_transcript_of_the_reference_connect_sequence() {
    // protocols.md §1.4, as mecademicpy sends it to a v9.3.0 robot
    let sim = fast_sim();
    let mut s = ok(TcpStream::connect(sim.control_addr()));
    let mut d = Deframer::nul_only();
    let banner = read_until(&mut s, &mut d, TIMEOUT, |_| true);
    assert_eq!(banner[0].to_text(), "[3000][Connected to Meca500 R3 v9.3.0]");
    let exchange = [
        ("-GetRobotSerial", "[2083][M500-0000]"),
        ("-GetFwVersionFull", "[2082][9.3.0.0-sim]"),
        ("-GetRealTimeMonitoring", "[2117][]"),
        ("-GetMonitoringInterval", "[2116][0.015]"),
    ];
    ok(s.write_all(b"\0"));
    for (cmd, answer) in exchange {
        ok(s.write_all(format!("{cmd}\0").as_bytes()));
        let got = read_until(&mut s, &mut d, TIMEOUT, |_| true);
        assert_eq!(got[0].to_text(), answer);
    }
    ok(s.write_all(b"-SetRtc(1795314763)\0-SetCtrlPortMonitoring(1)\n"));
    let got = read_until(&mut s, &mut d, TIMEOUT, |r| r.code == code::STATUS);
    assert_eq!(got[0].to_text(), "[2096][1]");
    assert_eq!(got[got.len() - 1].to_text(), "[2007][0,0,0,0,0,1,1]");
    // mirrored monitoring stream: cycles end with [2230]
    read_until(&mut s, &mut d, TIMEOUT, |r| r.code == code::RT_CYCLE_END);
    // overlong command without terminator → [3003]
    ok(s.write_all(&vec![b'A'; 5000]));
    read_until(&mut s, &mut d, TIMEOUT, |r| r.code == code::COMMAND_TOO_LONG);
}

#[test]
fn monitoring_port_streams_state_to_several_clients() {
    let sim = fast_sim();
    let Some(addr) = sim.monitoring_addr() else { panic!("monitoring disabled") };
    let mut a = ok(TcpStream::connect(addr));
    let mut b = ok(TcpStream::connect(addr));
    for s in [&mut a, &mut b] {
        let mut d = Deframer::nul_only();
        let first = read_until(s, &mut d, TIMEOUT, |r| r.code == code::STATUS);
        assert_eq!(first[0].code, code::CONNECTED);
        let cycle = read_until(s, &mut d, TIMEOUT, |r| r.code == code::RT_CYCLE_END);
        assert!(cycle.iter().any(|r| r.code == code::JOINTS));
    }
    // a status change is pushed
    let mut robot = connect(&sim, config());
    ok(robot.activate_and_home(TIMEOUT));
    let mut d = Deframer::nul_only();
    read_until(&mut a, &mut d, TIMEOUT, |r| r.to_text() == "[2007][1,1,0,0,0,1,1]");
}

#[test]
fn simulator_stops_when_dropped() {
    let sim = fast_sim();
    let addr = sim.control_addr();
    drop(sim);
    assert!(TcpStream::connect_timeout(&addr, Duration::from_millis(500)).is_err());
}

/// A move that lasts longer than one wait (a caller waiting in short slices, e.g. to check a
/// Ctrl-C flag between them): each slice that ends before the motion reports a timeout
/// (`MotionNotFinished`, kind `Timeout`) **without stopping the robot** — it still answers, so
/// it is not a link fault — and the motion ends at its target. (Before, the first slice's
/// timeout sent `ClearMotion`, which pauses the robot: every later slice timed out too.)
#[test]
fn a_motion_longer_than_a_wait_slice_is_not_stopped() {
    // real time: a 20° move of joint 1 at 10 % speed takes more than a second
    let sim = Meca500Sim::start(SimConfig::fast(1.0)).unwrap_or_else(|e| panic!("sim: {e}"));
    let mut robot = ready(&sim);
    let target = ArmJoints::new([20.0f64.to_radians(), 0.0, 0.0, 0.0, 0.0, 0.0]);
    ok(robot.move_joints(&target, &MotionOptions { speed_fraction: 0.1, timeout: TIMEOUT }));
    let start = Instant::now();
    let mut timeouts = 0;
    loop {
        match robot.wait_idle(Duration::from_millis(100)) {
            Ok(()) => break,
            Err(e) if e.kind() == ErrorKind::Timeout => {
                assert!(e.to_string().contains("still moving"), "{e}");
                timeouts += 1;
            }
            Err(e) => panic!("slice {timeouts}: {e}"),
        }
        assert!(start.elapsed() < Duration::from_secs(20), "the motion never ended");
    }
    assert!(timeouts >= 2, "the move should outlast a few slices ({timeouts} timeouts)");
    let q = ok(robot.joints());
    assert!((q.values()[0] - target.values()[0]).abs() < 1e-3, "joint 1 at {} rad", q.values()[0]);
}
