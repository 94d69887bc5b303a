//! The error type of this crate.

use vatcal_core::ParamId;
use vatcal_kinematics::ModelError;

/// Everything that can go wrong in an observability computation.
#[derive(Debug, thiserror::Error)]
pub enum ObservabilityError {
    /// The model rejected a measurement or a parameter (unknown TCP / position / parameter).
    #[error("measurement {index}: {source}")]
    Model {
        /// 0-based index of the measurement (or candidate)
        index: usize,
        /// the model's error
        #[source]
        source: ModelError,
    },
    /// The measurement list is empty.
    #[error("no measurements given")]
    NoMeasurements,
    /// The parameter list is empty.
    #[error("the parameter set is empty")]
    NoParameters,
    /// A Jacobian entry is NaN or infinite.
    #[error("measurement {index}: Jacobian column of `{param}` is not finite")]
    NonFinite {
        /// measurement index
        index: usize,
        /// parameter whose column is not finite
        param: ParamId,
    },
    /// The measurements cannot identify the given parameter set.
    #[error("{message}")]
    RankDeficient {
        /// numerical rank of the (column-normalised) Jacobian
        rank: usize,
        /// number of parameters, i.e. the rank that would be needed
        needed: usize,
        /// parameters that cannot be identified together with the others
        unidentifiable: Vec<ParamId>,
        /// a human-readable explanation naming the parameters
        message: String,
    },
    /// A dense factorisation failed (SVD did not converge).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// Invalid input to a selection (sizes, indices, options).
    #[error("{0}")]
    InvalidInput(String),
    /// Fewer candidates than poses requested.
    #[error("only {available} candidate poses for {requested} requested poses (need at least {requested})")]
    TooFewCandidates {
        /// number of candidates
        available: usize,
        /// requested design size
        requested: usize,
    },
}
