//! Issue 13, item 4: the demo's 300-slice printing path, commanded with the targets of
//! `vatcal-compensation` (the library of `vatcal compensate`), lands on the (paper-like) true
//! cell with the calibrated model's error, and with uncompensated nominal targets with the
//! nominal error. The tracker's measurements are checked against the noise-free oracle
//! `vatcal_compensation::path_accuracy` on the hidden truth.

use vatcal_campaign::validation::printing::{guide_schedule, printing_path};
use vatcal_compensation::{Branch, PathOptions, ToolTarget, path_accuracy};
use vatcal_demo::{DemoOptions, run_demo};
use vatcal_kinematics::Model;

#[test]
fn the_printing_path_lands_with_the_calibrated_error_when_compensated() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut opts = DemoOptions::new(3).expect("built-in cell");
    // the compensation uses the 34-parameter model; the discovery stage is tested in discovery.rs
    opts.discovery = false;
    let out = run_demo(&opts, dir.path(), &mut |_| {}).expect("demo");
    let c = &out.report.compensation;
    eprintln!("{c:#?}");
    assert_eq!(c.slices, 300);
    // the commanded runs are the compensation's targets, solved to rounding level
    assert!(c.calibrated_run_difference <= 1e-6 && c.nominal_run_difference <= 1e-6, "{c:?}");
    assert!(c.max_residual_mm < 1e-6 && c.max_residual_deg < 1e-7, "{c:?}");
    let (un, co) = (c.uncompensated.expect("nominal run"), c.compensated.expect("calibrated run"));
    let nominal_path = out.validation("nominal").and_then(|m| m.path.as_ref()).expect("nominal path");
    let calibrated_path =
        out.validation("calibrated").and_then(|m| m.path.as_ref()).expect("calibrated path");
    assert!((un.mean_mm - nominal_path.tip_stats.mean).abs() < 1e-12);
    assert!((co.mean_mm - calibrated_path.tip_stats.mean).abs() < 1e-12);
    // compensation removes more than half of the error (the paper-like truth keeps effects
    // outside the 34 parameters: seed 3 measured 0.72 → 0.31 mm)
    assert!(un.mean_mm > 0.5 && co.mean_mm < 0.5 * un.mean_mm, "{un:?} {co:?}");
    assert!(
        c.correction.mean_mm > 0.5 * un.mean_mm,
        "the compensation moves the request: {:?}",
        c.correction
    );

    // oracle without tracker noise: the hidden truth at the compensation's targets
    let nominal = Model::from_cell(&opts.nominal).expect("nominal model");
    let slices = printing_path(&out.report.validation.printing_path).expect("path");
    let guide = guide_schedule(&slices, out.report.validation.guide_start_mm);
    let targets: Vec<ToolTarget> =
        slices.iter().zip(&guide).map(|(s, q1)| ToolTarget::new(*q1, s.tool_pose)).collect();
    let tips: Vec<_> = slices.iter().map(|s| s.tip_in_tool_mm).collect();
    let path_opts = PathOptions { branch: Some(Branch(c.branch)), ..PathOptions::default() };
    let truth = path_accuracy(&out.truth, &out.identification.model, &nominal, &targets, &tips, &path_opts)
        .expect("oracle");
    let (tu, tc) = (truth.uncompensated(), truth.compensated());
    eprintln!("oracle: uncompensated {tu:?}, compensated {tc:?}");
    // the tracker (20 µm, 3σ) measures what the truth predicts, for both kinds of targets
    assert!((un.mean_mm - tu.mean_mm).abs() < 0.02, "{un:?} vs {tu:?}");
    assert!((co.mean_mm - tc.mean_mm).abs() < 0.02, "{co:?} vs {tc:?}");
    // the compensated run lands with the calibrated model's own error
    assert!((tc.mean_mm - truth.calibrated_model().mean_mm).abs() < 1e-6);

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).expect("json"))
            .expect("parse");
    assert_eq!(json["compensation"]["slices"], 300);
    assert!(json["compensation"]["compensated"]["mean_mm"].is_number());
    let summary = std::fs::read_to_string(dir.path().join("summary.md")).expect("summary");
    assert!(summary.contains("compensated targets (`vatcal compensate`)"), "{summary}");
}
