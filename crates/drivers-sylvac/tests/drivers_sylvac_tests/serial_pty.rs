//! The driver over the shared serial transport, against a fake gauge on the other end of a
//! pseudo-terminal pair (`serialport::TTYPort::pair()`): the gauge model is the simulator's
//! [`SimGauge`] fed by a small line loop on the pty master.
#![cfg(all(unix, feature = "serial"))]

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vatcal_drivers_sylvac::codec::LineDeframer;
use vatcal_drivers_sylvac::sim::{SimConfig, SimGauge};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_hardware_traits::transport::SerialTransport;
use vatcal_hardware_traits::transport::serialport::{SerialPort, TTYPort};
use vatcal_hardware_traits::{ErrorKind, Gauge};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// The fake gauge: answers every CR-terminated line on the pty master until stopped, then
/// closes the master (the driver's side sees a hang-up).
struct FakeGauge {
    gauge: Arc<Mutex<SimGauge>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FakeGauge {
    fn start(mut master: TTYPort, config: SimConfig) -> Self {
        let gauge = Arc::new(Mutex::new(SimGauge::new(config)));
        let stop = Arc::new(AtomicBool::new(false));
        let (g, flag) = (Arc::clone(&gauge), Arc::clone(&stop));
        let thread = std::thread::spawn(move || {
            let start = Instant::now();
            let mut deframer = LineDeframer::new();
            let mut buf = [0u8; 256];
            let _ = master.set_timeout(Duration::from_millis(5));
            while !flag.load(Ordering::SeqCst) {
                if let Ok(n) = master.read(&mut buf) {
                    deframer.push(&buf[..n]);
                }
                while let Ok(Some(line)) = deframer.next_line() {
                    let answer = g.lock().map(|mut g| g.handle_line(&line, start.elapsed()));
                    if let Ok(Some(answer)) = answer {
                        let _ = master.write_all(format!("{answer}\r").as_bytes());
                    }
                }
            }
        });
        Self { gauge, stop, thread: Some(thread) }
    }

    fn set_plunger_mm(&self, mm: f64) {
        if let Ok(mut g) = self.gauge.lock() {
            g.set_plunger_mm(mm);
        }
    }

    fn stop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for FakeGauge {
    fn drop(&mut self) {
        self.stop();
    }
}

fn pty_gauge(config: SimConfig) -> (FakeGauge, SylvacGauge<SerialTransport>) {
    let (master, slave) = ok(TTYPort::pair());
    let fake = FakeGauge::start(master, config);
    let transport = SerialTransport::from_port(Box::new(slave));
    let config = SylvacConfig { name: "gauge 2".to_owned(), ..SylvacConfig::default() };
    (fake, ok(SylvacGauge::new(transport, config)))
}

#[test]
fn identifies_reads_and_presets_over_a_pty() {
    let (fake, mut gauge) = pty_gauge(SimConfig::default());
    assert_eq!(gauge.id(), "SY289");
    fake.set_plunger_mm(3.25);
    let mm = ok(gauge.read_mm());
    assert!((mm - 3.25).abs() < 1e-9, "{mm}");
    ok(gauge.preset_mm(6.0));
    fake.set_plunger_mm(4.25);
    let mm = ok(gauge.read_mm());
    assert!((mm - 7.0).abs() < 1e-9, "{mm}");
    // beyond the measuring range the gauge answers ERR3
    fake.set_plunger_mm(13.0);
    assert_eq!(gauge.read_mm().err().map(|e| e.kind()), Some(ErrorKind::OutOfRange));
}

#[test]
fn a_hang_up_of_the_gauge_side_is_a_disconnection_naming_the_gauge() {
    let (mut fake, mut gauge) = pty_gauge(SimConfig::default());
    ok(gauge.read_mm());
    fake.stop();
    let e = gauge.read_mm().err().unwrap_or_else(|| panic!("read after hang-up succeeded"));
    assert_eq!(e.kind(), ErrorKind::Disconnected, "{e}");
    assert!(e.to_string().starts_with("gauge 2"), "{e}");
}
