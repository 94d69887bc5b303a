//! The driver against the simulator over real TCP on 127.0.0.1 (ephemeral ports). Every wait
//! is bounded; the simulator stops when dropped.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use vatcal_drivers_zaber::codec::{LineDeframer, Warning};
use vatcal_drivers_zaber::sim::{SimConfig, ZaberSim};
use vatcal_drivers_zaber::{LineEnding, MicrostepSize, ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::{ErrorKind, LinearAxis, MotionOptions};

const TIMEOUT: Duration = Duration::from_secs(5);

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn err_kind<T: std::fmt::Debug>(r: vatcal_hardware_traits::Result<T>) -> ErrorKind {
    match r {
        Ok(v) => panic!("expected an error, got {v:?}"),
        Err(e) => e.kind(),
    }
}

fn sim(config: SimConfig) -> ZaberSim {
    ok(ZaberSim::start(config))
}

fn config() -> ZaberConfig {
    ZaberConfig { poll_interval: Duration::from_millis(5), ..ZaberConfig::default() }
}

fn connect(sim: &ZaberSim, config: ZaberConfig) -> ZaberAxis {
    ok(ZaberAxis::connect_tcp(sim.addr(), config))
}

fn fast() -> MotionOptions {
    MotionOptions { speed_fraction: 1.0, timeout: TIMEOUT }
}

#[test]
fn identifies_the_axis_and_converts_units() {
    let s = sim(SimConfig::fast(50.0));
    let guide = connect(&s, config());
    let info = *guide.info();
    assert_eq!(info.resolution, 64);
    assert!((info.microstep_mm - 2.5 / 12_800.0).abs() < 1e-15);
    assert_eq!(info.limits_microsteps, Some((0, 1_536_000)));
    let (lo, hi) = info.travel_mm().unwrap_or_default();
    assert!(lo == 0.0 && (hi - 300.0).abs() < 1e-9);
    assert_eq!(guide.mm_to_microsteps(120.0), 614_400);
    assert!((guide.microsteps_to_mm(614_400) - 120.0).abs() < 1e-12);
}

#[test]
fn home_then_move_and_read_back() {
    let s = sim(SimConfig::fast(50.0));
    let mut guide = connect(&s, config());
    assert!(!ok(guide.is_homed()));
    assert_eq!(err_kind(guide.move_absolute_mm(10.0, &fast())), ErrorKind::NotHomed);
    ok(guide.home(TIMEOUT));
    assert!(ok(guide.is_homed()));
    assert_eq!(ok(guide.position_mm()), 0.0);
    ok(guide.move_absolute_and_wait(120.0, &fast()));
    assert!((ok(guide.position_mm()) - 120.0).abs() < 1e-9);
    assert_eq!(s.state().pos_microsteps, 614_400.0);
    ok(guide.move_absolute_and_wait(0.1234, &fast()));
    let microstep = guide.info().microstep_mm;
    assert!((ok(guide.position_mm()) - 0.1234).abs() <= microstep / 2.0 + 1e-12);
}

#[test]
fn fixed_microstep_size_and_plain_protocol_options() {
    // X-LRQ300BL-E01 style 0.49609375 um microsteps; no checksums, no ids, CRLF (zaber-serial style)
    let microstep_mm = 0.000_496_093_75;
    let s = sim(SimConfig { microstep_mm, start_homed: true, ..SimConfig::fast(50.0) });
    let cfg = ZaberConfig {
        microstep: MicrostepSize::Fixed { mm: microstep_mm },
        checksums: false,
        message_ids: false,
        line_ending: LineEnding::CrLf,
        ..config()
    };
    let mut guide = connect(&s, cfg);
    ok(guide.move_absolute_and_wait(100.0, &fast()));
    assert_eq!(s.state().pos_microsteps, (100.0 / microstep_mm).round());
    assert!((ok(guide.position_mm()) - 100.0).abs() < microstep_mm);
}

#[test]
fn out_of_range_targets() {
    let s = sim(SimConfig { start_homed: true, ..SimConfig::fast(50.0) });
    let mut guide = connect(&s, config());
    assert_eq!(err_kind(guide.move_absolute_mm(300.5, &fast())), ErrorKind::OutOfRange);
    assert_eq!(err_kind(guide.move_absolute_mm(-1.0, &fast())), ErrorKind::OutOfRange);
    assert_eq!(err_kind(guide.move_absolute_mm(f64::NAN, &fast())), ErrorKind::OutOfRange);
    // the device's own refusal maps the same way
    match guide.command(1, "move abs 99999999") {
        Ok(r) => panic!("accepted: {r:?}"),
        Err(e) => assert_eq!(e.into_hw("guide").kind(), ErrorKind::OutOfRange),
    }
    assert!(!s.state().busy);
}

#[test]
fn speed_fraction_scales_maxspeed() {
    let s = sim(SimConfig { start_homed: true, ..SimConfig::fast(50.0) });
    let base = s.state().maxspeed;
    let mut guide = connect(&s, config());
    ok(guide.move_absolute_mm(5.0, &MotionOptions { speed_fraction: 0.5, timeout: TIMEOUT }));
    assert_eq!(s.state().maxspeed, (base as f64 * 0.5).round() as i64, "during the move");
    ok(guide.wait_idle(TIMEOUT));
    assert_eq!(s.state().maxspeed, base, "set back when the move has ended");
    ok(guide.move_absolute_and_wait(6.0, &fast()));
    assert_eq!(s.state().maxspeed, base);
    // the next session reads the full speed again: fractions do not compound (a resumed
    // campaign at 25 % would otherwise move at 25 % of 25 %)
    ok(guide.move_absolute_and_wait(7.0, &MotionOptions { speed_fraction: 0.25, timeout: TIMEOUT }));
    drop(guide);
    let again = connect(&s, config());
    assert_eq!(again.info().base_maxspeed, Some(base));
}

#[test]
fn busy_stop_and_bounded_waits() {
    let s = sim(SimConfig { start_homed: true, ..SimConfig::default() }); // real time: 300 mm take 15 s
    let mut guide = connect(&s, config());
    ok(guide.move_absolute_mm(300.0, &fast()));
    assert_eq!(err_kind(guide.move_absolute_mm(10.0, &fast())), ErrorKind::Busy);
    let t0 = Instant::now();
    assert_eq!(err_kind(guide.wait_idle(Duration::from_millis(100))), ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2));
    // a wait that times out while the axis answers leaves it moving (a caller waiting in
    // slices waits again): it is still on its way, not stopped
    let moving = ok(guide.position_mm());
    std::thread::sleep(Duration::from_millis(100));
    assert!(ok(guide.position_mm()) > moving, "the axis stopped after a timed-out wait");
    ok(guide.stop());
    let p = ok(guide.position_mm());
    assert!(p > 0.0 && p < 300.0, "{p}");
    assert!(s.state().flags.is_empty(), "stop clears NI: {:?}", s.state().flags);
    ok(guide.move_absolute_and_wait(p - 0.5, &fast()));
}

#[test]
fn stall_and_limit_faults_fail_the_wait_with_the_flag_code() {
    let s = sim(SimConfig { start_homed: true, ..SimConfig::default() });
    let mut guide = connect(&s, config());
    for (inject, flag) in [(0, Warning::STALL), (1, Warning::LIMIT)] {
        ok(guide.move_absolute_mm(if inject == 0 { 200.0 } else { 10.0 }, &fast()));
        let result = std::thread::scope(|scope| {
            scope.spawn(|| {
                std::thread::sleep(Duration::from_millis(30));
                if inject == 0 { s.inject_stall() } else { s.inject_limit_hit() }
            });
            guide.wait_idle(TIMEOUT)
        });
        assert_eq!(err_kind(result), ErrorKind::DeviceFault { code: flag.code() });
        assert!(s.state().flags.is_empty(), "flags cleared after reporting");
    }
    ok(guide.move_absolute_and_wait(10.5, &MotionOptions { speed_fraction: 1.0, timeout: TIMEOUT }));
}

#[test]
fn stalled_device_times_out() {
    let s = sim(SimConfig::fast(50.0));
    let mut guide = connect(&s, ZaberConfig { io_timeout: Duration::from_millis(200), ..config() });
    s.set_stalled(true);
    let t0 = Instant::now();
    assert_eq!(err_kind(guide.position_mm()), ErrorKind::Timeout);
    assert_eq!(err_kind(guide.is_homed()), ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2));
    s.set_stalled(false);
    // late replies carry old message ids and are skipped
    assert!(!ok(guide.is_homed()));
}

#[test]
fn dropped_connection_is_disconnected() {
    let s = sim(SimConfig::fast(50.0));
    let mut guide = connect(&s, config());
    ok(guide.position_mm());
    s.drop_clients();
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(err_kind(guide.position_mm()), ErrorKind::Disconnected);
}

/// Sends `line` on a raw socket and returns the next lines (bounded wait).
fn raw(stream: &mut TcpStream, d: &mut LineDeframer, line: &[u8], n: usize) -> Vec<String> {
    raw_within(stream, d, line, n, TIMEOUT)
}

fn raw_within(
    stream: &mut TcpStream,
    d: &mut LineDeframer,
    line: &[u8],
    n: usize,
    timeout: Duration,
) -> Vec<String> {
    ok(stream.write_all(line));
    let deadline = Instant::now() + timeout;
    let mut lines = Vec::new();
    let mut buf = [0u8; 1024];
    while lines.len() < n && Instant::now() < deadline {
        while let Ok(Some(l)) = d.next_line() {
            lines.push(l);
        }
        if lines.len() >= n {
            break;
        }
        ok(stream.set_read_timeout(Some(Duration::from_millis(20))));
        if let Ok(k) = stream.read(&mut buf) {
            d.push(&buf[..k]);
        }
    }
    lines
}

#[test]
fn raw_transcript_of_the_reference() {
    let s = sim(SimConfig::fast(50.0));
    let mut t = ok(TcpStream::connect(s.addr()));
    let mut d = LineDeframer::new();
    // protocols.md §2.2 worked example (zaber-motion style: id, checksum, LF)
    assert_eq!(raw(&mut t, &mut d, b"/1 1 00 get pos:2C\n", 1), ["@01 1 00 OK IDLE WR 0:BD"]);
    // wrong checksum: ignored
    assert!(raw_within(&mut t, &mut d, b"/1 1 00 get pos:2D\n", 1, Duration::from_millis(200)).is_empty());
    // zaber-serial style (CRLF, no id), §2.4 warnings
    assert_eq!(raw(&mut t, &mut d, b"/1 0 warnings\r\n", 1), ["@01 0 OK IDLE WR 01 WR"]);
    assert_eq!(raw(&mut t, &mut d, b"/1 0 get comm.packet.size.max\n", 1), ["@01 0 RJ IDLE WR BADCOMMAND"]);
    // broadcast status poll
    assert_eq!(raw(&mut t, &mut d, b"/0 0\r", 1), ["@01 0 OK IDLE WR 0"]);
    // alerts when enabled
    raw(&mut t, &mut d, b"/1 0 set comm.alert 1\n", 1);
    // the reply, then the alert of the finished homing (in a later write; the read may get
    // both at once when the homing is this quick)
    let lines = raw(&mut t, &mut d, b"/1 1 home\n", 2);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(lines[0].starts_with("@01 1 OK BUSY"), "{lines:?}");
    assert_eq!(lines[1], "!01 1 IDLE --");
}

#[test]
fn simulator_stops_when_dropped() {
    let s = sim(SimConfig::default());
    let addr = s.addr();
    drop(s);
    assert!(TcpStream::connect_timeout(&addr, Duration::from_millis(500)).is_err());
}
