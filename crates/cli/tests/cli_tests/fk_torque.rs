//! End-to-end tests of `vatcal fk` and `vatcal torque` through the real binary.

use std::process::Command;

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> String {
    let p = dir.path().join(name);
    std::fs::write(&p, text).expect("write");
    p.display().to_string()
}

#[test]
fn fk_prints_one_xyz_row_per_input_row_matching_the_library() {
    let out = vatcal()
        .args(["fk", "--model", &fixture("meca500-zaber.toml"), "--input", &fixture("joints-example.csv")])
        .output()
        .expect("run");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).expect("utf8");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "x,y,z");
    assert_eq!(lines.len(), 4);
    let cell = vatcal_core::CellFile::load(fixture("meca500-zaber.toml")).expect("cell");
    let model = vatcal_kinematics::Model::from_cell(&cell).expect("model");
    let q = vatcal_core::JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    let p = model.tcp_position(&q, 2).expect("fk");
    let got: Vec<f64> = lines[2].split(',').map(|s| s.parse().expect("number")).collect();
    assert!((got[0] - p.x).abs() < 1e-12 && (got[1] - p.y).abs() < 1e-12 && (got[2] - p.z).abs() < 1e-12);
}

#[test]
fn torque_prints_six_columns() {
    let out = vatcal()
        .args([
            "torque",
            "--model",
            &fixture("meca500-zaber.toml"),
            "--input",
            &fixture("joints-example.csv"),
        ])
        .output()
        .expect("run");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).expect("utf8");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("tau2,tau3,tau4,tau5,tau6,tau7"));
    for l in lines {
        let v: Vec<f64> = l.split(',').map(|s| s.parse().expect("number")).collect();
        assert_eq!(v.len(), 6);
        assert!(v.iter().all(|t| t.is_finite() && t.abs() < 20.0));
    }
}

#[test]
fn bad_input_gives_file_line_column_and_nonzero_exit() {
    let dir = tempfile::tempdir().expect("tmp");
    let bad = write(&dir, "bad.csv", "tcp,q1,q2,q3,q4,q5,q6,q7\n1,0,0,0,0,0,0,0\n1,0,0,0,x,0,0,0\n");
    let out = vatcal()
        .args(["fk", "--model", &fixture("meca500-zaber.toml"), "--input", &bad])
        .output()
        .expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv:3") && err.contains("q4") && err.contains("not a number"), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    let cell = std::fs::read_to_string(fixture("meca500-zaber.toml")).expect("read");
    let broken = write(&dir, "cell.toml", &cell.replace("q_min = -70.0", "q_min = 95.0"));
    let out = vatcal()
        .args(["torque", "--model", &broken, "--input", &fixture("joints-example.csv")])
        .output()
        .expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cell.toml") && err.contains("joints[index=3].q_min"), "{err}");

    let out = vatcal()
        .args(["fk", "--model", &fixture("meca500-zaber.toml"), "--input", "/nonexistent.csv"])
        .output()
        .expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent.csv"));
}
