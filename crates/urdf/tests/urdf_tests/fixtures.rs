//! The two robot fixtures: FK of the imported MDH rows equals the URDF's own FK (proptest), and
//! the fixtures themselves are faithful to their sources (UR's DH table, the canonical cell).

use crate::common;

use std::collections::HashMap;

use common::{fixture, max_deviation_mm, mdh_frames};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use vatcal_urdf::{ImportedChain, JointKind, import_file};

fn ur5e() -> (urdf_rs::Robot, ImportedChain) {
    let path = fixture("ur5e.urdf");
    (urdf_rs::read_file(&path).expect("parse"), import_file(&path, "base_link", "tool0").expect("import"))
}

fn meca500() -> (urdf_rs::Robot, ImportedChain) {
    let path = fixture("meca500.urdf");
    (
        urdf_rs::read_file(&path).expect("parse"),
        import_file(&path, "meca_base_link", "meca_axis_6_link").expect("import"),
    )
}

fn by_name(chain: &ImportedChain, q: &[f64]) -> HashMap<String, f64> {
    chain.joints.iter().zip(q).map(|(j, v)| (j.name.clone(), *v)).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn ur5e_fk_matches_urdf(q in proptest::collection::vec(-6.3f64..6.3, 6)) {
        let (robot, chain) = ur5e();
        let dev = max_deviation_mm(&robot, &chain, &by_name(&chain, &q));
        prop_assert!(dev < 1e-9, "deviation {dev:e} mm");
    }

    #[test]
    fn meca500_fk_matches_urdf(q in proptest::collection::vec(-3.2f64..3.2, 6)) {
        let (robot, chain) = meca500();
        let dev = max_deviation_mm(&robot, &chain, &by_name(&chain, &q));
        prop_assert!(dev < 1e-9, "deviation {dev:e} mm");
    }
}

#[test]
fn ur5e_rows_limits_and_masses() {
    let (_, chain) = ur5e();
    assert_eq!(chain.robot_name, "ur5e");
    let names: Vec<&str> = chain.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "shoulder_pan_joint",
            "shoulder_lift_joint",
            "elbow_joint",
            "wrist_1_joint",
            "wrist_2_joint",
            "wrist_3_joint"
        ]
    );
    for j in &chain.joints {
        assert_eq!(j.kind, JointKind::Revolute);
        let lim = if j.name == "elbow_joint" { 180.0 } else { 360.0 };
        assert_eq!((j.q_min, j.q_max), (Some(-lim), Some(lim)), "{}", j.name);
    }
    // J2, J3, J4 are parallel: Hayati rows, exactly parallel so beta = 0
    for j in &chain.joints {
        assert_eq!(j.beta_deg, 0.0, "{}", j.name);
    }
    // tool0 lies on the J6 axis: the TCP is the origin of frame 6
    assert!(Vector3::from(chain.tcp_mm).norm() < 1e-9, "{:?}", chain.tcp_mm);
    let masses: Vec<(u8, f64)> = chain.inertials.iter().map(|i| (i.frame, i.mass_kg)).collect();
    assert_eq!(masses, [(1, 3.761), (2, 8.058), (3, 2.846), (4, 1.37), (5, 1.3), (6, 0.365)]);
    for r in &chain.joints {
        println!(
            "{:22} alpha {:8} a {:8} beta {:4} theta {:8} d {:8}",
            r.name, r.alpha_deg, r.a_mm, r.beta_deg, r.theta_deg, r.d_mm
        );
    }
    println!("base {:?}\ntcp {:?}\nnotes {:?}", chain.base_in_world, chain.tcp_mm, chain.notes);
}

/// UR's standard DH: T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), base_link = Rz(pi) · frame 0.
fn ur_dh_frames(q: &[f64]) -> Vec<Isometry3<f64>> {
    let d = [162.5, 0.0, 0.0, 133.3, 99.7, 99.6];
    let a = [0.0, -425.0, -392.2, 0.0, 0.0, 0.0];
    let alpha = [
        std::f64::consts::FRAC_PI_2,
        0.0,
        0.0,
        std::f64::consts::FRAC_PI_2,
        -std::f64::consts::FRAC_PI_2,
        0.0,
    ];
    let mut x = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::PI),
    );
    let mut out = Vec::new();
    for i in 0..6 {
        x =
            x * Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_euler_angles(0.0, 0.0, q[i]),
            ) * Isometry3::translation(0.0, 0.0, d[i])
                * Isometry3::translation(a[i], 0.0, 0.0)
                * Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_euler_angles(alpha[i], 0.0, 0.0),
                );
        out.push(x);
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The fixture is UR's published table: tool0 and every published COM land where the DH
    /// model puts them (so the import is checked against UR's numbers, not only the fixture).
    #[test]
    fn ur5e_fixture_is_the_published_dh_table(q in proptest::collection::vec(-3.2f64..3.2, 6)) {
        let (_, chain) = ur5e();
        let dh = ur_dh_frames(&q);
        let q_deg: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
        let frames = mdh_frames(&chain, &q_deg);
        let tcp = frames[6] * Point3::from(Vector3::from(chain.tcp_mm));
        prop_assert!((tcp - dh[5] * Point3::origin()).norm() < 1e-9);
        let com_dh = [
            [0.0, -25.61, 1.93], [212.5, 0.0, 113.36], [150.0, 0.0, 26.5],
            [0.0, -1.8, 16.34], [0.0, 1.8, 16.34], [0.0, 0.0, -1.159],
        ];
        for (i, c) in com_dh.iter().enumerate() {
            let inertial = &chain.inertials[i];
            let ours = frames[inertial.frame as usize] * Point3::from(Vector3::from(inertial.com_mm));
            let theirs = dh[i] * Point3::new(c[0], c[1], c[2]);
            prop_assert!((ours - theirs).norm() < 1e-9, "COM of link {}: {ours} vs {theirs}", i + 1);
        }
    }

    /// The Meca500 fixture is the canonical cell's arm (rows 2..7 of fixtures/meca500-zaber.toml,
    /// robot base frame = frame 1 · Rx(-90°)): flange and COMs agree.
    #[test]
    fn meca500_fixture_is_the_canonical_arm(q in proptest::collection::vec(-3.2f64..3.2, 6)) {
        let (_, chain) = meca500();
        let cell = vatcal_core::CellFile::load(fixture("meca500-zaber.toml")).expect("canonical cell");
        // canonical arm: row 2 without its mounting rotation, then rows 3..7
        let mut x = Isometry3::identity();
        let mut canon = Vec::new();
        for (k, row) in cell.joints.iter().skip(1).enumerate() {
            let (alpha, a) = if k == 0 { (0.0, 0.0) } else { (row.alpha_deg, row.a_mm) };
            x = x
                * Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_euler_angles(alpha.to_radians(), 0.0, 0.0))
                * Isometry3::translation(a, 0.0, 0.0)
                * Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_euler_angles(0.0, row.beta_deg.to_radians(), 0.0))
                * Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_euler_angles(0.0, 0.0, row.theta_deg.to_radians() + q[k]))
                * Isometry3::translation(0.0, 0.0, row.d_mm);
            canon.push(x);
        }
        let q_deg: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
        let frames = mdh_frames(&chain, &q_deg);
        let tcp = frames[6] * Point3::from(Vector3::from(chain.tcp_mm));
        prop_assert!((tcp - canon[5] * Point3::origin()).norm() < 1e-9, "flange {tcp} vs {}", canon[5] * Point3::origin());
        for l in &cell.inertials.links {
            let ours = chain.inertials.iter().find(|i| i.frame + 1 == l.frame).expect("same frames");
            prop_assert!((ours.mass_kg - l.mass_kg).abs() < 1e-12);
            let p_ours = frames[ours.frame as usize] * Point3::from(Vector3::from(ours.com_mm));
            let p_canon = canon[l.frame as usize - 2] * Point3::from(Vector3::from(l.com_mm));
            prop_assert!((p_ours - p_canon).norm() < 1e-9, "COM frame {}: {p_ours} vs {p_canon}", l.frame);
        }
    }
}

#[test]
fn meca500_rows_and_limits() {
    let (_, chain) = meca500();
    let lim =
        [(-175.0, 175.0), (-70.0, 90.0), (-135.0, 70.0), (-170.0, 170.0), (-115.0, 115.0), (-180.0, 180.0)];
    for (j, (lo, hi)) in chain.joints.iter().zip(lim) {
        assert_eq!((j.q_min, j.q_max), (Some(lo), Some(hi)), "{}", j.name);
    }
    // flange frame = tip link frame: TCP at its origin
    assert!(Vector3::from(chain.tcp_mm).norm() < 1e-9, "{:?}", chain.tcp_mm);
    // the base link's mass does not move and is not listed
    assert_eq!(chain.inertials.len(), 6);
    for r in &chain.joints {
        println!(
            "{:22} alpha {:8} a {:8} beta {:4} theta {:8} d {:8}",
            r.name, r.alpha_deg, r.a_mm, r.beta_deg, r.theta_deg, r.d_mm
        );
    }
    println!("base {:?}", chain.base_in_world);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The public URDF FK agrees with the tests' independent one.
    #[test]
    fn public_urdf_fk_matches_the_independent_one(q in proptest::collection::vec(-3.2f64..3.2, 6)) {
        let path = fixture("ur5e.urdf");
        let text = std::fs::read_to_string(&path).expect("read");
        let fk = vatcal_urdf::UrdfFk::new(&text, &path, "base_link", "tool0").expect("fk");
        let (robot, chain) = ur5e();
        prop_assert_eq!(fk.joint_count(), 6);
        prop_assert!(fk.tip_position_mm(&q[..5]).is_none());
        let q_deg: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
        let p = fk.tip_position_mm(&q_deg).expect("6 values");
        let poses = common::urdf_link_poses(&robot, "base_link", &by_name(&chain, &q));
        let tip = poses["tool0"] * Point3::origin();
        prop_assert!((Vector3::from(p) - tip.coords).norm() < 1e-9);
    }
}

#[test]
fn to_cell_is_a_valid_version_2_cell_that_round_trips() {
    for (chain, n) in [(ur5e().1, 6), (meca500().1, 6)] {
        let cell = chain.to_cell("fixture.urdf");
        assert_eq!((cell.format.as_str(), cell.version), ("serial-robot-cell", 2));
        cell.validate("to_cell").expect("valid cell");
        assert_eq!(cell.joints.len(), n);
        for (row, j) in cell.joints.iter().zip(&chain.joints) {
            assert_eq!((row.name.as_str(), row.kind.as_str()), (j.name.as_str(), "revolute"));
            assert_eq!(
                (row.alpha_deg, row.a_mm, row.beta_deg, row.theta_deg, row.d_mm),
                (j.alpha_deg, j.a_mm, j.beta_deg, j.theta_deg, j.d_mm)
            );
            assert_eq!((row.q_min, row.q_max), (j.q_min, j.q_max));
        }
        assert_eq!(cell.tcps.len(), 1);
        assert_eq!(cell.inertials.tool.frame as usize, n);
        assert_eq!(cell.inertials.tool.mass_kg, 0.0);
        // the placeholder calibration position is where TCP 1 is at q = 0
        let p = chain.tcp_at_zero_mm();
        let c = &cell.calibration_positions[0];
        assert_eq!([c.x_mm, c.y_mm, c.z_mm], p);
        let text = cell.to_toml_string().expect("serialise");
        let back = vatcal_core::CellFile::from_toml_str(&text, "round trip").expect("reload");
        assert_eq!(back, cell);
        assert!(text.contains("[urdf_import]") && text.contains("tip_link"), "{text}");
    }
    // UR5e at q = 0: tool0 at (a2 + a3, -d4 - d6, d1 - d5) = (-817.2, -232.9, 62.8) mm in UR's DH
    // base frame, i.e. (817.2, 232.9, 62.8) in base_link (turned 180° about z)
    let p = ur5e().1.tcp_at_zero_mm();
    let want = [817.2, 232.9, 62.8];
    for k in 0..3 {
        assert!((p[k] - want[k]).abs() < 1e-9, "{p:?}");
    }
}
