//! `vatcal discover` end to end: CSV in, report/plots/model out, on simulated data with a
//! hidden cyclic error of joint 4.

use std::process::Command;

use vatcal_core::effects::EffectSpec;
use vatcal_core::params::EffectParam;
use vatcal_core::{CellFile, ParamId};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
    synthetic_tracker_measurements,
};

const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

#[test]
fn discover_names_a_hidden_cyclic_error_and_writes_its_outputs() {
    let nominal = Model::from_cell(&CellFile::load(FIXTURE).expect("fixture")).expect("model");
    let mut truth = perturbed_truth(&nominal, 5, &ErrorBudget::realistic());
    let joint = 4;
    truth.enable_effect(EffectSpec::JointCyclic { joint, harmonic: 1 }).expect("effect");
    let a = 0.02f64.to_radians();
    truth.set_param(ParamId::Effect(EffectParam::CyclicSin { joint, harmonic: 1 }), a).expect("value");
    let starts = probe_start_poses(&nominal, 180, 6);
    let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise::default(), 7);
    let tracker = synthetic_tracker_measurements(&truth, 200, 0.005, 8);

    let dir = tempfile::tempdir().expect("tempdir");
    let (m, v) = (dir.path().join("probe.csv"), dir.path().join("tracker.csv"));
    vatcal_io::write_measurements(&m, &probe).expect("write probe");
    vatcal_io::write_measurements(&v, &tracker).expect("write tracker");
    let (report, out, plots) =
        (dir.path().join("r.json"), dir.path().join("final.toml"), dir.path().join("plots"));
    let run = vatcal()
        .args(["discover", "--model", FIXTURE, "--params", "paper34", "--seed", "3"])
        .arg("--measurements")
        .arg(&m)
        .arg("--validation")
        .arg(&v)
        .arg("--report")
        .arg(&report)
        .arg("--out")
        .arg(&out)
        .arg("--plots")
        .arg(&plots)
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    eprintln!("{stdout}");
    assert!(run.status.success(), "stderr: {}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.contains("added joint-cyclic (joint 4, harmonic 1)"), "{stdout}");
    assert!(stdout.contains("result: 1 effect(s) added"), "{stdout}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    let added = &json["added_effects"][0];
    assert_eq!(added["effect"], "joint-cyclic");
    assert_eq!(added["joint"], 4);
    let sin = added["values"]["cyclic4_h1_sin_deg"].as_f64().expect("value");
    assert!((sin - 0.02).abs() < 0.003, "{sin}");
    assert!(added["gap_after_mm"].as_f64() < added["gap_before_mm"].as_f64());

    let final_model = CellFile::load(&out).expect("final model loads");
    assert!(final_model.effects.iter().any(|e| e.effect == "joint-cyclic" && e.joint == Some(4)));
    assert!(plots.join("step1-joint-cyclic-j4.svg").exists());
    // the HTML report beside the JSON: self-contained, the plot inline
    let html = std::fs::read_to_string(report.with_extension("html")).expect("html report");
    assert!(html.starts_with("<!DOCTYPE html>") && html.contains("<svg"), "html");
    assert!(html.contains("joint-cyclic (joint 4, harmonic 1)"));
    assert!(!html.contains("<script") && !html.contains("href=\"http"));
}

#[test]
fn discover_reports_bad_arguments_clearly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let m = dir.path().join("m.csv");
    std::fs::write(&m, "position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0,0\n").expect("write");
    let run = vatcal()
        .args(["discover", "--model", FIXTURE, "--params", "alpha_9"])
        .arg("--measurements")
        .arg(&m)
        .output()
        .expect("runs");
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("alpha_9"), "{stderr}");
    let run = vatcal()
        .args(["discover", "--model", FIXTURE, "--measurements"])
        .arg(dir.path().join("missing.csv"))
        .output()
        .expect("runs");
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("missing.csv"));
    // the instruments' known noise: positive, and the probe's when the data has probe rows
    for (flags, expected) in [
        (vec!["--probe-sigma-mm=-0.002"], "--probe-sigma-mm must be a positive number"),
        (vec!["--tracker-sigma-mm", "0.007"], "give --probe-sigma-mm too"),
    ] {
        let run = vatcal()
            .args(["discover", "--model", FIXTURE])
            .args(&flags)
            .arg("--measurements")
            .arg(&m)
            .output()
            .expect("runs");
        assert!(!run.status.success());
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains(expected), "{flags:?}: {stderr}");
    }
    let help = vatcal().args(["discover", "--help"]).output().expect("runs");
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(help.contains("over all rounds") && !help.contains("per round"), "{help}");
}
