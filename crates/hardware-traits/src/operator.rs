//! The person at the cell, as a device: the campaign asks, the operator acts and confirms.

use std::fmt;

use crate::error::Result;

/// Something only a human can do (automatic in simulation).
#[derive(Debug, Clone, PartialEq)]
pub enum OperatorInstruction {
    /// Put the probe plate on the kinematic coupling so that the probe origin is at
    /// calibration position `position`.
    PlaceProbe {
        /// calibration position id
        position: u32,
    },
    /// Seat the master ball in the probe's trihedral socket (the probe is at `position`).
    SeatMasterBall {
        /// calibration position id
        position: u32,
    },
    /// Remove the master ball.
    RemoveMasterBall,
    /// Seat the laser tracker's SMR in the probe's trihedral nest (the probe is at
    /// `position`): the tracker registration measures it there.
    SeatNestSmr {
        /// calibration position id
        position: u32,
    },
    /// Remove the tracker's SMR from the probe's nest.
    RemoveNestSmr,
    /// Make sure the way is clear before an unplanned motion (e.g. after a crash the arm
    /// returns to the last recorded pose).
    ConfirmMotion {
        /// what will move
        description: String,
    },
}

impl fmt::Display for OperatorInstruction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OperatorInstruction::PlaceProbe { position } => {
                write!(f, "place the probe plate at calibration position {position}")
            }
            OperatorInstruction::SeatMasterBall { position } => {
                write!(f, "seat the master ball in the probe (probe at calibration position {position})")
            }
            OperatorInstruction::RemoveMasterBall => f.write_str("remove the master ball from the probe"),
            OperatorInstruction::SeatNestSmr { position } => write!(
                f,
                "seat the tracker's SMR in the probe's trihedral nest (probe at calibration position {position}) and make sure the tracker sees it"
            ),
            OperatorInstruction::RemoveNestSmr => {
                f.write_str("remove the tracker's SMR from the probe's nest")
            }
            OperatorInstruction::ConfirmMotion { description } => {
                write!(f, "check that the way is clear: {description}")
            }
        }
    }
}

/// Carries out [`OperatorInstruction`]s: blocks until the operator confirmed, or returns
/// [`crate::ErrorKind::Cancelled`] when the operator refuses.
pub trait Operator: Send {
    /// Asks for `instruction` and waits for the confirmation.
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()>;
}

impl<T: Operator + ?Sized> Operator for &mut T {
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()> {
        (**self).perform(instruction)
    }
}

impl<T: Operator + ?Sized> Operator for Box<T> {
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()> {
        (**self).perform(instruction)
    }
}
