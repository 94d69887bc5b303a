//! Held-out evaluation of a vatcal calibration on the MUKCa data (fixtures/real/mukca), through
//! the library, until `vatcal identify` reads fixed points at unknown places (issue 20 item 7,
//! branch wip/ident): calibrate the imported nominal cell on one placement with
//! `vatcal_identification::calibrate` (spec `default`: the cross-validated set), the two
//! sockets as free fixed points 1 and 2 and their known distance as a measurement, then evaluate
//! the nominal and the calibrated model on every placement given
//! (`vatcal_identification::evaluate_fixed_points`).
//!
//! ```text
//! cargo run -p vatcal-cli --example mukca_holdout -- CELL SET TRAIN [OTHER...]
//!   e.g. -- panda panda_6 front left right
//! ```
//! Environment (defaults as `vatcal identify`): `SPEC` (parameter set, `default`),
//! `POINT_DISTANCE` (`a,b,mm[,sigma_mm]`, `1,2,50`), `MAX_CONDITION` (1e3),
//! `LIMIT_TOLERANCE_DEG` (0.5). docs/real-data.md gives the values used for its table.

use anyhow::Context;
use vatcal_core::{CellFile, PointDistance};
use vatcal_identification::{CvOptions, IdentifyOptions, calibrate, evaluate_fixed_points};
use vatcal_io::{AngleUnit, LimitTolerance, ReadOptions};
use vatcal_kinematics::Model;
use vatcal_observability::sets::DataDesign;

fn env_or(name: &str, default: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| default.to_string())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [cell, set, train, others @ ..] = args.as_slice() else {
        anyhow::bail!("usage: mukca_holdout CELL SET TRAIN [OTHER...] (e.g. panda panda_6 front left right)");
    };
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/real/mukca");
    let mut c = CellFile::load(format!("{root}/cells/{cell}.toml"))?;
    // the imported cell has one placeholder calibration position: the second socket is another
    let mut second = c.calibration_positions.first().context("the cell has no calibration position")?.clone();
    second.id = 2;
    c.calibration_positions.push(second);
    let nominal = Model::from_cell(&c)?;
    let tolerance: f64 = env_or("LIMIT_TOLERANCE_DEG", "0.5").parse().context("LIMIT_TOLERANCE_DEG")?;
    let read_options = ReadOptions {
        angle_unit: AngleUnit::Rad,
        any_position_id: true,
        limit_tolerance: LimitTolerance { revolute_deg: tolerance, ..LimitTolerance::MEASURED },
        ..ReadOptions::default()
    };
    let read = |placement: &str| {
        vatcal_io::read_probe_measurements_with(
            format!("{root}/{set}/{placement}.csv"),
            &nominal,
            &read_options,
        )
        .map(|r| r.rows)
    };
    let distance = PointDistance::parse(&env_or("POINT_DISTANCE", "1,2,50")).map_err(anyhow::Error::msg)?;
    let design = DataDesign { free_positions: vec![1, 2], distances: vec![distance] };
    let options = IdentifyOptions {
        max_condition_number: env_or("MAX_CONDITION", "1e3").parse().context("MAX_CONDITION")?,
        ..IdentifyOptions::default()
    };
    let spec = env_or("SPEC", "default");
    let cal = calibrate(&nominal, &read(train)?, &spec, &design, &options, &CvOptions::default())?;
    println!("trained on {set}/{train}: {} parameters: {}", cal.params.len(), cal.params.names().join(","));
    println!("fit residuals: {}", cal.fit.residual_stats.one_line());
    if let Some(sel) = &cal.selection {
        for s in &sel.candidates {
            println!("  candidate {:?}: {} parameters, CV RMS {:.4} mm", s.set, s.params.len(), s.cv_rms_mm);
        }
        println!("  {}", sel.reason);
    }
    println!("{:<24} {:<8} {:>9} {:>9} {:>9} {:>11}", "[mm]", "model", "RMS", "mean", "max", "d1-2 err");
    for placement in std::iter::once(train).chain(others) {
        let rows = read(placement)?;
        for (name, model) in [("nominal", &nominal), ("vatcal", &cal.fit.model)] {
            let e = evaluate_fixed_points(model, &rows, &[distance])?;
            let derr = e.distances.first().map_or(f64::NAN, |d| d.error_mm);
            println!(
                "{:<24} {name:<8} {:>9.4} {:>9.4} {:>9.4} {derr:>+11.4}",
                format!("{set}/{placement}"),
                e.rms_mm,
                e.mean_mm,
                e.max_mm
            );
        }
    }
    Ok(())
}
