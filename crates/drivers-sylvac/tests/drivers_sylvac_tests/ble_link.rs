//! The BLE gauge (feature `ble`) without a reachable gauge: connecting fails with one clear
//! error value (no D-Bus / no adapter / not found within the scan timeout), never a panic or
//! a hang. Run with `cargo test -p vatcal-drivers-sylvac --features ble --test drivers_sylvac_tests ble_link::`.
#![cfg(feature = "ble")]

use std::time::{Duration, Instant};

use vatcal_drivers_sylvac::{BleConfig, BleTarget, SylvacBle, SylvacConfig};

#[test]
fn connecting_without_a_reachable_gauge_is_one_clear_error() {
    let ble = BleConfig {
        target: BleTarget::Name("SY-no-such-gauge".to_owned()),
        scan_timeout: Duration::from_millis(500),
        connect_timeout: Duration::from_millis(500),
    };
    let t0 = Instant::now();
    let e = match SylvacBle::connect_ble(&ble, SylvacConfig::default()) {
        Ok(_) => panic!("connected to a gauge that does not exist"),
        Err(e) => e.into_hw("gauge 1"),
    };
    let line = e.to_string();
    assert!(line.starts_with("gauge 1: "), "{line}");
    assert!(!line.contains('\n'), "{line}");
    assert!(t0.elapsed() < Duration::from_secs(30), "{:?}", t0.elapsed());
    eprintln!("{line}");
}
