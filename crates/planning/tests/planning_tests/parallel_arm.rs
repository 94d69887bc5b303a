//! Closed-form IK of 6R arms with three parallel middle axes and a UR-type wrist
//! (`ParallelArm`, issue 31 item 5): FK(IK(pose)) = pose on the UR5e fixture, on every sign
//! combination of the structure angles with every free offset non-zero, and through the
//! planner's IK (`ModelIk`) on nominal and calibrated (perturbed) models.

use super::ik::{arm_joints, fixture_arm, fixture_model, max_wrapped_diff, pose_errors, regular_any};

use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::{JointVector, ParamId};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::sample_orientation;
use vatcal_planning::ik::{
    ArmGeometry, IkMethod, ModelIk, ParallelArm, RefineOptions, robot_base_frame, rotation_angle_between,
    tool_pose_for_tcp,
};
use vatcal_planning::numeric_ik::MultiStartOptions;

/// The UR5e fixture with the MDH rows `(alpha_deg, a_mm, theta_deg, d_mm)` and continuous
/// joints (no limits).
fn ur_like(rows: [(f64, f64, f64, f64); 6]) -> Model {
    fixture_arm("ur5e.toml", rows)
}

/// The UR5e's lengths with every sign combination of the structure (`alpha_1, alpha_4,
/// alpha_5` = ±90 deg, `alpha_2, alpha_3` = 0 or 180 deg: bits of `variant`), every free
/// offset non-zero (`a_1`, `d_2`, `d_3`, `a_4`) and theta offsets on every joint.
fn sign_variant(variant: u8) -> Model {
    let quarter = |bit: u8| if variant & (1 << bit) == 0 { 90.0 } else { -90.0 };
    let parallel = |bit: u8| if variant & (1 << bit) == 0 { 0.0 } else { 180.0 };
    ur_like([
        (0.0, 0.0, 10.0, 162.5),
        (quarter(0), 35.0, -20.0, 40.0),
        (parallel(1), -425.0, 30.0, -25.0),
        (parallel(2), -392.2, -40.0, 133.3),
        (quarter(3), 12.0, 50.0, 99.7),
        (quarter(4), 0.0, -60.0, 99.6),
    ])
}

/// A "calibrated" UR5e: every MDH parameter and the base perturbed by a small random error,
/// Hayati beta on the parallel rows, compliance on every joint.
fn perturbed_ur5e(seed: u64) -> Model {
    let mut m = fixture_model("ur5e.toml");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let deg = 1f64.to_radians();
    let mut nudge = |m: &mut Model, id: ParamId, amplitude: f64| {
        let v = m.param(id).expect("param") + rng.random_range(-amplitude..amplitude);
        m.set_param(id, v).expect("set");
    };
    for i in 1..=6u8 {
        if i > 1 {
            nudge(&mut m, ParamId::Alpha(i), 0.3 * deg);
            nudge(&mut m, ParamId::A(i), 0.5);
        }
        nudge(&mut m, ParamId::D(i), 0.5);
        nudge(&mut m, ParamId::ThetaOffset(i), 0.5 * deg);
        m.set_param(ParamId::Compliance(i), 2e-3).expect("compliance");
    }
    for i in [3u8, 4] {
        nudge(&mut m, ParamId::Beta(i), 0.2 * deg);
    }
    m
}

/// The raw closed form on `model` (exactly its nominal structure) at joints `q`: every
/// solution reproduces the pose by the model's FK to 1e-9 mm / 1e-12 rad, and the generating
/// joints are among them to 1e-9 rad. `Ok(number of solutions)`.
fn check_closed_form(model: &Model, q: &JointVector) -> Result<usize, String> {
    let arm = ParallelArm::from_model(model).map_err(|e| e.to_string())?;
    let target = model.chain(q).tool;
    let base = robot_base_frame(model, 0.0);
    let solutions = arm.solve(&base.inverse().compose(&target));
    let mut nearest = f64::INFINITY;
    for s in solutions.as_slice() {
        let qs = JointVector::from_slice(s).map_err(|e| e.to_string())?;
        let (dp, dr) = pose_errors(model, &qs, &target);
        if dp >= 1e-9 || dr >= 1e-12 {
            return Err(format!("{s:?} misses the pose by {dp} mm, {dr} rad"));
        }
        nearest = nearest.min(max_wrapped_diff(&qs, q));
    }
    if nearest >= 1e-9 {
        return Err(format!(
            "generating joints not among the {} solutions (nearest {nearest})",
            solutions.len()
        ));
    }
    Ok(solutions.len())
}

/// The planner's IK on `model` at joints `q`: the parallel closed form is used, every solution
/// reproduces the pose to 1e-9 mm / 1e-12 rad, no two are the same, and the generating joints
/// are among them (1e-8 rad). `Ok(number of solutions)`.
fn check_model_ik(model: &Model, q: &JointVector) -> Result<usize, String> {
    let ik = ModelIk::closed_form_first(model, RefineOptions::default(), MultiStartOptions::default())
        .map_err(|e| e.to_string())?;
    if ik.method() != IkMethod::ParallelClosedForm {
        return Err(format!("not the parallel closed form: {}", ik.method()));
    }
    let target = model.chain(q).tool;
    let solutions = ik.solve(&[], &target);
    for (k, s) in solutions.iter().enumerate() {
        let (dp, dr) = pose_errors(model, s, &target);
        if dp >= 1e-9 || dr >= 1e-12 {
            return Err(format!("{s:?} misses the pose by {dp} mm, {dr} rad"));
        }
        if solutions[..k].iter().any(|o| max_wrapped_diff(o, s) < 1e-6) {
            return Err(format!("{s:?} is there twice"));
        }
    }
    let nearest = solutions.iter().map(|s| max_wrapped_diff(s, q)).fold(f64::INFINITY, f64::min);
    if nearest >= 1e-8 {
        return Err(format!(
            "generating joints not among the {} solutions (nearest {nearest})",
            solutions.len()
        ));
    }
    Ok(solutions.len())
}

#[test]
fn ur5e_has_the_parallel_closed_form() {
    let ur5e = fixture_model("ur5e.toml");
    let arm = ParallelArm::from_model(&ur5e).expect("the UR5e has three parallel middle axes");
    assert_eq!(arm.first_joint, 1);
    assert_eq!(arm.upper_arm_mm, -425.0);
    assert_eq!(arm.forearm_mm, -392.2);
    assert_eq!(arm.lateral_offset_mm(), 133.3);
    let ik = ModelIk::closed_form_first(&ur5e, RefineOptions::default(), MultiStartOptions::default())
        .expect("ik");
    assert!(ik.is_closed_form());
    assert_eq!(ik.method(), IkMethod::ParallelClosedForm);
    assert!(ik.method().to_string().contains("three parallel middle axes"), "{}", ik.method());
    // the IK the planner used before: the numerical one, naming the spherical-wrist row
    let before =
        ModelIk::new(&ur5e, RefineOptions::default(), MultiStartOptions::default()).expect("numerical");
    assert!(before.method().to_string().contains("d_mm = 99.700"), "{}", before.method());
}

#[test]
fn other_structures_are_named_and_fall_back() {
    // the Meca500 has a spherical wrist, not parallel axes 2-3-4
    let table = fixture_model("meca500-table.toml");
    let err = ParallelArm::from_model(&table).expect_err("meca500").to_string();
    assert!(err.contains("joint row 4: alpha_deg = -90.000") && err.contains("parallel"), "{err}");
    let ik = ModelIk::closed_form_first(&table, RefineOptions::default(), MultiStartOptions::default())
        .expect("ik");
    assert_eq!(ik.method(), IkMethod::ClosedForm);
    // a UR5e whose last wrist axis misses the one before (a_5 = 20 mm): no closed form
    let mut rows = [
        (0.0, 0.0, 0.0, 162.5),
        (90.0, 0.0, 0.0, 0.0),
        (0.0, -425.0, 0.0, 0.0),
        (0.0, -392.2, 0.0, 133.3),
        (90.0, 0.0, 0.0, 99.7),
        (-90.0, 20.0, 0.0, 99.6),
    ];
    let err = ParallelArm::from_model(&ur_like(rows)).expect_err("offset").to_string();
    assert!(err.contains("joint row 6: a_mm = 20.000"), "{err}");
    let model = ur_like(rows);
    let ik = ModelIk::closed_form_first(&model, RefineOptions::default(), MultiStartOptions::default())
        .expect("ik");
    let method = ik.method().to_string();
    assert!(!ik.is_closed_form(), "{method}");
    assert!(method.contains("spherical wrist") && method.contains("joint row 6: a_mm = 20.000"), "{method}");
    // a twisted forearm (alpha_3 = 30 deg)
    rows[5].1 = 0.0;
    rows[3].0 = 30.0;
    let err = ParallelArm::from_model(&ur_like(rows)).expect_err("twisted").to_string();
    assert!(
        err.contains("joint row 4: alpha_deg = 30.000") && err.contains("joints 2, 3, 4 parallel"),
        "{err}"
    );
    // a large Hayati beta on a parallel row breaks the structure; a small one is refined
    let mut m = fixture_model("ur5e.toml");
    m.set_param(ParamId::Beta(3), 0.1).expect("beta");
    let err = ParallelArm::from_model(&m).expect_err("beta").to_string();
    assert!(err.contains("joint row 3: beta_deg"), "{err}");
    m.set_param(ParamId::Beta(3), 0.01).expect("beta");
    assert!(ParallelArm::from_model(&m).is_ok());
}

#[test]
fn every_sign_combination_reproduces_the_pose() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for variant in 0..32u8 {
        let model = sign_variant(variant);
        let mut checked = 0;
        while checked < 8 {
            let d: [f64; 6] = std::array::from_fn(|_| rng.random_range(-170.0..170.0f64));
            let q = JointVector::from_slice(&d.map(f64::to_radians)).expect("joints");
            if !regular_any(&model, &q) {
                continue;
            }
            checked += 1;
            let n = check_closed_form(&model, &q).unwrap_or_else(|e| panic!("variant {variant}: {e}"));
            assert!((2..=8).contains(&n), "variant {variant}: {n} solutions");
            check_model_ik(&model, &q).unwrap_or_else(|e| panic!("variant {variant} (ModelIk): {e}"));
        }
    }
}

#[test]
fn the_wrist_singularity_still_gives_exact_solutions() {
    // theta_5 = 0: axes 4 and 6 parallel, theta_6 is chosen (0) and the others follow
    let model = fixture_model("ur5e.toml");
    let arm = ParallelArm::from_model(&model).expect("arm");
    for q in [[0.3, -1.2, 1.0, -0.7, 0.0, 0.4], [-2.0, -0.5, -1.4, 2.2, std::f64::consts::PI, -1.0]] {
        let target = arm.forward(&q);
        let solutions = arm.solve(&target);
        assert!(!solutions.is_empty());
        for s in solutions.as_slice() {
            let f = arm.forward(s);
            assert!(
                (f.p - target.p).norm() < 1e-9 && rotation_angle_between(&f.r, &target.r) < 1e-12,
                "{s:?}"
            );
        }
    }
}

#[test]
fn the_closed_form_finds_every_numeric_solution_of_the_planner_targets() {
    // the planner's TCP targets on the UR5e fixture (3 positions x 3 TCPs x 4 orientations):
    // the closed form finds every solution the multi-start numerical IK finds
    let model = fixture_model("ur5e.toml");
    let closed = ModelIk::closed_form_first(&model, RefineOptions::default(), MultiStartOptions::default())
        .expect("ik");
    let numeric = ModelIk::numerical(&model, MultiStartOptions::default()).expect("numeric");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut n_closed, mut n_numeric) = (0, 0);
    for position in model.position_ids() {
        for tcp in model.tcp_ids() {
            let t = model.tcp(tcp).expect("tcp");
            let p = model.position(position).expect("position");
            for _ in 0..4 {
                let r = sample_orientation(&mut rng, &(-t), 60f64.to_radians());
                let target = tool_pose_for_tcp(&r, &t, &p);
                let a = closed.solve(&[], &target);
                let b = numeric.solve(&[], &target);
                for q in &a {
                    let (dp, dr) = pose_errors(&model, q, &target);
                    assert!(dp < 1e-9 && dr < 1e-12, "{dp} mm, {dr} rad");
                }
                for q in &b {
                    assert!(a.iter().any(|c| max_wrapped_diff(c, q) < 1e-7), "numeric solution {q:?} missed");
                }
                n_closed += a.len();
                n_numeric += b.len();
            }
        }
    }
    assert!(n_closed >= n_numeric, "{n_closed} vs {n_numeric}");
    assert_eq!(n_closed, 8 * 36, "every planner target of the fixture has eight solutions");
}

#[test]
fn a_spherical_arm_is_not_taken_for_a_parallel_one() {
    // the detection is by structure: the canonical arm keeps its own closed form
    let canonical = fixture_model("meca500-zaber.toml");
    assert!(ArmGeometry::from_model(&canonical).is_ok());
    assert!(ParallelArm::from_model(&canonical).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        rng_seed: proptest::test_runner::RngSeed::Fixed(31),
        ..ProptestConfig::default()
    })]

    /// The UR5e fixture: up to eight exact closed-form solutions, the generating joints among them,
    /// and the same through the planner's IK.
    #[test]
    fn ur5e_closed_form_matches_fk(q in arm_joints()) {
        let model = fixture_model("ur5e.toml");
        prop_assume!(regular_any(&model, &q));
        let n = check_closed_form(&model, &q).map_err(TestCaseError::fail)?;
        prop_assert!((2..=8).contains(&n));
        check_model_ik(&model, &q).map_err(TestCaseError::fail)?;
    }

    /// A calibrated UR5e (alphas, lengths, theta offsets, Hayati beta on the parallel rows,
    /// compliance): the closed form seeds the refinement on the model; every solution reaches
    /// the pose and the generating joints are among them.
    #[test]
    fn calibrated_ur5e_ik_matches_fk(q in arm_joints(), seed in 0u64..1000) {
        let model = perturbed_ur5e(seed);
        prop_assume!(regular_any(&model, &q));
        let n = check_model_ik(&model, &q).map_err(TestCaseError::fail)?;
        prop_assert!(n >= 2);
    }
}
