//! Arbitrary bytes into every parser of the Meca500 codec, and into the driver through an
//! in-memory transport: no panic, every failure is an error value. Plus round trips of the
//! control and monitoring messages through the shared deframer under random chunking.

use std::time::Duration;

use proptest::prelude::*;
use vatcal_drivers_meca500::codec::{Banner, Deframer, Reply, StatusWord, parse_command};
use vatcal_drivers_meca500::{Meca500, Meca500Config};
use vatcal_hardware_traits::RobotArm;
use vatcal_hardware_traits::transport::ScriptedTransport;

fn quick() -> Meca500Config {
    Meca500Config {
        io_timeout: Duration::from_millis(20),
        connect_timeout: Duration::from_millis(20),
        ..Meca500Config::default()
    }
}

/// Bytes that look like Meca500 traffic often enough to get past the first checks.
fn wire_bytes() -> impl Strategy<Value = Vec<u8>> {
    let token = prop_oneof![
        Just(b"[".to_vec()),
        Just(b"]".to_vec()),
        Just(b"[3000][Connected to Meca500 R3 v9.3.0]".to_vec()),
        Just(b"[2007][1,1,0,0,0,1,1]".to_vec()),
        Just(b"[2200][1.0,2,3,4,5,6,7]".to_vec()),
        Just(b",".to_vec()),
        Just(vec![0u8]),
        "[0-9]{1,5}".prop_map(String::into_bytes),
        "-?[0-9]{0,4}\\.?[0-9]{0,4}(e[+-]?[0-9]{1,3})?".prop_map(String::into_bytes),
        proptest::collection::vec(any::<u8>(), 0..8),
    ];
    proptest::collection::vec(token, 0..24).prop_map(|v| v.concat())
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
    fn reply_and_command_parsers_take_any_bytes(bytes in prop_oneof![wire_bytes(), proptest::collection::vec(any::<u8>(), 0..120)]) {
        let mut d = Deframer::nul_or_lf();
        d.push(&bytes);
        d.push(&[0]);
        while let Ok(Some(frame)) = d.next_frame() {
            if let Ok(r) = Reply::parse(&frame) {
                let _ = r.values();
                let _ = r.last_six();
                let _ = r.is_error();
                let _ = StatusWord::from_reply(&r);
                let _ = Banner::from_reply(&r);
                prop_assert_eq!(Reply::parse(&r.encode()[..r.encode().len() - 1]).map(|b| b.code), Ok(r.code));
            }
            let _ = parse_command(&String::from_utf8_lossy(&frame));
        }
    }

    /// Monitoring-port style messages (code + six or seven numbers) survive encoding, any TCP
    /// segmentation and parsing with their values intact.
    #[test]
    fn monitoring_messages_round_trip_under_any_chunking(
        msgs in proptest::collection::vec((prop_oneof![Just(2026u16), Just(2027), Just(2200), Just(2201), Just(2210), Just(2211)], proptest::collection::vec(-1.0e4f64..1.0e4, 6..=7)), 1..10),
        cuts in proptest::collection::vec(0usize..2000, 0..12),
    ) {
        let replies: Vec<Reply> = msgs
            .iter()
            .map(|(c, v)| Reply::new(*c, v.iter().map(|x| format!("{x:.6}")).collect::<Vec<_>>().join(",")))
            .collect();
        let stream: Vec<u8> = replies.iter().flat_map(Reply::encode).collect();
        let mut d = Deframer::nul_only();
        let mut got = Vec::new();
        for chunk in split(&stream, &cuts) {
            d.push(&chunk);
            while let Ok(Some(f)) = d.next_frame() {
                got.push(Reply::parse(&f));
            }
        }
        prop_assert_eq!(got.len(), replies.len());
        for ((code, values), parsed) in msgs.iter().zip(got) {
            let parsed = parsed.map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(parsed.code, *code);
            let back = parsed.values().map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(back.len(), values.len());
            for (a, b) in back.iter().zip(values) {
                prop_assert!((a - b).abs() <= 1e-6, "{} vs {}", a, b);
            }
            let six = parsed.last_six().map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert!((six[5] - values[values.len() - 1]).abs() <= 1e-6);
        }
    }

    /// The driver fed arbitrary bytes (as banner, then as answers) returns errors, never panics.
    #[test]
    fn driver_takes_any_bytes(bytes in wire_bytes(), cuts in proptest::collection::vec(0usize..400, 0..6)) {
        let _ = Meca500::new(ScriptedTransport::new(split(&bytes, &cuts)), quick());
        let mut script = vec![b"[3000][Connected to Meca500 R3 v9.3.0]\0".to_vec()];
        script.extend(split(&bytes, &cuts));
        if let Ok(mut robot) = Meca500::new(ScriptedTransport::new(script), quick()) {
            let _ = robot.status();
            let _ = robot.joints();
            let _ = robot.wait_idle(Duration::from_millis(20));
            let _ = robot.reset_error();
        }
    }
}
