//! # vatcal-discovery
//!
//! Missing-effect discovery (background.md §8): fit the current model, locate where it
//! disagrees with the data, score every catalog effect that is not yet in the model, add the
//! best significant one, refit, and repeat until nothing passes. See `docs/discovery.md`.
//!
//! * [`workflow`] — the loop ([`discover`]) and its report types;
//! * [`distributions`] — χ² and F tail probabilities (also as logarithms);
//! * [`linear`] — column spaces, novelty `‖P⊥Z‖/‖Z‖` and the score (LM) test;
//! * [`criteria`] — F-test, AICc and BIC of nested fits;
//! * [`folds`] — seeded K-fold splits stratified by calibration position;
//! * [`location`] — residuals against every driving variable ("the where");
//! * [`catalog`] — driving variable, meaning and plausible range of each effect;
//! * [`fit`] — the fits (through `vatcal-identification`);
//! * [`plots`] — residual against an added effect's driving variable, before and after.

pub mod catalog;
pub mod criteria;
pub mod distributions;
pub mod fit;
pub mod folds;
pub mod linear;
pub mod location;
pub mod plots;
pub mod workflow;

pub use plots::write_effect_plots;
pub use workflow::{AddedEffect, DiscoverOptions, Discovery, Gap, discover};

/// Everything that can go wrong in discovery.
#[derive(Debug, thiserror::Error)]
pub enum DiscoveryError {
    /// No measurements were given.
    #[error("no measurements given")]
    NoMeasurements,
    /// The model rejected a measurement (unknown TCP or calibration position).
    #[error("measurement {index}: {message}")]
    Measurement {
        /// 0-based index of the measurement
        index: usize,
        /// the model's message
        message: String,
    },
    /// A fit failed (the identification crate's message).
    #[error("fit failed: {0}")]
    Fit(String),
    /// A Jacobian could not be assembled.
    #[error("Jacobian: {0}")]
    Jacobian(String),
    /// A dense factorisation failed.
    #[error("numerical failure: {0}")]
    Numerical(String),
}
