//! Independent poses (`Compensator::compensate_each`, `vatcal compensate --each`): every row
//! solved on its own, on the branch it names, nearest a configuration, or farthest from the
//! limits.

use vatcal_compensation::{
    Branch, CompensationError, Compensator, EachOptions, PathOptions, PoseRequest, Preference, RowOutcome,
    ToolTarget,
};
use vatcal_core::JointVector;

use crate::compensate::{calibrated_with_effects, context, fk_error, nominal, reachable_joints};

/// 300 unrelated poses of the calibrated model (random joints away from singularities, TCP 1..3
/// in turn, with the context its effects need): the generating joints and the requests.
fn random_poses(cal: &vatcal_kinematics::Model) -> (Vec<JointVector>, Vec<PoseRequest>) {
    let ctx = context();
    (0..300u64)
        .map(|k| {
            let q = reachable_joints(cal, 7_000 + k);
            let tool = cal.chain_full(&q, &ctx, false, None).tool;
            let tcp = 1 + (k % 3) as u32;
            (q, PoseRequest::from_tool_frame(cal, tcp, q, &tool, ctx).expect("request"))
        })
        .unzip()
}

fn targets(cal: &vatcal_kinematics::Model, requests: &[PoseRequest]) -> Vec<ToolTarget> {
    requests.iter().enumerate().map(|(row, r)| r.tool_target(cal, row).expect("target")).collect()
}

fn solved(outcome: &RowOutcome) -> &vatcal_compensation::Compensated {
    match outcome {
        RowOutcome::Solved(c) => c,
        RowOutcome::Skipped(s) => panic!("row {} skipped: {}", s.row, s.error),
    }
}

/// The acceptance test: 300 random independent poses on a calibrated (perturbed, with
/// compliance and effects) model are reproduced to 1e-6 mm / 1e-9 rad, inside the limits —
/// while compensating the same list as one path fails (a joint jump or a branch change).
#[test]
fn three_hundred_independent_poses_are_reproduced() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let (_, requests) = random_poses(&cal);
    let targets = targets(&cal, &requests);
    assert!(
        matches!(
            comp.compensate_path(&targets, &PathOptions::default()),
            Err(CompensationError::JointJump { .. } | CompensationError::BranchChange { .. })
        ),
        "unrelated poses are not a path"
    );
    let result = comp.compensate_each(&targets, &[], &EachOptions::default()).expect("each");
    assert_eq!(result.rows.len(), 300);
    let mut branches = std::collections::BTreeSet::new();
    for (outcome, req) in result.rows.iter().zip(&requests) {
        let c = solved(outcome);
        let (dp, dr) = fk_error(&cal, &c.q, req);
        assert!(dp < 1e-6 && dr < 1e-9, "FK error {dp:e} mm, {dr:e} rad");
        assert!(c.position_residual_mm < 1e-6 && c.rotation_residual_rad < 1e-9);
        assert!(cal.limit_violation(&c.q).is_none());
        assert_eq!(c.q[0], req.given[0], "the guide stays where the row asks");
        branches.insert(c.branch.0);
    }
    assert!(branches.len() > 1, "the rows use several branches: {branches:?}");
}

/// A row that names its branch gets it; `Preference::Near` at the generating joints gives them
/// back (the nearest solution, turned to their revolution); a branch that does not reach the
/// pose is named with the ones that do.
#[test]
fn named_branches_and_the_nearest_solution() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let (joints, requests) = random_poses(&cal);
    let (joints, requests) = (&joints[..60], &requests[..60]);
    let targets = targets(&cal, requests);
    // the branch of every generating configuration, as the solver classifies it
    let generating: Vec<Option<Branch>> = joints
        .iter()
        .zip(&targets)
        .map(|(q, t)| {
            let path = comp.compensate_path(
                std::slice::from_ref(t),
                &PathOptions { start: Some(*q), ..PathOptions::default() },
            );
            Some(solved(&path.expect("one row").rows[0]).branch)
        })
        .collect();
    let named = comp.compensate_each(&targets, &generating, &EachOptions::default()).expect("each");
    for ((outcome, want), req) in named.rows.iter().zip(&generating).zip(requests) {
        let c = solved(outcome);
        assert_eq!(Some(c.branch), *want);
        assert!(fk_error(&cal, &c.q, req).0 < 1e-6);
    }
    for (q, t) in joints.iter().zip(&targets) {
        let opts = EachOptions { prefer: Preference::Near(*q), ..EachOptions::default() };
        let r = comp.compensate_each(std::slice::from_ref(t), &[], &opts).expect("near");
        let c = solved(&r.rows[0]);
        let gap = (0..7).map(|k| (c.q[k] - q[k]).abs()).fold(0.0, f64::max);
        assert!(gap < 1e-6, "nearest solution {:?} vs generating {:?}", c.q.to_mm_deg(), q.to_mm_deg());
    }
    // a branch none of the solutions has: every branch of the first pose but one is asked for
    // in turn until one is missing, then the error names the others
    let all = comp.all_solutions(&targets[0], &Default::default());
    if let Some(missing) = (0..8u8).map(Branch).find(|b| all.iter().all(|(o, _)| o != b)) {
        let err = comp.compensate_each(&targets[..1], &[Some(missing)], &EachOptions::default());
        let Err(e @ CompensationError::BranchUnreachable { row: 0, .. }) = err else {
            panic!("expected BranchUnreachable, got {err:?}")
        };
        assert!(e.to_string().contains("branch(es)"), "{e}");
    }
    // skip mode keeps going
    let skip = EachOptions { skip_unreachable: true, ..EachOptions::default() };
    let far = PoseRequest::on_guide(1, 100.0, [5_000.0, 0.0, 0.0], [180.0, 0.0, 0.0]);
    let mut with_far = targets[..3].to_vec();
    with_far.insert(1, far.tool_target(&cal, 1).expect("target"));
    let r = comp.compensate_each(&with_far, &[], &skip).expect("skip");
    assert!(matches!(&r.rows[1], RowOutcome::Skipped(s) if s.row == 1));
    assert_eq!(r.solved().count(), 3);
}

/// A `Near` configuration of the wrong length is an option error, not a panic.
#[test]
fn a_bad_near_configuration_is_an_error() {
    let cal = calibrated_with_effects();
    let nom = nominal();
    let comp = Compensator::new(&cal, &nom).expect("compensator");
    let (_, requests) = random_poses(&cal);
    let t = targets(&cal, &requests[..1]);
    let opts = EachOptions { prefer: Preference::Near(JointVector::zeros(3)), ..EachOptions::default() };
    assert!(matches!(
        comp.compensate_each(&t, &[], &opts),
        Err(CompensationError::Option { option: "near", .. })
    ));
}
