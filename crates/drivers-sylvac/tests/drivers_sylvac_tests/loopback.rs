//! The driver against the simulated gauge over real TCP on 127.0.0.1 (ephemeral ports).
//! Every wait is bounded; the simulator stops when dropped.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use vatcal_drivers_sylvac::sim::{SimConfig, SylvacSim};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge, Unit};
use vatcal_hardware_traits::{ErrorKind, Gauge, Probe3d, TriCal, TriCalConfig};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn err_kind<T: std::fmt::Debug>(r: vatcal_hardware_traits::Result<T>) -> ErrorKind {
    match r {
        Ok(v) => panic!("expected an error, got {v:?}"),
        Err(e) => e.kind(),
    }
}

fn sim(config: SimConfig) -> SylvacSim {
    ok(SylvacSim::start(config))
}

fn connect(sim: &SylvacSim, config: SylvacConfig) -> SylvacGauge {
    ok(SylvacGauge::connect_tcp(sim.addr(), config))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn identifies_and_reads_the_plunger() {
    let s = sim(SimConfig::default());
    let mut g = connect(&s, SylvacConfig::default());
    assert_eq!(g.id(), "SY289");
    assert_eq!(g.unit(), Unit::Mm);
    for mm in [0.0, 1.2345, 6.35, 12.5] {
        s.set_plunger_mm(mm);
        let r = ok(g.read_mm());
        assert!(close(r, mm), "{mm} → {r}");
    }
}

#[test]
fn preset_and_zero() {
    let s = sim(SimConfig::default());
    let mut g = connect(&s, SylvacConfig::default());
    s.set_plunger_mm(3.2);
    ok(g.preset_mm(6.35));
    assert!(close(ok(g.read_mm()), 6.35));
    s.set_plunger_mm(3.3);
    assert!(close(ok(g.read_mm()), 6.45));
    ok(g.zero());
    assert!(close(ok(g.read_mm()), 0.0));
    s.set_plunger_mm(3.05);
    assert!(close(ok(g.read_mm()), -0.25));
    assert_eq!(err_kind(g.preset_mm(250.0)), ErrorKind::OutOfRange);
    assert_eq!(err_kind(g.preset_mm(f64::NAN)), ErrorKind::OutOfRange);
}

#[test]
fn preset_variants_to_verify_on_hardware() {
    // a gauge that acknowledges setters
    let s = sim(SimConfig { ack_setters: true, ..SimConfig::default() });
    let mut g = connect(&s, SylvacConfig::default());
    s.set_plunger_mm(1.0);
    ok(g.preset_mm(2.0));
    assert!(close(ok(g.read_mm()), 2.0));
    // a gauge that needs PRE ON: detected by the read-back check, fixed by the option
    let s = sim(SimConfig { preset_requires_on: true, ..SimConfig::default() });
    let mut g = connect(&s, SylvacConfig::default());
    s.set_plunger_mm(1.0);
    assert_eq!(err_kind(g.preset_mm(2.0)), ErrorKind::Protocol);
    let mut g = connect(&s, SylvacConfig { preset_mode_on: true, ..SylvacConfig::default() });
    ok(g.preset_mm(2.0));
    assert!(close(ok(g.read_mm()), 2.0));
}

#[test]
fn beyond_the_range_is_out_of_range_and_sensor_faults_are_device_faults() {
    let s = sim(SimConfig::default());
    let mut g = connect(&s, SylvacConfig::default());
    s.set_plunger_mm(12.6);
    assert_eq!(err_kind(g.read_mm()), ErrorKind::OutOfRange);
    s.set_plunger_mm(-0.01);
    assert_eq!(err_kind(g.read_mm()), ErrorKind::OutOfRange);
    s.set_plunger_mm(1.0);
    assert!(close(ok(g.read_mm()), 1.0));
    s.set_sensor_error(true);
    assert_eq!(err_kind(g.read_mm()), ErrorKind::DeviceFault { code: 0 });
}

#[test]
fn inch_display_is_converted_when_not_forced_to_mm() {
    let s = sim(SimConfig::default());
    {
        let mut raw = ok(TcpStream::connect(s.addr()));
        ok(raw.write_all(b"IN\r"));
        let deadline = Instant::now() + Duration::from_secs(2);
        while s.state().unit != Unit::Inch && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    let mut g = connect(&s, SylvacConfig { force_mm: false, ..SylvacConfig::default() });
    assert_eq!(g.unit(), Unit::Inch);
    s.set_plunger_mm(2.54);
    assert!((ok(g.read_mm()) - 2.54).abs() < 2.6e-4);
    ok(g.preset_mm(6.35));
    assert!((ok(g.read_mm()) - 6.35).abs() < 2.6e-4);
    // forcing mm switches the gauge back
    let g2 = connect(&s, SylvacConfig::default());
    assert_eq!(g2.unit(), Unit::Mm);
    assert_eq!(s.state().unit, Unit::Mm);
}

#[test]
fn continuous_output_is_switched_off_at_connection() {
    let s = sim(SimConfig { output_interval: Duration::from_millis(2), ..SimConfig::default() });
    let mut raw = ok(TcpStream::connect(s.addr()));
    ok(raw.write_all(b"OUT1\r"));
    let deadline = Instant::now() + Duration::from_secs(2);
    while !s.state().continuous_output && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(s.state().continuous_output);
    let mut g = connect(&s, SylvacConfig::default());
    assert!(!s.state().continuous_output, "the driver polls; streamed values would race with answers");
    for mm in [1.0, 2.0, 3.0] {
        s.set_plunger_mm(mm);
        assert!(close(ok(g.read_mm()), mm));
    }
}

#[test]
fn noisy_readings_average_to_the_plunger() {
    let s = sim(SimConfig { noise_std_mm: 0.0003, seed: 42, ..SimConfig::default() });
    let mut g = connect(&s, SylvacConfig::default());
    s.set_plunger_mm(4.0);
    let readings: Vec<f64> = (0..40).map(|_| ok(g.read_mm())).collect();
    let mean = readings.iter().sum::<f64>() / readings.len() as f64;
    assert!((mean - 4.0).abs() < 0.0003, "{mean}");
    assert!(readings.iter().any(|r| !close(*r, 4.0)));
    for r in &readings {
        assert!(((r * 1e4).round() - r * 1e4).abs() < 1e-6, "quantised to 0.1 um: {r}");
    }
}

#[test]
fn stalled_gauge_times_out_and_dropped_connection_is_disconnected() {
    let s = sim(SimConfig::default());
    let mut g =
        connect(&s, SylvacConfig { io_timeout: Duration::from_millis(150), ..SylvacConfig::default() });
    s.set_stalled(true);
    let t0 = Instant::now();
    assert_eq!(err_kind(g.read_mm()), ErrorKind::Timeout);
    assert!(t0.elapsed() < Duration::from_secs(2));
    s.set_stalled(false);
    s.set_plunger_mm(2.0);
    assert!(close(ok(g.read_mm()), 2.0), "late answer discarded");
    s.drop_clients();
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(err_kind(g.read_mm()), ErrorKind::Disconnected);
}

#[test]
fn raw_transcript() {
    let s = sim(SimConfig::default());
    let mut t = ok(TcpStream::connect(s.addr()));
    s.set_plunger_mm(1.2345);
    ok(t.write_all(b"?\rID?\rUNI?\rSET?\rBAT?\rFAC RST\rPRE +006.3500\rPRE?\r?\r"));
    let expected = "+001.2345\rSY289\rMM\rMM STO0 KEY1 BAT1\rBAT1\rERR1\r+006.3500\r+006.3500\r";
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(3);
    let mut buf = [0u8; 256];
    while got.len() < expected.len() && Instant::now() < deadline {
        ok(t.set_read_timeout(Some(Duration::from_millis(20))));
        if let Ok(n) = t.read(&mut buf) {
            got.extend_from_slice(&buf[..n]);
        }
    }
    assert_eq!(String::from_utf8_lossy(&got), expected);
}

#[test]
fn three_simulated_gauges_make_a_trical_probe() {
    let sims = [sim(SimConfig::default()), sim(SimConfig::default()), sim(SimConfig::default())];
    let gauges = [0, 1, 2].map(|i| {
        connect(&sims[i], SylvacConfig { name: format!("gauge {}", i + 1), ..SylvacConfig::default() })
    });
    let mut probe = ok(TriCal::new(gauges, TriCalConfig::new(Vec::new())));
    // master ball seated: plungers somewhere mid-travel
    let master = [8.0, 8.5, 9.0];
    for (s, p) in sims.iter().zip(master) {
        s.set_plunger_mm(p);
    }
    ok(probe.preset_master());
    // calibration ball offset by c along the (orthogonal) gauge axes: plunger_i = master_i - 6.35 + c_i
    let c = [0.12, -0.3, 0.05];
    for ((s, p), ci) in sims.iter().zip(master).zip(c) {
        s.set_plunger_mm(p - 6.35 + ci);
    }
    let reading = ok(probe.read());
    for (got, want) in reading.offset_mm.iter().zip(c) {
        assert!((got - want).abs() < 1e-9, "{:?}", reading.offset_mm);
    }
}

#[test]
fn simulator_stops_when_dropped() {
    let s = sim(SimConfig::default());
    let addr = s.addr();
    drop(s);
    assert!(TcpStream::connect_timeout(&addr, Duration::from_millis(500)).is_err());
}
