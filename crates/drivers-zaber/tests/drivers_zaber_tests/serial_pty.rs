//! The driver over the shared serial transport, against a fake device on the other end of a
//! pseudo-terminal pair (`serialport::TTYPort::pair()`): the device model is the simulator's
//! [`SimDevice`] fed by a small line loop on the pty master.
#![cfg(all(unix, feature = "serial"))]

use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vatcal_drivers_zaber::codec::{Command, LineDeframer};
use vatcal_drivers_zaber::sim::{SimConfig, SimDevice};
use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::transport::SerialTransport;
use vatcal_hardware_traits::transport::serialport::{SerialPort, TTYPort};
use vatcal_hardware_traits::{ErrorKind, LinearAxis, MotionOptions};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// The fake device: answers every command line on the pty master until stopped, then closes
/// the master (the driver's side sees a hang-up).
struct FakeDevice {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FakeDevice {
    fn start(mut master: TTYPort, config: SimConfig) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let start = Instant::now();
            let mut device = SimDevice::new(config);
            let mut deframer = LineDeframer::new();
            let mut buf = [0u8; 512];
            let _ = master.set_timeout(Duration::from_millis(5));
            while !flag.load(Ordering::SeqCst) {
                if let Ok(n) = master.read(&mut buf) {
                    deframer.push(&buf[..n]); // an error is a timeout: nothing to read
                }
                while let Ok(Some(line)) = deframer.next_line() {
                    let Ok((cmd, checksum)) = Command::parse(&line) else { continue };
                    if let Some(reply) = device.handle(&cmd, start.elapsed()) {
                        let _ = master.write_all(&reply.encode(checksum));
                    }
                }
            }
        });
        Self { stop, thread: Some(thread) }
    }

    fn stop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for FakeDevice {
    fn drop(&mut self) {
        self.stop();
    }
}

fn pty_guide(config: SimConfig) -> (FakeDevice, ZaberAxis<SerialTransport>) {
    let (master, slave) = ok(TTYPort::pair());
    let fake = FakeDevice::start(master, config);
    let transport = SerialTransport::from_port(Box::new(slave));
    let driver_config = ZaberConfig { poll_interval: Duration::from_millis(5), ..ZaberConfig::default() };
    (fake, ok(ZaberAxis::new(transport, driver_config)))
}

#[test]
fn homes_moves_and_reads_back_over_a_pty() {
    let (_fake, mut guide) = pty_guide(SimConfig::fast(50.0));
    assert_eq!(guide.info().limits_microsteps, Some((0, 1_536_000)));
    assert!(!ok(guide.is_homed()));
    ok(guide.home(Duration::from_secs(10)));
    assert!(ok(guide.is_homed()));
    let opts = MotionOptions { speed_fraction: 1.0, timeout: Duration::from_secs(10) };
    ok(guide.move_absolute_and_wait(42.5, &opts));
    let pos = ok(guide.position_mm());
    assert!((pos - 42.5).abs() <= guide.info().microstep_mm, "{pos}");
    // beyond the travel: refused before anything is sent
    let e = guide.move_absolute_mm(400.0, &opts).err().map(|e| e.kind());
    assert_eq!(e, Some(ErrorKind::OutOfRange));
}

#[test]
fn a_hang_up_of_the_device_side_is_a_disconnection_naming_the_device() {
    let (mut fake, mut guide) = pty_guide(SimConfig::fast(50.0));
    ok(guide.home(Duration::from_secs(10)));
    fake.stop(); // closes the pty master
    let e = guide.position_mm().err();
    let e = e.unwrap_or_else(|| panic!("read after hang-up succeeded"));
    assert_eq!(e.kind(), ErrorKind::Disconnected, "{e}");
    assert!(e.to_string().starts_with("zaber guide"), "{e}");
    assert_eq!(e.to_string().lines().count(), 1);
}
