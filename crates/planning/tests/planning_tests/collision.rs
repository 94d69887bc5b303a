//! Collision checker: probe states, obstacle placement, self-collision.

use crate::common;

use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_core::JointVector;
use vatcal_core::cell::{BoxObstacle, PlaneObstacle};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::sample_orientation;
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::geometry::{CellGeometry, RobotLinkGeometry};
use vatcal_planning::ik::{RefineOptions, ToolPoseIk, tool_pose_for_tcp};

/// A measurement configuration of TCP 2 at position 1 that is collision-free while measuring.
fn measuring_pose(model: &Model, checker: &CollisionChecker<'_>) -> JointVector {
    let ik = ToolPoseIk::new(model, RefineOptions::default()).expect("ik");
    let t = model.tcp(2).expect("tcp");
    let p = model.position(1).expect("position");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let r = sample_orientation(&mut rng, &(-t), 30f64.to_radians());
        for q in ik.solve(&[100.0, 200.0, 295.0], &tool_pose_for_tcp(&r, &t, &p)) {
            if model.limit_violation(&q).is_none()
                && checker.is_free(&q, ProbeState::Measuring { position: 1, tcp: 2 })
            {
                return q;
            }
        }
    }
    panic!("no free measuring pose found");
}

#[test]
fn only_the_measuring_ball_may_touch_the_probe() {
    let cell = common::cell();
    let model = common::nominal();
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    let q = measuring_pose(&model, &checker);
    // the ball sits on the probe origin: its lower half is inside the TriCal body model
    let contact = checker.check(&q, ProbeState::At { position: 1 }).expect("ball in the probe");
    assert_eq!(contact.body, "ball2");
    assert!(contact.other.contains("TriCal at position 1"), "{contact}");
    // measuring with another ball is not allowed either
    assert!(checker.check(&q, ProbeState::Measuring { position: 1, tcp: 1 }).is_some());
    // no probe there: free
    assert!(checker.is_free(&q, ProbeState::Absent));
    assert!(checker.is_free(&q, ProbeState::At { position: 2 }));
}

#[test]
fn obstacles_are_placed_where_the_cell_file_says() {
    let model = common::nominal();
    let q = JointVector::from_mm_deg(150.0, [90.0, 30.0, 20.0, 0.0, 40.0, 0.0]);
    let ball = model.tcp_position(&q, 1).expect("fk");
    // a 1 mm guide "box" (given in frame 0) around the centre of ball 1
    let in_frame0 = model.base_frame().inverse().transform_point(&ball);
    let tiny = |c: Vector3<f64>| BoxObstacle {
        x_min_mm: c.x - 0.5,
        x_max_mm: c.x + 0.5,
        y_min_mm: c.y - 0.5,
        y_max_mm: c.y + 0.5,
        z_min_mm: c.z - 0.5,
        z_max_mm: c.z + 0.5,
    };
    let geometry = CellGeometry { guide: Some(tiny(in_frame0)), ..CellGeometry::default() };
    let checker = CollisionChecker::new(&model, &geometry, 0.0).expect("checker");
    let contact = checker.check(&q, ProbeState::Absent).expect("box inside ball 1");
    assert_eq!((contact.body.as_str(), contact.other.as_str()), ("ball1", "guide"));
    let moved = CellGeometry {
        guide: Some(tiny(in_frame0 + Vector3::new(0.0, 0.0, 500.0))),
        ..CellGeometry::default()
    };
    let checker = CollisionChecker::new(&model, &moved, 0.0).expect("checker");
    assert!(checker.is_free(&q, ProbeState::Absent));
}

#[test]
fn floor_is_hit_exactly_when_it_rises_above_the_lowest_ball() {
    let model = common::nominal();
    let q = JointVector::from_mm_deg(20.0, [90.0, 60.0, -10.0, 0.0, 40.0, 0.0]);
    let radius = CellGeometry::default().end_effector.ball_radius_mm;
    let margin = 1.0;
    let lowest = model
        .tcp_ids()
        .into_iter()
        .map(|t| model.tcp_position(&q, t).expect("fk").z)
        .fold(f64::INFINITY, f64::min)
        - radius
        - margin;
    let with_floor =
        |z: f64| CellGeometry { floor: Some(PlaneObstacle { z_mm: z }), ..CellGeometry::default() };
    // the lowest body of this configuration is a ball (checked: nothing hits a floor just below it)
    let below = with_floor(lowest - 1e-3);
    assert!(CollisionChecker::new(&model, &below, margin).expect("c").is_free(&q, ProbeState::Absent));
    let above = with_floor(lowest + 1e-3);
    let contact =
        CollisionChecker::new(&model, &above, margin).expect("c").check(&q, ProbeState::Absent).expect("hit");
    assert!(contact.body.starts_with("ball") && contact.other == "floor", "{contact}");
}

#[test]
fn self_collision_of_non_adjacent_links() {
    let model = common::nominal();
    let q = JointVector::from_mm_deg(150.0, [0.0, 0.0, 0.0, 0.0, 45.0, 0.0]);
    let default = CellGeometry::default();
    assert!(CollisionChecker::new(&model, &default, 0.0).expect("c").is_free(&q, ProbeState::Absent));
    // a fat forearm reaches the end-effector (not adjacent)
    let fat = CellGeometry {
        robot: RobotLinkGeometry { forearm_radius_mm: 150.0, ..RobotLinkGeometry::default() },
        ..default.clone()
    };
    let contact =
        CollisionChecker::new(&model, &fat, 0.0).expect("c").check(&q, ProbeState::Absent).expect("hit");
    assert!(contact.body == "forearm" || contact.other == "forearm", "{contact}");
    // upper arm forward (J2 = 90), elbow folded back (J3 = 70): the wrist centre ends 35 mm from
    // the J1 axis and 77 mm below the shoulder, inside the base cylinder
    let folded = JointVector::from_mm_deg(150.0, [0.0, 90.0, 70.0, 0.0, 0.0, 0.0]);
    let wrist = model.chain(&folded).frames[6].p;
    let base_frame = vatcal_planning::ik::robot_base_frame(&model, 150.0);
    let local = base_frame.inverse().transform_point(&wrist);
    assert!(local.x.hypot(local.y) < 45.0 && local.z < 100.0, "wrist at {local} in the base frame");
    let contact = CollisionChecker::new(&model, &default, 0.0)
        .expect("c")
        .check(&folded, ProbeState::Absent)
        .expect("hit");
    assert!(contact.body == "base" || contact.body == "shoulder", "{contact}");
}

#[test]
fn invalid_geometry_tables_name_the_field() {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("read");
    let bad = format!("{text}\n[obstacles.robot_links]\nforearm_radius_mm = -3.0\n");
    let cell = vatcal_core::CellFile::from_toml_str(&bad, "bad.toml").expect("core accepts extra tables");
    let err = CellGeometry::from_cell(&cell).expect_err("negative radius");
    assert!(err.to_string().contains("obstacles.robot_links.forearm_radius_mm"), "{err}");
    let typo = format!("{text}\n[obstacles.end_effector]\nball_radius = 3.0\n");
    let cell = vatcal_core::CellFile::from_toml_str(&typo, "typo.toml").expect("core accepts extra tables");
    let err = CellGeometry::from_cell(&cell).expect_err("unknown field");
    assert!(err.to_string().contains("obstacles.end_effector"), "{err}");
    let good = format!("{text}\n[obstacles.robot_links]\nforearm_radius_mm = 30.0\n");
    let cell = vatcal_core::CellFile::from_toml_str(&good, "good.toml").expect("valid");
    assert_eq!(CellGeometry::from_cell(&cell).expect("ok").robot.forearm_radius_mm, 30.0);
}
