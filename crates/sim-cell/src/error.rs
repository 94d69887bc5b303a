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
    /// The nominal or true model cannot be built.
    #[error("cell model: {0}")]
    Model(String),
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
