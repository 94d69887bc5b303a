//! `vatcal identify` / `validate` with any instrument (issue 20): a tracker whose frame is
//! rotated and two metres away measuring an unknown marker, fixed points at unknown places with
//! a known distance, and the error paths (neither row kind, a distance naming unknown points, a
//! canonical-only parameter set on another chain). The data are simulated here from a perturbed
//! truth of the UR5e fixture (`vatcal_sim`), seeded.

use super::any_robot::{fixture, run, vatcal};
use nalgebra::{Rotation3, Vector3};
use vatcal_core::{Axis, CellFile, Measurement, ParamId};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
    synthetic_tracker_measurements_in_frame,
};

fn fail(args: &[&str]) -> String {
    let out = vatcal().args(args).output().expect("run");
    assert!(!out.status.success(), "vatcal {args:?} should fail");
    String::from_utf8(out.stderr).expect("utf8")
}

/// The UR5e truth: geometry perturbed, the measured point 80 mm from the nominal TCP 1.
fn truth(nominal: &Model, seed: u64) -> Model {
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(nominal, seed, &budget);
    let tcp = t.tcp(1).expect("tcp 1") + Vector3::new(30.0, -50.0, 56.6);
    for (axis, v) in Axis::ALL.iter().zip(tcp.iter()) {
        t.set_param(ParamId::Tcp { id: 1, axis: *axis }, *v).expect("tcp");
    }
    t
}

fn mean_of(validate_json: &str) -> f64 {
    let v: serde_json::Value = serde_json::from_str(validate_json).expect("json");
    v["model"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean")
}

/// The simulated "done" case through the binary: `vatcal identify` with its defaults,
/// then `vatcal validate` on 300 postures the fit never saw.
#[test]
fn identify_defaults_calibrate_a_tracker_frame_anywhere_to_the_noise_floor() {
    let dir = tempfile::tempdir().expect("tmp");
    let nominal = Model::from_cell(&CellFile::load(fixture("ur5e.toml")).expect("fixture")).expect("model");
    let truth = truth(&nominal, 11);
    let r = Rotation3::from_euler_angles(-2.1, 0.4, 1.3);
    let t = Vector3::new(-1400.0, 1200.0, 900.0);
    assert!(t.norm() > 2000.0);
    let rows = |n: usize, sigma: f64, seed: u64| -> Vec<Measurement> {
        synthetic_tracker_measurements_in_frame(&truth, n, sigma, seed, 1, &r, &t)
    };
    let train = dir.path().join("train.csv");
    let held = dir.path().join("held-out.csv");
    vatcal_io::write_measurements_for(&train, &rows(80, 0.01, 5), nominal.joint_kinds()).expect("write");
    vatcal_io::write_measurements_for(&held, &rows(300, 0.0, 6), nominal.joint_kinds()).expect("write");
    let (cal, report, val) =
        (dir.path().join("cal.toml"), dir.path().join("id.json"), dir.path().join("v.json"));
    let s = |p: &std::path::Path| p.display().to_string();
    let out = run(&[
        "identify",
        "--model",
        &fixture("ur5e.toml"),
        "--measurements",
        &s(&train),
        "--out",
        &s(&cal),
        "--report",
        &s(&report),
    ]);
    eprintln!("{out}");
    assert!(out.contains("initialisation: RMS residual"), "{out}");
    assert!(out.contains("cross-validation") && out.contains("<- chosen"), "{out}");
    assert!(out.contains("post/prior"), "the parameter table lists priors: {out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    let candidates = json["selection"]["candidates"].as_array().expect("candidates");
    // the richest set at each prior scale of the grid (x0.1 .. x30), the lowest score chosen
    assert_eq!(candidates.len(), 6);
    assert!(candidates.iter().all(|c| c["set"] == "kinematic+compliance" && c["prior_scale"].is_number()));
    let params = json["parameters"].as_array().expect("params");
    let tcp = params.iter().find(|p| p["name"] == "tcp1_x").expect("tcp1_x");
    assert!(tcp.get("prior_sigma_file_units").is_none(), "the marker is free: {tcp}");
    let offset = params.iter().find(|p| p["name"] == "theta_offset_2").expect("theta_offset_2");
    assert!(offset["posterior_over_prior"].as_f64().is_some_and(|r| r > 0.0 && r < 1.0), "{offset}");
    run(&["validate", "--model", &s(&cal), "--tracker", &s(&held), "--report", &s(&val)]);
    let after = mean_of(&std::fs::read_to_string(&val).expect("validate report"));
    run(&["validate", "--model", &fixture("ur5e.toml"), "--tracker", &s(&held), "--report", &s(&val)]);
    let before = mean_of(&std::fs::read_to_string(&val).expect("validate report"));
    eprintln!("held-out mean {before:.3} mm -> {after:.5} mm");
    assert!(before > 1000.0, "{before}");
    assert!(after < 0.02, "held-out mean {after} mm (noise 0.01 mm per axis)");
}

/// Two sockets 50 mm apart whose places nobody knows, the ball centre unknown: `--unknown-positions`
/// and `--point-distance`; held-out postures at the sockets (probe rows, read by `validate`) are
/// predicted to noise level.
#[test]
fn unknown_sockets_with_a_known_distance_through_the_cli() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut cell = CellFile::load(fixture("ur5e.toml")).expect("fixture");
    cell.calibration_positions.truncate(2);
    let sockets = [Vector3::new(380.0, 150.0, 40.0), Vector3::new(380.0 - 40.0, 150.0 + 30.0, 40.0)];
    for (p, s) in cell.calibration_positions.iter_mut().zip(&sockets) {
        (p.x_mm, p.y_mm, p.z_mm) = (s.x, s.y, s.z);
    }
    let truth = truth(&Model::from_cell(&cell).expect("model"), 23);
    let rows = |count: usize, seed: u64| -> Vec<Measurement> {
        let starts: Vec<Measurement> =
            probe_start_poses(&truth, count, seed).into_iter().map(|m| Measurement { tcp: 1, ..m }).collect();
        synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.01 }, seed + 1)
    };
    let (train, held) = (rows(300, 3), rows(150, 4));
    assert!(train.len() > 250 && held.len() > 100);
    // the user's cell: the fixture with its positions 1 and 2 where they are not
    let model_path = dir.path().join("cell.toml");
    CellFile::load(fixture("ur5e.toml")).expect("fixture").save(&model_path).expect("save");
    let s = |p: &std::path::Path| p.display().to_string();
    let (train_csv, held_csv) = (dir.path().join("train.csv"), dir.path().join("held.csv"));
    let kinds = truth.joint_kinds();
    vatcal_io::write_measurements_for(&train_csv, &train, kinds).expect("write");
    vatcal_io::write_measurements_for(&held_csv, &held, kinds).expect("write");
    let (cal, val) = (dir.path().join("cal.toml"), dir.path().join("v.json"));
    let out = run(&[
        "identify",
        "--model",
        &s(&model_path),
        "--measurements",
        &s(&train_csv),
        "--unknown-positions",
        "1,2",
        "--point-distance",
        "1,2,50,0.005",
        "--out",
        &s(&cal),
    ]);
    eprintln!("{out}");
    assert!(out.contains("base pose is absorbed by the points"), "{out}");
    let calibrated = Model::from_cell(&CellFile::load(&cal).expect("calibrated")).expect("model");
    let d = (calibrated.position(1).expect("p1") - calibrated.position(2).expect("p2")).norm();
    assert!((d - 50.0).abs() < 0.01, "socket distance {d}");
    run(&["validate", "--model", &s(&cal), "--tracker", &s(&held_csv), "--report", &s(&val)]);
    let after = mean_of(&std::fs::read_to_string(&val).expect("validate report"));
    eprintln!("held-out socket error {after:.5} mm, distance {d:.5} mm");
    assert!(after < 0.03, "held-out {after} mm");
}

/// Every new error path is one clear line naming the file (and line) and the field.
#[test]
fn any_instrument_errors_name_file_line_and_field() {
    let dir = tempfile::tempdir().expect("tmp");
    let s = |p: &std::path::Path| p.display().to_string();
    let out = s(&dir.path().join("out.toml"));
    // neither probe nor tracker columns
    let neither = dir.path().join("neither.csv");
    std::fs::write(&neither, "# joint rows only\ntcp,q1,q2,q3,q4,q5,q6\n1,0,-90,90,0,90,0\n").expect("write");
    let e =
        fail(&["identify", "--model", &fixture("ur5e.toml"), "--measurements", &s(&neither), "--out", &out]);
    assert!(e.contains("neither.csv:2: column `position / x,y,z / plane`"), "{e}");
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    // a row that is neither kind
    let row = dir.path().join("row.csv");
    std::fs::write(
        &row,
        "position,tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,1,0,-90,90,0,90,0,,,\n,1,0,-80,90,0,90,0,,,\n",
    )
    .expect("write");
    let e = fail(&["identify", "--model", &fixture("ur5e.toml"), "--measurements", &s(&row), "--out", &out]);
    assert!(e.contains("row.csv:3: column `position`: empty"), "{e}");
    // a distance naming a point that does not exist
    let tracker = dir.path().join("t.csv");
    std::fs::write(&tracker, "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,0,-90,90,0,90,0,1,2,3\n").expect("write");
    let (fixture_path, tracker_path) = (fixture("ur5e.toml"), s(&tracker));
    let with_tracker = |extra: &[&str]| {
        let mut args = vec!["identify", "--model", &fixture_path, "--tracker", &tracker_path, "--out", &out];
        args.extend_from_slice(extra);
        fail(&args)
    };
    let e = with_tracker(&["--point-distance", "1,7,50"]);
    assert!(e.contains("point 7 is not a calibration position"), "{e}");
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    let e = with_tracker(&["--point-distance", "1,x,50"]);
    assert!(e.contains("--point-distance") && e.contains("`x` is not a point id"), "{e}");
    // the paper's names on another chain
    let e = with_tracker(&["--params", "paper34"]);
    assert!(e.contains("canonical Meca500-on-guide cell") && e.contains("6 joints (RRRRRR)"), "{e}");
    assert!(!e.contains("three calibration positions"), "{e}");
    // units-flag mismatches and a row far beyond a limit: one line naming file, line, column
    // and the flag that is probably missing
    let cases: [(&str, &str, &[&str], &str); 4] = [
        (
            "rad.csv",
            "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,0.1,-1.5,1.2,0.3,1.5,0.2,400,100,300\n\
             1,0.2,-1.4,1.1,0.2,1.4,0.1,410,120,310\n1,0.3,-1.3,1.0,0.1,1.3,0.4,420,140,320\n",
            &[],
            "rad.csv:2: column `q2`: every revolute joint value of the file is within",
        ),
        (
            "metres.csv",
            "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,0.4,0.1,0.3\n\
             1,12,-80,90,-100,-90,30,0.41,0.12,0.3\n1,14,-80,90,-100,-90,30,0.42,0.14,-0.52\n",
            &[],
            "metres.csv:4: column `z`: every tracker coordinate of the file is within",
        ),
        (
            "mm.csv",
            "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,400,100,300\n",
            &["--length-unit", "m"],
            "mm.csv:2: column `x`: 400 m is more than 100 m",
        ),
        (
            "beyond.csv",
            "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,400,100,300\n1,10,-80,90,-100,-90,390,400,100,300\n",
            &[],
            "beyond.csv:3: column `q6`: 390 deg is outside the joint limits",
        ),
    ];
    for (name, text, extra, expected) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        let p = s(&path);
        let mut args = vec!["identify", "--model", &fixture_path, "--tracker", &p, "--out", &out];
        args.extend_from_slice(extra);
        let e = fail(&args);
        assert!(e.contains(expected), "{name}: {e}");
        assert_eq!(e.trim().lines().count(), 1, "{name}: {e}");
    }
}
