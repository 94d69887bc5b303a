//! Nominal forward kinematics and the parameter Jacobian of the canonical cell.
//!
//! Loads `fixtures/meca500-zaber.toml`, prints the world position of every TCP at one pose,
//! the origins of the MDH frames, and the 3 × 34 Jacobian of TCP 1 with respect to the paper's
//! 34 parameters; one column is checked against a central finite difference. Then the same FK
//! on another chain: the UR5e-class arm of `fixtures/ur5e.toml` (six revolute joints, no guide).
//!
//! ```text
//! cargo run -p vatcal-kinematics --example fk_jacobian
//! ```

use vatcal_core::CellFile;
use vatcal_kinematics::{JointVector, Model, ParamSet};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let model = Model::from_cell(&cell)?;

    // q1 = 150 mm on the guide, the arm joints in degrees
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    for tcp in model.tcp_ids() {
        let p = model.tcp_position(&q, tcp)?;
        println!("TCP {tcp}: world position ({:9.4}, {:9.4}, {:9.4}) mm", p.x, p.y, p.z);
    }
    let chain = model.chain(&q);
    for (i, f) in chain.frames.iter().take(model.joint_count() + 1).enumerate() {
        println!("  MDH frame {i} origin ({:9.3}, {:9.3}, {:9.3}) mm", f.p.x, f.p.y, f.p.z);
    }
    let tau = model.gravity_torques(&q);
    println!(
        "gravity torques tau1..tau{} [N·m] (0 on the prismatic guide): {:.4?}",
        model.joint_count(),
        &tau[..model.joint_count()]
    );

    // analytic Jacobian of TCP 1 with respect to the paper's 34 parameters
    let params = ParamSet::paper34();
    let j = model.jacobian(&q, 1, &params.0)?;
    println!("Jacobian of TCP 1: {} × {} (mm per parameter unit)", j.nrows(), j.ncols());
    for (k, id) in params.iter().enumerate().take(6) {
        let c = j.column(k);
        println!("  d p / d {:<12} = ({:10.4}, {:10.4}, {:10.4})", id.name(), c[0], c[1], c[2]);
    }

    // cross-check one column against a central difference of the FK
    let k = 5;
    let id = params.0[k];
    let h = 1e-6;
    let value = model.param(id)?;
    let (mut plus, mut minus) = (model.clone(), model.clone());
    plus.set_param(id, value + h)?;
    minus.set_param(id, value - h)?;
    let fd = (plus.tcp_position(&q, 1)? - minus.tcp_position(&q, 1)?) / (2.0 * h);
    let diff = (fd - j.column(k)).norm();
    println!("column `{}`: analytic vs finite difference differ by {diff:.2e} mm/unit", id.name());
    if diff > 1e-5 {
        return Err(format!("Jacobian column `{}` disagrees with the finite difference", id.name()).into());
    }

    // any serial chain: the UR5e-class 6R arm of fixtures/ur5e.toml (cell file version 2)
    let ur5e =
        Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
    let q6 = JointVector::from_file_units(&[0.0, -90.0, 90.0, -90.0, -90.0, 0.0], ur5e.joint_kinds())?;
    let p = ur5e.tcp_position(&q6, 1)?;
    println!("UR5e, {}: TCP 1 at ({:.4}, {:.4}, {:.4}) mm", ur5e.describe_chain(), p.x, p.y, p.z);
    Ok(())
}
