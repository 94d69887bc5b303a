//! The compensation crate's error type.

/// Errors of compensation. Row numbers are 0-based indices into the request list; the CLI
/// adds the file and line.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CompensationError {
    /// The model's arm is not Meca500-like (the closed-form seeds need it).
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
        /// cell joint (1..=7)
        joint: usize,
        /// value in file units (mm for q1, degrees otherwise)
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
    /// A joint would jump between consecutive rows by more than allowed.
    #[error(
        "row {row}: joint q{joint} jumps by {step_deg:.3} deg from the previous row (at most {max_deg} deg)"
    )]
    JointJump {
        /// row index
        row: usize,
        /// cell joint (2..=7)
        joint: usize,
        /// the jump [deg]
        step_deg: f64,
        /// the allowed step [deg]
        max_deg: f64,
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
            | Self::JointJump { row, .. } => Some(*row),
            _ => None,
        }
    }
}
