//! Which joints of a chain a pose request gives and which six the solver finds.

use nalgebra::Matrix6;
use vatcal_core::{JointVector, MAX_JOINTS};
use vatcal_kinematics::{Chain, Model};

use crate::CompensationError;

/// Which joints of a chain a pose request gives and which the solver finds.
///
/// A pose fixes six degrees of freedom, so exactly six joints are solved for:
/// * a chain of **six** joints: all six (the request gives none; columns
///   `tcp,x,y,z,alpha,beta,gamma`);
/// * a chain of **more than six** joints: the request gives the prismatic joints (the
///   "external axes", e.g. the canonical cell's guide `q1`), and there must be exactly
///   `N − 6` of them, so that six joints are left;
/// * a chain of **fewer than six** joints cannot reach an arbitrary pose: an error (compensate
///   positions only with a six-joint model, or extend the chain).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JointSplit {
    n: usize,
    given: [bool; MAX_JOINTS],
    /// 0-based indices of the solved joints, in chain order
    free: [usize; 6],
    free_revolute: [bool; 6],
}

impl JointSplit {
    /// The split of `model`'s chain (see the type docs).
    ///
    /// # Errors
    /// [`CompensationError::UnsupportedChain`] for fewer than six joints, or more than six
    /// joints whose prismatic joints are not exactly `N − 6`.
    pub fn of(model: &Model) -> Result<Self, CompensationError> {
        let kinds = model.joint_kinds();
        let n = kinds.len();
        let unsupported =
            |reason: String| CompensationError::UnsupportedChain { chain: model.describe_chain(), reason };
        if n < 6 {
            return Err(unsupported(format!(
                "a pose (position and orientation: 6 degrees of freedom) needs at least 6 joints; \
                 {n} joints cannot reach an arbitrary pose"
            )));
        }
        let mut given = [false; MAX_JOINTS];
        if n > 6 {
            let prismatic = kinds.iter().filter(|k| !k.is_revolute()).count();
            if prismatic != n - 6 {
                return Err(unsupported(format!(
                    "a request gives the prismatic joints (external axes) and the pose determines the \
                     other six; this chain has {prismatic} prismatic joint(s), so {} joints would be left \
                     for the 6 degrees of freedom of a pose",
                    n - prismatic
                )));
            }
            for (g, k) in given.iter_mut().zip(kinds) {
                *g = !k.is_revolute();
            }
        }
        let mut free = [0; 6];
        let mut free_revolute = [false; 6];
        for (slot, k) in (0..n).filter(|k| !given[*k]).enumerate() {
            free[slot] = k;
            free_revolute[slot] = kinds[k].is_revolute();
        }
        Ok(Self { n, given, free, free_revolute })
    }

    /// Number of joints of the chain.
    pub fn joint_count(&self) -> usize {
        self.n
    }

    /// The joints a request gives (1-based, in chain order).
    pub fn given_joints(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.n).filter(|k| self.given[*k]).map(|k| k + 1)
    }

    /// The six joints the solver finds (1-based, in chain order).
    pub fn solved_joints(&self) -> [usize; 6] {
        self.free.map(|k| k + 1)
    }

    /// 0-based indices of the solved joints.
    pub(crate) fn free(&self) -> &[usize; 6] {
        &self.free
    }

    /// True when solved joint `slot` (0..6) is revolute.
    pub(crate) fn free_revolute(&self, slot: usize) -> bool {
        self.free_revolute[slot]
    }

    /// `q` with its given joints set to the values in `given`.
    #[inline]
    pub(crate) fn apply_given(&self, q: &mut JointVector, given: &JointVector) {
        for k in 0..self.n {
            if self.given[k] {
                q[k] = given[k];
            }
        }
    }

    /// The 6×6 Jacobian of the tool frame with respect to the solved joints: column
    /// `[z_i × (p − o_i); z_i]` for a revolute and `[z_i; 0]` for a prismatic joint `i` (world
    /// axes of MDH frame `i`; rows: translation, then rotation). On the canonical cell this is
    /// `vatcal_planning::ik::tool_jacobian`.
    #[inline]
    pub fn jacobian(&self, chain: &Chain) -> Matrix6<f64> {
        let p = chain.tool.p;
        let mut j = Matrix6::zeros();
        for (c, &k) in self.free.iter().enumerate() {
            let f = &chain.frames[k + 1];
            let z = f.z_axis();
            if self.free_revolute[c] {
                let lin = z.cross(&(p - f.p));
                for r in 0..3 {
                    j[(r, c)] = lin[r];
                    j[(r + 3, c)] = z[r];
                }
            } else {
                for r in 0..3 {
                    j[(r, c)] = z[r];
                }
            }
        }
        j
    }
}
