//! The `identify` stage: the plan's parameter set (the paper's 34 parameters on the canonical
//! cell, the chain's identifiable default set otherwise) by Levenberg–Marquardt from the probe
//! measurements; the calibrated cell (`calibrated.toml`) records the joints' training range.
//!
//! Input: the nominal model, the campaign's measurements, the parameter set; output: the
//! [`Identification`]. Deterministic: recomputed from the journal when the stage is done.

use vatcal_core::training_range::TrainingRange;
use vatcal_core::{CellFile, Measurement, ParamSet};
use vatcal_identification::{Identification, IdentifyOptions, identify};
use vatcal_kinematics::Model;

use crate::PipelineError;

/// Identifies `params` (the plan's set: the paper's 34 on the canonical cell) from the probe
/// measurements (Levenberg–Marquardt).
///
/// # Errors
/// The identification fails (too few measurements, divergence).
pub fn identify_stage(
    nominal: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
) -> Result<Identification, PipelineError> {
    Ok(identify(nominal, measurements, params, &IdentifyOptions::default())?)
}

/// The calibrated cell of `fit`, with the joints' training range of the measurements it was
/// identified from (`compensate` and `validate` warn about postures outside it).
pub fn calibrated_cell(fit: &Identification, measurements: &[Measurement]) -> CellFile {
    let mut calibrated = fit.model.to_cell();
    calibrated.training_range =
        TrainingRange::from_postures(fit.model.joint_kinds(), measurements.iter().map(|m| &m.q));
    calibrated
}
