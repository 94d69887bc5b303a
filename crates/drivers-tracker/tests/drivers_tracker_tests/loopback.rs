//! The tracker drivers against their counterparts: the line-protocol driver against the
//! simulator over real TCP, the command driver against small shell scripts, the console
//! driver against a scripted operator.

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_drivers_tracker::sim::{SimConfig, SimFault, TargetSource, TrackerSim};
use vatcal_drivers_tracker::{
    CommandTracker, CommandTrackerConfig, ConsoleTracker, LineTracker, TrackerConfig,
};
use vatcal_hardware_traits::{ErrorKind, PROBE_NEST_TARGET, PositionTracker};

fn config() -> TrackerConfig {
    TrackerConfig { io_timeout: Duration::from_secs(2), ..TrackerConfig::default() }
}

#[test]
fn line_tracker_reads_targets_and_identifies() {
    let sim =
        TrackerSim::start(SimConfig { identity: "FARO Vantage E (sim)".into(), ..SimConfig::default() })
            .expect("sim");
    let p = Vector3::new(812.123456, -40.5, 1300.000001);
    sim.set_target_mm(2, p);
    sim.set_target_mm(PROBE_NEST_TARGET, Vector3::new(1.0, 2.0, 3.0));
    let mut t = LineTracker::connect_tcp(sim.addr(), config()).expect("connect");
    assert_eq!(t.identity(), "FARO Vantage E (sim)");
    assert!(t.label().starts_with("tracker at 127.0.0.1:"), "{}", t.label());
    for _ in 0..3 {
        let got = t.measure_mm(2).expect("reads");
        assert!((got - p).norm() < 1e-6, "to the wire's 1 nm: {got}");
    }
    assert_eq!(t.measure_mm(PROBE_NEST_TARGET).expect("nest"), Vector3::new(1.0, 2.0, 3.0));
    let e = t.measure_mm(7).expect_err("unknown target");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("unknown target: no target 7"), "{e}");
    assert_eq!(sim.measurements(), 5);
    // the boxed trait object works the same
    let mut boxed: Box<dyn PositionTracker> = Box::new(t);
    assert!((boxed.measure_mm(2).expect("boxed") - p).norm() < 1e-6);
}

/// A world that moves the target with every reading and loses the line of sight on target 3.
#[derive(Debug)]
struct Drifting(std::sync::atomic::AtomicU32);

impl TargetSource for Drifting {
    fn measure_mm(&self, target: u32) -> Result<Vector3<f64>, SimFault> {
        if target == 3 {
            return Err(SimFault::LineOfSight("SMR 3 turned away".into()));
        }
        let n = self.0.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Ok(Vector3::new(f64::from(n), f64::from(target), 0.0))
    }

    fn measure_duration(&self) -> Option<Duration> {
        Some(Duration::from_millis(30))
    }
}

#[test]
fn a_world_source_decides_readings_and_timing() {
    let sim = TrackerSim::start(SimConfig {
        source: Some(std::sync::Arc::new(Drifting(0.into()))),
        ..SimConfig::default()
    })
    .expect("sim");
    let mut t = LineTracker::connect_tcp(sim.addr(), config()).expect("connect");
    let start = std::time::Instant::now();
    assert_eq!(t.measure_mm(1).expect("first"), Vector3::new(0.0, 1.0, 0.0));
    assert_eq!(t.measure_mm(2).expect("second"), Vector3::new(1.0, 2.0, 0.0));
    assert!(start.elapsed() >= Duration::from_millis(60), "each answer waits its measurement time");
    let e = t.measure_mm(3).expect_err("los");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("line of sight lost: SMR 3 turned away"), "{e}");
}

fn script(body: &str) -> CommandTracker {
    CommandTracker::new(CommandTrackerConfig {
        timeout: Duration::from_secs(5),
        ..CommandTrackerConfig::new("sh", vec!["-c".into(), body.into()])
    })
}

#[test]
fn command_tracker_gets_target_point_and_hint() {
    // the script answers with what it was given: x = target, y = point, z = nominal x
    let mut t = script(
        "set -- $VATCAL_TRACKER_NOMINAL_MM; echo \"$VATCAL_TRACKER_TARGET, $VATCAL_TRACKER_POINT, ${1:-0}\"",
    );
    assert_eq!(t.measure_mm(2).expect("first"), Vector3::new(2.0, 1.0, 0.0));
    let hint = Vector3::new(-12.25, 3.0, 4.0);
    assert_eq!(t.measure_near_mm(3, Some(&hint)).expect("second"), Vector3::new(3.0, 2.0, -12.25));
    assert_eq!(t.label(), "tracker command `sh`");
}

#[test]
fn console_tracker_reads_the_operator() {
    let mut out = Vec::new();
    let mut t = ConsoleTracker::new("100 200 300\n\n1;2;3mm\n".as_bytes(), &mut out);
    assert_eq!(t.measure_mm(1).expect("first"), Vector3::new(100.0, 200.0, 300.0));
    assert_eq!(t.measure_mm(2).expect("blank line re-asked"), Vector3::new(1.0, 2.0, 3.0));
    assert_eq!(t.measure_mm(3).expect_err("end of input").kind(), ErrorKind::Cancelled);
}
