//! A chain that goes up a URDF tree: `fixtures/humanoid-tree.urdf` imported from the left sole to
//! the left gripper (up the leg with its six joints reversed, through the pelvis and the torso,
//! down the arm). FK of the rows against the tree's own FK (every link from the root, then seen
//! from the sole) at random joint vectors, masses included.

use crate::common;

use std::collections::HashMap;

use common::{fixture, max_deviation_mm, mdh_frames, urdf_link_poses};
use nalgebra::{Point3, Vector3};
use proptest::prelude::*;
use vatcal_urdf::{ImportedChain, JointKind, UrdfFk, import_file};

const BASE: &str = "left_sole_link";
const TIP: &str = "gripper_left_base_link";

fn humanoid(base: &str, tip: &str) -> (urdf_rs::Robot, ImportedChain) {
    let path = fixture("humanoid-tree.urdf");
    (urdf_rs::read_file(&path).expect("parse"), import_file(&path, base, tip).expect("import"))
}

/// URDF joint positions (rad) by name: `u` in 0..1 mapped into each joint's limits.
fn within_limits(chain: &ImportedChain, u: &[f64]) -> HashMap<String, f64> {
    chain
        .joints
        .iter()
        .zip(u)
        .map(|(j, u)| {
            let (lo, hi) = (j.q_min.expect("limited"), j.q_max.expect("limited"));
            (j.name.clone(), (lo + (hi - lo) * u).to_radians())
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn sole_to_gripper_fk_matches_the_tree(u in proptest::collection::vec(0.0f64..1.0, 12)) {
        let (robot, chain) = humanoid(BASE, TIP);
        let q = within_limits(&chain, &u);
        // TCP and every lumped centre of mass, against the whole tree's FK seen from the sole
        let dev = max_deviation_mm(&robot, &chain, &q);
        prop_assert!(dev < 1e-9, "deviation {dev:e} mm");
        // the public URDF FK (inverse transforms for the reversed joints) agrees too
        let fk = UrdfFk::new(
            &std::fs::read_to_string(fixture("humanoid-tree.urdf")).expect("read"),
            "humanoid-tree.urdf",
            BASE,
            TIP,
        )
        .expect("fk");
        let q_file: Vec<f64> = chain.joints.iter().map(|j| q[&j.name].to_degrees()).collect();
        let p = fk.tip_position_mm(&q_file).expect("12 values");
        let tip = urdf_link_poses(&robot, BASE, &q)[TIP] * Point3::origin();
        prop_assert!((Vector3::from(p) - tip.coords).norm() < 1e-9);
    }

    #[test]
    fn gripper_to_sole_and_arm_to_arm_fk(u in proptest::collection::vec(0.0f64..1.0, 12)) {
        for (base, tip) in [(TIP, BASE), ("gripper_right_base_link", TIP), ("right_sole_link", BASE)] {
            let (robot, chain) = humanoid(base, tip);
            let dev = max_deviation_mm(&robot, &chain, &within_limits(&chain, &u));
            prop_assert!(dev < 1e-9, "{base} -> {tip}: deviation {dev:e} mm");
        }
    }
}

#[test]
fn sole_to_gripper_goes_up_the_leg_then_down_the_arm() {
    let (_, chain) = humanoid(BASE, TIP);
    let names: Vec<&str> = chain.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "leg_left_6_joint",
            "leg_left_5_joint",
            "leg_left_4_joint",
            "leg_left_3_joint",
            "leg_left_2_joint",
            "leg_left_1_joint",
            "torso_1_joint",
            "arm_left_1_joint",
            "arm_left_2_joint",
            "arm_left_3_joint",
            "arm_left_4_joint",
            "arm_left_5_joint",
        ]
    );
    let reversed: Vec<bool> = chain.joints.iter().map(|j| j.reversed).collect();
    assert_eq!(reversed, [[true; 6].as_slice(), &[false; 6]].concat());
    // a reversed joint leads to its URDF parent: the leg's last row reaches the pelvis
    assert_eq!(chain.joints[5].child_link, "base_link");
    assert!(chain.joints.iter().all(|j| j.kind == JointKind::Revolute));
    // limits are the URDF's (joint values keep the URDF sign)
    assert!((chain.joints[3].q_min.expect("limit") - (-2.1f64).to_degrees()).abs() < 1e-9);
    // the tip frame is the gripper's own frame
    assert_eq!(chain.tcp_mm, [0.0, 0.0, 0.0]);
    // the pelvis moves with the last leg row, the torso links with the torso joint; the other
    // leg, the head, the other arm and the fingers are left out with notes
    let frame_of = |link: &str| {
        chain
            .inertials
            .iter()
            .find(|i| i.urdf_link.as_deref().unwrap_or_default().split('+').any(|l| l == link))
            .map(|i| i.frame)
    };
    assert_eq!(frame_of("base_link"), Some(6));
    assert_eq!(frame_of("torso_2_link"), Some(7));
    assert_eq!(frame_of("gripper_left_base_link"), Some(12));
    assert_eq!(frame_of("leg_left_6_link"), None, "fixed to the sole: does not move");
    for off in ["leg_right_3_link", "head_2_link", "arm_right_4_link", "gripper_left_finger_link"] {
        assert_eq!(frame_of(off), None, "{off}");
        assert!(chain.notes.iter().any(|n| n.contains(&format!("`{off}`"))), "{off}: {:?}", chain.notes);
    }
    assert!(chain.notes[0].contains("leg_left_6_joint") && chain.notes[0].contains("up the tree"));
    // one capsule radius per MDH link 0..12 from the <collision> primitives
    assert_eq!(chain.link_radii_mm.as_ref().map(Vec::len), Some(13));
}

#[test]
fn at_zero_the_gripper_is_where_the_tree_puts_it() {
    let (robot, chain) = humanoid(BASE, TIP);
    let zero: HashMap<String, f64> = HashMap::new();
    let tip = urdf_link_poses(&robot, BASE, &zero)[TIP] * Point3::origin();
    let frames = mdh_frames(&chain, &[0.0; 12]);
    let tcp = frames[12] * Point3::from(Vector3::from(chain.tcp_mm));
    assert!((tcp - tip).norm() < 1e-9);
    assert!(tip.z > 800.0, "the gripper (arm hanging down) is well above the sole: {tip}");
}

#[test]
fn still_refused_on_the_tree() {
    let path = fixture("humanoid-tree.urdf");
    // an unknown link lists the known ones
    let e = import_file(&path, "left_foot", TIP).expect_err("unknown");
    assert!(e.to_string().contains("`left_foot`") && e.to_string().contains("base_link"), "{e}");
    // base == tip
    let e = import_file(&path, TIP, TIP).expect_err("same link");
    assert!(e.to_string().contains("same link"), "{e}");
    // a mimic finger on the chain
    let e = import_file(&path, BASE, "gripper_left_finger_2_link").expect_err("mimic");
    assert!(e.to_string().contains("mimics joint `gripper_left_finger_joint`"), "{e}");
    // sole -> other gripper through the right arm: 6 + 1 + 5 = 12 joints is fine; sole -> sole
    // through both legs too (6 + 6)
    assert_eq!(import_file(&path, BASE, "gripper_right_base_link").expect("12").joints.len(), 12);
    assert_eq!(import_file(&path, BASE, "right_sole_link").expect("12").joints.len(), 12);
    // one more joint is too many: the right finger beyond the right gripper
    let e = import_file(&path, BASE, "gripper_right_finger_link").expect_err("13 joints");
    assert!(e.to_string().contains("13 actuated joints"), "{e}");
}
