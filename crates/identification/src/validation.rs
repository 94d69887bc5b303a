//! Validation of a model against measurements it was not fitted to.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use vatcal_core::Measurement;
use vatcal_kinematics::Model;

use crate::{ErrorStats, IdentifyError};

/// Position errors of one model on a validation set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationReport {
    /// statistics of the errors
    pub stats: ErrorStats,
    /// error of every measurement, `measured − FK` (tracker) or `calibration_position − FK`
    /// (probe), world frame \[mm\]
    pub errors_mm: Vec<Vector3<f64>>,
}

impl ValidationReport {
    /// Error magnitudes \[mm\], in measurement order.
    pub fn magnitudes(&self) -> Vec<f64> {
        self.errors_mm.iter().map(|e| e.norm()).collect()
    }
}

/// Errors `measured_xyz − FK(model)` of every measurement (tracker measurements normally;
/// probe measurements are accepted and give `calibration_position − FK`).
///
/// # Errors
/// No measurements; a measurement the model rejects (unknown TCP / position; the error names
/// its index).
///
/// # Examples
/// ```
/// use vatcal_core::{CellFile, JointVector, Measurement};
/// use vatcal_identification::validate;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
/// let p = model.tcp_position(&q, 1)?;
/// // a tracker that saw TCP 1 0.1 mm above where the model puts it
/// let seen = Measurement::tracker(1, q, p + nalgebra::Vector3::new(0.0, 0.0, 0.1));
/// let report = validate(&model, &[seen])?;
/// assert!((report.stats.mean - 0.1).abs() < 1e-9);
/// // an unknown TCP is an error naming the measurement
/// assert!(validate(&model, &[Measurement::tracker(9, q, p)]).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn validate(model: &Model, measurements: &[Measurement]) -> Result<ValidationReport, IdentifyError> {
    if measurements.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    let errors_mm = measurements
        .iter()
        .enumerate()
        .map(|(index, m)| {
            model
                .residual(m)
                .map(|r| r + m.target_offset_mm())
                .map_err(|source| IdentifyError::Measurement { index, source })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(ValidationReport { stats: ErrorStats::from_errors(&errors_mm), errors_mm })
}

/// Validation of two models on the same measurements (e.g. nominal vs calibrated).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelComparison {
    /// the reference model (e.g. nominal)
    pub baseline: ValidationReport,
    /// the model under test (e.g. calibrated)
    pub candidate: ValidationReport,
    /// baseline mean error / candidate mean error (> 1: the candidate is better)
    pub mean_improvement_factor: f64,
}

/// Validates `baseline` and `candidate` on `measurements`.
///
/// # Errors
/// As [`validate`], for either model.
pub fn compare_models(
    baseline: &Model,
    candidate: &Model,
    measurements: &[Measurement],
) -> Result<ModelComparison, IdentifyError> {
    let baseline = validate(baseline, measurements)?;
    let candidate = validate(candidate, measurements)?;
    let mean_improvement_factor =
        if candidate.stats.mean > 0.0 { baseline.stats.mean / candidate.stats.mean } else { f64::MAX };
    Ok(ModelComparison { baseline, candidate, mean_improvement_factor })
}
