//! `vatcal import-urdf` end to end: the written cell, read back by `vatcal fk`, reproduces the
//! URDF's forward kinematics to 1e-9 mm; errors name the link or joint.

use std::process::Command;

use rand::{RngExt, SeedableRng};

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `vatcal import-urdf` of the fixture `urdf` from `base` to `tip`, writing `out`.
fn import_urdf(urdf: &str, base: &str, tip: &str, out: &std::path::Path) -> std::process::Output {
    vatcal()
        .args(["import-urdf", &fixture(urdf), "--base-link", base, "--tip-link", tip, "--out"])
        .arg(out)
        .output()
        .expect("run")
}

/// Imports `urdf`, then computes the TCP of 60 random joint rows within the limits (a) through
/// `vatcal fk` on the written cell (when `through_cli`) or (b) by loading the written cell with
/// the library, and returns the largest distance to the URDF's own FK [mm] and the import's
/// stdout.
fn import_and_compare(urdf: &str, base: &str, tip: &str, seed: u64, through_cli: bool) -> (f64, String) {
    let dir = tempfile::tempdir().expect("tmp");
    let cell_path = dir.path().join("cell.toml");
    let out = import_urdf(urdf, base, tip, &cell_path);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary = String::from_utf8(out.stdout).expect("utf8");
    let cell = vatcal_core::CellFile::load(&cell_path).expect("the written cell loads");
    assert_eq!((cell.format.as_str(), cell.version), ("serial-robot-cell", 2));

    let text = std::fs::read_to_string(fixture(urdf)).expect("urdf");
    let fk = vatcal_urdf::UrdfFk::new(&text, urdf, base, tip).expect("urdf fk");
    let n = fk.joint_count();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut csv = String::from("tcp");
    for i in 1..=n {
        csv += &format!(",q{i}");
    }
    csv.push('\n');
    let mut rows = Vec::new();
    for _ in 0..60 {
        let q: Vec<f64> = cell
            .joints
            .iter()
            .map(|j| {
                let (lo, hi) = j.limits().unwrap_or((-180.0, 180.0));
                rng.random_range(lo..hi)
            })
            .collect();
        csv += "1";
        for v in &q {
            csv += &format!(",{v}");
        }
        csv.push('\n');
        rows.push(q);
    }
    if !through_cli {
        let model = vatcal_kinematics::Model::from_cell(&cell).expect("model");
        let kinds: Vec<vatcal_core::JointKind> =
            cell.joints.iter().map(|j| j.joint_kind().expect("kind")).collect();
        let mut worst: f64 = 0.0;
        for q in &rows {
            let jv = vatcal_core::JointVector::from_file_units(q, &kinds).expect("joint vector");
            let got = model.tcp_position(&jv, 1).expect("fk");
            let want = fk.tip_position_mm(q).expect("n values");
            worst = worst.max((got - nalgebra::Vector3::from(want)).norm());
        }
        return (worst, summary);
    }
    let rows_path = dir.path().join("rows.csv");
    std::fs::write(&rows_path, csv).expect("write rows");
    let out = vatcal()
        .args(["fk", "--model"])
        .arg(&cell_path)
        .arg("--input")
        .arg(&rows_path)
        .output()
        .expect("run fk");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).expect("utf8");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z"));
    let mut worst: f64 = 0.0;
    let mut count = 0;
    for (line, q) in lines.zip(&rows) {
        let got: Vec<f64> = line.split(',').map(|s| s.parse().expect("number")).collect();
        let want = fk.tip_position_mm(q).expect("n values");
        let d = ((got[0] - want[0]).powi(2) + (got[1] - want[1]).powi(2) + (got[2] - want[2]).powi(2)).sqrt();
        worst = worst.max(d);
        count += 1;
    }
    assert_eq!(count, rows.len());
    (worst, summary)
}

#[test]
fn ur5e_written_cell_matches_the_urdf() {
    let (worst, summary) = import_and_compare("ur5e.urdf", "base_link", "tool0", 12, false);
    println!("max deviation {worst:e} mm");
    assert!(worst < 1e-9, "max deviation {worst:e} mm");
    assert!(summary.contains("ur5e (6 joints, base_link -> tool0)"), "{summary}");
    assert!(summary.contains("shoulder_pan_joint") && summary.contains("check: FK"), "{summary}");
}

#[test]
fn ur5e_vatcal_fk_matches_the_urdf() {
    let (worst, _) = import_and_compare("ur5e.urdf", "base_link", "tool0", 12, true);
    println!("max deviation {worst:e} mm");
    assert!(worst < 1e-9, "max deviation {worst:e} mm");
}

#[test]
fn meca500_vatcal_fk_matches_the_urdf() {
    let (worst, _) = import_and_compare("meca500.urdf", "meca_base_link", "meca_axis_6_link", 7, true);
    println!("max deviation {worst:e} mm");
    assert!(worst < 1e-9, "max deviation {worst:e} mm");
}

#[test]
fn humanoid_sole_to_gripper_vatcal_fk_matches_the_urdf() {
    // up the left leg (six joints reversed), through the pelvis and torso, down the left arm
    let (worst, summary) =
        import_and_compare("humanoid-tree.urdf", "left_sole_link", "gripper_left_base_link", 31, true);
    println!("max deviation {worst:e} mm");
    assert!(worst < 1e-9, "max deviation {worst:e} mm");
    assert!(
        summary.contains("humanoid_tree (12 joints, left_sole_link -> gripper_left_base_link)"),
        "{summary}"
    );
    assert!(summary.contains("up the tree through joint(s) leg_left_6_joint"), "{summary}");
    // the library model of the written cell agrees as well
    let (worst, _) =
        import_and_compare("humanoid-tree.urdf", "left_sole_link", "gripper_left_base_link", 32, false);
    assert!(worst < 1e-9, "max deviation {worst:e} mm");
}

#[test]
fn humanoid_cell_records_the_reversed_joints() {
    let dir = tempfile::tempdir().expect("tmp");
    let cell_path = dir.path().join("h.toml");
    let out = import_urdf("humanoid-tree.urdf", "gripper_left_base_link", "left_sole_link", &cell_path);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let cell = vatcal_core::CellFile::load(&cell_path).expect("the written cell loads");
    let reversed: Vec<&str> = cell.extra["urdf_import"]["reversed_joints"]
        .as_array()
        .expect("reversed_joints")
        .iter()
        .map(|v| v.as_str().expect("name"))
        .collect();
    // gripper -> sole: the arm and the torso joint go up, the leg goes down
    assert_eq!(
        reversed,
        [
            "arm_left_5_joint",
            "arm_left_4_joint",
            "arm_left_3_joint",
            "arm_left_2_joint",
            "arm_left_1_joint",
            "torso_1_joint"
        ]
    );
}

#[test]
fn same_link_is_an_error() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = import_urdf("humanoid-tree.urdf", "torso_2_link", "torso_2_link", &dir.path().join("x.toml"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("humanoid-tree.urdf") && err.contains("the same link"), "{err}");
    assert!(!dir.path().join("x.toml").exists());
}

#[test]
fn errors_name_the_link() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = import_urdf("ur5e.urdf", "base_link", "tool1", &dir.path().join("x.toml"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("ur5e.urdf") && err.contains("`tool1`"), "{err}");
    assert!(!dir.path().join("x.toml").exists());
}
