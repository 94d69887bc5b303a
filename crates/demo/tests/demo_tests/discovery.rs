//! The discovery stage of the demo on the paper-like truth: four validated models (nominal,
//! the paper's 34 parameters, discovered, true structure), the `discovery` object of
//! `report.json`, `summary.html`; the discovered model's mean error on the held-out tracker
//! validation is at most 40 % of the 34-parameter one (issue 11's goal). The run is the
//! default demo shared with `paper_like.rs` and `compensation.rs` (`common::default_demo`,
//! seed 1, the paper's validation sizes).

use crate::common;

#[test]
fn the_demo_discovers_on_the_paper_like_truth_and_validates_four_models() {
    let demo = common::default_demo();
    assert!(demo.opts.discovery, "discovery is on by default");
    let out = &demo.out;
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
    // issue 11's goal on this seed (measured with 573 poses: 0.049 / 0.243 mm = 20 %)
    assert!(
        discovered <= 0.4 * calibrated,
        "discovered {discovered} mm is more than 40 % of the 34 parameters' {calibrated} mm"
    );
    let json = &demo.report_json;
    assert!(json["discovery"]["added_effects"].is_array());
    assert!(json["validation"]["models"][2]["random"]["stats"]["mean_mm"].is_number());
    let d = out.discovery.as_ref().expect("discovery outcome");
    assert_eq!(d.plots.len(), d.discovery.added_effects.len());
    assert!(demo.summary_md.contains("| true structure (floor) |"));
    // the measurement loop's campaign is timed like the others (timing.json, summary.md)
    let measurement_loop = d.measurement_loop.as_ref().expect("the loop's report");
    let timing = &demo.timing_json["discovery_loop"];
    if measurement_loop.ran {
        assert_eq!(timing["probe_measurements"]["count"].as_u64(), Some(measurement_loop.proposed as u64));
        assert!(timing["probe_measurements"]["measured_s"].as_f64().is_some_and(|s| s > 0.0), "{timing}");
        assert!(demo.summary_md.contains("| discovery loop |"));
    } else {
        assert!(timing.is_null(), "no loop measured and timing.json has {timing}");
    }
    let html = &demo.summary_html;
    assert!(html.contains("<svg") && html.contains("true structure (floor)"));
}
