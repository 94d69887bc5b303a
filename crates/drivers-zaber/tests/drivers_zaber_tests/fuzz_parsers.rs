//! Arbitrary bytes into every parser of the Zaber codec (replies, alerts, info lines, with and
//! without checksum; commands; warning lists) and into the driver through an in-memory
//! transport: no panic, every failure is an error value. Plus round trips of device messages
//! (checksum on and off) through the shared deframer under random chunking.

use std::time::Duration;

use proptest::prelude::*;
use vatcal_drivers_zaber::codec::{
    Alert, Command, Info, LineDeframer, Message, Reply, Status, Warning, checksum, parse_warning_list,
};
use vatcal_drivers_zaber::{ZaberAxis, ZaberConfig};
use vatcal_hardware_traits::LinearAxis;
use vatcal_hardware_traits::transport::ScriptedTransport;

/// Text that looks like Zaber traffic often enough to reach the deeper branches.
fn wire_text() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("@".to_owned()),
        Just("#".to_owned()),
        Just("!".to_owned()),
        Just("/".to_owned()),
        Just(" ".to_owned()),
        Just("OK".to_owned()),
        Just("RJ".to_owned()),
        Just("IDLE".to_owned()),
        Just("BUSY".to_owned()),
        Just("--".to_owned()),
        Just("WR".to_owned()),
        Just(":".to_owned()),
        "[0-9]{1,4}",
        "[A-F0-9]{2}",
        "[ -~]{0,6}",
    ];
    proptest::collection::vec(token, 0..14).prop_map(|v| v.concat())
}

fn with_valid_checksum(line: &str) -> String {
    let mut chars = line.chars();
    let sigil = chars.next().unwrap_or('@');
    let body = chars.as_str();
    format!("{sigil}{body}:{:02X}", checksum(body))
}

fn data_text() -> impl Strategy<Value = String> {
    proptest::collection::vec("[A-Za-z0-9.\\-]{1,8}", 0..4).prop_map(|v| v.join(" "))
}

fn warning() -> impl Strategy<Value = Option<Warning>> {
    proptest::option::of("[FWN][A-Z]".prop_map(|s| Warning([s.as_bytes()[0], s.as_bytes()[1]])))
}

fn status() -> impl Strategy<Value = Status> {
    prop_oneof![Just(Status::Idle), Just(Status::Busy)]
}

fn message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (0u8..100, 0u8..10, proptest::option::of(0u8..100), any::<bool>(), status(), warning(), data_text())
            .prop_map(|(address, axis, id, accepted, status, warning, data)| {
                Message::Reply(Reply { address, axis, id, accepted, status, warning, data })
            }),
        // info text starting with a letter, so that it cannot be mistaken for a message id
        (
            0u8..100,
            0u8..10,
            proptest::option::of(0u8..100),
            "[a-z][A-Za-z0-9.]{0,8}( [A-Za-z0-9.]{1,8}){0,3}"
        )
            .prop_map(|(address, axis, id, text)| Message::Info(Info { address, axis, id, text })),
        (0u8..100, 0u8..10, status(), warning(), data_text()).prop_map(
            |(address, axis, status, warning, data)| Message::Alert(Alert {
                address,
                axis,
                status,
                warning,
                data
            })
        ),
    ]
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
    fn message_parsers_take_any_input(
        text in prop_oneof![wire_text(), "[ -~]{0,60}"],
        bytes in proptest::collection::vec(any::<u8>(), 0..80),
    ) {
        for line in [text.clone(), with_valid_checksum(&text), String::from_utf8_lossy(&bytes).into_owned()] {
            if let Ok(m) = Message::parse(&line) {
                // whatever parses re-encodes to something that parses to the same message
                prop_assert_eq!(Message::parse(&m.to_line(true)), Ok(m.clone()));
                // without checksum, data ending in `:XX` (hex) would read as a checksum
                let plain = m.to_line(false);
                if !plain.contains(':') {
                    prop_assert_eq!(Message::parse(&plain), Ok(m));
                }
            }
            if let Ok((c, _)) = Command::parse(&line) {
                prop_assert_eq!(Command::parse(&c.to_line(true)).map(|(c, _)| c), Ok(c));
            }
            let _ = parse_warning_list(&line);
            let _ = Warning::parse(&line);
        }
    }

    #[test]
    fn device_messages_round_trip_with_and_without_checksum_under_any_chunking(
        msgs in proptest::collection::vec(message(), 1..8),
        checksum_on in any::<bool>(),
        cuts in proptest::collection::vec(0usize..1000, 0..12),
    ) {
        let stream: Vec<u8> = msgs.iter().flat_map(|m| m.encode(checksum_on)).collect();
        let mut d = LineDeframer::new();
        let mut got = Vec::new();
        for chunk in split(&stream, &cuts) {
            d.push(&chunk);
            while let Ok(Some(line)) = d.next_line() {
                got.push(Message::parse(&line));
            }
        }
        prop_assert_eq!(got, msgs.into_iter().map(Ok).collect::<Vec<_>>());
    }

    #[test]
    fn corrupted_checksums_are_errors(msg in message(), flip in 0usize..40) {
        let line = msg.to_line(true);
        let mut bytes = line.clone().into_bytes();
        let i = 1 + flip % (bytes.len() - 4); // inside the body, not the sigil or checksum
        bytes[i] = if bytes[i] == b'7' { b'8' } else { b'7' };
        let corrupted = String::from_utf8_lossy(&bytes).into_owned();
        prop_assert!(corrupted == line || Message::parse(&corrupted).is_err(), "{}", corrupted);
    }

    /// The driver fed arbitrary bytes as answers returns errors, never panics.
    #[test]
    fn driver_takes_any_bytes(text in wire_text(), cuts in proptest::collection::vec(0usize..200, 0..6)) {
        let bytes = text.replace(' ', "\r\n ").into_bytes();
        let config = ZaberConfig { io_timeout: Duration::from_millis(20), poll_interval: Duration::from_millis(1), ..ZaberConfig::default() };
        if let Ok(mut guide) = ZaberAxis::new(ScriptedTransport::new(split(&bytes, &cuts)), config) {
            let _ = guide.position_mm();
            let _ = guide.is_homed();
            let _ = guide.wait_idle(Duration::from_millis(20));
        }
    }
}
