//! Every rejected case gives its own error, naming the file, the joint (and its line) or links.

use vatcal_urdf::{UrdfImportError, import_file, import_str};

const LIMIT: &str = r#"<limit lower="-1" upper="1" effort="1" velocity="1"/>"#;

/// base - j1 (revolute) - l1 - j2 (`kind`, extra XML) - l2 - j3 (revolute) - tip, plus a branch
/// `other` off base.
fn robot(kind: &str, extra: &str) -> String {
    format!(
        r#"<robot name="r">
  <link name="base"/>
  <link name="l1"/>
  <link name="l2"/>
  <link name="tip"/>
  <link name="other"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <joint name="j2" type="{kind}">
    <parent link="l1"/><child link="l2"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    {extra}
  </joint>
  <joint name="j3" type="revolute">
    <parent link="l2"/><child link="tip"/><origin xyz="0.1 0 0"/><axis xyz="1 0 0"/>{LIMIT}
  </joint>
  <joint name="branch" type="fixed">
    <parent link="base"/><child link="other"/>
  </joint>
</robot>
"#
    )
}

fn err(text: &str, base: &str, tip: &str) -> UrdfImportError {
    match import_str(text, "robot.urdf", base, tip) {
        Ok(c) => panic!("expected an error, got {c:#?}"),
        Err(e) => e,
    }
}

#[test]
fn the_reference_robot_imports() {
    let c = import_str(&robot("revolute", LIMIT), "robot.urdf", "base", "tip").expect("valid");
    assert_eq!(c.joints.len(), 3);
}

#[test]
fn unknown_links() {
    let t = robot("revolute", LIMIT);
    let e = err(&t, "bse", "tip");
    assert!(matches!(&e, UrdfImportError::UnknownLink { role: "base", link, .. } if link == "bse"), "{e}");
    assert!(e.to_string().contains("robot.urdf") && e.to_string().contains("base, l1"), "{e}");
    let e = err(&t, "base", "tool0");
    assert!(matches!(&e, UrdfImportError::UnknownLink { role: "tip", .. }), "{e}");
}

#[test]
fn paths_up_the_tree_and_what_is_still_refused() {
    let t = robot("revolute", LIMIT);
    // a sibling branch: up from `other` to `base` (a fixed joint), then down to `tip`
    let c = import_str(&t, "robot.urdf", "other", "tip").expect("sibling branch");
    assert_eq!(c.joints.iter().map(|j| j.reversed).collect::<Vec<_>>(), [false; 3]);
    // tip above base: the whole chain traversed backwards
    let c = import_str(&t, "robot.urdf", "tip", "base").expect("swapped");
    let names: Vec<&str> = c.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ["j3", "j2", "j1"]);
    assert!(c.joints.iter().all(|j| j.reversed));
    assert_eq!(c.joints[0].child_link, "l2", "a reversed joint leads to its URDF parent link");
    assert!(c.notes.iter().any(|n| n.contains("j3, j2, j1") && n.contains("up the tree")), "{:?}", c.notes);
    // the same link is still an error naming it
    let e = err(&t, "l1", "l1");
    assert!(matches!(&e, UrdfImportError::NoPath { base, tip, .. } if base == "l1" && tip == "l1"), "{e}");
    assert!(e.to_string().contains("the same link"), "{e}");
    // two separate trees
    let two = t.replace("</robot>", r#"<link name="a"/><link name="b"/><joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#);
    let e = err(&two, "tip", "b");
    assert!(matches!(&e, UrdfImportError::NoPath { .. }), "{e}");
    assert!(e.to_string().contains("two separate trees (roots `base` and `a`)"), "{e}");
}

#[test]
fn planar_floating_and_spherical_joints_are_named() {
    for kind in ["planar", "floating", "spherical"] {
        let e = err(&robot(kind, ""), "base", "tip");
        assert!(
            matches!(&e, UrdfImportError::UnsupportedJoint { joint, joint_type, .. } if joint == "j2" && joint_type == kind),
            "{e}"
        );
        // file and line of the joint element
        assert!(e.to_string().starts_with("robot.urdf:10: joint `j2`"), "{e}");
    }
    // the same joint outside the chain is fine
    assert!(import_str(&robot("planar", ""), "robot.urdf", "base", "l1").is_ok());
}

#[test]
fn mimic_joints_are_named() {
    let e = err(&robot("revolute", &format!(r#"{LIMIT}<mimic joint="j1" multiplier="2"/>"#)), "base", "tip");
    assert!(
        matches!(&e, UrdfImportError::MimicJoint { joint, mimicked, .. } if joint == "j2" && mimicked == "j1"),
        "{e}"
    );
    assert!(e.to_string().contains("robot.urdf:10"), "{e}");
}

#[test]
fn continuous_is_revolute_without_limits() {
    let c = import_str(&robot("continuous", ""), "robot.urdf", "base", "tip").expect("valid");
    assert!(c.joints[1].continuous);
    assert_eq!((c.joints[1].q_min, c.joints[1].q_max), (None, None));
    assert_eq!((c.joints[0].q_min, c.joints[0].q_max), (Some((-1f64).to_degrees()), Some(1f64.to_degrees())));
}

#[test]
fn unusable_joint_values() {
    let e = err(
        &robot("revolute", &format!(r#"{LIMIT}<axis xyz="0 0 0"/>"#)).replace(r#"<axis xyz="0 1 0"/>"#, ""),
        "base",
        "tip",
    );
    assert!(
        matches!(&e, UrdfImportError::InvalidJoint { joint, reason, .. } if joint == "j2" && reason.contains("axis")),
        "{e}"
    );
    // URDF 1.0 revolute joint without <limit>: limits 0..0
    let e = err(&robot("revolute", ""), "base", "tip");
    assert!(
        matches!(&e, UrdfImportError::InvalidJoint { reason, .. } if reason.contains("empty range")),
        "{e}"
    );
    // reversed limits
    let e = err(
        &robot("prismatic", r#"<limit lower="0.2" upper="0.1" effort="1" velocity="1"/>"#),
        "base",
        "tip",
    );
    assert!(matches!(&e, UrdfImportError::InvalidJoint { .. }), "{e}");
    // URDF 1.2: omitted bounds are unlimited: fine for a revolute joint, not for a prismatic one
    let v12 = |kind: &str| {
        robot(kind, r#"<limit effort="1" velocity="1"/>"#)
            .replace(r#"<robot name="r">"#, r#"<robot name="r" version="1.2">"#)
    };
    let c = import_str(&v12("revolute"), "robot.urdf", "base", "tip").expect("unlimited revolute");
    assert_eq!(c.joints[1].q_min, None);
    let e = err(&v12("prismatic"), "base", "tip");
    assert!(matches!(&e, UrdfImportError::InvalidJoint { reason, .. } if reason.contains("finite")), "{e}");
    // non-finite origin
    let e = err(
        &robot("revolute", LIMIT).replace(r#"<origin xyz="0.1 0 0"/>"#, r#"<origin xyz="inf 0 0"/>"#),
        "base",
        "tip",
    );
    assert!(matches!(&e, UrdfImportError::InvalidJoint { joint, .. } if joint == "j3"), "{e}");
}

#[test]
fn joint_counts() {
    // only fixed joints
    let e = err(&robot("revolute", LIMIT), "base", "other");
    assert!(matches!(e, UrdfImportError::JointCount { count: 0, .. }), "{e}");
    // 13 revolute joints
    let mut t = String::from("<robot name=\"long\"><link name=\"l0\"/>");
    for k in 1..=13 {
        t += &format!(
            "<link name=\"l{k}\"/><joint name=\"j{k}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{k}\"/>\
             <origin xyz=\"0.1 0 0\" rpy=\"0.5 0 0\"/><axis xyz=\"0 0 1\"/>{LIMIT}</joint>",
            k - 1
        );
    }
    t += "</robot>";
    let e = err(&t, "l0", "l13");
    assert!(matches!(e, UrdfImportError::JointCount { count: 13, .. }), "{e}");
    assert!(import_str(&t, "long.urdf", "l0", "l12").is_ok());
}

#[test]
fn broken_files() {
    assert!(matches!(
        err("<robot name=\"x\"><link name=\"a\"></robot>", "a", "a"),
        UrdfImportError::Parse { .. }
    ));
    // a link with two parents
    let t = robot("revolute", LIMIT).replace(r#"<child link="other"/>"#, r#"<child link="l2"/>"#);
    let e = err(&t, "base", "tip");
    assert!(
        matches!(&e, UrdfImportError::InvalidTree { reason, .. } if reason.contains("`l2`") && reason.contains("two joints")),
        "{e}"
    );
    // a joint naming a missing link
    let t = robot("revolute", LIMIT).replace(r#"<child link="other"/>"#, r#"<child link="nowhere"/>"#);
    assert!(matches!(err(&t, "base", "tip"), UrdfImportError::InvalidTree { .. }));
    // a negative mass on a moving link
    let t = robot("revolute", LIMIT).replace(
        r#"<link name="l2"/>"#,
        r#"<link name="l2"><inertial><mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>"#,
    );
    let e = err(&t, "base", "tip");
    assert!(matches!(&e, UrdfImportError::InvalidLink { link, .. } if link == "l2"), "{e}");
    assert!(e.to_string().starts_with("robot.urdf:4:"), "{e}");
    // missing file
    let e = import_file("/nonexistent/robot.urdf", "a", "b").expect_err("missing");
    assert!(
        matches!(&e, UrdfImportError::Io { .. }) && e.to_string().contains("/nonexistent/robot.urdf"),
        "{e}"
    );
}
