//! `vatcal observability` and `vatcal select` on plane rows (issue 31 item 3): the UR5e's TCP
//! touching a table and pressing its face on a 50 mm gauge block standing on it, planes the
//! cell file does not have (estimated from the rows and analysed free), with and without the
//! known 50 mm between them; candidates mixing plane and tracker rows.

use std::path::{Path, PathBuf};

use super::select_observability::{text, vatcal};
use vatcal_core::{CellFile, Measurement, Target};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, insert_table_and_block, perturbed_truth, synthetic_tracker_measurements,
    table_and_block_contacts,
};

fn fixture() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))
}

/// The perturbed UR5e with a table 50 mm below its base and the block's top 50 mm above it.
fn truth() -> Model {
    let nominal = Model::from_cell(&CellFile::load(fixture()).expect("fixture")).expect("model");
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(&nominal, 4, &budget);
    insert_table_and_block(&mut t);
    t
}

/// 20 touches of the table, 20 presses on the block (5 µm contact noise).
fn plane_rows(truth: &Model) -> Vec<Measurement> {
    let rows = table_and_block_contacts(truth, 20, 0.005);
    assert_eq!(rows.len(), 40);
    rows
}

/// `plane,tcp,q1..q6,normal,x,y,z,label` (degrees, mm): plane rows leave x,y,z empty, tracker
/// rows `plane` and `normal`.
fn write_rows(path: &Path, model: &Model, rows: &[Measurement]) {
    let mut text = String::from("plane,tcp,q1,q2,q3,q4,q5,q6,normal,x,y,z,label\n");
    for (i, m) in rows.iter().enumerate() {
        let q: Vec<String> = m.q.to_file_units(model.joint_kinds()).iter().map(|v| v.to_string()).collect();
        let (plane, normal, xyz) = match m.target {
            Target::Plane { plane, normal } => (plane.to_string(), u8::from(normal).to_string(), ",,".into()),
            Target::Tracker { xyz_mm } => {
                (String::new(), String::new(), format!("{},{},{}", xyz_mm.x, xyz_mm.y, xyz_mm.z))
            }
            _ => unreachable!("plane and tracker rows only"),
        };
        text.push_str(&format!("{plane},{},{},{normal},{xyz},row{i}\n", m.tcp, q.join(",")));
    }
    std::fs::write(path, text).expect("write rows");
}

#[test]
fn observability_of_plane_rows_names_the_lost_base_and_the_scale() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("planes.csv");
    let truth = truth();
    write_rows(&csv, &truth, &plane_rows(&truth));
    let (model, csv) = (fixture(), csv.to_str().expect("path").to_string());
    let base = ["observability", "--model", model.to_str().expect("path"), "--measurements", &csv];

    // every parameter: the unknown planes' first; the base pose is a gauge of unknown planes
    let o = vatcal(&base);
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    assert!(out.contains("planes: 2 not in the cell file (1, 2)"), "{out}");
    assert!(out.contains("40 measurements (40 plane contact(s), 80 informative rows)"), "{out}");
    assert!(out.contains("identifiable (") && out.contains("plane1_offset"), "{out}");
    let lost = out.lines().find(|l| l.starts_with("NOT FULLY IDENTIFIABLE")).expect("rank-deficient");
    for p in ["base_x", "base_y", "base_gamma"] {
        assert!(lost.contains(p), "{p}: {lost}");
    }
    assert!(out.contains("turning it about their normal is invisible"), "{out}");
    assert!(out.contains("the scale of the chain is free"), "{out}");

    // the kinematic set needs the scale
    let kinematic = [&base[..], &["--params", "kinematic"]].concat();
    let o = vatcal(&kinematic);
    let err = text(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("nothing fixes the scale") && err.contains("--plane-distance"), "{err}");
    let o = vatcal(&[&kinematic[..], &["--plane-distance", "1,2,50"]].concat());
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    assert!(out.contains("(40 plane contact(s), 80 informative rows, 1 known plane distance(s))"), "{out}");
    assert!(out.contains("83 informative rows") && out.contains("redundant: none"), "{out}");
    assert!(!out.contains("the scale of the chain is free"), "{out}");
    assert!(out.contains("indices") && out.contains("O1 "), "{out}");

    // the default set: every parameter reduced to its identifiable basis, which leaves out
    // alpha_0 (a turn of the base about x is the same as tilting both planes) and is of full
    // rank on its own
    let o = vatcal(&[&base[..], &["--params", "default"]].concat());
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    let basis = out.lines().find(|l| l.starts_with("identifiable (")).expect("basis line");
    assert!(basis.contains("plane1_tilt_u") && basis.contains("plane2_tilt_u"), "{basis}");
    assert!(!basis.contains("alpha_0,") && !basis.ends_with("alpha_0"), "{basis}");
    assert!(out.contains("redundant: none") && !out.contains("NOT FULLY IDENTIFIABLE"), "{out}");

    // a plane distance naming a plane the data and the cell do not have
    let o = vatcal(&[&base[..], &["--plane-distance", "1,7,50"]].concat());
    let err = text(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("plane 7") && err.contains("--plane-distance"), "{err}");
}

#[test]
fn select_picks_among_plane_and_tracker_rows_and_keeps_the_columns() {
    let dir = tempfile::tempdir().expect("tempdir");
    let truth = truth();
    let mut rows = plane_rows(&truth);
    rows.extend(
        synthetic_tracker_measurements(&truth, 200, 0.01, 3).into_iter().filter(|m| m.tcp == 1).take(40),
    );
    assert_eq!(rows.len(), 80);
    let (cands, selected) = (dir.path().join("cands.csv"), dir.path().join("selected.csv"));
    write_rows(&cands, &truth, &rows);
    let model = fixture();
    let o = vatcal(&[
        "select",
        "--model",
        model.to_str().expect("path"),
        "--candidates",
        cands.to_str().expect("path"),
        "--count",
        "30",
        "--restarts",
        "2",
        "--seed",
        "5",
        "--out",
        selected.to_str().expect("path"),
    ]);
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    assert!(out.contains("planes: 2 not in the cell file (1, 2)"), "{out}");
    assert!(out.contains("selected 30 of 80 candidates"), "{out}");
    assert!(
        out.contains("ablation: no probe rows at calibration positions (80 plane/tracker rows); skipped"),
        "{out}"
    );
    let written = std::fs::read_to_string(&selected).expect("selection");
    let lines: Vec<&str> = written.lines().collect();
    assert_eq!(lines[0], "plane,tcp,q1,q2,q3,q4,q5,q6,normal,x,y,z,label");
    assert_eq!(lines.len(), 31);
    let plane_lines = lines[1..].iter().filter(|l| !l.starts_with(',')).count();
    eprintln!("{plane_lines} plane rows of 30 selected");
    // every written line is one of the input's, verbatim
    let input = std::fs::read_to_string(&cands).expect("candidates");
    assert!(lines[1..].iter().all(|l| input.lines().any(|i| i == *l)));
}

/// The `cond` of `vatcal select`'s `selection:` line.
fn selection_condition(out: &str) -> f64 {
    let line = out.lines().find(|l| l.starts_with("selection:")).expect("selection line");
    let after = line.split("cond ").nth(1).expect("cond");
    after.split_whitespace().next().expect("value").parse().expect("number")
}

#[test]
fn select_on_unknown_planes_takes_the_known_distance_into_every_design() {
    let dir = tempfile::tempdir().expect("tempdir");
    let truth = truth();
    let (cands, selected) = (dir.path().join("cands.csv"), dir.path().join("selected.csv"));
    write_rows(&cands, &truth, &plane_rows(&truth));
    let (model, cands) = (fixture(), cands.to_str().expect("path").to_string());
    let (model, out_path) = (model.to_str().expect("path"), selected.to_str().expect("path"));
    let base = [
        "select",
        "--model",
        model,
        "--candidates",
        &cands,
        "--count",
        "24",
        "--restarts",
        "2",
        "--seed",
        "3",
        "--out",
        out_path,
    ];
    let distance = ["--plane-distance", "1,2,50"];

    // the kinematic set needs the scale: refused without a known distance, naming the flag
    let kinematic = [&base[..], &["--params", "kinematic"]].concat();
    let o = vatcal(&kinematic);
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(!o.status.success());
    assert!(err.contains("nothing fixes the scale") && err.contains("--plane-distance"), "{err}");
    assert!(out.contains("the scale of the chain is free") && out.contains("--plane-distance"), "{out}");
    assert!(!selected.exists());
    let o = vatcal(&[&kinematic[..], &distance[..]].concat());
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    assert!(out.contains("selected 24 of 40 candidates for 28 parameters"), "{out}");
    assert!(out.contains("known distances: 0 point, 1 plane (3 rows in every design, unweighted"), "{out}");
    assert!(!out.contains("the scale of the chain is free"), "{out}");
    assert!(out.contains("rank 28/28"), "{out}");
    let written = std::fs::read_to_string(&selected).expect("selection");
    assert_eq!(written.lines().count(), 25, "{written}");
    let with_distance = selection_condition(&out);
    // the default set (the identifiable basis of every parameter, alpha_0 left out: it trades
    // exactly against the planes' tilts) selects a design of full rank
    let o = vatcal(&base);
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    assert!(out.contains("selected 24 of 40 candidates for 32 parameters (default"), "{out}");
    assert!(out.contains("rank 32/32"), "{out}");
    // a point distance between fixed calibration positions informs nothing here: said so
    let o = vatcal(&[&kinematic[..], &["--point-distance", "1,2,100"]].concat());
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    assert!(o.status.success(), "{err}");
    assert!(out.contains("note: --point-distance 1,2: neither point's coordinates"), "{out}");

    // the same parameters named one by one pass the rule; the scale is then only weakly seen
    // (through the nominal model's misfit), and the distance makes the selection much better
    // conditioned
    let names = "plane1_tilt_u,plane1_tilt_v,plane1_offset,plane2_tilt_u,plane2_tilt_v,plane2_offset,tcp1_x,tcp1_y,tcp1_z,theta_offset_2,theta_offset_3,theta_offset_4,theta_offset_5,alpha_1,a_1,d_2,alpha_2,a_2,alpha_3,a_3,alpha_4,a_4,d_5,alpha_5,a_5,beta_1,beta_2,beta_3";
    let listed = [&base[..], &["--params", names, "--objective", "o2"]].concat();
    let o = vatcal(&listed);
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    assert!(out.contains("the scale of the chain is free"), "{out}");
    let without = selection_condition(&out);
    let o = vatcal(&[&listed[..], &distance[..]].concat());
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    eprintln!("{out}{err}");
    assert!(o.status.success(), "{err}");
    let with = selection_condition(&out);
    eprintln!(
        "cond: kinematic with the distance {with_distance:.3e}; listed, o2: {without:.3e} without, {with:.3e} with"
    );
    assert!(with < without / 10.0, "{with} vs {without}");
}
