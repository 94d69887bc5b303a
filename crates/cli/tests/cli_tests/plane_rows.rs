//! Plane rows through the binary (issue 31 item 3): contacts of the UR5e truth with a table, a
//! 50 mm gauge block on it (the tool pressed flat: `normal` 1) and two walls, none of them in
//! the cell file; `identify` with `--plane-distance` identifies the planes with the robot, and
//! `validate --register-frame` on held-out tracker rows shows the noise floor. A plane row
//! without its plane id is a one-line error naming file, line and column.

use std::path::Path;

use vatcal_core::CellFile;
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, add_table_block_walls, perturbed_truth, synthetic_plane_contacts,
    synthetic_tracker_measurements,
};

use super::any_robot::{fixture, run, vatcal};

#[test]
fn plane_rows_identify_the_planes_and_validate_at_the_noise_floor() {
    let dir = tempfile::tempdir().expect("tmp");
    let s = |p: &Path| p.display().to_string();
    let nominal = Model::from_cell(&CellFile::load(fixture("ur5e.toml")).expect("fixture")).expect("model");
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut truth = perturbed_truth(&nominal, 31, &budget);
    add_table_block_walls(&mut truth, -50.0, 450.0);
    let mut contacts = Vec::new();
    for (plane, normal) in [(1, true), (2, true), (3, false), (4, false)] {
        contacts.extend(synthetic_plane_contacts(&truth, plane, 1, normal, 30, 0.005, 40 + u64::from(plane)));
    }
    let held: Vec<_> =
        synthetic_tracker_measurements(&truth, 300, 0.0, 8).into_iter().filter(|m| m.tcp == 1).collect();
    let (train, held_path, cal) =
        (dir.path().join("contacts.csv"), dir.path().join("held.csv"), dir.path().join("cal.toml"));
    vatcal_io::write_measurements_for(&train, &contacts, truth.joint_kinds()).expect("write");
    vatcal_io::write_measurements_for(&held_path, &held, truth.joint_kinds()).expect("write");
    let out = run(&[
        "identify",
        "--model",
        &fixture("ur5e.toml"),
        "--measurements",
        &s(&train),
        "--plane-distance",
        "1,2,50,0.002",
        "--cv-repeats",
        "1",
        "--out",
        &s(&cal),
    ]);
    assert!(out.contains("planes: 4 not in the cell file (1, 2, 3, 4)"), "{out}");
    assert!(out.contains("120 plane contact(s), 1 known distance(s)"), "{out}");
    assert!(out.contains("plane2_offset"), "{out}");
    let written = CellFile::load(&cal).expect("calibrated cell");
    assert_eq!(written.planes.iter().map(|p| p.id).collect::<Vec<_>>(), [1, 2, 3, 4]);
    let gap = written.planes[1].offset_mm - written.planes[0].offset_mm;
    assert!((gap - 50.0).abs() < 0.01, "block over table {gap}");
    let out = run(&[
        "validate",
        "--model",
        &s(&cal),
        "--baseline",
        &fixture("ur5e.toml"),
        "--tracker",
        &s(&held_path),
        "--register-frame",
    ]);
    assert!(out.contains("tracker frame registered"), "{out}");
    let mean = |label: &str| -> f64 {
        let line = out.lines().find(|l| l.starts_with(label)).unwrap_or_else(|| panic!("{label}: {out}"));
        line.split_whitespace().nth(3).and_then(|v| v.parse().ok()).unwrap_or_else(|| panic!("{line}"))
    };
    let (model, baseline) = (mean("model"), mean("baseline"));
    eprintln!(
        "held-out mean after registration: nominal {baseline} mm, calibrated from plane rows {model} mm"
    );
    assert!(model < 0.03 && baseline > 0.5, "{model} / {baseline}");
    // a plane row without its plane id
    let bad = dir.path().join("bad.csv");
    std::fs::write(
        &bad,
        "plane,normal,tcp,q1,q2,q3,q4,q5,q6\n1,1,1,10,-80,90,-100,-90,30\n,1,1,10,-80,90,-100,-90,30\n",
    )
    .expect("write");
    let out = vatcal()
        .args(["identify", "--model", &fixture("ur5e.toml"), "--measurements", &s(&bad), "--out", &s(&cal)])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("bad.csv:3: column `plane`: empty"), "{err}");
}
