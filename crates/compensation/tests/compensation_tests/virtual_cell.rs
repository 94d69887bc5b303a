//! Proof on the virtual cell (issue 13, item 4): the demo's 300-slice printing path commanded
//! with compensated targets lands with the calibrated model's error, and commanded with
//! uncompensated (nominal) targets with the nominal error.
//!
//! A hidden truth (`vatcal_sim::truth::perturbed_truth`) is identified from 40 synthetic probe
//! measurements with 2 µm noise (the paper's 34 parameters), exactly as the identification
//! tests do; the printing path and its reference joints (guide schedule, IK branch) come from
//! `vatcal_campaign::validation::printing`, as in the demo.

use vatcal_campaign::validation::printing::{
    PrintingJointRules, command_printing_joints, plan_printing_joints,
};
use vatcal_campaign::validation::{PrintingPathOptions, printing_path};
use vatcal_compensation::{PathOptions, ToolTarget, path_accuracy};
use vatcal_core::{CellFile, ParamSet};
use vatcal_identification::{IdentifyOptions, identify};
use vatcal_kinematics::Model;
use vatcal_planning::CellGeometry;
use vatcal_planning::collision::CollisionChecker;
use vatcal_planning::motion::{JointBounds, SingularityMargins};
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
};

const CELL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");

#[test]
fn printing_path_lands_with_the_calibrated_error_when_compensated() {
    let cell = CellFile::load(CELL).expect("cell");
    let nominal = Model::from_cell(&cell).expect("model");
    let truth = perturbed_truth(&nominal, 5, &ErrorBudget::realistic());
    let starts = probe_start_poses(&nominal, 40, 105);
    let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.002 }, 205);
    let fit = identify(&nominal, &probe, &ParamSet::paper34(), &IdentifyOptions::default()).expect("fit");
    let calibrated = fit.model;

    // the demo's printing path and reference joints (guide schedule and branch, nominal model)
    let slices = printing_path(&PrintingPathOptions::default()).expect("path");
    assert_eq!(slices.len(), 300);
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let checker = CollisionChecker::new(&nominal, &geometry, 2.0).expect("checker");
    let bounds = JointBounds::new(&nominal, 5.0, 5.0).expect("bounds");
    let rules = PrintingJointRules {
        bounds: &bounds,
        singularity: SingularityMargins::default(),
        checker: &checker,
        max_joint_step_rad: 10f64.to_radians(),
        guide_candidates: 11,
    };
    let reference = plan_printing_joints(&nominal, &slices, &rules).expect("reference joints");

    let targets: Vec<ToolTarget> =
        slices.iter().zip(&reference).map(|(s, q)| ToolTarget::new(q[0], s.tool_pose)).collect();
    let tips: Vec<_> = slices.iter().map(|s| s.tip_in_tool_mm).collect();
    let opts = PathOptions { start: Some(reference[0]), ..PathOptions::default() };
    let acc = path_accuracy(&truth, &calibrated, &nominal, &targets, &tips, &opts).expect("accuracy");
    let (c, n, m) = (acc.compensated(), acc.uncompensated(), acc.calibrated_model());
    eprintln!(
        "printing path, part end: uncompensated mean {:.4} max {:.4} mm | compensated mean {:.4} max {:.4} mm | \
         calibrated model's own error mean {:.4} max {:.4} mm | prediction residual {:.2e} mm",
        n.mean_mm, n.max_mm, c.mean_mm, c.max_mm, m.mean_mm, m.max_mm, acc.max_prediction_residual_mm
    );

    // the calibrated model predicts the request at the compensated joints (solver residual)
    assert!(acc.max_prediction_residual_mm < 1e-6, "{:e}", acc.max_prediction_residual_mm);
    // so the true error IS the calibrated model's own error, per slice, to that residual
    // (triangle inequality: | |t - w| - |t - m| | <= |m - w|)
    for (k, (a, b)) in acc.compensated_mm.iter().zip(&acc.calibrated_model_mm).enumerate() {
        assert!((a - b).abs() <= acc.max_prediction_residual_mm + 1e-9, "slice {k}: {a} vs {b}");
    }
    // compensation removes most of the nominal error (identification reaches ~0.01-0.03 mm on
    // validation poses with this noise; the nominal cell is off by ~1 mm)
    assert!(n.mean_mm > 0.3, "nominal error {} mm is implausibly small", n.mean_mm);
    assert!(c.mean_mm < 0.05, "compensated mean error {} mm", c.mean_mm);
    assert!(c.mean_mm * 10.0 < n.mean_mm, "compensated {} vs nominal {} mm", c.mean_mm, n.mean_mm);

    // the same joints as the demo's "calibrated" run (IK of the calibrated model seeded by the
    // reference joints), and the demo's "nominal" run
    let demo_cal = command_printing_joints(&calibrated, &slices, &reference).expect("demo calibrated");
    let demo_nom = command_printing_joints(&nominal, &slices, &reference).expect("demo nominal");
    let gap = |a: &[vatcal_core::JointVector], b: &[vatcal_core::JointVector]| {
        a.iter()
            .zip(b)
            .flat_map(|(x, y)| x.as_slice().iter().zip(y.as_slice()).map(|(u, v)| (u - v).abs()))
            .fold(0.0, f64::max)
    };
    assert!(gap(&acc.compensated_joints, &demo_cal) < 1e-8, "{}", gap(&acc.compensated_joints, &demo_cal));
    assert!(
        gap(&acc.uncompensated_joints, &demo_nom) < 1e-8,
        "{}",
        gap(&acc.uncompensated_joints, &demo_nom)
    );
    // one branch, continuous joints along the whole path
    let steps = acc
        .compensated_joints
        .windows(2)
        .map(|w| (1..7).map(|k| (w[1][k] - w[0][k]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(steps < 1f64.to_radians(), "largest joint step {} deg", steps.to_degrees());
}
