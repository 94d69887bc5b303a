//! `vatcal demo --out <tmp>` end to end (reduced sizes: 100 orientations × 5 guide steps,
//! 100 random validation poses, 100 slices): the report folder exists and parses.

use std::path::Path;
use std::process::Command;

use vatcal_core::CellFile;
use vatcal_kinematics::Model;

fn run_demo(out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "demo",
        "--out",
        out.to_str().expect("utf-8 path"),
        "--seed",
        "3",
        "--orientations",
        "100",
        "--guide-steps",
        "5",
        "--random-poses",
        "100",
        "--slices",
        "100",
        "--truth",
        "ideal",
        // the discovery stage is tested in crates/demo/tests/demo_tests/discovery.rs
        "--no-discovery",
    ];
    args.extend_from_slice(extra);
    Command::new(env!("CARGO_BIN_EXE_vatcal")).args(&args).output().expect("run vatcal")
}

#[test]
fn demo_writes_a_report_folder_that_parses() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("demo");
    let o = run_demo(&out, &[]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("random poses (n = 100)") && stdout.contains("printing path (100 slices)"),
        "{stdout}"
    );
    assert!(stdout.contains("1.272 → 0.271") && stdout.contains("1.192 → 0.220"), "{stdout}");
    // no progress bar when stdout is not a terminal
    assert!(!String::from_utf8_lossy(&o.stderr).contains("ETA"));

    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json"))
            .expect("report.json parses");
    assert_eq!(report["format"], "vatcal-demo-report/1");
    assert_eq!(report["seed"], 3);
    let models = report["validation"]["models"].as_array().expect("models");
    assert_eq!(models.len(), 2);
    let mean = |m: &serde_json::Value, what: &str| -> f64 {
        let s = if what == "random" { &m["random"]["stats"] } else { &m["path"]["tip_stats"] };
        s["mean_mm"].as_f64().expect("mean_mm")
    };
    assert!(mean(&models[0], "random") > 10.0 * mean(&models[1], "random"));
    assert!(mean(&models[0], "path") > 10.0 * mean(&models[1], "path"));
    assert_eq!(report["paper"]["random_nominal_mean_mm"], 1.272);

    let cal = Model::from_cell(&CellFile::load(out.join("calibrated.toml")).expect("calibrated.toml"))
        .expect("calibrated model");
    let probe =
        vatcal_io::read_probe_measurements(out.join("measurements.csv"), &cal).expect("measurements.csv");
    assert_eq!(probe.len() as u64, report["campaign"]["measurements"].as_u64().expect("count"));
    let tracker =
        vatcal_io::read_tracker_measurements(out.join("validation_random.csv"), &cal).expect("tracker csv");
    assert_eq!(tracker.len(), 100);
    for label in ["nominal", "calibrated"] {
        let path = out.join(format!("validation_path_{label}.csv"));
        assert_eq!(vatcal_io::read_tracker_measurements(&path, &cal).expect("path csv").len(), 300);
    }
    let errors = std::fs::read_to_string(out.join("printing_path_errors.csv")).expect("errors csv");
    assert_eq!(errors.lines().count(), 101);
    for svg in ["random_errors_histogram.svg", "path_errors.svg", "identification_convergence.svg"] {
        let text = std::fs::read_to_string(out.join(svg)).expect("svg");
        assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"), "{svg}");
    }
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(summary.contains("## 4. Validation") && summary.contains("**paper**"));

    // the CLI's own validation agrees with the demo's numbers on the same files
    let v = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(["validate", "--model"])
        .arg(out.join("calibrated.toml"))
        .arg("--baseline")
        .arg(out.join("nominal.toml"))
        .arg("--tracker")
        .arg(out.join("validation_random.csv"))
        .output()
        .expect("run validate");
    let text = String::from_utf8_lossy(&v.stdout);
    assert!(v.status.success(), "{text}{}", String::from_utf8_lossy(&v.stderr));
    let cal_mean = format!("{:.4}", mean(&models[1], "random"));
    assert!(text.contains(&cal_mean), "`vatcal validate` should report {cal_mean}:\n{text}");
}

#[test]
fn demo_reports_bad_arguments() {
    let dir = tempfile::tempdir().expect("tmp");
    let o = run_demo(&dir.path().join("demo"), &["--model", "/nonexistent/cell.toml"]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("/nonexistent/cell.toml"), "{stderr}");
    // sizes are checked before anything runs
    let o = run_demo(&dir.path().join("demo"), &["--count", "0"]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("`count`: must be at least 1"), "{stderr}");
    assert!(!dir.path().join("demo").join("plan").exists(), "nothing was planned");
}

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `vatcal plan` on a version-2 fixture (the Meca500 on a table: no guide, numerical IK) writes
/// a plan whose files have the chain's `q1..q6` columns; `vatcal demo --cell` on the UR5e
/// fixture runs the device-level pipeline on its own virtual cell (`--quick`, the paper-like
/// truth, discovery on) and calibrates it.
#[test]
fn plan_and_demo_run_on_any_chain() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = dir.path().join("plan");
    let o = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(["plan", "--model", &fixture("meca500-table.toml"), "--orientations", "12", "--count", "40"])
        .args([
            "--detmax-restarts",
            "1",
            "--restarts",
            "2",
            "--quiet",
            "--out",
            plan.to_str().expect("utf-8"),
        ])
        .output()
        .expect("run vatcal");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&o.stderr));
    let selected = std::fs::read_to_string(plan.join("selected.csv")).expect("selected.csv");
    assert!(selected.starts_with("position,tcp,q1,q2,q3,q4,q5,q6\n"), "{selected:.60}");
    assert_eq!(selected.lines().count(), 41);
    let cell = CellFile::load(fixture("meca500-table.toml")).expect("fixture");
    let model = Model::from_cell(&cell).expect("model");
    let table = vatcal_io::read_candidates(plan.join("selected.csv"), &model).expect("read back");
    for m in &table.measurements {
        let p = m.position().expect("probe row");
        let err =
            (model.tcp_position(&m.q, m.tcp).expect("fk") - model.position(p).expect("position")).norm();
        assert!(err < 1e-6, "selected pose {err} mm off its position");
    }

    let demo = dir.path().join("demo");
    let o = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(["demo", "--cell", &fixture("ur5e.toml"), "--quick", "--quiet", "--seed", "1"])
        .args(["--out", demo.to_str().expect("utf-8")])
        .output()
        .expect("run vatcal");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("6 joints (RRRRRR), no printing path"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(demo.join("report.json")).expect("report.json"))
            .expect("json");
    assert_eq!(json["format"], "vatcal-demo-report/1");
    assert_eq!(json["campaign"]["measurements"], 40);
    assert!(json["compensation"].is_null(), "no printing path");
    let mean = |label: &str| {
        json["validation"]["models"]
            .as_array()
            .and_then(|m| m.iter().find(|m| m["label"] == label))
            .and_then(|m| m["random"]["stats"]["mean_mm"].as_f64())
            .unwrap_or(f64::NAN)
    };
    let (before, after, discovered) = (mean("nominal"), mean("calibrated"), mean("discovered"));
    eprintln!(
        "ur5e demo (seed 2, quick, paper-like truth): {before} mm -> {after} mm -> discovered {discovered} mm"
    );
    // the paper-like truth's gear harmonics act on the UR5e's long links: the 31 parameters
    // leave a good part of a millimetre (docs/virtual-cell.md)
    assert!(before > 0.3 && after < 0.6 * before, "{before} mm -> {after} mm");
    assert!(json["discovery"].is_object(), "the discovery stage ran");
    assert!(discovered.is_finite(), "the discovered model was validated");
    for f in ["summary.md", "calibrated.toml", "measurements.csv", "plan/tour.csv"] {
        assert!(demo.join(f).is_file(), "{f} missing");
    }
    // the summary speaks of the UR5e's own parameter set and direction columns, not the
    // canonical cell's 34 parameters and dir2..dir7
    let n = json["identification"]["n_parameters"].as_u64().expect("n_parameters");
    assert_ne!(n, 34);
    let summary = std::fs::read_to_string(demo.join("summary.md")).expect("summary.md");
    for text in [
        format!("Detmax for the {n} parameters"),
        "`dir1..dir6`".to_string(),
        format!("starting from the calibrated {n}-parameter model"),
        format!("| the calibration's {n} parameters |"),
        format!("what the {n}-parameter model leaves"),
    ] {
        assert!(summary.contains(&text), "`{text}` missing from summary.md:\n{summary}");
    }
    for canonical in ["34 parameters", "34-parameter", "dir2..dir7"] {
        assert!(!summary.contains(canonical), "`{canonical}` in summary.md:\n{summary}");
    }
    // no guide and no printing path on this cell: the summary does not describe them
    assert!(summary.contains("* **printing path**: none"), "no-printing-path line missing:\n{summary}");
    for guide in
        ["guide steps", ", guide 0.", "guide angular", "printing path (0 slices)", "0 printing slices"]
    {
        assert!(!summary.contains(guide), "`{guide}` in summary.md:\n{summary}");
    }
}
