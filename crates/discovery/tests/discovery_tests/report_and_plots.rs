//! The report is deterministic, serialises to the JSON the CLI writes, and the plots are
//! written.

use crate::common;

use common::{Hidden, scenario};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::EffectParam;
use vatcal_core::{ParamId, ParamSet};
use vatcal_discovery::{DiscoverOptions, discover, write_effect_plots};

#[test]
fn report_json_plots_and_determinism() {
    let joint = 6;
    let a = 0.025f64.to_radians();
    let hidden = [Hidden {
        spec: EffectSpec::JointCyclic { joint, harmonic: 1 },
        values: vec![
            (ParamId::Effect(EffectParam::CyclicSin { joint, harmonic: 1 }), 0.6 * a),
            (ParamId::Effect(EffectParam::CyclicCos { joint, harmonic: 1 }), -0.8 * a),
        ],
    }];
    let s = scenario(71, &hidden, None, 150);
    let options = DiscoverOptions { seed: 5, ..DiscoverOptions::default() };
    let d1 = discover(&common::nominal(), &s.probe, &ParamSet::paper34(), Some(&s.validation), &options)
        .expect("runs");
    let d2 = discover(&common::nominal(), &s.probe, &ParamSet::paper34(), Some(&s.validation), &options)
        .expect("runs");
    let j1 = serde_json::to_value(&d1).expect("json");
    let j2 = serde_json::to_value(&d2).expect("json");
    assert_eq!(j1, j2, "same seed, same report");

    let added = j1["added_effects"].as_array().expect("list");
    assert_eq!(added.len(), 1, "{added:#?}");
    assert_eq!(added[0]["effect"], "joint-cyclic");
    assert_eq!(added[0]["joint"], 6);
    let sin = added[0]["values"]["cyclic6_h1_sin_deg"].as_f64().expect("value in degrees");
    let cos = added[0]["values"]["cyclic6_h1_cos_deg"].as_f64().expect("value in degrees");
    assert!((sin - 0.015).abs() < 0.002 && (cos + 0.020).abs() < 0.002, "sin {sin} cos {cos} deg");
    for key in ["gap_before_mm", "gap_after_mm"] {
        assert!(added[0][key].as_f64().is_some(), "{key}");
    }
    assert!(added[0]["score"]["statistic"].as_f64().is_some());
    assert!(added[0]["comparison"]["delta_bic"].as_f64().is_some());
    assert!(
        j1["final_gap_mm"].as_f64().expect("final gap") < j1["initial_gap_mm"].as_f64().expect("initial")
    );
    // every round lists its candidates with a status
    let round = &j1["rounds"][0];
    assert!(round["candidates"].as_array().expect("candidates").iter().all(|c| c["status"].is_string()));
    assert!(round["location"].as_array().expect("location").len() > 10);

    // the where-analysis of the first round points at joint 6
    let top = &d1.rounds[0].location[0];
    assert!(top.label.contains("q6"), "{}", top.sentence());

    let dir = tempfile::tempdir().expect("tempdir");
    let files = write_effect_plots(&d1, dir.path()).expect("plots");
    assert_eq!(files.len(), 1);
    let svg = std::fs::read_to_string(&files[0]).expect("svg");
    assert!(svg.starts_with("<svg") && svg.contains("before") && svg.contains("after"));
    assert!(files[0].file_name().is_some_and(|n| n.to_string_lossy() == "step1-joint-cyclic-j6.svg"));

    // the HTML report: one self-contained page with the plot inline
    let html = vatcal_discovery::html_report(&d1).expect("html").render();
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert_eq!(html.matches("<svg").count(), 1, "one inline plot per added effect");
    assert!(html.contains("joint-cyclic (joint 6"), "names the effect");
    for external in ["<script", "<link", "src=\"http", "href=\"http", "url("] {
        assert!(!html.contains(external), "{external}");
    }

    // the final model writes to a cell file with the effect in it
    let cell = d1.model.to_cell();
    assert!(cell.effects.iter().any(|e| e.effect == "joint-cyclic" && e.joint == Some(6)));
}
