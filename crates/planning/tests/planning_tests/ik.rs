//! Inverse kinematics: closed form on the nominal model, refinement on a calibrated model.

use crate::common;

use proptest::prelude::*;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::sample_orientation;
use vatcal_planning::ik::{
    ArmGeometry, RefineOptions, ToolPoseIk, refine_tool_pose, robot_base_frame, rotation_angle_between,
    tool_pose_for_tcp,
};
use vatcal_planning::motion::SingularityMargins;

/// Random joints inside the limits (2 deg margin).
fn joints() -> impl Strategy<Value = JointVector> {
    (
        0.0..300.0f64,
        -173.0..173.0f64,
        -68.0..88.0f64,
        -133.0..68.0f64,
        -168.0..168.0f64,
        -113.0..113.0f64,
        -178.0..178.0f64,
    )
        .prop_map(|(q1, a, b, c, d, e, f)| JointVector::from_mm_deg(q1, [a, b, c, d, e, f]))
}

/// Keeps away from the three singularities, where the branches merge. Within a few degrees of
/// the wrist singularity a calibrated wrist (axes no longer exactly intersecting) has more than
/// the eight solutions of the spherical wrist, so "the original is among the 8 branches" only
/// holds outside that band (candidates keep 10° from it).
fn regular(model: &Model, q: &JointVector) -> bool {
    let margins = SingularityMargins {
        wrist_deg: 5.0,
        elbow_deg: 2.0,
        shoulder_mm: 5.0,
        ..SingularityMargins::default()
    };
    margins.clear(model, &model.chain(q))
}

fn max_diff(a: &JointVector, b: &JointVector) -> f64 {
    a.as_slice().iter().zip(b.as_slice()).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn pose_errors(model: &Model, q: &JointVector, target: &Frame) -> (f64, f64) {
    let tool = model.chain(q).tool;
    ((tool.p - target.p).norm(), rotation_angle_between(&tool.r, &target.r))
}

#[test]
fn closed_form_gives_eight_exact_branches_for_a_generic_pose() {
    let model = common::nominal();
    let arm = ArmGeometry::from_model(&model).expect("meca500 structure");
    let q = JointVector::from_mm_deg(120.0, [30.0, 20.0, -40.0, 50.0, 60.0, -70.0]);
    let target = model.chain(&q).tool;
    let base = robot_base_frame(&model, q[0]);
    let solutions = arm.solve(&base.inverse().compose(&target));
    assert_eq!(solutions.len(), 8);
    for s in solutions.as_slice() {
        let mut qs = q;
        qs[1..].copy_from_slice(s);
        let (dp, dr) = pose_errors(&model, &qs, &target);
        assert!(dp < 1e-9 && dr < 1e-12, "branch {s:?}: {dp} mm, {dr} rad");
    }
}

#[test]
fn unreachable_pose_has_no_solution() {
    let model = common::nominal();
    let ik = ToolPoseIk::new(&model, RefineOptions::default()).expect("ik");
    let far = Frame { r: nalgebra::Matrix3::identity(), p: nalgebra::Vector3::new(600.0, 0.0, 0.0) };
    assert!(ik.solve_at_guide(150.0, &far).is_empty());
}

#[test]
fn non_meca_structure_is_rejected() {
    let mut model = common::nominal();
    model.set_param(vatcal_core::ParamId::Alpha(4), 0.5).expect("set");
    assert!(ArmGeometry::from_model(&model).is_err());
}

#[test]
fn random_tcp_poses_are_solved_exactly() {
    let model = common::nominal();
    let ik = ToolPoseIk::new(&model, RefineOptions::default()).expect("ik");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut solved = 0;
    for position in model.position_ids() {
        for tcp in model.tcp_ids() {
            let t = model.tcp(tcp).expect("tcp");
            let p = model.position(position).expect("position");
            for _ in 0..20 {
                let r = sample_orientation(&mut rng, &(-t), 60f64.to_radians());
                let target = tool_pose_for_tcp(&r, &t, &p);
                for q in ik.solve(&[0.0, 100.0, 200.0, 300.0], &target) {
                    let (dp, dr) = pose_errors(&model, &q, &target);
                    assert!(dp < 1e-9 && dr < 1e-12, "{dp} mm, {dr} rad");
                    let tcp_err = (model.tcp_position(&q, tcp).expect("fk") - p).norm();
                    assert!(tcp_err < 1e-9, "TCP {tcp} misses position {position} by {tcp_err} mm");
                    solved += 1;
                }
            }
        }
    }
    assert!(solved > 500, "only {solved} solutions");
}

#[test]
fn refinement_reports_non_convergence() {
    let model = common::nominal();
    let q = JointVector::from_mm_deg(100.0, [0.0; 6]);
    let far = Frame { r: nalgebra::Matrix3::identity(), p: nalgebra::Vector3::new(800.0, 0.0, 300.0) };
    assert!(refine_tool_pose(&model, &q, &far, &RefineOptions::default()).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Nominal model: the closed form contains the original branch, and every branch it returns
    /// reproduces the pose.
    #[test]
    fn nominal_ik_finds_every_branch(q in joints()) {
        let model = common::nominal();
        prop_assume!(regular(&model, &q));
        let target = model.chain(&q).tool;
        let ik = ToolPoseIk::new(&model, RefineOptions::default()).expect("ik");
        let base = robot_base_frame(&model, q[0]);
        let seeds = ik.seeds(q[0], &base, &target);
        prop_assert!(seeds.len() >= 2);
        prop_assert!(seeds.iter().all(|s| !s.beyond_reach));
        let nearest = seeds.iter().map(|s| max_diff(&s.q, &q)).fold(f64::INFINITY, f64::min);
        prop_assert!(nearest < 1e-9, "original not among the closed-form solutions (nearest {nearest})");
        for s in ik.solve_at_guide(q[0], &target) {
            let (dp, dr) = pose_errors(&model, &s, &target);
            prop_assert!(dp < 1e-9 && dr < 1e-12, "{dp} mm, {dr} rad");
        }
    }

    /// Calibrated model (errors on every parameter, compliance, effects): the refined solutions
    /// contain the original joints and reproduce the pose.
    #[test]
    fn calibrated_ik_finds_every_branch(q in joints(), seed in 0u64..1000) {
        let model = common::perturbed(seed);
        prop_assume!(regular(&model, &q));
        let target = model.chain(&q).tool;
        let ik = ToolPoseIk::new(&model, RefineOptions::default()).expect("ik");
        let solutions = ik.solve_at_guide(q[0], &target);
        let nearest = solutions.iter().map(|s| max_diff(s, &q)).fold(f64::INFINITY, f64::min);
        prop_assert!(nearest < 1e-8, "original not found (nearest {nearest}, {} solutions)", solutions.len());
        for s in &solutions {
            let (dp, dr) = pose_errors(&model, s, &target);
            prop_assert!(dp < 1e-9 && dr < 1e-12, "{dp} mm, {dr} rad");
        }
    }
}
