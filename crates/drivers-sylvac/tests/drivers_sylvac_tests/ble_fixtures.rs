//! The BLE decoders against the notification payloads in
//! `fixtures/sylvac-ble-notifications.txt` (derived from the documented formats, see the
//! file's header): presentation-format exponent, Measurement values, Parameters bitmaps,
//! RemoteResponse reassembly, and the whole ASCII driver fed the RemoteResponse notifications
//! the way the BLE transport delivers them (one notification per read).

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

use vatcal_drivers_sylvac::ble::{
    BleUnit, MAX_NOTIFICATION_LEN, Mode, ResponseReassembler, decode_measurement_mm, decode_parameters,
    presentation_format_exponent,
};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_hardware_traits::Gauge;
use vatcal_hardware_traits::transport::Transport;

const FIXTURE: &str = include_str!("../../../../fixtures/sylvac-ble-notifications.txt");

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap_or_else(|e| panic!("bad hex byte '{b}': {e}")))
        .collect()
}

/// `key=value` of a space-separated expectation field.
fn field<'a>(expect: &'a str, key: &str) -> &'a str {
    expect
        .split_whitespace()
        .find_map(|kv| kv.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
        .unwrap_or_else(|| panic!("no {key}= in '{expect}'"))
}

fn num<T: std::str::FromStr>(s: &str) -> T
where
    T::Err: std::fmt::Display,
{
    s.parse().unwrap_or_else(|e| panic!("'{s}': {e}"))
}

struct Record {
    kind: String,
    fields: Vec<String>,
}

fn records() -> Vec<Record> {
    FIXTURE
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| {
            let kind = l.split(" ; ").next().unwrap_or_default().trim().to_owned();
            let n = if kind == "response" { 5 } else { 4 };
            let fields: Vec<String> = l.splitn(n, " ; ").map(|f| f.trim().to_owned()).collect();
            assert_eq!(fields.len(), n, "record '{l}' needs {n} fields");
            Record { kind, fields }
        })
        .collect()
}

#[test]
fn fixture_covers_every_payload_kind() {
    let r = records();
    for kind in ["descriptor", "measurement", "parameters", "response"] {
        assert!(r.iter().filter(|r| r.kind == kind).count() >= 2, "too few {kind} records");
    }
    assert!(
        r.iter().all(|r| ["descriptor", "measurement", "parameters", "response"].contains(&r.kind.as_str()))
    );
}

#[test]
fn descriptors_give_the_exponent() {
    for r in records().iter().filter(|r| r.kind == "descriptor") {
        let want: i8 = num(field(&r.fields[2], "exponent"));
        assert_eq!(presentation_format_exponent(&hex(&r.fields[1])), want, "{}", r.fields[3]);
    }
}

#[test]
fn measurements_decode_to_the_documented_values() {
    for r in records().iter().filter(|r| r.kind == "measurement") {
        let exponent: i8 = num(field(&r.fields[2], "exponent"));
        let got = decode_measurement_mm(&hex(&r.fields[1]), exponent).unwrap_or_else(|e| panic!("{e}"));
        match field(&r.fields[2], "mm") {
            "none" => assert_eq!(got, None, "{}", r.fields[3]),
            v => {
                let want: f64 = num(v);
                let got = got.unwrap_or_else(|| panic!("no value: {}", r.fields[3]));
                assert!((got - want).abs() < 1e-9, "{got} vs {want}: {}", r.fields[3]);
            }
        }
    }
}

#[test]
fn parameters_decode_to_the_documented_bitmap() {
    for r in records().iter().filter(|r| r.kind == "parameters") {
        let p = decode_parameters(&hex(&r.fields[1])).unwrap_or_else(|e| panic!("{e}"));
        let unit = match field(&r.fields[2], "unit") {
            "mm" => BleUnit::Mm,
            "inch" => BleUnit::Inch,
            "unknown" => BleUnit::Unknown,
            other => panic!("unit {other}"),
        };
        let mode = match field(&r.fields[2], "mode") {
            "normal" => Mode::Normal,
            "min" => Mode::Min,
            "max" => Mode::Max,
            "delta" => Mode::Delta,
            other => panic!("mode {other}"),
        };
        assert_eq!((p.unit, p.mode), (unit, mode), "{}", r.fields[3]);
        match field(&r.fields[2], "resolution_m") {
            "none" => assert_eq!(p.resolution_m, None),
            v => {
                let want: f64 = num(v);
                let got = p.resolution_m.unwrap_or(f64::NAN);
                assert!((got - want).abs() < want * 1e-12, "{got} vs {want}");
            }
        }
    }
}

fn notifications(r: &Record) -> Vec<Vec<u8>> {
    r.fields[2].split('|').map(hex).collect()
}

fn answers(r: &Record) -> Vec<String> {
    r.fields[3].split('|').map(str::to_owned).collect()
}

#[test]
fn responses_reassemble_into_the_documented_answers() {
    for r in records().iter().filter(|r| r.kind == "response") {
        let mut reassembler = ResponseReassembler::new();
        let mut got = Vec::new();
        for n in notifications(r) {
            assert!(n.len() <= MAX_NOTIFICATION_LEN, "notification longer than 20 bytes: {}", r.fields[4]);
            got.extend(reassembler.push(&n).unwrap_or_else(|e| panic!("{e}")));
        }
        assert_eq!(got, answers(r), "{}", r.fields[4]);
    }
}

/// A fake BLE gauge at the transport level: a command written to RemoteRequest queues the
/// fixture's RemoteResponse notifications for it; each `recv` delivers one notification, as
/// the BLE transport does. Setters (no record) stay silent, like the gauge.
struct NotificationGauge {
    answers: Vec<(String, Vec<Vec<u8>>)>,
    queued: VecDeque<Vec<u8>>,
    written: Vec<String>,
}

impl Transport for NotificationGauge {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let command = String::from_utf8_lossy(bytes).trim_end_matches('\r').to_owned();
        if let Some((_, n)) = self.answers.iter().find(|(c, _)| *c == command) {
            self.queued.extend(n.iter().cloned());
        }
        self.written.push(command);
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        match self.queued.pop_front() {
            Some(n) => {
                buf[..n.len()].copy_from_slice(&n);
                Ok(n.len())
            }
            None => {
                std::thread::sleep(timeout.min(Duration::from_millis(2)));
                Err(io::Error::new(io::ErrorKind::TimedOut, "no notification"))
            }
        }
    }
}

#[test]
fn the_ascii_driver_reads_the_gauge_through_remote_response_notifications() {
    let recs = records();
    let mut answers_by_command: Vec<(String, Vec<Vec<u8>>)> = Vec::new();
    for r in recs.iter().filter(|r| r.kind == "response") {
        // the first record per command is the one the fake answers with
        if !answers_by_command.iter().any(|(c, _)| *c == r.fields[1]) {
            answers_by_command.push((r.fields[1].clone(), notifications(r)));
        }
    }
    let transport =
        NotificationGauge { answers: answers_by_command, queued: VecDeque::new(), written: Vec::new() };
    let config = SylvacConfig {
        io_timeout: Duration::from_millis(100),
        setter_ack_window: Duration::from_millis(5),
        ..SylvacConfig::default()
    };
    let mut gauge = SylvacGauge::new(transport, config).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(gauge.id(), "SY289");
    let mm = gauge.read_mm().unwrap_or_else(|e| panic!("{e}"));
    assert!((mm - 1.2345).abs() < 1e-12, "{mm}");
    let written = gauge.into_inner().written;
    assert_eq!(written, ["ID?", "OUT0", "MM", "UNI?", "?"]);
}
