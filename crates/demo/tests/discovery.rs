//! The discovery stage of the demo on the paper-like truth: four validated models (nominal,
//! the paper's 34 parameters, discovered, true structure), the `discovery` object of
//! `report.json`, `summary.html`; the discovered model's mean error on the held-out tracker
//! validation is at most 40 % of the 34-parameter one (issue 11's goal; seed 1). Smaller
//! validation sizes keep it fast.

use vatcal_demo::{DemoOptions, DemoSizes, run_demo};

#[test]
fn the_demo_discovers_on_the_paper_like_truth_and_validates_four_models() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut o = DemoOptions::new(1).expect("built-in cell");
    o.sizes = DemoSizes { random_poses: 150, slices: 60, ..DemoSizes::default() };
    assert!(o.discovery, "discovery is on by default");
    let out = run_demo(&o, dir.path(), &mut |_| {}).expect("demo");
    let mean = |label: &str| out.validation(label).map(|v| v.random.stats.mean).expect(label);
    let labels: Vec<&str> = out.report.validation.models.iter().map(|m| m.label.as_str()).collect();
    assert_eq!(labels, ["nominal", "calibrated", "discovered", "true-structure"]);
    for label in labels {
        let v = out.validation(label).expect(label);
        assert!(v.path.is_some(), "{label} has no printing-path run");
    }
    let (calibrated, discovered, truth) = (mean("calibrated"), mean("discovered"), mean("true-structure"));
    assert!(
        discovered <= calibrated,
        "discovered {discovered} mm worse than the 34 parameters {calibrated} mm"
    );
    assert!(truth < calibrated, "the true-structure floor {truth} mm is not below {calibrated} mm");
    // issue 11's goal on this seed (measured with 573 poses: 0.063 / 0.258 mm = 25 %)
    assert!(
        discovered <= 0.4 * calibrated,
        "discovered {discovered} mm is more than 40 % of the 34 parameters' {calibrated} mm"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).expect("json"))
            .expect("parse");
    assert!(json["discovery"]["added_effects"].is_array());
    assert!(json["validation"]["models"][2]["random"]["stats"]["mean_mm"].is_number());
    let d = out.discovery.as_ref().expect("discovery outcome");
    assert_eq!(d.plots.len(), d.discovery.added_effects.len());
    let summary = std::fs::read_to_string(dir.path().join("summary.md")).expect("summary");
    assert!(summary.contains("| true structure (floor) |"));
    let html = std::fs::read_to_string(dir.path().join("summary.html")).expect("html");
    assert!(html.contains("<svg") && html.contains("true structure (floor)"));
}
