//! The demo's error type.

use std::path::PathBuf;

/// Why the demo stopped.
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
    /// The nominal cell file is invalid.
    #[error(transparent)]
    Cell(#[from] vatcal_core::CellError),
    /// The model cannot be built from the cell file.
    #[error(transparent)]
    Model(#[from] vatcal_kinematics::ModelError),
    /// Planning failed.
    #[error("planning: {0}")]
    Plan(#[from] vatcal_planning::PlanError),
    /// The tour written by the planner cannot be read back.
    #[error(transparent)]
    Tour(#[from] vatcal_campaign::TourFileError),
    /// A simulated device could not be set up.
    #[error("virtual cell: {0}")]
    Device(#[from] vatcal_hardware_traits::Error),
    /// The measurement campaign failed.
    #[error("measurement campaign: {0}")]
    Campaign(Box<vatcal_campaign::CampaignError>),
    /// The identification failed.
    #[error("identification: {0}")]
    Identify(#[from] vatcal_identification::IdentifyError),
    /// The validation campaign failed.
    #[error("validation: {0}")]
    Validation(#[from] vatcal_campaign::validation::ValidationError),
    /// A measurement CSV could not be written.
    #[error(transparent)]
    Output(#[from] vatcal_io::IoError),
    /// A plot could not be drawn.
    #[error("plot: {0}")]
    Plot(#[from] vatcal_report::PlotError),
    /// The JSON report could not be serialised.
    #[error("report.json: {0}")]
    Json(#[from] serde_json::Error),
}

impl From<vatcal_campaign::CampaignError> for DemoError {
    fn from(e: vatcal_campaign::CampaignError) -> Self {
        Self::Campaign(Box::new(e))
    }
}
