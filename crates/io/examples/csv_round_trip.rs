//! Reading and writing the CSV files of `docs/formats.md`.
//!
//! Reads `fixtures/joints-example.csv` (joint rows `tcp,q1..q7`, q1 in mm, q2..q7 in degrees)
//! against the canonical cell, turns the rows into tracker measurements at their FK
//! positions, writes them with [`write_measurements`], reads them back with
//! [`read_tracker_measurements`] (bit-exact round trip), and shows the error a bad row gives
//! (file, line, column, reason).
//!
//! ```text
//! cargo run -p vatcal-io --example csv_round_trip
//! ```

use vatcal_core::{CellFile, Measurement};
use vatcal_io::{read_joint_rows, read_tracker_measurements, write_measurements};
use vatcal_kinematics::Model;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/");
    let model = Model::from_cell(&CellFile::load(format!("{root}meca500-zaber.toml"))?)?;
    let rows = read_joint_rows(format!("{root}joints-example.csv"), &model)?;
    let mut measurements = Vec::new();
    for row in &rows {
        println!("line {}: TCP {} at q = {:.3?} (mm, deg)", row.line, row.tcp, row.q.to_mm_deg());
        let p = model.tcp_position_ctx(&row.q, &row.context, row.tcp)?;
        measurements.push(Measurement::tracker(row.tcp, row.q, p));
    }

    let dir = std::env::temp_dir().join(format!("vatcal-io-example-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let csv = dir.join("tracker.csv");
    write_measurements(&csv, &measurements)?;
    println!("--- {}\n{}", csv.display(), std::fs::read_to_string(&csv)?);
    let back = read_tracker_measurements(&csv, &model)?;
    if back != measurements {
        return Err("the written measurements did not read back identically".into());
    }
    println!("{} measurements read back identically", back.len());

    // a bad row: the error names the file, the line and the column
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "tcp,q1,q2,q3,q4,q5,q6,q7\n1,0,0,0,0,0,0,0\n2,0,0,abc,0,0,0,0\n")?;
    match read_joint_rows(&bad, &model) {
        Ok(_) => return Err("a bad file must be refused".into()),
        Err(e) => println!("refused as expected: {e}"),
    }
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}
