//! The codec's parsers on arbitrary input: no panic, errors are values; round trips of every
//! request and reply; the driver fed arbitrary bytes through a scripted transport.

use nalgebra::Vector3;
use proptest::prelude::*;
use vatcal_drivers_tracker::codec::{ErrorCode, MAX_ID, Reply, Request, format_xyz_mm, parse_xyz_mm};
use vatcal_drivers_tracker::{LineTracker, TrackerConfig};
use vatcal_hardware_traits::transport::ScriptedTransport;

fn code() -> impl Strategy<Value = ErrorCode> {
    prop_oneof![
        Just(ErrorCode::LineOfSight),
        Just(ErrorCode::UnknownTarget),
        Just(ErrorCode::BadRequest),
        Just(ErrorCode::Device),
    ]
}

proptest! {
    #[test]
    fn parsers_never_panic(s in "\\PC{0,80}", bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
        let _ = Request::parse(&s);
        let _ = Reply::parse(&s);
        let _ = parse_xyz_mm(&s);
        let lossy = String::from_utf8_lossy(&bytes);
        let _ = Request::parse(&lossy);
        let _ = Reply::parse(&lossy);
        let _ = parse_xyz_mm(&lossy);
    }

    #[test]
    fn requests_round_trip(id in 1..=MAX_ID, target in any::<u32>(), identify in any::<bool>()) {
        let r = if identify { Request::Identify } else { Request::Measure { target } };
        let line = String::from_utf8(r.encode(id)).expect("ascii");
        prop_assert_eq!(Request::parse(line.trim_end()), Ok((id, r)));
    }

    #[test]
    fn replies_round_trip(id in 0..=MAX_ID, code in code(), text in "[ -~]{0,40}", ok in any::<bool>()) {
        let text = text.trim().to_owned();
        let r = if ok { Reply::Ok { id, text } } else { Reply::Err { id, code, message: text } };
        let line = String::from_utf8(r.encode()).expect("ascii");
        prop_assert_eq!(Reply::parse(line.trim_end()), Ok(r));
    }

    #[test]
    fn readings_round_trip_to_a_nanometre(x in -1e5f64..1e5, y in -1e5f64..1e5, z in -1e5f64..1e5) {
        let p = Vector3::new(x, y, z);
        let back = parse_xyz_mm(&format_xyz_mm(&p)).expect("parses");
        prop_assert!((back - p).amax() <= 5.1e-7);
    }

    #[test]
    fn the_driver_survives_arbitrary_bytes(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..40), 0..6)) {
        let mut script = vec![b"1 OK fuzz\n".to_vec()];
        script.extend(chunks);
        let config = TrackerConfig { io_timeout: std::time::Duration::from_millis(5), ..TrackerConfig::default() };
        if let Ok(mut t) = LineTracker::new(ScriptedTransport::new(script), config) {
            let _ = t.measure(1);
            let _ = t.measure(2);
        }
    }
}
