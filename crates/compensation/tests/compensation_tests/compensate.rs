//! Compensation on a calibrated model with compliance and effects: FK of the compensated
//! joints equals the request, paths keep their branch, bad rows are named.

use nalgebra::Vector3;
use proptest::prelude::*;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_compensation::{
    CompensationError, Compensator, PathOptions, PoseRequest, RowOutcome, SolveOptions, ToolTarget,
};
use vatcal_core::effects::{EffectSpec, ThermalDriver};
use vatcal_core::{CellFile, Frame, JointVector, MeasurementContext, ParamId};
use vatcal_kinematics::Model;
use vatcal_planning::ik::rotation_angle_between;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, random_joints};

pub(crate) fn nominal() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("cell");
    Model::from_cell(&cell).expect("model")
}

/// A "calibrated" model with every kind of error the compensation must honour: perturbed
/// geometry, compliance, and switched-on effects with non-zero values (joint cyclic error,
/// scale, backlash, guide angular and straightness errors, tool frame, thermal drift).
pub(crate) fn calibrated_with_effects() -> Model {
    let mut m = perturbed_truth(&nominal(), 11, &ErrorBudget::realistic());
    let specs = [
        EffectSpec::JointCyclic { joint: 3, harmonic: 1 },
        EffectSpec::JointScale { joint: 6 },
        EffectSpec::JointBacklash { joint: 5 },
        EffectSpec::GuideAngular { order: 2 },
        EffectSpec::GuideStraightness { order: 2 },
        EffectSpec::ToolFrame,
        EffectSpec::ThermalDrift { driver: ThermalDriver::Time },
    ];
    for (k, spec) in specs.into_iter().enumerate() {
        m.enable_effect(spec).expect("effect");
        for (j, id) in spec.params().into_iter().enumerate() {
            let v = match id {
                ParamId::Effect(_) if matches!(spec, EffectSpec::ThermalDrift { .. }) => 2e-8,
                ParamId::Effect(_) if matches!(spec, EffectSpec::GuideStraightness { .. }) => 0.03,
                ParamId::Effect(_) if matches!(spec, EffectSpec::ToolFrame) && j < 2 => 0.05,
                _ => 2e-4 * (1.0 + k as f64 * 0.3) * if j % 2 == 0 { 1.0 } else { -1.0 },
            };
            m.set_param(id, v).expect("set");
        }
    }
    m
}

pub(crate) fn context() -> MeasurementContext {
    MeasurementContext {
        dir: Some(vatcal_core::measurement::dirs_from_meca500_arm([1, -1, 1, -1, 1, -1])),
        time_s: Some(1800.0),
        temperature_c: None,
    }
}

/// Position [mm] and orientation [rad] error of the calibrated model at `q` for `req`.
pub(crate) fn fk_error(model: &Model, q: &JointVector, req: &PoseRequest) -> (f64, f64) {
    let chain = model.chain_full(q, &req.context, false, None);
    let target = req.tool_target(model, 0).expect("target");
    let tcp = model.tcp(req.tcp).expect("tcp");
    let p = chain.tool.transform_point(&tcp);
    ((p - Vector3::from(req.xyz_mm)).norm(), rotation_angle_between(&chain.tool.r, &target.tool.r))
}

/// Joint vectors away from the singularities (wrist |q6| >= 15 deg, elbow bent, shoulder).
pub(crate) fn reachable_joints(model: &Model, seed: u64) -> JointVector {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    loop {
        let q = random_joints(model, &mut rng, 0.1);
        let chain = model.chain(&q);
        let wrist = chain.theta[5].sin().abs() > 15f64.to_radians().sin();
        let r5 = model.row(5);
        let elbow = (chain.theta[3] + r5.d.atan2(r5.a)).sin().abs() > 15f64.to_radians().sin();
        let axis = chain.frames[2].z_axis();
        let w = chain.frames[6].p - chain.frames[2].p;
        let shoulder = (w - axis * w.dot(&axis)).norm() > 40.0;
        if wrist && elbow && shoulder {
            return q;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// FK of the calibrated model (compliance and every effect, with the row's context) at the
    /// compensated joints equals the request to 1e-6 mm and 1e-9 rad, from no seed at all.
    #[test]
    fn fk_of_compensated_joints_equals_the_request(seed in 0u64..1_000_000, tcp in 1u32..=3) {
        let cal = calibrated_with_effects();
        let nom = nominal();
        let comp = Compensator::new(&cal, &nom).expect("compensator");
        let q = reachable_joints(&cal, seed);
        let ctx = context();
        let tool = cal.chain_full(&q, &ctx, false, None).tool;
        let req = PoseRequest::from_tool_frame(&cal, tcp, q, &tool, ctx).expect("request");
        let c = comp.compensate_pose(&req, None, &SolveOptions::default());
        prop_assert!(c.is_ok(), "{:?}", c.err());
        let Ok(c) = c else { return Ok(()) };
        let (dp, dr) = fk_error(&cal, &c.q, &req);
        prop_assert!(dp < 1e-6 && dr < 1e-9, "FK error {dp:e} mm, {dr:e} rad");
        prop_assert!(c.position_residual_mm < 1e-6 && c.rotation_residual_rad < 1e-9);
        prop_assert!(cal.limit_violation(&c.q).is_none());
        prop_assert_eq!(c.q[0], q[0]);
    }
}

/// The corrected pose is FK_nominal of the compensated joints, and the Meca500 controller pose
/// is the simulator controller's own FK of those joints (same base frame, same joint zeros).
#[test]
fn corrected_pose_is_nominal_fk_and_the_controller_pose() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let q = reachable_joints(&cal, 3);
    let tool = cal.chain_full(&q, &context(), false, None).tool;
    let req = PoseRequest::from_tool_frame(&cal, 2, q, &tool, context()).expect("request");
    let c = comp.compensate_pose(&req, Some(&q), &SolveOptions::default()).expect("solve");
    let corrected = comp.corrected_pose(&c.q, 2, context()).expect("corrected");
    let nominal_tcp = nom.tcp_position_ctx(&c.q, &context(), 2).expect("fk");
    assert!((Vector3::from(corrected.world.xyz_mm) - nominal_tcp).norm() < 1e-9);
    // the corrected pose differs from the request by the calibration (~ mm), not by nothing
    let shift = (Vector3::from(corrected.world.xyz_mm) - Vector3::from(req.xyz_mm)).norm();
    assert!(shift > 0.05 && shift < 20.0, "corrected pose moved by {shift} mm");
    // round trip: the corrected request under the nominal model needs the same joints
    let back = Compensator::new(&nom, &nom)
        .expect("nominal")
        .compensate_pose(&corrected.world, Some(&c.q), &SolveOptions::default())
        .expect("nominal IK");
    assert!(
        back.q.as_slice().iter().zip(c.q.as_slice()).all(|(a, b)| (a - b).abs() < 1e-9),
        "{:?} vs {:?}",
        back.q,
        c.q
    );
    // the controller's own kinematics (drivers-meca500 simulator) at the joints
    let joints = corrected.controller_joints_deg.expect("a Meca500 arm");
    let pose = corrected.controller_pose.expect("a Meca500 arm");
    let sim = vatcal_drivers_meca500::sim::forward_kinematics(&joints);
    let expect = vatcal_drivers_meca500::sim::to_xyzabc(&sim);
    for (a, b) in pose.iter().zip(expect) {
        assert!((a - b).abs() < 1e-7, "{pose:?} vs {expect:?}");
    }
}

/// A dense path: tool poses along a joint-space line of the calibrated model.
fn path_targets(model: &Model, a: &JointVector, b: &JointVector, n: usize) -> Vec<ToolTarget> {
    (0..n)
        .map(|k| {
            let t = k as f64 / (n - 1) as f64;
            let q = JointVector::new::<7>(std::array::from_fn(|i| a[i] + t * (b[i] - a[i])));
            ToolTarget::new(q[0], model.chain(&q).tool)
        })
        .collect()
}

#[test]
fn a_path_keeps_its_branch_and_moves_continuously() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let a = JointVector::from_mm_deg(60.0, [-20.0, 10.0, -20.0, 30.0, 40.0, -50.0]);
    let b = JointVector::from_mm_deg(200.0, [35.0, 30.0, -5.0, -40.0, 70.0, 120.0]);
    let targets = path_targets(&cal, &a, &b, 400);
    let opts = PathOptions { start: Some(a), ..PathOptions::default() };
    let result = comp.compensate_path(&targets, &opts).expect("path");
    let solved: Vec<_> = result.solved().map(|(_, c)| *c).collect();
    assert_eq!(solved.len(), 400);
    let branch = result.branch.expect("branch");
    assert!(solved.iter().all(|c| c.branch == branch));
    for w in solved.windows(2) {
        let step = (1..7).map(|k| (w[1].q[k] - w[0].q[k]).abs()).fold(0.0, f64::max);
        assert!(step < 2f64.to_radians(), "joint step {} deg", step.to_degrees());
    }
    // the path's joints are those of the joint line (same branch as the start)
    let end = solved.last().expect("end").q;
    assert!(end.as_slice().iter().zip(b.as_slice()).all(|(x, y)| (x - y).abs() < 1e-8), "{end:?}");
    for (t, c) in targets.iter().zip(&solved) {
        let tool = cal.chain_full(&c.q, &t.context, false, None).tool;
        assert!((tool.p - t.tool.p).norm() < 1e-6 && rotation_angle_between(&tool.r, &t.tool.r) < 1e-9);
    }
}

#[test]
fn an_unreachable_row_is_named_or_skipped() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let a = JointVector::from_mm_deg(100.0, [0.0, 10.0, -20.0, 10.0, 40.0, 10.0]);
    let b = JointVector::from_mm_deg(110.0, [10.0, 15.0, -25.0, 15.0, 45.0, 15.0]);
    let mut targets = path_targets(&cal, &a, &b, 10);
    targets[6].tool.p += Vector3::new(0.0, 2000.0, 0.0);
    let err = comp.compensate_path(&targets, &PathOptions::default()).expect_err("unreachable");
    assert!(matches!(err, CompensationError::Unreachable { row: 6, .. }), "{err}");
    assert!(err.to_string().starts_with("row 6:"), "{err}");
    let skip = PathOptions { skip_unreachable: true, ..PathOptions::default() };
    let result = comp.compensate_path(&targets, &skip).expect("skip mode");
    let skipped: Vec<usize> = result.skipped().map(|s| s.row).collect();
    assert_eq!(skipped, vec![6]);
    assert_eq!(result.solved().count(), 9);
    assert!(matches!(result.rows[7], RowOutcome::Solved(_)));
}

#[test]
fn joint_jumps_and_limits_are_named() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let q = JointVector::from_mm_deg(100.0, [0.0, 10.0, -20.0, 10.0, 40.0, 10.0]);
    let tool = cal.chain(&q).tool;
    // the same point, the tool turned about its own z axis: only the last joint moves
    let turned = |deg: f64| {
        let r = tool.r * vatcal_core::frame::rot_z(deg.to_radians());
        ToolTarget::new(100.0, Frame { r, p: tool.p })
    };
    let jump = [turned(0.0), turned(1.0), turned(60.0)];
    let err = comp.compensate_path(&jump, &PathOptions::default()).expect_err("jump");
    assert!(matches!(err, CompensationError::JointJump { row: 2, joint: 7, .. }), "{err}");
    // keep turning by 10 deg per row: q7 (Meca500 J6, +-180 deg in the cell file) runs out
    let spin: Vec<_> = (0..40).map(|k| turned(10.0 * k as f64)).collect();
    let err = comp.compensate_path(&spin, &PathOptions::default()).expect_err("limit");
    match err {
        CompensationError::JointLimit { row, joint: 7, value, max, .. } => {
            assert!(value > max && (16..=19).contains(&row), "row {row}: {value} > {max}");
        }
        e => panic!("expected a joint-limit error, got {e}"),
    }
}

#[test]
fn bad_requests_are_errors() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let good = PoseRequest::on_guide(1, 100.0, [0.0, 0.0, 100.0], [180.0, 0.0, 0.0]);
    let unknown = PoseRequest { tcp: 9, ..good };
    let err = comp.compensate_requests(&[good, unknown], &PathOptions::default()).expect_err("tcp");
    assert!(err.to_string().contains("unknown TCP id 9"), "{err}");
    let nan = PoseRequest { xyz_mm: [f64::NAN, 0.0, 0.0], ..good };
    let err = comp.compensate_requests(&[nan], &PathOptions::default()).expect_err("nan");
    assert!(matches!(err, CompensationError::NonFinite { row: 0, field: "x", .. }), "{err}");
}
