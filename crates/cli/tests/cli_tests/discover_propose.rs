//! `vatcal discover --propose N --out-plan DIR`: the measurements that would decide the last
//! round's borderline candidate, written as a plan folder `vatcal campaign --plan` reads.

use std::process::Command;

use vatcal_core::effects::EffectSpec;
use vatcal_core::params::EffectParam;
use vatcal_core::{CellFile, ParamId};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
};

const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");

#[test]
fn discover_proposes_a_plan_for_its_borderline_candidate() {
    let nominal = Model::from_cell(&CellFile::load(FIXTURE).expect("fixture")).expect("model");
    let mut truth = perturbed_truth(&nominal, 9, &ErrorBudget::realistic());
    // a gear error near the detection limit of 100 probe poses
    truth.enable_effect(EffectSpec::JointCyclic { joint: 5, harmonic: 1 }).expect("effect");
    let id = ParamId::Effect(EffectParam::CyclicSin { joint: 5, harmonic: 1 });
    truth.set_param(id, 0.002f64.to_radians()).expect("value");
    let probe = synthetic_probe_measurements(
        &truth,
        &probe_start_poses(&nominal, 100, 10),
        ProbeNoise::default(),
        11,
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let m = dir.path().join("probe.csv");
    vatcal_io::write_measurements(&m, &probe).expect("write probe");
    let plan = dir.path().join("proposal");
    let run = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(["discover", "--model", FIXTURE, "--seed", "2", "--probe-sigma-mm", "0.002"])
        .args(["--propose", "12", "--propose-orientations", "6"])
        .arg("--measurements")
        .arg(&m)
        .arg("--out-plan")
        .arg(&plan)
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    eprintln!("{stdout}");
    assert!(run.status.success(), "stderr: {}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.contains("proposal: 12 measurements to decide"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(plan.join("proposal.json")).expect("proposal.json"))
            .expect("json");
    assert_eq!(json["selected"].as_array().map(Vec::len), Some(12));
    let before = json["std_before"].as_array().expect("std_before");
    let after = json["std_after"].as_array().expect("std_after");
    assert!(!before.is_empty());
    for (b, a) in before.iter().zip(after) {
        assert!(a.as_f64() < b.as_f64(), "the proposal must shrink every focus sigma: {b} -> {a}");
    }
    // the campaign runner reads the folder: 12 measure steps
    let tour = vatcal_pipeline::PlanFolder::new(&plan).read_tour(nominal.joint_kinds()).expect("tour");
    let measures =
        tour.steps.iter().filter(|s| matches!(s, vatcal_campaign::CampaignStep::Measure { .. })).count();
    assert_eq!(measures, 12);

    // --propose without --out-plan is refused by the argument parser
    let bad = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(["discover", "--model", FIXTURE, "--propose", "3"])
        .arg("--measurements")
        .arg(&m)
        .output()
        .expect("runs");
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("--out-plan"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}
