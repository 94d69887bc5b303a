//! Driver-level faults over real TCP: each surfaces as ONE error line naming the robot and its
//! address (`meca500 at 127.0.0.1:PORT: …`), and the driver leaves motion stopped where it
//! can (error mode and E-Stop stop the arm; after a lost or garbled answer the driver sends
//! `ClearMotion` while the link is up). Simulator faults use the simulator's fault injection;
//! garbled and truncated bytes come from a tiny raw TCP server in this file.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use vatcal_drivers_meca500::codec::{Deframer, code};
use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig};
use vatcal_drivers_meca500::{Meca500, Meca500Config};
use vatcal_hardware_traits::{ArmJoints, ErrorKind, MotionOptions, RobotArm};

const TIMEOUT: Duration = Duration::from_secs(5);
const BANNER: &[u8] = b"[3000][Connected to Meca500 R3 v9.3.0]\0";

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn config() -> Meca500Config {
    Meca500Config { io_timeout: Duration::from_millis(300), ..Meca500Config::default() }
}

/// Checks kind, one line, and the `meca500 at ADDR: ` prefix; returns the line.
fn one_line(r: vatcal_hardware_traits::Result<()>, addr: SocketAddr, kind: ErrorKind) -> String {
    vatcal_hardware_traits::testing::expect_one_line_error(r, &format!("meca500 at {addr}: "), kind)
}

/// A homed robot on a simulator running `scale` times faster than real time, and a slow J1
/// move (60° at 1 %: seconds) already accepted.
fn moving(scale: f64) -> (Meca500Sim, Meca500) {
    let sim = ok(Meca500Sim::start(SimConfig::fast(scale)));
    let mut robot = ok(Meca500::connect_tcp(sim.control_addr(), config()));
    ok(robot.activate_and_home(TIMEOUT));
    let slow = MotionOptions { speed_fraction: 0.01, timeout: TIMEOUT };
    ok(robot.move_joints(&ArmJoints::from_deg_array([60.0, 0.0, 0.0, 0.0, 0.0, 0.0]), &slow));
    (sim, robot)
}

/// Polls the simulator until `pred` holds (bounded).
fn eventually(sim: &Meca500Sim, pred: impl Fn(&vatcal_drivers_meca500::sim::SimState) -> bool) -> bool {
    let deadline = Instant::now() + TIMEOUT;
    while Instant::now() < deadline {
        if pred(&sim.state()) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    false
}

fn after(ms: u64, f: impl FnOnce() + Send) -> impl FnOnce() + Send {
    move || {
        std::thread::sleep(Duration::from_millis(ms));
        f();
    }
}

#[test]
fn connection_dropped_mid_move() {
    let (sim, mut robot) = moving(5.0);
    let addr = sim.control_addr();
    let r = std::thread::scope(|s| {
        s.spawn(after(50, || sim.drop_client()));
        robot.wait_idle(TIMEOUT)
    });
    let line = one_line(r, addr, ErrorKind::Disconnected);
    assert!(
        line.ends_with("connection closed while waiting for the end of the motion (checkpoint)"),
        "{line}"
    );
}

#[test]
fn stalled_robot_times_out_and_the_motion_is_cleared() {
    let (sim, mut robot) = moving(5.0);
    let addr = sim.control_addr();
    sim.set_stalled(true);
    let t0 = Instant::now();
    let line = one_line(robot.wait_idle(Duration::from_millis(300)), addr, ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    assert!(line.contains("within 0.300 s"), "{line}");
    // the ClearMotion the driver sent reaches the robot once it answers again: the arm stops
    // well short of the 60° target
    sim.set_stalled(false);
    assert!(eventually(&sim, |s| s.status.end_of_block && s.queue_len == 0), "{:?}", sim.state());
    let j1 = sim.state().joints_deg[0];
    assert!(j1 < 30.0, "J1 went on to {j1}°");
}

#[test]
fn robot_error_mode_mid_move() {
    let (sim, mut robot) = moving(5.0);
    let addr = sim.control_addr();
    let r = std::thread::scope(|s| {
        s.spawn(after(50, || sim.inject_error(code::MOTION_ERROR, "Collision detected.")));
        robot.wait_idle(TIMEOUT)
    });
    let line = one_line(r, addr, ErrorKind::DeviceFault { code: 3005 });
    assert!(line.contains("[3005]") && line.contains("Collision detected."), "{line}");
    assert!(eventually(&sim, |s| s.status.error && s.status.end_of_block), "{:?}", sim.state());
    // the status reports the cause too
    let st = ok(robot.status());
    assert_eq!(st.error.map(|e| e.0), Some(3005));
}

#[test]
fn estop_mid_move() {
    let (sim, mut robot) = moving(5.0);
    let addr = sim.control_addr();
    let r = std::thread::scope(|s| {
        s.spawn(after(50, || sim.set_estop(true)));
        robot.wait_idle(TIMEOUT)
    });
    let line = one_line(r, addr, ErrorKind::DeviceFault { code: 3070 });
    assert!(line.contains("E-Stop pressed"), "{line}");
    let j1 = sim.state().joints_deg[0];
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(sim.state().joints_deg[0], j1, "the arm still moves after the E-Stop");
}

/// A raw robot: sends the banner, then answers the `n`-th command frame (0-based) with
/// `reply` and every other with nothing; closes after the reply if `close`. Reports every
/// command frame it received on the channel.
fn raw_robot(n: usize, reply: &'static [u8], close: bool) -> (SocketAddr, mpsc::Receiver<String>) {
    let listener = ok(TcpListener::bind("127.0.0.1:0"));
    let addr = ok(listener.local_addr());
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let Ok((mut stream, _)) = listener.accept() else { return };
        let _ = stream.set_read_timeout(Some(Duration::from_millis(20)));
        if stream.write_all(BANNER).is_err() {
            return;
        }
        let mut d = Deframer::nul_or_lf();
        let mut seen = 0usize;
        let mut buf = [0u8; 1024];
        let deadline = Instant::now() + TIMEOUT;
        while Instant::now() < deadline {
            match stream.read(&mut buf) {
                Ok(0) => return,
                Ok(k) => d.push(&buf[..k]),
                Err(_) => {}
            }
            while let Ok(Some(frame)) = d.next_frame() {
                let text = String::from_utf8_lossy(&frame).into_owned();
                let _ = tx.send(text);
                if seen == n {
                    let _ = stream.write_all(reply);
                    if close {
                        return;
                    }
                }
                seen += 1;
            }
        }
    });
    (addr, rx)
}

fn received_within(rx: &mpsc::Receiver<String>, wanted: &str) -> bool {
    let deadline = Instant::now() + Duration::from_secs(2);
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match rx.recv_timeout(left) {
            Ok(f) if f == wanted => return true,
            Ok(_) => {}
            Err(_) => return false,
        }
    }
    false
}

#[test]
fn garbled_reply_while_waiting_is_a_protocol_error_and_clears_the_motion() {
    // wait_idle sends SetCheckpoint(1) first; the answer is garbage
    let (addr, rx) = raw_robot(0, b"[30x0][1]\0", false);
    let mut robot = ok(Meca500::connect_tcp(addr, config()));
    let line = one_line(robot.wait_idle(TIMEOUT), addr, ErrorKind::Protocol);
    assert!(line.contains("30x0"), "{line}");
    assert!(received_within(&rx, "ClearMotion"), "no ClearMotion after the garbled reply");
}

#[test]
fn truncated_reply_then_silence_times_out_and_clears_the_motion() {
    let (addr, rx) = raw_robot(0, b"[3030][", false);
    let mut robot = ok(Meca500::connect_tcp(addr, config()));
    one_line(robot.wait_idle(Duration::from_millis(200)), addr, ErrorKind::Timeout);
    assert!(received_within(&rx, "ClearMotion"), "no ClearMotion after the timeout");
}

#[test]
fn truncated_reply_then_close_is_a_disconnection() {
    let (addr, _rx) = raw_robot(0, b"[2007][1,1,0", true);
    let mut robot = ok(Meca500::connect_tcp(addr, config()));
    let line = one_line(robot.status().map(|_| ()), addr, ErrorKind::Disconnected);
    assert!(line.ends_with("connection closed while waiting for answer to GetStatusRobot"), "{line}");
}

#[test]
fn garbage_instead_of_a_banner_is_one_clear_error() {
    let listener = ok(TcpListener::bind("127.0.0.1:0"));
    let addr = ok(listener.local_addr());
    std::thread::spawn(move || {
        if let Ok((mut s, _)) = listener.accept() {
            let _ = s.write_all(b"SSH-2.0-OpenSSH_9.2\r\n\0");
            std::thread::sleep(Duration::from_millis(300));
        }
    });
    let e = match Meca500::connect_tcp(addr, config()) {
        Ok(_) => panic!("garbage banner accepted"),
        Err(e) => e.into_hw(&format!("meca500 at {addr}")),
    };
    assert_eq!(e.kind(), ErrorKind::Protocol, "{e}");
    assert!(!e.to_string().contains('\n'));
    let _ = TcpStream::connect(addr);
}
