//! Branch enumeration on a model ([`ToolPoseIk`]): the closed-form branches corrected on
//! their own branch, refined, and completed near the wrist singularity (`wrist_band`).

use vatcal_core::{Frame, JointVector, deg_to_rad};
use vatcal_kinematics::Model;

use super::closed_form::{ArmGeometry, ClosedFormArm, SEED_REACH_SLACK};
use super::common::{RefineOptions, max_abs_diff, rotation_angle_between, wrap_angle};
use super::refine::{Refined, refine_arm, refine_tool_pose};
use super::structure::robot_base_frame;
use crate::error::PlanError;

/// A closed-form seed of the refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSeed {
    /// joints (the external axes, q1, as given)
    pub q: JointVector,
    /// true for a seed just beyond the nominal arm's reach (not an exact nominal solution)
    pub beyond_reach: bool,
}

/// Closed-form seeds + refinement for the tool-changer frame pose of a model.
///
/// When the model is not exactly the nominal-structure arm (a calibrated model), each
/// closed-form seed is first corrected [`SEED_CORRECTIONS`] times on its own branch: with
/// `E(q) = T_nom(q)⁻¹ T_model(q)` the error of the nominal structure at the seed, the closed
/// form is solved again for `T* E(q)⁻¹`. Near a singularity a small model error moves the
/// solution a lot, and this keeps the seed on the right branch before the refinement.
///
/// The closed form is `A`: [`ArmGeometry`] (a spherical wrist, the default) or
/// [`ParallelArm`](crate::ik::ParallelArm) (three parallel middle axes and a UR-type wrist),
/// see [`ClosedFormArm`].
#[derive(Debug, Clone)]
pub struct ToolPoseIk<'a, A: ClosedFormArm = ArmGeometry> {
    pub(super) model: &'a Model,
    pub(super) arm: A,
    pub(super) refine: RefineOptions,
    pub(super) corrections: usize,
}

/// Branch-preserving closed-form corrections of a seed on a calibrated model.
pub const SEED_CORRECTIONS: usize = 2;

/// True when the model's tool frame is the closed-form arm's at a few test configurations
/// (nominal model: no seed correction needed).
fn closed_form_is_exact<A: ClosedFormArm>(model: &Model, arm: &A) -> bool {
    let tests = [
        [120.0, 30.0, 20.0, -40.0, 50.0, 60.0, -70.0],
        [10.0, -100.0, -50.0, 30.0, -120.0, -20.0, 150.0],
        [280.0, 150.0, 80.0, -120.0, 10.0, 100.0, 5.0],
    ];
    let k = arm.first_joint() - 1;
    tests.iter().all(|t| {
        let mut q = JointVector::zeros(model.joint_count());
        if k > 0 {
            q[0] = t[0];
        }
        for j in 0..6 {
            q[k + j] = deg_to_rad(t[j + 1]);
        }
        let arm_q: [f64; 6] = std::array::from_fn(|j| q[k + j]);
        let nominal = robot_base_frame(model, t[0]).compose(&arm.forward(&arm_q));
        let actual = model.chain(&q).tool;
        (nominal.p - actual.p).norm() < 1e-9 && rotation_angle_between(&nominal.r, &actual.r) < 1e-12
    })
}

impl<'a> ToolPoseIk<'a> {
    /// IK for `model`: a 6R arm with a spherical wrist ([`ArmGeometry::from_model`]), with at
    /// most one prismatic joint (the guide, joint 1) in front of it.
    ///
    /// # Examples
    /// Every solution that puts the tool-changer frame at a target pose with the guide at 150 mm,
    /// each checked by forward kinematics:
    /// ```
    /// use vatcal_core::{CellFile, JointVector};
    /// use vatcal_kinematics::Model;
    /// use vatcal_planning::ik::{RefineOptions, ToolPoseIk};
    ///
    /// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
    /// // a reachable target: the tool frame at a known configuration
    /// let known = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    /// let target = model.chain(&known).tool;
    /// let ik = ToolPoseIk::new(&model, RefineOptions::default())?;
    /// let solutions = ik.solve_at_guide(150.0, &target);
    /// assert!(solutions.len() >= 2, "several branches reach this pose");
    /// for q in &solutions {
    ///     assert!((model.chain(q).tool.p - target.p).norm() < 1e-8);
    /// }
    /// assert!(solutions.iter().any(|q| (1..=7).all(|j| (q.get(j) - known.get(j)).abs() < 1e-7)));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] when the model's arm does not have the structure the
    /// closed form needs (see [`ArmGeometry::from_model`]; the message names the row and value)
    /// or has more than one prismatic joint in front of the arm.
    pub fn new(model: &'a Model, refine: RefineOptions) -> Result<Self, PlanError> {
        Self::with_closed_form(model, refine)
    }
}

impl<'a, A: ClosedFormArm> ToolPoseIk<'a, A> {
    /// IK for `model` with the closed form `A` ([`ClosedFormArm::from_model`]), with at most
    /// one prismatic joint (the guide, joint 1) in front of the arm; e.g.
    /// `ToolPoseIk::<ParallelArm>::with_closed_form` for a UR-type arm.
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] when the model's arm does not have the structure `A`
    /// needs (the message names the row and value) or has more than one prismatic joint in
    /// front of the arm.
    pub fn with_closed_form(model: &'a Model, refine: RefineOptions) -> Result<Self, PlanError> {
        let arm = A::from_model(model)?;
        if arm.first_joint() > 2 {
            return Err(PlanError::UnsupportedArm(format!(
                "the closed-form IK holds one prismatic joint (the guide) at given positions; this chain has {} prismatic joints in front of the arm ({})",
                arm.first_joint() - 1,
                model.describe_chain()
            )));
        }
        let corrections = if closed_form_is_exact(model, &arm) { 0 } else { SEED_CORRECTIONS };
        Ok(Self { model, arm, refine, corrections })
    }

    /// The closed-form geometry in use.
    pub fn arm(&self) -> &A {
        &self.arm
    }

    /// True when the model is exactly the closed form's nominal structure (the seeds are
    /// solutions; no correction, no wrist-band search).
    pub fn is_exact(&self) -> bool {
        self.corrections == 0
    }

    /// The model.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// The guide joint held at the guide positions (1-based): `Some(1)` when the chain has a
    /// prismatic joint in front of the arm, `None` for an arm alone (guide positions ignored).
    pub fn guide_joint(&self) -> Option<usize> {
        (self.arm.first_joint() > 1).then_some(1)
    }

    /// The cell's joint vector for the guide at `q1_mm` (if the chain has one) and arm joints
    /// `arm` (rad).
    pub(super) fn joints(&self, q1_mm: f64, arm: &[f64; 6]) -> JointVector {
        let k = self.arm.first_joint() - 1;
        let mut q = JointVector::zeros(self.model.joint_count());
        if k > 0 {
            q[0] = q1_mm;
        }
        q.as_mut_slice()[k..k + 6].copy_from_slice(arm);
        q
    }

    /// Closed-form seeds at guide position `q1_mm` (ignored without a guide) for the world tool
    /// pose `target`, given the robot base frame `base` at that guide position
    /// ([`robot_base_frame`]); corrected on their branch for a calibrated model (see the type
    /// docs).
    pub fn seeds(&self, q1_mm: f64, base: &Frame, target: &Frame) -> Vec<IkSeed> {
        let base_inv = base.inverse();
        let solutions = self.arm.solve_with_reach_slack(&base_inv.compose(target), SEED_REACH_SLACK);
        let joints = |arm: &[f64; 6]| self.joints(q1_mm, arm);
        let mut out = Vec::with_capacity(solutions.len());
        for ((arm, beyond), branch) in
            solutions.as_slice().iter().zip(solutions.beyond_reach()).zip(solutions.branches())
        {
            let mut q = *arm;
            for _ in 0..self.corrections {
                let actual = self.model.chain(&joints(&q)).tool;
                let nominal = base.compose(&self.arm.forward(&q));
                let corrected = base_inv.compose(target).compose(&actual.inverse()).compose(&nominal);
                match self.arm.solve_with_reach_slack(&corrected, SEED_REACH_SLACK).of_branch(*branch) {
                    Some(next) => q = next,
                    None => break,
                }
            }
            out.push(IkSeed { q: joints(&q), beyond_reach: *beyond });
        }
        out
    }

    /// Refines one seed on the model.
    ///
    /// # Errors
    /// As [`refine_tool_pose`].
    pub fn refine(&self, seed: &JointVector, target: &Frame) -> Result<Refined, PlanError> {
        if seed.len() != self.model.joint_count() {
            return refine_tool_pose(self.model, seed, target, &self.refine);
        }
        refine_arm(self.model, self.arm.first_joint(), seed, target, &self.refine)
    }

    /// Every solution at guide position `q1_mm` (ignored without a guide; closed-form seeds
    /// refined on the model; seeds that do not converge are dropped; duplicates merged; on a
    /// calibrated model, the soft wrist direction scanned near the wrist singularity, see
    /// [`ToolPoseIk::add_wrist_band_solutions`]), each arm joint wrapped to (-pi, pi]. The
    /// closed-form branches come first, in branch order; up to 8 of them, plus any further
    /// solutions of a calibrated wrist near its singularity.
    pub fn solve_at_guide(&self, q1_mm: f64, target: &Frame) -> Vec<JointVector> {
        let base = robot_base_frame(self.model, q1_mm);
        let mut out: Vec<JointVector> = Vec::with_capacity(8);
        for seed in self.seeds(q1_mm, &base, target) {
            if let Ok(r) = self.refine(&seed.q, target) {
                let q = self.wrapped(r.q);
                if !out.iter().any(|p| max_abs_diff(p, &q) < 1e-9) {
                    out.push(q);
                }
            }
        }
        self.add_wrist_band_solutions(target, &mut out);
        out
    }

    /// `q` with every arm joint wrapped to (-pi, pi].
    pub(super) fn wrapped(&self, mut q: JointVector) -> JointVector {
        for v in q.as_mut_slice().iter_mut().skip(self.arm.first_joint() - 1) {
            *v = wrap_angle(*v);
        }
        q
    }

    /// Every solution over several guide positions (as [`ToolPoseIk::solve_at_guide`] at each:
    /// up to 8 per position, more near the wrist singularity of a calibrated model; one pass for
    /// an arm without a guide).
    pub fn solve(&self, guide_positions_mm: &[f64], target: &Frame) -> Vec<JointVector> {
        if self.guide_joint().is_none() {
            return self.solve_at_guide(0.0, target);
        }
        guide_positions_mm.iter().flat_map(|q1| self.solve_at_guide(*q1, target)).collect()
    }
}
