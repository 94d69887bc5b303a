//! The laser-tracker validation campaign (paper §5).
//!
//! After a calibration, the cell's accuracy is measured with a laser tracker whose SMRs sit in
//! the nests of the calibration end-effector (their centres known in the tool-changer frame,
//! like the TCPs), in the world (tank) frame:
//!
//! 1. **random poses** ([`random_validation_poses`]): joint vectors drawn over the whole
//!    workspace (inside the joint limits with a margin, collision-free), one SMR measured at
//!    each; the error of a model is `measured − FK_model(q)` — the histogram of the paper's
//!    Fig. 8 (paper: 573 poses, mean 1.272 mm nominal → 0.271 mm calibrated);
//! 2. **a six-dimensional printing path** ([`printing`]): the cell is *commanded* through the
//!    IK of each model under test (the calibrated model is what makes the cell accurate); at
//!    each of the 300 slices the three SMRs give the end-effector pose ([`fit_rigid_transform`]),
//!    which is carried to the end of the theoretical printed part on the tank bottom; the error
//!    is `measured − intended` there, lever effect included — the paper's Figs. 9–10 (mean
//!    1.192 mm nominal → 0.220 mm calibrated).
//!
//! Before either, the tracker is registered to the tank frame ([`register_tracker`], the
//! paper's procedure: the SMR in the probe's trihedral nest measured at the three calibration
//! positions, a rigid fit); its residual goes into the report.
//!
//! [`build_validation_plan`] turns both into a [`crate::CampaignPlan`] of `move` and `track`
//! steps (collision-free legs between the random poses, ordered to shorten the tour), so the
//! validation runs on the same crash-safe, resumable [`crate::Campaign`] runner as the
//! calibration, on any devices with a [`PositionTracker`](vatcal_hardware_traits::PositionTracker).
//! [`ValidationPlan::collect`] reads the measurements back from the campaign's records, and
//! [`evaluate`] computes the errors of each model with the statistics of
//! `vatcal_identification::ErrorStats`; [`plots`] draws them with `vatcal-report`.

mod analysis;
mod plan;
pub mod plots;
mod poses;
pub mod printing;
mod registration;
mod tracker_registration;

pub use analysis::{ModelValidation, PathValidation, evaluate, evaluate_path};
pub use plan::{
    PathRecords, PathRun, SliceRecord, ValidationPlan, ValidationPlanOptions, ValidationRecords,
    build_validation_plan,
};
pub use poses::{RandomPoseOptions, ValidationPose, random_validation_poses};
pub use printing::{PrintingPathError, PrintingPathOptions, PrintingSlice, printing_path};
pub use registration::{RegistrationError, fit_rigid_transform};
pub use tracker_registration::{
    RegistrationPoint, TrackerRegistration, TrackerRegistrationError, register_tracker,
    register_tracker_resuming,
};

use crate::CampaignError;

/// Errors of the validation campaign.
#[derive(Debug, thiserror::Error)]
pub enum ValidationError {
    /// An option is invalid.
    #[error("invalid validation option `{option}`: {reason}")]
    Option {
        /// option name
        option: String,
        /// what is wrong
        reason: String,
    },
    /// The planning layer failed (IK set-up, collision model, margins).
    #[error(transparent)]
    Planning(#[from] vatcal_planning::PlanError),
    /// Too many random draws were rejected.
    #[error("only {found} of {wanted} collision-free random poses after {draws} draws")]
    NotEnoughPoses {
        /// poses accepted
        found: usize,
        /// poses wanted
        wanted: usize,
        /// draws made
        draws: usize,
    },
    /// The printing path cannot be commanded (messages start with `printing path:`; an IK
    /// failure keeps the planning error as the source).
    #[error(transparent)]
    PrintingPath(#[from] PrintingPathError),
    /// No collision-free path between two consecutive validation poses.
    #[error("no collision-free path from {from} to {to}: {reason}")]
    NoPath {
        /// the pose left
        from: String,
        /// the pose reached
        to: String,
        /// why
        reason: String,
    },
    /// The campaign runner failed (the journal keeps what was measured: run again to resume).
    #[error(transparent)]
    Campaign(Box<CampaignError>),
    /// The campaign records do not hold every planned measurement.
    #[error("incomplete validation records: {0}")]
    Incomplete(String),
    /// The pose of a slice cannot be fitted from its SMRs.
    #[error("printing path `{run}`, slice {slice}: {reason}")]
    Registration {
        /// path run label
        run: String,
        /// slice index
        slice: usize,
        /// why
        reason: RegistrationError,
    },
    /// A model rejected a measurement (unknown TCP).
    #[error(transparent)]
    Model(#[from] vatcal_identification::IdentifyError),
    /// A plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] vatcal_report::PlotError),
}

impl From<CampaignError> for ValidationError {
    fn from(e: CampaignError) -> Self {
        Self::Campaign(Box::new(e))
    }
}
