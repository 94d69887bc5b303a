//! Arbitrary bytes into every parser of the Sylvac codec (ASCII answers and commands, BLE
//! payload decoders, the RemoteResponse reassembler) and into the driver through an in-memory
//! transport: no panic, every failure is an error value. Plus round trips where they hold.

use std::time::Duration;

use proptest::prelude::*;
use vatcal_drivers_sylvac::ble::{
    MAX_NOTIFICATION_LEN, ResponseReassembler, decode_measurement, decode_measurement_mm, decode_parameters,
    presentation_format_exponent, split_into_notifications,
};
use vatcal_drivers_sylvac::codec::{Answer, Command, LineDeframer, format_value, parse_value};
use vatcal_drivers_sylvac::{SylvacConfig, SylvacGauge};
use vatcal_hardware_traits::Gauge;
use vatcal_hardware_traits::transport::ScriptedTransport;

fn wire_text() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("\r".to_owned()),
        Just("+".to_owned()),
        Just("-".to_owned()),
        Just(".".to_owned()),
        Just("ERR".to_owned()),
        Just("MM".to_owned()),
        Just("IN".to_owned()),
        Just("SY289".to_owned()),
        Just(" ".to_owned()),
        "[0-9]{1,5}",
        "[ -~]{0,5}",
    ];
    proptest::collection::vec(token, 0..16).prop_map(|v| v.concat())
}

fn split(bytes: &[u8], cuts: &[usize]) -> Vec<Vec<u8>> {
    let mut cuts: Vec<usize> = cuts.iter().map(|c| c % (bytes.len() + 1)).collect();
    cuts.push(0);
    cuts.push(bytes.len());
    cuts.sort_unstable();
    cuts.windows(2).map(|w| bytes[w[0]..w[1]].to_vec()).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn ascii_parsers_take_any_input(text in prop_oneof![wire_text(), "[ -~]{0,40}"], bytes in proptest::collection::vec(any::<u8>(), 0..60)) {
        for line in [text, String::from_utf8_lossy(&bytes).into_owned()] {
            match Answer::parse(&line) {
                Answer::Value(v) => prop_assert!(v.is_finite()),
                Answer::Error(e) => prop_assert_eq!(Answer::parse(&e.to_text()), Answer::Error(e)),
                Answer::Text(_) => {}
            }
            let _ = parse_value(&line);
            if let Some(c) = Command::parse(&line) {
                // a parsed command re-encodes to the same command
                prop_assert_eq!(Command::parse(&c.to_text()), Some(c));
            }
        }
    }

    #[test]
    fn values_round_trip_through_the_display_format(v in -999.9999f64..999.9999, decimals in 0usize..6) {
        let text = format_value(v, 3, decimals);
        let back = parse_value(&text).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!((back - v).abs() <= 0.5 * 10f64.powi(-(decimals as i32)) + 1e-9, "{} -> {} -> {}", v, text, back);
    }

    #[test]
    fn ble_decoders_take_any_payload(payload in proptest::collection::vec(any::<u8>(), 0..24), exponent in any::<i8>()) {
        match decode_measurement(&payload, exponent) {
            Ok(_) => prop_assert_eq!(payload.len(), 4),
            Err(e) => prop_assert!(payload.len() != 4, "{}", e),
        }
        let _ = decode_measurement_mm(&payload, exponent);
        match decode_parameters(&payload) {
            Ok(_) => prop_assert_eq!(payload.len(), 2),
            Err(_) => prop_assert!(payload.len() != 2),
        }
        let e = presentation_format_exponent(&payload);
        prop_assert!(payload.len() < 2 || e == payload[1] as i8);
    }

    /// Any notifications, any chunking: the reassembler returns answers or an error value, and
    /// answers are the CR-separated pieces of the stream.
    #[test]
    fn reassembler_takes_any_notifications(
        answers in proptest::collection::vec("[ -~]{0,60}", 0..6),
        junk in proptest::collection::vec(any::<u8>(), 0..300),
        cuts in proptest::collection::vec(0usize..600, 0..10),
    ) {
        let stream: Vec<u8> = answers.iter().flat_map(|a| a.bytes().chain(std::iter::once(b'\r'))).collect();
        let mut r = ResponseReassembler::new();
        let mut got = Vec::new();
        for chunk in split(&stream, &cuts) {
            for n in split_into_notifications(&chunk) {
                prop_assert!(n.len() <= MAX_NOTIFICATION_LEN);
                got.extend(r.push(&n).map_err(|e| TestCaseError::fail(e.to_string()))?);
            }
        }
        prop_assert_eq!(&got, &answers);
        // arbitrary bytes: never a panic; answers never contain CR nor exceed the limit
        for n in split_into_notifications(&junk) {
            if let Ok(done) = r.push(&n) {
                for a in done {
                    prop_assert!(!a.contains('\r'));
                    prop_assert!(a.len() <= 3 * ResponseReassembler::MAX_RESPONSE);
                }
            }
        }
    }

    #[test]
    fn ascii_answers_survive_any_chunking(
        values in proptest::collection::vec(-99.9999f64..99.9999, 1..8),
        cuts in proptest::collection::vec(0usize..400, 0..10),
    ) {
        let stream: String = values.iter().map(|v| format!("{}\r", format_value(*v, 3, 4))).collect();
        let mut d = LineDeframer::new();
        let mut got = Vec::new();
        for chunk in split(stream.as_bytes(), &cuts) {
            d.push(&chunk);
            while let Ok(Some(line)) = d.next_line() {
                got.push(parse_value(&line).map_err(|e| TestCaseError::fail(e.to_string()))?);
            }
        }
        prop_assert_eq!(got.len(), values.len());
        for (a, b) in got.iter().zip(&values) {
            prop_assert!((a - b).abs() <= 0.5e-4 + 1e-12);
        }
    }

    /// The driver fed arbitrary bytes as answers returns errors, never panics.
    #[test]
    fn driver_takes_any_bytes(text in wire_text(), cuts in proptest::collection::vec(0usize..200, 0..6)) {
        let config = SylvacConfig {
            io_timeout: Duration::from_millis(20),
            setter_ack_window: Duration::from_millis(5),
            ..SylvacConfig::default()
        };
        if let Ok(mut gauge) = SylvacGauge::new(ScriptedTransport::new(split(text.as_bytes(), &cuts)), config) {
            let _ = gauge.read_mm();
            let _ = gauge.preset_mm(1.0);
        }
    }
}
