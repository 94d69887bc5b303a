//! IK branches: the closed-form branch bits of the canonical cell, the sign of `det J` elsewhere.

use std::fmt;

use vatcal_core::JointVector;
use vatcal_planning::ik::{ArmGeometry, wrap_angle};

/// An IK branch.
///
/// On the canonical cell (closed-form IK of the Meca500 arm), 0..=7 with the bits of
/// `vatcal_planning::ik::ArmSolutions`: bit 0 shoulder (set: wrist centre behind the J1 axis),
/// bit 1 elbow (set: the `−acos` elbow), bit 2 wrist (set: `θ_6 < 0`, cell joint 6 = Meca500
/// J5).
///
/// On any other chain (numerical IK) the branch is the sign of the determinant of the 6×6
/// Jacobian of the solved joints ([`JointSplit::jacobian`](crate::JointSplit::jacobian)):
/// [`Branch::DET_POSITIVE`] or [`Branch::DET_NEGATIVE`]. The solution branches of a
/// six-degree-of-freedom arm are separated by its singular configurations (`det J = 0`), so two
/// solutions of opposite sign are on different branches, and a path whose sign changes passes a singularity (a flip).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Branch(pub u8);

impl Branch {
    /// Numerical-IK branch class: `det J > 0`.
    pub const DET_POSITIVE: Branch = Branch(8);
    /// Numerical-IK branch class: `det J < 0`.
    pub const DET_NEGATIVE: Branch = Branch(9);

    /// The numerical-IK branch class of a Jacobian determinant.
    pub fn of_determinant(det: f64) -> Self {
        if det < 0.0 { Self::DET_NEGATIVE } else { Self::DET_POSITIVE }
    }

    /// True for a numerical-IK class ([`Branch::DET_POSITIVE`], [`Branch::DET_NEGATIVE`]).
    pub fn is_determinant_class(self) -> bool {
        self == Self::DET_POSITIVE || self == Self::DET_NEGATIVE
    }

    /// The branch as written in the `branch` column: `0..7` on the canonical cell, `+` / `-`
    /// (sign of `det J`) for a numerical-IK class.
    pub fn column(self) -> String {
        match self {
            Self::DET_POSITIVE => "+".into(),
            Self::DET_NEGATIVE => "-".into(),
            b => b.0.to_string(),
        }
    }

    /// The branch of arm joints `q` on the closed-form geometry `arm` (a calibrated model's
    /// arm is close enough: branches differ by sign changes far from its small errors, except
    /// right at a singularity).
    pub fn of(arm: &ArmGeometry, q: &JointVector) -> Self {
        let q_arm: [f64; 6] = std::array::from_fn(|k| q[k + 1]);
        let theta: [f64; 6] = std::array::from_fn(|k| q_arm[k] + arm.theta_offset_rad[k]);
        let tool = arm.forward(&q_arm);
        let w = tool.p - tool.z_axis() * arm.flange_mm;
        let (s2, c2) = theta[0].sin_cos();
        let shoulder = w.x * c2 + w.y * s2 < 0.0;
        let delta = arm.forearm_mm.atan2(arm.elbow_offset_mm);
        let elbow = wrap_angle(theta[2] + delta) < 0.0;
        let wrist = wrap_angle(theta[4]) < 0.0;
        Self(u8::from(shoulder) | (u8::from(elbow) << 1) | (u8::from(wrist) << 2))
    }

    /// Shoulder bit: wrist centre behind the J1 axis.
    pub fn shoulder_back(self) -> bool {
        self.0 & 1 != 0
    }

    /// Elbow bit: the `−acos` elbow solution.
    pub fn elbow_down(self) -> bool {
        self.0 & 2 != 0
    }

    /// Wrist bit: `θ_6 < 0` (Meca500 J5 negative, up to its offset).
    pub fn wrist_negative(self) -> bool {
        self.0 & 4 != 0
    }
}

impl fmt::Display for Branch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::DET_POSITIVE => return write!(f, "+ (det J > 0)"),
            Self::DET_NEGATIVE => return write!(f, "- (det J < 0)"),
            _ => {}
        }
        let s = |b: bool| if b { '-' } else { '+' };
        write!(
            f,
            "{} (shoulder {}, elbow {}, wrist {})",
            self.0,
            s(self.shoulder_back()),
            s(self.elbow_down()),
            s(self.wrist_negative())
        )
    }
}
