//! Imports the UR5e's URDF (`fixtures/ur5e.urdf`, base link `base_link`, tip `tool0`) into MDH +
//! Hayati-β rows, prints them, builds the cell model from the imported cell file and compares its
//! forward kinematics with the URDF's own (joint origins and axes, no MDH involved) at a few
//! joint vectors.
//!
//! ```text
//! cargo run -p vatcal-urdf --example import_ur5e
//! ```
//!
//! `vatcal import-urdf fixtures/ur5e.urdf --base-link base_link --tip-link tool0 --out cell.toml`
//! does the same and saves the cell file; replace its placeholder calibration position and its
//! tool mass before calibrating.

use vatcal_core::JointVector;
use vatcal_kinematics::Model;
use vatcal_urdf::{UrdfFk, import_str};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.urdf");
    let text = std::fs::read_to_string(path)?;
    let chain = import_str(&text, "ur5e.urdf", "base_link", "tool0")?;
    println!(
        "{}: {} joints from {} to {}",
        chain.robot_name,
        chain.joints.len(),
        chain.base_link,
        chain.tip_link
    );
    println!("  row  joint                kind       alpha_deg     a_mm  beta_deg  theta_deg     d_mm");
    for (i, j) in chain.joints.iter().enumerate() {
        println!(
            "  {:>3}  {:<20} {:<9} {:>10.3} {:>8.3} {:>9.3} {:>10.3} {:>8.3}",
            i + 1,
            j.name,
            format!("{:?}", j.kind),
            j.alpha_deg,
            j.a_mm,
            j.beta_deg,
            j.theta_deg,
            j.d_mm
        );
    }
    println!("  TCP 1 in frame {}: {:?} mm", chain.joints.len(), chain.tcp_mm);
    for note in &chain.notes {
        println!("  note: {note}");
    }

    // the imported cell file, as a model every other crate takes
    let cell = chain.to_cell("ur5e.urdf");
    let model = Model::from_cell(&cell)?;
    let urdf_fk = UrdfFk::new(&text, "ur5e.urdf", "base_link", "tool0")?;
    let poses_deg = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [10.0, -60.0, 80.0, -110.0, -90.0, 30.0],
        [-45.0, -100.0, 45.0, 20.0, 60.0, -120.0],
    ];
    let mut worst_mm: f64 = 0.0;
    for q_deg in &poses_deg {
        let q = JointVector::from_file_units(q_deg, model.joint_kinds())?;
        let p = model.tcp_position(&q, 1)?;
        let u = urdf_fk.tip_position_mm(q_deg).ok_or("six joint values")?;
        let diff = ((p.x - u[0]).powi(2) + (p.y - u[1]).powi(2) + (p.z - u[2]).powi(2)).sqrt();
        worst_mm = worst_mm.max(diff);
        println!(
            "  q = {q_deg:?} deg -> TCP 1 at [{:.4}, {:.4}, {:.4}] mm (URDF FK differs by {diff:.1e} mm)",
            p.x, p.y, p.z
        );
    }
    if worst_mm > 1e-9 {
        return Err(format!("the imported rows differ from the URDF by {worst_mm:e} mm").into());
    }
    Ok(())
}
