//! The error type of the CSV layer ([`IoError`]), below every reader and writer.

use std::path::{Path, PathBuf};

/// Errors of the CSV layer.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened, read or written.
    #[error("{path}: {cause}")]
    File {
        /// file
        path: PathBuf,
        /// cause (kept out of the error chain: the message already states it)
        cause: std::io::Error,
    },
    /// The CSV structure is broken (e.g. a row with the wrong number of fields).
    #[error("{path}:{line}: malformed CSV: {message}")]
    Csv {
        /// file
        path: PathBuf,
        /// 1-based line
        line: u64,
        /// csv's message
        message: String,
    },
    /// A required column is missing from the header.
    #[error("{path}: missing column `{column}` in the header (required columns: {required})")]
    MissingColumn {
        /// file
        path: PathBuf,
        /// the missing column
        column: String,
        /// all required columns
        required: String,
    },
    /// A field of a row is invalid.
    #[error("{path}:{line}: column `{column}`: {reason}")]
    Row {
        /// file
        path: PathBuf,
        /// 1-based line number
        line: u64,
        /// column name
        column: String,
        /// what is wrong
        reason: String,
    },
    /// The model has an effect that depends on a context column the file does not have.
    #[error("{path}: the model's {effect} needs the column(s) {columns}, which the file does not have")]
    ModelNeedsColumn {
        /// file
        path: PathBuf,
        /// the missing column(s), e.g. `dir2..dir7`
        columns: String,
        /// the effect that needs them, e.g. `joint-backlash (joint 3)`
        effect: String,
    },
    /// The file has a header but no data rows.
    #[error("{path}: no data rows")]
    Empty {
        /// file
        path: PathBuf,
    },
    /// The file kind needs another chain than the model's.
    #[error("{path}: {reason}")]
    UnsupportedChain {
        /// file
        path: PathBuf,
        /// why
        reason: String,
    },
    /// The reader options do not fit the file (e.g. directions derived from the row order of a
    /// file that has `dir` columns of its own).
    #[error("{path}: {reason}")]
    Options {
        /// file
        path: PathBuf,
        /// why
        reason: String,
    },
    /// The joint columns of the header do not match the model's joint count.
    #[error(
        "{path}:{line}: the model has {joints} joints: expected the joint columns {expected}, the header has {found}"
    )]
    JointColumns {
        /// file
        path: PathBuf,
        /// 1-based line of the header
        line: u64,
        /// joints of the model
        joints: usize,
        /// the expected columns, e.g. `q1..q6`
        expected: String,
        /// the joint columns found
        found: String,
    },
}

pub(crate) fn csv_error(path: &Path, e: &csv::Error) -> IoError {
    let line = e.position().map_or(0, |p| p.line());
    IoError::Csv { path: path.into(), line, message: e.to_string() }
}
