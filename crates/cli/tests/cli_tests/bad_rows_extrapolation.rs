//! Issue 29, items 4 and 5, through the binary: `vatcal identify` names a row 60 mm off by its
//! file and line (and keeps it), `--robust cauchy` down-weights it, `--drop-outliers 4` removes
//! it and calibrates again; the calibrated file records the training range, and `vatcal
//! validate` / `vatcal compensate` warn, naming file:line and joint, about postures outside it.
//! Simulated UR5e tracker data (a perturbed truth, the tracker frame rotated and two metres
//! away, the marker 80 mm from TCP 1), seeded.

use super::any_robot::{fixture, run, vatcal};
use nalgebra::{Rotation3, Vector3};
use std::path::{Path, PathBuf};
use vatcal_compensation::PoseRequest;

use vatcal_core::training_range::TrainingRange;
use vatcal_core::{Axis, CellFile, JointKind, JointVector, Measurement, MeasurementContext, ParamId, Target};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, synthetic_tracker_measurements};

/// The displaced row (0-based among the data rows) and its displacement (60 mm).
const BAD_ROW: usize = 17;
const DISPLACEMENT_MM: [f64; 3] = [36.0, -28.8, 38.4];

fn truth(nominal: &Model) -> Model {
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(nominal, 11, &budget);
    let tcp = t.tcp(1).expect("tcp 1") + Vector3::new(30.0, -50.0, 56.6);
    for (axis, v) in Axis::ALL.iter().zip(tcp.iter()) {
        t.set_param(ParamId::Tcp { id: 1, axis: *axis }, *v).expect("tcp");
    }
    t
}

/// What the tracker sees of TCP 1 at `q` (no noise).
fn seen(truth: &Model, q: &JointVector) -> Vector3<f64> {
    let r = Rotation3::from_euler_angles(0.9, -0.6, 2.2);
    r * truth.tcp_position(q, 1).expect("fk") + Vector3::new(1300.0, -1500.0, 500.0)
}

fn rows(truth: &Model, n: usize, sigma_mm: f64, seed: u64) -> Vec<Measurement> {
    synthetic_tracker_measurements(truth, n, sigma_mm, seed)
        .into_iter()
        .map(|m| {
            let Target::Tracker { xyz_mm } = m.target else { unreachable!("tracker rows") };
            let noise = xyz_mm - truth.tcp_position(&m.q, m.tcp).expect("fk");
            Measurement::tracker(1, m.q, seen(truth, &m.q) + noise)
        })
        .collect()
}

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("json")
}

/// The output of a run that may fail: (success, stdout, stderr).
fn run_full(args: &[&str]) -> (bool, String, String) {
    let out = vatcal().args(args).output().expect("run");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// A path as an argument.
fn s(path: &Path) -> String {
    path.display().to_string()
}

/// The files of the run: the UR5e fixture, the truth, 80 clean rows and 300 held-out ones, and
/// the bad file (row 17 displaced by 60 mm, a comment line before it).
struct Case {
    dir: tempfile::TempDir,
    ur5e: String,
    kinds: Vec<JointKind>,
    truth: Model,
    clean: Vec<Measurement>,
    bad_csv: String,
    /// 1-based line of the displaced row
    bad_line: usize,
    /// `file:line` of the displaced row
    named: String,
}

impl Case {
    fn new() -> Self {
        let dir = tempfile::tempdir().expect("tmp");
        let ur5e = fixture("ur5e.toml");
        let nominal = Model::from_cell(&CellFile::load(&ur5e).expect("fixture")).expect("model");
        let kinds = nominal.joint_kinds().to_vec();
        let truth = truth(&nominal);
        let clean = rows(&truth, 80, 0.01, 5);
        let held = rows(&truth, 300, 0.0, 6);
        let p = |name: &str| dir.path().join(name);
        vatcal_io::write_measurements_for(p("clean.csv"), &clean, &kinds).expect("write");
        vatcal_io::write_measurements_for(p("held.csv"), &held, &kinds).expect("write");
        // the bad file: row 17 displaced by 60 mm, a comment line before it
        let mut bad = clean.clone();
        let Target::Tracker { xyz_mm } = bad[BAD_ROW].target else { unreachable!("tracker rows") };
        bad[BAD_ROW].target = Target::Tracker { xyz_mm: xyz_mm + Vector3::from(DISPLACEMENT_MM) };
        let text = vatcal_io::measurements_to_csv_for(&bad, &kinds);
        let mut lines: Vec<&str> = text.lines().collect();
        let header = lines.iter().position(|l| !l.starts_with('#')).expect("header");
        lines.insert(header + 1 + BAD_ROW, "# the tracker lost the marker on the next row");
        let bad_line = header + 1 + BAD_ROW + 2; // 1-based line of the displaced row
        std::fs::write(p("bad.csv"), lines.join("\n") + "\n").expect("write");
        let bad_csv = s(&p("bad.csv"));
        let named = format!("{bad_csv}:{bad_line}");
        Case { dir, ur5e, kinds, truth, clean, bad_csv, bad_line, named }
    }

    /// A file of the run's folder.
    fn p(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `vatcal identify` of `data` on the UR5e fixture, writing `{out}.toml` and `{out}.json`.
    fn identify(&self, data: &str, out: &str, extra: &[&str]) -> String {
        let mut args = vec![
            "identify".to_string(),
            "--model".into(),
            self.ur5e.clone(),
            "--measurements".into(),
            data.to_string(),
            "--out".into(),
            s(&self.p(&format!("{out}.toml"))),
            "--report".into(),
            s(&self.p(&format!("{out}.json"))),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args)
    }

    /// The mean held-out error of a calibrated model \[mm\].
    fn held_mean(&self, model: &str) -> f64 {
        run(&[
            "validate",
            "--model",
            &s(&self.p(model)),
            "--tracker",
            &s(&self.p("held.csv")),
            "--report",
            &s(&self.p("v.json")),
        ]);
        json(&self.p("v.json"))["model"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean")
    }
}

#[test]
fn bad_rows_are_named_down_weighted_and_dropped_and_extrapolation_is_warned() {
    let case = Case::new();
    let range = the_clean_fit_records_its_training_range(&case);
    the_default_fit_names_the_bad_row_and_keeps_it(&case);
    cauchy_down_weights_the_bad_row(&case);
    drop_outliers_removes_the_bad_row_and_calibrates_again(&case);
    robust_and_dropping_fits_are_back_near_the_clean_fit(&case);
    bad_flags_are_refused(&case);
    let postures = validate_warns_of_postures_outside_the_training_range(&case, &range);
    compensate_warns_of_targets_outside_the_training_range(&case, &postures);
}

/// The clean data: nothing flagged; the training range is recorded in the file and report.
fn the_clean_fit_records_its_training_range(case: &Case) -> TrainingRange {
    let p = |name: &str| case.p(name);
    let out = case.identify(&s(&p("clean.csv")), "clean", &[]);
    assert!(out.contains("bad rows: 0 beyond 4 x robust sigma"), "{out}");
    assert!(out.contains("training range (80 rows"), "{out}");
    let cell = CellFile::load(p("clean.toml")).expect("calibrated");
    let range = cell.training_range.clone().expect("[training_range]");
    assert_eq!((range.rows, range.q_min.len()), (80, 6));
    assert_eq!(json(&p("clean.json"))["training_range"]["rows"], 80);
    assert!(std::fs::read_to_string(p("clean.toml")).expect("toml").contains("[training_range]"));
    range
}

/// The default names the displaced row by file and line and keeps it.
fn the_default_fit_names_the_bad_row_and_keeps_it(case: &Case) {
    let (named, bad_line) = (&case.named, case.bad_line);
    let out = case.identify(&case.bad_csv, "default", &[]);
    eprintln!("{out}");
    assert!(out.contains(named) && out.contains("kept in the fit"), "{named}\n{out}");
    let report = json(&case.p("default.json"));
    let first = &report["bad_rows"]["rows"][0];
    assert_eq!(
        (first["row"].as_u64(), first["line"].as_u64()),
        (Some(BAD_ROW as u64), Some(bad_line as u64))
    );
    assert_eq!(first["file"].as_str(), Some(case.bad_csv.as_str()));
    assert!(first["residual_mm"].as_f64().expect("residual") > 40.0);
    assert_eq!(report["bad_rows"]["k"], 4.0);
}

/// `--robust cauchy`: down-weighted, named with its weight.
fn cauchy_down_weights_the_bad_row(case: &Case) {
    let out = case.identify(&case.bad_csv, "cauchy", &["--robust", "cauchy"]);
    assert!(out.contains("robust fit (cauchy, c = 2.385") && out.contains(&case.named), "{out}");
    let report = json(&case.p("cauchy.json"));
    assert_eq!(report["bad_rows"]["robust"]["loss"], "cauchy");
    let row = &report["bad_rows"]["rows"][0];
    assert_eq!(row["line"].as_u64(), Some(case.bad_line as u64));
    assert!(row["weight"].as_f64().expect("weight") < 1e-3, "{row}");
}

/// `--drop-outliers 4`: removed, the calibration redone on the rows kept.
fn drop_outliers_removes_the_bad_row_and_calibrates_again(case: &Case) {
    let out = case.identify(&case.bad_csv, "drop", &["--drop-outliers", "4"]);
    assert!(out.contains("--drop-outliers 4: ") && out.contains(&case.named), "{out}");
    let report = json(&case.p("drop.json"));
    let dropped = report["bad_rows"]["dropped"].as_array().expect("dropped");
    assert!(dropped.iter().any(|d| d["line"].as_u64() == Some(case.bad_line as u64)), "{dropped:?}");
    assert_eq!(report["training_range"]["rows"].as_u64(), Some(80 - dropped.len() as u64));
    assert_eq!(report["n_measurements"].as_u64(), Some(80 - dropped.len() as u64));
}

/// Held-out postures: the robust and the dropping fits are back near the clean fit.
fn robust_and_dropping_fits_are_back_near_the_clean_fit(case: &Case) {
    let (e_clean, e_default, e_cauchy, e_drop) = (
        case.held_mean("clean.toml"),
        case.held_mean("default.toml"),
        case.held_mean("cauchy.toml"),
        case.held_mean("drop.toml"),
    );
    eprintln!(
        "held-out mean: clean {e_clean:.5} mm, default {e_default:.5} mm, cauchy {e_cauchy:.5} mm, drop {e_drop:.5} mm"
    );
    assert!(e_default > 2.0 * e_clean, "{e_default} vs {e_clean}");
    assert!(e_cauchy <= 1.2 * e_clean, "{e_cauchy} vs {e_clean}");
    assert!(e_drop <= 1.2 * e_clean, "{e_drop} vs {e_clean}");
}

/// Bad flags of `identify` are refused, naming the flag.
fn bad_flags_are_refused(case: &Case) {
    let args = |extra: &[&'static str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "identify",
            "--model",
            &case.ur5e,
            "--measurements",
            &case.bad_csv,
            "--out",
            &s(&case.p("x.toml")),
        ]
        .iter()
        .map(|x| x.to_string())
        .collect();
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    for (extra, expected) in [
        (&["--robust", "l1"][..], "--robust"),
        (&["--robust", "huber", "--drop-outliers", "4"][..], "cannot be used with"),
        (&["--drop-outliers", "0"][..], "--drop-outliers must be a positive number"),
        (&["--outlier-k", "0"][..], "--outlier-k must be a positive number"),
    ] {
        let a = args(extra);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let (ok, _, err) = run_full(&a);
        assert!(!ok && err.contains(expected), "{extra:?}: {err}");
    }
}

/// Validate: 40 training postures (inside) and 5 with q2 beyond the training maximum, each
/// named; extrapolation is not an error, and a model without a range says nothing about it.
/// Returns the 45 postures.
fn validate_warns_of_postures_outside_the_training_range(
    case: &Case,
    range: &TrainingRange,
) -> Vec<Measurement> {
    let (p, kinds) = (|name: &str| case.p(name), &case.kinds);
    let mut postures: Vec<Measurement> = case.clean[..40].to_vec();
    let q2_max = range.q_max[1];
    let mut outside_lines = Vec::new();
    for (k, m) in case.clean[40..45].iter().enumerate() {
        let mut v = m.q.to_file_units(kinds);
        v[1] = q2_max + 10.0 + k as f64;
        let q = JointVector::from_file_units(&v, kinds).expect("q");
        postures.push(Measurement::tracker(1, q, seen(&case.truth, &q)));
        outside_lines.push(2 + 40 + k as u64);
    }
    vatcal_io::write_measurements_for(p("wide.csv"), &postures, kinds).expect("write");
    let (ok, out, err) = run_full(&[
        "validate",
        "--model",
        &s(&p("clean.toml")),
        "--tracker",
        &s(&p("wide.csv")),
        "--report",
        &s(&p("wide.json")),
    ]);
    assert!(ok, "{err}");
    eprintln!("{out}\n{err}");
    for line in &outside_lines {
        let w = format!("warning: {}:{line}: outside the training range of", s(&p("wide.csv")));
        assert!(err.contains(&w), "{w}\n{err}");
    }
    assert_eq!(err.matches("outside the training range of").count(), 5, "{err}");
    assert!(
        err.contains("q2 = ") && out.contains("extrapolation: 5 of 45 rows leave the training range"),
        "{out}"
    );
    let report = json(&p("wide.json"));
    let ex = &report["extrapolation"];
    assert_eq!((ex["n_rows"].as_u64(), ex["n_total"].as_u64()), (Some(5), Some(45)));
    assert_eq!(ex["rows_per_joint"][1].as_u64(), Some(5));
    let lines: Vec<u64> =
        ex["rows"].as_array().expect("rows").iter().filter_map(|r| r["line"].as_u64()).collect();
    assert_eq!(lines, outside_lines);
    assert_eq!(ex["rows"][0]["joints"][0]["joint"].as_u64(), Some(2));
    // extrapolation is not an error, and a model without a range says nothing about it
    let (ok, out, err) = run_full(&["validate", "--model", &case.ur5e, "--tracker", &s(&p("wide.csv"))]);
    assert!(ok && !out.contains("extrapolation") && !err.contains("training range"), "{out}\n{err}");
    postures
}

/// Compensate: a pose of a training posture is quiet, one beyond the range is named.
fn compensate_warns_of_targets_outside_the_training_range(case: &Case, postures: &[Measurement]) {
    let p = |name: &str| case.p(name);
    let calibrated = Model::from_cell(&CellFile::load(p("clean.toml")).expect("cell")).expect("model");
    for (name, q, warned) in [("inside", case.clean[3].q, false), ("outside", postures[42].q, true)] {
        let tool = calibrated.chain(&q).tool;
        let r = PoseRequest::from_tool_frame(
            &calibrated,
            1,
            JointVector::zeros(6),
            &tool,
            MeasurementContext::default(),
        )
        .expect("request");
        let poses = p(&format!("{name}.csv"));
        std::fs::write(
            &poses,
            format!(
                "tcp,x,y,z,alpha,beta,gamma\n1,{},{},{},{},{},{}\n",
                r.xyz_mm[0], r.xyz_mm[1], r.xyz_mm[2], r.abc_deg[0], r.abc_deg[1], r.abc_deg[2]
            ),
        )
        .expect("write");
        let near: Vec<String> = q.to_file_units(&case.kinds).iter().map(|v| v.to_string()).collect();
        let target = p(&format!("{name}-targets.csv"));
        let (ok, _, err) = run_full(&[
            "compensate",
            "--model",
            &s(&p("clean.toml")),
            "--poses",
            &s(&poses),
            "--out",
            &s(&target),
            "--each",
            "--near",
            &near.join(","),
        ]);
        assert!(ok, "{name}: {err}");
        let file = std::fs::read_to_string(&target).expect("targets");
        if warned {
            let w = format!("warning: {}:2: the target leaves the training range of", s(&poses));
            assert!(err.contains(&w) && err.contains("q2 = "), "{w}\n{err}");
            assert!(file.contains("# extrapolation: 1 of 1 targets"), "{file}");
        } else {
            assert!(!err.contains("training range") && !file.contains("extrapolation"), "{err}\n{file}");
        }
    }
}
