//! Compensation on chains other than the canonical cell (issue 12): the UR5e-class arm and the
//! Meca500 on a table (six joints, the request gives no joint), with a perturbed "calibrated"
//! model (geometry and compliance): FK of the targets equals the request, paths stay
//! continuous on one branch class, unreachable rows are named, corrected poses round-trip, and
//! chains the pose cannot determine are clear errors.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_compensation::{
    Branch, CompensationError, Compensator, JointSplit, PathOptions, PoseRequest, RowOutcome, SolveOptions,
    ToolTarget,
};
use vatcal_core::{CellFile, JointVector, MeasurementContext};
use vatcal_kinematics::Model;
use vatcal_planning::ik::rotation_angle_between;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, random_joints};

fn cell(name: &str) -> CellFile {
    CellFile::load(format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect("cell")
}

fn model(name: &str) -> Model {
    Model::from_cell(&cell(name)).expect("model")
}

/// The nominal model of a fixture and a perturbed "calibrated" one (geometry, base, TCPs,
/// compliance on every revolute joint).
fn models(name: &str, seed: u64) -> (Model, Model) {
    let nominal = model(name);
    let calibrated = perturbed_truth(&nominal, seed, &ErrorBudget::realistic());
    (nominal, calibrated)
}

/// Position [mm] and orientation [rad] error of `model`'s FK at `q` for `req`.
fn fk_error(model: &Model, q: &JointVector, req: &PoseRequest) -> (f64, f64) {
    let chain = model.chain_full(q, &req.context, false, None);
    let target = req.tool_target(model, 0).expect("target");
    let p = chain.tool.transform_point(&model.tcp(req.tcp).expect("tcp"));
    ((p - Vector3::from(req.xyz_mm)).norm(), rotation_angle_between(&chain.tool.r, &target.tool.r))
}

/// Random joints away from singular configurations (|det J| of the 6×6 tool Jacobian, scaled
/// by the arm's size, above a threshold).
fn regular_joints(m: &Model, rng: &mut ChaCha8Rng) -> JointVector {
    let split = JointSplit::of(m).expect("split");
    loop {
        let q = random_joints(m, rng, 0.1);
        let det = split.jacobian(&m.chain(&q)).determinant();
        if det.abs() > 1e5 {
            return q;
        }
    }
}

#[test]
fn six_joint_arms_give_no_joint_and_the_canonical_cell_gives_its_guide() {
    for name in ["ur5e.toml", "meca500-table.toml"] {
        let split = JointSplit::of(&model(name)).expect("split");
        assert_eq!(split.given_joints().count(), 0, "{name}");
        assert_eq!(split.solved_joints(), [1, 2, 3, 4, 5, 6]);
    }
    let split = JointSplit::of(&model("meca500-zaber.toml")).expect("split");
    assert_eq!(split.given_joints().collect::<Vec<_>>(), vec![1]);
    assert_eq!(split.solved_joints(), [2, 3, 4, 5, 6, 7]);
}

/// FK of the calibrated model at the compensated joints equals the request to 1e-6 mm and
/// 1e-9 rad, from no seed (the first-row rule: every IK solution, the one farthest from the
/// limits), on both six-joint fixtures and every TCP.
#[test]
fn fk_of_compensated_joints_equals_the_request_on_six_joint_arms() {
    for (name, seed) in [("ur5e.toml", 3), ("meca500-table.toml", 5)] {
        let (nom, cal) = models(name, seed);
        let comp = Compensator::new(&cal, &nom).expect("compensator");
        assert!(!comp.is_closed_form());
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for k in 0..8 {
            let q = regular_joints(&cal, &mut rng);
            let tcp = cal.tcp_ids()[k % cal.tcp_ids().len()];
            let tool = cal.chain(&q).tool;
            let req = PoseRequest::from_tool_frame(
                &cal,
                tcp,
                JointVector::zeros(6),
                &tool,
                MeasurementContext::default(),
            )
            .expect("request");
            let c = comp
                .compensate_pose(&req, None, &SolveOptions::default())
                .unwrap_or_else(|e| panic!("{name} pose {k} at {q:?}: {e}"));
            let (dp, dr) = fk_error(&cal, &c.q, &req);
            assert!(dp < 1e-6 && dr < 1e-9, "{name} pose {k}: FK error {dp:e} mm, {dr:e} rad");
            assert!(c.position_residual_mm < 1e-6 && c.rotation_residual_rad < 1e-9);
            assert!(cal.limit_violation(&c.q).is_none());
            assert!(c.branch.is_determinant_class(), "{}", c.branch);
            // the compensation is not the identity: the nominal model misses the request
            let (miss, _) = fk_error(&nom, &c.q, &req);
            assert!(miss > 0.05, "{name}: the calibrated model differs from the nominal by {miss} mm only");
        }
    }
}

/// A 50-row path along a smooth joint-space curve (tool poses of the calibrated model): every
/// row solved on one branch class, joints continuous (no row moves a joint by more than the
/// path's own largest step plus a margin), FK equal to the requests.
#[test]
fn a_path_of_50_rows_keeps_its_branch_and_moves_continuously() {
    let cases = [
        ("ur5e.toml", [20.0, -100.0, 80.0, -60.0, 70.0, 10.0], [60.0, -70.0, 100.0, -100.0, 100.0, 60.0]),
        (
            "meca500-table.toml",
            [-20.0, 10.0, -20.0, 30.0, 40.0, -50.0],
            [35.0, 30.0, -5.0, -40.0, 70.0, 120.0],
        ),
    ];
    for (name, a_deg, b_deg) in cases {
        let (nom, cal) = models(name, 9);
        let comp = Compensator::new(&cal, &nom).expect("compensator");
        let a: Vec<f64> = a_deg.iter().map(|d: &f64| d.to_radians()).collect();
        let b: Vec<f64> = b_deg.iter().map(|d: &f64| d.to_radians()).collect();
        let path_q: Vec<JointVector> = (0..50)
            .map(|k| {
                let t = k as f64 / 49.0;
                let s = 0.5 - 0.5 * (std::f64::consts::PI * t).cos();
                JointVector::from_slice(&(0..6).map(|i| a[i] + s * (b[i] - a[i])).collect::<Vec<_>>())
                    .expect("q")
            })
            .collect();
        let requests: Vec<PoseRequest> = path_q
            .iter()
            .map(|q| {
                PoseRequest::from_tool_frame(
                    &cal,
                    1,
                    JointVector::zeros(6),
                    &cal.chain(q).tool,
                    MeasurementContext::default(),
                )
                .expect("request")
            })
            .collect();
        let result = comp.compensate_requests(&requests, &PathOptions::default()).expect("path");
        assert_eq!(result.solved().count(), 50, "{name}");
        let branch = result.branch.expect("branch");
        let largest_path_step = path_q
            .windows(2)
            .map(|w| (0..6).map(|i| (w[1][i] - w[0][i]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        let mut prev: Option<JointVector> = None;
        for ((_, c), req) in result.solved().zip(&requests) {
            assert_eq!(c.branch, branch, "{name}: one branch class along the path");
            let (dp, dr) = fk_error(&cal, &c.q, req);
            assert!(dp < 1e-6 && dr < 1e-9, "{name}: {dp:e} mm {dr:e} rad");
            if let Some(p) = prev {
                let step = (0..6).map(|i| (c.q[i] - p[i]).abs()).fold(0.0, f64::max);
                assert!(step < 3.0 * largest_path_step + 1e-3, "{name}: a joint jumps by {step} rad");
            }
            prev = Some(c.q);
        }
    }
}

/// A row far out of reach is named (0-based row 20), or skipped and reported in skip mode.
#[test]
fn an_unreachable_row_is_named() {
    let (nom, cal) = models("ur5e.toml", 2);
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let a = JointVector::new([0.3, -1.2, 1.1, -1.4, 1.5, 0.2]);
    let mut requests: Vec<PoseRequest> = (0..30)
        .map(|k| {
            let mut q = a;
            q[0] += 0.01 * k as f64;
            PoseRequest::from_tool_frame(
                &cal,
                1,
                JointVector::zeros(6),
                &cal.chain(&q).tool,
                MeasurementContext::default(),
            )
            .expect("request")
        })
        .collect();
    requests[20].xyz_mm[0] += 3000.0;
    let err = comp.compensate_requests(&requests, &PathOptions::default()).expect_err("unreachable");
    assert!(matches!(err, CompensationError::Unreachable { row: 20, .. }), "{err}");
    let skip = PathOptions { skip_unreachable: true, ..PathOptions::default() };
    let result = comp.compensate_requests(&requests, &skip).expect("skip mode");
    assert_eq!(result.solved().count(), 29);
    let skipped: Vec<usize> = result.skipped().map(|s| s.row).collect();
    assert_eq!(skipped, vec![20]);
    assert!(matches!(result.rows[20], RowOutcome::Skipped(_)));
}

/// `--emit poses` round trip: the corrected pose is FK_nominal of the targets, and the
/// nominal IK of that pose (what the controller does with it) gives joints at which the
/// calibrated FK equals the request. On the Meca500 on a table, the controller's `MovePose`
/// and `MoveJoints` are the Meca500 controller's own kinematics of the targets; the UR5e is not
/// a Meca500 arm.
#[test]
fn corrected_poses_round_trip_through_the_nominal_controller() {
    for (name, meca) in [("ur5e.toml", false), ("meca500-table.toml", true)] {
        let (nom, cal) = models(name, 4);
        let comp = Compensator::new(&cal, &nom).expect("compensator");
        assert_eq!(comp.meca500_arm().is_some(), meca, "{name}");
        let nominal_comp = Compensator::new(&nom, &nom).expect("nominal");
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        for _ in 0..4 {
            let q = regular_joints(&cal, &mut rng);
            let req = PoseRequest::from_tool_frame(
                &cal,
                2,
                JointVector::zeros(6),
                &cal.chain(&q).tool,
                MeasurementContext::default(),
            )
            .expect("request");
            let c = comp.compensate_pose(&req, Some(&q), &SolveOptions::default()).expect("solve");
            let corrected = comp.corrected_pose(&c.q, 2, MeasurementContext::default()).expect("corrected");
            let nominal_tcp = nom.tcp_position(&c.q, 2).expect("fk");
            assert!((Vector3::from(corrected.world.xyz_mm) - nominal_tcp).norm() < 1e-9);
            let back = nominal_comp
                .compensate_pose(&corrected.world, Some(&c.q), &SolveOptions::default())
                .expect("nominal IK of the corrected pose");
            let (dp, dr) = fk_error(&cal, &back.q, &req);
            assert!(dp < 1e-6 && dr < 1e-9, "{name}: round trip {dp:e} mm {dr:e} rad");
            match (corrected.controller_joints_deg, corrected.controller_pose) {
                (Some(j), Some(p)) => {
                    assert!(meca);
                    let expect = vatcal_drivers_meca500::sim::to_xyzabc(
                        &vatcal_drivers_meca500::sim::forward_kinematics(&j),
                    );
                    assert!(p.iter().zip(expect).all(|(a, b)| (a - b).abs() < 1e-7), "{p:?} vs {expect:?}");
                    assert!(j.iter().zip(c.q.as_slice()).all(|(a, b)| (a - b.to_degrees()).abs() < 1e-9));
                }
                (None, None) => assert!(!meca),
                other => panic!("{other:?}"),
            }
        }
    }
}

/// Chains a pose does not determine: fewer than six joints, and more than six whose prismatic
/// joints do not leave six. A nominal model of another chain is refused too.
#[test]
fn chains_the_pose_cannot_determine_are_errors() {
    let mut five = cell("ur5e.toml");
    five.joints.pop();
    five.inertials.links.retain(|l| l.frame <= 5);
    five.inertials.tool.frame = 5;
    let five = Model::from_cell(&five).expect("five-joint model");
    let err = JointSplit::of(&five).expect_err("five joints");
    assert!(err.to_string().contains("5 joints") && err.to_string().contains("at least 6"), "{err}");
    let err = Compensator::new(&five, &five).expect_err("five joints");
    assert!(matches!(err, CompensationError::UnsupportedChain { .. }), "{err}");
    // seven revolute joints (a redundant arm): no prismatic joint to give
    let mut seven = cell("ur5e.toml");
    let mut extra = seven.joints[5].clone();
    extra.index = 7;
    extra.d_mm = 50.0;
    seven.joints.push(extra);
    seven.inertials.tool.frame = 7;
    let seven = Model::from_cell(&seven).expect("seven-joint model");
    let err = JointSplit::of(&seven).expect_err("7R");
    assert!(err.to_string().contains("0 prismatic"), "{err}");
    let (ur, _) = models("ur5e.toml", 1);
    let meca = model("meca500-table.toml");
    assert!(Compensator::new(&ur, &meca).is_ok(), "same joint kinds (RRRRRR)");
    let canonical = model("meca500-zaber.toml");
    let err = Compensator::new(&ur, &canonical).expect_err("another chain");
    assert!(err.to_string().contains("another chain"), "{err}");
}

/// A chain of more than six joints: the canonical cell with a second prismatic axis (a lift
/// along the carriage z axis) — eight joints, the request gives both prismatic joints, the
/// numerical IK solves the six arm joints.
#[test]
fn a_chain_with_two_external_axes_gives_both() {
    let mut c = cell("meca500-zaber.toml");
    let mut lift = c.joints[0].clone();
    lift.index = 2;
    lift.name = "lift".into();
    lift.alpha_deg = 0.0;
    lift.a_mm = 0.0;
    lift.beta_deg = 0.0;
    lift.theta_deg = 0.0;
    lift.d_mm = 0.0;
    lift.q_min = Some(0.0);
    lift.q_max = Some(100.0);
    c.joints.insert(1, lift);
    for (k, j) in c.joints.iter_mut().enumerate() {
        j.index = (k + 1) as u8;
    }
    for l in &mut c.inertials.links {
        if l.frame >= 2 {
            l.frame += 1;
        }
    }
    c.inertials.tool.frame = 8;
    c.format = "serial-robot-cell".into();
    c.version = 2;
    let nom = Model::from_cell(&c).expect("eight-joint model");
    let cal = perturbed_truth(&nom, 6, &ErrorBudget::realistic());
    let split = JointSplit::of(&cal).expect("split");
    assert_eq!(split.given_joints().collect::<Vec<_>>(), vec![1, 2]);
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    assert!(!comp.is_closed_form());
    let q = JointVector::new([120.0, 40.0, 0.3, 0.2, -0.5, 0.6, 0.8, -0.4]);
    let target = ToolTarget::with_given(q, cal.chain(&q).tool);
    let result = comp.compensate_path(&[target], &PathOptions { start: Some(q), ..PathOptions::default() });
    let result = result.expect("solved");
    let (_, c) = result.solved().next().expect("one row");
    assert_eq!((c.q[0], c.q[1]), (120.0, 40.0), "the given joints stay as requested");
    let tool = cal.chain(&c.q).tool;
    assert!((tool.p - target.tool.p).norm() < 1e-6 && rotation_angle_between(&tool.r, &target.tool.r) < 1e-9);
    // from no seed: the multi-start numerical IK finds a solution
    let result = comp.compensate_path(&[target], &PathOptions::default()).expect("no seed");
    let (_, c) = result.solved().next().expect("one row");
    let tool = cal.chain(&c.q).tool;
    assert!((tool.p - target.tool.p).norm() < 1e-6 && rotation_angle_between(&tool.r, &target.tool.r) < 1e-9);
    assert!(matches!(c.branch, Branch::DET_POSITIVE | Branch::DET_NEGATIVE));
}

/// The row's context reaches the model on a six-joint arm: a calibrated UR5e with backlash on
/// joint 3 and a time-driven thermal drift; the targets put the TCP on the request under the
/// model *with* the row's `dir` and `time_s`, and the same joints without the context miss it.
#[test]
fn context_columns_pass_to_the_model_on_a_six_joint_arm() {
    use vatcal_core::ParamId;
    use vatcal_core::effects::{EffectSpec, ThermalDriver};
    let (nom, mut cal) = models("ur5e.toml", 8);
    for spec in
        [EffectSpec::JointBacklash { joint: 3 }, EffectSpec::ThermalDrift { driver: ThermalDriver::Time }]
    {
        cal.enable_effect(spec).expect("effect");
        for id in spec.params() {
            let v = match (spec, id) {
                (EffectSpec::ThermalDrift { .. }, ParamId::Effect(_)) => 2e-8,
                _ => 5e-4,
            };
            cal.set_param(id, v).expect("set");
        }
    }
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let context = MeasurementContext {
        dir: Some([1, -1, 1, -1, 1, -1, 0, 0, 0, 0, 0, 0]),
        time_s: Some(3600.0),
        temperature_c: None,
    };
    let q = JointVector::new([0.3, -1.2, 1.1, -1.4, 1.2, 0.2]);
    let tool = cal.chain_full(&q, &context, false, None).tool;
    let req = PoseRequest::from_tool_frame(&cal, 1, JointVector::zeros(6), &tool, context).expect("request");
    let c = comp.compensate_pose(&req, None, &SolveOptions::default()).expect("solve");
    let (dp, dr) = fk_error(&cal, &c.q, &req);
    assert!(dp < 1e-6 && dr < 1e-9, "with context: {dp:e} mm, {dr:e} rad");
    let without = PoseRequest { context: MeasurementContext::default(), ..req };
    let (miss, _) = fk_error(&cal, &c.q, &without);
    assert!(miss > 1e-3, "the context changes the prediction by only {miss} mm");
}
