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

/// Model, geometry (from the file) and checker input of a version-2 fixture.
fn any_chain_fixture(name: &str) -> (Model, CellGeometry) {
    let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    let cell = vatcal_core::CellFile::load(&path).expect("fixture");
    let model = Model::from_cell(&cell).expect("model");
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    (model, geometry)
}

fn deg(q: [f64; 6]) -> JointVector {
    let mut v = JointVector::zeros(6);
    for (k, x) in q.iter().enumerate() {
        v[k] = x.to_radians();
    }
    v
}

#[test]
fn ur5e_link_radii_come_from_the_cell_file() {
    let (model, geometry) = any_chain_fixture("ur5e.toml");
    assert_eq!(
        geometry.robot.link_radii_mm.as_deref(),
        Some(&[60.0, 60.0, 54.0, 40.0, 45.0, 45.0, 45.0][..])
    );
    assert_eq!(geometry.robot.chain_radius_mm(2), 54.0);
    // one radius per link 0..N: a 6-joint chain needs 7
    let short = CellGeometry {
        robot: RobotLinkGeometry { link_radii_mm: Some(vec![40.0; 6]), ..RobotLinkGeometry::default() },
        ..geometry.clone()
    };
    let err = CollisionChecker::new(&model, &short, 2.0).expect_err("6 radii for 7 links");
    assert!(err.to_string().contains("link_radii_mm"), "{err}");
    let negative = CellGeometry {
        robot: RobotLinkGeometry {
            link_radii_mm: Some(vec![40.0, 40.0, -1.0, 40.0, 40.0, 40.0, 40.0]),
            ..RobotLinkGeometry::default()
        },
        ..geometry
    };
    let err = CollisionChecker::new(&model, &negative, 2.0).expect_err("negative radius");
    assert!(err.to_string().contains("link_radii_mm[2]"), "{err}");
}

#[test]
fn ur5e_folded_elbow_hits_the_base_and_the_upright_home_pose_is_clear() {
    let (model, geometry) = any_chain_fixture("ur5e.toml");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    // UR home: upper arm and forearm straight up, wrist 1 at -90: nothing near anything
    let home = deg([0.0, -90.0, 0.0, -90.0, 0.0, 0.0]);
    assert!(
        checker.is_free(&home, ProbeState::Everywhere),
        "{:?}",
        checker.check(&home, ProbeState::Everywhere)
    );
    // upper arm up, elbow folded to 175 deg: the forearm comes back down the upper arm and
    // ends next to the J1 axis, just above the shoulder (UR5e base column r 60, forearm r 40)
    let folded = deg([0.0, -90.0, 175.0, 0.0, 0.0, 0.0]);
    let chain = model.chain(&folded);
    let forearm_end = chain.frames[4].p - chain.frames[4].z_axis() * model.row(4).d;
    assert!(forearm_end.x.hypot(forearm_end.y) < 60.0 + 40.0, "forearm end at {forearm_end}");
    assert!(forearm_end.z < 162.5 + 60.0 + 40.0, "forearm end at {forearm_end}");
    let contacts = checker.contacts(&chain, ProbeState::Absent);
    assert!(
        contacts.iter().any(|(c, d)| c.body == "link 1 (d_1)" && c.other == "link 3 (a_3)" && *d > 10.0),
        "{contacts:?}"
    );
    assert_eq!(checker.check(&folded, ProbeState::Absent), contacts.first().map(|c| c.0.clone()));
}

#[test]
fn ur5e_measurement_pose_with_the_flange_above_the_ball_is_clear() {
    use vatcal_planning::ik::ModelIk;
    use vatcal_planning::numeric_ik::MultiStartOptions;
    let (model, geometry) = any_chain_fixture("ur5e.toml");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    let (tcp, position) = (2, 1);
    let t = model.tcp(tcp).expect("tcp");
    let p = model.position(position).expect("position");
    // tool orientation with the ball-to-flange direction straight up (flange above the ball)
    let r =
        *nalgebra::Rotation3::rotation_between(&(-t).normalize(), &Vector3::z()).expect("rotation").matrix();
    let ik = ModelIk::new(&model, RefineOptions::default(), MultiStartOptions::default()).expect("ik");
    let solutions: Vec<JointVector> = ik
        .solve_at_guide(0.0, &tool_pose_for_tcp(&r, &t, &p))
        .into_iter()
        .filter(|q| model.limit_violation(q).is_none())
        .collect();
    assert!(solutions.len() >= 4, "{} solutions", solutions.len());
    // elbow up (the elbow highest above the table), the usual way to reach down to a probe
    let elbow_z = |q: &JointVector| model.chain(q).frames[3].p.z;
    let q = solutions.iter().max_by(|a, b| elbow_z(a).total_cmp(&elbow_z(b))).expect("a solution");
    assert!(elbow_z(q) > 300.0, "elbow at {} mm", elbow_z(q));
    let measuring = ProbeState::Measuring { position, tcp };
    assert!(checker.is_free(q, measuring), "{:?}", checker.contacts(&model.chain(q), measuring));
    // the elbow-down mirror of the same pose drives the upper arm through the table
    let q_down = solutions.iter().min_by(|a, b| elbow_z(a).total_cmp(&elbow_z(b))).expect("a solution");
    if elbow_z(q_down) < 0.0 {
        let contact = checker.check(q_down, measuring).expect("elbow below the table");
        assert_eq!(contact.other, "floor", "{contact}");
    }
}

/// Axis segment of a generic-chain capsule named `link k (a_k)` / `link k (d_k)` (module docs of
/// `collision`), computed here from the frames, and its link.
fn named_segment(
    model: &Model,
    chain: &vatcal_kinematics::Chain,
    name: &str,
) -> Option<(usize, Vector3<f64>, Vector3<f64>)> {
    let rest = name.strip_prefix("link ")?;
    let (link, kind) = rest.split_once(' ')?;
    let k: usize = link.parse().ok()?;
    let f = &chain.frames;
    if kind.starts_with("(a_") {
        let a = f[k].p;
        Some((k, a, a + f[k].r.column(0) * model.row(k + 1).a))
    } else {
        let b = f[k].p;
        Some((k, b - f[k].z_axis() * model.row(k).d, b))
    }
}

/// Closest distance between segments `p0 p1` and `q0 q1` (clamped parameters, sampled finely
/// enough for a test: 1e-3 of the segment lengths, then refined).
fn segment_distance(p0: Vector3<f64>, p1: Vector3<f64>, q0: Vector3<f64>, q1: Vector3<f64>) -> f64 {
    let (u, v, w0) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, b, c, d, e) = (u.dot(&u), u.dot(&v), v.dot(&v), u.dot(&w0), v.dot(&w0));
    let point_to = |x: Vector3<f64>, s0: Vector3<f64>, dir: Vector3<f64>, len2: f64| {
        let t = if len2 > 0.0 { ((x - s0).dot(&dir) / len2).clamp(0.0, 1.0) } else { 0.0 };
        (s0 + dir * t - x).norm()
    };
    let mut best = point_to(p0, q0, v, c)
        .min(point_to(p1, q0, v, c))
        .min(point_to(q0, p0, u, a))
        .min(point_to(q1, p0, u, a));
    let den = a * c - b * b;
    if den > 1e-12 {
        let s = (b * e - c * d) / den;
        let t = (a * e - b * d) / den;
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            best = best.min((p0 + u * s - q0 - v * t).norm());
        }
    }
    best
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 48, ..Default::default() })]

    /// Random joint vectors of both version-2 fixtures: every self-contact reported is between
    /// links at least 2 apart, is a real overlap of the two capsules (distance of their axes
    /// computed here, below the sum of the radii and margins), and is not the touching of two
    /// capsules at a joint they share (an end of each at a distance that no joint changes).
    #[test]
    fn generic_chains_report_no_contact_merely_at_a_shared_joint(
        raw in proptest::collection::vec(0.0f64..1.0, 12),
    ) {
        for name in ["ur5e.toml", "meca500-table.toml"] {
            let (model, mut geometry) = any_chain_fixture(name);
            // self-collision only
            (geometry.tank, geometry.trical, geometry.guide, geometry.floor) = (None, None, None, None);
            let margin = 2.0;
            let checker = CollisionChecker::new(&model, &geometry, margin).expect("checker");
            let sample = |offset: usize| {
                let mut q = JointVector::zeros(model.joint_count());
                for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
                    q[k] = lo + (hi - lo) * raw[(k + offset) % raw.len()];
                }
                q
            };
            let (q, other) = (sample(0), sample(6));
            let (chain, chain2) = (model.chain(&q), model.chain(&other));
            let n = model.joint_count();
            for (contact, _) in checker.contacts(&chain, ProbeState::Absent) {
                let link_of = |b: &str| named_segment(&model, &chain, b).map_or(n, |s| s.0);
                let (la, lb) = (link_of(&contact.body), link_of(&contact.other));
                proptest::prop_assert!(la.abs_diff(lb) >= 2, "{name}: adjacent links reported: {contact}");
                let (Some(a), Some(b)) =
                    (named_segment(&model, &chain, &contact.body), named_segment(&model, &chain, &contact.other))
                else {
                    continue; // an end-effector body: not a capsule
                };
                let reach = geometry.robot.chain_radius_mm(a.0) + geometry.robot.chain_radius_mm(b.0) + 2.0 * margin;
                proptest::prop_assert!(
                    segment_distance(a.1, a.2, b.1, b.2) < reach + 1e-6,
                    "{name}: {contact} reported but the capsules are apart"
                );
                let a2 = named_segment(&model, &chain2, &contact.body).expect("segment");
                let b2 = named_segment(&model, &chain2, &contact.other).expect("segment");
                for (ea, ea2) in [(a.1, a2.1), (a.2, a2.2)] {
                    for (eb, eb2) in [(b.1, b2.1), (b.2, b2.2)] {
                        let (d, d2) = ((ea - eb).norm(), (ea2 - eb2).norm());
                        proptest::prop_assert!(
                            !(d < reach && (d - d2).abs() < 1e-6),
                            "{name}: {contact} touch at a shared joint ({d} mm apart in every pose)"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn only_pairs_sharing_a_joint_are_left_out_of_the_self_collision_test() {
    let named = |pairs: &[(String, String)], a: &str, b: &str| pairs.iter().any(|(x, y)| x == a && y == b);
    // Meca500 on a table: upper arm and forearm touch 38 mm apart at the elbow corner, forearm
    // and flange at the wrist centre; both are left out, the elbow corner and the flange are not
    let (model, geometry) = any_chain_fixture("meca500-table.toml");
    let pairs = CollisionChecker::new(&model, &geometry, 2.0).expect("checker").self_collision_pairs();
    assert!(!named(&pairs, "link 2 (a_2)", "link 4 (d_4)"), "{pairs:?}");
    assert!(!named(&pairs, "link 4 (d_4)", "link 6 (d_6)"), "{pairs:?}");
    assert!(named(&pairs, "link 3 (a_3)", "link 6 (d_6)"), "{pairs:?}");
    assert!(named(&pairs, "link 1 (d_1)", "link 3 (a_3)"), "{pairs:?}");
    // UR5e: no two of its link capsules share a joint point, every pair 2 links apart is tested
    let (model, geometry) = any_chain_fixture("ur5e.toml");
    let checker = CollisionChecker::new(&model, &geometry, 2.0).expect("checker");
    assert_eq!(checker.self_collision_pairs().len(), 30);
    // a plate 3 m wide touches the base column in every configuration without sharing a joint
    // with it: still tested, so every pose is rejected rather than the pair silently skipped
    let huge = CellGeometry {
        end_effector: vatcal_planning::geometry::EndEffectorGeometry {
            plate_half_extents_mm: [1500.0, 1500.0, 1500.0],
            ..Default::default()
        },
        ..geometry
    };
    let checker = CollisionChecker::new(&model, &huge, 2.0).expect("checker");
    assert!(named(&checker.self_collision_pairs(), "link 1 (d_1)", "plate"));
    let home = deg([0.0, -90.0, 0.0, -90.0, 0.0, 0.0]);
    assert!(checker.check(&home, ProbeState::Absent).is_some());
}
