//! The devices file: the two fixtures parse, and every kind of mistake is one clear error
//! naming the file, the line and the field — before anything connects.

use std::time::Duration;

use vatcal_core::JointKind;
use vatcal_devices::{DevicesError, DevicesFile, Link};
use vatcal_hardware_traits::JointLayout;

const EXAMPLE: &str = include_str!("../../../../fixtures/devices-example.toml");
const SIM: &str = include_str!("../../../../fixtures/sim-cell-devices.toml");

fn parse(text: &str) -> Result<DevicesFile, DevicesError> {
    DevicesFile::parse(text, "devices.toml")
}

fn error(text: &str) -> String {
    parse(text).expect_err("must be rejected").to_string()
}

const ARM: &str = "arm = { kind = \"meca500\", address = \"10.0.0.1:10000\" }\n";
const GUIDE: &str = "guide = { kind = \"zaber\", tcp = \"10.0.0.2:55550\" }\n";
const GAUGES: &str = "gauges = [\n  { kind = \"sylvac\", tcp = \"10.0.0.3:1\" },\n  { kind = \"sylvac\", tcp = \"10.0.0.3:2\" },\n  { kind = \"sylvac\", tcp = \"10.0.0.3:3\" },\n]\n";

#[test]
fn the_fixtures_parse_with_their_addresses_and_timeouts() {
    let real = parse(EXAMPLE).expect("example");
    assert_eq!(real.arm.address.get_ref(), "192.168.0.100:10000");
    assert_eq!(real.guide_link(), Some(Link::Tcp("192.168.0.50:55550".into())));
    assert_eq!(real.gauge_link(2), Some(Link::Tcp("192.168.0.60:4003".into())));
    assert_eq!(real.arm_config().io_timeout, Duration::from_millis(2000));
    assert_eq!(real.guide_config().io_timeout, Duration::from_millis(1000));
    assert_eq!(real.gauge_config(1).name, "gauge 2");
    assert!(real.sim_control.is_none());
    let sim = parse(SIM).expect("sim");
    assert_eq!(sim.sim_control.as_ref().map(|c| c.tcp.get_ref().as_str()), Some("127.0.0.1:55570"));
    assert!(sim.gauges.iter().all(|g| g.tcp.as_ref().is_some_and(|t| t.get_ref().starts_with("127.0.0.1:"))));
}

#[test]
fn unknown_keys_are_rejected_with_their_name_and_line() {
    let e = error(&format!("{ARM}{GUIDE}{GAUGES}speed = 3\n"));
    assert!(e.starts_with("devices.toml: ") && e.contains("speed") && e.contains("line 8"), "{e}");
    let e = error(&format!("arm = {{ kind = \"meca500\", adress = \"10.0.0.1:10000\" }}\n{GUIDE}{GAUGES}"));
    assert!(e.contains("adress") && e.contains("line 1"), "{e}");
}

#[test]
fn the_guide_is_needed_exactly_when_the_cells_chain_has_one() {
    let canonical = JointLayout::MECA500_ON_GUIDE;
    let ur5e = JointLayout::of(&[JointKind::Revolute; 6]);
    let with_guide = parse(&format!("{ARM}{GUIDE}{GAUGES}")).expect("with a guide");
    let without = parse(&format!("{ARM}{GAUGES}")).expect("a file without a guide parses");
    assert!(without.guide.is_none() && without.guide_link().is_none());
    with_guide.check_cell(&canonical, "7 joints (PRRRRRR)").expect("canonical cell with its guide");
    without.check_cell(&ur5e, "6 joints (RRRRRR)").expect("UR5e without a guide");
    let e = without.check_cell(&canonical, "7 joints (PRRRRRR)").expect_err("guide missing").to_string();
    assert!(
        e.starts_with("devices.toml: ") && e.contains("has a guide") && e.contains("no `guide` entry"),
        "{e}"
    );
    let e = with_guide.check_cell(&ur5e, "6 joints (RRRRRR)").expect_err("guide too many").to_string();
    assert!(
        e.starts_with("devices.toml: ") && e.contains("6 joints (RRRRRR)") && e.contains("no guide"),
        "{e}"
    );
}

#[test]
fn missing_devices_are_named() {
    let e = error(&format!("{GUIDE}{GAUGES}"));
    assert!(e.contains("arm"), "{e}");
    let e = error(&format!("{ARM}{GUIDE}gauges = [ {{ kind = \"sylvac\", tcp = \"1.2.3.4:5\" }} ]\n"));
    assert!(e.contains("`gauges`") && e.contains("exactly 3 gauges") && e.contains("lists 1"), "{e}");
}

#[test]
fn bad_addresses_kinds_links_and_timeouts_name_the_field_and_line() {
    let e = error(&format!("arm = {{ kind = \"meca500\", address = \"10.0.0.1\" }}\n{GUIDE}{GAUGES}"));
    assert_eq!(e, "devices.toml:1: `arm.address`: `10.0.0.1` is not `host:port`");
    let e = error(&format!("{ARM}{GUIDE}{}", GAUGES.replace("10.0.0.3:2", "10.0.0.3:99999")));
    assert!(e.starts_with("devices.toml:5: `gauges[1].tcp`: ") && e.contains("port"), "{e}");
    let e = error(&format!("{ARM}guide = {{ kind = \"thorlabs\", tcp = \"1.2.3.4:5\" }}\n{GAUGES}"));
    assert!(e.contains("`guide.kind`") && e.contains("`thorlabs`") && e.contains("`zaber`"), "{e}");
    let e = error(&format!("{ARM}guide = {{ kind = \"zaber\" }}\n{GAUGES}"));
    assert!(e.contains("`guide`") && e.contains("`tcp") && e.contains("`serial"), "{e}");
    let e = error(&format!(
        "{ARM}guide = {{ kind = \"zaber\", tcp = \"1.2.3.4:5\", serial = \"/dev/ttyUSB0\" }}\n{GAUGES}"
    ));
    assert!(e.contains("not both"), "{e}");
    let e = error(&format!(
        "arm = {{ kind = \"meca500\", address = \"10.0.0.1:10000\", io_timeout_ms = 0 }}\n{GUIDE}{GAUGES}"
    ));
    assert!(e.contains("`arm.io_timeout_ms`") && e.contains("0 ms"), "{e}");
    let e = error(&format!("{ARM}{GUIDE}{GAUGES}tracker = {{ kind = \"faro\", tcp = \"1.2.3.4:5\" }}\n"));
    assert!(e.contains("`tracker.kind`") && e.contains("unknown kind `faro`"), "{e}");
    let e = error(&format!("{ARM}{GUIDE}{GAUGES}sim_control = {{ tcp = \"localhost\" }}\n"));
    assert!(e.contains("`sim_control.tcp`"), "{e}");
}

#[test]
fn thermometer_entries_are_checked() {
    let base = format!("{ARM}{GUIDE}{GAUGES}");
    for (entry, expected) in [
        ("{ kind = \"sim-cell\" }", "`thermometer.kind`: `sim-cell` reads `TEMP?`"),
        ("{ kind = \"pt1000\" }", "unknown kind `pt1000`"),
        ("{ kind = \"file\" }", "`thermometer.path`: a `file` thermometer needs `path`"),
        ("{ kind = \"command\", command = [] }", "`thermometer.command`: names no program"),
        ("{ kind = \"command\", path = \"/tmp/t\" }", "`thermometer.path`: not used by a `command`"),
        ("{ kind = \"file\", path = \"/tmp/t\", scale = 0.0 }", "`thermometer.scale`"),
        ("{ kind = \"file\", path = \"/tmp/t\", unit = \"F\" }", "unit"),
    ] {
        let e = error(&format!("{base}thermometer = {entry}\n"));
        assert!(e.starts_with("devices.toml:") && e.contains(expected), "{entry}: {e}");
    }
    let ok = parse(&format!("{base}thermometer = {{ kind = \"file\", path = \"/tmp/t\", scale = 0.001 }}\n"))
        .expect("valid");
    assert_eq!(ok.thermometer.as_ref().map(|t| t.kind.get_ref().as_str()), Some("file"));
    let sim =
        parse(&format!("{SIM}thermometer = {{ kind = \"sim-cell\" }}\n")).expect("sim-cell thermometer");
    assert!(sim.thermometer.is_some());
}

#[cfg(not(feature = "serial"))]
#[test]
fn a_serial_link_without_the_feature_is_refused_before_connecting() {
    let e = error(&format!("{ARM}guide = {{ kind = \"zaber\", serial = \"/dev/ttyUSB0\" }}\n{GAUGES}"));
    assert!(e.contains("`guide.serial`") && e.contains("`serial` feature"), "{e}");
}

#[test]
fn connecting_to_nothing_names_the_device() {
    // a port nobody listens on: bind, note the address, close
    let addr = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        l.local_addr().expect("addr").to_string()
    };
    let text = format!(
        "arm = {{ kind = \"meca500\", address = \"{addr}\", connect_timeout_ms = 500 }}\n{GUIDE}{GAUGES}"
    );
    let e = parse(&text).expect("valid file").connect().expect_err("nobody listens").to_string();
    assert!(e.starts_with(&format!("connecting the arm (meca500 at {addr}): meca500: ")), "{e}");
}

#[test]
fn tracker_entries_are_checked() {
    let base = format!("{ARM}{GUIDE}{GAUGES}");
    for (entry, expected) in [
        ("{ kind = \"sim-cell\" }", "`tracker.tcp`: a `sim-cell` tracker needs `tcp"),
        ("{ kind = \"sim-cell\", tcp = \"localhost\" }", "`tracker.tcp`: `localhost` is not `host:port`"),
        ("{ kind = \"command\" }", "`tracker.command`: a `command` tracker needs `command"),
        ("{ kind = \"command\", command = [\" \"] }", "`tracker.command`: names no program"),
        ("{ kind = \"console\", tcp = \"1.2.3.4:5\" }", "`tracker.tcp`: not used by a `console` tracker"),
        ("{ kind = \"console\", io_timeout_ms = 100 }", "`tracker.io_timeout_ms`: not used by a `console`"),
        ("{ kind = \"command\", command = [\"x\"], connect_timeout_ms = 5 }", "`tracker.connect_timeout_ms`"),
        ("{ kind = \"command\", command = [\"x\"], io_timeout_ms = 0 }", "`tracker.io_timeout_ms`: 0 ms"),
        ("{ kind = \"console\", frame = \"world\" }", "`tracker.frame`: `world`"),
        ("{ kind = \"laser\" }", "unknown kind `laser` (supported: `sim-cell`, `command`, `console`)"),
    ] {
        let e = error(&format!("{base}tracker = {entry}\n"));
        assert!(e.starts_with("devices.toml:8: ") && e.contains(expected), "{entry}: {e}");
    }
    let file =
        parse(&format!("{base}tracker = {{ kind = \"console\", frame = \"tank\" }}\n")).expect("console");
    assert!(file.tracker_reports_in_tank_frame());
    let file = parse(&format!("{base}tracker = {{ kind = \"command\", command = [\"faro-bridge\", \"--ip\", \"10.0.0.5\"], io_timeout_ms = 60000 }}\n"))
        .expect("command");
    assert!(!file.tracker_reports_in_tank_frame());
    let sim = parse(SIM).expect("sim");
    assert_eq!(
        sim.tracker.as_ref().and_then(|t| t.tcp.as_ref()).map(|a| a.get_ref().as_str()),
        Some("127.0.0.1:55580")
    );
}
