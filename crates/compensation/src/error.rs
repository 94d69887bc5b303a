//! The compensation crate's error type.

/// Errors of compensation. Row numbers are 0-based indices into the request list; the CLI
/// adds the file and line.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CompensationError {
    /// The planning layer failed (e.g. invalid options of the numerical IK).
    #[error(transparent)]
    Plan(#[from] vatcal_planning::PlanError),
    /// The model layer failed (e.g. an unknown TCP id).
    #[error(transparent)]
    Model(#[from] vatcal_kinematics::ModelError),
    /// A request value is not finite.
    #[error("row {row}: `{field}` must be finite, got {value}")]
    NonFinite {
        /// row index
        row: usize,
        /// field name
        field: &'static str,
        /// the value
        value: f64,
    },
    /// No joint solution reaches the pose (out of reach, or no convergence).
    #[error("row {row}: the pose cannot be reached ({reason})")]
    Unreachable {
        /// row index
        row: usize,
        /// why
        reason: String,
    },
    /// The pose is reached only outside the joint limits.
    #[error("row {row}: joint q{joint} = {value:.6} {unit} leaves its limits [{min:.6}, {max:.6}] {unit}")]
    JointLimit {
        /// row index
        row: usize,
        /// joint (1..=N)
        joint: usize,
        /// value in file units (mm for prismatic, degrees for revolute joints)
        value: f64,
        /// lower limit in file units
        min: f64,
        /// upper limit in file units
        max: f64,
        /// `mm` or `deg`
        unit: &'static str,
    },
    /// The pose is reachable only by another IK branch than the path's.
    #[error(
        "row {row}: reachable only by a branch change (path branch {from}, the pose needs {to}): \
         a wrist, elbow or shoulder flip"
    )]
    BranchChange {
        /// row index
        row: usize,
        /// branch of the path
        from: crate::Branch,
        /// branch the pose needs
        to: crate::Branch,
    },
    /// An independent pose has no solution on the branch it asks for (other branches reach it).
    #[error("row {row}: no solution on branch {branch} (the pose is reached on branch(es) {available})")]
    BranchUnreachable {
        /// row index
        row: usize,
        /// the branch asked for
        branch: crate::Branch,
        /// the branches that reach the pose, as in the `branch` column
        available: String,
    },
    /// A joint would jump between consecutive rows by more than allowed.
    #[error(
        "row {row}: joint q{joint} jumps by {step_deg:.3} deg from the previous row (at most {max_deg} deg)"
    )]
    JointJump {
        /// row index
        row: usize,
        /// joint (1..=N; a joint the pose determines)
        joint: usize,
        /// the jump \[deg\]
        step_deg: f64,
        /// the allowed step \[deg\]
        max_deg: f64,
    },
    /// Compensation does not handle this chain (fewer than six joints, or more than six whose
    /// prismatic joints do not leave exactly six to solve, see [`crate::JointSplit::of`]), or
    /// the nominal and calibrated models are different chains.
    #[error("compensation on {chain}: {reason}")]
    UnsupportedChain {
        /// the chain, e.g. `5 joints (RRRRR)`
        chain: String,
        /// why
        reason: String,
    },
    /// An option is invalid.
    #[error("invalid option `{option}`: {reason}")]
    Option {
        /// option name
        option: &'static str,
        /// what is wrong
        reason: String,
    },
}

impl CompensationError {
    /// The 0-based row the error is about, if it is about one row.
    pub fn row(&self) -> Option<usize> {
        match self {
            Self::NonFinite { row, .. }
            | Self::Unreachable { row, .. }
            | Self::JointLimit { row, .. }
            | Self::BranchChange { row, .. }
            | Self::BranchUnreachable { row, .. }
            | Self::JointJump { row, .. } => Some(*row),
            _ => None,
        }
    }
}
