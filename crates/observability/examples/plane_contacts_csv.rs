//! Writes a CSV of simulated plane rows for `vatcal observability` and `vatcal select`
//! (docs/observability.md, "Plane rows"): the UR5e (perturbed geometry) touching a table 50 mm
//! below its base with its TCP (20 rows, `normal` 0) and pressing its face on the top of a
//! 50 mm gauge block standing on it (20 rows, `normal` 1), 5 µm contact noise; with
//! `--trackers`, 40 tracker rows (10 µm) follow. Columns `plane,tcp,q1..q6,normal,x,y,z`
//! (degrees, mm). The planes are not in `fixtures/ur5e.toml`: the commands estimate them.
//!
//! ```text
//! cargo run -p vatcal-observability --example plane_contacts_csv -- planes.csv [--trackers]
//! ```

use std::fmt::Write as _;

use nalgebra::Vector3;
use vatcal_core::{CellFile, Target};
use vatcal_kinematics::{ContactPlane, Model};
use vatcal_sim::truth::{
    ErrorBudget, perturbed_truth, synthetic_plane_contacts, synthetic_tracker_measurements,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().ok_or("usage: plane_contacts_csv OUT.csv [--trackers]")?;
    let nominal =
        Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut truth = perturbed_truth(&nominal, 4, &budget);
    let up = Vector3::new(0.001, -0.002, 1.0);
    truth.insert_plane(1, ContactPlane::new(up, -50.0, 40.0));
    truth.insert_plane(2, ContactPlane::new(up, 0.0, 40.0));
    let mut rows = synthetic_plane_contacts(&truth, 1, 1, false, 20, 0.005, 1);
    rows.extend(synthetic_plane_contacts(&truth, 2, 1, true, 20, 0.005, 2));
    if args.iter().any(|a| a == "--trackers") {
        rows.extend(
            synthetic_tracker_measurements(&truth, 200, 0.01, 3).into_iter().filter(|m| m.tcp == 1).take(40),
        );
    }
    let mut text = String::from("plane,tcp,q1,q2,q3,q4,q5,q6,normal,x,y,z\n");
    for m in &rows {
        let q: Vec<String> =
            m.q.to_file_units(truth.joint_kinds()).iter().map(|v| format!("{v:.6}")).collect();
        let (plane, normal, xyz) = match m.target {
            Target::Plane { plane, normal } => {
                (plane.to_string(), u8::from(normal).to_string(), ",,".to_string())
            }
            Target::Tracker { xyz_mm } => {
                (String::new(), String::new(), format!("{:.4},{:.4},{:.4}", xyz_mm.x, xyz_mm.y, xyz_mm.z))
            }
            _ => return Err("plane and tracker rows only".into()),
        };
        writeln!(text, "{plane},{},{},{normal},{xyz}", m.tcp, q.join(","))?;
    }
    std::fs::write(path, text)?;
    println!("{} rows -> {path}", rows.len());
    Ok(())
}
