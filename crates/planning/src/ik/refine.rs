//! Refinement of a seed on the full model: the tool Jacobian, the tool kinematics with the
//! guide or other joints held, and [`refine_tool_pose`] (the chain-agnostic iteration of
//! `crate::numeric_ik::solve_local`).

use nalgebra::{Matrix6, Matrix6xX, Vector3};
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::Model;

use super::common::RefineOptions;
use super::structure::leading_prismatic_joints;
use crate::error::PlanError;
use crate::numeric_ik::{IkTarget, JointSpec, ToolKinematics, solve_local};

/// Result of a converged refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// joints (q1 as given in the seed)
    pub q: JointVector,
    /// iterations used
    pub iterations: usize,
    /// final tool position error (mm)
    pub position_error_mm: f64,
    /// final tool orientation error (rad)
    pub rotation_error_rad: f64,
}

/// The 6×6 joint Jacobian (q2..q7, the canonical cell's arm) of the tool frame:
/// `[z_i × (p - o_i); z_i]` (world axes; rows: translation, then rotation).
#[inline]
pub fn tool_jacobian(chain: &vatcal_kinematics::Chain) -> Matrix6<f64> {
    arm_tool_jacobian(chain, 2)
}

/// The 6×6 Jacobian of the tool frame in the six revolute joints `first..first + 6`
/// (1-based cell joints): `[z_i × (p - o_i); z_i]` (world axes; rows: translation, then
/// rotation).
#[inline]
pub fn arm_tool_jacobian(chain: &vatcal_kinematics::Chain, first: usize) -> Matrix6<f64> {
    let p = chain.tool.p;
    let mut j = Matrix6::zeros();
    for k in 0..6 {
        let f = &chain.frames[k + first];
        let z = f.z_axis();
        let lin = z.cross(&(p - f.p));
        for r in 0..3 {
            j[(r, k)] = lin[r];
            j[(r + 3, k)] = z[r];
        }
    }
    j
}

/// The arm of a [`Model`] with the guide held at `q1_mm`, as a [`ToolKinematics`] of the six
/// revolute joints after the prismatic joints in front of the arm (`[q2..q7]` on the canonical
/// cell, rad): tool-changer frame in the world and [`arm_tool_jacobian`]. The first prismatic
/// joint is at `q1_mm` (ignored without one), any further ones at 0; the model must have six
/// joints after them (the `joints` of a shorter chain panics).
#[derive(Debug, Clone, Copy)]
pub struct ArmAtGuide<'a> {
    /// the model
    pub model: &'a Model,
    /// guide position (mm)
    pub q1_mm: f64,
}

impl<'a> ArmAtGuide<'a> {
    /// The cell's joint vector for arm joints `q` (rad).
    pub fn joints(&self, q: &[f64]) -> JointVector {
        self.arm().joints(q)
    }

    fn arm(&self) -> ArmWithFixed<'a> {
        let first = leading_prismatic_joints(self.model) + 1;
        let mut fixed = JointVector::zeros(self.model.joint_count());
        if first > 1 {
            fixed[0] = self.q1_mm;
        }
        ArmWithFixed { model: self.model, fixed, first }
    }
}

impl ToolKinematics for ArmAtGuide<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        6
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        self.arm().evaluate(q)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        self.arm().jacobian(chain, jacobian)
    }
}

/// Six revolute joints `first..first + 6` (1-based) of a model solved for, every other joint
/// held at its value in `fixed`.
#[derive(Debug, Clone, Copy)]
struct ArmWithFixed<'a> {
    pub(super) model: &'a Model,
    pub(super) fixed: JointVector,
    pub(super) first: usize,
}

impl ArmWithFixed<'_> {
    pub(super) fn joints(&self, q: &[f64]) -> JointVector {
        let mut v = self.fixed;
        v.as_mut_slice()[self.first - 1..self.first + 5].copy_from_slice(&q[..6]);
        v
    }
}

impl ToolKinematics for ArmWithFixed<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        6
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        let chain = self.model.chain(&self.joints(q));
        (chain.tool, chain)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        jacobian.copy_from(&arm_tool_jacobian(chain, self.first));
    }
}

/// Any joints of a [`Model`]'s chain as a [`ToolKinematics`]: the joints `free` (1-based cell
/// joints, in this order) are solved for, the others are held at their values in `fixed`.
/// Jacobian column of joint `i`: `[z_i × (p - o_i); z_i]` (revolute) or `[z_i; 0]` (prismatic),
/// with the axes of MDH frame `i` from [`vatcal_kinematics::Chain::frames`] (effects and
/// compliance held fixed, as in [`tool_jacobian`]).
#[derive(Debug, Clone)]
pub struct ChainTool<'a> {
    /// the model
    pub model: &'a Model,
    /// values of the joints that are not solved for (internal units)
    pub fixed: JointVector,
    /// the joints solved for (1-based)
    pub free: Vec<usize>,
    /// per free joint: true when revolute
    pub revolute: Vec<bool>,
}

impl ChainTool<'_> {
    /// The cell's joint vector for the free joints' values `q`.
    pub fn joints(&self, q: &[f64]) -> JointVector {
        let mut v = self.fixed;
        for (i, x) in self.free.iter().zip(q) {
            v.set(*i, *x);
        }
        v
    }
}

impl ToolKinematics for ChainTool<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        self.free.len()
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        let chain = self.model.chain(&self.joints(q));
        (chain.tool, chain)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        let p = chain.tool.p;
        for (c, (i, revolute)) in self.free.iter().zip(&self.revolute).enumerate() {
            let f = &chain.frames[*i];
            let z = f.z_axis();
            let (lin, ang) = if *revolute { (z.cross(&(p - f.p)), z) } else { (z, Vector3::zeros()) };
            for r in 0..3 {
                jacobian[(r, c)] = lin[r];
                jacobian[(r + 3, c)] = ang[r];
            }
        }
    }
}

/// Refines `seed` so that the model's tool-changer frame reaches `target` (world), solving
/// for the six revolute joints after the prismatic joints in front of the arm (q2..q7 on the
/// canonical cell) and holding those prismatic joints (q1, the guide) at their seed values.
/// Levenberg–Marquardt on the weighted 6-DOF error (no joint limits):
/// [`crate::numeric_ik::solve_local`] on the arm (as [`ArmAtGuide`]); see the module docs.
///
/// # Errors
/// [`PlanError::IkNotConverged`] when the tolerances are missed; [`PlanError::UnsupportedArm`]
/// when the model has no six revolute joints after its leading prismatic joints, or `seed`
/// has the wrong length.
pub fn refine_tool_pose(
    model: &Model,
    seed: &JointVector,
    target: &Frame,
    opts: &RefineOptions,
) -> Result<Refined, PlanError> {
    let first = leading_prismatic_joints(model) + 1;
    let n = model.joint_count();
    if n < first + 5
        || seed.len() != n
        || !model.joint_kinds()[first - 1..first + 5].iter().all(|k| k.is_revolute())
    {
        return Err(PlanError::UnsupportedArm(format!(
            "the refinement needs six revolute joints after the prismatic external axes and one seed value per joint; this chain has {}, the seed {} values",
            model.describe_chain(),
            seed.len()
        )));
    }
    refine_arm(model, first, seed, target, opts)
}

/// [`refine_tool_pose`] for a chain already checked: arm joints `first..first + 6`, one seed
/// value per joint.
pub(super) fn refine_arm(
    model: &Model,
    first: usize,
    seed: &JointVector,
    target: &Frame,
    opts: &RefineOptions,
) -> Result<Refined, PlanError> {
    let arm = ArmWithFixed { model, fixed: *seed, first };
    let r = solve_local(
        &arm,
        &[JointSpec::continuous(); 6],
        &seed.as_slice()[first - 1..first + 5],
        &IkTarget::Pose(*target),
        opts,
    )?;
    Ok(Refined {
        q: arm.joints(&r.q),
        iterations: r.iterations,
        position_error_mm: r.position_error_mm,
        rotation_error_rad: r.rotation_error_rad,
    })
}
