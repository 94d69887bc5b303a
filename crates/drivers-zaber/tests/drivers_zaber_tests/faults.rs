//! Driver-level faults over real TCP: each surfaces as ONE error line naming the guide and its
//! address (`zaber guide at 127.0.0.1:PORT: …`), and the driver leaves the axis stopped where
//! it can (after a lost or garbled answer it sends `stop` while the link is up). Simulator
//! faults use the simulator's fault injection; garbled and truncated replies come from a small
//! TCP server in this file that runs the simulator's device model and corrupts one reply.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vatcal_drivers_zaber::codec::{Command, LineDeframer, Warning};
use vatcal_drivers_zaber::sim::{SimConfig, SimDevice, ZaberSim};
use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::{ErrorKind, LinearAxis, MotionOptions};

const TIMEOUT: Duration = Duration::from_secs(5);

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn config() -> ZaberConfig {
    ZaberConfig {
        io_timeout: Duration::from_millis(300),
        poll_interval: Duration::from_millis(5),
        ..ZaberConfig::default()
    }
}

fn opts() -> MotionOptions {
    MotionOptions { speed_fraction: 1.0, timeout: TIMEOUT }
}

/// Checks kind, one line, and the `zaber guide at ADDR: ` prefix; returns the line.
fn one_line<T: std::fmt::Debug>(
    r: vatcal_hardware_traits::Result<T>,
    addr: SocketAddr,
    kind: ErrorKind,
) -> String {
    vatcal_hardware_traits::testing::expect_one_line_error(r, &format!("zaber guide at {addr}: "), kind)
}

/// A homed guide in real time (20 mm/s), a 200 mm move already started (10 s).
fn moving() -> (ZaberSim, ZaberAxis) {
    let sim = ok(ZaberSim::start(SimConfig { start_homed: true, ..SimConfig::default() }));
    let mut guide = ok(ZaberAxis::connect_tcp(sim.addr(), config()));
    ok(guide.move_absolute_mm(200.0, &opts()));
    (sim, guide)
}

fn after(ms: u64, f: impl FnOnce() + Send) -> impl FnOnce() + Send {
    move || {
        std::thread::sleep(Duration::from_millis(ms));
        f();
    }
}

fn eventually(pred: impl Fn() -> bool) -> bool {
    let deadline = Instant::now() + TIMEOUT;
    while Instant::now() < deadline {
        if pred() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    false
}

#[test]
fn connection_dropped_mid_move() {
    let (sim, mut guide) = moving();
    let addr = sim.addr();
    let r = std::thread::scope(|s| {
        s.spawn(after(50, || sim.drop_clients()));
        guide.wait_idle(TIMEOUT)
    });
    let line = one_line(r, addr, ErrorKind::Disconnected);
    assert!(line.contains("connection closed while"), "{line}");
}

#[test]
fn stalled_device_times_out_and_the_axis_is_stopped() {
    let (sim, mut guide) = moving();
    let addr = sim.addr();
    sim.set_stalled(true);
    let line = one_line(guide.wait_idle(Duration::from_millis(300)), addr, ErrorKind::Timeout);
    assert!(line.contains("within 0.300 s"), "{line}");
    // the `stop` the driver sent is executed once the device answers again
    sim.set_stalled(false);
    assert!(eventually(|| !sim.state().busy), "still moving: {:?}", sim.state());
    let mm = sim.state().pos_microsteps * guide.info().microstep_mm;
    assert!(mm < 100.0, "the guide went on to {mm} mm");
}

#[test]
fn stall_fault_during_a_move() {
    let (sim, mut guide) = moving();
    let addr = sim.addr();
    let r = std::thread::scope(|s| {
        s.spawn(after(50, || sim.inject_stall()));
        guide.wait_idle(TIMEOUT)
    });
    let line = one_line(r, addr, ErrorKind::DeviceFault { code: Warning::STALL.code() });
    assert!(line.contains("FS"), "{line}");
    assert!(!sim.state().busy);
}

#[test]
fn guide_not_homed() {
    let sim = ok(ZaberSim::start(SimConfig::fast(50.0)));
    let addr = sim.addr();
    let mut guide = ok(ZaberAxis::connect_tcp(addr, config()));
    let line = one_line(guide.move_absolute_mm(100.0, &opts()), addr, ErrorKind::NotHomed);
    assert!(line.ends_with("the axis is not homed (home it first)"), "{line}");
    assert!(!sim.state().busy);
}

/// What the corrupting server does to the reply it picks.
#[derive(Clone, Copy)]
enum Corruption {
    /// replace it with these bytes and go on serving
    Replace(&'static [u8]),
    /// send only its first `n` bytes, then close the connection
    TruncateAndClose(usize),
    /// send only its first `n` bytes, then answer nothing any more
    TruncateAndStall(usize),
}

/// A TCP device running the simulator's model; the first reply to a status poll (empty
/// command) that comes after a `move` is corrupted.
fn corrupting_device(config: SimConfig, how: Corruption) -> (SocketAddr, Arc<Mutex<SimDevice>>) {
    let listener = ok(TcpListener::bind("127.0.0.1:0"));
    let addr = ok(listener.local_addr());
    let device = Arc::new(Mutex::new(SimDevice::new(config)));
    let model = Arc::clone(&device);
    std::thread::spawn(move || {
        let Ok((mut stream, _)) = listener.accept() else { return };
        let _ = stream.set_read_timeout(Some(Duration::from_millis(5)));
        let start = Instant::now();
        let mut d = LineDeframer::new();
        let mut buf = [0u8; 1024];
        let (mut moved, mut corrupted, mut stalled) = (false, false, false);
        while start.elapsed() < TIMEOUT {
            match stream.read(&mut buf) {
                Ok(0) => return,
                Ok(n) => d.push(&buf[..n]),
                Err(_) => {}
            }
            while let Ok(Some(line)) = d.next_line() {
                let Ok((cmd, checksum)) = Command::parse(&line) else { continue };
                let reply = model.lock().ok().and_then(|mut m| m.handle(&cmd, start.elapsed()));
                let Some(reply) = reply else { continue };
                let bytes = reply.encode(checksum);
                moved |= cmd.text.starts_with("move");
                if stalled {
                    continue;
                }
                if moved && !corrupted && cmd.text.is_empty() {
                    corrupted = true;
                    match how {
                        Corruption::Replace(b) => {
                            let _ = stream.write_all(b);
                        }
                        Corruption::TruncateAndClose(n) => {
                            let _ = stream.write_all(&bytes[..n.min(bytes.len())]);
                            return;
                        }
                        Corruption::TruncateAndStall(n) => {
                            let _ = stream.write_all(&bytes[..n.min(bytes.len())]);
                            stalled = true;
                        }
                    }
                } else {
                    let _ = stream.write_all(&bytes);
                }
            }
        }
    });
    (addr, device)
}

fn busy(device: &Arc<Mutex<SimDevice>>) -> bool {
    device.lock().map(|d| d.snapshot(Duration::from_secs(3600)).busy).unwrap_or(true)
}

#[test]
fn garbled_reply_while_moving_is_a_protocol_error_and_stops_the_axis() {
    let homed = SimConfig { start_homed: true, ..SimConfig::default() };
    let (addr, device) = corrupting_device(homed, Corruption::Replace(b"@01 1 %% OK BUSY ?? 0\r\n"));
    let mut guide = ok(ZaberAxis::connect_tcp(addr, config()));
    ok(guide.move_absolute_mm(200.0, &opts()));
    one_line(guide.wait_idle(TIMEOUT), addr, ErrorKind::Protocol);
    // the model only registers the `stop` command when it is handled; poll its state
    assert!(eventually(|| !busy(&device)), "the axis was not stopped");
}

#[test]
fn wrong_checksum_is_a_protocol_error() {
    let homed = SimConfig { start_homed: true, ..SimConfig::default() };
    let (addr, device) = corrupting_device(homed, Corruption::Replace(b"@01 1 00 OK BUSY -- 0:00\r\n"));
    let mut guide = ok(ZaberAxis::connect_tcp(addr, config()));
    ok(guide.move_absolute_mm(200.0, &opts()));
    let line = one_line(guide.wait_idle(TIMEOUT), addr, ErrorKind::Protocol);
    assert!(line.contains("checksum"), "{line}");
    assert!(eventually(|| !busy(&device)), "the axis was not stopped");
}

#[test]
fn truncated_reply_then_close_is_a_disconnection() {
    let homed = SimConfig { start_homed: true, ..SimConfig::default() };
    let (addr, _device) = corrupting_device(homed, Corruption::TruncateAndClose(7));
    let mut guide = ok(ZaberAxis::connect_tcp(addr, config()));
    ok(guide.move_absolute_mm(200.0, &opts()));
    let line = one_line(guide.wait_idle(TIMEOUT), addr, ErrorKind::Disconnected);
    assert!(line.ends_with("connection closed while waiting for the reply to a status poll"), "{line}");
}

#[test]
fn truncated_reply_then_silence_times_out() {
    let homed = SimConfig { start_homed: true, ..SimConfig::default() };
    let (addr, _device) = corrupting_device(homed, Corruption::TruncateAndStall(7));
    let mut guide = ok(ZaberAxis::connect_tcp(addr, config()));
    ok(guide.move_absolute_mm(200.0, &opts()));
    let t0 = Instant::now();
    let line = one_line(guide.wait_idle(TIMEOUT), addr, ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    assert!(line.contains("no reply to a status poll within 0.300 s"), "{line}");
}

#[test]
fn stall_latched_while_idle_refuses_the_next_move_until_homed() {
    let sim = ok(ZaberSim::start(SimConfig { start_homed: true, time_scale: 100.0, ..SimConfig::default() }));
    let addr = sim.addr();
    let mut guide = ok(ZaberAxis::connect_tcp(addr, config()));
    ok(guide.move_absolute_mm(10.0, &opts()));
    ok(guide.wait_idle(TIMEOUT));
    sim.inject_stall();
    // the stall is not cleared silently by the next move: the position is not to be trusted
    let line = one_line(
        guide.move_absolute_mm(20.0, &opts()),
        addr,
        ErrorKind::DeviceFault { code: Warning::STALL.code() },
    );
    assert!(line.contains("FS"), "{line}");
    assert!(!ok(guide.is_homed()), "a latched fault means: home again");
    ok(guide.home(TIMEOUT));
    assert!(ok(guide.is_homed()));
    ok(guide.move_absolute_mm(20.0, &opts()));
    ok(guide.wait_idle(TIMEOUT));
}
