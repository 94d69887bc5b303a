//! `vatcal fk` and `vatcal validate` apply the context columns (`dir2..dir7`, `time_s`,
//! `temperature_c`) to a model's backlash and thermal drift, and name the file and the missing
//! column when a model needs one the file lacks.

use std::process::Command;

use vatcal_core::effects::{EffectSpec, ThermalDriver};
use vatcal_core::measurement::dirs_from_meca500_arm;
use vatcal_core::params::EffectParam;
use vatcal_core::{CellFile, JointVector, MeasurementContext, ParamId};
use vatcal_kinematics::Model;

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

fn nominal() -> Model {
    let path = format!("{}/../../fixtures/meca500-zaber.toml", env!("CARGO_MANIFEST_DIR"));
    Model::from_cell(&CellFile::load(path).expect("cell")).expect("model")
}

/// The nominal cell with backlash on joint 3 (0.02°) and a temperature-driven thermal drift
/// (1e-4 /K, reference 20 °C), written to `dir/name`.
fn effect_model(dir: &tempfile::TempDir, name: &str) -> (Model, String) {
    let mut m = nominal();
    m.enable_effect(EffectSpec::JointBacklash { joint: 3 }).expect("backlash");
    m.set_param(ParamId::Effect(EffectParam::Backlash { joint: 3 }), 0.02f64.to_radians()).expect("b");
    m.enable_effect(EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature }).expect("thermal");
    m.set_param(ParamId::Effect(EffectParam::ThermalPerKelvin), 1e-4).expect("k");
    let path = dir.path().join(name);
    m.to_cell().save(&path).expect("save");
    // the file round-trips (so the binary sees this very model)
    let back = Model::from_cell(&CellFile::load(&path).expect("load")).expect("model");
    (back, path.display().to_string())
}

fn fk(model: &str, input: &str) -> std::process::Output {
    vatcal().args(["fk", "--model", model, "--input", input]).output().expect("run vatcal")
}

fn parse_xyz(stdout: &[u8]) -> Vec<[f64; 3]> {
    let text = String::from_utf8_lossy(stdout);
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|s| s.parse().expect("number")).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

#[test]
fn fk_applies_backlash_and_thermal_drift_from_the_context_columns() {
    let dir = tempfile::tempdir().expect("tmp");
    let (model, model_path) = effect_model(&dir, "effects.toml");
    let input = dir.path().join("rows.csv");
    std::fs::write(
        &input,
        "tcp,q1,q2,q3,q4,q5,q6,q7,time_s,temperature_c,dir2,dir3,dir4,dir5,dir6,dir7\n\
         1,150,10,20,-30,40,50,60,0,20,1,1,1,1,1,1\n\
         1,150,10,20,-30,40,50,60,0,20,1,-1,1,1,1,1\n\
         1,150,10,20,-30,40,50,60,0,25,1,1,1,1,1,1\n",
    )
    .expect("write");
    let out = fk(&model_path, input.to_str().expect("utf-8"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let got = parse_xyz(&out.stdout);
    assert_eq!(got.len(), 3);
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    let contexts = [(20.0, [1, 1, 1, 1, 1, 1]), (20.0, [1, -1, 1, 1, 1, 1]), (25.0, [1, 1, 1, 1, 1, 1])];
    for (row, (t, dir)) in got.iter().zip(contexts) {
        let ctx = MeasurementContext {
            dir: Some(dirs_from_meca500_arm(dir)),
            time_s: Some(0.0),
            temperature_c: Some(t),
        };
        let p = model.tcp_position_ctx(&q, &ctx, 1).expect("fk");
        for k in 0..3 {
            assert!((row[k] - p[k]).abs() < 1e-9, "{row:?} vs {p:?}");
        }
    }
    // the columns change the prediction: backlash flips ~0.04° of joint 3, 5 K of drift
    let d = |a: &[f64; 3], b: &[f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    assert!(d(&got[0], &got[1]) > 0.05, "backlash moved the TCP by {} mm", d(&got[0], &got[1]));
    assert!(d(&got[0], &got[2]) > 0.05, "temperature moved the TCP by {} mm", d(&got[0], &got[2]));

    // the same rows without a model effect: the columns are accepted and change nothing
    let plain = nominal();
    let out = fk(
        &format!("{}/../../fixtures/meca500-zaber.toml", env!("CARGO_MANIFEST_DIR")),
        input.to_str().expect("utf-8"),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let p = plain.tcp_position(&q, 1).expect("fk");
    for row in parse_xyz(&out.stdout) {
        assert!((row[0] - p.x).abs() < 1e-9 && (row[2] - p.z).abs() < 1e-9);
    }
}

#[test]
fn fk_names_the_file_and_the_column_a_model_needs() {
    let dir = tempfile::tempdir().expect("tmp");
    let (_, model_path) = effect_model(&dir, "effects.toml");
    // no dir columns at all
    let no_dir = dir.path().join("no_dir.csv");
    std::fs::write(&no_dir, "tcp,q1,q2,q3,q4,q5,q6,q7,temperature_c\n1,150,10,20,-30,40,50,60,21\n")
        .expect("write");
    let out = fk(&model_path, no_dir.to_str().expect("utf-8"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no_dir.csv") && err.contains("dir3,") && err.contains("joint-backlash (joint 3)"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // a column present but empty on one row
    let empty = dir.path().join("empty_temperature.csv");
    std::fs::write(
        &empty,
        "tcp,q1,q2,q3,q4,q5,q6,q7,temperature_c,dir2,dir3,dir4,dir5,dir6,dir7\n\
         1,150,10,20,-30,40,50,60,21,1,1,1,1,1,1\n\
         1,150,10,20,-30,40,50,60,,1,1,1,1,1,1\n",
    )
    .expect("write");
    let out = fk(&model_path, empty.to_str().expect("utf-8"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("empty_temperature.csv:3") && err.contains("temperature_c"), "{err}");
}

#[test]
fn validate_uses_the_context_columns_of_the_tracker_file() {
    let dir = tempfile::tempdir().expect("tmp");
    let (model, model_path) = effect_model(&dir, "effects.toml");
    // tracker rows that the effect model predicts exactly (with their context)
    let mut csv =
        String::from("tcp,q1,q2,q3,q4,q5,q6,q7,x,y,z,temperature_c,dir2,dir3,dir4,dir5,dir6,dir7\n");
    for (k, (t, d3)) in [(20.0, 1i8), (24.0, -1), (22.0, 1), (26.0, -1)].iter().enumerate() {
        let q = JointVector::from_mm_deg(50.0 * k as f64, [10.0, 20.0 + k as f64, -30.0, 40.0, 50.0, 60.0]);
        let ctx = MeasurementContext {
            dir: Some(dirs_from_meca500_arm([1, *d3, 1, 1, 1, 1])),
            time_s: None,
            temperature_c: Some(*t),
        };
        let p = model.tcp_position_ctx(&q, &ctx, 1).expect("fk");
        let v = q.to_mm_deg();
        csv.push_str(&format!(
            "1,{},{},{},{},{},{},{},{},{},{},{t},1,{d3},1,1,1,1\n",
            v[0], v[1], v[2], v[3], v[4], v[5], v[6], p.x, p.y, p.z
        ));
    }
    let tracker = dir.path().join("tracker.csv");
    std::fs::write(&tracker, csv).expect("write");
    let report = dir.path().join("report.json");
    let out = vatcal()
        .args([
            "validate",
            "--model",
            &model_path,
            "--tracker",
            tracker.to_str().expect("utf-8"),
            "--report",
            report.to_str().expect("utf-8"),
        ])
        .output()
        .expect("run");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    let mean = json["model"]["validation"]["stats"]["mean_mm"].as_f64().expect("mean");
    assert!(mean < 1e-6, "the effect model with its context predicts its own data: mean {mean} mm");
}
