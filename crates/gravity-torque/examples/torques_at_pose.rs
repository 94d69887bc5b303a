//! Gravity torques of the canonical cell at a pose, from the cell file alone.
//!
//! This crate takes the link transforms `H_i^{i-1}`, the joint kinds and the masses of any
//! serial chain (1..=12 joints), so a user without
//! `vatcal-kinematics` builds the transforms from the cell file's MDH rows
//! (`Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`) and calls [`gravity_torques`]. (With
//! `vatcal-kinematics`, `Model::gravity_torques(&q)` does all of this.) Then a hand check: a
//! single 2 kg body 100 mm out on a horizontal link feels m·g·L = 1.962 N·m.
//!
//! ```text
//! cargo run -p vatcal-gravity-torque --example torques_at_pose
//! ```

use nalgebra::{Matrix3, Vector3};
use vatcal_core::frame::{rot_x, rot_y, rot_z};
use vatcal_core::{CellFile, Frame, JointKind, MAX_JOINTS, deg_to_rad};
use vatcal_gravity_torque::{Body, MassModel, gravity_torques};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let masses = MassModel::from_inertials(&cell.inertials);
    println!("moving mass (links 2..7 and the tool): {:.3} kg", masses.total_mass_kg());

    // one value per joint in file units: mm for the prismatic guide, degrees for the arm
    let q_file = [150.0, 10.0, 20.0, -30.0, 40.0, 50.0, 60.0];
    let kinds = cell.joint_kinds();
    let mut links = Vec::with_capacity(cell.joints.len());
    for (row, (kind, q)) in cell.joints.iter().zip(kinds.iter().zip(q_file)) {
        let (theta_deg, d) =
            if kind.is_revolute() { (row.theta_deg + q, row.d_mm) } else { (row.theta_deg, row.d_mm + q) };
        let fixed = Frame {
            r: rot_x(deg_to_rad(row.alpha_deg)) * rot_y(deg_to_rad(row.beta_deg)),
            p: Vector3::new(row.a_mm, 0.0, 0.0),
        };
        let moving = Frame { r: rot_z(deg_to_rad(theta_deg)), p: Vector3::new(0.0, 0.0, d) };
        links.push(fixed.compose(&moving));
    }
    let b = &cell.base_in_world;
    let base_rotation =
        rot_x(deg_to_rad(b.alpha_deg)) * rot_y(deg_to_rad(b.beta_deg)) * rot_z(deg_to_rad(b.gamma_deg));
    let gravity = Vector3::from(cell.gravity.vector_m_per_s2);
    let tau = gravity_torques(&links, &kinds, &base_rotation, &masses, &gravity);
    println!("q = {q_file:?} (mm for prismatic, deg for revolute joints)");
    for (k, kind) in kinds.iter().enumerate() {
        if kind.is_revolute() {
            println!("  tau_{} = {:+.4} N·m (moment of gravity about +z_{})", k + 1, tau[k], k + 1);
        } else {
            println!("  joint {} is prismatic: no torque", k + 1);
        }
    }

    // hand check: frame 3's z axis is world +y, a 2 kg body at x = 100 mm in frame 3
    let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
    let mut flat = [Frame::identity(); 4];
    flat[2] = Frame { r: rx_m90, p: Vector3::zeros() };
    flat[3] = Frame { r: rx_m90.transpose(), p: Vector3::zeros() };
    let mut one_body = MassModel { links: [Body::default(); MAX_JOINTS], n: 4 };
    one_body.links[2] = Body { mass_kg: 2.0, com_mm: Vector3::new(100.0, 0.0, 0.0) };
    let flat_kinds = [JointKind::Revolute; 4];
    let tau =
        gravity_torques(&flat, &flat_kinds, &Matrix3::identity(), &one_body, &Vector3::new(0.0, 0.0, -9.81));
    println!(
        "2 kg at 100 mm on a horizontal link: tau_3 = {:.4} N·m (m g L = {:.4})",
        tau[2],
        2.0 * 9.81 * 0.1
    );
    if (tau[2] - 2.0 * 9.81 * 0.1).abs() > 1e-12 {
        return Err("the hand check failed".into());
    }
    Ok(())
}
