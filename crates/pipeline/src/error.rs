//! The pipeline's error type.

use std::path::PathBuf;

/// Why a pipeline stage stopped. Each stage's error is kept as the `source` (print the chain, e.g.
/// with `anyhow`'s `{:#}`, to see the cause).
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// A file or directory could not be written.
    #[error("{path}: {source}")]
    Io {
        /// file or directory
        path: PathBuf,
        /// cause
        source: std::io::Error,
    },
    /// An option is invalid.
    #[error("invalid option `{option}`: {reason}")]
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
    /// The tour of a plan folder cannot be read.
    #[error(transparent)]
    Tour(#[from] vatcal_campaign::TourFileError),
    /// A file of a plan or run folder is missing or invalid.
    #[error("{path}: {reason}")]
    Folder {
        /// the file
        path: PathBuf,
        /// what is wrong
        reason: String,
    },
    /// A device could not be set up.
    #[error("a device cannot be set up")]
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
    /// A JSON file could not be serialised.
    #[error("JSON cannot be serialised")]
    Json(#[from] serde_json::Error),
    /// The printing path's targets from `vatcal-compensation` cannot be solved or differ from
    /// the commanded joints.
    #[error("compensation of the printing path")]
    Compensation(#[from] PrintingPathCheckError),
    /// The journal of a run folder cannot be read.
    #[error(transparent)]
    Journal(#[from] vatcal_campaign::JournalError),
    /// The tracker cannot be registered to the tank frame.
    #[error(transparent)]
    TrackerRegistration(#[from] vatcal_campaign::validation::TrackerRegistrationError),
    /// The discovery stage failed.
    #[error("discovery failed")]
    Discovery(#[from] vatcal_discovery::DiscoveryError),
}

impl From<vatcal_campaign::CampaignError> for PipelineError {
    fn from(e: vatcal_campaign::CampaignError) -> Self {
        Self::Campaign(Box::new(e))
    }
}

/// Why the validation's printing path is not commanded by the compensation's targets (the
/// source of [`PipelineError::Compensation`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PrintingPathCheckError {
    /// The plan has no run with this label over every slice.
    #[error("no `{label}` printing-path run of every slice")]
    MissingRun {
        /// run label ([`crate::NOMINAL`] or [`crate::CALIBRATED`])
        label: String,
    },
    /// The compensation library cannot solve the targets (its error is the source).
    #[error("{targets} targets of the printing path")]
    Solve {
        /// `compensated` (under the calibrated model) or `uncompensated` (under the nominal)
        targets: &'static str,
        /// why
        #[source]
        source: vatcal_compensation::CompensationError,
    },
    /// A commanded joint differs from its target by more than [`JOINT_AGREEMENT`].
    #[error(
        "the `{label}` printing-path run differs from the compensation's targets by {difference:.3e} (allowed {JOINT_AGREEMENT:.0e})"
    )]
    Differs {
        /// run label
        label: String,
        /// largest difference \[rad for revolute, mm for prismatic joints\]
        difference: f64,
    },
}

/// Largest allowed difference between a commanded joint of the validation's printing path and
/// the compensation's target \[rad for q2..q7, mm for q1\].
pub const JOINT_AGREEMENT: f64 = 1e-6;
