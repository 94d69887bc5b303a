#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Missing-effect discovery (background.md §8): fit the current model, locate where it
//! disagrees with the data, screen every catalog effect that is not yet in the model on one part
//! of the data, confirm the best on held-out data the screening never saw, add an effect only if
//! it shrinks the held-out gap by more than its uncertainty, refit, check the earlier additions
//! are still needed, and repeat until nothing passes. See `docs/discovery.md`.
//!
//! * [`workflow`] — the loop ([`discover`]) and its report types;
//! * [`distributions`] — χ² and F tail probabilities (also as logarithms);
//! * [`linear`] — column spaces, novelty `‖P⊥Z‖/‖Z‖` and the score (LM) test;
//! * [`criteria`] — F-test, AICc and BIC of nested fits;
//! * [`folds`] — seeded K-fold splits stratified by calibration position;
//! * [`location`] — residuals against every driving variable ("the where");
//! * [`noise`] — the noise reference of the size rule (replicates, instruments, σ̂);
//! * [`power`] — minimum detectable effect size and the measurements a decision needs;
//! * [`catalog`] — driving variable, meaning and plausible range of each effect;
//! * [`fit`] — the fits (through `vatcal-identification`);
//! * [`propose`] — the measurements that would decide a borderline or ambiguous candidate;
//! * [`plots`] — residual against an added effect's driving variable, before and after;
//! * [`html`] — the report as one self-contained HTML page.

pub mod catalog;
pub mod criteria;
pub mod distributions;
pub mod fit;
pub mod folds;
pub mod html;
pub mod linear;
pub mod location;
pub mod noise;
pub mod plots;
pub mod power;
pub mod propose;
pub mod workflow;

pub use html::html_report;
pub use plots::write_effect_plots;
pub use power::{Detectability, candidate_detectability};
pub use workflow::{AddedEffect, DiscoverOptions, Discovery, Gap, discover};

/// Everything that can go wrong in discovery.
#[derive(Debug, thiserror::Error)]
pub enum DiscoveryError {
    /// No measurements were given.
    #[error("no measurements given")]
    NoMeasurements,
    /// The model rejected a measurement (unknown TCP or calibration position).
    #[error("measurement {index}: {source}")]
    Measurement {
        /// 0-based index of the measurement
        index: usize,
        /// the model's error
        #[source]
        source: vatcal_kinematics::ModelError,
    },
    /// A fit failed (the identification crate's error is the source).
    #[error("fit failed: {0}")]
    Fit(#[source] Box<vatcal_identification::IdentifyError>),
    /// A Jacobian could not be assembled (the observability crate's error is the source).
    #[error("Jacobian: {0}")]
    Jacobian(#[source] vatcal_observability::ObservabilityError),
    /// A dense factorisation failed.
    #[error("numerical failure: {0}")]
    Numerical(String),
}
