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

pub(super) fn pose_errors(model: &Model, q: &JointVector, target: &Frame) -> (f64, f64) {
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
    // a fixed seed: the same cases on every run (a random seed drew a near-singular case that
    // fails, see `known_failure_near_the_wrist_singularity_on_a_perturbed_model`)
    #![proptest_config(ProptestConfig {
        cases: 128,
        rng_seed: proptest::test_runner::RngSeed::Fixed(12),
        ..ProptestConfig::default()
    })]

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

// ---------------------------------------------------------------------------------------------
// Any 6R arm with a spherical wrist (issue 12): the closed form outside the canonical cell.

/// A model of the canonical fixture's sibling `fixtures/<name>`.
pub(super) fn fixture_model(name: &str) -> Model {
    let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    Model::from_cell(&vatcal_core::CellFile::load(&path).expect("fixture")).expect("model")
}

/// A 6R arm standing on the table of `fixtures/meca500-table.toml`, with the MDH rows
/// `(alpha_deg, a_mm, theta_deg, d_mm)` and continuous joints (no limits; the IK wraps into
/// (-180, 180] deg).
fn table_arm(rows: [(f64, f64, f64, f64); 6]) -> Model {
    fixture_arm("meca500-table.toml", rows)
}

/// The six-joint fixture `fixtures/<name>` with the MDH rows `(alpha_deg, a_mm, theta_deg,
/// d_mm)` and continuous joints (no limits).
pub(super) fn fixture_arm(name: &str, rows: [(f64, f64, f64, f64); 6]) -> Model {
    let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut cell = vatcal_core::CellFile::load(&path).expect("fixture");
    for (row, (alpha, a, theta, d)) in cell.joints.iter_mut().zip(rows) {
        row.alpha_deg = alpha;
        row.a_mm = a;
        row.theta_deg = theta;
        row.d_mm = d;
        row.q_min = None;
        row.q_max = None;
    }
    Model::from_cell(&cell).expect("arm model")
}

/// KUKA KR 16, standard DH as published for it (FreeCAD wiki "Robot 6-Axis", KUKA example:
/// d = (675, 0, 0, -670, 0, -158) mm, a = (260, 680, 0, 0, 0, 0) mm, alpha = (-90, 0, 90, -90,
/// 90, 180) deg, theta_2 offset -90 deg; the KR 16's elbow offset a_3 = -35 mm as listed on
/// javakuka.org), converted row by row to MDH (MDH row i takes alpha_{i-1}, a_{i-1} of DH row
/// i-1; the last DH row's 180 deg flip of the flange frame is left out). a_1 = 260 mm != 0.
fn kuka_kr16() -> Model {
    table_arm([
        (0.0, 0.0, 0.0, 675.0),
        (-90.0, 260.0, -90.0, 0.0),
        (0.0, 680.0, 0.0, 0.0),
        (90.0, -35.0, 0.0, -670.0),
        (-90.0, 0.0, 0.0, 0.0),
        (90.0, 0.0, 0.0, -158.0),
    ])
}

/// The KR 16's lengths with every sign combination the closed form supports (`alpha_1, alpha_3,
/// alpha_4, alpha_5` = ±90 deg, `alpha_2` = 0 or 180 deg: bits of `variant`), a sideways
/// shoulder offset split over `d_2` and `d_3` (PUMA-like) and theta offsets on every joint.
fn sign_variant(variant: u8) -> Model {
    let s = |bit: u8| if variant & (1 << bit) == 0 { 90.0 } else { -90.0 };
    let alpha2 = if variant & 16 == 0 { 0.0 } else { 180.0 };
    table_arm([
        (0.0, 0.0, 10.0, 675.0),
        (s(0), 260.0, -90.0, 120.0),
        (alpha2, 680.0, 20.0, -40.0),
        (s(1), -35.0, -30.0, -670.0),
        (s(2), 0.0, 40.0, 0.0),
        (s(3), 0.0, -50.0, -158.0),
    ])
}

/// Largest difference of two joint vectors, revolute joints modulo a whole turn.
pub(super) fn max_wrapped_diff(a: &JointVector, b: &JointVector) -> f64 {
    a.as_slice()
        .iter()
        .zip(b.as_slice())
        .map(|(x, y)| vatcal_planning::ik::wrap_angle(x - y).abs())
        .fold(0.0, f64::max)
}

/// Checks the planner's IK ([`ModelIk`]) on `model` at joints `q`: the closed form is used,
/// every solution reproduces the tool pose to 1e-9 mm / 1e-9 rad, the generating joint vector
/// is among them. `Err` names what failed.
fn check_model_ik(model: &Model, q: &JointVector) -> Result<usize, String> {
    use vatcal_planning::ik::ModelIk;
    use vatcal_planning::numeric_ik::MultiStartOptions;
    let ik = ModelIk::new(model, RefineOptions::default(), MultiStartOptions::default())
        .map_err(|e| e.to_string())?;
    if !ik.is_closed_form() {
        return Err(format!("not the closed form: {}", ik.method()));
    }
    let target = model.chain(q).tool;
    let solutions = ik.solve(&[q[0]], &target);
    for s in &solutions {
        let (dp, dr) = pose_errors(model, s, &target);
        if dp >= 1e-9 || dr >= 1e-9 {
            return Err(format!("{s:?} misses the pose by {dp} mm, {dr} rad"));
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

/// Joints in (-170, 170) deg (six revolute joints).
pub(super) fn arm_joints() -> impl Strategy<Value = JointVector> {
    proptest::array::uniform6(-170.0..170.0f64)
        .prop_map(|d| JointVector::from_slice(&d.map(f64::to_radians)).expect("six joints"))
}

/// Away from the branch-merging singularities (the chain-agnostic inverse condition number).
pub(super) fn regular_any(model: &Model, q: &JointVector) -> bool {
    let margins = SingularityMargins { min_inverse_condition: 0.03, ..SingularityMargins::default() };
    margins.clear(model, &model.chain(q))
}

#[test]
fn the_structure_is_detected_on_the_fixtures() {
    let table = fixture_model("meca500-table.toml");
    let arm = ArmGeometry::from_model(&table).expect("the Meca500 on a table has a spherical wrist");
    assert_eq!(arm.first_joint, 1);
    let canonical = ArmGeometry::from_model(&common::nominal()).expect("canonical");
    assert_eq!(canonical.first_joint, 2);
    // same arm, same geometry
    assert_eq!(arm.upper_arm_mm, canonical.upper_arm_mm);
    assert_eq!(arm.alpha_rad, canonical.alpha_rad);
    let kuka = ArmGeometry::from_model(&kuka_kr16()).expect("KR 16");
    assert_eq!(kuka.shoulder_forward_mm, 260.0);
    assert_eq!(kuka.forearm_mm, -670.0);
}

#[test]
fn ur5e_is_reported_as_not_spherical() {
    let ur5e = fixture_model("ur5e.toml");
    let err = ArmGeometry::from_model(&ur5e).expect_err("the UR5e wrist is not spherical").to_string();
    assert!(err.contains("spherical wrist"), "{err}");
    assert!(err.contains("joint row 5") && err.contains("d_mm = 99.700"), "{err}");
    // ModelIk::new has no closed form of three parallel axes (`parallel_arm.rs`): numerical IK
    let ik = vatcal_planning::ik::ModelIk::new(
        &ur5e,
        RefineOptions::default(),
        vatcal_planning::numeric_ik::MultiStartOptions::default(),
    )
    .expect("numerical IK");
    assert!(!ik.is_closed_form());
    let method = ik.method().to_string();
    assert!(method.starts_with("multi-start numerical") && method.contains("d_mm = 99.700"), "{method}");
}

#[test]
fn non_qualifying_rows_are_named() {
    // a bent upper arm (alpha_2 = 30 deg) on the KR 16
    let mut rows = [
        (0.0, 0.0, 0.0, 675.0),
        (-90.0, 260.0, -90.0, 0.0),
        (30.0, 680.0, 0.0, 0.0),
        (90.0, -35.0, 0.0, -670.0),
        (-90.0, 0.0, 0.0, 0.0),
        (90.0, 0.0, 0.0, -158.0),
    ];
    let err = ArmGeometry::from_model(&table_arm(rows)).expect_err("bent").to_string();
    assert!(err.contains("joint row 3: alpha_deg = 30.000") && err.contains("parallel"), "{err}");
    // an offset wrist: a_5 = 20 mm
    rows[2].0 = 0.0;
    rows[5].1 = 20.0;
    let err = ArmGeometry::from_model(&table_arm(rows)).expect_err("offset wrist").to_string();
    assert!(err.contains("joint row 6: a_mm = 20.000") && err.contains("spherical wrist"), "{err}");
}

#[test]
fn closed_form_covers_every_supported_sign_combination() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for variant in 0..32u8 {
        let model = sign_variant(variant);
        let arm = ArmGeometry::from_model(&model).unwrap_or_else(|e| panic!("variant {variant}: {e}"));
        let base = robot_base_frame(&model, 0.0);
        let mut checked = 0;
        while checked < 8 {
            let d: [f64; 6] = std::array::from_fn(|_| rand::RngExt::random_range(&mut rng, -170.0..170.0f64));
            let q = JointVector::from_slice(&d.map(f64::to_radians)).expect("joints");
            if !regular_any(&model, &q) {
                continue;
            }
            checked += 1;
            let target = model.chain(&q).tool;
            let solutions = arm.solve(&base.inverse().compose(&target));
            assert!(solutions.len() >= 2, "variant {variant}: {} solutions", solutions.len());
            let mut nearest = f64::INFINITY;
            for s in solutions.as_slice() {
                let qs = JointVector::from_slice(s).expect("joints");
                let (dp, dr) = pose_errors(&model, &qs, &target);
                assert!(dp < 1e-9 && dr < 1e-9, "variant {variant}, {s:?}: {dp} mm, {dr} rad");
                nearest = nearest.min(max_wrapped_diff(&qs, &q));
            }
            assert!(nearest < 1e-9, "variant {variant}: generating joints not found (nearest {nearest})");
            check_model_ik(&model, &q).unwrap_or_else(|e| panic!("variant {variant}: {e}"));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        rng_seed: proptest::test_runner::RngSeed::Fixed(64),
        ..ProptestConfig::default()
    })]

    /// The Meca500 alone on a table: the planner's IK is the closed form, every solution
    /// reproduces the pose, the generating joints are among them.
    #[test]
    fn meca500_table_ik_matches_fk(q in arm_joints()) {
        let model = fixture_model("meca500-table.toml");
        prop_assume!(regular_any(&model, &q));
        let n = check_model_ik(&model, &q).map_err(TestCaseError::fail)?;
        prop_assert!(n >= 2);
    }

    /// A KUKA KR 16 from its published DH table (a_1 = 260 mm).
    #[test]
    fn kuka_kr16_ik_matches_fk(q in arm_joints()) {
        let model = kuka_kr16();
        prop_assume!(regular_any(&model, &q));
        let n = check_model_ik(&model, &q).map_err(TestCaseError::fail)?;
        prop_assert!(n >= 2);
    }

    /// The canonical cell through the planner's IK (guide held at the generating q1).
    #[test]
    fn canonical_model_ik_matches_fk(q in joints()) {
        let model = common::nominal();
        prop_assume!(regular(&model, &q));
        check_model_ik(&model, &q).map_err(TestCaseError::fail)?;
    }
}

/// The closed form finds at least as many solutions within the joint limits as the multi-start
/// numerical IK on the Meca500 alone on a table, for the planner's TCP targets.
#[test]
fn meca500_table_closed_form_finds_at_least_the_numeric_solutions() {
    use vatcal_planning::ik::ModelIk;
    use vatcal_planning::numeric_ik::MultiStartOptions;
    let model = fixture_model("meca500-table.toml");
    let closed = ModelIk::new(&model, RefineOptions::default(), MultiStartOptions::default()).expect("ik");
    assert!(closed.is_closed_form());
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
                let a: Vec<JointVector> = closed
                    .solve(&[], &target)
                    .into_iter()
                    .filter(|q| model.limit_violation(q).is_none())
                    .collect();
                let b: Vec<JointVector> = numeric
                    .solve(&[], &target)
                    .into_iter()
                    .filter(|q| model.limit_violation(q).is_none())
                    .collect();
                for s in &b {
                    assert!(
                        a.iter().any(|c| max_wrapped_diff(c, s) < 1e-6),
                        "numerical solution {s:?} not found by the closed form"
                    );
                }
                n_closed += a.len();
                n_numeric += b.len();
            }
        }
    }
    eprintln!("meca500-table: {n_closed} closed-form vs {n_numeric} numerical solutions within the limits");
    assert!(n_closed >= n_numeric && n_numeric > 0, "{n_closed} closed form vs {n_numeric} numerical");
}

// ---------------------------------------------------------------------------------------------
// Near the wrist singularity of a calibrated model (the wrist axes no longer meet exactly):
// more than the eight spherical-wrist solutions, found by `ToolPoseIk::add_wrist_band_solutions`.

/// Checks `ToolPoseIk::solve_at_guide` on `model` at joints `q`: every solution reproduces the
/// tool pose to 1e-9 mm / 1e-12 rad, no two solutions are the same (1e-6 rad, modulo a turn),
/// the generating joints are among them. `Ok(number of solutions)`, `Err` names what failed.
fn check_calibrated_ik(model: &Model, q: &JointVector) -> Result<usize, String> {
    let target = model.chain(q).tool;
    let ik = ToolPoseIk::new(model, RefineOptions::default()).map_err(|e| e.to_string())?;
    let solutions = ik.solve_at_guide(q[0], &target);
    for (k, s) in solutions.iter().enumerate() {
        let (dp, dr) = pose_errors(model, s, &target);
        if dp >= 1e-9 || dr >= 1e-12 {
            return Err(format!("{s:?} misses the pose by {dp} mm, {dr} rad"));
        }
        if let Some(t) = solutions[..k].iter().find(|t| max_wrapped_diff(s, t) < 1e-6) {
            return Err(format!("{s:?} returned twice (also as {t:?})"));
        }
    }
    let nearest = solutions.iter().map(|s| max_diff(s, q)).fold(f64::INFINITY, f64::min);
    if nearest >= 1e-8 {
        return Err(format!("original not found (nearest {nearest}, {} solutions)", solutions.len()));
    }
    Ok(solutions.len())
}

/// Found by a random proptest seed in CI (2026-12-02): on the perturbed model of seed 969, the
/// arm's J5 6.5° from the wrist singularity and the wrist centre 7.3 mm from the J1 axis, the
/// generating joints are not one of the eight refined closed-form branches. Those eight are the
/// continuations of the nominal branches (each followed from the nominal model to this one in
/// 1000 parameter steps lands on the solution the closed form + refinement returns); the
/// generating joints and a solution next to them (arm J1 = 0.032 rad, J4 = -0.28 rad) are two
/// further solutions of the calibrated wrist, which the scan of the soft wrist direction finds.
#[test]
fn further_solutions_near_the_wrist_and_shoulder_singularities_are_found() {
    let model = common::perturbed(969);
    let q =
        JointVector::new([0.0, 0.0, -0.9375220691465624, 0.6061287380229476, 0.0, 0.11413765393503994, 0.0]);
    let n = check_calibrated_ik(&model, &q).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(n, 10, "the eight branches and the two further solutions");
    // the eight branches of the closed form are still there, first and in branch order
    let target = model.chain(&q).tool;
    let ik = ToolPoseIk::new(&model, RefineOptions::default()).expect("ik");
    let base = robot_base_frame(&model, q[0]);
    let solutions = ik.solve_at_guide(q[0], &target);
    for (seed, s) in ik.seeds(q[0], &base, &target).iter().zip(&solutions) {
        let refined = ik.refine(&seed.q, &target).expect("refined");
        let wrapped = JointVector::from_slice(
            &refined
                .q
                .as_slice()
                .iter()
                .enumerate()
                .map(|(j, v)| if j == 0 { *v } else { vatcal_planning::ik::wrap_angle(*v) })
                .collect::<Vec<_>>(),
        )
        .expect("joints");
        assert!(max_diff(&wrapped, s) < 1e-12, "{wrapped:?} vs {s:?}");
    }
}

/// Six arm joints whose wrist centre is `rho_mm` from the axis of arm joint 1 (on the nominal
/// structure) at azimuth `azimuth_deg` and `h_mm` above the shoulder, on closed-form branch
/// `branch` (shoulder, elbow bits), with wrist joints `wrist_deg`; `None` when out of reach.
fn near_shoulder_arm(
    arm: &ArmGeometry,
    rho_mm: f64,
    azimuth_deg: f64,
    h_mm: f64,
    branch: u8,
    wrist_deg: [f64; 3],
) -> Option<[f64; 6]> {
    let a = azimuth_deg.to_radians();
    let w = nalgebra::Vector3::new(rho_mm * a.cos(), rho_mm * a.sin(), arm.shoulder_height_mm + h_mm);
    // identity orientation: z6 = z of the base frame
    let target = Frame { r: nalgebra::Matrix3::identity(), p: w + nalgebra::Vector3::z() * arm.flange_mm };
    let s = arm.solve(&target).of_branch(branch)?;
    Some([s[0], s[1], s[2], wrist_deg[0].to_radians(), wrist_deg[1].to_radians(), wrist_deg[2].to_radians()])
}

/// A wrist angle 2°..10° from the wrist singularity, either side.
fn near_wrist_deg() -> impl Strategy<Value = f64> {
    (2.0..10.0f64, any::<bool>()).prop_map(|(a, negative)| if negative { -a } else { a })
}

/// The arguments of [`near_shoulder_arm`] near both singularities: the wrist centre 5..10 mm
/// from the J1 axis (any azimuth, -150..250 mm above the shoulder, any branch), J5 2°..10°
/// from the wrist singularity; plus a perturbation seed.
#[derive(Debug, Clone)]
struct NearBoth {
    rho_mm: f64,
    azimuth_deg: f64,
    h_mm: f64,
    branch: u8,
    wrist_deg: [f64; 3],
    seed: u64,
}

impl NearBoth {
    /// The arm joints on `arm` (None when out of reach).
    fn arm_joints(&self, arm: &ArmGeometry) -> Option<[f64; 6]> {
        near_shoulder_arm(arm, self.rho_mm, self.azimuth_deg, self.h_mm, self.branch, self.wrist_deg)
    }
}

prop_compose! {
    fn near_both()(
        rho_mm in 5.0..10.0f64,
        azimuth_deg in -180.0..180.0f64,
        h_mm in -150.0..250.0f64,
        branch in 0u8..4,
        j4 in -170.0..170.0f64,
        j5 in near_wrist_deg(),
        j6 in -170.0..170.0f64,
        seed in 0u64..1000,
    ) -> NearBoth {
        NearBoth { rho_mm, azimuth_deg, h_mm, branch, wrist_deg: [j4, j5, j6], seed }
    }
}

/// The Meca500 of `fixtures/meca500-table.toml` with the errors of `common::perturbed` (every
/// MDH parameter, the base pose, compliance on every joint).
fn perturbed_table(seed: u64) -> Model {
    use rand::RngExt;
    use vatcal_core::ParamId;
    let mut m = fixture_model("meca500-table.toml");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut nudge = |m: &mut Model, id: ParamId, amplitude: f64| {
        let v = m.param(id).expect("param") + rng.random_range(-amplitude..amplitude);
        m.set_param(id, v).expect("set");
    };
    let deg = 1f64.to_radians();
    for i in 1..=6u8 {
        nudge(&mut m, ParamId::Alpha(i), 0.3 * deg);
        nudge(&mut m, ParamId::A(i), 0.5);
        nudge(&mut m, ParamId::D(i), 0.5);
        nudge(&mut m, ParamId::ThetaOffset(i), 0.5 * deg);
        m.set_param(ParamId::Compliance(i), 2e-3).expect("compliance");
    }
    for b in vatcal_core::params::BaseParam::ALL {
        let amplitude = if matches!(
            b,
            vatcal_core::params::BaseParam::X
                | vatcal_core::params::BaseParam::Y
                | vatcal_core::params::BaseParam::Z
        ) {
            2.0
        } else {
            0.3 * deg
        };
        nudge(&mut m, ParamId::Base(b), amplitude);
    }
    m
}

/// [`regular`] for the Meca500 alone on a table (arm joint `j` is cell joint `j`): J5 at least
/// 2° from the wrist singularity, the elbow 2° from stretched/folded, the wrist centre 5 mm from
/// the J1 axis.
fn regular_table(model: &Model, q: &JointVector) -> bool {
    let chain = model.chain(q);
    let r4 = model.row(4);
    let wrist = chain.theta[4].sin().abs() >= 2f64.to_radians().sin();
    let elbow = (chain.theta[2] + r4.d.atan2(r4.a)).sin().abs() >= 2f64.to_radians().sin();
    let axis = chain.frames[1].z_axis();
    let w = chain.frames[5].p - chain.frames[1].p;
    wrist && elbow && (w - axis * w.dot(&axis)).norm() >= 5.0
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 128,
        rng_seed: proptest::test_runner::RngSeed::Fixed(21),
        ..ProptestConfig::default()
    })]

    /// Calibrated model, J5 2°..10° from the wrist singularity (the band the proptest above
    /// leaves out): every solution reproduces the pose, none twice, the original is found.
    #[test]
    fn calibrated_ik_near_the_wrist_singularity(q in joints(), j5 in near_wrist_deg(), seed in 0u64..1000) {
        let model = common::perturbed(seed);
        let mut q = q;
        q[5] = j5.to_radians();
        prop_assume!(regular(&model, &q));
        let n = check_calibrated_ik(&model, &q).map_err(TestCaseError::fail)?;
        prop_assert!(n >= 2);
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        rng_seed: proptest::test_runner::RngSeed::Fixed(22),
        ..ProptestConfig::default()
    })]

    /// Calibrated model near the wrist singularity (arm J5 2°..10°) with the wrist centre
    /// 5..10 mm from the J1 axis, where one spherical-wrist branch can become three solutions
    /// (about 1 % of such cases lost the generating joints before the wrist scan).
    #[test]
    fn calibrated_ik_near_the_wrist_and_shoulder_singularities(q1 in 0.0..300.0f64, c in near_both()) {
        let arm = ArmGeometry::from_model(&common::nominal()).expect("meca500");
        let joints = c.arm_joints(&arm);
        prop_assume!(joints.is_some());
        let a = joints.unwrap_or_default();
        let q = JointVector::new([q1, a[0], a[1], a[2], a[3], a[4], a[5]]);
        let model = common::perturbed(c.seed);
        prop_assume!(regular(&model, &q));
        check_calibrated_ik(&model, &q).map_err(TestCaseError::fail)?;
    }

    /// The same on the Meca500 alone on a table (`ModelIk`, the any-chain closed form).
    #[test]
    fn calibrated_table_ik_near_the_wrist_and_shoulder_singularities(c in near_both()) {
        let arm = ArmGeometry::from_model(&fixture_model("meca500-table.toml")).expect("meca500");
        let joints = c.arm_joints(&arm);
        prop_assume!(joints.is_some());
        let q = JointVector::from_slice(&joints.unwrap_or_default()).expect("joints");
        let model = perturbed_table(c.seed);
        prop_assume!(regular_table(&model, &q));
        check_model_ik(&model, &q).map_err(TestCaseError::fail)?;
    }
}
