//! Synthetic chains: random URDF chains (any axes, prismatic joints, fixed joints anywhere,
//! exactly / nearly parallel axes, side branches) and hand-made special cases. FK of the
//! imported rows must equal the URDF's FK to 1e-9 mm.

use crate::common;

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt::Write as _;

use common::max_deviation_mm;
use proptest::prelude::*;
use vatcal_urdf::{ImportedChain, JointKind, import_str};

#[derive(Debug, Clone)]
struct JointSpec {
    /// "fixed", "revolute", "continuous", "prismatic"
    kind: &'static str,
    xyz: [f64; 3],
    rpy: [f64; 3],
    axis: [f64; 3],
}

fn v3(v: [f64; 3]) -> String {
    format!("{} {} {}", v[0], v[1], v[2])
}

/// URDF text of a chain l0 - j1 - l1 - ... - jn - ln, every link with a mass, plus a fixed
/// side link and a moving side link hanging off `l{side}`.
fn chain_urdf(joints: &[JointSpec], side: usize) -> String {
    let mut t = String::from("<robot name=\"synthetic\">\n");
    let link = |t: &mut String, name: &str, k: usize| {
        let _ = writeln!(
            t,
            "<link name=\"{name}\"><inertial><origin xyz=\"{} {} {}\"/><mass value=\"{}\"/>\
             <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>",
            0.01 * k as f64,
            -0.02,
            0.005 * k as f64,
            0.5 + 0.25 * k as f64
        );
    };
    for k in 0..=joints.len() {
        link(&mut t, &format!("l{k}"), k);
    }
    link(&mut t, "side_fixed", 7);
    link(&mut t, "side_moving", 9);
    for (k, j) in joints.iter().enumerate() {
        let _ = writeln!(
            t,
            "<joint name=\"j{}\" type=\"{}\"><parent link=\"l{k}\"/><child link=\"l{}\"/>\
             <origin xyz=\"{}\" rpy=\"{}\"/><axis xyz=\"{}\"/>\
             <limit lower=\"-3.2\" upper=\"3.2\" effort=\"1\" velocity=\"1\"/></joint>",
            k + 1,
            j.kind,
            k + 1,
            v3(j.xyz),
            v3(j.rpy),
            v3(j.axis)
        );
    }
    let _ = writeln!(
        t,
        "<joint name=\"side_fixed_joint\" type=\"fixed\"><parent link=\"l{side}\"/><child link=\"side_fixed\"/>\
         <origin xyz=\"0.05 0.1 -0.02\" rpy=\"0.3 0.2 0.1\"/></joint>"
    );
    let _ = writeln!(
        t,
        "<joint name=\"side_moving_joint\" type=\"revolute\"><parent link=\"l{side}\"/><child link=\"side_moving\"/>\
         <origin xyz=\"0 0.1 0\"/><axis xyz=\"1 0 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>"
    );
    t.push_str("</robot>\n");
    t
}

fn joint_spec() -> impl Strategy<Value = JointSpec> {
    let kind = prop_oneof![2 => Just("fixed"), 4 => Just("revolute"), 1 => Just("continuous"), 2 => Just("prismatic")];
    let coord = || prop_oneof![2 => Just(0.0), 3 => -0.4f64..0.4];
    let angle = || {
        prop_oneof![
            4 => Just(0.0),
            1 => Just(FRAC_PI_2),
            1 => Just(-FRAC_PI_2),
            1 => Just(PI),
            1 => -0.01f64..0.01,   // nearly parallel: Hayati rows with beta != 0
            1 => 0.015f64..0.05,   // just past the tolerance: far common normals
            3 => -3.2f64..3.2,
        ]
    };
    let axis = prop_oneof![
        3 => Just([0.0, 0.0, 1.0]),
        1 => Just([0.0, 1.0, 0.0]),
        1 => Just([1.0, 0.0, 0.0]),
        1 => Just([0.0, 0.0, -1.0]),
        1 => Just([0.0, -2.0, 0.0]),
        3 => [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0]
            .prop_filter("usable axis", |a| a.iter().map(|v| v * v).sum::<f64>() > 0.01),
    ];
    (kind, [coord(), coord(), coord()], [angle(), angle(), angle()], axis)
        .prop_map(|(kind, xyz, rpy, axis)| JointSpec { kind, xyz, rpy, axis })
}

fn chain_spec() -> impl Strategy<Value = (Vec<JointSpec>, usize)> {
    proptest::collection::vec(joint_spec(), 1..=9)
        .prop_map(|mut js| {
            if js.iter().all(|j| j.kind == "fixed") {
                js[0].kind = "revolute";
            }
            js
        })
        .prop_flat_map(|js| {
            let n = js.len();
            (Just(js), 0..=n)
        })
}

/// URDF joint positions (rad / m) by name from raw values in -3.2..3.2.
fn joint_values(chain: &ImportedChain, raw: &[f64]) -> HashMap<String, f64> {
    chain
        .joints
        .iter()
        .zip(raw)
        .map(|(j, v)| (j.name.clone(), if j.kind == JointKind::Prismatic { 0.1 * v } else { *v }))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_chains_fk_and_masses(
        (joints, side) in chain_spec(),
        raw in proptest::collection::vec(-3.2f64..3.2, 9),
    ) {
        let text = chain_urdf(&joints, side);
        let n = joints.len();
        let chain = import_str(&text, "random.urdf", "l0", &format!("l{n}"))
            .map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        let robot = urdf_rs::read_from_string(&text).expect("parse");
        // FK of the TCP and of every COM
        for q in [vec![0.0; 9], raw] {
            let dev = max_deviation_mm(&robot, &chain, &joint_values(&chain, &q));
            prop_assert!(dev < 1e-9, "deviation {dev:e} mm\n{text}\n{chain:#?}");
        }
        // the right links in the right frames: link k belongs to the frame of the last actuated
        // joint among j1..jk; links before the first actuated joint and the moving side link
        // are left out; the fixed side link goes with l{side}
        let mut frame_of_link = vec![0usize; n + 1];
        let mut frame = 0;
        for (k, j) in joints.iter().enumerate() {
            if j.kind != "fixed" {
                frame += 1;
            }
            frame_of_link[k + 1] = frame;
        }
        let mut expected: HashMap<usize, Vec<String>> = HashMap::new();
        for (k, &f) in frame_of_link.iter().enumerate() {
            if f > 0 {
                expected.entry(f).or_default().push(format!("l{k}"));
            }
        }
        if frame_of_link[side] > 0 {
            expected.entry(frame_of_link[side]).or_default().push("side_fixed".into());
        }
        prop_assert_eq!(chain.inertials.len(), expected.len());
        for i in &chain.inertials {
            let mut got: Vec<String> = i.urdf_link.as_deref().unwrap_or_default().split('+').map(String::from).collect();
            let mut want = expected[&(i.frame as usize)].clone();
            got.sort();
            want.sort();
            prop_assert_eq!(got, want, "frame {}", i.frame);
        }
        // side_moving moves with a joint that is not on the chain: always left out, with a note
        prop_assert!(chain.notes.iter().any(|s| s.contains("side_moving")));
        prop_assert_eq!(chain.joints.len(), joints.iter().filter(|j| j.kind != "fixed").count());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Chains that go up the tree: from the last link back to `l0` (every joint reversed), and
    /// from link `l{b}` to the moving side link (up or down to `l{side}`, then down its joint).
    #[test]
    fn random_paths_up_the_tree_fk_and_masses(
        (joints, side) in chain_spec(),
        b_raw in 0usize..10,
        raw in proptest::collection::vec(-3.2f64..3.2, 10),
    ) {
        let text = chain_urdf(&joints, side);
        let n = joints.len();
        let b = b_raw % (n + 1);
        let robot = urdf_rs::read_from_string(&text).expect("parse");
        for (base, tip) in [(format!("l{n}"), "l0".to_string()), (format!("l{b}"), "side_moving".to_string())] {
            let chain = import_str(&text, "random.urdf", &base, &tip)
                .map_err(|e| TestCaseError::fail(format!("{base} -> {tip}: {e}\n{text}")))?;
            for q in [vec![0.0; 10], raw.clone()] {
                let dev = max_deviation_mm(&robot, &chain, &joint_values(&chain, &q));
                prop_assert!(dev < 1e-9, "{base} -> {tip}: deviation {dev:e} mm\n{text}\n{chain:#?}");
            }
            // reversed exactly on the joints above the base link
            for j in &chain.joints {
                let k: usize = j.name.trim_start_matches('j').parse().unwrap_or(usize::MAX);
                let above_base = j.name != "side_moving_joint" && k <= n && k > side.min(b) && k <= b;
                let above_base = above_base || (tip == "l0");
                prop_assert_eq!(j.reversed, above_base, "{} -> {}: {}", base, tip, j.name);
            }
        }
        // ln -> l0: link l_k moves with the actuated joints among j_{k+1}..j_n
        let chain = import_str(&text, "random.urdf", &format!("l{n}"), "l0").expect("imported above");
        for i in &chain.inertials {
            for name in i.urdf_link.as_deref().unwrap_or_default().split('+') {
                let k: usize = match name {
                    "side_fixed" => side,
                    other => other.trim_start_matches('l').parse().expect("chain link"),
                };
                let frame = joints[k..].iter().filter(|j| j.kind != "fixed").count();
                prop_assert_eq!(i.frame as usize, frame, "{}", name);
            }
        }
        prop_assert!(chain.notes.iter().any(|s| s.contains("side_moving")));
    }
}

/// Deterministic joint vectors (rad / m) for the hand-made cases.
fn samples(chain: &ImportedChain) -> Vec<HashMap<String, f64>> {
    (0..20)
        .map(|s| {
            let raw: Vec<f64> =
                (0..chain.joints.len()).map(|k| 3.0 * ((s * 7 + k * 3) as f64 * 0.77).sin()).collect();
            joint_values(chain, &raw)
        })
        .collect()
}

fn import_and_check(joints: &[JointSpec]) -> ImportedChain {
    let text = chain_urdf(joints, 1);
    let chain = import_str(&text, "case.urdf", "l0", &format!("l{}", joints.len())).expect("import");
    let robot = urdf_rs::read_from_string(&text).expect("parse");
    for q in samples(&chain) {
        let dev = max_deviation_mm(&robot, &chain, &q);
        assert!(dev < 1e-9, "deviation {dev:e} mm for {chain:#?}");
    }
    chain
}

fn j(kind: &'static str, xyz: [f64; 3], rpy: [f64; 3], axis: [f64; 3]) -> JointSpec {
    JointSpec { kind, xyz, rpy, axis }
}

const Z: [f64; 3] = [0.0, 0.0, 1.0];
const O: [f64; 3] = [0.0, 0.0, 0.0];

#[test]
fn parallel_axes_use_hayati_rows_with_zero_beta() {
    let c = import_and_check(&[
        j("revolute", [0.0, 0.0, 0.1], O, Z),
        j("revolute", [0.3, 0.05, 0.02], O, Z),
        j("revolute", [0.25, -0.1, 0.04], O, Z),
        j("fixed", [0.1, 0.0, 0.03], O, Z),
    ]);
    for r in &c.joints {
        assert_eq!((r.alpha_deg, r.beta_deg), (0.0, 0.0), "{r:?}");
    }
    // the Hayati frame keeps the origin the previous row gave it
    assert_eq!(c.joints[1].d_mm, 0.0);
    assert!((c.joints[1].a_mm - (300.0f64.hypot(50.0))).abs() < 1e-9);
}

#[test]
fn nearly_parallel_axes_give_beta_or_alpha() {
    let tilt = 0.3f64.to_radians();
    // tilt about y (towards x_1): beta
    let c = import_and_check(&[j("revolute", O, O, Z), j("revolute", [0.2, 0.0, 0.05], [0.0, tilt, 0.0], Z)]);
    assert!((c.joints[1].beta_deg - 0.3).abs() < 1e-9, "{:?}", c.joints[1]);
    assert_eq!(c.joints[1].alpha_deg, 0.0);
    // x_1 aims at where axis 2 crosses the plane z_1 = 0
    assert!((c.joints[1].a_mm - (200.0 - 50.0 * tilt.tan())).abs() < 1e-9, "{:?}", c.joints[1]);
    // tilt about x (across x_1): alpha, beta = 0
    let c = import_and_check(&[j("revolute", O, O, Z), j("revolute", [0.2, 0.0, 0.0], [tilt, 0.0, 0.0], Z)]);
    assert!((c.joints[1].alpha_deg - 0.3).abs() < 1e-9, "{:?}", c.joints[1]);
    assert_eq!(c.joints[1].beta_deg, 0.0);
    // 2° is past the tolerance: classic common normal (beta = 0), far away along z
    let c = import_and_check(&[
        j("revolute", O, O, Z),
        j("revolute", [0.2, 0.0, 0.05], [2f64.to_radians(), 0.0, 0.0], Z),
        j("revolute", [0.1, 0.0, 0.0], [0.0, FRAC_PI_2, 0.0], Z),
    ]);
    assert_eq!(c.joints[1].beta_deg, 0.0);
    assert!((c.joints[1].alpha_deg - 2.0).abs() < 1e-9);
}

#[test]
fn prismatic_guide_along_base_x_then_arm() {
    let c = import_and_check(&[
        j("prismatic", [0.1, 0.0, 0.0], O, [1.0, 0.0, 0.0]),
        j("fixed", [0.0, 0.0, 0.05], [0.0, 0.0, 0.4], Z),
        j("revolute", [0.0, 0.0, 0.08], O, Z),
        j("prismatic", [0.05, 0.0, 0.0], [0.0, 0.0, 0.0], Z),
        j("revolute", [0.1, 0.02, 0.0], [0.0, FRAC_PI_2, 0.0], [0.0, 1.0, 0.0]),
    ]);
    assert_eq!(c.joints[0].kind, JointKind::Prismatic);
    assert_eq!(c.joints[2].kind, JointKind::Prismatic);
    // z_1 along the base's x axis: row 1 tilts by alpha_0 = 90° to keep the base angles regular
    assert_eq!(c.joints[0].alpha_deg, 90.0);
    assert_eq!((c.joints[0].q_min, c.joints[0].q_max), (Some(-3200.0), Some(3200.0)));
}

#[test]
fn coincident_antiparallel_and_intersecting_axes() {
    import_and_check(&[
        j("revolute", O, O, Z),
        j("revolute", [0.0, 0.0, 0.1], O, [0.0, 0.0, -1.0]), // same line, opposite sense
        j("revolute", [0.0, 0.0, 0.1], O, [1.0, 0.0, 0.0]),  // intersecting
        j("revolute", O, [0.2, -0.4, 1.0], [0.0, 1.0, 0.0]), // through the same point
        j("fixed", [0.0, 0.0, 0.07], [PI, 0.0, 0.0], Z),
    ]);
}

#[test]
fn single_joint_and_tip_frame_choice() {
    let c = import_and_check(&[j("continuous", [0.1, 0.2, 0.3], [0.1, 0.2, 0.3], [0.3, -0.5, 0.8])]);
    assert_eq!(c.joints.len(), 1);
    assert!(c.joints[0].continuous && c.joints[0].q_min.is_none() && c.joints[0].q_max.is_none());
    // tip on the axis with its z along it: frame N is the tip frame, TCP at the origin
    let c = import_and_check(&[j("revolute", O, O, Z), j("fixed", [0.0, 0.0, 0.1], [0.0, 0.0, 0.7], Z)]);
    assert_eq!(c.tcp_mm, [0.0, 0.0, 0.0]);
    // frame 0 = frame 1 at q = 0: the base pose carries the tip's height and rotation
    assert_eq!(
        (c.base_in_world.z_mm, c.base_in_world.alpha_deg, c.base_in_world.beta_deg),
        (100.0, 0.0, 0.0)
    );
    assert!((c.base_in_world.gamma_deg - 0.7f64.to_degrees()).abs() < 1e-9);
}

#[test]
fn side_branches_are_lumped_or_left_out_with_a_note() {
    // side links hang off l1 (moved by j1)
    let c = import_and_check(&[
        j("revolute", O, O, Z),
        j("fixed", [0.1, 0.0, 0.0], O, Z),
        j("revolute", [0.1, 0.0, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
    ]);
    assert_eq!(c.inertials[0].urdf_link.as_deref(), Some("l1+l2+side_fixed"));
    assert!((c.inertials[0].mass_kg - (0.75 + 2.25 + 1.0)).abs() < 1e-12);
    assert!(
        c.notes.iter().any(|n| n.contains("side_moving") && n.contains("side_moving_joint")),
        "{:?}",
        c.notes
    );
}

#[test]
fn twelve_joints_are_accepted() {
    let js: Vec<JointSpec> = (0..12)
        .map(|k| {
            j(
                if k % 3 == 2 { "prismatic" } else { "revolute" },
                [0.05, 0.01 * k as f64, 0.02],
                [0.3 * k as f64, 0.5, -0.2],
                Z,
            )
        })
        .collect();
    assert_eq!(import_and_check(&js).joints.len(), 12);
}

/// A 3-joint URDF whose links carry the given `<collision>` elements (base, l1, l1 fixed child,
/// l2, l3).
fn collision_urdf(collisions: [&str; 5]) -> String {
    let [c0, c1, c1b, c2, c3] = collisions;
    format!(
        r#"<robot name="caps">
  <link name="base">{c0}</link> <link name="l1">{c1}</link> <link name="l1b">{c1b}</link>
  <link name="l2">{c2}</link> <link name="l3">{c3}</link>
  <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/></joint>
  <joint name="fix" type="fixed"><parent link="l1"/><child link="l1b"/><origin xyz="0 0 0.05"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.1" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/></joint>
</robot>"#
    )
}

fn collision(geometry: &str) -> String {
    format!(r#"<collision><origin xyz="0 0 0.02"/><geometry>{geometry}</geometry></collision>"#)
}

#[test]
fn collision_primitives_give_one_capsule_radius_per_link() {
    let cyl = collision(r#"<cylinder radius="0.075" length="0.1"/>"#);
    let l1 = format!(
        "{}{}",
        collision(r#"<cylinder radius="0.06" length="0.2"/>"#),
        collision(r#"<mesh filename="package://x/l1.stl"/>"#)
    );
    // box 50 x 80 x 300 mm: half its cross-section diagonal is 47.2 mm, below l1's 60 mm
    let l1b = collision(r#"<box size="0.05 0.3 0.08"/>"#);
    let l2 = collision(r#"<sphere radius="0.07"/>"#);
    let c =
        import_str(&collision_urdf([&cyl, &l1, &l1b, &l2, ""]), "caps.urdf", "base", "l3").expect("import");
    assert_eq!(
        c.link_radii_mm.as_deref(),
        Some(&[75.0, 60.0, 70.0, vatcal_urdf::DEFAULT_LINK_RADIUS_MM][..])
    );
    assert!(c.notes.iter().any(|n| n.contains("mesh")), "{:?}", c.notes);
    assert!(c.notes.iter().any(|n| n.contains("links 3 have no <collision> primitive")), "{:?}", c.notes);
    // the written cell carries them in [obstacles.robot_links] and reads back unchanged
    let text = c.to_cell("caps.urdf").to_toml_string().expect("toml");
    let cell = vatcal_core::CellFile::from_toml_str(&text, "caps.toml").expect("cell");
    let radii =
        cell.obstacles.as_ref().and_then(|o| o.extra.get("robot_links")).and_then(|t| t.get("link_radii_mm"));
    let radii: Vec<f64> = radii
        .and_then(|v| v.as_array())
        .expect("link_radii_mm")
        .iter()
        .filter_map(|v| v.as_float())
        .collect();
    assert_eq!(radii, vec![75.0, 60.0, 70.0, 30.0]);
    // a 47.2 mm box alone on link 1 sets its radius
    let c = import_str(&collision_urdf(["", "", &l1b, "", ""]), "caps.urdf", "base", "l3").expect("import");
    let r1 = c.link_radii_mm.expect("radii")[1];
    assert!((r1 - 0.5 * 50f64.hypot(80.0)).abs() < 1e-9, "{r1}");
    // meshes only, or no <collision> at all: no radii, no [obstacles] table
    let mesh = collision(r#"<mesh filename="package://x/l1.stl"/>"#);
    let c = import_str(&collision_urdf(["", &mesh, "", "", ""]), "caps.urdf", "base", "l3").expect("import");
    assert_eq!(c.link_radii_mm, None);
    assert!(c.notes.iter().any(|n| n.contains("mesh")), "{:?}", c.notes);
    let c = import_str(&collision_urdf(["", "", "", "", ""]), "caps.urdf", "base", "l3").expect("import");
    assert!(c.to_cell("caps.urdf").obstacles.is_none());
    // a zero radius is an error naming the link
    let zero = collision(r#"<sphere radius="0"/>"#);
    let err =
        import_str(&collision_urdf(["", "", "", &zero, ""]), "caps.urdf", "base", "l3").expect_err("zero");
    assert!(err.to_string().contains("l2"), "{err}");
}
