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
    // issue 11's goal on this seed (measured with 573 poses, release, the default 15-min
    // budget: 0.080 / 0.266 mm = 30.2 %; without a budget 0.049 / 0.243 mm = 20 %)
    assert!(
        discovered <= 0.4 * calibrated,
        "discovered {discovered} mm is more than 40 % of the 34 parameters' {calibrated} mm"
    );
    let json = &demo.report_json;
    assert!(json["discovery"]["added_effects"].is_array());
    assert!(json["validation"]["models"][2]["random"]["stats"]["mean_mm"].is_number());
    let d = out.discovery.as_ref().expect("discovery outcome");
    assert_eq!(d.plots.len(), d.discovery.added_effects.len());
    // the default discovery campaign fits 15 min of device time (issue 30 item 4)
    assert_eq!(demo.opts.discovery_budget_s, Some(vatcal_pipeline::budget::DEFAULT_DISCOVERY_BUDGET_S));
    let b = d.budget.as_ref().expect("the default has a budget");
    assert_eq!(b.budget_s, 900.0);
    assert!(b.spent_s > 0.0 && b.spent_s <= b.budget_s, "spent {} s of {} s", b.spent_s, b.budget_s);
    // planned with its repeats: 66 of at most 360 + 12 (release run of seed 1)
    assert_eq!(b.batches[0].batch, "detmax");
    assert!(b.batches[0].planned < demo.opts.discovery_count, "the budget sized the batch: {b:?}");
    assert_eq!(demo.timing_json["discovery_spent_s"].as_f64(), Some(b.spent_s));
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

/// `--discovery-budget-min`: a quick demo with a 12-minute budget sizes its Detmax batch to fit,
/// measures the targeted batch only if it fits what is left, and spends at most the budget;
/// report.json and timing.json say what was predicted and spent.
#[test]
fn a_discovery_budget_sizes_the_batches_and_is_not_exceeded() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut opts = vatcal_demo::DemoOptions::new(3).expect("built-in cell").quick();
    opts.discovery_budget_s = Some(720.0);
    // more than the budget can take: it shrinks the batch
    opts.discovery_count = 75;
    let out = vatcal_demo::run_demo(&opts, dir.path(), &mut |_| {}).expect("demo");
    let d = out.discovery.as_ref().expect("discovery outcome");
    let b = d.budget.as_ref().expect("the budget report");
    assert_eq!(b.budget_s, 720.0);
    assert!(b.spent_s <= 720.0, "spent {} s of 720 s: {b:?}", b.spent_s);
    assert_eq!(b.batches[0].batch, "detmax");
    assert!(b.batches[0].planned < opts.discovery_count, "{b:?}");
    assert!(d.extra_measurements <= b.batches[0].planned, "{b:?}");
    let measured: f64 = b.batches.iter().filter_map(|x| x.device_s).sum();
    assert!((measured - b.spent_s).abs() < 1e-9);
    // the predictions are close to what the batches took
    for x in b.batches.iter().filter(|x| x.device_s.is_some()) {
        let t = x.device_s.expect("measured");
        assert!((x.predicted_s - t).abs() < 0.15 * t, "{x:?}");
    }
    assert!(!b.stop.is_empty());
    let timing: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("timing.json")).expect("timing"))
            .expect("json");
    assert_eq!(timing["discovery_budget_s"].as_f64(), Some(720.0));
    assert_eq!(timing["discovery_spent_s"].as_f64(), Some(b.spent_s));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).expect("report"))
            .expect("json");
    assert!(report["discovery"]["budget"]["batches"].is_array());
}
