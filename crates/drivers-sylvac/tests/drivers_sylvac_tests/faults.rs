//! Driver-level faults over real TCP: each surfaces as ONE error line naming the gauge and its
//! address (`gauge 1 at 127.0.0.1:PORT: …`). Simulator faults use the simulator's fault
//! injection; garbled and truncated answers come from a tiny raw TCP gauge in this file.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::time::{Duration, Instant};

use vatcal_drivers_sylvac::codec::LineDeframer;
use vatcal_drivers_sylvac::sim::{SimConfig, SylvacSim};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_hardware_traits::{ErrorKind, Gauge};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn config() -> SylvacConfig {
    SylvacConfig {
        name: "gauge 1".to_owned(),
        io_timeout: Duration::from_millis(200),
        ..SylvacConfig::default()
    }
}

/// Checks kind, one line, and the `gauge 1 at ADDR: ` prefix; returns the line.
fn one_line<T: std::fmt::Debug>(
    r: vatcal_hardware_traits::Result<T>,
    addr: SocketAddr,
    kind: ErrorKind,
) -> String {
    vatcal_hardware_traits::testing::expect_one_line_error(r, &format!("gauge 1 at {addr}: "), kind)
}

fn sim_gauge() -> (SylvacSim, SylvacGauge) {
    let sim = ok(SylvacSim::start(SimConfig::default()));
    let gauge = ok(SylvacGauge::connect_tcp(sim.addr(), config()));
    (sim, gauge)
}

#[test]
fn connection_dropped() {
    let (sim, mut gauge) = sim_gauge();
    ok(gauge.read_mm());
    sim.drop_clients();
    std::thread::sleep(Duration::from_millis(50));
    let line = one_line(gauge.read_mm(), sim.addr(), ErrorKind::Disconnected);
    assert!(line.contains("connection closed while"), "{line}");
}

#[test]
fn stalled_gauge_times_out() {
    let (sim, mut gauge) = sim_gauge();
    sim.set_stalled(true);
    let t0 = Instant::now();
    let line = one_line(gauge.read_mm(), sim.addr(), ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(1), "{:?}", t0.elapsed());
    assert!(line.ends_with("no answer to '?' within 0.200 s"), "{line}");
    sim.set_stalled(false);
    // the late answer is discarded, the next reading is fresh
    sim.set_plunger_mm(2.5);
    let mm = ok(gauge.read_mm());
    assert!((mm - 2.5).abs() < 1e-9, "{mm}");
}

#[test]
fn gauge_out_of_range() {
    let (sim, mut gauge) = sim_gauge();
    sim.set_plunger_mm(13.0); // beyond the 12.5 mm range
    let line = one_line(gauge.read_mm(), sim.addr(), ErrorKind::OutOfRange);
    assert!(line.contains("ERR3"), "{line}");
    sim.set_plunger_mm(1.0);
    ok(gauge.read_mm());
}

#[test]
fn sensor_fault() {
    let (sim, mut gauge) = sim_gauge();
    sim.set_sensor_error(true);
    one_line(gauge.read_mm(), sim.addr(), ErrorKind::DeviceFault { code: 0 });
}

/// A raw gauge: identifies itself normally, answers `?` with `reading` (raw bytes), then
/// closes if `close`.
fn raw_gauge(reading: &'static [u8], close: bool) -> SocketAddr {
    let listener = ok(TcpListener::bind("127.0.0.1:0"));
    let addr = ok(listener.local_addr());
    std::thread::spawn(move || {
        let Ok((mut stream, _)) = listener.accept() else { return };
        let _ = stream.set_read_timeout(Some(Duration::from_millis(5)));
        let mut d = LineDeframer::new();
        let mut buf = [0u8; 256];
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(5) {
            match stream.read(&mut buf) {
                Ok(0) => return,
                Ok(n) => d.push(&buf[..n]),
                Err(_) => {}
            }
            while let Ok(Some(line)) = d.next_line() {
                let answer: &[u8] = match line.trim() {
                    "ID?" => b"SY289\r",
                    "UNI?" => b"MM\r",
                    "?" => reading,
                    _ => b"",
                };
                let _ = stream.write_all(answer);
                if line.trim() == "?" && close {
                    return;
                }
            }
        }
    });
    addr
}

#[test]
fn garbled_answer_is_a_protocol_error() {
    let addr = raw_gauge(b"+0#1.2\xff\r", false);
    let mut gauge = ok(SylvacGauge::connect_tcp(addr, config()));
    let line = one_line(gauge.read_mm(), addr, ErrorKind::Protocol);
    assert!(line.contains("'?' answered"), "{line}");
}

#[test]
fn truncated_answer_then_close_is_a_disconnection() {
    let addr = raw_gauge(b"+001.2", true);
    let mut gauge = ok(SylvacGauge::connect_tcp(addr, config()));
    let line = one_line(gauge.read_mm(), addr, ErrorKind::Disconnected);
    assert!(line.ends_with("connection closed while waiting for the answer to '?'"), "{line}");
}

#[test]
fn truncated_answer_then_silence_times_out() {
    let addr = raw_gauge(b"+001.2", false);
    let mut gauge = ok(SylvacGauge::connect_tcp(addr, config()));
    one_line(gauge.read_mm(), addr, ErrorKind::Timeout);
}

#[test]
fn overlong_answer_is_a_framing_error_not_a_hang() {
    static LONG: [u8; 400] = [b'7'; 400];
    let addr = raw_gauge(&LONG, false);
    let mut gauge = ok(SylvacGauge::connect_tcp(addr, config()));
    let line = one_line(gauge.read_mm(), addr, ErrorKind::Protocol);
    assert!(line.contains("longer than 256 bytes"), "{line}");
}
