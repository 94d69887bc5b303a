//! End-to-end tests of `vatcal identify` and `vatcal validate` on simulated data.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use vatcal_core::{CellFile, Measurement};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
    synthetic_tracker_measurements,
};

fn fixture() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
}

fn nominal() -> Model {
    Model::from_cell(&CellFile::load(fixture()).expect("fixture")).expect("model")
}

fn vatcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vatcal")).args(args).output().expect("run vatcal")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn write(path: &Path, m: &[Measurement]) {
    vatcal_io::write_measurements(path, m).expect("write csv");
}

#[test]
fn identify_then_validate_reaches_the_noise_floor() {
    let dir = tempfile::tempdir().expect("tmp");
    let nominal = nominal();
    let truth = perturbed_truth(&nominal, 21, &ErrorBudget::realistic());
    let starts = probe_start_poses(&nominal, 40, 22);
    let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.003 }, 23);
    let validation = synthetic_tracker_measurements(&truth, 200, 0.0, 24);
    let (m, v) = (dir.path().join("m.csv"), dir.path().join("v.csv"));
    write(&m, &probe);
    write(&v, &validation);
    let (cal, report) = (dir.path().join("cal.toml"), dir.path().join("r.json"));
    let out = vatcal(&[
        "identify",
        "--model",
        s(&fixture()),
        "--measurements",
        s(&m),
        "--out",
        s(&cal),
        "--report",
        s(&report),
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "identify failed:\n{stdout}\n{}", text(&out.stderr));
    assert!(stdout.contains("mean [mm]") && stdout.contains("converged"), "{stdout}");
    assert!(stdout.lines().filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit())).count() >= 3);
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    assert_eq!(r["parameters"].as_array().map(Vec::len), Some(34));
    assert_eq!(r["converged"], serde_json::Value::Bool(true));

    let (plot, vreport) = (dir.path().join("h.svg"), dir.path().join("v.json"));
    let out = vatcal(&[
        "validate",
        "--model",
        s(&cal),
        "--baseline",
        s(&fixture()),
        "--tracker",
        s(&v),
        "--plot",
        s(&plot),
        "--report",
        s(&vreport),
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "validate failed:\n{stdout}\n{}", text(&out.stderr));
    assert!(
        stdout.contains("95%") && stdout.contains("baseline") && stdout.contains("RMS x / y / z"),
        "{stdout}"
    );
    let svg = std::fs::read_to_string(&plot).expect("svg");
    assert!(svg.contains("<svg") && svg.contains("baseline (meca500-zaber.toml)"));
    let vr: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&vreport).expect("v")).expect("json");
    let calibrated = vr["model"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean");
    let before = vr["baseline"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean");
    eprintln!("validation mean error: nominal {before} mm, calibrated {calibrated} mm");
    assert!(before > 0.5, "nominal {before}");
    assert!(calibrated < 0.025, "calibrated {calibrated}");
}

#[test]
fn bad_input_gets_a_clear_error_and_a_non_zero_exit() {
    let dir = tempfile::tempdir().expect("tmp");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0,0\n2,1,100,abc,0,0,0,0,0\n")
        .expect("write");
    let cal = dir.path().join("cal.toml");
    let out = vatcal(&["identify", "--model", s(&fixture()), "--measurements", s(&bad), "--out", s(&cal)]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("bad.csv:3") && stderr.contains("q2"), "{stderr}");
    assert!(!cal.exists());

    // unknown parameter name
    let nominal = nominal();
    let exact = probe_start_poses(&nominal, 45, 31);
    let m = dir.path().join("m.csv");
    write(&m, &exact);
    let out = vatcal(&[
        "identify",
        "--model",
        s(&fixture()),
        "--measurements",
        s(&m),
        "--out",
        s(&cal),
        "--params",
        "d_4,zz_9",
    ]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("zz_9"), "{}", text(&out.stderr));

    // rank-deficient data: one calibration position
    let one: Vec<Measurement> = exact.iter().filter(|m| m.position() == Some(2)).copied().collect();
    let m1 = dir.path().join("one.csv");
    write(&m1, &one);
    let out = vatcal(&["identify", "--model", s(&fixture()), "--measurements", s(&m1), "--out", s(&cal)]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("cannot identify") && stderr.contains("base_"), "{stderr}");

    // the literal paper method is reported as not converging
    let truth = perturbed_truth(&nominal, 32, &ErrorBudget::realistic());
    let probe = synthetic_probe_measurements(&truth, &exact, ProbeNoise::default(), 33);
    write(&m, &probe);
    let out = vatcal(&[
        "identify",
        "--model",
        s(&fixture()),
        "--measurements",
        s(&m),
        "--out",
        s(&cal),
        "--method",
        "paper",
        "--max-iterations",
        "8",
    ]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("did not converge"), "{stderr}");
    assert!(text(&out.stdout).contains("mean [mm]"), "the log is printed");

    // validate with a file that has neither probe rows (position) nor tracker rows (x,y,z)
    let joints_only = dir.path().join("joints-only.csv");
    std::fs::write(&joints_only, "tcp,q1,q2,q3,q4,q5,q6,q7\n1,100,0,0,0,0,0,0\n").expect("write");
    let out = vatcal(&["validate", "--model", s(&fixture()), "--tracker", s(&joints_only)]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("joints-only.csv:1: column `position / x,y,z / plane`"),
        "{}",
        text(&out.stderr)
    );
}
