//! Issue 13, item 4: the demo's 300-slice printing path, commanded with the targets of
//! `vatcal-compensation` (the library of `vatcal compensate`), lands on the (paper-like) true
//! cell with the calibrated model's error, and with uncompensated nominal targets with the
//! nominal error. The tracker's measurements are checked against the noise-free oracle
//! `vatcal_compensation::path_accuracy` on the hidden truth. The run is the default demo shared
//! with `paper_like.rs` and `discovery.rs` (`common::default_demo`).

use vatcal_campaign::validation::printing::{guide_schedule, printing_path};
use vatcal_compensation::{Branch, PathOptions, ToolTarget, path_accuracy};
use vatcal_kinematics::Model;

use crate::common;

#[test]
fn the_printing_path_lands_with_the_calibrated_error_when_compensated() {
    let demo = common::default_demo();
    let (opts, out) = (&demo.opts, &demo.out);
    let c = out.report.compensation.as_ref().expect("the canonical cell has the printing path");
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
    // outside the 34 parameters: seed 1 measured 1.12 → 0.30 mm)
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
    // the tracker measures what the truth predicts, for both kinds of targets: within its noise
    // (20 µm, 3σ) plus what the oracle leaves out — it evaluates the truth cold (no
    // time/temperature context), while the tracker measures the path on the warm cell (the
    // paper-like thermal growth, 23e-6/K over a ~1.5 K warm-up, ≈ 20 µm at the path's reach)
    // through its registration and SMR-nest errors (seed 1 measured +12 µm uncompensated,
    // +22 µm compensated)
    let tolerance_mm = 0.02 + 0.015;
    assert!((un.mean_mm - tu.mean_mm).abs() < tolerance_mm, "{un:?} vs {tu:?}");
    assert!((co.mean_mm - tc.mean_mm).abs() < tolerance_mm, "{co:?} vs {tc:?}");
    // the compensated run lands with the calibrated model's own error
    assert!((tc.mean_mm - truth.calibrated_model().mean_mm).abs() < 1e-6);

    let json = &demo.report_json;
    assert_eq!(json["compensation"]["slices"], 300);
    assert!(json["compensation"]["compensated"]["mean_mm"].is_number());
    let summary = &demo.summary_md;
    assert!(summary.contains("compensated targets (`vatcal compensate`)"), "{summary}");
}
