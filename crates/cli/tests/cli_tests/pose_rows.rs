//! Pose rows through the binary (issue 31 item 1): a ROS-style motion-capture log of the tool
//! body (metres, radians, quaternions) of the UR5e truth, whose tool is tilted by a few mrad;
//! `identify` with its defaults, then `validate` on held-out postures reports position and
//! orientation errors, both at the noise floor.

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::{EffectParam, ToolFrameDof};
use vatcal_core::{CellFile, ParamId};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, synthetic_tracker_measurements};

use super::any_robot::{fixture, run};

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller
    let u1: f64 = rng.random_range(1e-12..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The UR5e truth: geometry perturbed (no compliance), the tool tilted by (3, -2) mrad.
fn truth() -> Model {
    let nominal = Model::from_cell(&CellFile::load(fixture("ur5e.toml")).expect("fixture")).expect("model");
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(&nominal, 23, &budget);
    t.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
    t.set_param(ParamId::Effect(EffectParam::ToolFrame(ToolFrameDof::Rx)), 3e-3).expect("rx");
    t.set_param(ParamId::Effect(EffectParam::ToolFrame(ToolFrameDof::Ry)), -2e-3).expect("ry");
    t
}

/// A pose CSV of TCP 1 (metres, radians, `qw,qx,qy,qz`) with noise `sigma_mm` / `sigma_rad`.
fn write_poses(path: &Path, truth: &Model, n: usize, sigma_mm: f64, sigma_rad: f64, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000);
    let mut text = String::from("tcp,q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz\n");
    for m in synthetic_tracker_measurements(truth, n, 0.0, seed).into_iter().filter(|m| m.tcp == 1) {
        let mut g = |s: f64| Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * s;
        let p = (truth.tcp_position(&m.q, 1).expect("fk") + g(sigma_mm)) / 1000.0;
        let r = truth.tool_rotation_ctx(&m.q, &m.context).expect("rotation");
        let q =
            (UnitQuaternion::from_scaled_axis(g(sigma_rad)) * UnitQuaternion::from_matrix(&r)).into_inner();
        let joints: Vec<String> = m.q.as_slice().iter().map(f64::to_string).collect();
        text += &format!("1,{},{},{},{},{},{},{},{}\n", joints.join(","), p.x, p.y, p.z, q.w, q.i, q.j, q.k);
    }
    std::fs::write(path, text).expect("write");
}

#[test]
fn pose_rows_identify_and_validate_with_orientation_errors() {
    let dir = tempfile::tempdir().expect("tmp");
    let s = |p: &Path| p.display().to_string();
    let truth = truth();
    let (train, held) = (dir.path().join("train.csv"), dir.path().join("held.csv"));
    write_poses(&train, &truth, 300, 0.01, 1e-3, 5);
    write_poses(&held, &truth, 300, 0.0, 0.0, 6);
    let (cal, val) = (dir.path().join("cal.toml"), dir.path().join("v.json"));
    let ros = ["--length-unit", "m", "--angle-unit", "rad"];
    let model = fixture("ur5e.toml");
    let mut args = vec!["identify", "--model", &model, "--measurements"];
    let (train_s, cal_s) = (s(&train), s(&cal));
    args.extend([train_s.as_str(), "--out", cal_s.as_str()]);
    args.extend(ros);
    let out = run(&args);
    eprintln!("{out}");
    let held_s = s(&held);
    let val_s = s(&val);
    let mut args = vec!["validate", "--model", &cal_s, "--baseline", &model, "--tracker", &held_s];
    args.extend(["--report", val_s.as_str()]);
    args.extend(ros);
    let out = run(&args);
    eprintln!("{out}");
    assert!(out.contains("orientation errors of the pose rows"), "{out}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&val).expect("report")).expect("json");
    let position_mm = v["model"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean");
    let orientation_mrad = v["orientation"]["model"]["mean_mrad"].as_f64().expect("orientation mean");
    let baseline_mrad = v["orientation"]["baseline"]["mean_mrad"].as_f64().expect("baseline mean");
    eprintln!("held-out: {position_mm:.5} mm, {orientation_mrad:.3} mrad (nominal {baseline_mrad:.3} mrad)");
    assert!(position_mm < 0.015, "{position_mm}");
    assert!(baseline_mrad > 3.0 && orientation_mrad < 0.4, "{orientation_mrad} / {baseline_mrad}");
}

/// `identify` on `train` (ROS units) with `extra` flags and the JSON report; then the held-out
/// position error [mm] of `validate` on `held`. Returns the report and that error.
fn identify_and_validate(
    dir: &Path,
    train: &Path,
    held: &Path,
    extra: &[&str],
    tag: &str,
) -> (serde_json::Value, f64) {
    let s = |p: &Path| p.display().to_string();
    let (cal, rep, val) =
        (dir.join(format!("{tag}.toml")), dir.join(format!("{tag}.json")), dir.join(format!("{tag}-v.json")));
    let (train_s, cal_s, rep_s, held_s, val_s) = (s(train), s(&cal), s(&rep), s(held), s(&val));
    let ros = ["--length-unit", "m", "--angle-unit", "rad"];
    let model = fixture("ur5e.toml");
    let mut args = vec!["identify", "--model", &model, "--measurements", &train_s, "--out", &cal_s];
    args.extend(["--report", rep_s.as_str(), "--params", "kinematic"]);
    args.extend(ros);
    args.extend(extra);
    let out = run(&args);
    eprintln!("{out}");
    assert!(out.contains("fitted scatter per axis: tracker"), "{out}");
    let mut args = vec!["validate", "--model", &cal_s, "--tracker", &held_s, "--report", &val_s];
    args.extend(ros);
    run(&args);
    let json = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).expect("report")).expect("json")
    };
    let v = json(&val);
    (json(&rep), v["model"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean"))
}

/// Without --orientation-weight the pose rows are weighed by their fitted scatter: with 10 µm
/// and 1 mrad of noise the fitted σ come back near those values, the summary counts the
/// orientation rows apart, and the held-out error is no worse than with the stated default.
#[test]
fn pose_rows_are_weighed_by_their_fitted_scatter() {
    let dir = tempfile::tempdir().expect("tmp");
    let truth = truth();
    let (train, held) = (dir.path().join("train.csv"), dir.path().join("held.csv"));
    write_poses(&train, &truth, 300, 0.01, 1e-3, 15);
    write_poses(&held, &truth, 300, 0.0, 0.0, 16);
    let (fitted, fitted_mm) = identify_and_validate(dir.path(), &train, &held, &[], "fitted");
    let (stated, stated_mm) =
        identify_and_validate(dir.path(), &train, &held, &["--orientation-weight", "100"], "stated");
    let s = &fitted["fitted_scatter"];
    eprintln!("fitted: {s}\nheld-out {fitted_mm:.5} mm (stated weight 100: {stated_mm:.5} mm)");
    let tracker_mm = s["tracker_mm"].as_f64().expect("tracker sigma");
    let orientation_rad = s["orientation_rad"].as_f64().expect("orientation sigma");
    assert!((tracker_mm / 0.01 - 1.0).abs() < 0.2, "{tracker_mm}");
    assert!((orientation_rad / 1e-3 - 1.0).abs() < 0.2, "{orientation_rad}");
    assert_eq!(s["stated"], false);
    assert_eq!(stated["fitted_scatter"]["stated"], true);
    assert_eq!(stated["fitted_scatter"]["orientation_weight"].as_f64(), Some(100.0));
    assert!(fitted_mm < 0.015 && fitted_mm <= 1.05 * stated_mm, "{fitted_mm} vs {stated_mm}");
}

/// A stated orientation noise in the file (`# vatcal-noise: … orientation_sigma_mrad=…`) sets
/// the orientation weight (no refits from the scatter): `w_tracker · (σ_tracker / σ_o)²`; an
/// orientation σ without the reference kind's σ is a one-line error.
#[test]
fn a_stated_orientation_noise_sets_the_weight() {
    let dir = tempfile::tempdir().expect("tmp");
    let truth = truth();
    let (train, held) = (dir.path().join("train.csv"), dir.path().join("held.csv"));
    write_poses(&train, &truth, 200, 0.01, 1e-3, 25);
    write_poses(&held, &truth, 100, 0.0, 0.0, 26);
    let rows = std::fs::read_to_string(&train).expect("train");
    std::fs::write(&train, format!("# vatcal-noise: tracker_sigma_mm=0.01 orientation_sigma_mrad=2\n{rows}"))
        .expect("write");
    let (report, held_mm) = identify_and_validate(dir.path(), &train, &held, &[], "noise");
    let s = &report["fitted_scatter"];
    assert_eq!(s["stated"], true, "{s}");
    // σ_tracker / σ_o = 0.01 mm / 0.002 rad = 5 mm/rad, weight 25 mm²/rad² (tracker weight 1)
    let w = s["orientation_weight"].as_f64().expect("weight");
    assert!((w - 25.0).abs() < 1e-9, "{w}");
    assert!(held_mm < 0.02, "{held_mm}");
    std::fs::write(&train, format!("# vatcal-noise: orientation_sigma_mrad=2\n{rows}")).expect("write");
    let model = fixture("ur5e.toml");
    let (train_s, out_s) = (train.display().to_string(), dir.path().join("x.toml").display().to_string());
    let args = ["identify", "--model", &model, "--measurements", &train_s, "--out", &out_s];
    let ros = ["--length-unit", "m", "--angle-unit", "rad"];
    let out = super::any_robot::vatcal().args([&args[..], &ros[..]].concat()).output().expect("run");
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(e.contains("orientation_sigma_mrad but not tracker_sigma_mm"), "{e}");
}
