//! End-to-end tests of `vatcal compensate` through the real binary.

use std::process::Command;

use vatcal_compensation::PoseRequest;
use vatcal_core::{CellFile, JointVector, MeasurementContext};
use vatcal_kinematics::Model;

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn nominal() -> Model {
    Model::from_cell(&CellFile::load(fixture("meca500-zaber.toml")).expect("cell")).expect("model")
}

/// A calibrated model file (a perturbed truth of a fixture) in a temporary folder and six
/// requests along a short joint-space line of that model.
struct Setup {
    dir: tempfile::TempDir,
    model_path: String,
    calibrated: Model,
    requests: Vec<PoseRequest>,
}

impl Setup {
    /// `name` in the temporary folder.
    fn path(&self, name: &str) -> String {
        self.dir.path().join(name).display().to_string()
    }

    /// Writes `text` to `name` in the temporary folder; returns its path.
    fn write(&self, name: &str, text: &str) -> String {
        let p = self.path(name);
        std::fs::write(&p, text).expect("write");
        p
    }
}

/// The perturbed truth (`seed`) of the fixture `fixture_name`, saved and read back, and the
/// requests of TCP `tcp` at six points from `a` to `b`; with `given_guide` each request gives
/// its joints (the guide `q1` of the canonical cell), else none (a six-joint arm).
fn setup_with(
    fixture_name: &str,
    seed: u64,
    (a, b): (JointVector, JointVector),
    tcp: u32,
    given_guide: bool,
) -> Setup {
    let dir = tempfile::tempdir().expect("tmp");
    let nominal = Model::from_cell(&CellFile::load(fixture(fixture_name)).expect("cell")).expect("model");
    let calibrated =
        vatcal_sim::truth::perturbed_truth(&nominal, seed, &vatcal_sim::truth::ErrorBudget::realistic());
    let model_path = dir.path().join("calibrated.toml").display().to_string();
    calibrated.to_cell().save(&model_path).expect("save");
    let calibrated = Model::from_cell(&CellFile::load(&model_path).expect("load")).expect("model");
    let requests = (0..6)
        .map(|k| {
            let t = k as f64 / 5.0;
            let v: Vec<f64> = (0..a.len()).map(|i| a[i] + t * (b[i] - a[i])).collect();
            let q = JointVector::from_slice(&v).expect("q");
            let tool = calibrated.chain(&q).tool;
            let given = if given_guide { q } else { JointVector::zeros(q.len()) };
            PoseRequest::from_tool_frame(&calibrated, tcp, given, &tool, MeasurementContext::default())
                .expect("request")
        })
        .collect();
    Setup { dir, model_path, calibrated, requests }
}

/// The canonical cell: TCP 2 along a short line with the guide from 100 to 130 mm.
fn setup() -> Setup {
    let a = JointVector::from_mm_deg(100.0, [0.0, 10.0, -20.0, 10.0, 40.0, 10.0]);
    let b = JointVector::from_mm_deg(130.0, [15.0, 20.0, -30.0, 20.0, 50.0, 40.0]);
    setup_with("meca500-zaber.toml", 4, (a, b), 2, true)
}

/// A six-joint fixture: TCP 1 along a short path well inside the joint limits of both arms
/// (the Meca500's are tight); the requests have no joint columns.
fn six_joint_setup(fixture_name: &str, seed: u64) -> Setup {
    let a = JointVector::from_slice(&[-0.35, 0.17, -0.35, 0.52, 0.7, -0.87]).expect("a");
    let b = JointVector::from_slice(&[-0.17, 0.26, -0.26, 0.35, 0.79, -0.52]).expect("b");
    setup_with(fixture_name, seed, (a, b), 1, false)
}

/// A poses CSV of `requests`: `tcp,q1,x,y,z,alpha,beta,gamma` with the guide column `q1`
/// (`with_q1`, the canonical cell), else `tcp,x,y,z,alpha,beta,gamma`.
fn poses_csv(requests: &[PoseRequest], with_q1: bool) -> String {
    let mut s = String::from(if with_q1 {
        "tcp,q1,x,y,z,alpha,beta,gamma\n"
    } else {
        "tcp,x,y,z,alpha,beta,gamma\n"
    });
    for r in requests {
        let q1 = if with_q1 { format!("{},", r.given[0]) } else { String::new() };
        s.push_str(&format!(
            "{},{q1}{},{},{},{},{},{}\n",
            r.tcp, r.xyz_mm[0], r.xyz_mm[1], r.xyz_mm[2], r.abc_deg[0], r.abc_deg[1], r.abc_deg[2]
        ));
    }
    s
}

fn run(args: &[&str]) -> (bool, String, String) {
    let out = vatcal().args(args).output().expect("run");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// `vatcal compensate --model model --poses poses --out out` followed by `extra`.
fn compensate(model: &str, poses: &str, out: &str, extra: &[&str]) -> (bool, String, String) {
    let mut args = vec!["compensate", "--model", model, "--poses", poses, "--out", out];
    args.extend_from_slice(extra);
    run(&args)
}

/// Data rows of a CSV with `#` comments, split into fields (header first).
fn csv_rows(text: &str) -> Vec<Vec<String>> {
    text.lines().filter(|l| !l.starts_with('#')).map(|l| l.split(',').map(String::from).collect()).collect()
}

/// The command lines of a robot program (its `#` comments left out).
fn program_commands(text: &str) -> Vec<&str> {
    text.lines().filter(|l| !l.starts_with('#')).collect()
}

/// The joints `q1..qN` of target rows (`line,tcp,q1..qN,...`, mm/deg) of `model`'s chain, in
/// internal units.
fn joints_of(rows: &[Vec<String>], model: &Model) -> Vec<JointVector> {
    let kinds = model.joint_kinds();
    rows.iter()
        .map(|r| {
            let v: Vec<f64> = r[2..2 + kinds.len()].iter().map(|x| x.parse().expect("number")).collect();
            JointVector::from_file_units(&v, kinds).expect("q")
        })
        .collect()
}

/// `vatcal fk --model model_path --input joints_csv` puts every row's TCP on its request's
/// point (1e-6 mm).
fn assert_fk_reaches(model_path: &str, joints_csv: &str, requests: &[PoseRequest]) {
    let (ok, fk, err) = run(&["fk", "--model", model_path, "--input", joints_csv]);
    assert!(ok, "{err}");
    let lines: Vec<&str> = fk.lines().skip(1).collect();
    assert_eq!(lines.len(), requests.len(), "{fk}");
    for (line, req) in lines.iter().zip(requests) {
        let p: Vec<f64> = line.split(',').map(|v| v.parse().expect("number")).collect();
        assert!((0..3).all(|k| (p[k] - req.xyz_mm[k]).abs() < 1e-6), "{p:?} vs {:?}", req.xyz_mm);
    }
}

/// The joints `targets` also give the requested orientations (library FK of `calibrated`).
fn assert_orientations(calibrated: &Model, targets: &[JointVector], requests: &[PoseRequest]) {
    assert_eq!(targets.len(), requests.len());
    for (q, req) in targets.iter().zip(requests) {
        let target = req.tool_target(calibrated, 0).expect("target");
        let tool = calibrated.chain(q).tool;
        assert!(vatcal_planning::ik::rotation_angle_between(&tool.r, &target.tool.r) < 1e-9);
    }
}

#[test]
fn joint_targets_reach_the_requests_under_the_calibrated_model() {
    let s = setup();
    let poses = s.write("poses.csv", &poses_csv(&s.requests, true));
    let out = s.path("targets.csv");
    let (ok, _, err) = compensate(&s.model_path, &poses, &out, &[]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).expect("out");
    assert!(text.contains("# calibration: ") && text.contains("fnv1a64"), "{text}");
    let rows = csv_rows(&text);
    assert_eq!(rows[0].join(","), "line,tcp,q1,q2,q3,q4,q5,q6,q7,branch,residual_mm,residual_deg");
    assert_eq!(rows.len(), 7);
    // `vatcal fk` with the calibrated model on the output (it reads tcp,q1..q7) gives the
    // requested points
    assert_fk_reaches(&s.model_path, &out, &s.requests);
    let branch = &rows[1][9];
    for row in &rows[1..] {
        assert_eq!(&row[9], branch, "one branch along the path");
        let residual: f64 = row[10].parse().expect("residual");
        assert!(residual < 1e-6);
    }
    // the joints also give the requested orientation (library FK of the same joints)
    assert_orientations(&s.calibrated, &joints_of(&rows[1..], &s.calibrated), &s.requests);
}

#[test]
fn corrected_poses_and_meca500_programs() {
    let s = setup();
    let poses = s.write("poses.csv", &poses_csv(&s.requests, true));
    let joints = s.path("targets.csv");
    let (ok, _, err) = compensate(&s.model_path, &poses, &joints, &[]);
    assert!(ok, "{err}");
    let targets = joints_of(&csv_rows(&std::fs::read_to_string(&joints).expect("read"))[1..], &s.calibrated);

    // --emit poses: FK of the nominal model at the compensated joints, in the input format
    let corrected = s.path("corrected.csv");
    let nominal_path = fixture("meca500-zaber.toml");
    let (ok, _, err) =
        compensate(&s.model_path, &poses, &corrected, &["--emit", "poses", "--nominal", &nominal_path]);
    assert!(ok, "{err}");
    let rows = csv_rows(&std::fs::read_to_string(&corrected).expect("read"));
    assert_eq!(rows[0].join(","), "line,tcp,q1,x,y,z,alpha,beta,gamma");
    let nom = nominal();
    for (row, q) in rows[1..].iter().zip(&targets) {
        let v: Vec<f64> = row[3..6].iter().map(|x| x.parse().expect("number")).collect();
        let p = nom.tcp_position(q, 2).expect("fk");
        assert!((v[0] - p.x).abs() < 1e-6 && (v[1] - p.y).abs() < 1e-6 && (v[2] - p.z).abs() < 1e-6);
    }
    // the corrected poses are themselves a valid poses file: compensating them under the
    // nominal model gives back the same joints
    let back = s.path("back.csv");
    let (ok, _, err) = compensate(&nominal_path, &corrected, &back, &[]);
    assert!(ok, "{err}");
    let back_joints = joints_of(&csv_rows(&std::fs::read_to_string(&back).expect("read"))[1..], &nom);
    assert_eq!(back_joints.len(), targets.len());
    for (b, q) in back_joints.iter().zip(&targets) {
        let (v, mm_deg) = (b.to_mm_deg(), q.to_mm_deg());
        assert!(v.iter().zip(mm_deg).all(|(a, b)| (a - b).abs() < 1e-6), "{v:?} vs {mm_deg:?}");
    }

    // --emit meca500: MoveJoints lines the driver's codec parses, one guide comment each
    let program = s.path("program.txt");
    let (ok, _, err) = compensate(&s.model_path, &poses, &program, &["--emit", "meca500"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&program).expect("read");
    assert!(text.contains(&format!("# calibration: {}", s.model_path)), "{text}");
    let commands = program_commands(&text);
    let guides: Vec<f64> = text
        .lines()
        .filter_map(|l| l.strip_prefix("# guide q1_mm="))
        .map(|l| l.split(' ').next().expect("value").parse().expect("number"))
        .collect();
    assert_eq!(commands.len(), targets.len());
    assert_eq!(guides.len(), targets.len());
    for ((line, q), g) in commands.iter().zip(&targets).zip(&guides) {
        let parsed = vatcal_drivers_meca500::codec::parse_command(line).expect("parse");
        let vatcal_drivers_meca500::Command::MoveJoints(j) = parsed.command else {
            panic!("{line} is not MoveJoints")
        };
        let mm_deg = q.to_mm_deg();
        assert!(j.iter().zip(&mm_deg[1..]).all(|(a, b)| (a - b).abs() < 1e-8), "{j:?}");
        assert!((g - mm_deg[0]).abs() < 1e-8);
    }

    // --emit meca500-poses: MovePose lines = the controller's FK of the joints
    let (ok, _, err) = compensate(&s.model_path, &poses, &program, &["--emit", "meca500-poses"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&program).expect("read");
    let commands = program_commands(&text);
    assert_eq!(commands[0], "SetWrf(0,0,0,0,0,0)");
    assert_eq!(commands[1], "SetTrf(0,0,0,0,0,0)");
    assert_eq!(commands.len(), 2 + targets.len());
    for (line, q) in commands[2..].iter().zip(&targets) {
        let parsed = vatcal_drivers_meca500::codec::parse_command(line).expect("parse");
        let vatcal_drivers_meca500::Command::MovePose(p) = parsed.command else { panic!("{line}") };
        let mm_deg = q.to_mm_deg();
        let arm: [f64; 6] = std::array::from_fn(|k| mm_deg[k + 1]);
        let sim =
            vatcal_drivers_meca500::sim::to_xyzabc(&vatcal_drivers_meca500::sim::forward_kinematics(&arm));
        assert!(p.iter().zip(sim).all(|(a, b)| (a - b).abs() < 1e-6), "{p:?} vs {sim:?}");
    }
}

#[test]
fn bad_and_unreachable_rows_are_named() {
    let s = setup();
    let out = s.path("out.csv");
    let bad = s.write("bad.csv", "tcp,q1,x,y,z,alpha,beta,gamma\n2,100,0,0,0,0,0,0\n2,100,0,zz,0,0,0,0\n");
    let (ok, _, err) = compensate(&s.model_path, &bad, &out, &[]);
    assert!(!ok);
    assert!(err.contains("bad.csv:3") && err.contains("`y`") && err.contains("not a number"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // the guide outside its stroke: file, line, column and limits named
    let stroke = s.write("stroke.csv", "tcp,q1,x,y,z,alpha,beta,gamma\n2,400,0,0,0,0,0,0\n");
    let (ok, _, err) = compensate(&s.model_path, &stroke, &out, &[]);
    assert!(!ok);
    assert!(
        err.contains("stroke.csv:2")
            && err.contains("`q1`")
            && err.contains("outside the joint limits [0, 300] mm"),
        "{err}"
    );

    let mut far = s.requests.clone();
    far[3].xyz_mm[1] += 3000.0;
    let far_path = s.write("far.csv", &poses_csv(&far, true));
    let (ok, _, err) = compensate(&s.model_path, &far_path, &out, &[]);
    assert!(!ok);
    assert!(err.contains("far.csv:5") && err.contains("cannot be reached"), "{err}");
    let (ok, _, err) = compensate(&s.model_path, &far_path, &out, &["--skip-unreachable"]);
    assert!(ok, "{err}");
    assert!(err.contains("skipped") && err.contains("far.csv:5"), "{err}");
    let text = std::fs::read_to_string(&out).expect("read");
    assert!(text.contains("# skipped"), "{text}");
    assert_eq!(csv_rows(&text).len(), 1 + 5);
}

/// On the UR5e and the Meca500 on a table the requests have no joint columns; the targets
/// `q1..q6` put the TCP on the request under the calibrated model (`vatcal fk`), on one branch
/// class (`+`/`-`), and `--emit poses` round-trips: the nominal IK of the corrected poses gives
/// joints at which the calibrated FK equals the request.
#[test]
fn six_joint_arms_compensate_and_round_trip() {
    for name in ["ur5e.toml", "meca500-table.toml"] {
        let s = six_joint_setup(name, 5);
        let poses = s.write("poses.csv", &poses_csv(&s.requests, false));
        let out = s.path("targets.csv");
        // --emit joints needs no nominal model
        let (ok, _, err) = compensate(&s.model_path, &poses, &out, &[]);
        assert!(ok, "{name}: {err}");
        let rows = csv_rows(&std::fs::read_to_string(&out).expect("out"));
        assert_eq!(rows[0].join(","), "line,tcp,q1,q2,q3,q4,q5,q6,branch,residual_mm,residual_deg");
        assert_eq!(rows.len(), 7);
        let branch = rows[1][8].clone();
        assert!(branch == "+" || branch == "-", "{branch}");
        assert_fk_reaches(&s.model_path, &out, &s.requests);
        assert!(rows[1..].iter().all(|row| row[8] == branch), "one branch class along the path");
        let targets = joints_of(&rows[1..], &s.calibrated);
        assert_orientations(&s.calibrated, &targets, &s.requests);

        // --emit poses with the nominal model, then compensate the corrected poses under it
        let nominal_path = fixture(name);
        let corrected = s.path("corrected.csv");
        let (ok, _, err) =
            compensate(&s.model_path, &poses, &corrected, &["--emit", "poses", "--nominal", &nominal_path]);
        assert!(ok, "{err}");
        let text = std::fs::read_to_string(&corrected).expect("read");
        assert_eq!(csv_rows(&text)[0].join(","), "line,tcp,x,y,z,alpha,beta,gamma");
        let back = s.path("back.csv");
        let (ok, _, err) = compensate(&nominal_path, &corrected, &back, &[]);
        assert!(ok, "{err}");
        let back_joints =
            joints_of(&csv_rows(&std::fs::read_to_string(&back).expect("read"))[1..], &s.calibrated);
        assert_eq!(back_joints.len(), s.requests.len());
        for (q, req) in back_joints.iter().zip(&s.requests) {
            let p = s.calibrated.tcp_position(q, req.tcp).expect("fk");
            assert!((p - nalgebra::Vector3::from(req.xyz_mm)).norm() < 1e-6, "{name}: round trip {p:?}");
        }
        for (a, b) in back_joints.iter().zip(&targets) {
            assert!(a.as_slice().iter().zip(b.as_slice()).all(|(x, y)| (x - y).abs() < 1e-9));
        }
    }
}

/// `--emit meca500` works on the Meca500 on a table (no guide comments) and is a clear error
/// on the UR5e; other poses files and options that do not fit the chain are named.
#[test]
fn six_joint_arms_programs_and_errors() {
    let s = six_joint_setup("meca500-table.toml", 6);
    let poses = s.write("poses.csv", &poses_csv(&s.requests, false));
    let program = s.path("program.txt");
    let nominal_path = fixture("meca500-table.toml");
    let (ok, _, err) =
        compensate(&s.model_path, &poses, &program, &["--emit", "meca500", "--nominal", &nominal_path]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&program).expect("read");
    assert!(!text.contains("# guide"), "{text}");
    let commands = program_commands(&text);
    assert_eq!(commands.len(), s.requests.len());
    for line in commands {
        let parsed = vatcal_drivers_meca500::codec::parse_command(line).expect("parse");
        assert!(matches!(parsed.command, vatcal_drivers_meca500::Command::MoveJoints(_)), "{line}");
    }

    let s = six_joint_setup("ur5e.toml", 6);
    let poses = s.write("poses.csv", &poses_csv(&s.requests, false));
    let out = s.path("out.txt");
    let ur_nominal = fixture("ur5e.toml");
    let (ok, _, err) =
        compensate(&s.model_path, &poses, &out, &["--emit", "meca500", "--nominal", &ur_nominal]);
    assert!(!ok && err.contains("not a Meca500 arm"), "{err}");
    // --emit poses without a nominal model of this chain
    let (ok, _, err) = compensate(&s.model_path, &poses, &out, &["--emit", "poses"]);
    assert!(!ok && err.contains("--nominal"), "{err}");
    // a canonical --branch on a numerical-IK chain
    let (ok, _, err) = compensate(&s.model_path, &poses, &out, &["--branch", "3"]);
    assert!(!ok && err.contains("+ or -"), "{err}");
    // a q1 column: the pose determines every joint of a six-joint arm
    let with_q1 = s.write("q1.csv", "tcp,q1,x,y,z,alpha,beta,gamma\n1,100,0,0,500,0,0,0\n");
    let (ok, _, err) = compensate(&s.model_path, &with_q1, &out, &[]);
    assert!(!ok && err.contains("q1") && err.contains("6 joints (RRRRRR)"), "{err}");
    // an unreachable row is named by file and line
    let mut far = s.requests.clone();
    far[3].xyz_mm[2] += 3000.0;
    let far_path = s.write("far.csv", &poses_csv(&far, false));
    let (ok, _, err) = compensate(&s.model_path, &far_path, &out, &[]);
    assert!(!ok && err.contains("far.csv:5") && err.contains("cannot be reached"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// The context columns of a six-joint arm are `dir1..dir6` (its revolute joints): a calibrated
/// UR5e with backlash on joint 3 refuses a poses file without `dir3` and compensates with the
/// columns.
#[test]
fn six_joint_arm_context_columns() {
    let s = six_joint_setup("ur5e.toml", 7);
    let mut cal = s.calibrated.clone();
    let spec = vatcal_core::effects::EffectSpec::JointBacklash { joint: 3 };
    cal.enable_effect(spec).expect("effect");
    for id in spec.params() {
        cal.set_param(id, 5e-4).expect("set");
    }
    let backlash_path = s.path("backlash.toml");
    cal.to_cell().save(&backlash_path).expect("save");
    let poses = s.write("poses.csv", &poses_csv(&s.requests, false));
    let out = s.path("out.csv");
    let (ok, _, err) = compensate(&backlash_path, &poses, &out, &[]);
    assert!(!ok && err.contains("dir3"), "{err}");
    let mut text = String::from("tcp,x,y,z,alpha,beta,gamma,dir1,dir2,dir3,dir4,dir5,dir6\n");
    for line in poses_csv(&s.requests, false).lines().skip(1) {
        text.push_str(&format!("{line},1,1,-1,1,1,1\n"));
    }
    let poses = s.write("poses.csv", &text);
    let (ok, _, err) = compensate(&backlash_path, &poses, &out, &[]);
    assert!(ok, "{err}");
    // fk with the same context columns: the targets (joint rows with dir1..dir6) reach the requests
    let rows = csv_rows(&std::fs::read_to_string(&out).expect("read"));
    let mut joints = String::from("tcp,q1,q2,q3,q4,q5,q6,dir1,dir2,dir3,dir4,dir5,dir6\n");
    for r in &rows[1..] {
        joints.push_str(&format!("{},{},1,1,-1,1,1,1\n", r[1], r[2..8].join(",")));
    }
    let joints_path = s.write("joints.csv", &joints);
    assert_fk_reaches(&backlash_path, &joints_path, &s.requests);
}
