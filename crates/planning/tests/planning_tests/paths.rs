//! Collision-free paths: straight when possible, RRT-Connect otherwise, always verified.

use crate::common;

use vatcal_core::JointVector;
use vatcal_core::cell::MotionLimits;
use vatcal_planning::candidates::{Candidate, CandidateOptions, generate_candidates};
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::motion::{JointBounds, MOVE_MARGIN_DEG, MotionTimer, Resolution, interpolate};
use vatcal_planning::paths::{PathFailure, PathMethod, PathOptions, PathPlanner, segment_is_free};

/// Independent check at twice the planner's resolution.
fn verify(checker: &CollisionChecker<'_>, path: &[JointVector], probe: ProbeState) {
    let fine = Resolution { max_joint_step_deg: 0.5, max_guide_step_mm: 0.5 };
    for w in path.windows(2) {
        let n = fine.intervals(&w[0], &w[1]);
        for i in 0..=n {
            let q = interpolate(&w[0], &w[1], i as f64 / n as f64);
            assert!(checker.is_free(&q, probe), "path collides: {:?}", checker.check(&q, probe));
        }
    }
}

fn retreat_poses(model: &vatcal_kinematics::Model, checker: &CollisionChecker<'_>) -> Vec<Candidate> {
    let opts = CandidateOptions {
        orientations: 10,
        guide_steps: 5,
        positions: Some(vec![2]),
        ..CandidateOptions::default()
    };
    generate_candidates(model, checker, &opts).expect("candidates").candidates
}

#[test]
fn rrt_connect_finds_verified_paths_where_straight_moves_collide() {
    let model = common::nominal();
    let geometry = CellGeometry::from_cell(&common::cell()).expect("geometry");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    let bounds = JointBounds::new(&model, MOVE_MARGIN_DEG, 0.0).expect("bounds");
    let timer = MotionTimer::from_limits(&MotionLimits::default()).expect("timer");
    let probe = ProbeState::At { position: 2 };
    let poses = retreat_poses(&model, &checker);
    let opts = PathOptions::default();
    let planner = PathPlanner { checker: &checker, bounds: &bounds, timer: &timer, opts: &opts };
    // pairs whose straight joint move collides
    let mut hard = Vec::new();
    'outer: for (i, a) in poses.iter().enumerate() {
        for b in poses.iter().skip(i + 1) {
            if !segment_is_free(&checker, &a.retreat, &b.retreat, probe, &opts.resolution) {
                hard.push((a.retreat, b.retreat));
                if hard.len() == 4 {
                    break 'outer;
                }
            }
        }
    }
    assert!(!hard.is_empty(), "no colliding straight move among {} poses", poses.len());
    for (k, (a, b)) in hard.iter().enumerate() {
        let path = planner.plan(a, b, probe, k as u64).expect("path");
        assert_eq!(path.method, PathMethod::RrtConnect);
        assert_eq!(path.waypoints.first(), Some(a));
        assert_eq!(path.waypoints.last(), Some(b));
        verify(&checker, &path.waypoints, probe);
        // deterministic for a seed
        let again = planner.plan(a, b, probe, k as u64).expect("path");
        assert_eq!(path, again);
    }
}

#[test]
fn free_straight_moves_stay_straight_and_bad_ends_are_reported() {
    let model = common::nominal();
    let geometry = CellGeometry::from_cell(&common::cell()).expect("geometry");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    let bounds = JointBounds::new(&model, MOVE_MARGIN_DEG, 0.0).expect("bounds");
    let timer = MotionTimer::from_limits(&MotionLimits::default()).expect("timer");
    let probe = ProbeState::At { position: 2 };
    let poses = retreat_poses(&model, &checker);
    let opts = PathOptions::default();
    let planner = PathPlanner { checker: &checker, bounds: &bounds, timer: &timer, opts: &opts };
    let a = poses[0].retreat;
    let mut b = a;
    b[6] += 0.2; // turn the last joint a little
    let path = planner.plan(&a, &b, probe, 0).expect("path");
    assert_eq!(path.method, PathMethod::Straight);
    assert_eq!(path.waypoints, vec![a, b]);
    // the measurement pose itself is in contact with the probe when the ball is not allowed in
    let measuring = poses[0].q;
    match planner.plan(&a, &measuring, probe, 0) {
        Err(PathFailure::GoalInCollision(c)) => assert!(c.to_string().contains("TriCal"), "{c}"),
        other => panic!("expected a goal collision, got {other:?}"),
    }
    match planner.plan(&measuring, &a, probe, 0) {
        Err(PathFailure::StartInCollision(_)) => {}
        other => panic!("expected a start collision, got {other:?}"),
    }
}

#[test]
fn motion_time_is_the_slowest_joint() {
    let timer = MotionTimer::from_limits(&MotionLimits::default()).expect("timer");
    let a = JointVector::from_mm_deg(0.0, [0.0; 6]);
    // J1 at 150 deg/s × 0.25 = 37.5 deg/s: 75 deg take 2 s; guide 50 mm/s × 0.25: 20 mm take 1.6 s
    let b = JointVector::from_mm_deg(20.0, [75.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!((timer.move_time_s(&a, &b) - 2.0).abs() < 1e-12);
    let c = JointVector::from_mm_deg(40.0, [75.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!((timer.move_time_s(&a, &c) - 3.2).abs() < 1e-12);
    assert_eq!(Resolution::default().intervals(&a, &b), 75);
}
