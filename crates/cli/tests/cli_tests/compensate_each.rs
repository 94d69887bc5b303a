//! `vatcal compensate --each`: independent poses, each row solved on its own (issue 23).

use std::process::Command;

use rand::SeedableRng;
use vatcal_compensation::PoseRequest;
use vatcal_core::{CellFile, JointVector, MeasurementContext};
use vatcal_kinematics::Model;

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn run(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vatcal")).args(args).output().expect("run");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into())
}

/// A calibrated stand-in (the canonical cell's perturbed truth, seed 4, saved and read back)
/// in `dir`; its path and model.
fn calibrated(dir: &tempfile::TempDir) -> (String, Model) {
    let nominal =
        Model::from_cell(&CellFile::load(fixture("meca500-zaber.toml")).expect("cell")).expect("model");
    let cal = vatcal_sim::truth::perturbed_truth(&nominal, 4, &vatcal_sim::truth::ErrorBudget::realistic());
    let path = dir.path().join("calibrated.toml").display().to_string();
    cal.to_cell().save(&path).expect("save");
    (path.clone(), Model::from_cell(&CellFile::load(&path).expect("load")).expect("model"))
}

/// `count` requests of TCP 1..3 at random joints of `model` (seeded), away from the wrist
/// singularity, and the joints.
fn random_requests(model: &Model, count: usize, seed: u64) -> Vec<(JointVector, PoseRequest)> {
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(count);
    while out.len() < count {
        let q = vatcal_sim::truth::random_joints(model, &mut rng, 0.1);
        if model.chain(&q).theta[5].sin().abs() < 15f64.to_radians().sin() {
            continue;
        }
        let tool = model.chain(&q).tool;
        let tcp = 1 + (out.len() % 3) as u32;
        let req = PoseRequest::from_tool_frame(model, tcp, q, &tool, MeasurementContext::default())
            .expect("request");
        out.push((q, req));
    }
    out
}

/// `tcp,q1,x,y,z,alpha,beta,gamma[,branch]` rows (full precision).
fn poses_csv(requests: &[PoseRequest], branches: Option<&[&str]>) -> String {
    let mut s = String::from("tcp,q1,x,y,z,alpha,beta,gamma");
    s.push_str(if branches.is_some() { ",branch\n" } else { "\n" });
    for (k, r) in requests.iter().enumerate() {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{}",
            r.tcp,
            r.given[0],
            r.xyz_mm[0],
            r.xyz_mm[1],
            r.xyz_mm[2],
            r.abc_deg[0],
            r.abc_deg[1],
            r.abc_deg[2]
        ));
        if let Some(b) = branches {
            s.push_str(&format!(",{}", b[k]));
        }
        s.push('\n');
    }
    s
}

/// The data rows of an output CSV (`#` comments and the header left out).
fn data_rows(text: &str) -> Vec<Vec<String>> {
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect()
}

/// The acceptance test through the binary: 300 random independent poses on a calibrated
/// model are refused as a path (joint jumps / branch changes), and with `--each` every row's
/// joints put its TCP on the request under the calibrated model to 1e-6 mm (by `vatcal fk`)
/// with the requested orientation to 1e-9 rad.
#[test]
fn each_reproduces_300_random_independent_poses() {
    let dir = tempfile::tempdir().expect("tmp");
    let (model_path, cal) = calibrated(&dir);
    let rows = random_requests(&cal, 300, 23);
    let requests: Vec<PoseRequest> = rows.iter().map(|(_, r)| *r).collect();
    let poses = dir.path().join("poses.csv").display().to_string();
    std::fs::write(&poses, poses_csv(&requests, None)).expect("write");
    let out = dir.path().join("targets.csv").display().to_string();
    let (ok, err) = run(&["compensate", "--model", &model_path, "--poses", &poses, "--out", &out]);
    assert!(!ok && (err.contains("jumps") || err.contains("branch change")), "a path refuses them: {err}");

    let (ok, err) = run(&["compensate", "--model", &model_path, "--poses", &poses, "--out", &out, "--each"]);
    assert!(ok, "{err}");
    assert!(err.contains("compensated 300 of 300"), "{err}");
    let text = std::fs::read_to_string(&out).expect("out");
    assert!(text.contains("# independent poses (--each)"), "{text}");
    let targets = data_rows(&text);
    assert_eq!(targets.len(), 300);
    let (ok, fk_err) = {
        let o = Command::new(env!("CARGO_BIN_EXE_vatcal"))
            .args(["fk", "--model", &model_path, "--input", &out])
            .output()
            .expect("fk");
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr),
        )
    };
    assert!(ok, "{fk_err}");
    let fk: Vec<Vec<f64>> = fk_err
        .lines()
        .skip(1)
        .take(300)
        .map(|l| l.split(',').map(|v| v.parse().expect("number")).collect())
        .collect();
    let kinds = cal.joint_kinds();
    let mut worst = 0.0f64;
    for ((p, req), row) in fk.iter().zip(&requests).zip(&targets) {
        let err = (0..3).map(|k| (p[k] - req.xyz_mm[k]).powi(2)).sum::<f64>().sqrt();
        worst = worst.max(err);
        let v: Vec<f64> = row[2..9].iter().map(|x| x.parse().expect("number")).collect();
        let q = JointVector::from_file_units(&v, kinds).expect("q");
        assert!(cal.limit_violation(&q).is_none());
        let target = req.tool_target(&cal, 0).expect("target");
        let r = vatcal_planning::ik::rotation_angle_between(&cal.chain(&q).tool.r, &target.tool.r);
        assert!(r < 1e-9, "orientation {r:e} rad");
    }
    assert!(worst < 1e-6, "largest TCP error {worst:e} mm");
    let branches: std::collections::BTreeSet<&str> = targets.iter().map(|r| r[9].as_str()).collect();
    assert!(branches.len() > 1, "{branches:?}");
}

/// A `branch` column switches to independent poses and is honoured row by row; `--near` picks
/// the generating joints back; bad values are named with file, line and column.
#[test]
fn branch_column_near_and_errors() {
    let dir = tempfile::tempdir().expect("tmp");
    let (model_path, cal) = calibrated(&dir);
    let rows = random_requests(&cal, 12, 5);
    let requests: Vec<PoseRequest> = rows.iter().map(|(_, r)| *r).collect();
    let out = dir.path().join("out.csv").display().to_string();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name).display().to_string();
        std::fs::write(&p, text).expect("write");
        p
    };
    // every row on branch 6 (shoulder +, elbow -, wrist -) or empty (free)
    let named: Vec<&str> = (0..12).map(|k| if k % 2 == 0 { "6" } else { "" }).collect();
    let poses = write("named.csv", &poses_csv(&requests, Some(&named)));
    let (ok, err) =
        run(&["compensate", "--model", &model_path, "--poses", &poses, "--out", &out, "--skip-unreachable"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).expect("out");
    assert!(text.contains("on the branch its `branch` column names"), "{text}");
    let lines_solved: Vec<Vec<String>> = data_rows(&text);
    let mut on_six = 0;
    for row in &lines_solved {
        let line: usize = row[0].parse().expect("line");
        if (line - 2).is_multiple_of(2) {
            assert_eq!(row[9], "6", "{row:?}");
            on_six += 1;
        }
    }
    // the free rows are all solved; a named row is solved on branch 6 or skipped, with its line
    // named: branch 6 does not reach it, or only outside the joint limits
    assert_eq!(lines_solved.len() - on_six, 6, "{text}");
    let skipped: Vec<&str> = text.lines().filter(|l| l.starts_with("# skipped")).collect();
    assert_eq!(on_six + skipped.len(), 6, "{text}");
    assert!(on_six > 0, "{text}");
    for l in skipped {
        assert!(
            l.contains("named.csv:") && (l.contains("branch 6") || l.contains("leaves its limits")),
            "{l}"
        );
    }

    // --near the generating joints of row 1 gives them back
    let (q, req) = &rows[0];
    let one = write("one.csv", &poses_csv(std::slice::from_ref(req), None));
    let near: Vec<String> = q.to_mm_deg().iter().map(|v| format!("{v}")).collect();
    let near = near.join(",");
    let each_near = |near: &str| {
        run(&["compensate", "--model", &model_path, "--poses", &one, "--out", &out, "--each", "--near", near])
    };
    let (ok, err) = each_near(&near);
    assert!(ok, "{err}");
    let row = &data_rows(&std::fs::read_to_string(&out).expect("out"))[0];
    let got: Vec<f64> = row[2..9].iter().map(|x| x.parse().expect("number")).collect();
    let want = q.to_mm_deg();
    assert!((0..7).all(|k| (got[k] - want[k]).abs() < 1e-6), "{got:?} vs {want:?}");

    let bad = write("bad.csv", &poses_csv(&requests[..2], Some(&["3", "x"])));
    let (ok, err) = run(&["compensate", "--model", &model_path, "--poses", &bad, "--out", &out]);
    assert!(
        !ok && err.contains("bad.csv:3") && err.contains("column `branch`") && err.contains("`x`"),
        "{err}"
    );
    let sign = write("sign.csv", &poses_csv(&requests[..1], Some(&["+"])));
    let (ok, err) = run(&["compensate", "--model", &model_path, "--poses", &sign, "--out", &out]);
    assert!(!ok && err.contains("sign.csv:2") && err.contains("0..=7"), "{err}");
    let (ok, err) = each_near("1,2");
    assert!(!ok && err.contains("--near") && err.contains("7 finite joint values"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}
