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

/// The whole loop with child processes, as a user runs it: `vatcal plan` + `vatcal campaign`
/// on the simulated cell (paper-like truth, served over TCP), `vatcal discover --propose 8
/// --out-plan DIR` on the measurements, then `vatcal campaign --plan DIR` on the same cell
/// measures every proposed pose.
#[test]
fn the_proposed_plan_runs_as_a_campaign_on_the_simulated_cell() {
    use crate::campaign_sim::{devices_file, ok, plan, s, start_cell, vatcal};
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(4, dir.path());
    let cell = start_cell(4);
    let devices = devices_file(&cell, dir.path());
    let campaign = |plan: &std::path::Path, out: &std::path::Path| {
        ok(&vatcal(&[
            "campaign",
            "--devices",
            s(&devices),
            "--plan",
            s(plan),
            "--out",
            s(out),
            "--operator",
            "auto",
            "--quiet",
        ]))
    };
    let run = dir.path().join("run");
    campaign(&plan, &run);
    let proposal = dir.path().join("proposal");
    let stdout = ok(&vatcal(&[
        "discover",
        "--model",
        FIXTURE,
        "--measurements",
        s(&run.join("measurements.csv")),
        "--seed",
        "2",
        "--probe-sigma-mm",
        "0.002",
        "--propose",
        "8",
        "--propose-orientations",
        "6",
        "--out-plan",
        s(&proposal),
    ]));
    eprintln!("{stdout}");
    assert!(stdout.contains("proposal: 8 measurements to decide"), "{stdout}");
    let selected = std::fs::read_to_string(proposal.join("selected.csv")).expect("selected.csv");
    assert_eq!(selected.lines().count(), 1 + 8, "{selected}");
    // the proposed campaign on the same cell: every proposed pose measured
    let more = dir.path().join("more");
    campaign(&proposal, &more);
    let rows = std::fs::read_to_string(more.join("measurements.csv")).expect("measurements.csv");
    let data: Vec<&str> =
        rows.lines().skip(1).filter(|l| !l.starts_with('#') && !l.trim().is_empty()).collect();
    assert_eq!(data.len(), 8, "{rows}");
    // the proposed rows are probe rows of the planned (position, tcp) pairs
    let pairs = |lines: Vec<&str>| {
        let mut v: Vec<(String, String)> = lines
            .iter()
            .map(|l| {
                let f: Vec<&str> = l.split(',').map(str::trim).collect();
                (f[0].to_string(), f[1].to_string())
            })
            .collect();
        v.sort();
        v
    };
    assert_eq!(pairs(selected.lines().skip(1).collect()), pairs(data), "{selected}\n{rows}");
}
