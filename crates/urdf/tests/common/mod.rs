//! Independent forward kinematics for the tests: the URDF's own joint origins and axes on one
//! side, a plain product of MDH + beta transforms on the other. Nothing here uses the crate's
//! conversion code.

#![allow(dead_code)]

use std::collections::HashMap;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use vatcal_urdf::{ImportedChain, JointKind};

/// Path of a fixture file.
pub fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn rx(a: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a)
}
fn ry(a: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a)
}
fn rz(a: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a)
}
fn rot(q: UnitQuaternion<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::identity(), q)
}
fn tr(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::translation(x, y, z)
}

/// Poses [mm] of every link of the tree in the frame of `base`, for URDF joint positions `q` by
/// joint name (rad / m; joints not in `q` stay at 0): the plain forward kinematics of the whole
/// tree from its root(s), then seen from `base` (`pose(base)⁻¹ · pose(link)`).
pub fn urdf_link_poses(
    robot: &urdf_rs::Robot,
    base: &str,
    q: &HashMap<String, f64>,
) -> HashMap<String, Isometry3<f64>> {
    let roots: Vec<String> = robot
        .links
        .iter()
        .filter(|l| !robot.joints.iter().any(|j| j.child.link == l.name))
        .map(|l| l.name.clone())
        .collect();
    let mut poses = HashMap::new();
    for r in &roots {
        poses.insert(r.clone(), Isometry3::identity());
    }
    let mut stack = roots;
    while let Some(l) = stack.pop() {
        let parent = poses[&l];
        for j in robot.joints.iter().filter(|j| j.parent.link == l) {
            let o = &j.origin;
            // URDF: R = Rz(yaw) Ry(pitch) Rx(roll)
            let origin = Isometry3::from_parts(
                Translation3::new(o.xyz[0] * 1000.0, o.xyz[1] * 1000.0, o.xyz[2] * 1000.0),
                UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]),
            );
            let v = q.get(&j.name).copied().unwrap_or(0.0);
            let axis = Unit::new_normalize(Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]));
            let motion = match j.joint_type {
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                    rot(UnitQuaternion::from_axis_angle(&axis, v))
                }
                urdf_rs::JointType::Prismatic => {
                    let t = axis.into_inner() * v * 1000.0;
                    tr(t.x, t.y, t.z)
                }
                _ => Isometry3::identity(),
            };
            poses.insert(j.child.link.clone(), parent * origin * motion);
            stack.push(j.child.link.clone());
        }
    }
    let from_base = poses[base].inverse();
    poses.into_iter().map(|(name, p)| (name, from_base * p)).collect()
}

/// MDH frames 0..=N [mm] in the base-link frame for joint values `q_file` (deg / mm), by the
/// plain product `T(x,y,z) Rx Ry Rz · Π Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`.
pub fn mdh_frames(chain: &ImportedChain, q_file: &[f64]) -> Vec<Isometry3<f64>> {
    let b = &chain.base_in_world;
    let mut x = tr(b.x_mm, b.y_mm, b.z_mm)
        * rot(rx(b.alpha_deg.to_radians()))
        * rot(ry(b.beta_deg.to_radians()))
        * rot(rz(b.gamma_deg.to_radians()));
    let mut out = vec![x];
    for (j, q) in chain.joints.iter().zip(q_file) {
        let (theta, d) = match j.kind {
            JointKind::Revolute => ((j.theta_deg + q).to_radians(), j.d_mm),
            JointKind::Prismatic => (j.theta_deg.to_radians(), j.d_mm + q),
        };
        x = x
            * rot(rx(j.alpha_deg.to_radians()))
            * tr(j.a_mm, 0.0, 0.0)
            * rot(ry(j.beta_deg.to_radians()))
            * rot(rz(theta))
            * tr(0.0, 0.0, d);
        out.push(x);
    }
    out
}

/// URDF joint positions (rad / m by name) → file units (deg / mm, in row order).
pub fn file_units(chain: &ImportedChain, q: &HashMap<String, f64>) -> Vec<f64> {
    chain
        .joints
        .iter()
        .map(|j| match j.kind {
            JointKind::Revolute => q[&j.name].to_degrees(),
            JointKind::Prismatic => q[&j.name] * 1000.0,
        })
        .collect()
}

/// Largest distance [mm] between the TCP and the tip origin, and between each imported COM and
/// the mass-weighted COM of the URDF links it lumps, for URDF joint positions `q`.
pub fn max_deviation_mm(robot: &urdf_rs::Robot, chain: &ImportedChain, q: &HashMap<String, f64>) -> f64 {
    let poses = urdf_link_poses(robot, &chain.base_link, q);
    let frames = mdh_frames(chain, &file_units(chain, q));
    let tcp = frames[chain.joints.len()] * Point3::from(Vector3::from(chain.tcp_mm));
    let tip = poses[&chain.tip_link] * Point3::origin();
    let mut worst = (tcp - tip).norm();
    for inertial in &chain.inertials {
        let names = inertial.urdf_link.as_deref().unwrap_or_default();
        let mut m = 0.0;
        let mut mc = Vector3::zeros();
        for name in names.split('+') {
            let link = robot.links.iter().find(|l| l.name == name).expect("lumped link exists");
            let c = &link.inertial.origin.xyz;
            let p = poses[name] * Point3::new(c[0] * 1000.0, c[1] * 1000.0, c[2] * 1000.0);
            m += link.inertial.mass.value;
            mc += p.coords * link.inertial.mass.value;
        }
        assert!((m - inertial.mass_kg).abs() < 1e-12, "mass of frame {}", inertial.frame);
        let com = frames[inertial.frame as usize] * Point3::from(Vector3::from(inertial.com_mm));
        worst = worst.max((com.coords - mc / m).norm());
    }
    worst
}
