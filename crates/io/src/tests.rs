//! Tests of the readers and writers through the crate's public functions.

use std::io::Write;

use nalgebra::Vector3;
use vatcal_core::{CellFile, Target};
use vatcal_kinematics::Model;

use super::*;

fn model() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    Model::from_cell(&cell).expect("model")
}

fn file(text: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::NamedTempFile::new().expect("tmp");
    f.write_all(text.as_bytes()).expect("write");
    f
}

#[test]
fn reads_columns_by_name_skips_comments_and_round_trips() {
    let m = model();
    let f = file(
        "# comment\nq1,tcp,q2,q3,q4,q5,q6,q7,extra,position,time_s\n\n100,2,10,20,-30,40,50,60,zzz,3,1.5\n",
    );
    let ms = read_probe_measurements(f.path(), &m).expect("ok");
    assert_eq!(ms.len(), 1);
    assert_eq!(ms[0].tcp, 2);
    assert_eq!(ms[0].position(), Some(3));
    assert_eq!(ms[0].context.time_s, Some(1.5));
    assert!((ms[0].q.get(4).to_degrees() - (-30.0)).abs() < 1e-12);
    let out = tempfile::NamedTempFile::new().expect("tmp");
    write_measurements(out.path(), &ms).expect("write");
    let back = read_probe_measurements(out.path(), &m).expect("reread");
    assert_eq!(back, ms);
}

#[test]
fn pose_requests_read_by_name_with_context_and_named_errors() {
    let m = model();
    let f = file("# poses\ngamma,beta,alpha,z,y,x,q1,tcp,time_s\n3,2,180,40,-40,60,100,2,7.5\n");
    let rows = read_pose_requests(f.path(), &m, &[1]).expect("ok");
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    assert_eq!((r.line, r.tcp, r.given.len(), r.given.get(1)), (3, 2, 7, 100.0));
    assert!((2..=7).all(|i| r.given.get(i) == 0.0), "{:?}", r.given);
    assert_eq!((r.xyz_mm, r.abc_deg), ([60.0, -40.0, 40.0], [180.0, 2.0, 3.0]));
    assert_eq!(r.context.time_s, Some(7.5));
    let cases = [
        (
            "tcp,q1,x,y,z,alpha,beta,gamma\n2,400,0,0,0,0,0,0\n",
            "q1",
            "400 mm is outside the joint limits [0, 300] mm",
        ),
        ("tcp,q1,x,y,z,alpha,beta,gamma,q3\n2,100,0,0,0,0,0,0,5\n", "q3", "the pose determines the others"),
        ("tcp,q1,x,y,z,alpha,beta,gamma\n2,100,0,0,0,0,nan,0\n", "beta", "not finite"),
        ("tcp,q1,x,y,z,alpha,beta,gamma\n7,100,0,0,0,0,0,0\n", "tcp", "unknown tcp id 7"),
        ("tcp,q1,x,y,z,alpha,beta\n2,100,0,0,0,0,0\n", "gamma", "missing column"),
    ];
    for (text, column, reason) in cases {
        let f = file(text);
        let e = read_pose_requests(f.path(), &m, &[1]).expect_err("bad").to_string();
        assert!(e.contains(column) && e.contains(reason), "{e}");
        assert!(e.contains(&f.path().display().to_string()), "{e}");
    }
}

#[test]
fn centring_offsets_are_read_written_and_checked() {
    let m = model();
    let f = file(
        "position,tcp,q1,q2,q3,q4,q5,q6,q7,offset_x_mm,offset_y_mm,offset_z_mm\n\
         1,1,100,0,0,0,0,0,0,0.001,-0.002,0.0035\n\
         2,1,100,0,0,0,0,0,0,,,\n",
    );
    let ms = read_probe_measurements(f.path(), &m).expect("ok");
    assert_eq!(ms[0].probe_offset_mm, Some(Vector3::new(0.001, -0.002, 0.0035)));
    assert_eq!(ms[0].target_offset_mm(), Vector3::new(0.001, -0.002, 0.0035));
    assert_eq!(ms[1].probe_offset_mm, None);
    let out = tempfile::NamedTempFile::new().expect("tmp");
    write_measurements(out.path(), &ms).expect("write");
    assert!(
        std::fs::read_to_string(out.path()).expect("read").contains("offset_x_mm,offset_y_mm,offset_z_mm")
    );
    assert_eq!(read_measurements(out.path(), &m).expect("reread"), ms);
    // without the columns nothing changes
    let plain = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0,0\n");
    assert_eq!(read_probe_measurements(plain.path(), &m).expect("ok")[0].probe_offset_mm, None);
    // a partial triple is an error naming the missing column
    let bad = file(
        "position,tcp,q1,q2,q3,q4,q5,q6,q7,offset_x_mm,offset_y_mm,offset_z_mm\n1,1,100,0,0,0,0,0,0,0.001,,0.002\n",
    );
    let e = read_probe_measurements(bad.path(), &m).expect_err("must fail").to_string();
    assert!(e.contains(":2:") && e.contains("offset_y_mm") && e.contains("all three"), "{e}");
}

#[test]
fn errors_name_file_line_and_column() {
    let m = model();
    let cases = [
        ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,abc,0\n", "q6", "not a number"),
        ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,9,100,0,0,0,0,0,0\n", "tcp", "unknown tcp id 9"),
        ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n4,1,100,0,0,0,0,0,0\n", "position", "unknown position id 4"),
        ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,95,0,0,0,0\n", "q3", "outside the joint limits"),
        ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,NaN,0,0,0\n", "q4", "not finite"),
    ];
    for (text, col, reason) in cases {
        let f = file(text);
        let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
        assert!(e.contains(":2:"), "{e}");
        assert!(e.contains(col) && e.contains(reason), "{e}");
    }
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6\n1,1,100,0,0,0,0,0\n");
    let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
    assert!(e.contains(":1: the model has 7 joints: expected the joint columns q1..q7"), "{e}");
    let f = file("position,q1,q2,q3,q4,q5,q6,q7\n1,100,0,0,0,0,0,0\n");
    let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
    assert!(e.contains("missing column `tcp`"), "{e}");
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0\n");
    let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
    assert!(e.contains("malformed CSV"), "{e}");
}

pub(crate) fn fixture_model(name: &str) -> Model {
    let cell =
        CellFile::load(format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect("fixture");
    Model::from_cell(&cell).expect("model")
}

#[test]
fn n_joint_models_read_and_write_q1_to_qn_and_their_dir_columns() {
    let ur = fixture_model("ur5e.toml");
    let f = file(
        "tcp,q1,q2,q3,q4,q5,q6,dir1,dir2,dir3,dir4,dir5,dir6,x,y,z\n2,10,-20,30,-40,50,-60,1,-1,1,-1,1,-1,1,2,3\n",
    );
    let ms = read_tracker_measurements(f.path(), &ur).expect("ok");
    assert_eq!(ms[0].q.len(), 6);
    assert!((ms[0].q[5].to_degrees() + 60.0).abs() < 1e-12);
    assert_eq!(ms[0].context.dir_of(1), 1);
    assert_eq!(ms[0].context.dir_of(6), -1);
    let text = measurements_to_csv_for(&ms, ur.joint_kinds());
    assert!(text.starts_with("tcp,q1,q2,q3,q4,q5,q6,x,y,z,dir1,dir2,dir3,dir4,dir5,dir6\n"), "{text}");
    let out = tempfile::NamedTempFile::new().expect("tmp");
    write_measurements_for(out.path(), &ms, ur.joint_kinds()).expect("write");
    assert_eq!(read_tracker_measurements(out.path(), &ur).expect("reread"), ms);
    // the canonical cell's 7 columns on a 6-joint model: file, header line and the
    // expected columns are named
    let f = file("# seven\ntcp,q1,q2,q3,q4,q5,q6,q7\n1,0,0,0,0,0,0,0\n");
    let e = read_joint_rows(f.path(), &ur).expect_err("7 columns for 6 joints").to_string();
    assert!(
        e.contains(&format!(
            "{}:2: the model has 6 joints: expected the joint columns q1..q6",
            f.path().display()
        )),
        "{e}"
    );
    // and six columns on the 7-joint cell
    let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,0,0,0,0,0,0\n");
    let e = read_joint_rows(f.path(), &model()).expect_err("6 columns for 7 joints").to_string();
    assert!(e.contains("expected the joint columns q1..q7, the header has q1,q2,q3,q4,q5,q6"), "{e}");
    // joint rows of any chain round-trip, in degrees for revolute joints
    let rows = vec![(3, ms[0].q)];
    let out = tempfile::NamedTempFile::new().expect("tmp");
    write_joint_rows_for(out.path(), &rows, ur.joint_kinds()).expect("write");
    let back = read_joint_rows(out.path(), &ur).expect("reread");
    assert_eq!((back[0].tcp, back[0].q), (3, ms[0].q));
    // limits of the Meca500 alone, in degrees
    let meca = fixture_model("meca500-table.toml");
    let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,0,95,0,0,0,0\n");
    let e = read_joint_rows(f.path(), &meca).expect_err("J2 limit").to_string();
    assert!(e.contains(":2: column `q2`: 95 deg is outside the joint limits"), "{e}");
    // a canonical-cell pose request (with the guide `q1`) on a six-joint arm, where the
    // pose determines every joint: the stray column and the chain are named
    let f = file("tcp,q1,x,y,z,alpha,beta,gamma\n1,0,0,0,0,0,0,0\n");
    let e = read_pose_requests(f.path(), &ur, &[]).expect_err("no guide on the arm").to_string();
    assert!(e.contains("column(s) q1 in the header") && e.contains("gives the joint columns none"), "{e}");
    // and the arm's own requests are read
    let f = file("tcp,x,y,z,alpha,beta,gamma\n1,400,100,300,180,0,0\n");
    let rows = read_pose_requests(f.path(), &ur, &[]).expect("six-joint request");
    assert_eq!((rows[0].given.len(), rows[0].xyz_mm), (6, [400.0, 100.0, 300.0]));
}

/// A backlash on joint i needs exactly the column `dir{i}`, on any chain: the error names
/// that column, and a file with only that direction column is read (the other revolute
/// joints' directions are then unknown, 0).
#[test]
fn a_backlash_needs_its_joints_dir_column_on_any_chain() {
    use vatcal_core::effects::EffectSpec;
    let mut ur = fixture_model("ur5e.toml");
    ur.enable_effect(EffectSpec::JointBacklash { joint: 4 }).expect("backlash on joint 4");
    let f = file("tcp,q1,q2,q3,q4,q5,q6,dir1,dir2,dir3,dir5,dir6\n1,10,-20,30,-40,50,-60,1,1,1,1,1\n");
    let e = read_joint_rows(f.path(), &ur).expect_err("no dir4").to_string();
    assert!(
        e.contains(&format!(
            "{}: the model's joint-backlash (joint 4) needs the column(s) dir4,",
            f.path().display()
        )),
        "{e}"
    );
    let f = file("tcp,q1,q2,q3,q4,q5,q6,dir4,x,y,z\n1,10,-20,30,-40,50,-60,-1,1,2,3\n");
    let ms = read_tracker_measurements(f.path(), &ur).expect("dir4 alone");
    assert_eq!((ms[0].context.dir_of(4), ms[0].context.dir_of(3)), (-1, 0));
    let f = file("tcp,q1,q2,q3,q4,q5,q6,dir4\n1,10,-20,30,-40,50,-60,\n");
    let e = read_joint_rows(f.path(), &ur).expect_err("empty dir4").to_string();
    assert!(e.contains(":2: column `dir4`: empty, but the model's joint-backlash (joint 4) needs it"), "{e}");
    // a 12-joint chain: the column of joint 11
    let cell = twelve_joint_cell();
    let mut m = Model::from_cell(&cell).expect("12 joints");
    m.enable_effect(EffectSpec::JointBacklash { joint: 11 }).expect("backlash on joint 11");
    let header = (1..=12).map(|i| format!("q{i}")).collect::<Vec<_>>().join(",");
    let f = file(&format!("tcp,{header}\n1{}\n", ",0".repeat(12)));
    let e = read_joint_rows(f.path(), &m).expect_err("no dir11").to_string();
    assert!(e.contains("needs the column(s) dir11,"), "{e}");
    let f = file(&format!("tcp,{header},dir11\n1{},1\n", ",0".repeat(12)));
    let rows = read_joint_rows(f.path(), &m).expect("dir11");
    assert_eq!(rows[0].context.dir_of(11), 1);
}

/// The UR5e fixture with its six revolute rows repeated: 12 revolute joints.
fn twelve_joint_cell() -> CellFile {
    let mut cell =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("fixture");
    let mut more = cell.joints.clone();
    for (k, j) in more.iter_mut().enumerate() {
        j.index = 7 + k as u8;
    }
    cell.joints.extend(more);
    cell
}

/// Rows are converted in parallel: the order is kept, and with several bad rows the error
/// is the first one's, whichever thread meets it first.
#[test]
fn large_files_keep_row_order_and_report_the_first_bad_row() {
    let m = model();
    let mut text = String::from("position,tcp,q1,q2,q3,q4,q5,q6,q7\n");
    for i in 0..3000 {
        text.push_str(&format!("{},1,{},0,0,0,0,0,0\n", 1 + i % 3, f64::from(i) * 0.1));
    }
    let f = file(&text);
    let c = read_candidates(f.path(), &m).expect("ok");
    assert_eq!(c.measurements.len(), 3000);
    for (i, ms) in c.measurements.iter().enumerate() {
        assert_eq!(ms.position(), Some(1 + i as u32 % 3));
        assert_eq!(ms.q.to_mm_deg()[0], i as f64 * 0.1, "row {i}");
        assert_eq!(c.lines[i], i as u64 + 2);
    }
    // bad rows at data rows 2500 and 700 (file lines 2502 and 702): line 702 is named
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    lines[2501] = "1,1,0,0,0,0,0,x,0".into();
    lines[701] = "1,9,0,0,0,0,0,0,0".into();
    let f = file(&(lines.join("\n") + "\n"));
    for e in [
        read_candidates(f.path(), &m).expect_err("bad rows").to_string(),
        read_probe_measurements(f.path(), &m).expect_err("bad rows").to_string(),
    ] {
        assert!(e.contains(":702:") && e.contains("unknown tcp id 9"), "{e}");
    }
}

#[test]
fn tracker_and_candidates() {
    let m = model();
    let f = file("tcp,q1,q2,q3,q4,q5,q6,q7,x,y,z\n1,0,0,0,0,0,0,0,1.5,2.5,3.5\n");
    let t = read_tracker_measurements(f.path(), &m).expect("ok");
    assert!(matches!(t[0].target, Target::Tracker { xyz_mm } if xyz_mm == Vector3::new(1.5, 2.5, 3.5)));
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7,note\n1,1,0,0,0,0,0,0,0,a\n2,2,10,0,0,0,0,0,0,b\n");
    let c = read_candidates(f.path(), &m).expect("ok");
    assert_eq!(c.measurements.len(), 2);
    let out = tempfile::NamedTempFile::new().expect("tmp");
    c.write_subset(out.path(), &[1]).expect("write");
    let text = std::fs::read_to_string(out.path()).expect("read");
    assert_eq!(text, "position,tcp,q1,q2,q3,q4,q5,q6,q7,note\n2,2,10,0,0,0,0,0,0,b\n");
}

/// Item 5 of issue 20: a measured joint slightly beyond its limit is a warning naming file,
/// line and joint; further than the tolerance, an error; the readers without options (and
/// so planning and compensation) keep the limits strict.
#[test]
fn limit_tolerance_warns_within_and_refuses_beyond() {
    let m = model(); // canonical cell: q1 guide [0, 300] mm, q3 = Meca500 J2 [-70, 90] deg
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,10,0,0,0,0\n1,1,300.2,0,90.3,0,0,0,0\n");
    let read = read_probe_measurements_with(f.path(), &m, &ReadOptions::default()).expect("within");
    assert_eq!(read.rows.len(), 2);
    let w: Vec<String> = read.warnings.iter().map(ToString::to_string).collect();
    assert_eq!(w.len(), 2, "{w:?}");
    let name = f.path().display().to_string();
    assert!(
        w[0].starts_with(&format!("{name}:3: column `q1`: 300.2 mm is beyond the joint limits")),
        "{w:?}"
    );
    assert!(w[1].starts_with(&format!("{name}:3: column `q3`: 90.3 deg is beyond")), "{w:?}");
    assert!(w[1].contains("by 0.3000 deg") && w[1].contains("tolerance of 0.5 deg"), "{w:?}");
    // the value is read as measured (not clamped)
    assert!((read.rows[1].q[2] - 90.3f64.to_radians()).abs() < 1e-12);
    // strict readers: an error, as before
    let e = read_probe_measurements(f.path(), &m).expect_err("strict").to_string();
    assert!(e.contains(":3: column `q1`") && e.contains("outside the joint limits"), "{e}");
    // beyond the tolerance: an error naming file, line, joint and the tolerance
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,10,0,0,0,0\n1,1,100,0,91,0,0,0,0\n");
    let e =
        read_probe_measurements_with(f.path(), &m, &ReadOptions::default()).expect_err("1 deg").to_string();
    assert!(
        e.contains(":3: column `q3`: 91 deg is outside the joint limits [-70, 90] deg (by 1.0000 deg")
            && e.contains("tolerance of 0.5 deg"),
        "{e}"
    );
    assert!(!e.contains("--angle-unit"), "no unit hint for a value that fits no other unit: {e}");
    // a larger tolerance reads it
    let wide = ReadOptions {
        limit_tolerance: LimitTolerance { revolute_deg: 2.0, prismatic_mm: 0.5 },
        ..ReadOptions::default()
    };
    assert_eq!(read_probe_measurements_with(f.path(), &m, &wide).expect("2 deg").warnings.len(), 1);
}

/// Issue 29: every row read with options carries its line (comments and blank lines
/// skipped), so a later step can name it `file:line`.
#[test]
fn rows_read_with_options_know_their_lines() {
    let m = model();
    let f = file(
        "# vatcal-noise: probe_sigma_mm=0.002\nposition,tcp,q1,q2,q3,q4,q5,q6,q7,x,y,z\n1,1,100,0,10,0,0,0,0,,,\n\n# a comment\n,1,120,0,12,0,0,0,0,1,2,3\n",
    );
    let read = read_measurements_with(f.path(), &m, &ReadOptions::default()).expect("read");
    assert_eq!(read.lines, vec![3, 6]);
    let sources = read.sources();
    assert_eq!(sources.len(), read.rows.len());
    assert_eq!(sources[1].to_string(), format!("{}:6", f.path().display()));
    // an error on a row after blank and comment lines names the row's own line
    let f =
        file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,10,0,0,0,0\n\n# c\n# d\n1,1,100,0,x,0,0,0,0\n");
    let e = read_probe_measurements(f.path(), &m).expect_err("bad q3").to_string();
    assert!(e.contains(":6: column `q3`"), "{e}");
}

/// Item 6: metres and radians are read as mm and radians; a file that does not look like
/// the stated units is refused with a hint naming the other unit.
#[test]
fn units_are_options_and_mismatches_are_named() {
    let ur = fixture_model("ur5e.toml");
    let deg = file("tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,400,-100.5,250\n");
    let (q, rad) = ([10.0f64, -80.0, 90.0, -100.0, -90.0, 30.0], "");
    let rad_row: Vec<String> = q.iter().map(|v| v.to_radians().to_string()).collect();
    let si = file(&format!("tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,{},0.4,-0.1005,0.25\n{rad}", rad_row.join(",")));
    let options =
        ReadOptions { length_unit: LengthUnit::M, angle_unit: AngleUnit::Rad, ..ReadOptions::default() };
    let a = read_tracker_measurements(deg.path(), &ur).expect("deg");
    let b = read_tracker_measurements_with(si.path(), &ur, &options).expect("SI");
    assert!(b.warnings.is_empty());
    for k in 0..6 {
        assert!((a[0].q[k] - b.rows[0].q[k]).abs() < 1e-12, "joint {k}");
    }
    let (Target::Tracker { xyz_mm: pa }, Target::Tracker { xyz_mm: pb }) = (a[0].target, b.rows[0].target)
    else {
        panic!("tracker rows");
    };
    assert!((pa - pb).norm() < 1e-9, "{pa} vs {pb}");
    // radians read as degrees: every angle within ±2π "degrees" on 3+ rows
    let text =
        format!("tcp,q1,q2,q3,q4,q5,q6\n1,{}\n1,0.1,0.2,0.3,0.4,0.5,0.6\n1,0,0,0,0,0,0\n", rad_row.join(","));
    let f = file(&text);
    let e = read_joint_rows_with(f.path(), &ur, &ReadOptions::default()).expect_err("radians").to_string();
    assert!(
        e.contains(":2: column `q4`: every revolute joint value") && e.contains("--angle-unit rad"),
        "{e}"
    );
    assert!(
        read_joint_rows_with(
            f.path(),
            &ur,
            &ReadOptions { angle_unit: AngleUnit::Rad, ..ReadOptions::default() }
        )
        .is_ok()
    );
    assert!(read_joint_rows(f.path(), &ur).is_ok(), "the readers without options have no heuristics");
    // degrees read as radians: more than two turns
    let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,10,-80,90,-100,-90,30\n");
    let e = read_joint_rows_with(
        f.path(),
        &ur,
        &ReadOptions { angle_unit: AngleUnit::Rad, ..ReadOptions::default() },
    )
    .expect_err("degrees")
    .to_string();
    assert!(
        e.contains(":2: column `q1`: 10 rad is outside the joint limits") && e.contains("--angle-unit deg"),
        "{e}"
    );
    // more than two turns: the magnitude alone tells
    let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,0.1,-80,0,0,0,0\n");
    let e = read_joint_rows_with(
        f.path(),
        &ur,
        &ReadOptions { angle_unit: AngleUnit::Rad, ..ReadOptions::default() },
    )
    .expect_err("degrees")
    .to_string();
    assert!(e.contains(":2: column `q2`: -80 rad is implausible") && e.contains("--angle-unit deg"), "{e}");
    // millimetres read as metres
    let e = read_tracker_measurements_with(
        deg.path(),
        &ur,
        &ReadOptions { length_unit: LengthUnit::M, ..ReadOptions::default() },
    )
    .map(|_| ())
    .expect_err("mm as m");
    assert!(
        e.to_string().contains(":2: column `x`: 400 m is more than 100 m")
            && e.to_string().contains("--length-unit mm"),
        "{e}"
    );
    // metres read as millimetres: every tracker coordinate within ±10 mm
    let f = file(
        "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,0.4,0.1,0.3\n\
         1,12,-80,90,-100,-90,30,0.41,0.12,0.3\n1,14,-80,90,-100,-90,30,0.42,0.14,-0.52\n",
    );
    for read in [read_tracker_measurements_with, read_measurements_with] {
        let e = read(f.path(), &ur, &ReadOptions::default()).map(|_| ()).expect_err("m as mm").to_string();
        assert!(
            e.contains(":4: column `z`: every tracker coordinate") && e.contains("--length-unit m"),
            "{e}"
        );
        let ok = read(f.path(), &ur, &ReadOptions { length_unit: LengthUnit::M, ..ReadOptions::default() });
        assert!(ok.is_ok(), "read in metres");
    }
    // a guide in metres beyond its limit in mm hints at the unit
    let m = model();
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,150,0,10,0,0,0,0\n");
    let e = read_probe_measurements_with(
        f.path(),
        &m,
        &ReadOptions { length_unit: LengthUnit::M, ..ReadOptions::default() },
    )
    .expect_err("150 m")
    .to_string();
    assert!(e.contains(":2: column `q1`") && e.contains("--length-unit mm"), "{e}");
}

/// Item 6: the approach directions from the row order, on any chain; a file with its own
/// `dir` columns is refused; a backlash model reads a file without `dir` columns then.
#[test]
fn directions_derived_from_the_row_order() {
    use vatcal_core::effects::EffectSpec;
    let mut ur = fixture_model("ur5e.toml");
    ur.enable_effect(EffectSpec::JointBacklash { joint: 4 }).expect("backlash on joint 4");
    let f = file(
        "tcp,q1,q2,q3,q4,q5,q6\n1,10,-80,90,-100,-90,30\n1,10,-80,90,-90,-90,30\n1,12,-80,90,-95,-90,30\n",
    );
    let e = read_joint_rows_with(f.path(), &ur, &ReadOptions::default()).expect_err("no dir4").to_string();
    assert!(e.contains("needs the column(s) dir4"), "{e}");
    let options = ReadOptions { dir_from_row_order: true, ..ReadOptions::default() };
    let rows = read_joint_rows_with(f.path(), &ur, &options).expect("derived").rows;
    let dirs: Vec<(i8, i8, i8)> =
        rows.iter().map(|r| (r.context.dir_of(1), r.context.dir_of(4), r.context.dir_of(6))).collect();
    assert_eq!(dirs, vec![(0, 0, 0), (0, 1, 0), (1, -1, 0)]);
    let f = file("tcp,q1,q2,q3,q4,q5,q6,dir4\n1,10,-80,90,-100,-90,30,1\n");
    let e = read_joint_rows_with(f.path(), &ur, &options).expect_err("own dir4").to_string();
    assert!(e.contains("has its own direction column `dir4`"), "{e}");
}

/// Issue 31: markers the model lacks are read with `any_tcp_id` (the caller adds them),
/// refused without it; positions are still checked.
#[test]
fn any_tcp_id_reads_markers_the_model_lacks() {
    let ur = fixture_model("ur5e.toml");
    let f =
        file("tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,1,2,3\n7,10,-80,90,-100,-90,30,4,5,6\n");
    let e = read_measurements_with(f.path(), &ur, &ReadOptions::default()).expect_err("tcp 7").to_string();
    assert!(e.contains(":3: column `tcp`: unknown tcp id 7 (the model has [1, 2, 3])"), "{e}");
    let options = ReadOptions { any_tcp_id: true, ..ReadOptions::default() };
    let rows = read_measurements_with(f.path(), &ur, &options).expect("any tcp").rows;
    assert_eq!(rows.iter().map(|m| m.tcp).collect::<Vec<_>>(), [1, 7]);
    let f = file("position,tcp,q1,q2,q3,q4,q5,q6\n7,7,10,-80,90,-100,-90,30\n");
    let e = read_measurements_with(f.path(), &ur, &options).expect_err("position 7").to_string();
    assert!(e.contains("unknown position id 7"), "{e}");
}

/// Issue 31: plane rows `plane,tcp,q…[,normal]` read beside probe and tracker rows (any plane
/// id: planes the cell lacks are identified), written back with the same columns; a plane row
/// without its plane id, a `normal` header without `plane`, a row naming both a position and a
/// plane and a bad `normal` value are each one line naming file, line and column.
#[test]
fn plane_rows_are_read_written_and_checked() {
    let ur = fixture_model("ur5e.toml");
    let f = file(
        "plane,normal,position,tcp,q1,q2,q3,q4,q5,q6,x,y,z\n\
         3,1,,1,10,-80,90,-100,-90,30,,,\n\
         4,,,1,11,-80,90,-100,-90,30,,,\n\
         ,,1,1,12,-80,90,-100,-90,30,,,\n\
         ,,,1,13,-80,90,-100,-90,30,1,2,3\n",
    );
    let rows = read_measurements(f.path(), &ur).expect("plane rows");
    assert_eq!(rows[0].target, Target::Plane { plane: 3, normal: true });
    assert_eq!(rows[1].target, Target::Plane { plane: 4, normal: false });
    assert_eq!(rows[2].target, Target::Probe { position: 1 });
    assert!(matches!(rows[3].target, Target::Tracker { .. }));
    let out = tempfile::NamedTempFile::new().expect("tmp");
    write_measurements_for(out.path(), &rows, ur.joint_kinds()).expect("write");
    let text = std::fs::read_to_string(out.path()).expect("read");
    assert!(text.starts_with("position,plane,normal,tcp,q1"), "{text}");
    let back = read_measurements(out.path(), &ur).expect("reread");
    for (a, b) in back.iter().zip(&rows) {
        assert_eq!((a.target, a.tcp), (b.target, b.tcp));
        assert!((a.q.as_slice().iter().zip(b.q.as_slice())).all(|(x, y)| (x - y).abs() < 1e-14));
    }
    assert_eq!(back.len(), rows.len());
    let bad = |text: &str| read_measurements(file(text).path(), &ur).expect_err("bad").to_string();
    let e =
        bad("plane,normal,tcp,q1,q2,q3,q4,q5,q6\n3,1,1,10,-80,90,-100,-90,30\n,1,1,10,-80,90,-100,-90,30\n");
    assert!(e.contains(":3: column `plane`: empty: a probe row needs `position`"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
    let e = bad("normal,tcp,q1,q2,q3,q4,q5,q6\n1,1,10,-80,90,-100,-90,30\n");
    assert!(e.contains(":1: column `plane`: the header has `normal` but no `plane`"), "{e}");
    let e = bad("plane,position,tcp,q1,q2,q3,q4,q5,q6\n3,1,1,10,-80,90,-100,-90,30\n");
    assert!(e.contains(":2: column `plane`: a row is a probe row (`position`) or a plane row"), "{e}");
    let e = bad("plane,normal,tcp,q1,q2,q3,q4,q5,q6\n3,yes,1,10,-80,90,-100,-90,30\n");
    assert!(e.contains(":2: column `normal`: `yes` is not 1/true or 0/false"), "{e}");
    let e = bad("plane,tcp,q1,q2,q3,q4,q5,q6\n-3,1,10,-80,90,-100,-90,30\n");
    assert!(e.contains(":2: column `plane`: `-3` is not a non-negative integer id"), "{e}");
}
