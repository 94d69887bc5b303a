//! Writes the simulated plane-contact files of docs/real-data.md's plane section: a UR5e truth
//! (geometry perturbed, seed 23) pressing its tool on a table (plane 1, slightly tilted, at
//! z = −50 mm) and on the top of a 50 mm gauge block standing on it (plane 2) with the tool
//! flat on them (`normal` 1), and touching two walls (planes 3 and 4, at x = 450 mm and
//! y = −450 mm) with the TCP only: `contacts.csv` (5 µm contact noise, 40 contacts per plane)
//! and the noise-free tracker rows `held.csv` for validation, in the folder given (default
//! `/tmp/vatcal-planes`).
//!
//! `cargo run -p vatcal-cli --example plane_rows_files -- /tmp/vatcal-planes`

use std::path::Path;

use vatcal_core::CellFile;
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, add_table_block_walls, perturbed_truth, synthetic_plane_contacts,
    synthetic_tracker_measurements,
};

/// The UR5e truth (geometry perturbed, no compliance) and its four planes.
fn truth() -> anyhow::Result<Model> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml");
    let nominal = Model::from_cell(&CellFile::load(path)?)?;
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(&nominal, 23, &budget);
    add_table_block_walls(&mut t, -50.0, 450.0);
    Ok(t)
}

fn main() -> anyhow::Result<()> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/tmp/vatcal-planes".to_string());
    let dir = Path::new(&dir);
    std::fs::create_dir_all(dir)?;
    let truth = truth()?;
    let mut contacts = Vec::new();
    for (plane, normal) in [(1, true), (2, true), (3, false), (4, false)] {
        contacts.extend(synthetic_plane_contacts(&truth, plane, 1, normal, 40, 0.005, 10 + u64::from(plane)));
    }
    let kinds = truth.joint_kinds();
    vatcal_io::write_measurements_for(dir.join("contacts.csv"), &contacts, kinds)?;
    let held: Vec<_> =
        synthetic_tracker_measurements(&truth, 900, 0.0, 6).into_iter().filter(|m| m.tcp == 1).collect();
    vatcal_io::write_measurements_for(dir.join("held.csv"), &held, kinds)?;
    println!(
        "{}: contacts.csv ({} plane rows), held.csv ({} tracker rows)",
        dir.display(),
        contacts.len(),
        held.len()
    );
    Ok(())
}
