//! The demo's error type.

use std::path::PathBuf;

/// Why the demo stopped. Each stage's error is kept as the `source` (print the chain, e.g.
/// with `anyhow`'s `{:#}`, to see the cause).
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A file or directory could not be written.
    #[error("{path}: {source}")]
    Io {
        /// file or directory
        path: PathBuf,
        /// cause
        source: std::io::Error,
    },
    /// An option is invalid.
    #[error("invalid demo option `{option}`: {reason}")]
    Option {
        /// option name
        option: String,
        /// what is wrong
        reason: String,
    },
    /// The nominal cell file is invalid.
    #[error(transparent)]
    Cell(#[from] vatcal_core::CellError),
    /// The model cannot be built from the cell file.
    #[error(transparent)]
    Model(#[from] vatcal_kinematics::ModelError),
    /// Planning failed.
    #[error("planning failed")]
    Plan(#[from] vatcal_planning::PlanError),
    /// The tour written by the planner cannot be read back.
    #[error(transparent)]
    Tour(#[from] vatcal_campaign::TourFileError),
    /// A simulated device could not be set up.
    #[error("the virtual cell cannot be set up")]
    Device(#[from] vatcal_hardware_traits::Error),
    /// The measurement campaign failed.
    #[error("the measurement campaign failed")]
    Campaign(#[source] Box<vatcal_campaign::CampaignError>),
    /// The identification failed.
    #[error("identification failed")]
    Identify(#[from] vatcal_identification::IdentifyError),
    /// The validation campaign failed.
    #[error("the validation failed")]
    Validation(#[from] vatcal_campaign::validation::ValidationError),
    /// A measurement CSV could not be written.
    #[error(transparent)]
    Output(#[from] vatcal_io::IoError),
    /// A plot could not be drawn.
    #[error("a plot cannot be drawn")]
    Plot(#[from] vatcal_report::PlotError),
    /// The JSON report could not be serialised.
    #[error("report.json cannot be serialised")]
    Json(#[from] serde_json::Error),
}

impl From<vatcal_campaign::CampaignError> for DemoError {
    fn from(e: vatcal_campaign::CampaignError) -> Self {
        Self::Campaign(Box::new(e))
    }
}
