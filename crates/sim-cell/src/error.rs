//! Errors of the simulated cell.

use std::net::SocketAddr;

/// Why the simulated cell could not start.
#[derive(Debug, thiserror::Error)]
pub enum SimCellError {
    /// An option is invalid.
    #[error("option {option}: {reason}")]
    Option {
        /// option name
        option: String,
        /// what is wrong
        reason: String,
    },
    /// The built-in cell file does not parse (a build defect).
    #[error("cell model: {0}")]
    Cell(#[from] vatcal_core::cell::CellError),
    /// The nominal model cannot be built, or is not the canonical Meca500-on-guide cell.
    #[error("cell model: {0}")]
    Model(#[from] vatcal_kinematics::ModelError),
    /// The hidden truth cannot be built (a truth file that cannot be read or does not fit the
    /// nominal cell).
    #[error("cell model: {0}")]
    Truth(#[from] vatcal_sim::truth::TruthError),
    /// A port cannot be bound.
    #[error("{device}: cannot listen on {address}: {source}")]
    Bind {
        /// device (`meca500`, `zaber`, `gauge-1`, …)
        device: String,
        /// the address
        address: SocketAddr,
        /// the OS error
        source: std::io::Error,
    },
}
