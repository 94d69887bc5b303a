//! The planning crate's error type.

use std::path::PathBuf;

/// Errors of measurement planning.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The model's arm does not have the structure the closed-form IK assumes.
    #[error("the arm of this model is not a Meca500-like arm: {0}")]
    UnsupportedArm(String),
    /// The numerical IK refinement did not converge.
    #[error(
        "IK refinement did not converge (tool error {position_error_mm:.3e} mm, {rotation_error_rad:.3e} rad)"
    )]
    IkNotConverged {
        /// final position error (mm)
        position_error_mm: f64,
        /// final orientation error (rad)
        rotation_error_rad: f64,
    },
    /// A geometry table of the cell file is invalid.
    #[error("cell geometry: field `{field}`: {reason}")]
    Geometry {
        /// field path, e.g. `obstacles.robot_links.upper_arm_radius_mm`
        field: String,
        /// what is wrong
        reason: String,
    },
    /// An option is invalid.
    #[error("invalid option `{option}`: {reason}")]
    Option {
        /// option name
        option: String,
        /// what is wrong
        reason: String,
    },
    /// A stage left nothing to work with.
    #[error("{0}")]
    Empty(String),
    /// The model layer failed (unknown TCP or position, ...).
    #[error(transparent)]
    Model(#[from] vatcal_kinematics::ModelError),
    /// Detmax selection failed (the observability error is the source).
    #[error("selection failed: {0}")]
    Selection(#[source] vatcal_observability::ObservabilityError),
    /// No collision-free path was found to a measurement of the tour.
    #[error("no collision-free path to measurement {measurement} of the tour (from {from}): {reason}")]
    NoPath {
        /// 1-based rank of the measurement in the tour
        measurement: usize,
        /// where the leg starts: `the start pose` or `measurement k`
        from: String,
        /// why (e.g. start in collision, RRT budget exhausted)
        reason: String,
    },
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// file path (`<memory>` for CSV text built in memory)
        path: PathBuf,
        /// the I/O, CSV or JSON error
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}
