//! Every tracker fault is one clear error of the right kind, and the driver goes on after it:
//! lost line of sight, silence (timeout), garbled answers, a closed link, overlong lines, a
//! late answer after a timeout; for the command tracker a timeout, a non-zero exit and garbage.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use vatcal_drivers_tracker::sim::{SimConfig, TrackerSim};
use vatcal_drivers_tracker::{CommandTracker, CommandTrackerConfig, LineTracker, TrackerConfig};
use vatcal_hardware_traits::{ErrorKind, PositionTracker};

fn connect(sim: &TrackerSim, io_ms: u64) -> LineTracker {
    let config = TrackerConfig { io_timeout: Duration::from_millis(io_ms), ..TrackerConfig::default() };
    LineTracker::connect_tcp(sim.addr(), config).expect("connect")
}

fn sim_with_target() -> (TrackerSim, Vector3<f64>) {
    let sim = TrackerSim::start(SimConfig::default()).expect("sim");
    let p = Vector3::new(10.0, 20.0, 30.0);
    sim.set_target_mm(1, p);
    (sim, p)
}

#[test]
fn line_of_sight_loss_is_out_of_range_then_recovers() {
    let (sim, p) = sim_with_target();
    let mut t = connect(&sim, 1000);
    sim.set_line_of_sight(false);
    let e = t.measure_mm(1).expect_err("los");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("at 127.0.0.1:") && e.to_string().contains("line of sight lost"), "{e}");
    sim.set_line_of_sight(true);
    assert_eq!(t.measure_mm(1).expect("visible again"), p);
}

#[test]
fn silence_is_a_timeout_and_the_late_answer_is_skipped() {
    let (sim, p) = sim_with_target();
    let mut t = connect(&sim, 150);
    sim.set_stalled(true);
    let start = Instant::now();
    let e = t.measure_mm(1).expect_err("stalled");
    assert!(e.is_timeout(), "{e}");
    assert!(e.to_string().contains("no answer to 'MEASURE 1' within 0.150 s"), "{e}");
    assert!(start.elapsed() < Duration::from_secs(1));
    sim.set_target_mm(1, p * 2.0);
    sim.set_stalled(false); // the held request is answered now: a late answer
    std::thread::sleep(Duration::from_millis(30));
    assert_eq!(t.measure_mm(1).expect("next request"), p * 2.0);
}

#[test]
fn garbled_answers_are_protocol_errors() {
    let (sim, p) = sim_with_target();
    let mut t = connect(&sim, 1000);
    sim.set_garbled(true);
    let e = t.measure_mm(1).expect_err("garbage");
    assert_eq!(e.kind(), ErrorKind::Protocol);
    assert!(e.to_string().contains("answered garbage"), "{e}");
    sim.set_garbled(false);
    assert_eq!(t.measure_mm(1).expect("clean again"), p);
}

#[test]
fn a_closed_link_is_disconnected() {
    let (sim, _) = sim_with_target();
    let mut t = connect(&sim, 1000);
    sim.drop_clients();
    std::thread::sleep(Duration::from_millis(30));
    let e = t.measure_mm(1).expect_err("closed");
    assert_eq!(e.kind(), ErrorKind::Disconnected, "{e}");
}

/// A raw server: answers `ID?`, then the given bytes to the first `MEASURE`, then closes.
fn raw_server(answer: &'static [u8]) -> std::net::SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr");
    std::thread::spawn(move || {
        let Ok((stream, _)) = listener.accept() else { return };
        let mut reader = BufReader::new(stream.try_clone().expect("clone"));
        let mut w = stream;
        let mut line = String::new();
        while reader.read_line(&mut line).is_ok_and(|n| n > 0) {
            let id = line.split_whitespace().next().unwrap_or("0").to_owned();
            if line.contains("ID?") {
                let _ = w.write_all(format!("{id} OK raw\n").as_bytes());
            } else {
                let _ = w.write_all(answer);
                std::thread::sleep(Duration::from_millis(50));
                return;
            }
            line.clear();
        }
    });
    addr
}

#[test]
fn raw_garbage_overlong_lines_and_truncation() {
    let config = || TrackerConfig { io_timeout: Duration::from_millis(300), ..TrackerConfig::default() };
    let cases: [(&'static [u8], ErrorKind, &str); 5] = [
        (b"\xff\xfe\x00garbage\n", ErrorKind::Protocol, "does not start with a request id"),
        (b"2 OK 1 2\n", ErrorKind::Protocol, "is not `x y z`"),
        (b"2 ERR BOOM x\n", ErrorKind::Protocol, "unknown error code"),
        (&[b'7'; 400], ErrorKind::Protocol, "longer than 256 bytes"),
        (b"2 OK 1 2 ", ErrorKind::Disconnected, "closed"),
    ];
    for (answer, kind, text) in cases {
        let mut t = LineTracker::connect_tcp(raw_server(answer), config()).expect("connect");
        let e = t.measure_mm(1).expect_err("fault");
        assert_eq!(e.kind(), kind, "{e}");
        assert!(e.to_string().contains(text), "{text}: {e}");
    }
    // a device fault keeps the tracker's words
    let mut t =
        LineTracker::connect_tcp(raw_server(b"2 ERR DEVICE laser not warmed up\n"), config()).expect("c");
    let e = t.measure_mm(1).expect_err("fault");
    assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 0 });
    assert!(e.to_string().contains("laser not warmed up"), "{e}");
}

fn script(body: &str, timeout_ms: u64) -> CommandTracker {
    CommandTracker::new(CommandTrackerConfig {
        timeout: Duration::from_millis(timeout_ms),
        ..CommandTrackerConfig::new("sh", vec!["-c".into(), body.into()])
    })
}

#[test]
fn command_tracker_faults() {
    let e = script("sleep 5", 150).measure_mm(1).expect_err("slow");
    assert!(e.is_timeout() && e.to_string().contains("killed") && e.to_string().contains("target 1"), "{e}");
    let e = script("echo 'SDK: no tracker on 10.0.0.5' >&2; exit 2", 5000).measure_mm(1).expect_err("exit");
    assert_eq!(e.kind(), ErrorKind::DeviceFault { code: 2 });
    assert!(e.to_string().contains("no tracker on 10.0.0.5"), "{e}");
    let e = script("echo 'x=1 y=2 z=3'", 5000).measure_mm(1).expect_err("garbage");
    assert_eq!(e.kind(), ErrorKind::Protocol);
    assert!(e.to_string().contains("garbled answer `x=1 y=2 z=3`"), "{e}");
    let e = script("true", 5000).measure_mm(1).expect_err("nothing");
    assert_eq!(e.kind(), ErrorKind::Protocol);
    let e = script("echo LOS SMR blocked by the arm", 5000).measure_mm(1).expect_err("los");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    let e = CommandTracker::new(CommandTrackerConfig::new("/nonexistent/faro-bridge", vec![]))
        .measure_mm(1)
        .expect_err("missing");
    assert!(e.to_string().contains("/nonexistent/faro-bridge"), "{e}");
}
