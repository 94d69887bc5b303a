//! Planned validation and discovery campaigns by hand (issue 22 item 3), with real child
//! processes over TCP: `vatcal sim-cell --seed 3` (ephemeral ports, time scale 1000, its
//! tracker reporting in its own frame), a small calibration (`vatcal plan`, `vatcal campaign`,
//! `vatcal identify`), then
//!
//! * `vatcal plan --kind validation` (random poses and the printing path commanded by the
//!   nominal and the calibrated model) → `vatcal campaign --plan` (registration, then the
//!   tracker points; killed with `kill -9` half-way and resumed) → `vatcal validate` reads the
//!   tracker rows: every planned point once, the calibrated model several times better than
//!   the nominal one;
//! * `vatcal plan --kind discovery` → `vatcal campaign --plan` → probe rows with `dir2..dir7`
//!   and `time_s`, the two-sided repeats approached from the opposite side on every joint →
//!   `vatcal discover` reads them.

use std::path::{Path, PathBuf};

use super::calibrate::kill_in;
use super::campaign_sim::{SimCellProcess, campaign_args, identify_run, ok, plan, s, vatcal};

const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");

fn campaign(devices: &Path, plan: &Path, out: &Path, resume: bool) -> String {
    let mut args = campaign_args(devices, plan, out);
    if resume {
        args.push("--resume");
    }
    ok(&vatcal(&args))
}

fn summary(plan: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(plan.join("summary.json")).expect("summary.json"))
        .expect("json")
}

/// Data rows of a CSV as `(header, rows of fields)`.
fn table(csv: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines.next().expect("header").split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(String::from).collect()).collect())
}

#[test]
fn validation_and_discovery_plans_run_by_hand_over_tcp() {
    let dir = tempfile::tempdir().expect("tmp");
    let cell = SimCellProcess::start(&["--seed", "3", "--time-scale", "1000"]);
    let devices = cell.devices_file(dir.path());
    // the calibration the validation compares with
    let plan = plan(3, dir.path());
    let run = dir.path().join("run");
    campaign(&devices, &plan, &run, false);
    let calibrated = identify_run(&run);

    std::thread::scope(|scope| {
        // discovery by hand, on a second cell of the same seed beside the validation
        let discovery = scope.spawn(|| {
            let cell = SimCellProcess::start(&["--seed", "3", "--time-scale", "1000"]);
            let dir = dir.path().join("discovery-cell");
            std::fs::create_dir_all(&dir).expect("create dir");
            discovery_plan_campaign_and_discover(&dir, &cell.devices_file(&dir), &calibrated);
        });
        // validation by hand
        let (vplan, planned) = plan_validation(dir.path(), &calibrated);
        a_validation_plan_without_a_tracker_is_refused(dir.path(), &devices, &vplan);
        let rows = validation_killed_half_way_and_resumed(dir.path(), &devices, &vplan, planned);
        the_calibrated_model_validates_better_than_the_nominal(dir.path(), &calibrated, &rows, planned);
        discovery.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
    });
}

/// `vatcal plan --kind validation`: 20 random poses and the printing path of the nominal and
/// the calibrated model. Returns the plan folder and its number of tracker points.
fn plan_validation(dir: &Path, calibrated: &Path) -> (PathBuf, usize) {
    let vplan = dir.join("vplan");
    let path_model = format!("calibrated={}", s(calibrated));
    ok(&vatcal(&[
        "plan",
        "--kind",
        "validation",
        "--model",
        FIXTURE,
        "--seed",
        "3",
        "--random-poses",
        "20",
        "--slices",
        "20",
        "--path-model",
        &path_model,
        "--out",
        s(&vplan),
    ]));
    let vs = summary(&vplan);
    assert_eq!(vs["kind"], "validation", "{vs}");
    assert_eq!(vs["path_runs"], serde_json::json!(["nominal", "calibrated"]), "{vs}");
    let planned = vs["tracker_measurements"].as_u64().expect("count") as usize;
    assert_eq!(planned, 20 + 2 * 20 * 3, "{vs}");
    (vplan, planned)
}

/// A validation plan without a tracker in the devices file is refused before connecting.
fn a_validation_plan_without_a_tracker_is_refused(dir: &Path, devices: &Path, vplan: &Path) {
    let no_tracker = dir.join("no-tracker.toml");
    let text = std::fs::read_to_string(devices).expect("devices");
    let kept: Vec<&str> = text.lines().filter(|l| !l.starts_with("tracker")).collect();
    std::fs::write(&no_tracker, kept.join("\n")).expect("write");
    let never = dir.join("never");
    let refused = vatcal(&campaign_args(&no_tracker, vplan, &never));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("no `tracker`"), "{err}");
}

/// `kill -9` half-way through the tracker points, then `--resume`: the registration is
/// reused and every point is journaled once. Returns the tracker rows' file.
fn validation_killed_half_way_and_resumed(
    dir: &Path,
    devices: &Path,
    vplan: &Path,
    planned: usize,
) -> PathBuf {
    let vrun = dir.join("vrun");
    let journal = vrun.join("validation.journal");
    let tracked =
        || std::fs::read_to_string(&journal).map_or(0, |t| t.matches("\"outcome\":\"tracked\"").count());
    kill_in(&campaign_args(devices, vplan, &vrun), || tracked() >= planned / 2);
    let before_resume = tracked();
    assert!(before_resume >= planned / 2 && before_resume < planned, "{before_resume} of {planned}");
    let registration = std::fs::read_to_string(vrun.join("tracker-registration.json")).expect("registration");
    let stdout = campaign(devices, vplan, &vrun, true);
    assert!(stdout.contains("resumed at step"), "{stdout}");
    assert_eq!(
        std::fs::read_to_string(vrun.join("tracker-registration.json")).expect("registration"),
        registration,
        "the resume reuses the registration"
    );
    let reg: serde_json::Value = serde_json::from_str(&registration).expect("json");
    assert!(reg["rms_residual_mm"].as_f64().expect("rms") < 0.02, "{reg}");
    assert_eq!(tracked(), planned, "every point journaled once");
    let rows = vrun.join("validation_measurements.csv");
    let (header, data) = table(&rows);
    assert!(header.starts_with(&["tcp".into(), "q1".into()]) && header.contains(&"x".into()), "{header:?}");
    assert_eq!(data.len(), planned);
    rows
}

/// `vatcal validate` reads the tracker rows: every planned point, the calibrated model several
/// times better than the nominal one.
fn the_calibrated_model_validates_better_than_the_nominal(
    dir: &Path,
    calibrated: &Path,
    rows: &Path,
    planned: usize,
) {
    let report = dir.join("validate.json");
    let stdout = ok(&vatcal(&[
        "validate",
        "--model",
        s(calibrated),
        "--baseline",
        FIXTURE,
        "--tracker",
        s(rows),
        "--report",
        s(&report),
    ]));
    eprintln!("{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    let mean = |m: &serde_json::Value| m["validation"]["stats"]["mean_mm"].as_f64().expect("mean");
    let (nominal, cal) = (mean(&v["baseline"]), mean(&v["model"]));
    assert_eq!(v["model"]["validation"]["stats"]["n"].as_u64(), Some(planned as u64));
    // the paper-like truth is ~1.3 mm off nominal; the 34 parameters remove most of it
    assert!((0.5..3.0).contains(&nominal), "nominal {nominal}");
    assert!(cal < nominal / 3.0, "calibrated {cal} vs nominal {nominal}");
}

/// `vatcal plan --kind discovery` → `vatcal campaign --plan` → probe rows with `dir2..dir7`
/// and `time_s`, each two-sided repeat after its pose with every direction reversed →
/// `vatcal discover` reads them.
fn discovery_plan_campaign_and_discover(dir: &Path, devices: &Path, calibrated: &Path) {
    let dplan = dir.join("dplan");
    ok(&vatcal(&[
        "plan",
        "--kind",
        "discovery",
        "--model",
        FIXTURE,
        "--seed",
        "3",
        "--orientations",
        "20",
        "--guide-steps",
        "3",
        "--count",
        "24",
        "--two-sided-repeats",
        "4",
        "--out",
        s(&dplan),
        "--quiet",
    ]));
    let ds = summary(&dplan);
    assert_eq!((ds["kind"].as_str(), ds["two_sided_repeats"].as_u64()), (Some("discovery"), Some(4)), "{ds}");
    let drun = dir.join("drun");
    campaign(devices, &dplan, &drun, false);
    let (header, data) = table(&drun.join("discovery_measurements.csv"));
    for col in ["position", "tcp", "time_s", "dir2", "dir7"] {
        assert!(header.iter().any(|h| h == col), "{col} in {header:?}");
    }
    assert_eq!(data.len(), 24 + 4);
    let col = |name: &str| header.iter().position(|h| h == name).expect("column");
    let (d2, d7) = (col("dir2"), col("dir7"));
    // a repeat follows its pose, same ball and position, every direction reversed
    let pairs = data
        .windows(2)
        .filter(|w| {
            w[0][..2] == w[1][..2]
                && (d2..=d7).all(|k| {
                    let (a, b): (i32, i32) = (w[0][k].parse().expect("dir"), w[1][k].parse().expect("dir"));
                    a == -b && a != 0
                })
        })
        .count();
    assert_eq!(pairs, 4, "{data:?}");
    let stdout = ok(&vatcal(&[
        "discover",
        "--model",
        s(calibrated),
        "--measurements",
        s(&drun.join("discovery_measurements.csv")),
        "--seed",
        "3",
        "--probe-sigma-mm",
        "0.002",
    ]));
    assert!(stdout.contains("result:"), "{stdout}");
}
