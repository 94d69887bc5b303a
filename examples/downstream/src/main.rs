//! A downstream crate's calibration, from in-memory data, with `vatcal-kinematics` and
//! `vatcal-identification` only.
//!
//! 1. The nominal model of a cell (the canonical Meca500-on-guide cell, embedded as text).
//! 2. A "true" cell: the nominal one with small errors on the paper's 34 parameters.
//! 3. 80 laser-tracker measurements of the true cell (TCP world positions at joint vectors
//!    spread over the joint ranges), built in memory — no files, no simulator crate.
//! 4. `identify` the 34 parameters; print them and the error on 40 other poses, before and
//!    after. Exits with an error when the calibration does not bring the error down.

use vatcal_identification::{IdentifyOptions, file_unit_label, identify, to_file_units, validate};
use vatcal_kinematics::{CellFile, JointVector, Measurement, Model, ParamSet};

/// The nominal cell (in a real project: the robot's own cell file).
const CELL: &str = include_str!("../../../fixtures/meca500-zaber.toml");

/// `count` joint vectors spread over the joint ranges (10 % margin), reproducible: a
/// low-discrepancy sequence (golden-ratio steps per joint), no random generator needed.
fn poses(model: &Model, count: usize, offset: usize) -> Vec<JointVector> {
    let limits = model.joint_limits();
    let steps = [0.618_034, 0.414_214, 0.732_051, 0.236_068, 0.645_751, 0.162_278, 0.317_837];
    (offset..offset + count)
        .map(|k| {
            let v: Vec<f64> = limits
                .iter()
                .enumerate()
                .map(|(j, (lo, hi))| {
                    let u = (0.5 + k as f64 * steps[j % steps.len()]).fract();
                    lo + (hi - lo) * (0.1 + 0.8 * u)
                })
                .collect();
            JointVector::from_slice(&v).expect("7 joints")
        })
        .collect()
}

/// Tracker measurements of `truth` at `qs` (TCPs in turn).
fn measure(truth: &Model, qs: &[JointVector]) -> Result<Vec<Measurement>, Box<dyn std::error::Error>> {
    let tcps = truth.tcp_ids();
    qs.iter()
        .enumerate()
        .map(|(k, q)| {
            let tcp = tcps[k % tcps.len()];
            Ok(Measurement::tracker(tcp, *q, truth.tcp_position(q, tcp)?))
        })
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let nominal = Model::from_cell(&CellFile::from_toml_str(CELL, "meca500-zaber.toml")?)?;
    let params = ParamSet::paper34();
    // the true cell: every parameter off by a few typical scales' thousandths, signs alternating
    let mut truth = nominal.clone();
    let start = nominal.params(&params)?;
    let errors: Vec<f64> = params
        .iter()
        .enumerate()
        .map(
            |(k, id)| if k.is_multiple_of(2) { 1.0 } else { -1.0 } * (0.5 + 0.1 * (k % 5) as f64) * id.typical_scale(),
        )
        .collect();
    let true_values: Vec<f64> = start.iter().zip(&errors).map(|(v, e)| v + e).collect();
    truth.set_params(&params, &true_values)?;

    let fit_data = measure(&truth, &poses(&nominal, 80, 0))?;
    let check_data = measure(&truth, &poses(&nominal, 40, 1000))?;
    let fit = identify(&nominal, &fit_data, &params, &IdentifyOptions::default())?;

    println!("identified {} parameters from {} tracker measurements:", params.len(), fit_data.len());
    println!("{:<16} {:<9} {:>14} {:>14} {:>12}", "parameter", "unit", "nominal", "identified", "true - id.");
    for (k, id) in params.iter().enumerate() {
        let file = |v: f64| to_file_units(*id, v);
        println!(
            "{:<16} {:<9} {:>14.6} {:>14.6} {:>12.2e}",
            id.name(),
            file_unit_label(*id),
            file(start[k]),
            file(fit.values[k]),
            file(true_values[k]) - file(fit.values[k])
        );
    }
    let before = validate(&nominal, &check_data)?.stats;
    let after = validate(&fit.model, &check_data)?.stats;
    println!(
        "error on {} other poses: nominal mean {:.4} mm (max {:.4}), calibrated mean {:.2e} mm (max {:.2e})",
        check_data.len(),
        before.mean,
        before.max,
        after.mean,
        after.max
    );
    if !(fit.converged && after.mean < 1e-3 * before.mean) {
        return Err(format!(
            "the calibration did not converge to the truth: {} -> {} mm",
            before.mean, after.mean
        )
        .into());
    }
    Ok(())
}
